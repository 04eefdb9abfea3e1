// The engine of `pinsim share`'s page: the framework's Simulation, the scene's integrator,
// the built-in backend and force plugins and the PinballGame rules, compiled to WebAssembly.
// A small C API for the page's JavaScript (share_template.html): strings cross as UTF-8
// C strings owned here, valid until the next call. Every entry point catches: an error is
// a nonzero return and pinsim_web_error()'s text, never an abort.
#include <emscripten/emscripten.h>
#include <fmt/format.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "core/json_read.hpp"
#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "core/static_plugins.hpp"
#include "pictures/play_game.hpp"
#include "pictures/render_data.hpp"

namespace {
using nlohmann::json;
using pinsim::PinballGame;

/// The most play a page reruns, s: an hour (1.8e7 steps of the table's 0.2 ms, minutes of
/// the tab's time); a longer recording is refused, not run for hours.
constexpr double kWebRerunSeconds = 3600.0;

struct Engine {
  std::unique_ptr<pinsim::Scene> scene;
  std::string scene_file;  ///< the name `share` was given, written into recordings
  std::unique_ptr<pinsim::PluginLoader> loader;
  std::unique_ptr<PinballGame> game;
  std::string error;
  std::string text;  ///< the last string returned
};
Engine& engine() {
  static Engine e;
  return e;
}

const char* give(std::string s) {
  engine().text = std::move(s);
  return engine().text.c_str();
}

template <class F>
int guarded(F&& f) {
  try {
    f();
    return 0;
  } catch (const std::exception& e) {
    engine().error = e.what();
  } catch (...) {
    engine().error = "unknown error";
  }
  return 1;
}

PinballGame& game() {
  if (!engine().game) throw std::runtime_error("no scene loaded");
  return *engine().game;
}
}  // namespace

extern "C" {

/// Parses the scene (its text; `file` names it in messages and recordings) and starts a game.
EMSCRIPTEN_KEEPALIVE int pinsim_web_load(const char* scene_text, const char* file) {
  return guarded([&] {
    Engine& e = engine();
    e.game.reset();
    e.scene_file = file;
    e.scene = std::make_unique<pinsim::Scene>(pinsim::parse_scene(scene_text, file, "/"));
    e.loader = std::make_unique<pinsim::PluginLoader>(std::vector<std::filesystem::path>{});
    e.game = std::make_unique<PinballGame>(*e.scene, *e.loader);
  });
}

/// A new game on the loaded scene (score 0, three balls, the ball on the plunger).
EMSCRIPTEN_KEEPALIVE int pinsim_web_new_game() {
  return guarded([&] {
    Engine& e = engine();
    if (!e.scene) throw std::runtime_error("no scene loaded");
    e.game = std::make_unique<PinballGame>(*e.scene, *e.loader);
  });
}

EMSCRIPTEN_KEEPALIVE const char* pinsim_web_error() { return engine().error.c_str(); }

/// Names of the scene's inputs, as a JSON array.
EMSCRIPTEN_KEEPALIVE const char* pinsim_web_inputs() {
  json a = json::array();
  if (engine().game) a = game().input_names();
  return give(a.dump());
}

EMSCRIPTEN_KEEPALIVE int pinsim_web_set_input(const char* name, int pressed) {
  return guarded([&] { game().set_input(name, pressed != 0); });
}

/// n steps of the scene's dt (fewer if the game ends).
EMSCRIPTEN_KEEPALIVE int pinsim_web_step(int n) {
  return guarded([&] {
    PinballGame& g = game();
    for (int i = 0; i < n && !g.game_over(); ++i) g.step();
  });
}

EMSCRIPTEN_KEEPALIVE double pinsim_web_dt() { return engine().game ? game().dt() : 0.0; }

/// The game's state: {"steps","t","score","balls_left","game_over","message","state_hash"}.
EMSCRIPTEN_KEEPALIVE const char* pinsim_web_status() {
  if (!engine().game) return give("{}");
  const PinballGame& g = game();
  const double t = g.state().t;
  return give(json{{"steps", g.steps()},
                   {"t", t},
                   {"score", g.score()},
                   {"balls_left", g.balls_left()},
                   {"game_over", g.game_over()},
                   {"message", t < g.message_until() ? g.message() : std::string()},
                   {"state_hash", fmt::format("{:016x}", g.state().hash())}}
                  .dump());
}

/// What moves, for drawing: {"particles": [[x, y, r], ...], "moving": [[x0, y0, x1, y1, ...]
/// per ring of every obstacle with a motion]} (scene units).
EMSCRIPTEN_KEEPALIVE const char* pinsim_web_frame() {
  if (!engine().game) return give("{}");
  const PinballGame& g = game();
  const pinsim::State& s = g.state();
  json parts = json::array();
  for (Eigen::Index i = 0; i < s.x.cols(); ++i)
    parts.push_back({s.x(0, i), s.x(1, i), s.radius[i]});
  json moving = json::array();
  const json& bs = g.scene().backend_scene;
  const json& obs = bs.contains("obstacles") ? bs["obstacles"] : json::array();
  if (g.backend().has_outline())
    for (const auto& o : g.backend().outline(s, 0.0).obstacles) {
      const auto k = static_cast<std::size_t>(o.index);
      if (k >= obs.size() || !obs[k].contains("motion")) continue;
      for (const auto& ring : o.rings) {
        json r = json::array();
        for (const auto& p : ring) {
          r.push_back(p.x());
          r.push_back(p.y());
        }
        moving.push_back(std::move(r));
      }
    }
  return give(json{{"particles", parts}, {"moving", moving}}.dump());
}

/// The view the background picture was drawn for: [x0, y0, x1, y1] (scene units).
EMSCRIPTEN_KEEPALIVE const char* pinsim_web_view() {
  if (!engine().game) return give("[]");
  const pinsim::ViewBox v = pinsim::scene_view(game().scene(), game().backend());
  return give(json{v.x0, v.y0, v.x1, v.y1}.dump());
}

/// The game so far as `pinsim play --record` writes it.
EMSCRIPTEN_KEEPALIVE const char* pinsim_web_recording() {
  if (!engine().game) return give("{}");
  return give(game().recording(engine().scene_file).dump(2));
}

/// A new game, then a recording's inputs rerun (as `pinsim play --rerun`).
EMSCRIPTEN_KEEPALIVE int pinsim_web_rerun(const char* recording) {
  return guarded([&] {
    // parse_json_text: nesting limited while parsing (a deep file would overflow the wasm
    // stack in anything recursive), duplicate keys refused
    const json rec = pinsim::parse_json_text(recording, "recording");
    Engine& e = engine();
    if (!e.scene) throw std::runtime_error("no scene loaded");
    e.game = std::make_unique<PinballGame>(*e.scene, *e.loader);
    e.game->rerun(rec, "recording", kWebRerunSeconds);
  });
}

/// The plugins linked in, as a JSON array of names.
EMSCRIPTEN_KEEPALIVE const char* pinsim_web_plugins() {
  json a = json::array();
  for (const auto& p : pinsim::static_plugins()) a.push_back(p.name);
  return give(a.dump());
}

}  // extern "C"
