#include "grading/verdicts.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "core/format.hpp"
#include "core/param_validation.hpp"
#include "core/plugin_instance.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "grading/backend_checks.hpp"
#include "grading/path_record.hpp"
#include "tools/plugin_check.hpp"

namespace fs = std::filesystem;

namespace pinsim::grading {
namespace {

Verdict check_plugin_test(const LoadedPlugin& p, const RubricTest& t) {
  CheckOptions opt;
  opt.params = t.spec.value("params", nlohmann::json::object());
  opt.seed = t.spec.value("seed", opt.seed);
  opt.trials = t.spec.value("trials", opt.trials);
  opt.assume_internal = t.spec.value("assume_internal", false);
  opt.only = t.check;
  const CheckReport rep = check_force_plugin(p, opt);
  const CheckResult* r = rep.find(t.check);
  if (r == nullptr) {
    // The checks stop early when the plugin cannot even be created: say why.
    std::string why;
    for (const auto& c : rep.checks)
      if (c.status == CheckStatus::Fail) why += "; " + c.what + ": " + c.detail;
    return {false, "the check '" + t.check + "' could not run" + why};
  }
  if (r->status == CheckStatus::Skip) return {false, r->what + ": not checked: " + r->detail};
  return {r->status == CheckStatus::Pass, r->what + ": worst error " + num(r->worst, 3) +
                                              " (accepted " + num(r->tolerance, 3) + "); " +
                                              r->detail};
}

/// Random states on which submission and reference are compared: forces (and energies).
Verdict reference_test(const std::shared_ptr<const LoadedPlugin>& sub, const RubricTest& t) {
  PluginLoader loader(plugin_search_dirs());
  const std::string ref_name = t.spec.at("reference").get<std::string>();
  auto ref = loader.load(ref_name);
  const nlohmann::json given = t.spec.value("params", nlohmann::json::object());
  nlohmann::json ref_params =
      validate_params(*ref->table, given, "reference '" + ref_name + "' params");
  nlohmann::json sub_params;
  try {
    sub_params = validate_params(*sub->table, given, "your plugin's params");
  } catch (const std::exception& e) {
    return {false, std::string("your plugin does not accept the parameters the reference takes: ") +
                       e.what()};
  }
  if (sub->table->arity != ref->table->arity)
    return {false, "your plugin acts on elements of " + std::to_string(sub->table->arity) +
                       " particles, the reference on " + std::to_string(ref->table->arity)};
  const uint32_t arity = ref->table->arity;
  const bool whole_body = arity == PINSIM_ARITY_VARIABLE;
  const int n = 7;
  std::vector<uint32_t> elements;
  if (whole_body) {
    // One closed ring of all particles, counter-clockwise (length first, then indices).
    elements.push_back(static_cast<uint32_t>(n));
    for (int i = 0; i < n; ++i) elements.push_back(static_cast<uint32_t>(i));
  } else {
    for (int i = 0; i + static_cast<int>(arity) <= n; ++i)
      for (uint32_t k = 0; k < arity; ++k) elements.push_back(static_cast<uint32_t>(i) + k);
  }
  std::mt19937_64 rng(t.spec.value("seed", 7ull));
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto random_state = [&] {
    State s;
    s.x.resize(2, n);
    s.v.resize(2, n);
    s.inv_mass = Eigen::VectorXd::Constant(n, 1.0);
    s.radius = Eigen::VectorXd::Constant(n, 0.05);
    for (int i = 0; i < n; ++i) {
      if (whole_body) {  // around a circle, so the ring encloses an area
        const double a = 2.0 * M_PI * i / n;
        s.x.col(i) << std::cos(a) + 0.1 * u(rng), std::sin(a) + 0.1 * u(rng);
      } else {
        s.x.col(i) << 0.3 * i + 0.1 * u(rng), 0.2 * u(rng);
      }
      s.v.col(i) << u(rng), u(rng);
    }
    return s;
  };
  const State rest = random_state();
  ForceInstance fr(ref, rest, {ref_params, nullptr, elements, "reference"});
  ForceInstance fs_(sub, rest, {sub_params, nullptr, elements, "your plugin"});
  const double tol = t.spec.value("tolerance", 1e-8);
  double worst = 0.0;
  std::string where = "";
  const int trials = t.spec.value("trials", 8);
  for (int k = 0; k < trials; ++k) {
    const State s = random_state();
    Eigen::Matrix2Xd f1 = Eigen::Matrix2Xd::Zero(2, n), f2 = Eigen::Matrix2Xd::Zero(2, n);
    fr.add_force(s.view(), f1.data());
    fs_.add_force(s.view(), f2.data());
    const double scale = std::max(1e-12, f1.cwiseAbs().maxCoeff());
    for (int i = 0; i < n; ++i) {
      const double err = (f2.col(i) - f1.col(i)).norm() / scale;
      if (!std::isfinite(err) || err > worst) {
        worst = std::isfinite(err) ? err : HUGE_VAL;
        where = "state " + std::to_string(k) + ", particle " + std::to_string(i) + ": yours (" +
                num(f2(0, i), 3) + ", " + num(f2(1, i), 3) + "), reference (" + num(f1(0, i), 3) +
                ", " + num(f1(1, i), 3) + ")";
      }
    }
    if (fr.has_energy() && !fs_.has_energy()) {
      // Omitting energy() must not skip its comparison: the reference's energy is part of
      // what the plugin is asked to reproduce.
      worst = HUGE_VAL;
      where = "your plugin has no energy() (the reference '" + ref_name +
              "' has one: declare PINSIM_CAP_ENERGY and implement it)";
    } else if (fr.has_energy()) {
      const double e1 = fr.energy(s.view()), e2 = fs_.energy(s.view());
      const double err = std::abs(e2 - e1) / std::max(1e-12, std::abs(e1));
      if (!std::isfinite(err) || err > worst) {
        worst = std::isfinite(err) ? err : HUGE_VAL;
        where = "state " + std::to_string(k) + ": energy yours " + num(e2, 3) + ", reference " +
                num(e1, 3);
      }
    }
  }
  return {worst <= tol, "agreement with the reference '" + ref_name + "' on " +
                            std::to_string(trials) + " random states: worst relative error " +
                            num(worst, 3) + " (accepted " + num(tol, 3) + ")" +
                            (where.empty() ? "" : "; worst at " + where)};
}

Verdict simulation_test(const std::shared_ptr<const LoadedPlugin>& sub, const RubricTest& t,
                        const fs::path& rubric_dir) {
  const Scene base = load_scene(rubric_dir / t.spec.at("scene").get<std::string>());
  Scene mine = base;
  int replaced = 0;
  for (auto& f : mine.forces)
    if (f.name == t.plugin) {
      f.library.clear();  // resolved to the submission's plugin by the loader below
      ++replaced;
    }
  if (replaced == 0) return {false, "the scene uses no force '" + t.plugin + "' (rubric error)"};
  PluginLoader l1(plugin_search_dirs(base.plugin_path)), l2(plugin_search_dirs(base.plugin_path));
  l2.provide(sub);
  Simulation ref(base, l1), sim(mine, l2);
  const double tol = t.spec.value("tolerance", 1e-6);
  double worst = 0.0;
  uint64_t worst_step = 0;
  // The picture of a failure: both runs to the end (or to the step before the run failed),
  // marked at the first step where a particle is further than the tolerance from the
  // reference's.
  PathRecorder rec(base);
  std::optional<PathComparison> parted;
  auto picture = [&]() -> std::optional<PathComparison> {
    if (!parted) return std::nullopt;
    PathComparison whole = rec.failed(parted->particle, nullptr);
    parted->mine = std::move(whole.mine);
    parted->reference = std::move(whole.reference);
    parted->drawn_to = whole.drawn_to;
    return parted;
  };
  for (uint64_t n = 0; n < base.steps(); ++n) {
    ref.step();
    try {
      sim.step();
    } catch (const NumericError& e) {
      Verdict v{false, "your simulation failed at step " + std::to_string(e.step) + ", particle " +
                           std::to_string(e.particle) + ": " + e.what()};
      v.figure = picture();
      return v;
    }
    const Eigen::RowVectorXd dist = (sim.state().x - ref.state().x).colwise().norm();
    const double d = dist.maxCoeff();
    if (!(d <= worst)) {
      worst = std::isfinite(d) ? d : HUGE_VAL;
      worst_step = n + 1;
    }
    rec.add(n + 1, sim.state(), ref.state());
    if (!parted) {
      for (Eigen::Index i = 0; i < dist.size() && !parted; ++i)
        if (!(dist[i] <= tol)) {
          parted = rec.failed(static_cast<std::size_t>(i), &ref.backend());
          parted->what = "your path first leaves the reference's by more than " + num(tol, 3);
        }
    }
  }
  Verdict v{worst <= tol, "simulation of " + t.spec.at("scene").get<std::string>() + " (" +
                              std::to_string(base.steps()) +
                              " steps): largest position difference " + num(worst, 3) +
                              " from the reference, at step " + std::to_string(worst_step) +
                              " (accepted " + num(tol, 3) + ")"};
  if (!v.passed) v.figure = picture();
  return v;
}

/// Not scored: the same scene on a second reference (Box2D), and how far the submission's
/// and the reference's final positions are from it, so a student sees two opinions.
std::string second_opinion(const Scene& scene, const RubricTest& t, const State& mine,
                           const State& ref) {
  if (!t.spec.contains("second_opinion")) return "";
  const std::string name = t.spec.at("second_opinion").get<std::string>();
  try {
    Scene other = scene;
    other.backend =
        PluginRef{name, "", t.spec.value("second_opinion_params", nlohmann::json::object()),
                  "second opinion"};
    PluginLoader loader(plugin_search_dirs());
    Simulation sim(other, loader);
    for (uint64_t n = 0; n < other.steps(); ++n) sim.step();
    const auto& x = sim.state().x;
    return "\nsecond opinion (" + name + ", not scored): yours differs from it by " +
           num((mine.x - x).colwise().norm().maxCoeff(), 3) + ", the reference by " +
           num((ref.x - x).colwise().norm().maxCoeff(), 3);
  } catch (const std::exception& e) {
    return "\nsecond opinion (" + name + ") unavailable: " + e.what();
  }
}

/// The grader's own measurement of a backend's advance() for backend_approaching_only: the
/// submission's contact reports are not trusted. advance() only drifts x along v and resolves
/// contacts (forces, gravity included, act in the integrator outside it), so any velocity
/// change it makes is a contact impulse, and the reports must account for it.
struct AdvanceAudit {
  const pinsim_plugin* inner = nullptr;  ///< the submission's table
  std::vector<bool> moving;              ///< per obstacle: moves (its velocity is unknown here)
  double tol = 1e-9;                     ///< the rubric's separating tolerance (m/s)
  double rel = 1e-6;  ///< accepted mismatch, relative to |v| (the sdf backend passes at 1e-13)
  uint64_t step = 0;
  std::string failure;  ///< the first failure, empty while none
};
thread_local AdvanceAudit* g_audit = nullptr;

bool finite_event(const pinsim_event& e) {
  return std::isfinite(e.t) && std::isfinite(e.point[0]) && std::isfinite(e.point[1]) &&
         std::isfinite(e.normal[0]) && std::isfinite(e.normal[1]) && std::isfinite(e.vn_before) &&
         std::isfinite(e.vn_after);
}

std::string audit_advance(const AdvanceAudit& a, const pinsim_state_mut& s,
                          const std::vector<double>& v0, const std::vector<pinsim_event>& evs) {
  const std::string at = "at step " + std::to_string(a.step) + " particle ";
  for (const auto& e : evs) {
    if (!finite_event(e))
      return at + std::to_string(e.particle) + ": a contact report holds a non-finite number (t " +
             num(e.t, 3) + ", normal (" + num(e.normal[0], 3) + ", " + num(e.normal[1], 3) +
             "), vn_before " + num(e.vn_before, 3) + ", vn_after " + num(e.vn_after, 3) + ")";
  }
  for (uint64_t i = 0; i < s.n; ++i) {
    const Eigen::Vector2d vb(v0[2 * i], v0[2 * i + 1]), va(s.v[2 * i], s.v[2 * i + 1]);
    const Eigen::Vector2d dv = va - vb;
    const double scale = std::max({vb.norm(), va.norm(), 1e-12});
    const double acc = a.rel * scale + 1e-12;
    const pinsim_event* first = nullptr;
    int contacts = 0;
    for (const auto& e : evs)
      if (e.particle == static_cast<int64_t>(i) || e.other == static_cast<int64_t>(i)) {
        if (first == nullptr) first = &e;
        ++contacts;
      }
    const std::string who = at + std::to_string(i);
    if (first == nullptr) {
      if (dv.norm() > acc)
        return who + ": its velocity changed by (" + num(dv.x(), 3) + ", " + num(dv.y(), 3) +
               ") in advance() with no contact reported: every impulse must be reported";
      continue;
    }
    // The first contact meets the velocity the step started with: check the reported
    // approach against it, for static obstacles (a moving obstacle's velocity is unknown).
    if (first->particle != static_cast<int64_t>(i) || first->obstacle < 0 ||
        static_cast<std::size_t>(first->obstacle) >= a.moving.size() ||
        a.moving[static_cast<std::size_t>(first->obstacle)])
      continue;
    const Eigen::Vector2d n(first->normal[0], first->normal[1]);
    if (std::abs(n.norm() - 1.0) > 1e-6)
      return who + ": a contact report's normal (" + num(n.x(), 3) + ", " + num(n.y(), 3) +
             ") is not a unit vector";
    const double vn = vb.dot(n);
    if (std::abs(first->vn_before - vn) > acc)
      return who + ": reported normal velocity before the impulse " + num(first->vn_before, 6) +
             ", but the grader measured " + num(vn, 6) + " (v before . normal)";
    // One contact: the whole normal velocity change is its impulse (friction is tangential).
    if (contacts == 1 && std::abs(dv.dot(n) - (first->vn_after - first->vn_before)) > acc)
      return who + ": reported a normal velocity change of " +
             num(first->vn_after - first->vn_before, 6) + ", but the grader measured " +
             num(dv.dot(n), 6);
    if (vn > a.tol && dv.dot(n) > acc)
      return who + ": got an impulse while separating (measured v.n = " + num(vn, 3) +
             " > 0 before, velocity change along the normal " + num(dv.dot(n), 3) + ")";
  }
  return "";
}

int audited_advance(void* self, pinsim_state_mut* s, double dt, const pinsim_event_sink* events,
                    pinsim_error* err) {
  AdvanceAudit& a = *g_audit;
  const std::vector<double> v0(s->v, s->v + 2 * s->n);
  std::vector<pinsim_event> evs;
  const pinsim_event_sink mine{&evs, [](void* c, const pinsim_event* e) {
                                 static_cast<std::vector<pinsim_event>*>(c)->push_back(*e);
                               }};
  const int rc = a.inner->backend.advance(self, s, dt, &mine, err);
  if (events != nullptr)
    for (const auto& e : evs) events->emit(events->context, &e);
  if (rc == 0 && a.failure.empty()) a.failure = audit_advance(a, *s, v0, evs);
  return rc;
}

/// The submission's backend with advance() measured by `audit` (which must outlive it).
std::shared_ptr<const LoadedPlugin> audited(const std::shared_ptr<const LoadedPlugin>& plugin,
                                            AdvanceAudit& audit) {
  struct Owner {
    std::shared_ptr<const LoadedPlugin> inner;
    pinsim_plugin table;
  };
  auto owner = std::make_shared<Owner>(Owner{plugin, *plugin->table});
  owner->table.backend.advance = audited_advance;
  audit.inner = plugin->table;
  auto p = std::make_shared<LoadedPlugin>(*plugin);
  p->table = &owner->table;
  p->owner = owner;
  return p;
}

Verdict backend_test(const std::shared_ptr<const LoadedPlugin>& plugin, const RubricTest& t,
                     const fs::path& rubric_dir) {
  const std::string scene_file = t.spec.at("scene").get<std::string>();
  Scene ref_scene = load_scene(rubric_dir / scene_file);
  ref_scene.backend = PluginRef{t.spec.at("reference").get<std::string>(), "",
                                ref_scene.backend.params, ref_scene.backend.where};
  Scene mine = ref_scene;
  mine.backend = PluginRef{t.plugin, "", nlohmann::json::object(), "your backend"};
  PluginLoader l1(plugin_search_dirs()), l2(plugin_search_dirs());
  const double tol = t.spec.value("tolerance", 1e-3);
  const bool approaching = t.check == "backend_approaching_only";
  AdvanceAudit audit;
  audit.tol = tol;
  for (const auto& o : ref_scene.backend_scene.value("obstacles", nlohmann::json::array())) {
    const std::string d = o.dump();
    bool moves = false;
    for (const char* k : {"\"motion\"", "\"pivot\"", "\"path\"", "\"velocity\""})
      moves = moves || d.find(k) != std::string::npos;
    audit.moving.push_back(moves);
  }
  l2.provide(approaching ? audited(plugin, audit) : plugin);
  struct Scope {
    explicit Scope(AdvanceAudit* a) { g_audit = a; }
    ~Scope() { g_audit = nullptr; }
  } scope(approaching ? &audit : nullptr);
  Simulation ref(ref_scene, l1), sub(mine, l2);
  for (uint64_t n = 0; n < ref_scene.steps(); ++n) {
    ref.step();
    audit.step = n + 1;
    try {
      sub.step();
    } catch (const NumericError& e) {
      if (!audit.failure.empty()) return {false, audit.failure};
      return {false,
              "your backend's run failed at step " + std::to_string(e.step) + ": " + e.what()};
    }
    const State& s = sub.state();
    if (approaching) {
      if (!audit.failure.empty()) return {false, audit.failure};
      for (const auto& e : sub.events())
        if (!(e.vn_before <= tol))
          return {false, "at t = " + num(e.t, 3) + " particle " + std::to_string(e.particle) +
                             " got an impulse from obstacle " + ref_scene.obstacle_id(e.obstacle) +
                             " while separating (normal velocity before = " + num(e.vn_before, 3) +
                             " > 0): apply an impulse only when v.n < 0"};
      // Motion gate: a backend that holds the balls applies no impulse at all.
      const double off = (s.x - ref.state().x).colwise().norm().maxCoeff();
      if (!(off <= 1e-3))
        return {false, "motion gate: at step " + std::to_string(n + 1) + " your path is " +
                           num(off, 3) + " from the reference's (accepted 0.001)"};
    }
  }
  if (t.check == "backend_agreement") {
    const double d = (sub.state().x - ref.state().x).colwise().norm().maxCoeff();
    return {d <= tol, "final positions after " + std::to_string(ref_scene.steps()) +
                          " steps differ from the reference by " + num(d, 3) + " (accepted " +
                          num(tol, 3) + ")" +
                          second_opinion(ref_scene, t, sub.state(), ref.state())};
  }
  return {true, "every impulse was applied while approaching"};
}

}  // namespace

Verdict run_check(const RubricTest& t, const std::shared_ptr<const LoadedPlugin>& sub,
                  const fs::path& rubric_dir) {
  if (t.check == "load")
    return {true, "loaded plugin '" + t.plugin + "' " + sub->table->version + " from " +
                      sub->path.filename().string()};
  if (t.check == "reference") return reference_test(sub, t);
  if (t.check == "simulation") return simulation_test(sub, t, rubric_dir);
  if (is_stage_check(t.check)) return run_stage_check(t, sub, rubric_dir);
  if (t.check.rfind("backend_", 0) == 0) return backend_test(sub, t, rubric_dir);
  return check_plugin_test(*sub, t);
}

}  // namespace pinsim::grading
