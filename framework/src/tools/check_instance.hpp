// check-plugin's hold on a plugin: one live instance of it, called through its C table with
// every error code turned into an exception, on states the checks own.
#pragma once

#include <Eigen/Core>
#include <stdexcept>
#include <string>

#include "core/plugin_loader.hpp"
#include "tools/check_layout.hpp"
#include "tools/constraint_checks.hpp"

namespace pinsim::plugin_check {

using Eigen::Matrix2Xd;
using Eigen::MatrixXd;
using Eigen::Vector2d;
using Eigen::VectorXd;

/// A plugin call that returned an error code, with the plugin's message.
class PluginCallError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
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

inline std::string dof_name(Eigen::Index j) {
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
  /// d f / d (component c of parameter `param`) from the plugin (PINSIM_CAP_DPARAM).
  VectorXd dforce_dparam(const Sample& s, uint32_t param, uint32_t c) const {
    VectorXd f = VectorXd::Zero(static_cast<Eigen::Index>(2 * s.n()));
    const pinsim_state_view sv = s.view();
    call("add_dforce_dparam",
         [&](pinsim_error* e) { return t_->add_dforce_dparam(self_, &sv, param, c, f.data(), e); });
    return f;
  }
  /// (df/dx)^T w (which = 0) or (df/dv)^T w (which = 1) from the plugin
  /// (PINSIM_CAP_JACOBIAN_PRODUCTS).
  VectorXd jacobian_product(const Sample& s, const VectorXd& w, int which) const {
    VectorXd gx = VectorXd::Zero(w.size()), gv = gx;
    const pinsim_state_view sv = s.view();
    call("add_jacobian_products", [&](pinsim_error* e) {
      return t_->add_jacobian_products(self_, &sv, w.data(), gx.data(),
                                       which == 1 ? gv.data() : nullptr, e);
    });
    return which == 0 ? gx : gv;
  }
  /// add_adjoint_products at s (PINSIM_CAP_ADJOINT_PRODUCTS): gx, gv (all zero without
  /// PINSIM_CAP_DFDV) and gp, `slots` long.
  void adjoint_products(const Sample& s, const VectorXd& w, bool with_v, uint32_t slots,
                        VectorXd& gx, VectorXd& gv, VectorXd& gp) const {
    gx = VectorXd::Zero(w.size());
    gv = gx;
    gp = VectorXd::Zero(slots);
    const pinsim_state_view sv = s.view();
    call("add_adjoint_products", [&](pinsim_error* e) {
      return t_->add_adjoint_products(self_, &sv, w.data(), gx.data(), with_v ? gv.data() : nullptr,
                                      gp.data(), e);
    });
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

}  // namespace pinsim::plugin_check
