// Test fixture: a finite-rest-length Hooke spring that provides force and energy but no
// Jacobian, so implicit Euler must fall back to finite differences.
#include <cmath>
#include <pinsim/plugin.hpp>
#include <vector>

class SpringNoJac {
 public:
  static pinsim::PluginInfo info() {
    pinsim::PluginInfo i;
    i.name = "spring_nojac";
    i.doc = "test fixture: Hooke spring f_k = -k (R - L) R^ without Jacobians";
    i.arity = 2;
    i.capabilities = PINSIM_CAP_INTERNAL;
    i.params.push_back(pinsim::real("k", 100.0).min(0).units("N/m").doc("stiffness"));
    i.params.push_back(pinsim::real("rest_length", 1.0).min(0).units("m").doc("rest length"));
    return i;
  }
  explicit SpringNoJac(const pinsim::CreateContext& c)
      : k_(c.params.real("k")), l_(c.params.real("rest_length")) {
    idx_.assign(c.elements.data, c.elements.data + 2 * c.elements.count);
  }
  void add_force(const pinsim::StateView& s, pinsim::ForceOut& f) const {
    for (std::size_t e = 0; e + 1 < idx_.size(); e += 2) {
      const pinsim::Vec2 d = s.x.col(idx_[e]) - s.x.col(idx_[e + 1]);
      const double r = d.norm();
      if (!(r > 0.0)) continue;
      const pinsim::Vec2 fk = -k_ * (r - l_) / r * d;
      f.col(idx_[e]) += fk;
      f.col(idx_[e + 1]) -= fk;
    }
  }
  double energy(const pinsim::StateView& s) const {
    double E = 0.0;
    for (std::size_t e = 0; e + 1 < idx_.size(); e += 2) {
      const double r = (s.x.col(idx_[e]) - s.x.col(idx_[e + 1])).norm();
      E += 0.5 * k_ * (r - l_) * (r - l_);
    }
    return E;
  }

 private:
  double k_, l_;
  std::vector<uint32_t> idx_;
};

PINSIM_PLUGIN(SpringNoJac)
