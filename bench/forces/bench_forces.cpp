// Forces for 1e5 damped springs and 1e5 bending triples through the plugin interface (the
// C table, exactly as the simulation calls it), beside a plain hand-written loop over the
// same 2xN doubles. Prints CSV: force, variant, elements, ns per element (median of
// repeats), million elements per second, checksum (sum of |f|, equal for equal work).
//
// Usage: pinsim_bench_forces [elements=100000] [repeats=15]
#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/param_validation.hpp"
#include "core/plugin_loader.hpp"

namespace {

using Clock = std::chrono::steady_clock;

struct Setup {
  Eigen::Matrix2Xd x, v;
  Eigen::VectorXd w, r;
  std::vector<uint32_t> elements;
  pinsim_state_view view() const {
    return {static_cast<uint64_t>(x.cols()), 0.0, x.data(), v.data(), w.data(), r.data()};
  }
};

/// A wavy chain of n particles (consecutive ones 0.1 apart), random velocities, and the
/// elements as sliding windows of `arity` along it.
Setup chain(std::size_t elements, uint32_t arity) {
  const auto n = static_cast<Eigen::Index>(elements + arity - 1);
  Setup s;
  s.x.resize(2, n);
  s.v.resize(2, n);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (Eigen::Index i = 0; i < n; ++i) {
    s.x.col(i) << 0.1 * static_cast<double>(i) + 0.02 * u(rng), 0.03 * u(rng);
    s.v.col(i) << u(rng), u(rng);
  }
  s.w = Eigen::VectorXd::Ones(n);
  s.r = Eigen::VectorXd::Constant(n, 0.01);
  for (std::size_t e = 0; e < elements; ++e)
    for (uint32_t k = 0; k < arity; ++k) s.elements.push_back(static_cast<uint32_t>(e + k));
  return s;
}

/// Median ns per element of `fn` over `repeats` timed runs (after one warm-up).
double time_ns(const std::function<void()>& fn, std::size_t elements, int repeats) {
  fn();
  std::vector<double> t;
  for (int i = 0; i < repeats; ++i) {
    const auto a = Clock::now();
    fn();
    const auto b = Clock::now();
    t.push_back(std::chrono::duration<double, std::nano>(b - a).count() /
                static_cast<double>(elements));
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

void row(const char* force, const char* variant, std::size_t m, double ns, double checksum) {
  std::printf("%s,%s,%zu,%.3f,%.1f,%.9e\n", force, variant, m, ns, 1e3 / ns, checksum);
}

/// Plain damped spring, the seed's f_k = -R̂ {ks (R - L) + kd Ṙ}, on raw 2xN arrays.
void plain_springs(const double* x, const double* v, const uint32_t* id, const double* rest,
                   std::size_t m, double ks, double kd, double* f) {
  for (std::size_t e = 0; e < m; ++e) {
    const uint32_t a = id[2 * e], b = id[2 * e + 1];
    const double rx = x[2 * a] - x[2 * b], ry = x[2 * a + 1] - x[2 * b + 1];
    const double r = std::sqrt(rx * rx + ry * ry);
    const double inv = r > 1e-100 ? 1.0 / r : 0.0;
    const double nx = rx * inv, ny = ry * inv;
    const double rdot = (v[2 * a] - v[2 * b]) * nx + (v[2 * a + 1] - v[2 * b + 1]) * ny;
    const double s = ks * (r - rest[e]) + kd * rdot;
    f[2 * a] -= s * nx;
    f[2 * a + 1] -= s * ny;
    f[2 * b] += s * nx;
    f[2 * b + 1] += s * ny;
  }
}

/// Plain seed bending: f0 = -k/(2a)(b̂ - â(â·b̂)), f2 = k/(2b)(â - b̂(â·b̂)), f1 = -f0 - f2.
void plain_bending(const double* x, const uint32_t* id, std::size_t m, double k, double* f) {
  for (std::size_t e = 0; e < m; ++e) {
    const uint32_t i0 = id[3 * e], i1 = id[3 * e + 1], i2 = id[3 * e + 2];
    const double ax = x[2 * i1] - x[2 * i0], ay = x[2 * i1 + 1] - x[2 * i0 + 1];
    const double bx = x[2 * i2] - x[2 * i1], by = x[2 * i2 + 1] - x[2 * i1 + 1];
    const double la = std::sqrt(ax * ax + ay * ay), lb = std::sqrt(bx * bx + by * by);
    if (!(la > 1e-100 && lb > 1e-100)) continue;
    const double ia = 1.0 / la, ib = 1.0 / lb;
    const double ahx = ax * ia, ahy = ay * ia, bhx = bx * ib, bhy = by * ib;
    const double c = ahx * bhx + ahy * bhy;
    const double c0 = 0.5 * k * ia, c2 = 0.5 * k * ib;
    const double f0x = -c0 * (bhx - ahx * c), f0y = -c0 * (bhy - ahy * c);
    const double f2x = c2 * (ahx - bhx * c), f2y = c2 * (ahy - bhy * c);
    f[2 * i0] += f0x;
    f[2 * i0 + 1] += f0y;
    f[2 * i2] += f2x;
    f[2 * i2 + 1] += f2y;
    f[2 * i1] -= f0x + f2x;
    f[2 * i1 + 1] -= f0y + f2y;
  }
}

/// One plugin instance made through the C table.
struct Instance {
  std::shared_ptr<const pinsim::LoadedPlugin> p;
  void* self = nullptr;
  Instance(std::shared_ptr<const pinsim::LoadedPlugin> plugin, const nlohmann::json& params,
           const Setup& s)
      : p(std::move(plugin)) {
    const std::string pj = pinsim::validate_params(*p->table, params, "bench").dump();
    const pinsim_state_view iv = s.view();
    pinsim_create_args a{};
    a.params_json = pj.c_str();
    a.initial = &iv;
    a.elements = s.elements.data();
    a.arity = p->table->arity;
    a.n_elements = s.elements.size() / a.arity;
    a.context = "bench";
    char msg[256] = {0};
    pinsim_error err{msg, sizeof msg};
    self = p->table->create(&a, &err);
    if (self == nullptr) {
      std::fprintf(stderr, "create failed: %s\n", msg);
      std::exit(1);
    }
  }
  ~Instance() { p->table->destroy(self); }
  void add_force(const pinsim_state_view& sv, double* f) const {
    p->table->force.add_force(self, &sv, f, nullptr);
  }
};

}  // namespace

int main(int argc, char** argv) {
  const std::size_t m = argc > 1 ? std::strtoull(argv[1], nullptr, 10) : 100000;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 15;
  pinsim::PluginLoader loader(pinsim::plugin_search_dirs());
  std::printf("force,variant,elements,ns_per_element,million_per_s,checksum\n");

  {  // damped springs: rest lengths from a slightly different initial shape, so R != L
    const Setup s = chain(m, 2);
    Setup init = s;
    init.x *= 1.01;
    const double ks = 100.0, kd = 1.0;
    std::vector<double> rest(m);
    for (std::size_t e = 0; e < m; ++e)
      rest[e] = (init.x.col(s.elements[2 * e]) - init.x.col(s.elements[2 * e + 1])).norm();
    Eigen::Matrix2Xd f = Eigen::Matrix2Xd::Zero(2, s.x.cols());
    const double plain = time_ns(
        [&] {
          f.setZero();
          plain_springs(s.x.data(), s.v.data(), s.elements.data(), rest.data(), m, ks, kd,
                        f.data());
        },
        m, repeats);
    row("damped_spring", "plain_loop", m, plain, f.cwiseAbs().sum());
    Instance inst(loader.load("damped_spring"), {{"ks", ks}, {"kd", kd}}, init);
    const pinsim_state_view sv = s.view();
    const double plug = time_ns(
        [&] {
          f.setZero();
          inst.add_force(sv, f.data());
        },
        m, repeats);
    row("damped_spring", "plugin", m, plug, f.cwiseAbs().sum());
  }
  {  // bending triples, flat rest shape (the seed's formula)
    const Setup s = chain(m, 3);
    const double k = 1.0;
    Eigen::Matrix2Xd f = Eigen::Matrix2Xd::Zero(2, s.x.cols());
    const double plain = time_ns(
        [&] {
          f.setZero();
          plain_bending(s.x.data(), s.elements.data(), m, k, f.data());
        },
        m, repeats);
    row("bending", "plain_loop", m, plain, f.cwiseAbs().sum());
    Instance inst(loader.load("bending"), {{"k", k}}, s);
    const pinsim_state_view sv = s.view();
    const double plug = time_ns(
        [&] {
          f.setZero();
          inst.add_force(sv, f.data());
        },
        m, repeats);
    row("bending", "plugin", m, plug, f.cwiseAbs().sum());
  }
  return 0;
}
