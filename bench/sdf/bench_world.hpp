// BenchWorld: particles of one radius and unit mass driven by uniform gravity through one
// collision backend (SdfBackend or Box2dBackend, constructed directly from their impl
// libraries), stepped with the same floating-point operations as the framework's symplectic
// Euler with the gravity plugin: f = g / w, kick v += (dt w) f, then the backend's advance
// from t = n dt (the step count times dt, as Simulation keeps it), so a scene's ball follows
// the path `pinsim run` computes, bit for bit. Plus the thread-CPU clock and the median the
// benchmarks report.
#pragma once

#include <time.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <memory>
#include <pinsim/plugin.hpp>
#include <string>
#include <vector>

namespace pinsim::bench {

/// Thread CPU time in ns, so that a busy shared machine does not inflate the figures.
inline double cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e9 * static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec);
}

inline double median(std::vector<double> a) {
  std::sort(a.begin(), a.end());
  return a[a.size() / 2];
}

/// Backend parameters: B's declared defaults, then `scene_params`, then `over`.
template <class B>
nlohmann::json params_for(const nlohmann::json& scene_params,
                          const nlohmann::json& over = nlohmann::json::object()) {
  nlohmann::json p = nlohmann::json::object();
  for (const auto& d : B::info().params) p[d.name] = d.default_value[0];
  if (scene_params.is_object())
    for (const auto& [k, v] : scene_params.items()) p[k] = v;
  for (const auto& [k, v] : over.items()) p[k] = v;
  return p;
}

/// The part of a scene a backend sees: obstacles, inputs, contacts.
inline nlohmann::json backend_scene(const nlohmann::json& s) {
  nlohmann::json b = nlohmann::json::object();
  for (const char* k : {"obstacles", "inputs", "contacts"})
    if (s.contains(k)) b[k] = s[k];
  return b;
}

template <class B>
struct BenchWorld {
  std::vector<double> x, v, w, r;
  std::unique_ptr<B> be;
  double t = 0.0;
  uint64_t steps = 0;
  uint64_t events = 0;

  /// Particles of one radius and one mass (inverse mass w = 1 / mass).
  BenchWorld(const nlohmann::json& scene, const nlohmann::json& params, std::vector<double> x0,
             std::vector<double> v0, double radius, const nlohmann::json& contacts = nullptr,
             double mass = 1.0)
      : x(std::move(x0)), v(std::move(v0)), w(x.size() / 2, 1.0 / mass), r(x.size() / 2, radius) {
    pinsim_state_view sv{w.size(), 0.0, x.data(), v.data(), w.data(), r.data()};
    nlohmann::json bs = backend_scene(scene);
    if (!contacts.is_null()) bs["contacts"] = contacts;
    CreateContext ctx{Params(params), bs, StateView(sv), Elements{}, "bench"};
    be = std::make_unique<B>(ctx);
  }
  /// One symplectic Euler step with gravity (gx, gy); `sink` receives the contact events.
  void step(double dt, double gx, double gy, const pinsim_event_sink* sink = nullptr) {
    for (std::size_t i = 0; i < w.size(); ++i) {
      const double hw = dt * w[i];
      v[2 * i] += hw * (0.0 + gx / w[i]);
      v[2 * i + 1] += hw * (0.0 + gy / w[i]);
    }
    pinsim_state_mut sm{w.size(), t, x.data(), v.data(), w.data(), r.data()};
    MutableState ms(sm);
    pinsim_event_sink count{
        this, [](void* c, const pinsim_event*) { ++static_cast<BenchWorld*>(c)->events; }};
    EventSink es(sink ? sink : &count);
    be->advance(ms, dt, es);
    t = static_cast<double>(++steps) * dt;
  }
  /// FNV-1a over the positions' bytes: a determinism check printed beside each figure.
  uint64_t hash() const {
    uint64_t h = 1469598103934665603ull;
    for (double d : x) {
      unsigned char b[sizeof d];
      std::memcpy(b, &d, sizeof d);
      for (unsigned char c : b) h = (h ^ c) * 1099511628211ull;
    }
    return h;
  }
};

}  // namespace pinsim::bench
