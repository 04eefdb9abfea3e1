#include "core/block_krylov.hpp"

#include <cmath>
#include <limits>

namespace pinsim {

void BlockSystem::index() {
  const int64_t np = a.rows();
  diag_block.resize(static_cast<std::size_t>(np));
  for (int64_t i = 0; i < np; ++i) diag_block[static_cast<std::size_t>(i)] = a.find(i, i);
  tblock.resize(static_cast<std::size_t>(a.blocks()));
  for (int64_t i = 0; i < np; ++i)
    for (int64_t k = a.first[static_cast<std::size_t>(i)];
         k < a.first[static_cast<std::size_t>(i) + 1]; ++k)
      tblock[static_cast<std::size_t>(k)] = a.find(a.col[static_cast<std::size_t>(k)], i);
}

bool BlockSystem::symmetric_pattern() const {
  return std::all_of(tblock.begin(), tblock.end(), [](int64_t t) { return t >= 0; });
}

bool BlockSystem::is_symmetric(std::vector<double>& root) const {
  const int64_t np = a.rows();
  if (root.size() != static_cast<std::size_t>(2 * np))
    root.resize(static_cast<std::size_t>(2 * np));
  double* sd = root.data();
  const double* v = a.value.data();
  for (int64_t i = 0; i < np; ++i) {
    const double* d = v + 4 * diag_block[static_cast<std::size_t>(i)];
    sd[2 * i] = std::sqrt(std::abs(d[0]));
    sd[2 * i + 1] = std::sqrt(std::abs(d[3]));
  }
  for (int64_t i = 0; i < np; ++i) {
    for (int64_t k = a.first[static_cast<std::size_t>(i)];
         k < a.first[static_cast<std::size_t>(i) + 1]; ++k) {
      const int64_t j = a.col[static_cast<std::size_t>(k)];
      const int64_t t = tblock[static_cast<std::size_t>(k)];
      const double* q = v + 4 * k;
      if (j == i) {
        if (!(std::abs(q[1] - q[2]) <= 1e-13 * (sd[2 * i] * sd[2 * i + 1]))) return false;
        continue;
      }
      if (t >= 0 && j < i) continue;  // the pair, seen from the other side
      for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 2; ++c) {
          const double diff = t < 0 ? q[2 * r + c] : q[2 * r + c] - v[4 * t + 2 * c + r];
          if (!(std::abs(diff) <= 1e-13 * (sd[2 * i + r] * sd[2 * j + c]))) return false;
        }
    }
  }
  return true;
}

void BlockSystem::transpose_into(BlockSystem& out) const {
  const double* in = a.value.data();
  out.a.value.resize(a.value.size());
  double* o = out.a.value.data();
  // block q of A^T holds the transpose of A's block k
  auto put = [&](std::size_t q, std::size_t k) {
    const double* b = in + 4 * k;
    o[4 * q] = b[0];
    o[4 * q + 1] = b[2];
    o[4 * q + 2] = b[1];
    o[4 * q + 3] = b[3];
  };
  if (symmetric_pattern()) {  // A's pattern: block k at (i, j) of A^T is A's (j, i)
    out.a.first = a.first;
    out.a.col = a.col;
    out.diag_block = diag_block;
    out.tblock = tblock;
    for (std::size_t k = 0; k < tblock.size(); ++k) put(k, static_cast<std::size_t>(tblock[k]));
    return;
  }
  // A^T's own pattern: A's blocks by column (rows of A^T), each column's rows in order
  const int64_t np = a.rows();
  out.a.first.assign(static_cast<std::size_t>(np) + 1, 0);
  for (const int32_t j : a.col) ++out.a.first[static_cast<std::size_t>(j) + 1];
  for (int64_t j = 0; j < np; ++j)
    out.a.first[static_cast<std::size_t>(j) + 1] += out.a.first[static_cast<std::size_t>(j)];
  out.a.col.resize(a.col.size());
  std::vector<int64_t> next(out.a.first.begin(), out.a.first.end() - 1);
  for (int64_t i = 0; i < np; ++i)
    for (int64_t k = a.first[static_cast<std::size_t>(i)];
         k < a.first[static_cast<std::size_t>(i) + 1]; ++k) {
      const auto q = static_cast<std::size_t>(
          next[static_cast<std::size_t>(a.col[static_cast<std::size_t>(k)])]++);
      out.a.col[q] = static_cast<int32_t>(i);
      put(q, static_cast<std::size_t>(k));
    }
  out.index();
}

void BlockKrylov::resize(int64_t np) {
  np_ = np;
  const Eigen::Index n = 2 * np;
  for (Eigen::VectorXd* x : {&r0_, &p_, &v_, &y_, &z_, &s_, &t_, &inv_diag_})
    if (x->size() != n) x->resize(n);
}

double BlockKrylov::residual_of(const BlockSystem& s, const Eigen::VectorXd& b,
                                const Eigen::VectorXd& x, Eigen::VectorXd& r) {
  const double* bd = b.data();
  double* out = r.data();
  return sum_rows<1>([&](int64_t lo, int64_t hi, double* sum) {
    s.a.multiply(x.data(), lo, hi, [&](int64_t i, double y0, double y1) {
      out[2 * i] = bd[2 * i] - y0;
      out[2 * i + 1] = bd[2 * i + 1] - y1;
      sum[0] += out[2 * i] * out[2 * i];
      sum[1] += out[2 * i + 1] * out[2 * i + 1];
    });
  })[0];
}

double BlockKrylov::product(const BlockSystem& s, const double* in, double* out, const double* w) {
  return sum_rows<1>([&](int64_t lo, int64_t hi, double* sum) {
    s.a.multiply(in, lo, hi, [&](int64_t i, double y0, double y1) {
      out[2 * i] = y0;
      out[2 * i + 1] = y1;
      sum[0] += w[2 * i] * y0;
      sum[1] += w[2 * i + 1] * y1;
    });
  })[0];
}

void BlockKrylov::jacobi(const BlockSystem& s) {
  for_rows([&](int64_t lo, int64_t hi) {
    for (int64_t i = lo; i < hi; ++i) {
      const double* d = s.a.value.data() + 4 * s.diag_block[static_cast<std::size_t>(i)];
      inv_diag_[2 * i] = d[0] != 0.0 ? 1.0 / d[0] : 1.0;
      inv_diag_[2 * i + 1] = d[3] != 0.0 ? 1.0 / d[3] : 1.0;
    }
  });
}

BlockKrylov::Solve BlockKrylov::cg(const BlockSystem& s, double bb, Eigen::VectorXd& xv,
                                   Eigen::VectorXd& rv, Eigen::Index max_iterations) {
  Solve out;
  if (bb == 0.0) {
    xv.setZero();
    out.converged = true;
    return out;
  }
  jacobi(s);
  double* x = xv.data();
  double* r = rv.data();
  double* p = p_.data();
  double* q = v_.data();  // A p
  double* z = z_.data();
  const double* d = inv_diag_.data();
  const double threshold = std::max(1e-24 * bb, std::numeric_limits<double>::min());
  const auto first = sum_rows<2>([&](int64_t lo, int64_t hi, double* sum) {
    for (int64_t i = 2 * lo; i < 2 * hi; ++i) {
      p[i] = d[i] * r[i];
      sum[i & 1] += r[i] * r[i];
      sum[2 + (i & 1)] += r[i] * p[i];
    }
  });
  double r2 = first[0], abs_new = first[1];
  Eigen::Index it = 0;
  while (!(r2 < threshold) && it < max_iterations && r2 == r2) {
    const double alpha = abs_new / product(s, p, q, p);
    const auto next = sum_rows<2>([&](int64_t lo, int64_t hi, double* sum) {
      for (int64_t i = 2 * lo; i < 2 * hi; ++i) {
        x[i] += alpha * p[i];
        r[i] -= alpha * q[i];
        z[i] = d[i] * r[i];
        sum[i & 1] += r[i] * r[i];
        sum[2 + (i & 1)] += r[i] * z[i];
      }
    });
    ++it;
    r2 = next[0];
    if (r2 < threshold) break;
    const double abs_old = abs_new;
    abs_new = next[1];
    const double beta = abs_new / abs_old;
    for_rows([&](int64_t lo, int64_t hi) {
      for (int64_t i = 2 * lo; i < 2 * hi; ++i) p[i] = z[i] + beta * p[i];
    });
  }
  out.iterations = it;
  out.residual = std::sqrt(r2 / bb);
  out.converged = out.residual <= 1e-12;
  return out;
}

BlockKrylov::Solve BlockKrylov::bicgstab(const BlockSystem& s, const Eigen::VectorXd& b, double bb,
                                         Eigen::VectorXd& xv, Eigen::VectorXd& rv,
                                         Eigen::Index max_iterations) {
  Solve out;
  if (bb == 0.0) {
    xv.setZero();
    out.converged = true;
    return out;
  }
  jacobi(s);
  double* x = xv.data();
  double* r = rv.data();
  double* r0 = r0_.data();
  double* p = p_.data();
  double* v = v_.data();
  double* y = y_.data();
  double* z = z_.data();
  double* sv = s_.data();
  double* t = t_.data();
  const double* d = inv_diag_.data();
  const double tol2 = 1e-24 * bb;
  const double eps2 =
      std::numeric_limits<double>::epsilon() * std::numeric_limits<double>::epsilon();
  double r2 = sum_rows<1>([&](int64_t lo, int64_t hi, double* sum) {
    for (int64_t i = 2 * lo; i < 2 * hi; ++i) {
      r0[i] = r[i];
      p[i] = v[i] = 0.0;
      sum[i & 1] += r[i] * r[i];
    }
  })[0];
  double r0_sqnorm = r2, rho_next = r2;
  double rho = 1.0, alpha = 1.0, w = 1.0;
  Eigen::Index it = 0;
  while (r2 > tol2 && it < max_iterations) {
    const double rho_old = rho;
    rho = rho_next;
    if (std::abs(rho) < eps2 * r0_sqnorm) {  // r nearly orthogonal to r0: restart
      r2 = residual_of(s, b, xv, rv);
      for_rows([&](int64_t lo, int64_t hi) {
        for (int64_t i = 2 * lo; i < 2 * hi; ++i) r0[i] = r[i];
      });
      rho = r0_sqnorm = r2;
    }
    const double beta = (rho / rho_old) * (alpha / w);
    for_rows([&](int64_t lo, int64_t hi) {
      for (int64_t i = 2 * lo; i < 2 * hi; ++i) {
        p[i] = r[i] + beta * (p[i] - w * v[i]);
        y[i] = d[i] * p[i];
      }
    });
    alpha = rho / product(s, y, v, r0);
    const double s2 = sum_rows<1>([&](int64_t lo, int64_t hi, double* sum) {
      for (int64_t i = 2 * lo; i < 2 * hi; ++i) {
        sv[i] = r[i] - alpha * v[i];
        z[i] = d[i] * sv[i];
        sum[i & 1] += sv[i] * sv[i];
      }
    })[0];
    ++it;
    if (s2 <= tol2) {  // converged halfway: x + alpha y
      for_rows([&](int64_t lo, int64_t hi) {
        for (int64_t i = 2 * lo; i < 2 * hi; ++i) {
          x[i] += alpha * y[i];
          r[i] = sv[i];
        }
      });
      r2 = s2;
      break;
    }
    const auto tz = sum_rows<2>([&](int64_t lo, int64_t hi, double* sum) {
      s.a.multiply(z, lo, hi, [&](int64_t i, double y0, double y1) {
        t[2 * i] = y0;
        t[2 * i + 1] = y1;
        sum[0] += y0 * y0;
        sum[1] += y1 * y1;
        sum[2] += y0 * sv[2 * i];
        sum[3] += y1 * sv[2 * i + 1];
      });
    });
    const double t2 = tz[0];
    w = t2 > 0.0 ? tz[1] / t2 : 0.0;
    const auto rn = sum_rows<2>([&](int64_t lo, int64_t hi, double* sum) {
      for (int64_t i = 2 * lo; i < 2 * hi; ++i) {
        x[i] += alpha * y[i] + w * z[i];
        r[i] = sv[i] - w * t[i];
        sum[i & 1] += r[i] * r[i];
        sum[2 + (i & 1)] += r0[i] * r[i];
      }
    });
    r2 = rn[0];
    rho_next = rn[1];
  }
  out.iterations = it;
  out.residual = std::sqrt(r2 / bb);
  out.converged = out.residual <= 1e-12;
  return out;
}

}  // namespace pinsim
