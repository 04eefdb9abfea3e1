// my_anchor: every listed particle is tied to a fixed anchor point by a zero-rest-length
// spring and slowed by linear drag. A template: rename it, change the physics, keep the shape.
//
//   E = k/2 |x_i - anchor|^2          (seed, "Hooke's Law for nD linear springs")
//   f_i = -k (x_i - anchor) - c v_i    (the drag part is dissipative: it has no energy)
//   df_i/dx_i = -k I,  df_i/dv_i = -c I
//   df_i/dk = -(x_i - anchor),  df_i/danchor = k I,  df_i/dc = -v_i
#include <pinsim/plugin.hpp>
#include <string>
#include <string_view>
#include <vector>

class MyAnchor {
 public:
  /// Name, documentation, arity and the parameters the scene may set (with units).
  static pinsim::PluginInfo info() {
    pinsim::PluginInfo i;
    i.name = "my_anchor";  // the scene's "type"; the library must be libpinsim_plugin_<name>.so
    i.version = "1.0.0";
    i.doc = "Zero-rest-length spring from each listed particle to a fixed anchor, plus drag";
    i.arity = 1;  // one particle per element (2 = pairs, 3 = triples)
    i.capabilities = PINSIM_CAP_DISSIPATIVE;
    // .differentiable(): add_dforce_dparam below gives df/dparam (pinsim grad, pinsim fit)
    i.params.push_back(
        pinsim::real("k", 10.0).min(0).units("N/m").doc("spring stiffness").differentiable());
    i.params.push_back(
        pinsim::vec2("anchor", 0.0, 0.0).units("m").doc("anchor point").differentiable());
    i.params.push_back(
        pinsim::real("c", 0.1).min(0).units("N s/m").doc("linear drag").differentiable());
    return i;
  }

  /// Reads the (validated) parameters and the element list; throw pinsim::Error on bad input.
  explicit MyAnchor(const pinsim::CreateContext& ctx)
      : k_(ctx.params.real("k")),
        c_(ctx.params.real("c")),
        anchor_(ctx.params.vec2("anchor")),
        // One particle per element; throws, naming the scene entry, on a wrong arity or an
        // index out of range.
        particles_(pinsim::element_indices(ctx, 1)) {}

  /// f += force. s.x and s.v are 2xN (one column per particle).
  void add_force(const pinsim::StateView& s, pinsim::ForceOut& f) const {
    for (uint32_t p : particles_) f.col(p) += -k_ * (s.x.col(p) - anchor_) - c_ * s.v.col(p);
  }

  /// Potential energy of the conservative part; f(x, v = 0) must equal -dE/dx.
  double energy(const pinsim::StateView& s) const {
    double e = 0.0;
    for (uint32_t p : particles_) e += 0.5 * k_ * (s.x.col(p) - anchor_).squaredNorm();
    return e;
  }

  /// Jacobians for implicit integrators: J.add_block(i, j, M) adds df_i/dx_j (2x2).
  void add_dfdx(const pinsim::StateView&, pinsim::Triplets& J) const {
    for (uint32_t p : particles_) J.add_block(p, p, -k_ * pinsim::Mat2::Identity());
  }
  void add_dfdv(const pinsim::StateView&, pinsim::Triplets& J) const {
    for (uint32_t p : particles_) J.add_block(p, p, -c_ * pinsim::Mat2::Identity());
  }

  /// Optional, for gradients in the parameters: df += d f / d param (component 0, or 0 and 1
  /// of a vec2). check-plugin compares it with differences of add_force.
  void add_dforce_dparam(const pinsim::StateView& s, std::string_view param, int component,
                         pinsim::ForceOut& df) const {
    for (uint32_t p : particles_) {
      if (param == "k") df.col(p) -= s.x.col(p) - anchor_;
      if (param == "anchor") df(component, p) += k_;
      if (param == "c") df.col(p) -= s.v.col(p);
    }
  }

 private:
  double k_, c_;
  pinsim::Vec2 anchor_;
  std::vector<uint32_t> particles_;
};

PINSIM_PLUGIN(MyAnchor)
