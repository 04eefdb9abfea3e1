// Test harness: builds SdfBackend without the host and steps it with symplectic Euler
// (kick v += dt g done here, drift by the backend).
#pragma once

#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "sdf_backend.hpp"

namespace pinsim::sdf::test {

/// Parameters with the declared defaults, then `over` on top (what the host does).
inline nlohmann::json params(const nlohmann::json& over = nlohmann::json::object()) {
  nlohmann::json p = nlohmann::json::object();
  for (const auto& d : SdfBackend::info().params) p[d.name] = d.default_value[0];
  for (const auto& [k, v] : over.items()) p[k] = v;
  return p;
}

struct Ball {
  Vec2 x, v;
  double r = 0.01;
  double inv_mass = 1.0;
};

class Sim {
 public:
  Sim(const nlohmann::json& scene, const std::vector<Ball>& balls,
      const nlohmann::json& par = nlohmann::json::object()) {
    for (const Ball& b : balls) {
      x.push_back(b.x.x());
      x.push_back(b.x.y());
      v.push_back(b.v.x());
      v.push_back(b.v.y());
      w.push_back(b.inv_mass);
      r.push_back(b.r);
    }
    pinsim_state_view sv{balls.size(), 0.0, x.data(), v.data(), w.data(), r.data()};
    CreateContext ctx{Params(params(par)), scene, StateView(sv), Elements{}, "test.json"};
    backend = std::make_unique<SdfBackend>(ctx);
  }
  /// One symplectic Euler step: v += dt g, then the backend's drift with contacts.
  void step(double dt, const Vec2& g = Vec2::Zero()) {
    for (std::size_t i = 0; i < w.size(); ++i)
      if (w[i] > 0.0) {
        v[2 * i] += dt * g.x();
        v[2 * i + 1] += dt * g.y();
      }
    pinsim_state_mut sm{w.size(), t, x.data(), v.data(), w.data(), r.data()};
    MutableState ms(sm);
    pinsim_event_sink sink{
        this, [](void* c, const pinsim_event* e) { static_cast<Sim*>(c)->events.push_back(*e); }};
    EventSink es(&sink);
    backend->advance(ms, dt, es);
    t += dt;
  }
  Vec2 pos(std::size_t i = 0) const { return {x[2 * i], x[2 * i + 1]}; }
  Vec2 vel(std::size_t i = 0) const { return {v[2 * i], v[2 * i + 1]}; }

  std::vector<double> x, v, w, r;
  double t = 0.0;
  std::vector<pinsim_event> events;
  std::unique_ptr<SdfBackend> backend;
};

/// An obstacle JSON object.
inline nlohmann::json obstacle(const std::string& id, const nlohmann::json& shape, double e = 1.0,
                               double mu = 0.0, double kick = 0.0) {
  return {{"id", id},
          {"shape", shape},
          {"material", {{"restitution", e}, {"friction", mu}, {"kick", kick}}}};
}

/// Reads a scene file from configs/ (comments allowed).
inline nlohmann::json load_config(const std::string& name) {
  std::ifstream in(std::string(PINSIM_CONFIG_DIR) + "/" + name);
  std::stringstream ss;
  ss << in.rdbuf();
  return nlohmann::json::parse(ss.str(), nullptr, true, true);
}

/// The backend's part of a scene file.
inline nlohmann::json backend_scene(const nlohmann::json& s) {
  nlohmann::json b = nlohmann::json::object();
  for (const char* k : {"obstacles", "inputs", "contacts"})
    if (s.contains(k)) b[k] = s[k];
  return b;
}

}  // namespace pinsim::sdf::test
