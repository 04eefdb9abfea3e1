// The pinball game behind `pinsim play`: physics at the scene's dt with live inputs, score,
// ball save, game over, and an input recording that reruns to the identical state.
// No window code here (that is cli/cmd_play.cpp, with SDL2).
#pragma once

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/json_read.hpp"
#include "core/plugin_instance.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "pictures/render_data.hpp"

namespace pinsim {

/// The most game time a recording may rerun, s: a day of play (4.3e8 steps of the table's
/// 0.2 ms, about 2.5 h to rerun here); an edited "steps" of 1e18 would otherwise run for ever.
inline constexpr double kMaxRerunSeconds = 86400.0;
/// And at most this many steps whatever the scene's dt (a day of the table's 0.2 ms steps).
inline constexpr uint64_t kMaxRerunSteps = 432000000;

/// "press" or "release" in entry's "action" at `at`; InputError otherwise.
bool read_action(const nlohmann::json& entry, const Loc& at);

/// Refuses an input name the table does not have (a typo would otherwise be ignored, and
/// the game run without that press), naming the table's inputs.
void check_input_name(const std::string& input, const Loc& at,
                      const std::vector<std::string>& names);

/// Checks a recording's form (`play --record`'s JSON: "scene", "steps", "state_hash",
/// "inputs" [{"step", "input", "action"}]); InputError naming `file` and the JSON path of the
/// first problem. `scene_given`: the scene comes from elsewhere, "scene" may be absent.
void check_recording(const nlohmann::json& rec, const std::string& file, bool scene_given);

/// Rules; defaults suit configs/pinball.json.
struct GameRules {
  int balls = 3;              ///< balls per game
  double ball_save_s = 10.0;  ///< a ball drained this soon after it was served comes back free
  int bumper_points = 100;    ///< per contact with an obstacle whose id contains "bumper"
  int sling_points = 10;      ///< ... "sling"
  int kick_points = 25;       ///< ... any other obstacle with a kick
};

/// One recorded input: applied before step `step` (counting from 0).
struct GameInput {
  uint64_t step;
  std::string input;
  bool press;
};

class PinballGame {
 public:
  /// The scene's own scripted inputs are dropped: the player drives the inputs.
  PinballGame(const Scene& scene, PluginLoader& loader, GameRules rules = {});

  /// Presses or releases a named input (a flipper, the plunger) before the next step, through
  /// Simulation::set_input (the backend's timeline grows; nothing is rebuilt). Repeats of
  /// the current state are ignored (and not recorded).
  void set_input(const std::string& input, bool pressed);
  /// One Simulation::step (the scene's integrator, its NaN and energy checks), then the
  /// rules on its events: score, drain, ball save, game over. Does nothing after game over.
  void step();

  const State& state() const { return sim_->state(); }
  uint64_t steps() const { return sim_->step_index(); }
  double dt() const { return scene_.dt; }
  int score() const { return score_; }
  int balls_left() const { return balls_left_; }
  bool game_over() const { return game_over_; }
  /// A short message to show ("BALL SAVED", "GAME OVER", ...) and until when (sim time).
  const std::string& message() const { return message_; }
  double message_until() const { return message_until_; }
  /// Names of the scene's inputs (from the moving obstacles).
  const std::vector<std::string>& input_names() const { return input_names_; }
  const BackendInstance& backend() const { return sim_->backend(); }
  const Scene& scene() const { return scene_; }

  /// {"scene", "dt", "steps", "inputs": [{"step","input","action"}], "state_hash", "score",
  ///  "balls_left", "game_over", "ball": [x, y]}
  nlohmann::json recording(const std::string& scene_file) const;
  /// Reruns a recording's inputs for its number of steps (the scene must be the same).
  /// First refuses (InputError naming `file` and the JSON path) what a rerun could not use
  /// or would get silently wrong: a malformed recording (check_recording), an input the
  /// table lacks, inputs out of step order or after the last step, and more than
  /// max_seconds of play or kMaxRerunSteps steps (an edited step count would run for ever).
  /// `pinsim play
  /// --rerun` and the web page's rerun both come here.
  /// `max_seconds`: the web page passes less than a day (its tab would freeze for hours).
  void rerun(const nlohmann::json& recording, const std::string& file = "recording",
             double max_seconds = kMaxRerunSeconds);

 private:
  void serve_ball();

  Scene scene_;
  GameRules rules_;
  std::unique_ptr<Simulation> sim_;  ///< the one step path: forces, integrator, backend
  State initial_;
  std::vector<GameInput> recorded_;
  std::vector<std::string> input_names_;
  std::vector<bool> pressed_;
  ViewBox table_;  ///< the obstacles' bounds (from the backend): below it the ball has drained
  int score_ = 0;
  int balls_left_ = 0;
  bool game_over_ = false;
  double served_at_ = 0.0;
  std::string message_;
  double message_until_ = 0.0;
};

}  // namespace pinsim
