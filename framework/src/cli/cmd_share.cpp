// pinsim share [SCENE] [--out game.html] [--width W] [--source DIR]... [--web-build DIR]
// One self-contained HTML page in which the table is played live: the engine compiled to
// WebAssembly (the `web` preset's pinsim_web.js, wasm embedded), the scene's text and the
// static table drawn as `play` draws it. With --source, the page's engine is the prebuilt
// one linked with the plugins of those folders compiled to WebAssembly (tools/web_build).
// No source code of any plugin goes in.
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <thread>

#include "cli_common.hpp"
#include "commands.hpp"
#include "core/base64.hpp"
#include "core/data_files.hpp"
#include "core/input_error.hpp"
#include "core/output_file.hpp"
#include "pictures/cairo_handles.hpp"
#include "pictures/play_game.hpp"
#include "pictures/render_field.hpp"
#include "pictures/share.hpp"
#include "tools/web_build.hpp"

namespace pinsim::cli {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

struct ShareArgs {
  std::string scene;
  std::string out = "game.html";
  int width = 600;
  std::vector<std::string> sources;  ///< plugin folders compiled into the page's engine
  std::string web_build;             ///< where they are compiled (default: a temporary folder)
};

std::string read_text(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  if (!in) throw std::runtime_error(f.string() + ": cannot read");
  return ss.str();
}

/// The web engine: $PINSIM_WEB_MODULE, else an installed pinsim's (share/pinsim/web), else
/// where the build put it.
fs::path web_module() {
  if (const char* env = std::getenv("PINSIM_WEB_MODULE"); env && *env) return env;
  std::error_code ec;
  if (const fs::path installed = data_dir() / "web" / "pinsim_web.js";
      fs::is_regular_file(installed, ec))
    return installed;
  return PINSIM_WEB_MODULE;
}

/// The web SDK that compiles plugin folders for the page: $PINSIM_WEB_SDK, else an
/// installed pinsim's (share/pinsim/web), else the web build's staged copy (web-sdk).
fs::path web_sdk() {
  if (const char* env = std::getenv("PINSIM_WEB_SDK"); env && *env) return env;
  std::error_code ec;
  const fs::path config = fs::path("cmake") / "pinsimConfig.cmake";
  for (const fs::path& dir :
       {data_dir() / "web", fs::path(PINSIM_WEB_MODULE).parent_path() / "web-sdk"})
    if (fs::is_regular_file(dir / config, ec)) return dir;
  throw std::runtime_error(
      "--source: pinsim's web SDK is not there: build the web engine (`cmake --preset web && "
      "cmake --build --preset web`) and install it beside pinsim (`cmake --install build/web "
      "--prefix PREFIX`), or set PINSIM_WEB_SDK");
}

/// A temporary folder, removed with this object.
struct TempFolder {
  fs::path path;
  TempFolder() {
    std::string templ = (fs::temp_directory_path() / "pinsim-share.XXXXXX").string();
    if (::mkdtemp(templ.data()) == nullptr)
      throw std::runtime_error("cannot make a temporary folder in " +
                               fs::temp_directory_path().string());
    path = templ;
  }
  ~TempFolder() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  TempFolder(const TempFolder&) = delete;
  TempFolder& operator=(const TempFolder&) = delete;
};

/// The engine for the page: the prebuilt one, or one linked with the --source folders.
fs::path page_engine(const ShareArgs& a, std::unique_ptr<TempFolder>& tmp) {
  if (a.sources.empty()) return web_module();
  const fs::path sdk = web_sdk();
  fs::path dir = a.web_build;
  if (dir.empty()) {
    tmp = std::make_unique<TempFolder>();
    dir = tmp->path;
  }
  std::vector<fs::path> sources(a.sources.begin(), a.sources.end());
  const unsigned cores = std::thread::hardware_concurrency();
  const WebBuild b = build_web_engine(sources, sdk, dir, cores == 0 ? 2 : static_cast<int>(cores));
  spdlog::info("compiled {} plugin folder(s) for the web in {:.0f} s (web SDK {})", sources.size(),
               b.seconds, sdk.string());
  return b.module;
}

int share_command(const ShareArgs& a) {
  Scene scene = load_scene_or_default(a.scene, {});
  // The scene's own text goes into the page (the default scene's when none is given): the
  // text load_scene read (bounded, once: the file may be a pipe or a device).
  const std::string scene_text =
      a.scene.empty() ? std::string(kDefaultSceneText) : scene_file_text(a.scene);
  const std::string scene_file = a.scene.empty() ? std::string(kDefaultSceneName) : a.scene;

  std::unique_ptr<TempFolder> tmp;
  const fs::path module = page_engine(a, tmp);
  std::error_code ec;
  if (!fs::is_regular_file(module, ec))
    throw std::runtime_error(
        "the web engine " + module.string() +
        " is not built: build it with `cmake --preset web && cmake --build --preset web` "
        "(or configure with -DPINSIM_WEB=ON), or set PINSIM_WEB_MODULE");
  // Every plugin the scene uses must be linked into the web engine.
  fs::path list_file = module;
  list_file.replace_extension(".plugins");
  std::set<std::string> built_in;
  {
    std::istringstream in(read_text(list_file));
    for (std::string n; in >> n;) built_in.insert(n);
  }
  std::vector<const PluginRef*> used{&scene.backend};
  for (const auto& f : scene.forces) used.push_back(&f);
  for (const PluginRef* p : used) {
    if (!built_in.count(p->name)) {
      std::string have;
      for (const auto& n : built_in) have += (have.empty() ? "" : ", ") + n;
      throw InputError(scene.label + ": plugin '" + p->name +
                       "' is not in the web engine (it has: " + have +
                       "); give the folder of its source with --source DIR (docs/pictures.md, "
                       "pinsim share)");
    }
    if (!p->library.empty())
      throw InputError(scene.label + ": plugin '" + p->name + "' is given as a library file (" +
                       p->library +
                       "); the web engine has only its built-in plugins: drop \"library\"");
  }

  // The game checks the scene as `play` does (inputs, a backend that takes them).
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  PinballGame game(scene, loader);
  const PixelMap map(scene_view(scene, game.backend()), a.width);
  const CairoSurface bg = image_surface(map.width, map.height);
  {
    const CairoContext cr = cairo_context(bg.get());
    draw_static_table(cr.get(), scene, loader, map);
  }
  SharePage page;
  page.title = scene.name;
  page.engine_js = read_text(module);
  page.data = {{"scene_text", scene_text},
               {"scene_file", scene_file},
               {"background", "data:image/png;base64," + base64(png_bytes(bg.get()))},
               {"view", {map.view.x0, map.view.y0, map.view.x1, map.view.y1}},
               {"width", map.width},
               {"height", map.height},
               {"scale", map.scale}};
  const std::string html = share_html(page);
  write_file_atomically(a.out, html);
  spdlog::info("shared {} as {} ({:.0f} kB: engine {:.0f} kB)", scene_file, a.out,
               html.size() / 1024.0, page.engine_js.size() / 1024.0);
  return 0;
}

}  // namespace

void add_share_command(CLI::App& app) {
  auto a = std::make_shared<ShareArgs>();
  CLI::App* c = app.add_subcommand(
      "share",
      "Write one self-contained HTML page in which the table is played live (WebAssembly)");
  c->add_option("scene", a->scene, "Scene file (default: the embedded pinball table)");
  c->add_option("--out,-o", a->out, "HTML file (default: game.html)");
  c->add_option("--width,-w", a->width, "Picture width, pixels (the page scales it to the window)")
      ->check(CLI::Range(64, 4096));
  c->add_option("--source", a->sources,
                "A plugin folder (CMakeLists.txt with pinsim_add_plugin) compiled to "
                "WebAssembly into the page's engine; repeatable. Needs Emscripten");
  c->add_option("--web-build", a->web_build,
                "Where --source folders are compiled (kept; default: a temporary folder)");
  c->callback([a] { throw CLI::RuntimeError(share_command(*a)); });
}

}  // namespace pinsim::cli
