#include "pictures/play_game.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

#include "pictures/render_data.hpp"
#include "pictures/render_field.hpp"

namespace pinsim {
using nlohmann::json;

namespace {
void emit_event(void* ctx, const pinsim_event* e) {
  static_cast<std::vector<pinsim_event>*>(ctx)->push_back(*e);
}
}  // namespace

PinballGame::PinballGame(const Scene& scene, PluginLoader& loader, GameRules rules)
    : scene_(scene), loader_(loader), rules_(rules) {
  scene_.backend_scene.erase("inputs");
  sim_ = std::make_unique<Simulation>(scene_, loader_);
  state_ = scene_.initial_state();
  initial_ = state_;
  balls_left_ = rules_.balls;
  if (scene_.backend_scene.contains("obstacles"))
    for (const auto& o : scene_.backend_scene["obstacles"])
      if (o.contains("motion") && o["motion"].contains("input")) {
        const std::string n = o["motion"]["input"];
        if (std::find(input_names_.begin(), input_names_.end(), n) == input_names_.end())
          input_names_.push_back(n);
      }
  pressed_.assign(input_names_.size(), false);
  table_ = obstacles_view(scene_.backend_scene);
  rebuild_backend();
}

void PinballGame::rebuild_backend() {
  json bs = scene_.backend_scene;
  if (!inputs_.empty()) bs["inputs"] = inputs_;
  backend_ = make_backend(scene_, loader_, bs);
}

void PinballGame::set_input(const std::string& input, bool pressed) {
  const auto it = std::find(input_names_.begin(), input_names_.end(), input);
  if (it == input_names_.end()) return;
  const auto k = static_cast<std::size_t>(it - input_names_.begin());
  if (pressed_[k] == pressed || game_over_) return;
  pressed_[k] = pressed;
  recorded_.push_back({steps_, input, pressed});
  // Takes effect at the start of the next step, i.e. at the current time.
  inputs_.push_back({{"t", state_.t}, {"input", input}, {"action", pressed ? "press" : "release"}});
  rebuild_backend();
}

void PinballGame::serve_ball() {
  for (Eigen::Index i = 0; i < state_.x.cols(); ++i) {
    state_.x.col(i) = initial_.x.col(i);
    state_.v.col(i) = initial_.v.col(i);
  }
  served_at_ = state_.t;
}

void PinballGame::step() {
  if (game_over_) return;
  const double h = scene_.dt;
  sim_->compute_forces(state_, f_);
  for (Eigen::Index i = 0; i < state_.x.cols(); ++i)
    state_.v.col(i) += (h * state_.inv_mass[i]) * f_.col(i);
  events_.clear();
  const pinsim_event_sink sink{&events_, &emit_event};
  backend_->advance(state_, h, &sink);
  ++steps_;
  state_.t = static_cast<double>(steps_) * h;

  // Score, and drains: a contact with the "drain" obstacle, or the ball off the table.
  bool drained = false;
  const json& obs = scene_.backend_scene.contains("obstacles") ? scene_.backend_scene["obstacles"]
                                                               : json::array();
  for (const auto& e : events_) {
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
  for (Eigen::Index i = 0; i < state_.x.cols(); ++i)
    if (!table.empty() &&
        (state_.x(1, i) < table.y0 - 0.05 * (table.y1 - table.y0) || !state_.x.col(i).allFinite()))
      drained = true;
  if (!drained) return;
  if (state_.t - served_at_ < rules_.ball_save_s) {
    message_ = "BALL SAVED";
  } else if (--balls_left_ <= 0) {
    game_over_ = true;
    message_ = "GAME OVER";
    message_until_ = HUGE_VAL;
    return;
  } else {
    message_ = fmt::format("BALL {}", rules_.balls - balls_left_ + 1);
  }
  message_until_ = state_.t + 2.0;
  serve_ball();
}

json PinballGame::recording(const std::string& scene_file) const {
  json in = json::array();
  for (const auto& r : recorded_)
    in.push_back({{"step", r.step}, {"input", r.input}, {"action", r.press ? "press" : "release"}});
  json ball = json::array();
  if (state_.x.cols() > 0) ball = {state_.x(0, 0), state_.x(1, 0)};
  return {{"scene", scene_file},
          {"dt", scene_.dt},
          {"steps", steps_},
          {"inputs", in},
          {"state_hash", fmt::format("{:016x}", state_.hash())},
          {"score", score_},
          {"balls_left", balls_left_},
          {"game_over", game_over_},
          {"ball", ball}};
}

void PinballGame::replay(const json& rec) {
  const uint64_t n = rec.at("steps").get<uint64_t>();
  const json& in = rec.at("inputs");
  std::size_t k = 0;
  while (steps_ < n) {
    while (k < in.size() && in[k].at("step").get<uint64_t>() <= steps_) {
      set_input(in[k].at("input").get<std::string>(), in[k].at("action") == "press");
      ++k;
    }
    if (game_over_) break;
    step();
  }
}

}  // namespace pinsim
