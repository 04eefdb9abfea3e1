// A "bending" submission that declares the shipped plugin's options but implements only the
// flat rest shape (seed: E = -k/2 â·b̂, a = p1 - p0, b = p2 - p1, s = â·b̂,
// f0 = -k/(2|a|) (b̂ - â s), f2 = k/(2|b|) (â - b̂ s), f1 = -f0 - f2): the force rubric's
// option tests (rest shape, rest angle, length scaling) must catch it.
#include <pinsim/plugin.hpp>
#include <vector>

class FlatOnlyBending {
 public:
  static pinsim::PluginInfo info() {
    pinsim::PluginInfo i;
    i.name = "bending";
    i.doc = "test fixture: flat rest shape only, options ignored";
    i.arity = 3;
    i.capabilities = PINSIM_CAP_INTERNAL;
    i.params.push_back(pinsim::real("k", 1.0).min(0));
    i.params.push_back(pinsim::string("shape", "flat").choices("flat|initial|angle"));
    i.params.push_back(pinsim::real("rest_angle", 0.0));
    i.params.push_back(pinsim::boolean("length_scaled", false));
    return i;
  }
  explicit FlatOnlyBending(const pinsim::CreateContext& c) : k_(c.params.real("k")) {
    idx_.assign(c.elements.data, c.elements.data + 3 * c.elements.count);
  }
  void add_force(const pinsim::StateView& s, pinsim::ForceOut& f) const {
    for (std::size_t e = 0; 3 * e < idx_.size(); ++e) {
      const pinsim::Vec2 a = s.x.col(idx_[3 * e + 1]) - s.x.col(idx_[3 * e]);
      const pinsim::Vec2 b = s.x.col(idx_[3 * e + 2]) - s.x.col(idx_[3 * e + 1]);
      const double la = a.norm(), lb = b.norm();
      if (!(la > 0 && lb > 0)) continue;
      const pinsim::Vec2 ah = a / la, bh = b / lb;
      const double dot = ah.dot(bh);
      const pinsim::Vec2 f0 = -k_ / (2 * la) * (bh - ah * dot);
      const pinsim::Vec2 f2 = k_ / (2 * lb) * (ah - bh * dot);
      f.col(idx_[3 * e]) += f0;
      f.col(idx_[3 * e + 2]) += f2;
      f.col(idx_[3 * e + 1]) -= f0 + f2;
    }
  }
  double energy(const pinsim::StateView& s) const {
    double sum = 0;
    for (std::size_t e = 0; 3 * e < idx_.size(); ++e) {
      const pinsim::Vec2 a = s.x.col(idx_[3 * e + 1]) - s.x.col(idx_[3 * e]);
      const pinsim::Vec2 b = s.x.col(idx_[3 * e + 2]) - s.x.col(idx_[3 * e + 1]);
      if (a.norm() > 0 && b.norm() > 0) sum += -0.5 * k_ * a.normalized().dot(b.normalized());
    }
    return sum;
  }

 private:
  double k_;
  std::vector<uint32_t> idx_;
};

PINSIM_PLUGIN(FlatOnlyBending)
