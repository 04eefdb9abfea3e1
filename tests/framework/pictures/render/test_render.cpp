// Pictures: `pinsim render` (PNG pixels and size, SVG elements), `pinsim replay` (the page in
// headless Chromium draws the ball where trajectory.csv says) and `pinsim play` (under Xvfb,
// a recording reruns to the same state hash).
#include <cairo.h>
#include <sys/wait.h>

#include <array>
#include <catch2/catch.hpp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <regex>

#include "core/simulation.hpp"
#include "pictures/render_data.hpp"
#include "test_support.hpp"

using namespace pinsim;
namespace fs = std::filesystem;

namespace {

using test::pinsim_cli;
using test::shell;

const std::string kScene = PINSIM_TEST_SOURCE_DIR "/framework/pictures/render/box_ball.json";
// The test scene's unit box, 400 pixels across: pixel = (400 x, 400 (1 - y)).
const std::string kView = "--view 0,0,1,1 --width 400";
int px(double x) { return static_cast<int>(400 * x); }
int py(double y) { return static_cast<int>(400 * (1 - y)); }

/// A PNG read with cairo; pixels as 0..255 RGB.
class Png {
 public:
  explicit Png(const fs::path& file) : s_(cairo_image_surface_create_from_png(file.c_str())) {}
  ~Png() { cairo_surface_destroy(s_); }
  Png(const Png&) = delete;
  Png& operator=(const Png&) = delete;
  bool ok() const { return cairo_surface_status(s_) == CAIRO_STATUS_SUCCESS; }
  int width() const { return cairo_image_surface_get_width(s_); }
  int height() const { return cairo_image_surface_get_height(s_); }
  std::array<int, 3> rgb(int x, int y) const {
    const unsigned char* d = cairo_image_surface_get_data(s_);
    const int stride = cairo_image_surface_get_stride(s_);
    uint32_t v = 0;
    std::memcpy(&v, d + static_cast<std::ptrdiff_t>(y) * stride + 4 * x, 4);
    return {static_cast<int>((v >> 16) & 255), static_cast<int>((v >> 8) & 255),
            static_cast<int>(v & 255)};
  }
  bool is_red(int x, int y) const {  // the first particle's colour, #d91f1f
    const auto c = rgb(x, y);
    return c[0] > 180 && c[1] < 80 && c[2] < 80;
  }
  bool is_blue(int x, int y) const {  // the second run's colour, #1a59d9
    const auto c = rgb(x, y);
    return c[2] > 180 && c[0] < 80;
  }
  bool is_dark(int x, int y) const {  // inside an obstacle
    const auto c = rgb(x, y);
    return c[0] < 90 && c[1] < 100 && c[2] < 120;
  }
  bool is_light(int x, int y) const {  // free space far from obstacles
    const auto c = rgb(x, y);
    return c[0] > 200 && c[1] > 180 && c[2] > 150;
  }

 private:
  cairo_surface_t* s_;
};

fs::path make_run(const std::string& tag, const std::string& extra = "") {
  const fs::path dir = test::temp_dir(tag);
  const auto r =
      pinsim_cli("-q run " + kScene + " --out " + dir.string() + " --overwrite " + extra);
  REQUIRE(r.code == 0);
  return dir;
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t k = 0; (k = text.find(what, k)) != std::string::npos; k += what.size()) ++n;
  return n;
}

}  // namespace

TEST_CASE("render: a scene as PNG shows the obstacles, the field and the ball") {
  const fs::path out = test::temp_dir("render-scene") / "scene.png";
  const auto r = pinsim_cli("-q render " + kScene + " " + kView + " --out " + out.string());
  REQUIRE(r.code == 0);
  Png png(out);
  REQUIRE(png.ok());
  CHECK(png.width() == 400);
  CHECK(png.height() == 400);
  CHECK(png.is_dark(px(0.5), py(0.3)));    // the disc's centre
  CHECK(png.is_light(px(0.8), py(0.75)));  // free space (far from any wall)
  CHECK(png.is_red(px(0.2), py(0.8)));     // the ball at t = 0
  CHECK(!png.is_red(px(0.5), py(0.8)));
  // The zero contour is drawn sharp and dark: just outside the disc's rim.
  const auto rim = png.rgb(px(0.5), py(0.3 + 0.15) - 1);
  CHECK(rim[0] < 80);
}

TEST_CASE("render --no-field: the obstacles are drawn, the field around them is not") {
  const fs::path dir = test::temp_dir("render-nofield");
  const auto r = pinsim_cli("-q render " + kScene + " " + kView + " --out " +
                            (dir / "solid.png").string() + " --no-field");
  REQUIRE(r.code == 0);
  REQUIRE(pinsim_cli("-q render " + kScene + " " + kView + " --out " + (dir / "field.png").string())
              .code == 0);
  Png solid(dir / "solid.png"), field(dir / "field.png");
  REQUIRE(solid.ok());
  REQUIRE(field.ok());
  CHECK(solid.is_dark(px(0.5), py(0.3)));  // the disc's centre: the obstacle is there
  // Just outside the disc's rim (radius 0.15) the field is shaded; without it the pixel
  // is the plain background, as in free space far from every wall.
  const int x = px(0.5), y = py(0.3 + 0.15 + 0.04);
  const auto background = solid.rgb(px(0.8), py(0.75));
  CHECK(solid.is_light(px(0.8), py(0.75)));
  CHECK(solid.rgb(x, y) == background);
  CHECK(field.rgb(x, y) != field.rgb(px(0.8), py(0.75)));
  CHECK(solid.is_red(px(0.2), py(0.8)));  // the ball at t = 0
}

TEST_CASE("render: a backend without outlines still draws its field; the view fits the particles") {
  const fs::path dir = test::temp_dir("render-no-outline");
  test::write_file(dir / "scene.json", R"({"plugin_path": [")" PINSIM_TEST_FIXTURE_DIR R"("],
    "time": {"dt": 0.01, "duration": 0.1}, "backend": {"name": "disc_backend"},
    "particles": [{"x": [0.0, 0.0], "radius": 0.05}, {"x": [1.0, 1.0], "radius": 0.05}],
    "forces": []})");
  const fs::path out = dir / "scene.png";
  const auto r =
      pinsim_cli("render " + (dir / "scene.json").string() + " --width 200 --out " + out.string());
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(r.output.find("does not report its obstacles' outlines") != std::string::npos);
  CHECK(r.output.find("PINSIM_CAP_OUTLINES") != std::string::npos);
  Png png(out);
  REQUIRE(png.ok());
  // the particles' box -0.05..1.05, padded: square, the disc about (0.5, 0.5) in the middle
  CHECK(png.width() == 200);
  CHECK(png.height() == 200);
  CHECK(png.is_dark(100, 100));
  CHECK(png.is_light(100, 20));
}

TEST_CASE("render: the view is the backend's outline bounds and the particles") {
  // box_ball.json: the inside of the unit box bounds everything: 0..1 padded by 3 %
  const fs::path out = test::temp_dir("render-view") / "scene.png";
  const auto r = pinsim_cli("-q render " + kScene + " --width 412 --out " + out.string());
  REQUIRE(r.code == 0);
  Png png(out);
  REQUIRE(png.ok());
  CHECK(png.width() == 412);
  CHECK(png.height() == 412);
  // the box's wall (dark, inside the obstacle) fills the 3 % margin; free space inside
  CHECK(png.is_dark(2, 206));
  CHECK(png.is_light(140, 130));
}

TEST_CASE("render: a run as PNG and SVG, with its path and contacts") {
  const fs::path run = make_run("render-run");
  const RunData data = load_run(run);
  REQUIRE(!data.contacts.empty());
  const auto& last = data.particles.at(0).back();

  const fs::path png_file = run / "run.png";
  auto r = pinsim_cli("-q render " + run.string() + " " + kView + " --out " + png_file.string());
  REQUIRE(r.code == 0);
  Png png(png_file);
  REQUIRE(png.ok());
  CHECK(png.width() == 400);
  CHECK(png.is_red(px(last.x), py(last.y)));  // the ball at the run's end
  CHECK(!png.is_red(px(0.2), py(0.8)));       // not at its start any more
  // The path passes x = 0.3 at y = 0.8 - 4.905 (0.1)^2 (before the bounce): red-ish line.
  const double y_path = 0.8 - 4.905 * 0.01;
  bool path_seen = false;
  for (int dy = -2; dy <= 2; ++dy) {
    const auto c = png.rgb(px(0.3), py(y_path) + dy);
    path_seen = path_seen || (c[0] > 150 && c[1] < 120);
  }
  CHECK(path_seen);
  // A contact ring (orange) near the first contact point.
  const auto& c0 = data.contacts.front();
  bool ring = false;
  for (int dx = -5; dx <= 5 && !ring; ++dx)
    for (int dy = -5; dy <= 5 && !ring; ++dy) {
      const auto c = png.rgb(px(c0.x) + dx, py(c0.y) + dy);
      ring = c[0] > 200 && c[1] > 90 && c[1] < 190 && c[2] < 80;
    }
  CHECK(ring);

  const fs::path svg_file = run / "run.svg";
  r = pinsim_cli("-q render " + run.string() + " " + kView + " --out " + svg_file.string());
  REQUIRE(r.code == 0);
  const std::string svg = test::read_file(svg_file);
  CHECK(svg.size() > 2000);
  CHECK(svg.find("<svg") != std::string::npos);
  CHECK(std::regex_search(svg, std::regex("width=\"400(pt)?\"")));
  CHECK(std::regex_search(svg, std::regex("height=\"400(pt)?\"")));
  CHECK(count(svg, "<image") >= 1);  // the shaded field
  CHECK(count(svg, "<path") >= 5);   // contours, path, contact marks, ball
}

TEST_CASE("render: a run made with --set overrides is drawn as it ran, from its scene.json") {
  // The disc moved from x = 0.5 to x = 0.75 on the command line: the run folder keeps the
  // scene as run, and the picture (no --scene given) shows the disc where the ball met it.
  const fs::path run = make_run("render-set", "--set obstacles[1].shape.center=[0.75,0.3]");
  const auto doc = nlohmann::json::parse(test::read_file(run / "scene.json"));
  CHECK(doc["obstacles"][1]["shape"]["center"] == nlohmann::json::array({0.75, 0.3}));
  const fs::path png_file = run / "set.png";
  const auto r = pinsim_cli("-q render " + run.string() + " " + kView +
                            " --no-trajectories --out " + png_file.string());
  REQUIRE(r.code == 0);
  Png png(png_file);
  REQUIRE(png.ok());
  CHECK(png.is_dark(px(0.75), py(0.3)));   // the disc's centre as run
  CHECK(!png.is_dark(px(0.45), py(0.3)));  // not where the scene file has it
}

TEST_CASE("render: a folder of runs (a crosscheck) overlays both paths") {
  const fs::path report = test::temp_dir("render-overlay");
  auto r = pinsim_cli("-q run " + kScene + " --out " + (report / "a").string());
  REQUIRE(r.code == 0);
  r = pinsim_cli("-q run " + kScene + " --set time.dt=0.004 --out " + (report / "b").string());
  REQUIRE(r.code == 0);
  const fs::path out = report / "overlay.png";
  r = pinsim_cli("-q render " + report.string() + " " + kView + " --out " + out.string());
  REQUIRE(r.code == 0);
  Png png(out);
  REQUIRE(png.ok());
  const auto a = load_run(report / "a").particles.at(0).back();
  const auto b = load_run(report / "b").particles.at(0).back();
  CHECK(png.is_red(px(a.x), py(a.y)));
  CHECK(png.is_blue(px(b.x), py(b.y)));
}

TEST_CASE("render: crosscheck --out writes a run folder per backend; render overlays them") {
  const fs::path report = test::temp_dir("render-crosscheck");
  auto r = pinsim_cli("-q crosscheck " + kScene + " --backends sdf,box2d --out " + report.string());
  REQUIRE((r.code == 0 || r.code == 1));  // 1: a tolerance failed; the folders are written
  CHECK(fs::exists(report / "report.json"));
  for (const char* b : {"sdf", "box2d"}) {
    CAPTURE(b);
    const auto s = nlohmann::json::parse(test::read_file(report / b / "summary.json"));
    CHECK(s["backend"] == b);
    CHECK(s["status"] == "ok");
    CHECK(s["steps"] == 1000);
    const auto scene = nlohmann::json::parse(test::read_file(report / b / "scene.json"));
    CHECK(scene["backend"]["name"] == b);
    CHECK(fs::exists(report / b / "events.csv"));
  }
  const fs::path out = report / "overlay.png";
  r = pinsim_cli("-q render " + report.string() + " " + kView + " --out " + out.string());
  REQUIRE(r.code == 0);
  Png png(out);
  REQUIRE(png.ok());
  // Each run's final position, in its colour (subfolders in name order: box2d, then sdf).
  const auto a = load_run(report / "box2d").particles.at(0).back();
  const auto b = load_run(report / "sdf").particles.at(0).back();
  CHECK(load_run(report / "sdf").particles.at(0).size() == 101);  // t = 0, 0.01, ..., 1
  CHECK(png.is_red(px(a.x), py(a.y)));
  CHECK(png.is_blue(px(b.x), py(b.y)));
}

TEST_CASE("render: a missing run folder is named as such, not as a scene file") {
  const fs::path gone = test::temp_dir("render-missing") / "no_such_run";
  const auto r = pinsim_cli("render " + gone.string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output,
             Catch::Matchers::Contains(gone.string() + ": no such run folder or scene file"));
  CHECK_THAT(r.output, !Catch::Matchers::Contains("scene file not found"));
}

TEST_CASE("render: bad input is one error line") {
  const auto r = pinsim_cli("render " + kScene + " --out /tmp/x.jpg");
  CHECK(r.code == 2);
  CHECK(r.output.find(".png or .svg") != std::string::npos);
  const auto r2 = pinsim_cli("render /nonexistent-run-dir/");
  CHECK(r2.code != 0);
}

namespace {

/// Chromium in headless mode with a fresh profile and no background network; "" if absent.
std::string chromium_command(const fs::path& profile) {
  const char* names[] = {"chromium", "chromium-browser", "google-chrome"};
  for (const char* n : names)
    if (shell(std::string("command -v ") + n + " >/dev/null").code == 0)
      return std::string(n) +
             " --headless --no-sandbox --disable-gpu --disable-quic --no-first-run"
             " --disable-background-networking --disable-component-update --disable-sync"
             " --hide-scrollbars --force-device-scale-factor=1 --virtual-time-budget=5000"
             " --user-data-dir=" +
             profile.string();
  return "";
}

}  // namespace

TEST_CASE(
    "replay: the page loads in headless Chromium and draws the ball where the trajectory "
    "says") {
  const fs::path run = make_run("replay-run");
  const fs::path page = run / "replay.html";
  auto r = pinsim_cli("-q replay " + run.string() + " " + kView + " --out " + page.string());
  REQUIRE(r.code == 0);
  const std::string html = test::read_file(page);
  CHECK(html.find("http://") == std::string::npos);  // self-contained: nothing to fetch
  CHECK(html.find("https://") == std::string::npos);
  CHECK(html.find("data:image/png;base64,") != std::string::npos);

  const std::string chrome = chromium_command(test::temp_dir("chromium-profile"));
  if (chrome.empty()) {
    WARN("SKIPPED: chromium is not installed (scripts/setup.sh installs it)");
    return;
  }
  // The ball at t = 0.5 s, a sample time of trajectory.csv (written every 10 steps).
  const RunData data = load_run(run);
  const Eigen::Vector2d at = data.position(0, 0.5);
  const Eigen::Vector2d start = data.position(0, 0.0);
  const std::string url = "'file://" + page.string() + "?t=0.5'";

  r = shell(chrome + " --enable-logging=stderr --v=0 --dump-dom " + url);
  INFO(r.output.substr(0, 4000));
  CHECK(r.output.find("data-status=\"ok\"") != std::string::npos);
  CHECK(r.output.find("data-t=\"0.500000\"") != std::string::npos);
  CHECK(r.output.find("Uncaught") == std::string::npos);
  CHECK(r.output.find(":CONSOLE(") == std::string::npos);  // no console messages at all

  const fs::path shot = run / "shot.png";
  r = shell(chrome + " --window-size=400,460 --screenshot=" + shot.string() + " " + url);
  INFO(r.output.substr(0, 4000));
  Png png(shot);
  REQUIRE(png.ok());
  CHECK(png.width() == 400);
  CHECK(png.is_red(px(at.x()), py(at.y())));
  CHECK(!png.is_red(px(start.x()), py(start.y())));  // no ball where it started
  CHECK(png.is_dark(px(0.5), py(0.3)));              // the background: the disc
}

TEST_CASE(
    "play: a window under Xvfb with scripted input, and its recording reruns to the same "
    "state hash") {
  if (shell("command -v xvfb-run >/dev/null").code != 0) {
    WARN("SKIPPED: xvfb-run is not installed (scripts/setup.sh installs xvfb)");
    return;
  }
  const fs::path dir = test::temp_dir("play");
  const std::string table = PINSIM_SOURCE_DIR "/configs/pinball.json";
  const std::string script = PINSIM_TEST_SOURCE_DIR "/framework/pictures/render/play_script.json";
  const fs::path rec = dir / "recording.json", shot = dir / "shot.png";
  auto r =
      shell(test::play_window_env() + "xvfb-run -a -s '-screen 0 1024x1280x24' " +
            std::string(PINSIM_BIN) + " play " + table + " --script " + script +
            " --seconds 3 --width 400 --record " + rec.string() + " --screenshot " + shot.string());
  INFO(r.output);
  REQUIRE(r.code == 0);
  const auto recording = nlohmann::json::parse(test::read_file(rec));
  CHECK(recording["steps"] == 15000);  // 3 s at dt = 0.0002 s
  CHECK(recording["inputs"].size() == 6);
  CHECK(recording["inputs"][1]["action"] == "release");
  CHECK(recording["inputs"][1]["step"] == 3000);  // t = 0.6 s

  // The screenshot is what the window showed: the table, and the ball where the game has it.
  Png png(shot);
  REQUIRE(png.ok());
  CHECK(png.width() == 400);
  CHECK(png.height() > 600);
  const double bx = recording["ball"][0], by = recording["ball"][1];
  // The window's mapping: the scene view (see `render`), 400 pixels across; recompute it.
  const Scene scene = load_scene(table);
  PluginLoader loader(plugin_search_dirs(scene.plugin_path));
  const Simulation sim(scene, loader);
  const PixelMap map(scene_view(scene, sim.backend()), 400);
  CHECK(png.height() == map.height);
  CHECK(png.is_red(static_cast<int>(map.px(bx)), static_cast<int>(map.py(by))));
  CHECK(png.is_dark(static_cast<int>(map.px(0.22)), static_cast<int>(map.py(0.72))));  // bumper

  // Rerunning the recording without a window reaches the identical state.
  r = pinsim_cli("play --rerun " + rec.string());
  INFO(r.output);
  CHECK(r.code == 0);
  CHECK(r.output.find(recording["state_hash"].get<std::string>()) != std::string::npos);
  CHECK(r.output.find("identical") != std::string::npos);

  // A changed recording does not (the check can fail); --replay is --rerun's other name.
  auto changed = recording;
  changed["inputs"][1]["step"] = 3500;  // the plunger released 0.1 s later
  test::write_file(dir / "changed.json", changed.dump());
  r = pinsim_cli("play --replay " + (dir / "changed.json").string());
  CHECK(r.code == 1);
}

TEST_CASE("play --record: a recording that cannot be written is exit 1, nothing left half") {
  // SDL's dummy video driver, not Xvfb: the window is not what this test is about, and two
  // `xvfb-run -a` started at the same moment (ctest -j) can pick the same display.
  // The recording goes to a temporary file beside it, renamed over it: renaming a file over
  // a folder fails (EISDIR), so the write fails after the game and leaves the folder as it
  // was and no temporary behind.
  const fs::path dir = test::temp_dir("play-record");
  const fs::path rec = dir / "recording.json";
  fs::create_directories(rec / "inside");
  const std::string script = PINSIM_TEST_SOURCE_DIR "/framework/pictures/render/play_script.json";
  const auto r = shell("SDL_VIDEODRIVER=dummy " + std::string(PINSIM_BIN) +
                       " play " PINSIM_SOURCE_DIR "/configs/pinball.json --script " + script +
                       " --seconds 0.2 --width 200 --record " + rec.string());
  INFO(r.output);
  CHECK(r.code == 1);
  CHECK_THAT(r.output.c_str(), Catch::Contains(rec.string() + ": cannot "));
  CHECK(fs::is_directory(rec / "inside"));
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.path() != rec;
  CHECK(files == 0);
}

TEST_CASE("play --script: an input the table does not have is exit 2 naming it") {
  // Once ignored: the game ran without that press. Read before any window opens.
  const fs::path dir = test::temp_dir("play-script-input");
  test::write_file(dir / "script.json",
                   R"([{"t": 0, "input": "left", "action": "press"},
                       {"t": 0.1, "input": "flipper", "action": "press"}])");
  const auto r = shell("SDL_VIDEODRIVER=dummy " + std::string(PINSIM_BIN) +
                       " play " PINSIM_SOURCE_DIR "/configs/pinball.json --script " +
                       (dir / "script.json").string() + " --seconds 0.2 --width 200");
  INFO(r.output);
  CHECK(r.code == 2);
  CHECK_THAT(r.output.c_str(),
             Catch::Contains((dir / "script.json").string() +
                             ": [1].input: unknown input 'flipper': this table's inputs are "
                             "'plunger', 'left', 'right'"));
}

TEST_CASE("render and replay: a folder that is not a readable run is exit 2 naming it") {
  const fs::path empty = test::temp_dir("not-a-run");
  auto r = pinsim_cli("render " + empty.string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output.c_str(),
             Catch::Contains(empty.string() + ": not a run folder (expected "
                                              "trajectory.csv or trajectory.h5 in it"));
  r = pinsim_cli("replay " + empty.string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output.c_str(),
             Catch::Contains(empty.string() + ": not a run folder (expected "
                                              "trajectory.csv or trajectory.h5 in it"));
  // A folder that does not exist is named as missing, not as a scene file or a bad folder.
  r = pinsim_cli("replay " + (empty / "gone").string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output.c_str(), Catch::Contains((empty / "gone").string() + ": no such run folder"));
  // A run folder whose trajectory.csv is cut off in a row: the file and line are named.
  const fs::path run = make_run("broken-run");
  test::write_file(run / "trajectory.csv", "t,particle,x,y,vx,vy\n0,0,0.5\n");
  for (const std::string cmd : {"render ", "replay "}) {
    r = pinsim_cli(cmd + run.string() + " " + kView + " --out " + (run / "x.png").string());
    CAPTURE(cmd);
    CHECK(r.code == 2);
    CHECK_THAT(r.output.c_str(), Catch::Contains(run.string() + ": cannot read the run folder: ") &&
                                     Catch::Contains("trajectory.csv:2: expected 6 numbers"));
  }
  // Particle indices out of place (hand-edited or damaged files): an index of 10^7 in a
  // three-row file once made render draw ten million empty paths for minutes and replay take
  // gigabytes; 1e300 was cast to an integer (undefined behaviour). Each row is named.
  const fs::path idx = make_run("bad-index");
  const std::vector<std::pair<std::string, std::string>> index_cases = {
      {"0,0,0.5,0.5,0,0\n0,9999999,0.5,0.5,0,0\n",
       "trajectory.csv:3: particle index 9999999: expected an integer from 0 to 1 (each frame "
       "lists the particles 0, 1, 2, ... in order)"},
      {"0,1e300,0.5,0.5,0,0\n", "trajectory.csv:2: particle index 1e+300: expected an integer"},
      {"0,-1,0.5,0.5,0,0\n", "trajectory.csv:2: particle index -1: expected an integer"},
      {"0,0.5,0.5,0.5,0,0\n", "trajectory.csv:2: particle index 0.5: expected an integer"},
      {"0,nan,0.5,0.5,0,0\n", "trajectory.csv:2: particle index nan: expected an integer"}};
  for (const auto& [rows, message] : index_cases) {
    test::write_file(idx / "trajectory.csv", "t,particle,x,y,vx,vy\n" + rows);
    for (const std::string cmd : {"render ", "replay "}) {
      r = pinsim_cli(cmd + idx.string() + " " + kView + " --out " + (idx / "x.html").string());
      CAPTURE(cmd, rows);
      CHECK(r.code == 2);
      CHECK_THAT(r.output.c_str(),
                 Catch::Contains(idx.string() + ": cannot read the run folder: ") &&
                     Catch::Contains(message));
    }
  }
  // The same in events.csv: a contact of a particle the trajectory does not have.
  test::write_file(idx / "trajectory.csv", "t,particle,x,y,vx,vy\n0,0,0.5,0.5,0,0\n");
  const std::string header = "t,particle,obstacle,other_particle,x,y,nx,ny,vn_before,vn_after\n";
  for (const auto& [row, message] : std::vector<std::pair<std::string, std::string>>{
           {"0.1,1e300,floor,,0.5,0,0,1,-1,1\n",
            "events.csv:2: field 2: particle index 1e+300: expected one of the trajectory's 1 "
            "particles, an integer below 1"},
           {"0.1,0,,3,0.5,0,0,1,-1,1\n", "events.csv:2: field 4: particle index 3: expected"}}) {
    test::write_file(idx / "events.csv", header + row);
    r = pinsim_cli("render " + idx.string() + " " + kView + " --out " + (idx / "x.png").string());
    CAPTURE(row);
    CHECK(r.code == 2);
    CHECK_THAT(r.output.c_str(), Catch::Contains(message));
  }
  // ... and a well-formed pair of files is drawn.
  test::write_file(idx / "events.csv", header + "0.1,0,,0,0.5,0,0,1,-1,1\n");
  CHECK(pinsim_cli("-q render " + idx.string() + " " + kView + " --out " + (idx / "x.png").string())
            .code == 0);

  // A summary.json nested 100,000 deep (once a stack overflow): refused while parsing.
  const fs::path deep = make_run("deep-summary");
  test::write_file(deep / "summary.json", std::string(100000, '[') + std::string(100000, ']'));
  r = pinsim_cli("render " + deep.string() + " " + kView + " --out " + (deep / "x.png").string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output.c_str(),
             Catch::Contains((deep / "summary.json").string() + ": ") &&
                 Catch::Contains("nested deeper than 256 levels of arrays and objects"));
  r = pinsim_cli("render " + kScene + " --view 1,1,0,0");
  CHECK(r.code == 2);
  CHECK_THAT(r.output.c_str(), Catch::Contains("--view: expected x0,y0,x1,y1"));
}

TEST_CASE("play --rerun: a recording that cannot be used is exit 2 naming the file and path") {
  const fs::path dir = test::temp_dir("bad-recording");
  const std::string table = PINSIM_SOURCE_DIR "/configs/pinball.json";
  auto r = pinsim_cli("play --rerun " + (dir / "missing.json").string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output.c_str(),
             Catch::Contains("--rerun " + (dir / "missing.json").string() +
                             ": cannot be read (expected a recording written by play --record)"));
  test::write_file(dir / "cut.json", "{\"steps\": 10,");
  r = pinsim_cli("play --rerun " + (dir / "cut.json").string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output.c_str(), Catch::Contains((dir / "cut.json").string() + ":1:"));
  const nlohmann::json good = {{"scene", table},
                               {"steps", 10},
                               {"state_hash", "0"},
                               {"inputs", {{{"step", 0}, {"input", "left"}, {"action", "press"}}}}};
  const std::vector<std::pair<std::function<void(nlohmann::json&)>, std::string>> cases = {
      {[](nlohmann::json& j) { j["inputs"][0]["action"] = "hold"; },
       "rec.json: inputs[0].action: expected \"press\" or \"release\", got string \"hold\""},
      {[](nlohmann::json& j) { j["inputs"][0]["step"] = -1; },
       "rec.json: inputs[0].step: expected a non-negative integer, got number -1"},
      {[](nlohmann::json& j) { j.erase("steps"); }, "rec.json: steps: required step count"},
      {[](nlohmann::json& j) { j["inputs"] = 3; }, "rec.json: inputs: expected a list of inputs"},
      {[](nlohmann::json& j) { j.erase("scene"); }, "rec.json: scene: required scene file"},
      // Inputs a rerun would skip or apply late, silently: an input the table lacks, a step
      // past the recording's end, steps out of order.
      {[](nlohmann::json& j) { j["inputs"][0]["input"] = "lefft"; },
       "rec.json: inputs[0].input: unknown input 'lefft': this table's inputs are 'plunger', "
       "'left', 'right'"},
      {[](nlohmann::json& j) { j["inputs"][0]["step"] = 11; },
       "rec.json: inputs[0].step: step 11 is after the recording's 10 steps"},
      {[](nlohmann::json& j) {
         j["inputs"][0]["step"] = 5;
         j["inputs"].push_back({{"step", 4}, {"input", "left"}, {"action", "release"}});
       },
       "rec.json: inputs[1].step: step 4 comes before the previous input's 5 (inputs are in "
       "step order)"}};
  for (const auto& [change, message] : cases) {
    nlohmann::json rec = good;
    change(rec);
    test::write_file(dir / "rec.json", rec.dump());
    r = pinsim_cli("play --rerun " + (dir / "rec.json").string());
    CAPTURE(rec.dump());
    CHECK(r.code == 2);
    CHECK_THAT(r.output.c_str(), Catch::Contains(message));
  }
  // An edited step count of 10^18 (once a rerun that never ended: the ball rests in the
  // plunger lane and never drains) is refused past a day of play, 86400 s / 0.0002 s steps.
  nlohmann::json endless = good;
  endless["steps"] = 1000000000000000000ull;
  test::write_file(dir / "rec.json", endless.dump());
  r = pinsim_cli("play --rerun " + (dir / "rec.json").string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output.c_str(),
             Catch::Contains("rec.json: steps: 1000000000000000000 steps of dt = 0.0002 s are "
                             "2e+14 s of play, more than the limit of 86400 s (24 hours)"));
  endless["steps"] = 432000001;  // one step past the limit
  test::write_file(dir / "rec.json", endless.dump());
  CHECK(pinsim_cli("play --rerun " + (dir / "rec.json").string()).code == 2);
  // The good one reruns (its made-up hash differs: exit 1), also under the option's other name.
  test::write_file(dir / "rec.json", good.dump());
  CHECK(pinsim_cli("play --replay " + (dir / "rec.json").string()).code == 1);
}
