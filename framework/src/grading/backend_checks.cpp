#include "grading/backend_checks.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <set>
#include <vector>

#include "core/format.hpp"
#include "core/input_error.hpp"
#include "core/scene.hpp"
#include "core/simulation.hpp"
#include "grading/path_record.hpp"

namespace fs = std::filesystem;

namespace pinsim::grading {
namespace {

using V2 = Eigen::Vector2d;

/// How deep below the surface a ball may end a step before it counts as penetrating: ten
/// times the reference's contact offset (depth_min 1e-5), far below a step's travel in every
/// scene of the rubric.
constexpr double kDepth = 1e-4;
/// Free flight before the first contact is x0 + sum of dt v_k to rounding: a motion gate that
/// only a backend moving the balls exactly as the host's drift does passes.
constexpr double kFlightAbs = 1e-9;
constexpr double kFlightRel = 1e-12;
/// Time resolution of the grader's own search for a first contact with a moving obstacle, s.
constexpr double kMovingSample = 1e-6;

const std::set<std::string> kStageChecks = {"backend_free_flight", "backend_bounce",
                                            "backend_rest",        "backend_energy",
                                            "backend_path",        "backend_no_tunnelling"};

[[noreturn]] void rubric_error(const std::string& scene, const std::string& what) {
  throw InputError(scene + ": cannot be graded by this check (rubric error): " + what);
}

std::string vec(const V2& v) {
  std::string s = "(";
  s += num(v.x(), 6);
  s += ", ";
  s += num(v.y(), 6);
  s += ")";
  return s;
}

/// The reference and the submission on the same scene, stepped together.
struct Pair {
  Scene scene, mine;  ///< the reference's and the submission's
  std::string file;
  std::unique_ptr<PluginLoader> l1, l2;
  std::unique_ptr<Simulation> ref, sub;
  std::vector<bool> moving;     ///< per obstacle
  std::vector<double> e, kick;  ///< per obstacle: restitution and kick
  bool any_moving = false;

  Pair(const RubricTest& t, const std::shared_ptr<const LoadedPlugin>& plugin,
       const fs::path& rubric_dir) {
    file = t.spec.at("scene").get<std::string>();
    scene = load_scene(rubric_dir / file);
    scene.backend = PluginRef{t.spec.at("reference").get<std::string>(), "", scene.backend.params,
                              scene.backend.where};
    mine = scene;
    mine.backend = PluginRef{t.plugin, "", nlohmann::json::object(), "your backend"};
    l1 = std::make_unique<PluginLoader>(plugin_search_dirs());
    l2 = std::make_unique<PluginLoader>(plugin_search_dirs());
    l2->provide(plugin);
    ref = std::make_unique<Simulation>(scene, *l1);
    if (!ref->backend().has_distance()) rubric_error(file, "the reference has no distance()");
    sub = std::make_unique<Simulation>(mine, *l2);
    for (const auto& o : scene.backend_scene.value("obstacles", nlohmann::json::array())) {
      moving.push_back(o.contains("motion"));
      any_moving = any_moving || moving.back();
      const auto m = o.value("material", nlohmann::json::object());
      e.push_back(m.value("restitution", 1.0));
      kick.push_back(m.value("kick", 0.0));
      if (m.value("friction", 0.0) != 0.0)
        rubric_error(file, "an obstacle with friction (the closed forms are frictionless)");
    }
  }

  double clearance(const V2& p, double t, double r, int64_t* k = nullptr) const {
    return ref->backend().distance(p.x(), p.y(), t, k) - r;
  }
  /// The obstacles' outward unit normal at p: central differences of the distance.
  V2 normal(const V2& p, double t) const {
    const double h = 1e-7;
    const auto& b = ref->backend();
    V2 g((b.distance(p.x() + h, p.y(), t, nullptr) - b.distance(p.x() - h, p.y(), t, nullptr)) /
             (2 * h),
         (b.distance(p.x(), p.y() + h, t, nullptr) - b.distance(p.x(), p.y() - h, t, nullptr)) /
             (2 * h));
    return g.normalized();
  }
  /// The normal velocity of the obstacles' surface at p, time t: phi(p, t) falls at the rate
  /// the surface advances, u.n = -d phi / dt (central differences; 0 for static ones).
  double surface_speed(const V2& p, double t) const {
    if (!any_moving) return 0.0;
    const double h = 1e-7;
    const auto& b = ref->backend();
    return -(b.distance(p.x(), p.y(), t + h, nullptr) -
             b.distance(p.x(), p.y(), std::max(0.0, t - h), nullptr)) /
           (t + h - std::max(0.0, t - h));
  }
  /// The first time in [t0, t1] at which a ball of radius r moving along x0 + v (t - t0)
  /// touches an obstacle: sphere tracing for static obstacles (exact to 1e-12 of length),
  /// sampling every kMovingSample and bisection when some move. +inf if none.
  double first_contact(const V2& x0, const V2& v, double t0, double t1, double r) const {
    const double speed = v.norm();
    auto at = [&](double t) -> V2 { return x0 + v * (t - t0); };
    if (!any_moving) {
      if (speed == 0.0) return clearance(x0, t0, r) <= 0 ? t0 : HUGE_VAL;
      double t = t0;
      for (int it = 0; it < 100000 && t <= t1; ++it) {
        const double c = clearance(at(t), t, r);
        if (c <= 1e-12) return t;
        t += c / speed;
      }
      return HUGE_VAL;
    }
    if (speed * kMovingSample > 1e-4)
      rubric_error(file, "a ball too fast for the search among moving obstacles");
    double a = t0;
    if (clearance(at(a), a, r) <= 0) return a;
    for (double b = t0 + kMovingSample; a < t1; a = b, b += kMovingSample) {
      b = std::min(b, t1);
      if (clearance(at(b), b, r) <= 0) {
        for (int k = 0; k < 60; ++k) {
          const double m = 0.5 * (a + b);
          (clearance(at(m), m, r) <= 0 ? b : a) = m;
        }
        return b;
      }
      if (b >= t1) break;
    }
    return HUGE_VAL;
  }
  /// The uniform gravity of the scene's forces (every force must be uniform gravity).
  V2 gravity() const {
    V2 g = V2::Zero();
    for (const auto& f : scene.forces) {
      if (f.name != "gravity" || f.params.value("mode", std::string("uniform")) != "uniform" ||
          !f.elements.is_null())
        rubric_error(file, "the closed forms take uniform gravity on all particles only, not '" +
                               f.name + "'");
      const auto gj = f.params.value("g", nlohmann::json::array({0.0, -9.81}));
      g += V2(gj.at(0).get<double>(), gj.at(1).get<double>());
    }
    return g;
  }
  uint64_t steps() const { return scene.steps(); }
  double dt() const { return scene.dt; }
  /// Steps the submission (and the reference); a failure of the submission's run is the
  /// verdict's message.
  std::optional<std::string> step(uint64_t n) {
    ref->step();
    try {
      sub->step();
    } catch (const NumericError& e) {
      return "your backend's run failed at step " + std::to_string(e.step) + ": " + e.what();
    }
    (void)n;
    return std::nullopt;
  }
};

/// Free flight under constant gravity as the host integrates it (symplectic Euler: the kick
/// v_k = v_{k-1} + g dt, then the drift x_k = x_{k-1} + dt v_k), in closed form:
///   v_n = v_0 + n g dt,  x_n = x_0 + n dt v_0 + g dt^2 n (n + 1) / 2.
struct Flight {
  V2 x0, v0, g;
  double dt;
  V2 x(uint64_t n) const {
    const double k = static_cast<double>(n);
    return x0 + k * dt * v0 + g * (dt * dt * k * (k + 1) / 2);
  }
  V2 v(uint64_t n) const { return v0 + static_cast<double>(n) * dt * g; }
};

/// The last step before particle i's free flight first touches an obstacle: the drift of
/// step n is the straight segment from x_{n-1} to x_n, traced by the reference's distance.
uint64_t free_steps(const Pair& p, const Flight& f, double r, uint64_t steps) {
  for (uint64_t n = 1; n <= steps; ++n) {
    const double t0 = (n - 1) * p.dt();
    if (p.first_contact(f.x(n - 1), f.v(n), t0, t0 + p.dt(), r) <= t0 + p.dt()) return n - 1;
  }
  return steps;
}

/// The motion gate: step n's position of particle i against free flight.
std::optional<std::string> gate(const State& s, Eigen::Index i, uint64_t n, const Flight& f) {
  const V2 x = s.x.col(i), want = f.x(n);
  if ((x - want).norm() <= kFlightAbs + kFlightRel * want.norm()) return std::nullopt;
  return "motion gate: at step " + std::to_string(n) + " (t = " + num(n * f.dt, 6) + ") particle " +
         std::to_string(i) + " is at " + vec(x) +
         ", but before its first contact it flies freely to " + vec(want) +
         " (x0 + n dt v0 + g dt^2 n(n+1)/2; off by " + num((x - want).norm(), 3) +
         "). No other part of this test is graded until the balls move";
}

/// The first particle deeper than `depth` inside an obstacle (its index in *who), if any.
std::optional<std::string> penetration(const Pair& p, const State& s, uint64_t n, double depth,
                                       Eigen::Index* who = nullptr) {
  for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
    int64_t k = -1;
    const double c = p.clearance(s.x.col(i), s.t, s.radius[i], &k);
    if (who != nullptr) *who = i;
    if (!(c >= -depth))
      return "at step " + std::to_string(n) + " (t = " + num(s.t, 6) + ") particle " +
             std::to_string(i) + " is " + num(-c, 3) + " inside obstacle " +
             p.scene.obstacle_id(k) + " (tunnelled or penetrated; accepted " + num(depth, 3) + ")";
  }
  return std::nullopt;
}

std::vector<Flight> flights(const Pair& p) {
  const State s0 = p.scene.initial_state();
  const V2 g = p.gravity();
  std::vector<Flight> f;
  for (Eigen::Index i = 0; i < s0.x.cols(); ++i) f.push_back({s0.x.col(i), s0.v.col(i), g, p.dt()});
  return f;
}

// ---- backend_free_flight: no contact in the run; every step against the closed form.
Verdict free_flight(Pair& p, const RubricTest& t) {
  const auto fl = flights(p);
  const State s0 = p.scene.initial_state();
  for (std::size_t i = 0; i < fl.size(); ++i)
    if (free_steps(p, fl[i], s0.radius[i], p.steps()) < p.steps())
      rubric_error(p.file, "particle " + std::to_string(i) + " touches an obstacle");
  const double tol = t.spec.value("tolerance", kFlightAbs);
  double worst = 0.0;
  for (uint64_t n = 1; n <= p.steps(); ++n) {
    if (auto e = p.step(n)) return {false, *e};
    const State& s = p.sub->state();
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
      const Flight& f = fl[i];
      const double dx = (V2(s.x.col(i)) - f.x(n)).norm(), dv = (V2(s.v.col(i)) - f.v(n)).norm();
      worst = std::max({worst, dx, dv});
      if (!(dx <= tol && dv <= tol))
        return {false, "at step " + std::to_string(n) + " particle " + std::to_string(i) +
                           " is at " + vec(s.x.col(i)) + " with velocity " + vec(s.v.col(i)) +
                           "; free flight (x_n = x0 + n dt v0 + g dt^2 n(n+1)/2, v_n = v0 + n "
                           "g dt) is at " +
                           vec(f.x(n)) + " with " + vec(f.v(n)) + " (accepted " + num(tol, 3) +
                           ")"};
    }
  }
  return {true, std::to_string(fl.size()) + " balls, " + std::to_string(p.steps()) +
                    " steps of free flight: largest difference from the closed form " +
                    num(worst, 3) + " (accepted " + num(tol, 3) + ")"};
}

// ---- backend_bounce: no forces; each ball meets one obstacle once, at time t*, and leaves
// with v' = v - (1 + e) vn n, vn = (v - u).n the normal velocity relative to the surface
// (u.n = -d phi/dt), so that (v' - u).n = -e vn (restitution, Newton's impact law).
struct Bounce {
  double t_hit, t_next;  ///< the impact and the next contact of the outgoing path (or inf)
  V2 x_hit, v_out, n;
  double vn, un, e;
  int64_t obstacle;
};

Verdict bounce(Pair& p, const RubricTest& t) {
  if (!p.scene.forces.empty()) rubric_error(p.file, "forces in a bounce scene");
  const State s0 = p.scene.initial_state();
  const double T = p.steps() * p.dt();
  std::vector<Bounce> b;
  for (Eigen::Index i = 0; i < s0.x.cols(); ++i) {
    const double r = s0.radius[i];
    const V2 x0 = s0.x.col(i), v0 = s0.v.col(i);
    Bounce c{};
    c.t_hit = p.first_contact(x0, v0, 0.0, T, r);
    if (!(c.t_hit < T)) rubric_error(p.file, "particle " + std::to_string(i) + " hits nothing");
    c.x_hit = x0 + v0 * c.t_hit;
    p.clearance(c.x_hit, c.t_hit, r, &c.obstacle);
    c.n = p.normal(c.x_hit, c.t_hit);
    c.un = p.surface_speed(c.x_hit - r * c.n, c.t_hit);
    c.vn = v0.dot(c.n) - c.un;
    c.e = p.e.at(static_cast<std::size_t>(c.obstacle));
    if (p.kick.at(static_cast<std::size_t>(c.obstacle)) != 0.0 || !(c.vn < 0))
      rubric_error(p.file, "particle " + std::to_string(i) + ": a kick, or no approach");
    c.v_out = v0 - (1 + c.e) * c.vn * c.n;
    // The outgoing path, from 1e-4 off the surface, must meet nothing within the run for the
    // closed form to hold; where it does, only the steps before are graded.
    const double lift = 1e-4 / std::max(1e-300, (c.v_out.dot(c.n) - c.un));
    c.t_next = p.any_moving
                   ? HUGE_VAL
                   : p.first_contact(c.x_hit + c.v_out * lift, c.v_out, c.t_hit + lift, T, r);
    if (!(std::ceil(c.t_hit / p.dt()) * p.dt() < std::min(T, c.t_next)))
      rubric_error(p.file, "particle " + std::to_string(i) + " has no step after its impact");
    b.push_back(c);
  }
  const double tol = t.spec.value("tolerance", 1e-3);
  const double vtol = t.spec.value("velocity_tolerance", 1e-3);
  double worst_x = 0.0, worst_v = 0.0, deepest = 0.0;
  for (uint64_t n = 1; n <= p.steps(); ++n) {
    if (auto e = p.step(n)) return {false, *e};
    const State& s = p.sub->state();
    const double tn = n * p.dt();
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
      const Bounce& c = b[static_cast<std::size_t>(i)];
      const V2 x = s.x.col(i), v = s.v.col(i);
      const std::string at = "at step " + std::to_string(n) + " (t = " + num(tn, 6) +
                             ") particle " + std::to_string(i) + " (speed " +
                             num(V2(s0.v.col(i)).norm(), 3) + ")";
      if (tn < c.t_hit) {
        if (auto e = gate(s, i, n, {s0.x.col(i), s0.v.col(i), V2::Zero(), p.dt()}))
          return {false, *e};
        continue;
      }
      deepest = std::max(deepest, -p.clearance(x, tn, s.radius[i]));
      if (auto e = penetration(p, s, n, kDepth)) return {false, *e};
      if (tn >= c.t_next) continue;
      const V2 want = c.x_hit + c.v_out * (tn - c.t_hit);
      const double dv = (v - c.v_out).norm() / c.v_out.norm(), dx = (x - want).norm();
      worst_v = std::max(worst_v, dv);
      worst_x = std::max(worst_x, dx);
      if (!(dv <= vtol))
        return {false, at + " has velocity " + vec(v) +
                           " after its impact at t = " + num(c.t_hit, 6) + " on obstacle " +
                           p.scene.obstacle_id(c.obstacle) + "; the impact law gives " +
                           vec(c.v_out) + " (v' = v - (1 + e) vn n with e = " + num(c.e, 3) +
                           ", relative normal velocity vn = (v - u).n = " + num(c.vn, 6) +
                           ", surface speed u.n = " + num(c.un, 6) + ", so (v' - u).n = -e vn = " +
                           num(-c.e * c.vn, 6) + "; yours: " + num(v.dot(c.n) - c.un, 6) +
                           "; relative error " + num(dv, 3) + ", accepted " + num(vtol, 3) + ")"};
      if (!(dx <= tol))
        return {false, at + " is at " + vec(x) + "; after its impact at t* = " + num(c.t_hit, 6) +
                           " it is at x* + v' (t - t*) = " + vec(want) + " (off by " + num(dx, 3) +
                           ", accepted " + num(tol, 3) + ")"};
    }
  }
  double lo = HUGE_VAL, hi = 0.0;
  for (Eigen::Index i = 0; i < s0.x.cols(); ++i) {
    lo = std::min(lo, V2(s0.v.col(i)).norm());
    hi = std::max(hi, V2(s0.v.col(i)).norm());
  }
  return {true, std::to_string(b.size()) + " balls at " + num(lo, 3) + " to " + num(hi, 3) +
                    " units/s, one impact each: free flight before it, never deeper than " +
                    num(std::max(0.0, deepest), 3) + " inside, outgoing velocity within " +
                    num(worst_v, 3) + " (relative) of v' = v - (1 + e) vn n, position within " +
                    num(worst_x, 3) + " of x* + v' (t - t*)"};
}

// ---- backend_rest: balls dropped onto static obstacles under gravity come to rest. Free
// flight until the first contact (gate); never deeper than the tolerance; over the last
// quarter of the run each ball stays within the tolerance of one place (no jitter), and it
// ends on the surface (clearance within the tolerance: not hovering, not sunk).
Verdict rest(Pair& p, const RubricTest& t) {
  const auto fl = flights(p);
  const State s0 = p.scene.initial_state();
  std::vector<uint64_t> free;
  for (std::size_t i = 0; i < fl.size(); ++i) {
    free.push_back(free_steps(p, fl[i], s0.radius[i], p.steps()));
    if (free.back() == 0 || free.back() >= p.steps() * 3 / 4)
      rubric_error(p.file, "particle " + std::to_string(i) + " does not fall, or does not land");
  }
  const double tol = t.spec.value("tolerance", kDepth);
  const uint64_t settled = p.steps() - p.steps() / 4;
  std::vector<V2> lo(fl.size(), V2::Constant(HUGE_VAL)), hi(fl.size(), V2::Constant(-HUGE_VAL));
  double deepest = 0.0;
  for (uint64_t n = 1; n <= p.steps(); ++n) {
    if (auto e = p.step(n)) return {false, *e};
    const State& s = p.sub->state();
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
      if (n <= free[static_cast<std::size_t>(i)])
        if (auto e = gate(s, i, n, fl[static_cast<std::size_t>(i)])) return {false, *e};
      deepest = std::max(deepest, -p.clearance(s.x.col(i), s.t, s.radius[i]));
      if (n > settled) {
        lo[i] = lo[i].cwiseMin(V2(s.x.col(i)));
        hi[i] = hi[i].cwiseMax(V2(s.x.col(i)));
      }
    }
    if (auto e = penetration(p, s, n, tol)) return {false, *e + ": the ball sinks"};
  }
  const State& s = p.sub->state();
  double worst_range = 0.0, worst_gap = 0.0;
  for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
    const double range = (hi[i] - lo[i]).norm();
    const double gap = p.clearance(s.x.col(i), s.t, s.radius[i]);
    worst_range = std::max(worst_range, range);
    worst_gap = std::max(worst_gap, std::abs(gap));
    const std::string who = "particle " + std::to_string(i);
    if (!(range <= tol))
      return {false, who + " jitters at rest: over the last " + std::to_string(p.steps() / 4) +
                         " steps it moved within a box of diagonal " + num(range, 3) +
                         " (accepted " + num(tol, 3) + ")"};
    if (!(std::abs(gap) <= tol))
      return {false, who + " does not rest on the surface: at the end its clearance phi - r is " +
                         num(gap, 3) + " (accepted +-" + num(tol, 3) + ")"};
  }
  return {true, "free flight until the first contact, never deeper than " +
                    num(std::max(0.0, deepest), 3) + "; at rest over the last " +
                    std::to_string(p.steps() / 4) + " steps within " + num(worst_range, 3) +
                    ", clearance at the end " + num(worst_gap, 3) + " (accepted " + num(tol, 3) +
                    ")"};
}

// ---- backend_energy: static obstacles, e <= 1, no kicks. The host's free flight
// (symplectic Euler, v += g dt then x += dt v) conserves exactly the modified energy
//   H = sum_i m_i (|v_i|^2 / 2 - g.x_i + (dt / 2) g.v_i)
// (its change over a step is m (dt g.v + dt^2 |g|^2 / 2 - dt g.v - dt^2 |g|^2 + dt^2 |g|^2 / 2)
// = 0). An impulse dv at time tau into the step keeps |v| at most (e <= 1) and changes H by
// m g.dv (tau - dt / 2), at most m |g| |dv| dt / 2. So the energy E = H - sum m (dt/2) g.v
// can rise above its start by at most
//   B(n) = sum over steps and balls of m |g| |dv| dt / 2 + sum_i m_i (dt/2) |g| (|v_i(n)| +
//   |v_i(0)|)
// with dv the velocity change the grader measures in each step (v after the step minus v
// after the host's kick); anything more is energy the backend made. Gate: free flight until
// the first contact; and the balls keep moving: the final kinetic energy at least a quarter
// of the reference's.
Verdict energy(Pair& p, const RubricTest& t) {
  if (p.any_moving) rubric_error(p.file, "moving obstacles in an energy scene");
  for (std::size_t k = 0; k < p.e.size(); ++k)
    if (p.kick[k] != 0.0 || p.e[k] > 1.0) rubric_error(p.file, "a kick or e > 1");
  const auto fl = flights(p);
  const State s0 = p.scene.initial_state();
  std::vector<uint64_t> free;
  for (std::size_t i = 0; i < fl.size(); ++i)
    free.push_back(free_steps(p, fl[i], s0.radius[i], p.steps()));
  const V2 g = p.gravity();
  const double dt = p.dt();
  auto mass = [&](const State& s, Eigen::Index i) {
    return s.inv_mass[i] > 0.0 ? 1.0 / s.inv_mass[i] : 0.0;
  };
  auto kinetic = [&](const State& s) {
    double e = 0.0;
    for (Eigen::Index i = 0; i < s.x.cols(); ++i)
      e += 0.5 * mass(s, i) * V2(s.v.col(i)).squaredNorm();
    return e;
  };
  auto total = [&](const State& s) {
    double e = kinetic(s);
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) e -= mass(s, i) * g.dot(V2(s.x.col(i)));
    return e;
  };
  auto swing = [&](const State& s) {  // sum m (dt/2) |g| (|v(n)| + |v(0)|)
    double b = 0.0;
    for (Eigen::Index i = 0; i < s.x.cols(); ++i)
      b += mass(s, i) * 0.5 * dt * g.norm() * (V2(s.v.col(i)).norm() + V2(s0.v.col(i)).norm());
    return b;
  };
  const double e0 = total(s0);
  const double tol = t.spec.value("tolerance", 1e-9);
  double impulses = 0.0, margin = HUGE_VAL;
  uint64_t margin_step = 0;
  Eigen::Matrix2Xd v_prev = s0.v;
  for (uint64_t n = 1; n <= p.steps(); ++n) {
    if (auto e = p.step(n)) return {false, *e};
    const State& s = p.sub->state();
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
      if (n <= free[static_cast<std::size_t>(i)])
        if (auto e = gate(s, i, n, fl[static_cast<std::size_t>(i)])) return {false, *e};
      if (mass(s, i) > 0.0) {
        const V2 dv = V2(s.v.col(i)) - (V2(v_prev.col(i)) + dt * g);
        impulses += mass(s, i) * g.norm() * dv.norm() * dt / 2;
      }
    }
    v_prev = s.v;
    const double de = total(s) - e0, bound = impulses + swing(s) + tol;
    if (!(bound - de >= margin)) {
      margin = std::isfinite(de) ? bound - de : -HUGE_VAL;
      margin_step = n;
    }
    if (!(de <= bound))
      return {false, "at step " + std::to_string(n) + " (t = " + num(s.t, 6) +
                         ") the energy E = sum m (|v|^2/2 - g.x) is " + num(e0 + de, 9) + ", " +
                         num(de, 3) + " above its start " + num(e0, 9) +
                         "; symplectic Euler's steps and your impulses account for at most " +
                         num(bound, 3) +
                         " of it (sum m |g| |dv| dt/2 + sum m (dt/2) |g| (|v| + |v0|)): static "
                         "obstacles with e <= 1 cannot add energy"};
  }
  const double mine = kinetic(p.sub->state()), theirs = kinetic(p.ref->state());
  if (!(mine >= 0.25 * theirs))
    return {false, "motion gate: at the end the balls' kinetic energy is " + num(mine, 6) +
                       ", under a quarter of the reference's " + num(theirs, 6) +
                       ": the balls must keep bouncing (the obstacles are nearly elastic)"};
  return {true, "over " + std::to_string(p.steps()) +
                    " steps the energy stayed below its start plus what symplectic Euler's steps "
                    "and the impulses account for; the closest it came was " +
                    num(margin, 3) + " below that bound (at step " + std::to_string(margin_step) +
                    "); final kinetic energy " + num(mine, 6) + ", the reference's " +
                    num(theirs, 6)};
}

/// A failed verdict with the picture of both paths up to now, failing on particle i.
Verdict failed_path(const Pair& p, const PathRecorder& rec, Eigen::Index i, std::string why) {
  Verdict v{false, std::move(why)};
  v.figure = rec.failed(static_cast<std::size_t>(i), &p.ref->backend());
  return v;
}

// ---- backend_path: the reference's path, step by step; the first step where it leaves.
Verdict path(Pair& p, const RubricTest& t) {
  const double tol = t.spec.value("tolerance", 1e-3);
  double worst = 0.0;
  uint64_t worst_step = 0;
  PathRecorder rec(p.scene);
  for (uint64_t n = 1; n <= p.steps(); ++n) {
    if (auto e = p.step(n)) return {false, *e};
    const State &s = p.sub->state(), &r = p.ref->state();
    rec.add(n, s, r);
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
      const double d = (s.x.col(i) - r.x.col(i)).norm();
      if (!(d <= worst)) {
        worst = std::isfinite(d) ? d : HUGE_VAL;
        worst_step = n;
      }
      if (!(d <= tol))
        return failed_path(p, rec, i,
                           "your path leaves the reference's at step " + std::to_string(n) +
                               " of " + std::to_string(p.steps()) + " (t = " + num(s.t, 6) +
                               "): particle " + std::to_string(i) + " is at " + vec(s.x.col(i)) +
                               ", the reference's at " + vec(r.x.col(i)) + ", " + num(d, 3) +
                               " apart (accepted " + num(tol, 3) + ")");
    }
  }
  return {true, "the path follows the reference's for all " + std::to_string(p.steps()) +
                    " steps: largest difference " + num(worst, 3) + " at step " +
                    std::to_string(worst_step) + " (accepted " + num(tol, 3) + ")"};
}

// ---- backend_no_tunnelling: thin walls hit at speed. Free flight until the first contact
// (gate); no step ends deeper than the tolerance inside an obstacle; and every step ends
// within path_tolerance of the reference's position, so a ball that passed through a wall
// (and so ends a step on its far side, not inside it) is found at the first step it does.
Verdict no_tunnelling(Pair& p, const RubricTest& t) {
  const auto fl = flights(p);
  const State s0 = p.scene.initial_state();
  std::vector<uint64_t> free;
  for (std::size_t i = 0; i < fl.size(); ++i)
    free.push_back(free_steps(p, fl[i], s0.radius[i], p.steps()));
  const double tol = t.spec.value("tolerance", kDepth);
  const double ptol = t.spec.value("path_tolerance", 1e-2);
  double deepest = 0.0, worst = 0.0;
  PathRecorder rec(p.scene);
  for (uint64_t n = 1; n <= p.steps(); ++n) {
    if (auto e = p.step(n)) return {false, *e};
    const State &s = p.sub->state(), &r = p.ref->state();
    rec.add(n, s, r);
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
      if (n <= free[static_cast<std::size_t>(i)])
        if (auto e = gate(s, i, n, fl[static_cast<std::size_t>(i)]))
          return failed_path(p, rec, i, *e);
      deepest = std::max(deepest, -p.clearance(s.x.col(i), s.t, s.radius[i]));
    }
    Eigen::Index who = 0;
    if (auto e = penetration(p, s, n, tol, &who)) return failed_path(p, rec, who, *e);
    for (Eigen::Index i = 0; i < s.x.cols(); ++i) {
      const double d = (s.x.col(i) - r.x.col(i)).norm();
      worst = std::max(worst, std::isfinite(d) ? d : HUGE_VAL);
      if (!(d <= ptol))
        return failed_path(p, rec, i,
                           "at step " + std::to_string(n) + " (t = " + num(s.t, 6) + ") particle " +
                               std::to_string(i) + " (speed " + num(V2(s0.v.col(i)).norm(), 3) +
                               ") is at " + vec(s.x.col(i)) + ", the reference's at " +
                               vec(r.x.col(i)) + ": " + num(d, 3) + " apart (accepted " +
                               num(ptol, 3) +
                               "); a ball that tunnels ends the step on the far side of the wall");
    }
  }
  return {true, std::to_string(s0.x.cols()) + " balls, " + std::to_string(p.steps()) +
                    " steps: never deeper than " + num(std::max(0.0, deepest), 3) +
                    " inside an obstacle (accepted " + num(tol, 3) + "), always within " +
                    num(worst, 3) + " of the reference's path (accepted " + num(ptol, 3) + ")"};
}

}  // namespace

bool is_stage_check(const std::string& check) { return kStageChecks.count(check) != 0; }

Verdict run_stage_check(const RubricTest& t, const std::shared_ptr<const LoadedPlugin>& sub,
                        const fs::path& rubric_dir) {
  Pair p(t, sub, rubric_dir);
  if (t.check == "backend_free_flight") return free_flight(p, t);
  if (t.check == "backend_bounce") return bounce(p, t);
  if (t.check == "backend_rest") return rest(p, t);
  if (t.check == "backend_energy") return energy(p, t);
  if (t.check == "backend_no_tunnelling") return no_tunnelling(p, t);
  return path(p, t);
}

}  // namespace pinsim::grading
