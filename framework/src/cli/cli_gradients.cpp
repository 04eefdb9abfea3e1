#include "cli_gradients.hpp"

#include <charconv>
#include <map>

#include "cli_common.hpp"
#include "core/format.hpp"
#include "core/input_error.hpp"

namespace pinsim::cli {

grad::RecordedFrames recorded_frames(const std::filesystem::path& dir, double dt) {
  const RunData run = read_run_folder(dir);
  grad::RecordedFrames f;
  f.source = dir.string();
  // frames by step: positions of the particles recorded then
  std::map<uint64_t, std::vector<std::pair<std::size_t, Eigen::Vector2d>>> by_step;
  for (std::size_t i = 0; i < run.particles.size(); ++i)
    for (const TrajSample& s : run.particles[i]) {
      const int64_t k = grad::step_of_time(s.t, dt);
      if (k < 0)
        throw InputError(dir.string() + ": particle " + std::to_string(i) +
                         " at t = " + num(s.t, 17) +
                         " s: not a step time of the scene (dt = " + num(dt) + " s)");
      by_step[static_cast<uint64_t>(k)].emplace_back(i, Eigen::Vector2d(s.x, s.y));
    }
  for (const auto& [step, list] : by_step) {
    Eigen::Matrix2Xd x = Eigen::Matrix2Xd::Zero(2, static_cast<Eigen::Index>(run.particles.size()));
    std::vector<bool> present(run.particles.size(), false);
    for (const auto& [i, p] : list) {
      x.col(static_cast<Eigen::Index>(i)) = p;
      present[i] = true;
    }
    f.steps.push_back(step);
    f.x.push_back(std::move(x));
    f.present.push_back(std::move(present));
  }
  if (f.steps.empty()) throw InputError(dir.string() + ": the run folder holds no frames");
  return f;
}

grad::LossFactory loss_factory(const std::string& spec) {
  if (spec.rfind("misfit:", 0) == 0) {
    const std::filesystem::path dir = spec.substr(7);
    if (dir.empty()) throw InputError("--loss " + spec + ": expected misfit:RUN_FOLDER");
    return [dir](const grad::LossContext& ctx) {
      return grad::make_misfit(recorded_frames(dir, ctx.dt), ctx);
    };
  }
  return [spec](const grad::LossContext& ctx) { return grad::parse_loss(spec, ctx); };
}

std::string assignment(const std::string& path, const std::vector<double>& value) {
  auto text = [](double v) {
    char buf[32];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, r.ptr);
  };
  if (value.size() == 1) return path + "=" + text(value[0]);
  std::string out = path + "=[";
  for (std::size_t c = 0; c < value.size(); ++c) {
    if (c > 0) out += ',';
    out += text(value[c]);
  }
  out += ']';
  return out;
}

}  // namespace pinsim::cli
