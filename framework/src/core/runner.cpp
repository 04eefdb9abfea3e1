#include "core/runner.hpp"

#include <spdlog/spdlog.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include "core/crash_summary.hpp"
#include "core/format.hpp"
#include "core/recorder.hpp"
#include "core/stop_signals.hpp"

namespace pinsim {

namespace {
/// CPU time of the process (every thread), s.
double process_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}
/// What may add energy to the run, "" if nothing: then its total energy can only stay or
/// fall (up to the integrator's error) and a rise past kEnergyRiseBound is a warning.
/// Conservative: anything that may do work outside the energy the forces report counts.
std::string energy_source(const Scene& scene, const Simulation& sim) {
  for (const auto& f : sim.forces())
    if (!f->has_energy()) return "force " + f->plugin().name() + " reports no energy";
  const nlohmann::json& b = scene.backend_scene;
  if (!b.is_object()) return "";
  if (b.contains("inputs") && b["inputs"].is_array() && !b["inputs"].empty())
    return "scripted inputs";
  auto above = [](const nlohmann::json& m, const char* key, double limit) {
    return m.is_object() && m.contains(key) && m[key].is_number() && m[key].get<double>() > limit;
  };
  if (b.contains("obstacles") && b["obstacles"].is_array())
    for (const auto& o : b["obstacles"]) {
      if (!o.is_object()) continue;
      if (o.contains("motion")) return "a moving obstacle";
      const nlohmann::json m = o.value("material", nlohmann::json());
      if (above(m, "kick", 0.0)) return "a kicking obstacle";
      if (above(m, "restitution", 1.0)) return "restitution above 1";
    }
  if (b.contains("contacts") && above(b["contacts"], "restitution", 1.0))
    return "restitution above 1";
  return "";
}
}  // namespace

RunResult run_scene(const Scene& scene, PluginLoader& loader, const RunSettings& settings) {
  Simulation sim(scene, loader, settings.options);
  std::unique_ptr<Recorder> rec;
  if (settings.out) rec = std::make_unique<Recorder>(*settings.out, scene, settings.overwrite);

  nlohmann::json plugins = nlohmann::json::object();
  plugins[sim.backend().plugin().name()] = sim.backend().plugin().table->version;
  for (const auto& f : sim.forces()) plugins[f->plugin().name()] = f->plugin().table->version;

  nlohmann::json summary = {
      {"status", "running"},
      {"scene", scene.label},
      {"scene_dir", std::filesystem::absolute(scene.base_dir).string()},
      {"name", scene.name},
      {"backend", sim.backend().plugin().name()},
      {"integrator", sim.integrator_name()},
      {"dt", scene.dt},
      {"duration", scene.duration},
      {"particles", sim.state().size()},
      {"threads", sim.threads()},
      {"versions", {{"pinsim", PINSIM_VERSION}, {"plugins", plugins}}},
  };
  std::unique_ptr<CrashSummary> crash;
  if (rec) {
    rec->write_summary(summary);
    crash = std::make_unique<CrashSummary>(rec->dir(), summary);
    rec->write_state(sim.state());
  }

  // The start's energy scale: kinetic plus |potential| energy (1 if both are 0).
  double scale0 = sim.kinetic_energy(sim.state()) + std::abs(sim.potential_energy(sim.state()));
  if (!(scale0 > 0.0)) scale0 = 1.0;
  nlohmann::json warnings = nlohmann::json::array();

  const uint64_t steps = scene.steps();
  const auto start = std::chrono::steady_clock::now();
  const double cpu_start = process_cpu_s();
  auto last_progress = start;
  RunResult result;
  std::string status = "ok";
  uint64_t contacts = 0;
  bool output_failed = false;
  try {
    for (uint64_t n = 0; n < steps; ++n) {
      if (const int sig = settings.stop ? settings.stop->load(std::memory_order_relaxed) : 0) {
        status = "interrupted";
        result.exit_code = stop_exit_code(sig);
        summary["signal"] = {{"name", signal_name(sig)}, {"number", sig}};
        spdlog::warn("{}: stopped by {} after step {} (t = {})", scene.label, signal_name(sig),
                     sim.step_index(), sim.state().t);
        break;
      }
      sim.step();
      contacts += sim.events().size();
      if (rec) {
        rec->write_events(sim.events(), sim.step_index());
        if (sim.step_index() % scene.output_every == 0 || n + 1 == steps)
          rec->write_state(sim.state());
        CrashSummary::set_step(sim.step_index());
      }
      if (settings.progress && (n & 255) == 0) {
        const auto now = std::chrono::steady_clock::now();
        if (now - last_progress > std::chrono::milliseconds(200)) {
          last_progress = now;
          settings.progress(static_cast<double>(n) / static_cast<double>(steps), sim);
        }
      }
    }
  } catch (const OutputError& e) {
    status = "error";
    result.exit_code = 1;
    output_failed = true;
    summary["error"] = {{"kind", "output"},
                        {"message", e.what()},
                        {"step", sim.step_index()},
                        {"t", sim.state().t}};
    spdlog::error(
        "{}: {}; the run stopped after step {} (t = {}); the files keep every whole "
        "line written before",
        scene.label, e.what(), sim.step_index(), sim.state().t);
  } catch (const NumericError& e) {
    status = "error";
    result.exit_code = 1;
    summary["error"] = {
        {"kind", "numeric"}, {"numeric", e.kind_name()}, {"message", e.what()}, {"step", e.step},
        {"t", e.t},          {"particle", e.particle},   {"plugin", e.plugin}};
    spdlog::error("{}: step {} (t = {}), particle {}{}: {}", scene.label, e.step, num(e.t),
                  e.particle, e.plugin.empty() ? "" : ", " + e.plugin, e.what());
  } catch (const std::exception& e) {
    status = "error";
    result.exit_code = 1;
    summary["error"] = {{"kind", "plugin"},
                        {"message", e.what()},
                        {"step", sim.step_index() + 1},
                        {"t", sim.state().t}};
    spdlog::error("{}: step {} (t = {}): {}", scene.label, sim.step_index() + 1, sim.state().t,
                  e.what());
  }
  if (rec && !output_failed) {
    try {
      // The impulses of a step that failed (an interrupt comes between steps: the last
      // step's impulses are written already).
      if (!sim.events().empty() && status == "error")
        rec->write_events(sim.events(), sim.step_index() + 1);
      rec->close();
    } catch (const OutputError& e) {
      status = "error";
      result.exit_code = 1;
      summary["error"] = {{"kind", "output"},
                          {"message", e.what()},
                          {"step", sim.step_index()},
                          {"t", sim.state().t}};
      spdlog::error("{}: {}", scene.label, e.what());
    }
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double cpu = process_cpu_s() - cpu_start;

  // Energy at the end (guarded: the state may be non-finite after a failure).
  double e_end = 0.0;
  try {
    e_end = sim.kinetic_energy(sim.state()) + sim.potential_energy(sim.state());
  } catch (const std::exception&) {
    e_end = std::nan("");
  }
  summary["status"] = status;
  summary["steps"] = sim.step_index();
  summary["t_end"] = sim.state().t;
  summary["wall_time_s"] = wall;
  summary["cpu_time_s"] = cpu;
  summary["contacts"] = contacts;
  if (rec)
    summary["events"] = {{"mode", scene.output_events},
                         {"events_rows", rec->event_rows()},
                         {"contacts_rows", rec->contact_rows()}};
  summary["force_evaluations"] = sim.force_evaluations();
  summary["energy"] = {{"start", sim.energy_start()},
                       {"end", std::isfinite(e_end) ? nlohmann::json(e_end) : nlohmann::json()},
                       {"max_relative_drift", sim.max_energy_drift()},
                       {"checked_every_steps", scene.energy_every},
                       {"complete", sim.energy_complete()}};
  // Energy that rose with nothing to add it: a force's sign or its energy is wrong.
  {
    const double e0 = sim.energy_start(), rise = e_end - e0;
    const double bound = kEnergyRiseBound * std::max(scale0, 1e-300);
    if (status != "error" && std::isfinite(e_end) && rise > bound && sim.energy_complete() &&
        energy_source(scene, sim).empty()) {
      const std::string what =
          "the total energy rose from " + num(e0) + " to " + num(e_end) + " (by " +
          num(rise / scale0) + " x the start's kinetic plus |potential| energy, " + num(scale0) +
          "; the bound is " + num(kEnergyRiseBound) +
          ") with nothing in the scene that adds energy: check the forces' signs and energies";
      warnings.push_back({{"kind", "energy_rise"}, {"message", what}});
      spdlog::warn("{}: {}", scene.label, what);
    }
  }
  if (!warnings.empty()) summary["warnings"] = warnings;
  if (const nlohmann::json solver = sim.integrator_stats(); !solver.is_null())
    summary["solver"] = solver;
  summary["state_hash"] = fmt::format("{:016x}", sim.state().hash());
  if (rec) {
    // The run is over: from here, summary.json says how it ended.
    crash->disarm();
    try {
      rec->write_summary(summary);
    } catch (const OutputError& e) {
      if (crash->write_instead(summary.dump(2) + "\n") == 0) {
        spdlog::warn("{}; summary.json written into the space reserved for it", e.what());
      } else {
        // The summary of the start ("running") stays: it still parses.
        spdlog::error("{}: {}", scene.label, e.what());
        result.exit_code = 1;
        if (status == "ok") summary["status"] = "error";
        summary["error"] = {{"kind", "output"}, {"message", e.what()}};
      }
    }
  }
  crash.reset();
  result.summary = std::move(summary);
  return result;
}

}  // namespace pinsim
