#include "tools/plugin_check.hpp"

#include <fenv.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>

#include "core/format.hpp"
#include "core/param_validation.hpp"
#include "core/plugin_table_check.hpp"
#include "tools/check_layout.hpp"
#include "tools/constraint_checks.hpp"

namespace pinsim {

namespace {

using Eigen::Matrix2Xd;
using Eigen::MatrixXd;
using Eigen::Vector2d;
using Eigen::VectorXd;

/// A plugin call that returned an error code, with the plugin's message.
class PluginCallError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Floating-point traps off for the engine's lifetime, restored after.
class TrapsOff {
 public:
  TrapsOff() : saved_(fegetexcept()) { fedisableexcept(FE_ALL_EXCEPT); }
  ~TrapsOff() {
    feclearexcept(FE_ALL_EXCEPT);
    feenableexcept(saved_);
  }
  TrapsOff(const TrapsOff&) = delete;
  TrapsOff& operator=(const TrapsOff&) = delete;

 private:
  int saved_;
};

/// A state the checks own.
struct Sample {
  Matrix2Xd x, v;
  VectorXd w, r;  // inverse masses, radii
  std::size_t n() const { return static_cast<std::size_t>(x.cols()); }
  pinsim_state_view view() const {
    return {static_cast<uint64_t>(n()), 0.0, x.data(), v.data(), w.data(), r.data()};
  }
};

std::string dof_name(Eigen::Index j) {
  return "particle " + std::to_string(j / 2) + (j % 2 == 0 ? " x" : " y");
}

/// One live plugin instance, destroyed with the object.
class Instance {
 public:
  Instance(const pinsim_plugin* t, const std::string& params, const Sample& initial,
           const CheckLayout& layout)
      : t_(t) {
    const pinsim_state_view iv = initial.view();
    pinsim_create_args a{};
    a.params_json = params.c_str();
    a.scene_json = nullptr;
    a.initial = &iv;
    a.elements = layout.elements.data();
    a.n_elements = layout.count;
    a.arity = layout.arity;
    a.context = "check-plugin";
    char msg[1024] = {0};
    pinsim_error err{msg, sizeof msg};
    self_ = t_->create(&a, &err);
    if (self_ == nullptr)
      throw PluginCallError(std::string("create failed: ") + (msg[0] ? msg : "no message"));
  }
  ~Instance() {
    if (self_ != nullptr) t_->destroy(self_);
  }
  Instance(const Instance&) = delete;
  Instance& operator=(const Instance&) = delete;

  bool has(uint32_t cap) const { return (t_->capabilities & cap) != 0; }

  VectorXd force(const Sample& s) const {
    VectorXd f = VectorXd::Zero(static_cast<Eigen::Index>(2 * s.n()));
    const pinsim_state_view sv = s.view();
    call("add_force",
         [&](pinsim_error* e) { return t_->force.add_force(self_, &sv, f.data(), e); });
    return f;
  }
  double energy(const Sample& s) const {
    double out = 0.0;
    const pinsim_state_view sv = s.view();
    call("energy", [&](pinsim_error* e) { return t_->force.energy(self_, &sv, &out, e); });
    return out;
  }
  /// The constraint entry (PINSIM_CAP_CONSTRAINTS) with this instance's energy and force.
  ConstraintProbe probe(const Sample& like) const {
    ConstraintProbe p;
    call("constraint_set", [&](pinsim_error* e) { return t_->constraint_set(self_, &p.set, e); });
    p.constraints = [this](const double* x, const uint64_t* which, uint64_t count, double* c,
                           double* dc) {
      call("constraints",
           [&](pinsim_error* e) { return t_->constraints(self_, x, which, count, c, dc, e); });
    };
    auto at = [like](const VectorXd& x, const VectorXd& v) {
      Sample s = like;
      s.x = Eigen::Map<const Matrix2Xd>(x.data(), 2, x.size() / 2);
      s.v = Eigen::Map<const Matrix2Xd>(v.data(), 2, v.size() / 2);
      return s;
    };
    if (has(PINSIM_CAP_ENERGY))
      p.energy = [this, at](const VectorXd& x) { return energy(at(x, VectorXd::Zero(x.size()))); };
    p.force = [this, at](const VectorXd& x, const VectorXd& v) { return force(at(x, v)); };
    return p;
  }
  /// Dense df/dx (which = 0) or df/dv (which = 1).
  MatrixXd jacobian(const Sample& s, int which) const {
    const auto m = static_cast<Eigen::Index>(2 * s.n());
    Dense d{MatrixXd::Zero(m, m), false};
    pinsim_triplet_sink sink{&d,
                             [](void* c, uint32_t row, uint32_t col, double v) {
                               auto* dd = static_cast<Dense*>(c);
                               if (row >= dd->m.rows() || col >= dd->m.cols())
                                 dd->out_of_range = true;
                               else
                                 dd->m(row, col) += v;
                             },
                             nullptr};
    const pinsim_state_view sv = s.view();
    call(which == 0 ? "add_jacobians(dfdx)" : "add_jacobians(dfdv)", [&](pinsim_error* e) {
      return t_->force.add_jacobians(self_, &sv, which == 0 ? &sink : nullptr,
                                     which == 1 ? &sink : nullptr, e);
    });
    if (d.out_of_range) throw PluginCallError("Jacobian entry outside the 2n x 2n matrix");
    return d.m;
  }

 private:
  struct Dense {
    MatrixXd m;
    bool out_of_range;
  };
  template <class F>
  void call(const char* what, F&& f) const {
    char msg[1024] = {0};
    pinsim_error err{msg, sizeof msg};
    if (f(&err) != 0)
      throw PluginCallError(std::string(what) +
                            " returned an error: " + (msg[0] ? msg : "no message"));
  }

  const pinsim_plugin* t_;
  void* self_ = nullptr;
};

/// The engine: owns the random generator and the element list.
class Checker {
 public:
  Checker(const LoadedPlugin& p, const CheckOptions& o) : plugin_(p), t_(p.table), opt_(o) {
    rng_.seed(o.seed);
    if (o.scene != nullptr) {
      const ForceSpec& f = o.scene->forces[o.force_index];
      if (f.name != t_->name)
        throw InputError(f.where + ".type: is '" + f.name + "', not the plugin checked ('" +
                         t_->name + "')");
      layout_ = scene_layout(*o.scene, o.force_index, t_->arity);
      nlohmann::json params = f.params.is_object() ? f.params : nlohmann::json::object();
      for (const auto& [k, v] : o.params.items()) params[k] = v;
      params_ = validate_params(*t_, params, f.where + ".params").dump();
    } else {
      layout_ = topology_layout(o.topology, t_->arity);
      params_ = validate_params(*t_, o.params, "check-plugin: params").dump();
    }
    n_ = layout_.n;
  }

  CheckReport run();

 private:
  // --- states -------------------------------------------------------------------------
  double uni(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng_); }

  /// Random positions in [-1, 1]^2 at least 0.2 apart (or the layout's reference
  /// positions perturbed), random velocities, random masses (or the scene's).
  Sample random_state(bool moving = true) {
    Sample s;
    const auto n = static_cast<Eigen::Index>(n_);
    s.x.resize(2, n);
    s.v.resize(2, n);
    s.w.resize(n);
    s.r = VectorXd::Constant(n, 0.05);
    if (layout_.x.cols() == n) {
      for (Eigen::Index i = 0; i < n; ++i) {
        s.x.col(i) = layout_.x.col(i) + layout_.noise * Vector2d(uni(-1, 1), uni(-1, 1));
        s.v.col(i) = moving ? Vector2d(uni(-1, 1), uni(-1, 1)) : Vector2d::Zero();
        s.w[i] = uni(0.5, 2.0);
      }
      if (layout_.from_scene()) {
        s.w = layout_.inv_mass;
        s.r = layout_.radius;
      }
      return s;
    }
    for (Eigen::Index i = 0; i < n; ++i) {
      for (int tries = 0; tries < 1000; ++tries) {
        s.x.col(i) = Vector2d(uni(-1, 1), uni(-1, 1));
        bool ok = true;
        for (Eigen::Index j = 0; j < i; ++j) ok = ok && (s.x.col(i) - s.x.col(j)).norm() > 0.2;
        if (ok) break;
      }
      s.v.col(i) = moving ? Vector2d(uni(-1, 1), uni(-1, 1)) : Vector2d::Zero();
      s.w[i] = uni(0.5, 2.0);
    }
    return s;
  }

  /// The state instances are created from (rest lengths, angles, areas): a random one, or
  /// a scene's own initial state.
  Sample rest_state() {
    if (!layout_.from_scene()) return random_state();
    Sample s;
    s.x = layout_.x;
    s.v = layout_.v;
    s.w = layout_.inv_mass;
    s.r = layout_.radius;
    return s;
  }

  std::unique_ptr<Instance> make(const Sample& initial) {
    return std::make_unique<Instance>(t_, params_, initial, layout_);
  }

  // --- finite differences ----------------------------------------------------------------
  /// Relative discrepancy between an analytic array and its finite-difference estimate.
  static double rel(const MatrixXd& a, const MatrixXd& fd, Eigen::Index* where) {
    const MatrixXd d = (a - fd).cwiseAbs();
    Eigen::Index r = 0, c = 0;
    const double m = d.maxCoeff(&r, &c);
    if (where) *where = r * 1000 + c;
    const double scale = a.cwiseAbs().maxCoeff() + fd.cwiseAbs().maxCoeff() + 1e-12;
    if (!std::isfinite(m)) return std::numeric_limits<double>::infinity();
    return m / scale;
  }

  /// Step-halving verdict: the error at h/2 is small, or it is moderate and shrank like
  /// a consistent (second order) difference quotient. A wrong formula keeps its error.
  bool converged(double e1, double e2) const {
    if (!(e2 <= opt_.fd_tolerance) && !(e2 <= 1e-3 && e2 <= 0.35 * e1)) return false;
    return std::isfinite(e2);
  }

  CheckResult gradient_check();
  CheckResult jacobian_check(int which);
  CheckResult momentum_check(bool angular);
  CheckResult invariance_check();
  CheckResult degenerate_check();
  CheckResult dissipation_check();
  CheckResult constraint_check(int which);

  /// Records a state's error; the reported worst is the worst failing one if any failed.
  static void keep_worst(CheckResult& r, double err, bool ok, const std::string& detail) {
    if (!std::isfinite(err)) err = std::numeric_limits<double>::infinity();
    const bool had_fail = r.status == CheckStatus::Fail;
    bool take = false;
    if (!ok)
      take = !had_fail || err > r.worst;
    else
      take = !had_fail && (r.detail.empty() || err > r.worst);
    if (!ok) r.status = CheckStatus::Fail;
    if (take) {
      r.worst = err;
      r.detail = detail;
    }
  }

  const LoadedPlugin& plugin_;
  const pinsim_plugin* t_;
  CheckOptions opt_;
  std::mt19937_64 rng_;
  CheckLayout layout_;
  std::size_t n_ = 6;
  std::string params_;
};

constexpr double kStep = 1e-4;  // finite-difference step at scene scale 1

CheckResult Checker::gradient_check() {
  CheckResult r{"gradient",        "f = -dE/dx by central differences, step halving",
                CheckStatus::Pass, 0.0,
                opt_.fd_tolerance, ""};
  if (!(t_->capabilities & PINSIM_CAP_ENERGY)) {
    r.status = CheckStatus::Skip;
    r.detail = "no energy (PINSIM_CAP_ENERGY not declared)";
    return r;
  }
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    Sample s = random_state(false);  // v = 0: only the conservative part
    auto inst = make(init);
    const VectorXd f = inst->force(s);
    auto fd = [&](double h) {
      VectorXd g(f.size());
      for (Eigen::Index j = 0; j < f.size(); ++j) {
        Sample p = s, m = s;
        p.x.data()[j] += h;
        m.x.data()[j] -= h;
        g[j] = -(inst->energy(p) - inst->energy(m)) / (2 * h);
      }
      return g;
    };
    const VectorXd g1 = fd(kStep), g2 = fd(kStep / 2);
    Eigen::Index at = 0;
    const double e1 = rel(f, g1, nullptr), e2 = rel(f, g2, &at);
    const Eigen::Index j = at / 1000;
    const bool ok = converged(e1, e2);
    keep_worst(r, e2, ok,
               "state " + std::to_string(trial) + ", " + dof_name(j) + ": f = " + num(f[j], 3) +
                   ", -dE/dx = " + num(g2[j], 3) + "; error " + num(e1, 3) + " at h, " +
                   num(e2, 3) + " at h/2" + (ok ? "" : " (does not converge)"));
  }
  return r;
}

CheckResult Checker::jacobian_check(int which) {
  const char* name = which == 0 ? "dfdx" : "dfdv";
  CheckResult r{name,
                which == 0 ? "df/dx against central differences of f, step halving"
                           : "df/dv against central differences of f, step halving",
                CheckStatus::Pass,
                0.0,
                opt_.fd_tolerance,
                ""};
  const uint32_t cap = which == 0 ? PINSIM_CAP_DFDX : PINSIM_CAP_DFDV;
  if (!(t_->capabilities & cap) || t_->force.add_jacobians == nullptr) {
    r.status = CheckStatus::Skip;
    r.detail = std::string("not provided (PINSIM_CAP_") + (which == 0 ? "DFDX" : "DFDV") +
               " not declared)";
    return r;
  }
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample s = random_state();
    auto inst = make(init);
    const MatrixXd k = inst->jacobian(s, which);
    auto fd = [&](double h) {
      MatrixXd g(k.rows(), k.cols());
      for (Eigen::Index j = 0; j < k.cols(); ++j) {
        Sample p = s, m = s;
        (which == 0 ? p.x : p.v).data()[j] += h;
        (which == 0 ? m.x : m.v).data()[j] -= h;
        g.col(j) = (inst->force(p) - inst->force(m)) / (2 * h);
      }
      return g;
    };
    const MatrixXd g1 = fd(kStep), g2 = fd(kStep / 2);
    Eigen::Index at = 0;
    const double e1 = rel(k, g1, nullptr), e2 = rel(k, g2, &at);
    const Eigen::Index row = at / 1000, col = at % 1000;
    const bool ok = converged(e1, e2);
    keep_worst(r, e2, ok,
               "state " + std::to_string(trial) + ", d(" + dof_name(row) + ")/d(" + dof_name(col) +
                   "): analytic " + num(k(row, col), 3) + ", difference " + num(g2(row, col), 3) +
                   "; error " + num(e1, 3) + " at h, " + num(e2, 3) + " at h/2" +
                   (ok ? "" : " (does not converge)"));
  }
  return r;
}

bool is_internal(const pinsim_plugin* t, const CheckOptions& o) {
  return (t->capabilities & PINSIM_CAP_INTERNAL) || o.assume_internal;
}

double cross(const Vector2d& a, const Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

CheckResult Checker::momentum_check(bool angular) {
  CheckResult r{angular ? "angular_momentum" : "momentum",
                angular ? "internal force: sum of x cross f = 0" : "internal force: sum f = 0",
                CheckStatus::Pass,
                0.0,
                opt_.identity_tolerance,
                ""};
  if (!is_internal(t_, opt_)) {
    r.status = CheckStatus::Skip;
    r.detail = "not an internal force (PINSIM_CAP_INTERNAL not declared)";
    return r;
  }
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample s = random_state();
    auto inst = make(init);
    const VectorXd fv = inst->force(s);
    const Eigen::Map<const Matrix2Xd> f(fv.data(), 2, fv.size() / 2);
    double err = 0.0, scale = 1e-300;
    if (!angular) {
      err = f.rowwise().sum().norm();
      scale += f.colwise().norm().sum();
    } else {
      double tq = 0.0;
      for (Eigen::Index i = 0; i < f.cols(); ++i) {
        tq += cross(s.x.col(i), f.col(i));
        scale += s.x.col(i).norm() * f.col(i).norm();
      }
      err = std::abs(tq);
    }
    const double e = std::isfinite(err) ? err / scale : std::numeric_limits<double>::infinity();
    keep_worst(r, e, e <= r.tolerance,
               "state " + std::to_string(trial) + ": |" + (angular ? "sum x*f" : "sum f") +
                   "| = " + num(err, 3) + " against a scale of " + num(scale, 3));
  }
  return r;
}

CheckResult Checker::invariance_check() {
  CheckResult r{
      "rigid_invariance",      "energy unchanged and forces rotated under random rigid motions",
      CheckStatus::Pass,       0.0,
      opt_.identity_tolerance, ""};
  if (!is_internal(t_, opt_)) {
    r.status = CheckStatus::Skip;
    r.detail = "not an internal force (PINSIM_CAP_INTERNAL not declared)";
    return r;
  }
  const bool has_e = (t_->capabilities & PINSIM_CAP_ENERGY) != 0;
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample s = random_state();
    auto inst = make(init);
    const double th = uni(-M_PI, M_PI);
    Eigen::Matrix2d q;
    q << std::cos(th), -std::sin(th), std::sin(th), std::cos(th);
    const Vector2d tr(uni(-3, 3), uni(-3, 3));
    Sample m = s;
    m.x = (q * s.x).colwise() + tr;
    m.v = q * s.v;
    const VectorXd f0 = inst->force(s), f1 = inst->force(m);
    const Eigen::Map<const Matrix2Xd> a(f0.data(), 2, f0.size() / 2);
    Matrix2Xd rot = q * a;
    const Eigen::Map<const VectorXd> rotv(rot.data(), rot.size());
    const double scale = f0.cwiseAbs().maxCoeff() + 1e-300;
    double e = (f1 - rotv).cwiseAbs().maxCoeff() / scale;
    std::string what = "forces differ from the rotated forces by " + num(e, 3) + " relative";
    if (has_e) {
      const double e0 = inst->energy(s), e1 = inst->energy(m);
      // Scale: |E| plus the work the forces would do over the configuration's extent.
      const double escale = std::abs(e0) + f0.cwiseAbs().sum() * 2.0 + 1e-300;
      const double de = std::abs(e1 - e0) / escale;
      if (!(de <= e)) what = "energy " + num(e0, 3) + " became " + num(e1, 3);
      e = std::max(e, de);
      if (!std::isfinite(de)) e = std::numeric_limits<double>::infinity();
    }
    if (!std::isfinite(e)) e = std::numeric_limits<double>::infinity();
    keep_worst(r, e, e <= r.tolerance,
               "state " + std::to_string(trial) + ", rotation " + num(th, 3) + " rad: " + what);
  }
  return r;
}

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

CheckResult Checker::dissipation_check() {
  CheckResult r{"dissipation",
                "damping never adds energy: (f(x,v) - f(x,0))·v <= 0 and df/dv negative "
                "semidefinite",
                CheckStatus::Pass,
                0.0,
                opt_.identity_tolerance,
                ""};
  if (!(t_->capabilities & PINSIM_CAP_DISSIPATIVE)) {
    r.status = CheckStatus::Skip;
    r.detail = "no damping (PINSIM_CAP_DISSIPATIVE not declared)";
    return r;
  }
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample s = random_state();
    Sample still = s;
    still.v.setZero();
    auto inst = make(init);
    const VectorXd fd = inst->force(s) - inst->force(still);
    const Eigen::Map<const VectorXd> v(s.v.data(), s.v.size());
    const double p = fd.dot(v);
    const double scale = fd.norm() * v.norm() + 1e-300;
    double e = std::max(0.0, p) / scale;
    std::string what = "damping power " + num(p, 3);
    if (inst->has(PINSIM_CAP_DFDV) && t_->force.add_jacobians != nullptr) {
      const MatrixXd k = inst->jacobian(s, 1);
      const MatrixXd sym = 0.5 * (k + k.transpose());
      const double kmax = sym.cwiseAbs().maxCoeff();
      if (kmax > 0 && std::isfinite(kmax)) {
        const double lmax = Eigen::SelfAdjointEigenSolver<MatrixXd>(sym).eigenvalues().maxCoeff();
        const double el = std::max(0.0, lmax) / kmax;
        if (el > e) what = "df/dv has a positive eigenvalue " + num(lmax, 3);
        e = std::max(e, el);
      } else if (!std::isfinite(kmax)) {
        e = std::numeric_limits<double>::infinity();
      }
    }
    if (!std::isfinite(p)) e = std::numeric_limits<double>::infinity();
    keep_worst(r, e, e <= r.tolerance, "state " + std::to_string(trial) + ": " + what);
  }
  return r;
}

// The constraint entry (which: 0 energy, 1 force, 2 gradient) on random states: E = sum
// ks/2 C^2 up to a constant, f = -sum J^T (ks C + kd J v), dC/dp by central differences.
CheckResult Checker::constraint_check(int which) {
  static const char* const names[] = {"constraint_energy", "constraint_force",
                                      "constraint_gradient"};
  static const char* const whats[] = {
      "constraints: E(x) - E(x0) = sum ks/2 (C(x)^2 - C(x0)^2)",
      "constraints: add_force = -sum J^T (ks C + kd J v)",
      "constraints: dC/dp against central differences of C, step halving"};
  CheckResult r{names[which],
                whats[which],
                CheckStatus::Pass,
                0.0,
                which == 2 ? opt_.fd_tolerance : 1e-8,
                ""};
  if (!(t_->capabilities & PINSIM_CAP_CONSTRAINTS)) {
    r.status = CheckStatus::Skip;
    r.detail = "no constraints (PINSIM_CAP_CONSTRAINTS not declared)";
    return r;
  }
  if (which == 0 && !(t_->capabilities & PINSIM_CAP_ENERGY)) {
    r.status = CheckStatus::Skip;
    r.detail = "no energy to compare with (PINSIM_CAP_ENERGY not declared)";
    return r;
  }
  for (int trial = 0; trial < opt_.trials; ++trial) {
    const Sample init = rest_state();
    const Sample a = random_state(), b = random_state();
    auto inst = make(init);
    const ConstraintProbe p = inst->probe(a);
    const Eigen::Map<const VectorXd> xa(a.x.data(), a.x.size()), va(a.v.data(), a.v.size()),
        xb(b.x.data(), b.x.size());
    std::string detail;
    const std::string state = "state " + std::to_string(trial) + ": ";
    if (which == 0) {
      const double e = constraint_energy_error(p, xb, xa, detail);
      keep_worst(r, e, e <= r.tolerance, state + detail);
    } else if (which == 1) {
      const double e = constraint_force_error(p, xa, va, detail);
      keep_worst(r, e, e <= r.tolerance, state + detail);
    } else {
      std::string d1;
      const double e1 = constraint_gradient_error(p, xa, kStep, d1);
      const double e2 = constraint_gradient_error(p, xa, kStep / 2, detail);
      const bool ok = converged(e1, e2);
      keep_worst(r, e2, ok,
                 state + detail + "; error " + num(e1, 3) + " at h, " + num(e2, 3) + " at h/2" +
                     (ok ? "" : " (does not converge)"));
    }
  }
  return r;
}

CheckReport Checker::run() {
  CheckReport rep;
  rep.plugin = t_->name;
  rep.path = plugin_.path.string();
  rep.layout = layout_.description;
  // Creation first: if the plugin cannot even be instantiated, the rest is moot.
  CheckResult create{
      "create", "instances build from random states and element lists", CheckStatus::Pass, 0.0, 0.0,
      ""};
  try {
    make(rest_state());
    create.detail = layout_.description;
  } catch (const std::exception& e) {
    create.status = CheckStatus::Fail;
    create.detail = e.what();
    rep.checks.push_back(create);
    return rep;
  }
  rep.checks.push_back(create);
  using Fn = std::function<CheckResult()>;
  const std::vector<std::pair<std::string, Fn>> checks = {
      {"gradient", [&] { return gradient_check(); }},
      {"dfdx", [&] { return jacobian_check(0); }},
      {"dfdv", [&] { return jacobian_check(1); }},
      {"momentum", [&] { return momentum_check(false); }},
      {"angular_momentum", [&] { return momentum_check(true); }},
      {"rigid_invariance", [&] { return invariance_check(); }},
      {"degenerate", [&] { return degenerate_check(); }},
      {"dissipation", [&] { return dissipation_check(); }},
      {"constraint_energy", [&] { return constraint_check(0); }},
      {"constraint_force", [&] { return constraint_check(1); }},
      {"constraint_gradient", [&] { return constraint_check(2); }},
  };
  for (const auto& [name, fn] : checks) {
    if (!opt_.only.empty() && name != opt_.only) continue;
    // The constraint checks are listed only for a plugin that has constraints (or when asked
    // for by name): a plugin without them is not one check short.
    if (opt_.only.empty() && name.rfind("constraint_", 0) == 0 &&
        !(t_->capabilities & PINSIM_CAP_CONSTRAINTS))
      continue;
    try {
      rep.checks.push_back(fn());
    } catch (const std::exception& e) {
      CheckResult r{name, "",      CheckStatus::Fail, std::numeric_limits<double>::infinity(),
                    0.0,  e.what()};
      rep.checks.push_back(r);
    }
  }
  return rep;
}

const char* status_name(CheckStatus s) {
  switch (s) {
    case CheckStatus::Pass:
      return "pass";
    case CheckStatus::Fail:
      return "FAIL";
    case CheckStatus::Skip:
      return "skip";
  }
  return "?";
}

}  // namespace

bool CheckReport::passed() const {
  return std::none_of(checks.begin(), checks.end(),
                      [](const CheckResult& c) { return c.status == CheckStatus::Fail; });
}

const CheckResult* CheckReport::find(const std::string& name) const {
  for (const auto& c : checks)
    if (c.name == name) return &c;
  return nullptr;
}

CheckReport check_force_plugin(const LoadedPlugin& plugin, const CheckOptions& opt) {
  if (!plugin.is_force())
    throw LoadError(plugin.path.string() + ": '" + plugin.name() +
                    "' is not a force plugin; check-plugin checks force plugins");
  if (opt.scene != nullptr && opt.force_index >= opt.scene->forces.size())
    throw InputError(opt.scene->label + ": --force-index " + std::to_string(opt.force_index) +
                     ": the scene has " + std::to_string(opt.scene->forces.size()) + " force(s)");
  // A table whose flags promise a function it lacks would be called through NULL: its
  // own failure, before anything is called (tables loaded from a file were checked already).
  if (const std::string bad = plugin_table_problems(*plugin.table); !bad.empty()) {
    CheckReport rep;
    rep.plugin = plugin.name();
    rep.path = plugin.path.string();
    rep.checks.push_back({"table", "function pointers match the capability flags",
                          CheckStatus::Fail, std::numeric_limits<double>::infinity(), 0.0, bad});
    return rep;
  }
  TrapsOff traps;
  Checker c(plugin, opt);
  return c.run();
}

std::string format_report(const CheckReport& rep) {
  std::ostringstream o;
  o << "check-plugin " << rep.plugin << " (" << rep.path << ")\n";
  if (!rep.layout.empty()) o << "  on " << rep.layout << "\n";
  for (const auto& c : rep.checks) {
    char line[160];
    std::snprintf(line, sizeof line, "  %-4s  %-17s worst %-9s tol %-8s ", status_name(c.status),
                  c.name.c_str(), c.status == CheckStatus::Skip ? "-" : num(c.worst, 3).c_str(),
                  c.tolerance > 0 ? num(c.tolerance, 3).c_str() : "-");
    o << line << c.detail << "\n";
  }
  int passes = 0, fails = 0;
  std::string skipped;
  for (const auto& c : rep.checks) {
    passes += c.status == CheckStatus::Pass ? 1 : 0;
    fails += c.status == CheckStatus::Fail ? 1 : 0;
    if (c.status == CheckStatus::Skip) skipped += (skipped.empty() ? "" : ", ") + c.name;
  }
  const std::size_t skips = rep.checks.size() - static_cast<std::size_t>(passes + fails);
  o << (fails == 0 ? "PASS" : "FAIL") << ": " << rep.plugin << ", " << rep.checks.size()
    << " checks: " << passes << " passed, " << fails << " failed, " << skips << " skipped"
    << (skips > 0 ? " (" + skipped + ")" : std::string()) << "\n";
  return o.str();
}

nlohmann::json report_json(const CheckReport& rep) {
  nlohmann::json j;
  j["plugin"] = rep.plugin;
  j["path"] = rep.path;
  j["layout"] = rep.layout;
  j["passed"] = rep.passed();
  j["checks"] = nlohmann::json::array();
  for (const auto& c : rep.checks) {
    nlohmann::json cj;
    cj["name"] = c.name;
    cj["what"] = c.what;
    cj["status"] = c.status == CheckStatus::Pass   ? "pass"
                   : c.status == CheckStatus::Fail ? "fail"
                                                   : "skip";
    cj["worst"] = std::isfinite(c.worst) ? nlohmann::json(c.worst) : nlohmann::json("inf");
    cj["tolerance"] = c.tolerance;
    cj["detail"] = c.detail;
    j["checks"].push_back(cj);
  }
  return j;
}

}  // namespace pinsim
