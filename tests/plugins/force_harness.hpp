// Test harness for force plugins: loads a plugin through the loader and drives it through its
// C table (exactly as the host does), plus small integrators for physics tests.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/bodies.hpp"
#include "core/param_validation.hpp"
#include "core/plugin_loader.hpp"

namespace pinsim::test {

/// Plain particle state for tests.
struct Particles {
  Eigen::Matrix2Xd x, v;
  Eigen::VectorXd w, r;  ///< inverse masses, radii
  explicit Particles(Eigen::Index n = 0)
      : x(Eigen::Matrix2Xd::Zero(2, n)),
        v(Eigen::Matrix2Xd::Zero(2, n)),
        w(Eigen::VectorXd::Ones(n)),
        r(Eigen::VectorXd::Constant(n, 0.01)) {}
  std::size_t n() const { return static_cast<std::size_t>(x.cols()); }
  pinsim_state_view view(double t = 0.0) const {
    return {static_cast<uint64_t>(n()), t, x.data(), v.data(), w.data(), r.data()};
  }
};

inline std::shared_ptr<const LoadedPlugin> load_force(const std::string& name) {
  static PluginLoader loader(plugin_search_dirs());
  return loader.load(name);
}

/// One plugin instance created through the C table.
class Force {
 public:
  Force(const std::string& name, const nlohmann::json& params, const Particles& initial,
        std::vector<uint32_t> elements)
      : plugin_(load_force(name)), elements_(std::move(elements)) {
    const pinsim_plugin* t = plugin_->table;
    const std::string pj = validate_params(*t, params, "test: params").dump();
    const pinsim_state_view iv = initial.view();
    pinsim_create_args a{};
    a.params_json = pj.c_str();
    a.initial = &iv;
    a.elements = elements_.data();
    a.arity = t->arity;
    a.n_elements = element_count(elements_, t->arity);  // arity 0: length-prefixed
    a.context = "test";
    char msg[512] = {0};
    pinsim_error err{msg, sizeof msg};
    self_ = t->create(&a, &err);
    if (self_ == nullptr) throw std::runtime_error(std::string("create: ") + msg);
  }
  ~Force() { plugin_->table->destroy(self_); }
  Force(const Force&) = delete;
  Force& operator=(const Force&) = delete;

  /// f += force(s)
  void add(const Particles& s, Eigen::Matrix2Xd& f) const {
    const pinsim_state_view sv = s.view();
    char msg[512] = {0};
    pinsim_error err{msg, sizeof msg};
    if (plugin_->table->force.add_force(self_, &sv, f.data(), &err) != 0)
      throw std::runtime_error(std::string("add_force: ") + msg);
  }
  Eigen::Matrix2Xd force(const Particles& s) const {
    Eigen::Matrix2Xd f = Eigen::Matrix2Xd::Zero(2, s.x.cols());
    add(s, f);
    return f;
  }
  double energy(const Particles& s) const {
    const pinsim_state_view sv = s.view();
    double e = 0.0;
    char msg[512] = {0};
    pinsim_error err{msg, sizeof msg};
    if (plugin_->table->force.energy(self_, &sv, &e, &err) != 0)
      throw std::runtime_error(std::string("energy: ") + msg);
    return e;
  }
  /// Dense df/dx (which = 0) or df/dv (which = 1), received as the host receives it: 2x2
  /// blocks through the sink's add_blocks (block k at particles p[2k], p[2k+1], values
  /// v[4k..4k+3] column-major), single entries through add. With `blocks` false the sink has
  /// no add_blocks, as for a host that predates it: every entry comes through add.
  Eigen::MatrixXd jacobian(const Particles& s, int which, bool blocks = true) const {
    const auto m = static_cast<Eigen::Index>(2 * s.n());
    Eigen::MatrixXd k = Eigen::MatrixXd::Zero(m, m);
    pinsim_triplet_sink sink{&k,
                             [](void* c, uint32_t r, uint32_t col, double v) {
                               (*static_cast<Eigen::MatrixXd*>(c))(r, col) += v;
                             },
                             [](void* c, const uint32_t* p, const double* v, uint64_t count) {
                               auto& km = *static_cast<Eigen::MatrixXd*>(c);
                               for (uint64_t b = 0; b < count; ++b)
                                 km.block<2, 2>(2 * p[2 * b], 2 * p[2 * b + 1]) +=
                                     Eigen::Map<const Eigen::Matrix2d>(v + 4 * b);
                             }};
    if (!blocks) sink.add_blocks = nullptr;
    const pinsim_state_view sv = s.view();
    char msg[512] = {0};
    pinsim_error err{msg, sizeof msg};
    if (plugin_->table->force.add_jacobians(self_, &sv, which == 0 ? &sink : nullptr,
                                            which == 1 ? &sink : nullptr, &err) != 0)
      throw std::runtime_error(std::string("add_jacobians: ") + msg);
    return k;
  }
  const pinsim_plugin& table() const { return *plugin_->table; }

 private:
  std::shared_ptr<const LoadedPlugin> plugin_;
  std::vector<uint32_t> elements_;
  void* self_ = nullptr;
};

/// Sum of the forces of several plugins.
inline Eigen::Matrix2Xd total_force(const std::vector<const Force*>& forces, const Particles& s) {
  Eigen::Matrix2Xd f = Eigen::Matrix2Xd::Zero(2, s.x.cols());
  for (const Force* fo : forces) fo->add(s, f);
  return f;
}

/// Classical RK4 on (x, v) with a = w f(x, v): fourth order, for closed-form comparisons.
inline void rk4_step(const std::vector<const Force*>& forces, Particles& s, double dt) {
  auto acc = [&](const Particles& p) {
    Eigen::Matrix2Xd a = total_force(forces, p);
    for (Eigen::Index i = 0; i < a.cols(); ++i) a.col(i) *= p.w[i];
    return a;
  };
  Particles p = s;
  const Eigen::Matrix2Xd k1x = s.v, k1v = acc(s);
  p.x = s.x + 0.5 * dt * k1x;
  p.v = s.v + 0.5 * dt * k1v;
  const Eigen::Matrix2Xd k2x = p.v, k2v = acc(p);
  p.x = s.x + 0.5 * dt * k2x;
  p.v = s.v + 0.5 * dt * k2v;
  const Eigen::Matrix2Xd k3x = p.v, k3v = acc(p);
  p.x = s.x + dt * k3x;
  p.v = s.v + dt * k3v;
  const Eigen::Matrix2Xd k4x = p.v, k4v = acc(p);
  s.x += dt / 6.0 * (k1x + 2 * k2x + 2 * k3x + k4x);
  s.v += dt / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v);
}

/// Symplectic Euler (the seed's integrator): v += dt w f(x, v); x += dt v.
inline void symplectic_euler_step(const std::vector<const Force*>& forces, Particles& s, double dt,
                                  double drag = 0.0) {
  Eigen::Matrix2Xd f = total_force(forces, s);
  f -= drag * s.v;
  for (Eigen::Index i = 0; i < f.cols(); ++i) s.v.col(i) += dt * s.w[i] * f.col(i);
  s.x += dt * s.v;
}

}  // namespace pinsim::test
