// pinsim share [SCENE] [--out game.html] [--width W]
// One self-contained HTML page in which the table is played live: the engine compiled to
// WebAssembly (the `web` preset's pinsim_web.js, wasm embedded), the scene's text and the
// static table drawn as `play` draws it. No source code of any plugin goes in.
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>

#include "cli_common.hpp"
#include "commands.hpp"
#include "core/base64.hpp"
#include "core/input_error.hpp"
#include "core/output_file.hpp"
#include "pictures/cairo_handles.hpp"
#include "pictures/play_game.hpp"
#include "pictures/render_field.hpp"
#include "pictures/share.hpp"

namespace pinsim::cli {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

struct ShareArgs {
  std::string scene;
  std::string out = "game.html";
  int width = 600;
};

std::string read_text(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  if (!in) throw std::runtime_error(f.string() + ": cannot read");
  return ss.str();
}

/// The web engine: $PINSIM_WEB_MODULE, else where the build put it.
fs::path web_module() {
  if (const char* env = std::getenv("PINSIM_WEB_MODULE"); env && *env) return env;
  return PINSIM_WEB_MODULE;
}

int share_command(const ShareArgs& a) {
  Scene scene = load_scene_or_default(a.scene, {});
  // The scene's own text goes into the page (the default scene's when none is given): the
  // text load_scene read (bounded, once: the file may be a pipe or a device).
  const std::string scene_text =
      a.scene.empty() ? std::string(kDefaultSceneText) : scene_file_text(a.scene);
  const std::string scene_file = a.scene.empty() ? std::string(kDefaultSceneName) : a.scene;

  const fs::path module = web_module();
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
                       "); docs/pictures.md (pinsim share, \"Plugins\") says how to build one in");
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
  c->callback([a] { throw CLI::RuntimeError(share_command(*a)); });
}

}  // namespace pinsim::cli
