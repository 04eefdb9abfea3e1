// pinsim/constraint_spring.hpp: the generalized (damped) constraint spring, header-only.
//
// Seed lecture, "Generalized spring model" and "Generalized damped springs":
//   E = ks/2 C(p)^2,   f = -J^T (ks C + kd dC/dt),   J = dC/dp,   dC/dt = J v.
// The author writes only C and dC/dp for one element (a stencil of Arity particles):
//
//   class MySpring : public pinsim::ConstraintSpring<MySpring, 3> {
//    public:
//     static pinsim::PluginInfo info();
//     explicit MySpring(const pinsim::CreateContext& ctx)
//         : ConstraintSpring(ctx, ctx.params.real("ks"), ctx.params.real("kd")) {}
//     /// Returns C for element e at positions p (one column per particle) and writes
//     /// dC/dp into dC (same shape).
//     double constraint(std::size_t e, const Stencil& p, Stencil& dC) const;
//     // optional, exact second derivatives d2C/dp2 (dof 2k+c), else the SDK differentiates
//     // your dC/dp by central differences:
//     void constraint_hessian(std::size_t e, const Stencil& p, Hessian& H) const;
//   };
//   PINSIM_PLUGIN(MySpring)
//
// The base provides add_force, energy, add_dfdx and add_dfdv (and add_jacobians, both in one
// pass, which the host calls), so the plugin gets the capabilities ENERGY | DFDX | DFDV; and
// constraint_set and constraints, the constraints themselves (CONSTRAINTS: XPBD runs the
// force as compliant constraints, alpha = 1/ks, check-plugin compares them with the energy).
// Jacobians (s = ks C + kd dC/dt, H = d2C/dp2):
//   df/dx = -ks J^T J - s H - kd J^T (H v)^T       (d(J v)/dx = H v)
//   df/dv = -kd J^T J
// and the derivatives in the two parameters (add_dforce_dparam, for "ks" and "kd" declared
// .differentiable(), as constraint_spring_params() declares them):
//   df/dks = -J^T C,   df/dkd = -J^T (J v)
// with the Jacobians' transposed products (add_jacobian_products) and both in one pass
// (add_adjoint_products: w . df/dks = -(J w) C, w . df/dkd = -(J w)(J v)).
#pragma once

#include <algorithm>
#include <cstdint>
#include <pinsim/parallel.hpp>
#include <pinsim/plugin.hpp>
#include <string>
#include <type_traits>
#include <vector>

namespace pinsim {

/// The two parameters every constraint spring has: stiffness ks and damping kd.
/// `c_units` is the unit of C (e.g. "m" for a length, "1" for an angle or cosine).
inline std::vector<ParamDecl> constraint_spring_params(double ks_default, double kd_default,
                                                       const std::string& c_units) {
  const std::string ks_units = c_units == "1" ? "J" : "J/" + c_units + "^2";
  const std::string kd_units = c_units == "1" ? "J s" : "J s/" + c_units + "^2";
  return {
      real("ks", ks_default).min(0).units(ks_units).doc("stiffness: E = ks/2 C^2").differentiable(),
      real("kd", kd_default).min(0).units(kd_units).doc("damping on dC/dt").differentiable()};
}

template <class Derived, uint32_t Arity>
class ConstraintSpring {
 public:
  static_assert(Arity >= 1 && Arity <= 8, "ConstraintSpring: stencil of 1 to 8 particles");
  static constexpr uint32_t kArity = Arity;
  static constexpr int kDofs = 2 * static_cast<int>(Arity);
  /// Positions (or gradients) of one element's particles, one column per particle.
  using Stencil = Eigen::Matrix<double, 2, static_cast<int>(Arity)>;
  /// Second derivatives over the element's dofs, dof = 2*k + component.
  using Hessian = Eigen::Matrix<double, kDofs, kDofs>;

  /// Stores ks, kd and the element list; checks arity and indices against ctx.initial.
  ConstraintSpring(const CreateContext& ctx, double ks, double kd) : ks_(ks), kd_(kd) {
    idx_ = element_indices(ctx, Arity);
    ks_each_.assign(count(), ks);
    kd_each_.assign(count(), kd);
  }

  /// The elements as constraints: C, particles, ks and kd per element (pinsim/abi.h,
  /// pinsim_constraint_set).
  ConstraintSet constraint_set() const {
    return {count(), Arity, idx_.data(), ks_each_.data(), kd_each_.data()};
  }

  /// c[k] = C of element which[k] at positions x (2n), its dC/dp into dc[2 Arity k ..] (x0 y0
  /// x1 y1 ... over its particles). Only reads: may run on several threads at once.
  void constraints(const double* x, const uint64_t* which, std::size_t n, double* c,
                   double* dc) const {
    for (std::size_t k = 0; k < n; ++k) {
      if (which[k] >= count())
        throw Error("constraints: element " + std::to_string(which[k]) + " of " +
                    std::to_string(count()));
      const auto e = static_cast<std::size_t>(which[k]);
      Stencil p, g;
      for (uint32_t a = 0; a < Arity; ++a) {
        p(0, a) = x[2 * particle(e, a)];
        p(1, a) = x[2 * particle(e, a) + 1];
      }
      c[k] = self().constraint(e, p, g);
      std::copy(g.data(), g.data() + kDofs, dc + static_cast<std::size_t>(kDofs) * k);
    }
  }

  /// f += -J^T (ks C + kd J v) for every element. Serially: element after element, each
  /// subtracting its terms from its particles' forces, so a particle's force gets its terms in
  /// element order. With threads (pinsim/parallel.hpp) and at least kParallelElements
  /// elements, in fixed chunks of elements: a particle whose elements all lie in one chunk
  /// gets its terms from that chunk, directly, in element order; the terms of a particle
  /// whose elements span chunks go to a buffer and are subtracted per particle in element
  /// order after the chunks. Either way each particle's sum has the same operands in the
  /// same order as the serial loop: f is the same to the bit for any thread count.
  void add_force(const StateView& s, ForceOut& f) const {
    const double* x = s.x.data();
    const double* v = s.v.data();
    double* out = f.data();
    const std::size_t m = count();
    // element e's terms sc dC(c, k) into t[2k + c]
    auto terms = [&](std::size_t e, double* t) {
      const uint32_t* id = idx_.data() + e * Arity;
      Stencil p, dC;
      for (uint32_t k = 0; k < Arity; ++k) {
        p(0, k) = x[2 * id[k]];
        p(1, k) = x[2 * id[k] + 1];
      }
      const double c = self().constraint(e, p, dC);
      double cdot = 0.0;
      for (uint32_t k = 0; k < Arity; ++k)
        cdot += dC(0, k) * v[2 * id[k]] + dC(1, k) * v[2 * id[k] + 1];
      const double sc = ks_ * c + kd_ * cdot;
      for (uint32_t k = 0; k < Arity; ++k) {
        t[2 * k] = sc * dC(0, k);
        t[2 * k + 1] = sc * dC(1, k);
      }
    };
    if (m < kParallelElements || available_threads() < 2) {
      double t[kDofs];
      for (std::size_t e = 0; e < m; ++e) {
        terms(e, t);
        const uint32_t* id = idx_.data() + e * Arity;
        for (uint32_t k = 0; k < Arity; ++k) {
          out[2 * id[k]] -= t[2 * k];
          out[2 * id[k] + 1] -= t[2 * k + 1];
        }
      }
      return;
    }
    build_plan();
    double* buf = buffer_.data();
    for_chunks(m, kChunk, [&](std::size_t, std::size_t b, std::size_t e) {
      double t[kDofs];
      for (std::size_t i = b; i < e; ++i) {
        terms(i, t);
        const uint32_t* id = idx_.data() + i * Arity;
        const uint32_t* at = deferred_.data() + i * Arity;
        for (uint32_t k = 0; k < Arity; ++k) {
          if (at[k] == kDirect) {
            out[2 * id[k]] -= t[2 * k];
            out[2 * id[k] + 1] -= t[2 * k + 1];
          } else {
            buf[2 * at[k]] = t[2 * k];
            buf[2 * at[k] + 1] = t[2 * k + 1];
          }
        }
      }
    });
    for_chunks(
        shared_.size(), kParticleChunk,
        [&](std::size_t, std::size_t b, std::size_t e) {
          for (std::size_t r = b; r < e; ++r) {
            const uint32_t q = shared_[r];
            for (uint32_t j = shared_first_[r]; j < shared_first_[r + 1]; ++j) {
              out[2 * q] -= buf[2 * j];
              out[2 * q + 1] -= buf[2 * j + 1];
            }
          }
        },
        Schedule::Even);
  }

  /// Elements from which add_force runs in parallel when threads are available: below it
  /// the serial loop is faster (bench/threads, docs/threads.md).
  static constexpr std::size_t kParallelElements = 8192;

  /// E = sum over elements of ks/2 C^2 (the conservative part).
  double energy(const StateView& s) const {
    double sum = 0.0;
    for (std::size_t e = 0; e < count(); ++e) {
      Stencil dC;
      const double c = self().constraint(e, gather(s.x, e), dC);
      sum += c * c;
    }
    return 0.5 * ks_ * sum;
  }

  /// df/dx = -ks J^T J - (ks C + kd Cdot) H - kd J^T (H v)^T, per element.
  void add_dfdx(const StateView& s, Triplets& out) const {
    for (std::size_t e = 0; e < count(); ++e) {
      const Stencil p = gather(s.x, e), vel = gather(s.v, e);
      Stencil dC;
      const double c = self().constraint(e, p, dC);
      const Eigen::Map<const Eigen::Matrix<double, kDofs, 1>> g(dC.data()), vv(vel.data());
      scatter(e, dfdx(e, p, c, g, vv), out);
    }
  }

  /// Both in one pass over the elements (C and J once per element; what the host asks for
  /// each step): df/dx into *dx, df/dv into *dv, either may be null. The same entries, in
  /// the same order per matrix, as add_dfdx and add_dfdv.
  void add_jacobians(const StateView& s, Triplets* dx, Triplets* dv) const {
    if (dv != nullptr && kd_ == 0.0) dv = nullptr;
    if (dx == nullptr && dv == nullptr) return;
    for (std::size_t e = 0; e < count(); ++e) {
      const Stencil p = gather(s.x, e);
      Stencil dC;
      const double c = self().constraint(e, p, dC);
      const Eigen::Map<const Eigen::Matrix<double, kDofs, 1>> g(dC.data());
      // Block by block, each entry as dfdx() and add_dfdv() compute it (no 2k x 2k
      // matrices formed and copied).
      if (dx != nullptr) {
        const Stencil vel = gather(s.v, e);
        const Eigen::Map<const Eigen::Matrix<double, kDofs, 1>> vv(vel.data());
        const Hessian h = hessian(e, p);
        const double sc = ks_ * c + kd_ * g.dot(vv);
        const Eigen::Matrix<double, kDofs, 1> u = ks_ * g + kd_ * (h * vv);
        for (uint32_t a = 0; a < Arity; ++a)
          for (uint32_t b = 0; b < Arity; ++b) {
            const int ra = 2 * static_cast<int>(a), cb = 2 * static_cast<int>(b);
            const Mat2 k = -(g.template segment<2>(ra) * u.template segment<2>(cb).transpose()) -
                           sc * h.template block<2, 2>(ra, cb);
            dx->add_block(particle(e, a), particle(e, b), k);
          }
      }
      if (dv != nullptr) {
        const Eigen::Matrix<double, kDofs, 1> kg = -kd_ * g;
        for (uint32_t a = 0; a < Arity; ++a)
          for (uint32_t b = 0; b < Arity; ++b) {
            const Mat2 d = kg.template segment<2>(2 * static_cast<int>(a)) *
                           g.template segment<2>(2 * static_cast<int>(b)).transpose();
            dv->add_block(particle(e, a), particle(e, b), d);
          }
      }
    }
  }

  /// df += d f / d ks = -sum J^T C ("ks") or d f / d kd = -sum J^T (J v) ("kd"), element
  /// after element (a derived class with other differentiable parameters defines its own and
  /// calls this one for ks and kd).
  void add_dforce_dparam(const StateView& s, std::string_view param, int, ForceOut& df) const {
    const bool stiffness = param == "ks";
    if (!stiffness && param != "kd")
      throw Error("add_dforce_dparam: no derivative in parameter '" + std::string(param) + "'");
    for (std::size_t e = 0; e < count(); ++e) {
      Stencil dC;
      const double c = self().constraint(e, gather(s.x, e), dC);
      double coef = c;
      if (!stiffness) {
        const Stencil vel = gather(s.v, e);
        coef = dC.cwiseProduct(vel).sum();
      }
      for (uint32_t k = 0; k < Arity; ++k) df.col(particle(e, k)) -= coef * dC.col(k);
    }
  }

  /// gx += (df/dx)^T w and gv += (df/dv)^T w (gv may be null), element by element, with
  /// g = dC/dp, u = ks g + kd H v and H symmetric: (df/dx)^T w = -u (g.w) - (ks C + kd g.v) H w
  /// and (df/dv)^T w = -kd g (g.w), per element's stencil.
  void add_jacobian_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut* gv) const {
    constraint_products(s, w, &gx, gv, nullptr);
  }

  /// add_jacobian_products and, in the same pass, w . d f / d ks = -sum (g.w) C and
  /// w . d f / d kd = -sum (g.w) (g.v) into their slots, found by name among the derived
  /// class's differentiable parameters; any other differentiable parameter's from its
  /// add_dforce_dparam. A derived class with its own add_jacobian_products gets that one, and
  /// the parameters' sums from a pass of their own.
  void add_adjoint_products(const StateView& s, const Field& w, ForceOut& gx, ForceOut* gv,
                            std::span<double> gp) const {
    const FusedSlots& f = fused_slots();
    if (gp.size() != f.total)
      throw Error("add_adjoint_products: " + std::to_string(gp.size()) + " slots given, " +
                  std::to_string(f.total) + " differentiable parameter components declared");
    double two[2] = {0.0, 0.0};
    if constexpr (std::is_same_v<decltype(&Derived::add_jacobian_products),
                                 decltype(&ConstraintSpring::add_jacobian_products)>) {
      constraint_products(s, w, &gx, gv, two);
    } else {
      self().add_jacobian_products(s, w, gx, gv);
      constraint_products(s, w, nullptr, nullptr, two);
    }
    if (f.ks >= 0) gp[static_cast<std::size_t>(f.ks)] += two[0];
    if (f.kd >= 0) gp[static_cast<std::size_t>(f.kd)] += two[1];
    for (const auto& o : f.others) {
      Eigen::Matrix2Xd df = Eigen::Matrix2Xd::Zero(2, w.cols());
      ForceOut out(df.data(), 2, w.cols());
      self().add_dforce_dparam(s, o.name, o.component, out);
      gp[o.slot] += w.cwiseProduct(df).sum();
    }
  }

  /// df/dv = -kd J^T J, per element.
  void add_dfdv(const StateView& s, Triplets& out) const {
    if (kd_ == 0.0) return;
    for (std::size_t e = 0; e < count(); ++e) {
      Stencil dC;
      self().constraint(e, gather(s.x, e), dC);
      const Eigen::Map<const Eigen::Matrix<double, kDofs, 1>> g(dC.data());
      scatter(e, -kd_ * g * g.transpose(), out);
    }
  }

 protected:
  /// Where ks and kd sit among the derived class's differentiable parameter components
  /// (declaration order, a vec2 two; -1 when not declared differentiable), and the others.
  struct FusedSlots {
    struct Other {
      std::string name;
      int component;
      std::size_t slot;
    };
    int ks = -1, kd = -1;
    std::vector<Other> others;
    std::size_t total = 0;
  };
  static const FusedSlots& fused_slots() {
    static const FusedSlots slots = [] {
      FusedSlots f;
      for (const ParamDecl& p : Derived::info().params) {
        if (!(p.flags & PINSIM_PARAM_DIFFERENTIABLE)) continue;
        const int comps = p.type == PINSIM_PARAM_VEC2 ? 2 : 1;
        for (int c = 0; c < comps; ++c, ++f.total) {
          if (comps == 1 && p.name == "ks")
            f.ks = static_cast<int>(f.total);
          else if (comps == 1 && p.name == "kd")
            f.kd = static_cast<int>(f.total);
          else
            f.others.push_back({p.name, c, f.total});
        }
      }
      return f;
    }();
    return slots;
  }

  /// The products of add_jacobian_products (unless gx is null), and with gp the sums
  /// w . d f / d ks, w . d f / d kd into gp[0], gp[1].
  void constraint_products(const StateView& s, const Field& w, ForceOut* gx, ForceOut* gv,
                           double* gp) const {
    if (gx == nullptr || (gv != nullptr && kd_ == 0.0)) gv = nullptr;
    double dks = 0.0, dkd = 0.0;
    for (std::size_t e = 0; e < count(); ++e) {
      const Stencil p = gather(s.x, e), vel = gather(s.v, e), we = gather(w, e);
      Stencil dC;
      const double c = self().constraint(e, p, dC);
      const Eigen::Map<const Eigen::Matrix<double, kDofs, 1>> g(dC.data()), vv(vel.data()),
          wv(we.data());
      const double gw = g.dot(wv), gdv = g.dot(vv);
      dks -= gw * c;
      dkd -= gw * gdv;
      if (gx == nullptr) continue;
      const Hessian h = hessian(e, p);
      const double sc = ks_ * c + kd_ * gdv;
      const Eigen::Matrix<double, kDofs, 1> r = -(ks_ * g + kd_ * (h * vv)) * gw - sc * (h * wv);
      for (uint32_t k = 0; k < Arity; ++k) {
        gx->col(particle(e, k)) += r.template segment<2>(2 * static_cast<int>(k));
        if (gv != nullptr)
          gv->col(particle(e, k)) -= kd_ * gw * g.template segment<2>(2 * static_cast<int>(k));
      }
    }
    if (gp != nullptr) {
      gp[0] += dks;
      gp[1] += dkd;
    }
  }

  /// Number of elements.
  std::size_t count() const { return idx_.size() / Arity; }
  /// Particle k of element e.
  uint32_t particle(std::size_t e, uint32_t k) const { return idx_[e * Arity + k]; }
  /// Positions (or velocities) of element e's particles taken from a 2xN matrix.
  template <class M>
  Stencil gather(const M& m, std::size_t e) const {
    Stencil p;
    for (uint32_t k = 0; k < Arity; ++k) p.col(k) = m.col(particle(e, k));
    return p;
  }
  double ks() const { return ks_; }
  double kd() const { return kd_; }

 private:
  const Derived& self() const { return static_cast<const Derived&>(*this); }

  /// Element e's df/dx = -ks g g^T - (ks C + kd g.v) H - kd g (H v)^T (g = J^T = dC/dp),
  /// computed as -g (ks g + kd H v)^T - (ks C + kd g.v) H: one outer product.
  template <class G>
  Hessian dfdx(std::size_t e, const Stencil& p, double c, const G& g, const G& vv) const {
    const Hessian h = hessian(e, p);
    const double sc = ks_ * c + kd_ * g.dot(vv);
    const Eigen::Matrix<double, kDofs, 1> u = ks_ * g + kd_ * (h * vv);
    return -(g * u.transpose()) - sc * h;
  }

  /// The author's exact Hessian if there is one, else central differences of dC/dp with a
  /// step relative to the stencil's size (error ~1e-10 relative for smooth C).
  Hessian hessian(std::size_t e, const Stencil& p) const {
    Hessian h;
    if constexpr (requires(const Derived& d, const Stencil& q, Hessian& hh) {
                    d.constraint_hessian(std::size_t{0}, q, hh);
                  }) {
      h.setZero();
      self().constraint_hessian(e, p, h);
    } else {
      const Eigen::Vector2d lo = p.rowwise().minCoeff(), hi = p.rowwise().maxCoeff();
      const double size = std::max((hi - lo).maxCoeff(), 1e-300);
      const double step = 1e-5 * size;
      for (int j = 0; j < kDofs; ++j) {
        Stencil qp = p, qm = p, gp, gm;
        qp.data()[j] += step;
        qm.data()[j] -= step;
        self().constraint(e, qp, gp);
        self().constraint(e, qm, gm);
        for (int i = 0; i < kDofs; ++i) h(i, j) = (gp.data()[i] - gm.data()[i]) / (2.0 * step);
      }
      h = (0.5 * (h + h.transpose())).eval();
    }
    return h;
  }

  /// Elements per chunk of the parallel add_force (any value gives the same bits; larger
  /// chunks leave fewer particles whose elements span two chunks: on a grid sheet, about
  /// one row of particles per chunk).
  static constexpr std::size_t kChunk = 16384;
  /// deferred_ value of a slot whose term goes straight into the particle's force.
  static constexpr uint32_t kDirect = 0xffffffffu;

  /// Once: for each slot j = e * Arity + k, kDirect if particle idx_[j] has all its slots in
  /// element chunk e / kChunk, else the slot's place in buffer_, where each such shared
  /// particle shared_[r] has its slots in increasing order at shared_first_[r] ..
  /// shared_first_[r + 1] - 1 (a counting sort of the slots by particle).
  void build_plan() const {
    if (!shared_first_.empty()) return;
    const uint32_t n = idx_.empty() ? 0 : *std::max_element(idx_.begin(), idx_.end()) + 1;
    std::vector<uint32_t> first(static_cast<std::size_t>(n) + 1, 0);
    for (uint32_t q : idx_) ++first[q + 1];
    for (std::size_t q = 0; q < n; ++q) first[q + 1] += first[q];
    std::vector<uint32_t> slots(idx_.size());
    std::vector<uint32_t> at(first.begin(), first.end() - 1);
    for (std::size_t j = 0; j < idx_.size(); ++j) slots[at[idx_[j]]++] = static_cast<uint32_t>(j);
    const std::size_t chunk_slots = kChunk * Arity;
    deferred_.assign(idx_.size(), kDirect);
    shared_.clear();
    shared_first_.assign(1, 0);
    uint32_t placed = 0;
    for (uint32_t q = 0; q < n; ++q) {
      if (first[q] == first[q + 1]) continue;
      if (slots[first[q]] / chunk_slots == slots[first[q + 1] - 1] / chunk_slots) continue;
      for (uint32_t j = first[q]; j < first[q + 1]; ++j) deferred_[slots[j]] = placed++;
      shared_.push_back(q);
      shared_first_.push_back(placed);
    }
    buffer_.assign(2 * static_cast<std::size_t>(placed), 0.0);
  }

  void scatter(std::size_t e, const Hessian& k, Triplets& out) const {
    for (uint32_t a = 0; a < Arity; ++a)
      for (uint32_t b = 0; b < Arity; ++b)
        out.add_block(particle(e, a), particle(e, b),
                      k.template block<2, 2>(2 * static_cast<int>(a), 2 * static_cast<int>(b)));
  }

  double ks_;
  double kd_;
  std::vector<uint32_t> idx_;
  std::vector<double> ks_each_, kd_each_;  ///< ks and kd per element, for constraint_set()
  // Plan and scratch of the parallel add_force (the host calls one instance from one thread
  // at a time; the chunks inside a call write disjoint parts).
  mutable std::vector<uint32_t> deferred_, shared_, shared_first_;
  mutable std::vector<double> buffer_;
};

}  // namespace pinsim
