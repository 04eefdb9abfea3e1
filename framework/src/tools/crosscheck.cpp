#include "tools/crosscheck.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "core/json_read.hpp"

namespace pinsim {
namespace {

double angle_between(const double* a, const double* b) {
  const double c = a[0] * b[0] + a[1] * b[1];
  const double s = a[0] * b[1] - a[1] * b[0];
  return std::abs(std::atan2(s, c));
}

nlohmann::json event_json(const Scene& scene, const pinsim_event& e) {
  const double e_ach = e.vn_before < 0.0 ? -e.vn_after / e.vn_before : std::nan("");
  return {{"t", e.t},
          {"obstacle",
           e.obstacle >= 0 ? scene.obstacle_id(e.obstacle) : fmt::format("particle {}", e.other)},
          {"point", {e.point[0], e.point[1]}},
          {"normal", {e.normal[0], e.normal[1]}},
          {"vn_before", e.vn_before},
          {"vn_after", e.vn_after},
          {"restitution", std::isfinite(e_ach) ? nlohmann::json(e_ach) : nlohmann::json()}};
}

}  // namespace

CrosscheckSpec parse_crosscheck(const Scene& scene) {
  CrosscheckSpec spec;
  const Loc root{scene.label, ""};
  if (!scene.doc.contains("crosscheck")) return spec;
  const nlohmann::json& c = scene.doc["crosscheck"];
  const Loc at = root / "crosscheck";
  require_object(c, at);
  check_keys(c,
             {"backends", "position_tolerance", "time_of_impact_tolerance", "normal_tolerance",
              "velocity_tolerance", "min_horizon", "params"},
             at);
  auto positive = [&](const char* key, double def) {
    const double v = read_number_or(c, key, def, at);
    if (!(v > 0.0)) throw(at / key).error("must be > 0, got " + c.at(key).dump());
    return v;
  };
  spec.position_tolerance = positive("position_tolerance", spec.position_tolerance);
  spec.time_of_impact_tolerance =
      positive("time_of_impact_tolerance", spec.time_of_impact_tolerance);
  spec.normal_tolerance = positive("normal_tolerance", spec.normal_tolerance);
  spec.velocity_tolerance = positive("velocity_tolerance", spec.velocity_tolerance);
  if (c.contains("min_horizon")) {
    const double h = read_number(c, "min_horizon", at);
    if (!(h >= 0.0))
      throw(at / "min_horizon").error("must be >= 0, got " + c.at("min_horizon").dump());
    spec.min_horizon = h;
  }
  if (c.contains("backends")) {
    const auto& b = c["backends"];
    if (!b.is_array() || b.size() != 2 || !b[0].is_string() || !b[1].is_string())
      throw(at / "backends")
          .error("expected two backend names, e.g. [\"sdf\", \"box2d\"], got " + b.dump());
    spec.backends = {b[0].get<std::string>(), b[1].get<std::string>()};
  }
  if (c.contains("params")) {
    const auto& p = c["params"];
    require_object(p, at / "params");
    for (const auto& [k, v] : p.items()) {
      require_object(v, at / "params" / k);
      spec.params[k] = v;
    }
  }
  return spec;
}

CrosscheckRun run_for_crosscheck(const Scene& scene_in, PluginLoader& loader,
                                 const std::string& backend, const CrosscheckSpec& spec) {
  Scene scene = scene_in;
  const auto it = spec.params.find(backend);
  if (it != spec.params.end()) {
    scene.backend =
        PluginRef{backend, "", it->second, scene.label + ": crosscheck.params." + backend};
  } else if (scene.backend.name != backend) {
    scene.backend = PluginRef{backend, "", nlohmann::json::object(), "--backends " + backend};
  }
  Simulation sim(scene, loader);
  CrosscheckRun run;
  run.backend = backend;
  const uint64_t steps = scene.steps();
  auto sample = [&] {
    run.t.push_back(sim.state().t);
    run.x.push_back(sim.state().x);
    run.energy.push_back(sim.kinetic_energy(sim.state()) + sim.potential_energy(sim.state()));
  };
  sample();
  const auto start = std::chrono::steady_clock::now();
  try {
    for (uint64_t n = 0; n < steps; ++n) {
      sim.step();
      run.events.insert(run.events.end(), sim.events().begin(), sim.events().end());
      sample();
    }
  } catch (const std::exception& e) {
    run.error = fmt::format("step {} (t = {}): {}", sim.step_index() + 1, sim.state().t, e.what());
  }
  run.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return run;
}

CrosscheckReport compare_runs(const Scene& scene, const CrosscheckSpec& spec,
                              const CrosscheckRun& a, const CrosscheckRun& b) {
  CrosscheckReport rep;
  std::vector<std::string> failures;
  const std::size_t ns = std::min(a.t.size(), b.t.size());
  const Eigen::Index np = a.x.empty() ? 0 : a.x[0].cols();
  const double duration = scene.duration;
  const double horizon_needed = spec.min_horizon.value_or(duration);
  std::ostringstream tab;
  tab << fmt::format("crosscheck {}: {} vs {}, {} steps of dt = {} s\n", scene.label, a.backend,
                     b.backend, scene.steps(), scene.dt);
  for (const CrosscheckRun* r : {&a, &b})
    if (!r->error.empty()) {
      failures.push_back(r->backend + " stopped: " + r->error);
      tab << fmt::format("  {} stopped early: {}\n", r->backend, r->error);
    }

  nlohmann::json particles = nlohmann::json::array();
  tab << fmt::format("\n  {:>8} {:>14} {:>14} {:>14}   (position tolerance {})\n", "particle",
                     "max dev", "final dev", "horizon s", spec.position_tolerance);
  for (Eigen::Index i = 0; i < np; ++i) {
    double max_dev = 0.0, horizon = -1.0;
    nlohmann::json series = nlohmann::json::array();
    const std::size_t stride = std::max<std::size_t>(1, ns / 400);
    for (std::size_t k = 0; k < ns; ++k) {
      const double d = (a.x[k].col(i) - b.x[k].col(i)).norm();
      max_dev = std::max(max_dev, d);
      if (horizon < 0.0 && d > spec.position_tolerance) horizon = k > 0 ? a.t[k - 1] : 0.0;
      if (k % stride == 0 || k + 1 == ns) series.push_back({a.t[k], d});
    }
    const bool held = horizon < 0.0;
    if (held) horizon = ns > 0 ? a.t[ns - 1] : 0.0;
    const double final_dev = ns > 0 ? (a.x[ns - 1].col(i) - b.x[ns - 1].col(i)).norm() : 0.0;
    if (horizon + 0.5 * scene.dt < horizon_needed)
      failures.push_back(fmt::format("particle {}: agreement horizon {} s < required {} s", i,
                                     horizon, horizon_needed));
    particles.push_back({{"particle", i},
                         {"max_deviation", max_dev},
                         {"final_deviation", final_dev},
                         {"agreement_horizon", horizon},
                         {"tolerance_held_to_end", held},
                         {"deviation", series}});
    tab << fmt::format("  {:>8} {:>14.6g} {:>14.6g} {:>14.6g}{}\n", i, max_dev, final_dev, horizon,
                       held ? " (whole run)" : "");

    // Contacts of particle i side by side, in time order; checked within the horizon.
    auto of = [&](const CrosscheckRun& r) {
      std::vector<pinsim_event> v;
      for (const auto& e : r.events)
        if (e.particle == i || e.other == i) v.push_back(e);
      return v;
    };
    const auto ea = of(a), eb = of(b);
    nlohmann::json pairs = nlohmann::json::array();
    tab << fmt::format("\n  particle {} contacts: {} on {}, {} on {}\n", i, ea.size(), a.backend,
                       eb.size(), b.backend);
    tab << fmt::format("  {:>3} | {:<14} {:>9} {:>17} {:>6} | {:<14} {:>9} {:>17} {:>6} | {}\n",
                       "#", "obstacle", "t", "normal", "e", "obstacle", "t", "normal", "e",
                       "check");
    const std::size_t m = std::max(ea.size(), eb.size());
    std::size_t shown = 0;
    for (std::size_t k = 0; k < m; ++k) {
      const pinsim_event* pa = k < ea.size() ? &ea[k] : nullptr;
      const pinsim_event* pb = k < eb.size() ? &eb[k] : nullptr;
      const double t_first = std::min(pa ? pa->t : HUGE_VAL, pb ? pb->t : HUGE_VAL);
      const bool within = t_first <= horizon;
      nlohmann::json pj = {{"index", k}, {"within_horizon", within}};
      std::string verdict = within ? "ok" : "after horizon";
      if (pa) pj[a.backend] = event_json(scene, *pa);
      if (pb) pj[b.backend] = event_json(scene, *pb);
      if (pa && pb) {
        const double dt_imp = pb->t - pa->t;
        const double dn = angle_between(pa->normal, pb->normal);
        const double dv = pb->vn_after - pa->vn_after;
        pj["time_of_impact_difference"] = dt_imp;
        pj["normal_angle"] = dn;
        pj["vn_after_difference"] = dv;
        std::vector<std::string> bad;
        if (pa->obstacle != pb->obstacle || pa->other != pb->other) bad.push_back("obstacle");
        if (std::abs(dt_imp) > spec.time_of_impact_tolerance)
          bad.push_back(fmt::format("dt {:.3g}", dt_imp));
        if (dn > spec.normal_tolerance) bad.push_back(fmt::format("normal {:.3g} rad", dn));
        if (std::abs(dv) > spec.velocity_tolerance) bad.push_back(fmt::format("dvn {:.3g}", dv));
        if (!bad.empty() && within) {
          verdict.clear();
          for (const auto& s : bad) verdict += (verdict.empty() ? "" : ", ") + s;
          failures.push_back(fmt::format("particle {} contact {}: {}", i, k, verdict));
        }
      } else if (within) {
        verdict = fmt::format("missing on {}", pa ? b.backend : a.backend);
        failures.push_back(fmt::format("particle {} contact {}: {}", i, k, verdict));
      }
      pj["verdict"] = verdict;
      pairs.push_back(pj);
      if (shown < 40) {
        auto cell = [&](const pinsim_event* e) {
          if (!e) return fmt::format("{:<14} {:>9} {:>17} {:>6}", "-", "", "", "");
          const std::string id =
              e->obstacle >= 0 ? scene.obstacle_id(e->obstacle) : fmt::format("p{}", e->other);
          const double er = e->vn_before < 0.0 ? -e->vn_after / e->vn_before : 0.0;
          return fmt::format("{:<14.14} {:>9.5f} ({:>7.4f},{:>7.4f}) {:>6.3f}", id, e->t,
                             e->normal[0], e->normal[1], er);
        };
        tab << fmt::format("  {:>3} | {} | {} | {}\n", k, cell(pa), cell(pb), verdict);
        ++shown;
      } else if (shown == 40) {
        tab << "  ... (all contacts are in report.json)\n";
        ++shown;
      }
    }
    particles.back()["contacts"] = pairs;
  }

  nlohmann::json energy = nlohmann::json::object();
  tab << "\n  energy (kinetic + potential):\n";
  for (const CrosscheckRun* r : {&a, &b}) {
    if (r->energy.empty()) continue;
    const double e0 = r->energy.front(), e1 = r->energy.back();
    double lo = e0, hi = e0;
    for (double e : r->energy) {
      lo = std::min(lo, e);
      hi = std::max(hi, e);
    }
    nlohmann::json series = nlohmann::json::array();
    const std::size_t stride = std::max<std::size_t>(1, r->energy.size() / 400);
    for (std::size_t k = 0; k < r->energy.size(); k += stride)
      series.push_back({r->t[k], r->energy[k]});
    energy[r->backend] = {{"start", e0},
                          {"end", e1},
                          {"min", lo},
                          {"max", hi},
                          {"series", series},
                          {"wall_time_s", r->wall_time},
                          {"contacts", r->events.size()}};
    tab << fmt::format(
        "  {:>8}: start {:.6g}, end {:.6g}, min {:.6g}, max {:.6g}; {} contacts, {:.3f} s wall\n",
        r->backend, e0, e1, lo, hi, r->events.size(), r->wall_time);
  }

  rep.pass = failures.empty();
  tab << "\n  " << (rep.pass ? "PASS" : "FAIL") << "\n";
  for (const auto& f : failures) tab << "    " << f << "\n";
  rep.json = {{"scene", scene.label},
              {"backends", {a.backend, b.backend}},
              {"dt", scene.dt},
              {"duration", duration},
              {"tolerances",
               {{"position_tolerance", spec.position_tolerance},
                {"time_of_impact_tolerance", spec.time_of_impact_tolerance},
                {"normal_tolerance", spec.normal_tolerance},
                {"velocity_tolerance", spec.velocity_tolerance},
                {"min_horizon", horizon_needed}}},
              {"pass", rep.pass},
              {"failures", failures},
              {"errors", {{a.backend, a.error}, {b.backend, b.error}}},
              {"particles", particles},
              {"energy", energy}};
  rep.table = tab.str();
  return rep;
}

}  // namespace pinsim
