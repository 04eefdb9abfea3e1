#include "tools/crosscheck.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <sstream>

#include "core/json_read.hpp"
#include "core/output_file.hpp"
#include "core/recorder.hpp"
#include "core/stop_signals.hpp"

namespace pinsim {
namespace {

double angle_between(const double* a, const double* b) {
  const double c = a[0] * b[0] + a[1] * b[1];
  const double s = a[0] * b[1] - a[1] * b[0];
  return std::abs(std::atan2(s, c));
}

// A contact the backend reported before resolving it within its step: its outgoing normal
// speed is still the incoming one (box2d closes a contact so when another contact of the
// same particle begins in the same step). It has no restitution of its own.
bool unresolved(const pinsim_event& e) { return e.vn_before < 0.0 && e.vn_after == e.vn_before; }

// The restitution achieved, -vn_after / vn_before; NaN where there is none.
double achieved_restitution(const pinsim_event& e) {
  return e.vn_before < 0.0 && !unresolved(e) ? -e.vn_after / e.vn_before : std::nan("");
}

nlohmann::json event_json(const Scene& scene, const pinsim_event& e) {
  const double e_ach = achieved_restitution(e);
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
  const Loc root{scene.label, "", true};
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
    if (!(v > 0.0)) (at / key).fail("must be > 0, got " + c.at(key).dump());
    return v;
  };
  spec.position_tolerance = positive("position_tolerance", spec.position_tolerance);
  spec.time_of_impact_tolerance =
      positive("time_of_impact_tolerance", spec.time_of_impact_tolerance);
  spec.normal_tolerance = positive("normal_tolerance", spec.normal_tolerance);
  spec.velocity_tolerance = positive("velocity_tolerance", spec.velocity_tolerance);
  if (c.contains("min_horizon")) {
    const double h = read_number(c, "min_horizon", at);
    if (!(h >= 0.0)) (at / "min_horizon").fail("must be >= 0, got " + c.at("min_horizon").dump());
    spec.min_horizon = h;
  }
  if (c.contains("backends")) {
    const auto& b = c["backends"];
    if (!b.is_array() || b.size() != 2 || !b[0].is_string() || !b[1].is_string())
      (at / "backends")
          .fail("expected two backend names, e.g. [\"sdf\", \"box2d\"], got " + b.dump());
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
                                 const std::string& backend, const CrosscheckSpec& spec,
                                 const std::filesystem::path* run_dir) {
  Scene scene = scene_in;
  const auto it = spec.params.find(backend);
  if (it != spec.params.end()) {
    scene.backend =
        PluginRef{backend, "", it->second, scene.label + ": crosscheck.params." + backend};
  } else if (scene.backend.name != backend) {
    scene.backend = PluginRef{backend, "", nlohmann::json::object(), "--backends " + backend};
  }
  if (run_dir) {
    // The run folder's scene.json is the scene as run here: this backend and its params.
    nlohmann::json b = {{"name", scene.backend.name}};
    if (!scene.backend.library.empty()) b["library"] = scene.backend.library;
    if (scene.backend.params.is_object()) b["params"] = scene.backend.params;
    scene.doc["backend"] = b;
  }
  Simulation sim(scene, loader);
  std::unique_ptr<Recorder> rec;
  if (run_dir) {
    rec = std::make_unique<Recorder>(*run_dir, scene, /*overwrite=*/true);
    rec->write_state(sim.state());
  }
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
      if ((run.stopped_by = stop_signal().load()) != 0) break;
      sim.step();
      run.events.insert(run.events.end(), sim.events().begin(), sim.events().end());
      sample();
      if (rec) {
        rec->write_events(sim.events(), sim.step_index());
        if (sim.step_index() % scene.output_every == 0 || n + 1 == steps)
          rec->write_state(sim.state());
      }
    }
  } catch (const OutputError&) {
    throw;
  } catch (const std::exception& e) {
    run.error = fmt::format("step {} (t = {}): {}", sim.step_index() + 1, sim.state().t, e.what());
  }
  run.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  run.steps = sim.step_index();
  if (rec) {
    rec->close();
    nlohmann::json summary = {
        {"status", !run.error.empty()    ? "error"
                   : run.stopped_by != 0 ? "interrupted"
                                         : "ok"},
        {"scene", scene.label},
        {"scene_dir", std::filesystem::absolute(scene.base_dir).string()},
        {"name", scene.name},
        {"backend", backend},
        {"integrator", sim.integrator_name()},
        {"dt", scene.dt},
        {"duration", scene.duration},
        {"particles", sim.state().size()},
        {"steps", run.steps},
        {"t_end", sim.state().t},
        {"contacts", run.events.size()},
        {"energy", {{"start", run.energy.front()}, {"end", run.energy.back()}}},
        {"written_by", "crosscheck"}};
    if (!run.error.empty()) summary["error"] = {{"message", run.error}};
    rec->write_summary(summary);
  }
  return run;
}

namespace {

/// One particle's position deviation between the two runs, over their common samples.
struct Deviation {
  double max = 0.0;                                 ///< largest deviation, scene length
  double at_end = 0.0;                              ///< deviation at the last sample
  double horizon = 0.0;                             ///< agreement horizon, s
  bool held = false;                                ///< the tolerance held to the end
  bool too_short = false;                           ///< horizon below the required one
  nlohmann::json series = nlohmann::json::array();  ///< [t, deviation], about 400 samples
};

/// The k-th contacts of one particle on the two runs, matched and checked.
struct ContactPair {
  std::optional<pinsim_event> a;  ///< run a's contact, if it has a k-th
  std::optional<pinsim_event> b;  ///< run b's contact, if it has a k-th
  bool failed = false;            ///< a tolerance failed within the horizon
  std::string verdict;            ///< "ok", "after horizon", or what failed
  nlohmann::json json;            ///< the pair in report.json
};

/// Everything compared for one particle.
struct ParticleComparison {
  Eigen::Index particle = 0;
  Deviation deviation;
  std::size_t contacts_a = 0, contacts_b = 0;  ///< its contacts on each run
  std::vector<ContactPair> pairs;
};

/// One run's energy: first, last, least and largest value, and a thinned series.
struct EnergySummary {
  const CrosscheckRun* run = nullptr;
  double start = 0.0, end = 0.0, min = 0.0, max = 0.0;
  nlohmann::json series = nlohmann::json::array();  ///< [t, energy], about 400 samples
};

// Deviation of particle i over the first ns samples; the horizon is the last sample time
// before the deviation first exceeds the position tolerance (the whole run if it never does).
Deviation particle_deviation(const Scene& scene, const CrosscheckSpec& spec, double horizon_needed,
                             const CrosscheckRun& a, const CrosscheckRun& b, Eigen::Index i,
                             std::size_t ns) {
  Deviation dev;
  double horizon = -1.0;
  const std::size_t stride = std::max<std::size_t>(1, ns / 400);
  for (std::size_t k = 0; k < ns; ++k) {
    const double d = (a.x[k].col(i) - b.x[k].col(i)).norm();
    dev.max = std::max(dev.max, d);
    if (horizon < 0.0 && d > spec.position_tolerance) horizon = k > 0 ? a.t[k - 1] : 0.0;
    if (k % stride == 0 || k + 1 == ns) dev.series.push_back({a.t[k], d});
  }
  dev.held = horizon < 0.0;
  if (dev.held) horizon = ns > 0 ? a.t[ns - 1] : 0.0;
  dev.horizon = horizon;
  dev.at_end = ns > 0 ? (a.x[ns - 1].col(i) - b.x[ns - 1].col(i)).norm() : 0.0;
  dev.too_short = horizon + 0.5 * scene.dt < horizon_needed;
  return dev;
}

// The contacts of particle i in run r (as the particle or as the other one), in time order.
std::vector<pinsim_event> contacts_of(const CrosscheckRun& r, Eigen::Index i) {
  std::vector<pinsim_event> v;
  for (const auto& e : r.events)
    if (e.particle == i || e.other == i) v.push_back(e);
  return v;
}

// Matches the k-th contacts pa and pb (either may be missing) and checks obstacle, time of
// impact, normal and normal velocity after; a failure counts only within the horizon.
ContactPair compare_contact(const Scene& scene, const CrosscheckSpec& spec, const CrosscheckRun& a,
                            const CrosscheckRun& b, const pinsim_event* pa, const pinsim_event* pb,
                            std::size_t k, double horizon) {
  ContactPair cp;
  if (pa) cp.a = *pa;
  if (pb) cp.b = *pb;
  const double t_first = std::min(pa ? pa->t : HUGE_VAL, pb ? pb->t : HUGE_VAL);
  const bool within = t_first <= horizon;
  cp.json = {{"index", k}, {"within_horizon", within}};
  cp.verdict = within ? "ok" : "after horizon";
  if (pa) cp.json[a.backend] = event_json(scene, *pa);
  if (pb) cp.json[b.backend] = event_json(scene, *pb);
  if (pa && pb) {
    const double dt_imp = pb->t - pa->t;
    const double dn = angle_between(pa->normal, pb->normal);
    const double dv = pb->vn_after - pa->vn_after;
    cp.json["time_of_impact_difference"] = dt_imp;
    cp.json["normal_angle"] = dn;
    cp.json["vn_after_difference"] = dv;
    std::vector<std::string> bad;
    if (pa->obstacle != pb->obstacle || pa->other != pb->other) bad.push_back("obstacle");
    if (std::abs(dt_imp) > spec.time_of_impact_tolerance)
      bad.push_back(fmt::format("dt {:.3g}", dt_imp));
    if (dn > spec.normal_tolerance) bad.push_back(fmt::format("normal {:.3g} rad", dn));
    if (std::abs(dv) > spec.velocity_tolerance) bad.push_back(fmt::format("dvn {:.3g}", dv));
    if (!bad.empty() && within) {
      cp.verdict.clear();
      for (const auto& s : bad) cp.verdict += (cp.verdict.empty() ? "" : ", ") + s;
      cp.failed = true;
    }
  } else if (within) {
    cp.verdict = fmt::format("missing on {}", pa ? b.backend : a.backend);
    cp.failed = true;
  }
  cp.json["verdict"] = cp.verdict;
  return cp;
}

// Particle i on both runs: its deviation, then its contacts paired in time order.
void compare_particle(const Scene& scene, const CrosscheckSpec& spec, double horizon_needed,
                      const CrosscheckRun& a, const CrosscheckRun& b, std::size_t ns,
                      ParticleComparison& pc) {
  const Eigen::Index i = pc.particle;
  pc.deviation = particle_deviation(scene, spec, horizon_needed, a, b, i, ns);
  const auto ea = contacts_of(a, i), eb = contacts_of(b, i);
  pc.contacts_a = ea.size();
  pc.contacts_b = eb.size();
  const std::size_t m = std::max(ea.size(), eb.size());
  for (std::size_t k = 0; k < m; ++k)
    pc.pairs.push_back(compare_contact(scene, spec, a, b, k < ea.size() ? &ea[k] : nullptr,
                                       k < eb.size() ? &eb[k] : nullptr, k, pc.deviation.horizon));
}

// Energy of run r over its samples; nothing if it has none.
std::optional<EnergySummary> summarize_energy(const CrosscheckRun& r) {
  if (r.energy.empty()) return std::nullopt;
  EnergySummary es;
  es.run = &r;
  es.start = r.energy.front();
  es.end = r.energy.back();
  es.min = es.start;
  es.max = es.start;
  for (double e : r.energy) {
    es.min = std::min(es.min, e);
    es.max = std::max(es.max, e);
  }
  const std::size_t stride = std::max<std::size_t>(1, r.energy.size() / 400);
  for (std::size_t k = 0; k < r.energy.size(); k += stride)
    es.series.push_back({r.t[k], r.energy[k]});
  return es;
}

// The failures, in report order: runs that stopped, then per particle a short horizon and
// each failed contact.
std::vector<std::string> collect_failures(const CrosscheckRun& a, const CrosscheckRun& b,
                                          const std::vector<ParticleComparison>& particles,
                                          double horizon_needed) {
  std::vector<std::string> failures;
  for (const CrosscheckRun* r : {&a, &b})
    if (!r->error.empty()) failures.push_back(r->backend + " stopped: " + r->error);
  for (const ParticleComparison& pc : particles) {
    if (pc.deviation.too_short)
      failures.push_back(fmt::format("particle {}: agreement horizon {} s < required {} s",
                                     pc.particle, pc.deviation.horizon, horizon_needed));
    for (std::size_t k = 0; k < pc.pairs.size(); ++k)
      if (pc.pairs[k].failed)
        failures.push_back(
            fmt::format("particle {} contact {}: {}", pc.particle, k, pc.pairs[k].verdict));
  }
  return failures;
}

// One cell of the contact table: obstacle (or other particle), time, normal and the
// restitution achieved; "-" for a missing contact.
std::string contact_cell(const Scene& scene, const std::optional<pinsim_event>& e) {
  if (!e) return fmt::format("{:<14} {:>9} {:>17} {:>6}", "-", "", "", "");
  const std::string id =
      e->obstacle >= 0 ? scene.obstacle_id(e->obstacle) : fmt::format("p{}", e->other);
  const double er = achieved_restitution(*e);
  const std::string e_text = std::isfinite(er) ? fmt::format("{:.3f}", er)
                             : unresolved(*e)  ? std::string("open")
                                               : std::string("-");
  return fmt::format("{:<14.14} {:>9.5f} ({:>7.4f},{:>7.4f}) {:>6}", id, e->t, e->normal[0],
                     e->normal[1], e_text);
}

// Particle pc's contact table: counts, a header and the first 40 pairs.
void format_contacts(const Scene& scene, const CrosscheckRun& a, const CrosscheckRun& b,
                     const ParticleComparison& pc, std::ostringstream& tab) {
  constexpr std::size_t kRowsShown = 40;
  tab << fmt::format("\n  particle {} contacts: {} on {}, {} on {}\n", pc.particle, pc.contacts_a,
                     a.backend, pc.contacts_b, b.backend);
  tab << fmt::format("  {:>3} | {:<14} {:>9} {:>17} {:>6} | {:<14} {:>9} {:>17} {:>6} | {}\n", "#",
                     "obstacle", "t", "normal", "e", "obstacle", "t", "normal", "e", "check");
  for (std::size_t k = 0; k < pc.pairs.size() && k < kRowsShown; ++k) {
    const ContactPair& cp = pc.pairs[k];
    tab << fmt::format("  {:>3} | {} | {} | {}\n", k, contact_cell(scene, cp.a),
                       contact_cell(scene, cp.b), cp.verdict);
  }
  if (pc.pairs.size() > kRowsShown) tab << "  ... (all contacts are in report.json)\n";
}

// What the contact tables' e column means, and why it can differ from the material's.
constexpr const char* kContactLegend =
    "\n  e = -vn_after / vn_before, the normal speed relative to the obstacle's surface, out over\n"
    "  in. 'open': the backend reported the contact but had not resolved it when the step\n"
    "  ended it (box2d: another contact of the same particle began in that step); its\n"
    "  restitution is null in report.json. When one step holds several contacts of a particle\n"
    "  (a ball rolling along box2d's segments of a curved wall), Box2D solves them together,\n"
    "  so one contact's e can exceed the material's restitution; a bumper's kick raises e too.\n";

// The readable summary: stopped runs, per particle its deviation row and contact table,
// the energies, the verdict and the failures.
std::string format_table(const Scene& scene, const CrosscheckSpec& spec, const CrosscheckRun& a,
                         const CrosscheckRun& b, const std::vector<ParticleComparison>& particles,
                         const std::vector<EnergySummary>& energies,
                         const std::vector<std::string>& failures) {
  std::ostringstream tab;
  tab << fmt::format("crosscheck {}: {} vs {}, {} steps of dt = {} s\n", scene.label, a.backend,
                     b.backend, scene.steps(), scene.dt);
  for (const CrosscheckRun* r : {&a, &b})
    if (!r->error.empty()) tab << fmt::format("  {} stopped early: {}\n", r->backend, r->error);
  tab << fmt::format("\n  {:>8} {:>14} {:>14} {:>14}   (position tolerance {})\n", "particle",
                     "max dev", "final dev", "horizon s", spec.position_tolerance);
  for (const ParticleComparison& pc : particles) {
    const Deviation& d = pc.deviation;
    tab << fmt::format("  {:>8} {:>14.6g} {:>14.6g} {:>14.6g}{}\n", pc.particle, d.max, d.at_end,
                       d.horizon, d.held ? " (whole run)" : "");
    format_contacts(scene, a, b, pc, tab);
  }
  if (!a.events.empty() || !b.events.empty()) tab << kContactLegend;
  tab << "\n  energy (kinetic + potential):\n";
  for (const EnergySummary& es : energies)
    tab << fmt::format(
        "  {:>8}: start {:.6g}, end {:.6g}, min {:.6g}, max {:.6g}; {} contacts, {:.3f} s wall\n",
        es.run->backend, es.start, es.end, es.min, es.max, es.run->events.size(),
        es.run->wall_time);
  tab << "\n  " << (failures.empty() ? "PASS" : "FAIL") << "\n";
  for (const auto& f : failures) tab << "    " << f << "\n";
  return tab.str();
}

// report.json: the scene, tolerances, verdict, failures, per particle deviation and
// contacts, and per run energy.
nlohmann::json report_json(const Scene& scene, const CrosscheckSpec& spec, double horizon_needed,
                           const CrosscheckRun& a, const CrosscheckRun& b,
                           const std::vector<ParticleComparison>& particles,
                           const std::vector<EnergySummary>& energies,
                           const std::vector<std::string>& failures) {
  nlohmann::json pj = nlohmann::json::array();
  for (const ParticleComparison& pc : particles) {
    nlohmann::json pairs = nlohmann::json::array();
    for (const ContactPair& cp : pc.pairs) pairs.push_back(cp.json);
    pj.push_back({{"particle", pc.particle},
                  {"max_deviation", pc.deviation.max},
                  {"final_deviation", pc.deviation.at_end},
                  {"agreement_horizon", pc.deviation.horizon},
                  {"tolerance_held_to_end", pc.deviation.held},
                  {"deviation", pc.deviation.series},
                  {"contacts", pairs}});
  }
  nlohmann::json energy = nlohmann::json::object();
  for (const EnergySummary& es : energies)
    energy[es.run->backend] = {{"start", es.start},
                               {"end", es.end},
                               {"min", es.min},
                               {"max", es.max},
                               {"series", es.series},
                               {"wall_time_s", es.run->wall_time},
                               {"contacts", es.run->events.size()}};
  return {{"scene", scene.label},
          {"backends", {a.backend, b.backend}},
          {"dt", scene.dt},
          {"duration", scene.duration},
          {"tolerances",
           {{"position_tolerance", spec.position_tolerance},
            {"time_of_impact_tolerance", spec.time_of_impact_tolerance},
            {"normal_tolerance", spec.normal_tolerance},
            {"velocity_tolerance", spec.velocity_tolerance},
            {"min_horizon", horizon_needed}}},
          {"pass", failures.empty()},
          {"failures", failures},
          {"errors", {{a.backend, a.error}, {b.backend, b.error}}},
          {"particles", pj},
          {"energy", energy}};
}

}  // namespace

CrosscheckReport compare_runs(const Scene& scene, const CrosscheckSpec& spec,
                              const CrosscheckRun& a, const CrosscheckRun& b) {
  const double horizon_needed = spec.min_horizon.value_or(scene.duration);
  // Each particle over the samples both runs have: deviation, horizon, contacts.
  const std::size_t ns = std::min(a.t.size(), b.t.size());
  const Eigen::Index np = a.x.empty() ? 0 : a.x[0].cols();
  std::vector<ParticleComparison> particles(static_cast<std::size_t>(np));
  for (Eigen::Index i = 0; i < np; ++i) {
    particles[static_cast<std::size_t>(i)].particle = i;
    compare_particle(scene, spec, horizon_needed, a, b, ns, particles[static_cast<std::size_t>(i)]);
  }
  // Each run's energy.
  std::vector<EnergySummary> energies;
  for (const CrosscheckRun* r : {&a, &b})
    if (auto es = summarize_energy(*r)) energies.push_back(std::move(*es));
  // The verdict, then the same results as a table and as report.json.
  const std::vector<std::string> failures = collect_failures(a, b, particles, horizon_needed);
  CrosscheckReport rep;
  rep.pass = failures.empty();
  rep.table = format_table(scene, spec, a, b, particles, energies, failures);
  rep.json = report_json(scene, spec, horizon_needed, a, b, particles, energies, failures);
  return rep;
}

}  // namespace pinsim
