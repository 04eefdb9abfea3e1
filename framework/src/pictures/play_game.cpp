#include "pictures/play_game.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

#include "core/format.hpp"
#include "core/input_error.hpp"
#include "pictures/render_data.hpp"

namespace pinsim {
using nlohmann::json;

PinballGame::PinballGame(const Scene& scene, PluginLoader& loader, GameRules rules)
    : scene_(scene), rules_(rules) {
  scene_.backend_scene.erase("inputs");
  sim_ = std::make_unique<Simulation>(scene_, loader);
  initial_ = sim_->state();
  balls_left_ = rules_.balls;
  if (scene_.backend_scene.contains("obstacles"))
    for (const auto& o : scene_.backend_scene["obstacles"])
      if (o.contains("motion") && o["motion"].contains("input")) {
        const std::string n = o["motion"]["input"];
        if (std::find(input_names_.begin(), input_names_.end(), n) == input_names_.end())
          input_names_.push_back(n);
      }
  pressed_.assign(input_names_.size(), false);
  table_ = obstacles_view(sim_->backend(), initial_);
  if (!input_names_.empty() && !sim_->backend().has_input())
    throw PluginError(scene_.label + ": backend '" + sim_->backend().plugin().name() +
                      "' does not take live inputs (PINSIM_CAP_INPUTS), so it cannot be played");
}

void PinballGame::set_input(const std::string& input, bool pressed) {
  const auto it = std::find(input_names_.begin(), input_names_.end(), input);
  if (it == input_names_.end()) return;
  const auto k = static_cast<std::size_t>(it - input_names_.begin());
  if (pressed_[k] == pressed || game_over_) return;
  pressed_[k] = pressed;
  recorded_.push_back({steps(), input, pressed});
  // Takes effect at the start of the next step, i.e. at the current time.
  sim_->set_input(input, pressed);
}

void PinballGame::serve_ball() {
  State& s = sim_->state();
  for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
    s.x.col(i) = initial_.x.col(i);
    s.v.col(i) = initial_.v.col(i);
  }
  served_at_ = s.t;
}

void PinballGame::step() {
  if (game_over_) return;
  sim_->step();
  const State& state = sim_->state();

  // Score, and drains: a contact with the "drain" obstacle, or the ball off the table.
  bool drained = false;
  const json& obs = scene_.backend_scene.contains("obstacles") ? scene_.backend_scene["obstacles"]
                                                               : json::array();
  for (const auto& e : sim_->events()) {
    if (e.obstacle < 0 || static_cast<std::size_t>(e.obstacle) >= obs.size()) continue;
    const std::string id = scene_.obstacle_id(e.obstacle);
    const json& o = obs[static_cast<std::size_t>(e.obstacle)];
    const double kick = o.contains("material") ? o["material"].value("kick", 0.0) : 0.0;
    if (id.find("drain") != std::string::npos)
      drained = true;
    else if (id.find("bumper") != std::string::npos)
      score_ += rules_.bumper_points;
    else if (id.find("sling") != std::string::npos)
      score_ += rules_.sling_points;
    else if (kick > 0)
      score_ += rules_.kick_points;
  }
  const ViewBox& table = table_;
  for (Eigen::Index i = 0; i < state.x.cols(); ++i)
    if (!table.empty() &&
        (state.x(1, i) < table.y0 - 0.05 * (table.y1 - table.y0) || !state.x.col(i).allFinite()))
      drained = true;
  if (!drained) return;
  if (state.t - served_at_ < rules_.ball_save_s) {
    message_ = "BALL SAVED";
  } else if (--balls_left_ <= 0) {
    game_over_ = true;
    message_ = "GAME OVER";
    message_until_ = HUGE_VAL;
    return;
  } else {
    message_ = fmt::format("BALL {}", rules_.balls - balls_left_ + 1);
  }
  message_until_ = state.t + 2.0;
  serve_ball();
}

json PinballGame::recording(const std::string& scene_file) const {
  json in = json::array();
  for (const auto& r : recorded_)
    in.push_back({{"step", r.step}, {"input", r.input}, {"action", r.press ? "press" : "release"}});
  const State& state = sim_->state();
  json ball = json::array();
  if (state.x.cols() > 0) ball = {state.x(0, 0), state.x(1, 0)};
  return {{"scene", scene_file},
          {"dt", scene_.dt},
          {"steps", steps()},
          {"inputs", in},
          {"state_hash", fmt::format("{:016x}", state.hash())},
          {"score", score_},
          {"balls_left", balls_left_},
          {"game_over", game_over_},
          {"ball", ball}};
}

bool read_action(const json& entry, const Loc& at) {
  const std::string a = read_string_or(entry, "action", "", at);
  if (a != "press" && a != "release")
    (at / "action")
        .fail("expected \"press\" or \"release\", " + describe(entry.value("action", json())));
  return a == "press";
}

void check_input_name(const std::string& input, const Loc& at,
                      const std::vector<std::string>& names) {
  if (std::find(names.begin(), names.end(), input) != names.end()) return;
  std::string list;
  for (const std::string& n : names) list += (list.empty() ? "'" : ", '") + n + "'";
  at.fail("unknown input '" + input + "': this table's inputs are " +
          (list.empty() ? std::string("none") : list));
}

void check_recording(const json& rec, const std::string& file, bool scene_given) {
  const Loc root{file, ""};
  require_object(rec, root);
  read_string_or(rec, "scene", "", root);  // "": the embedded default scene
  if (!scene_given && !rec.contains("scene"))
    (root / "scene").fail("required scene file is missing (or give SCENE on the command line)");
  if (!rec.contains("steps")) (root / "steps").fail("required step count is missing");
  read_count_or(rec, "steps", 0, root);
  if (read_string_or(rec, "state_hash", "", root).empty())
    (root / "state_hash").fail("required state hash is missing");
  if (!rec.contains("inputs") || !rec["inputs"].is_array())
    (root / "inputs").fail("expected a list of inputs, " + describe(rec.value("inputs", json())));
  const json& in = rec["inputs"];
  for (std::size_t i = 0; i < in.size(); ++i) {
    const Loc at = (root / "inputs")[i];
    require_object(in[i], at);
    if (!in[i].contains("step")) (at / "step").fail("required step number is missing");
    read_count_or(in[i], "step", 0, at);
    if (read_string_or(in[i], "input", "", at).empty())
      (at / "input").fail("required input name is missing");
    read_action(in[i], at);
  }
}

void PinballGame::rerun(const json& rec, const std::string& file, double max_seconds) {
  check_recording(rec, file, true);
  const Loc root{file, ""};
  const uint64_t n = rec.at("steps").get<uint64_t>();
  const double seconds = static_cast<double>(n) * scene_.dt;
  if (!(seconds <= max_seconds))
    (root / "steps")
        .fail(std::to_string(n) + " steps of dt = " + num(scene_.dt) + " s are " + num(seconds) +
              " s of play, more than the limit of " + num(max_seconds) + " s" +
              (max_seconds == 86400.0 ? " (24 hours)" : ""));
  if (n > kMaxRerunSteps)
    (root / "steps")
        .fail(std::to_string(n) + " steps are more than the limit of " +
              std::to_string(kMaxRerunSteps) + " steps");
  // Each input one of the table's, in step order, within the recording's steps: anything
  // else would be skipped or applied late by the rerun, silently.
  const json& in = rec.at("inputs");
  for (std::size_t i = 0; i < in.size(); ++i) {
    const Loc at = (root / "inputs")[i];
    check_input_name(in[i].at("input").get<std::string>(), at / "input", input_names_);
    const uint64_t step = in[i].at("step").get<uint64_t>();
    if (step > n)
      (at / "step")
          .fail("step " + std::to_string(step) + " is after the recording's " + std::to_string(n) +
                " steps");
    if (i > 0 && step < in[i - 1].at("step").get<uint64_t>())
      (at / "step")
          .fail("step " + std::to_string(step) + " comes before the previous input's " +
                std::to_string(in[i - 1].at("step").get<uint64_t>()) +
                " (inputs are in step order)");
  }
  std::size_t k = 0;
  while (steps() < n) {
    while (k < in.size() && in[k].at("step").get<uint64_t>() <= steps()) {
      set_input(in[k].at("input").get<std::string>(), in[k].at("action") == "press");
      ++k;
    }
    if (game_over_) break;
    step();
  }
}

}  // namespace pinsim
