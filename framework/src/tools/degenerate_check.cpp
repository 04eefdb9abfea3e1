// check-plugin's degenerate-state check: finite force, energy and Jacobians where a plugin
// divides by a length or an angle that vanishes.
#include <string>
#include <utility>
#include <vector>

#include "tools/plugin_checker.hpp"

namespace pinsim::plugin_check {

CheckResult Checker::degenerate_check() {
  CheckResult r{"degenerate",
                "finite f, E and Jacobians on coincident particles, zero-length edge, "
                "straight and fully folded strands",
                CheckStatus::Pass,
                0.0,
                0.0,
                ""};
  const Sample base = random_state();
  std::vector<std::pair<std::string, Sample>> states;
  {
    Sample s = base;  // every particle at one point
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) s.x.col(i) = base.x.col(0);
    states.emplace_back("coincident particles", s);
  }
  {
    Sample s = base;  // first edge of zero length
    s.x.col(1) = s.x.col(0);
    states.emplace_back("zero-length edge", s);
  }
  {
    Sample s = base;  // evenly spaced on a line
    const Vector2d d(std::cos(0.7), std::sin(0.7));
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) s.x.col(i) = base.x.col(0) + 0.3 * i * d;
    states.emplace_back("straight strand", s);
  }
  {
    Sample s = base;  // p_{i+2} = p_i: every joint folded back completely
    for (Eigen::Index i = 0; i < s.x.cols(); ++i)
      s.x.col(i) = base.x.col(0) + (i % 2 == 0 ? Vector2d::Zero() : Vector2d(0.3, 0.1));
    states.emplace_back("fully folded strand", s);
  }
  int bad_total = 0;
  auto count_bad = [](const auto& m) {
    int c = 0;
    for (Eigen::Index i = 0; i < m.size(); ++i) c += std::isfinite(m.data()[i]) ? 0 : 1;
    return c;
  };
  const Sample other = rest_state();
  for (const auto& [init_name, init] : states) {
    // Once as the evaluated state of an instance made from a random initial state, once as
    // the initial state itself (rest lengths and angles taken from a degenerate shape).
    for (int as_initial = 0; as_initial < 2; ++as_initial) {
      const std::string label = as_initial ? init_name + " as the initial state" : init_name;
      try {
        auto inst = make(as_initial ? init : other);
        for (const Sample* s : {&init, &other}) {
          if (!as_initial && s == &other) continue;
          int bad = count_bad(inst->force(*s));
          if (inst->has(PINSIM_CAP_ENERGY)) bad += std::isfinite(inst->energy(*s)) ? 0 : 1;
          if (t_->force.add_jacobians != nullptr) {
            if (inst->has(PINSIM_CAP_DFDX)) bad += count_bad(inst->jacobian(*s, 0));
            if (inst->has(PINSIM_CAP_DFDV)) bad += count_bad(inst->jacobian(*s, 1));
          }
          if (bad > 0) {
            r.status = CheckStatus::Fail;
            if (bad_total == 0)
              r.detail = label + ": " + std::to_string(bad) + " non-finite values";
            bad_total += bad;
          }
        }
      } catch (const PluginCallError& e) {
        r.status = CheckStatus::Fail;
        if (bad_total == 0) r.detail = label + ": " + e.what();
        bad_total += 1;
      }
    }
  }
  r.worst = bad_total;
  if (bad_total == 0)
    r.detail = "all values finite in " + std::to_string(2 * states.size()) + " cases";
  return r;
}

}  // namespace pinsim::plugin_check
