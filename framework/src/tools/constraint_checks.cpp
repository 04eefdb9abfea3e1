#include "tools/constraint_checks.hpp"

#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include "core/format.hpp"

namespace pinsim {
namespace {

/// The set's constraints one after another: particles[start[e] .. start[e + 1]).
struct Flat {
  std::vector<std::size_t> start{0};
  std::vector<uint32_t> particles;
};

Flat flatten(const pinsim_constraint_set& s) {
  Flat f;
  const uint32_t* p = s.particles;
  for (uint64_t e = 0; e < s.count; ++e) {
    const uint32_t len = s.arity == PINSIM_ARITY_VARIABLE ? *p++ : s.arity;
    for (uint32_t a = 0; a < len; ++a) f.particles.push_back(*p++);
    f.start.push_back(f.particles.size());
  }
  return f;
}

/// C and dC/dp of every constraint at x.
void evaluate(const ConstraintProbe& p, const Flat& f, const Eigen::VectorXd& x,
              std::vector<double>& c, std::vector<double>& dc) {
  std::vector<uint64_t> all(p.set.count);
  std::iota(all.begin(), all.end(), uint64_t{0});
  c.assign(p.set.count, 0.0);
  dc.assign(2 * f.particles.size(), 0.0);
  if (p.set.count > 0) p.constraints(x.data(), all.data(), p.set.count, c.data(), dc.data());
}

double finite_or_inf(double e) {
  return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
}

}  // namespace

double constraint_energy_error(const ConstraintProbe& p, const Eigen::VectorXd& x0,
                               const Eigen::VectorXd& x, std::string& detail) {
  const Flat f = flatten(p.set);
  std::vector<double> c, dc;
  auto u = [&](const Eigen::VectorXd& at) {
    evaluate(p, f, at, c, dc);
    double sum = 0.0;
    for (uint64_t e = 0; e < p.set.count; ++e) sum += 0.5 * p.set.ks[e] * c[e] * c[e];
    return sum;
  };
  const double de = p.energy(x) - p.energy(x0), du = u(x) - u(x0);
  detail = "E(x) - E(x0) = " + num(de, 6) + ", sum ks/2 C^2 changed by " + num(du, 6);
  return finite_or_inf(std::abs(de - du) / (std::abs(de) + std::abs(du) + 1e-300));
}

double constraint_force_error(const ConstraintProbe& p, const Eigen::VectorXd& x,
                              const Eigen::VectorXd& v, std::string& detail) {
  const Flat f = flatten(p.set);
  std::vector<double> c, dc;
  evaluate(p, f, x, c, dc);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(x.size());
  for (uint64_t e = 0; e < p.set.count; ++e) {
    const double* d = dc.data() + 2 * f.start[e];
    double cdot = 0.0;
    for (std::size_t a = 0; a < f.start[e + 1] - f.start[e]; ++a) {
      const uint32_t i = f.particles[f.start[e] + a];
      cdot += d[2 * a] * v[2 * i] + d[2 * a + 1] * v[2 * i + 1];
    }
    const double s = p.set.ks[e] * c[e] + p.set.kd[e] * cdot;
    for (std::size_t a = 0; a < f.start[e + 1] - f.start[e]; ++a) {
      const uint32_t i = f.particles[f.start[e] + a];
      g[2 * i] -= s * d[2 * a];
      g[2 * i + 1] -= s * d[2 * a + 1];
    }
  }
  const Eigen::VectorXd fp = p.force(x, v);
  Eigen::Index at = 0;
  const double diff = (fp - g).cwiseAbs().maxCoeff(&at);
  const double scale = fp.cwiseAbs().maxCoeff() + g.cwiseAbs().maxCoeff() + 1e-300;
  detail = "dof " + std::to_string(at) + ": add_force " + num(fp[at], 6) +
           ", -J^T (ks C + kd J v) " + num(g[at], 6);
  return finite_or_inf(diff / scale);
}

double constraint_gradient_error(const ConstraintProbe& p, const Eigen::VectorXd& x, double h,
                                 std::string& detail) {
  const Flat f = flatten(p.set);
  std::vector<double> c, dc, cp, cm, scratch;
  evaluate(p, f, x, c, dc);
  double worst = 0.0, scale = 1e-300;
  for (double d : dc) scale = std::max(scale, std::abs(d));
  for (uint64_t e = 0; e < p.set.count; ++e)
    for (std::size_t a = 0; a < f.start[e + 1] - f.start[e]; ++a)
      for (int k = 0; k < 2; ++k) {
        const uint32_t i = f.particles[f.start[e] + a];
        Eigen::VectorXd xp = x, xm = x;
        xp[2 * i + k] += h;
        xm[2 * i + k] -= h;
        evaluate(p, f, xp, cp, scratch);
        evaluate(p, f, xm, cm, scratch);
        const double fd = (cp[e] - cm[e]) / (2.0 * h);
        const double an = dc[2 * (f.start[e] + a) + static_cast<std::size_t>(k)];
        const double err = std::abs(fd - an);
        if (!(err <= worst)) {
          worst = err;
          detail = "constraint " + std::to_string(e) + ", particle " + std::to_string(i) +
                   (k == 0 ? " x" : " y") + ": dC/dp " + num(an, 6) + ", difference " + num(fd, 6);
        }
      }
  return finite_or_inf(worst / scale);
}

}  // namespace pinsim
