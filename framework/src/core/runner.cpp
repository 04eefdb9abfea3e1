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

/// Wall and CPU time since construction, s.
struct Stopwatch {
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  double cpu_start = process_cpu_s();
  double wall() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  double cpu() const { return process_cpu_s() - cpu_start; }
};

/// A run's output folder, when it has one: the recorder and the guard that leaves
/// summary.json saying so when the process crashes (declared after the recorder, so it goes
/// first).
struct RunFiles {
  std::unique_ptr<Recorder> rec;
  std::unique_ptr<CrashSummary> crash;
};

/// Which failure ended the run, for summary.json's "error" "kind".
enum class Failure { none, output, numeric, plugin };

/// How the steps ended: what the summary and the exit code report.
struct RunEnd {
  std::string status = "ok";  ///< "ok", "interrupted" or "error"
  int exit_code = 0;          ///< as RunResult::exit_code
  Failure failure = Failure::none;
  uint64_t contacts = 0;  ///< impulses over the run
};

/// Where a failure happened: during the steps, or closing the files after them.
enum class Stage { steps, closing };

/// The one mapping of a failure to what the run reports: summary.json's "error" (kind output,
/// numeric or plugin, with the step and the time), a log line and exit code 1.
void record_failure(const std::exception& e, Stage stage, const Scene& scene, const Simulation& sim,
                    RunEnd& end, nlohmann::json& summary) {
  end.status = "error";
  end.exit_code = 1;
  if (dynamic_cast<const OutputError*>(&e) != nullptr) {
    end.failure = Failure::output;
    summary["error"] = {{"kind", "output"},
                        {"message", e.what()},
                        {"step", sim.step_index()},
                        {"t", sim.state().t}};
    if (stage == Stage::closing)
      spdlog::error("{}: {}", scene.label, e.what());
    else
      spdlog::error(
          "{}: {}; the run stopped after step {} (t = {}); the files keep every whole "
          "line written before",
          scene.label, e.what(), sim.step_index(), sim.state().t);
  } else if (const auto* n = dynamic_cast<const NumericError*>(&e)) {
    end.failure = Failure::numeric;
    summary["error"] = {
        {"kind", "numeric"}, {"numeric", n->kind_name()}, {"message", n->what()}, {"step", n->step},
        {"t", n->t},         {"particle", n->particle},   {"plugin", n->plugin}};
    spdlog::error("{}: step {} (t = {}), particle {}{}: {}", scene.label, n->step, num(n->t),
                  n->particle, n->plugin.empty() ? "" : ", " + n->plugin, n->what());
  } else {
    end.failure = Failure::plugin;
    summary["error"] = {{"kind", "plugin"},
                        {"message", e.what()},
                        {"step", sim.step_index() + 1},
                        {"t", sim.state().t}};
    spdlog::error("{}: step {} (t = {}): {}", scene.label, sim.step_index() + 1, sim.state().t,
                  e.what());
  }
}

/// summary.json at the start: what runs, with which plugins, at which versions.
nlohmann::json start_summary(const Scene& scene, const Simulation& sim) {
  nlohmann::json plugins = nlohmann::json::object();
  plugins[sim.backend().plugin().name()] = sim.backend().plugin().table->version;
  for (const auto& f : sim.forces()) plugins[f->plugin().name()] = f->plugin().table->version;
  return {
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
}

/// Writes the summary of the start, arms the crash guard and writes the initial state.
void write_start(RunFiles& files, const nlohmann::json& summary, const State& s) {
  if (!files.rec) return;
  files.rec->write_summary(summary);
  files.crash = std::make_unique<CrashSummary>(files.rec->dir(), summary);
  files.rec->write_state(s);
}

/// The steps until the scene's end, a stop signal or a failure, with their output. A
/// failure is recorded (record_failure), never thrown.
RunEnd run_steps(const Scene& scene, Simulation& sim, RunFiles& files, const RunSettings& settings,
                 nlohmann::json& summary) {
  RunEnd end;
  const uint64_t steps = scene.steps();
  auto last_progress = std::chrono::steady_clock::now();
  try {
    for (uint64_t n = 0; n < steps; ++n) {
      if (const int sig = settings.stop ? settings.stop->load(std::memory_order_relaxed) : 0) {
        end.status = "interrupted";
        end.exit_code = stop_exit_code(sig);
        summary["signal"] = {{"name", signal_name(sig)}, {"number", sig}};
        spdlog::warn("{}: stopped by {} after step {} (t = {})", scene.label, signal_name(sig),
                     sim.step_index(), sim.state().t);
        break;
      }
      sim.step();
      end.contacts += sim.events().size();
      if (files.rec) {
        files.rec->write_events(sim.events(), sim.step_index());
        if (sim.step_index() % scene.output_every == 0 || n + 1 == steps)
          files.rec->write_state(sim.state());
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
  } catch (const std::exception& e) {
    record_failure(e, Stage::steps, scene, sim, end, summary);
  }
  return end;
}

/// Closes the files after the steps (unless writing them failed): first the impulses of a
/// step that failed (an interrupt comes between steps: the last step's impulses are written
/// already).
void close_files(const Scene& scene, const Simulation& sim, RunFiles& files, RunEnd& end,
                 nlohmann::json& summary) {
  if (!files.rec || end.failure == Failure::output) return;
  try {
    if (!sim.events().empty() && end.status == "error")
      files.rec->write_events(sim.events(), sim.step_index() + 1);
    files.rec->close();
  } catch (const OutputError& e) {
    record_failure(e, Stage::closing, scene, sim, end, summary);
  }
}

/// The total energy at the end; NaN if it cannot be evaluated (the state may be non-finite
/// after a failure).
double end_energy(const Simulation& sim) {
  try {
    return sim.kinetic_energy(sim.state()) + sim.potential_energy(sim.state());
  } catch (const std::exception&) {
    return std::nan("");
  }
}

/// The summary's "warnings": an energy that rose past the bound with nothing in the scene to
/// add it (a force's sign or its energy is wrong). `scale0` is the start's kinetic plus
/// |potential| energy.
nlohmann::json energy_warnings(const Scene& scene, const Simulation& sim, const RunEnd& end,
                               double e_end, double scale0) {
  nlohmann::json warnings = nlohmann::json::array();
  const double e0 = sim.energy_start(), rise = e_end - e0;
  const double bound = kEnergyRiseBound * std::max(scale0, 1e-300);
  if (end.status != "error" && std::isfinite(e_end) && rise > bound && sim.energy_complete() &&
      energy_source(scene, sim).empty()) {
    const std::string what =
        "the total energy rose from " + num(e0) + " to " + num(e_end) + " (by " +
        num(rise / scale0) + " x the start's kinetic plus |potential| energy, " + num(scale0) +
        "; the bound is " + num(kEnergyRiseBound) +
        ") with nothing in the scene that adds energy: check the forces' signs and energies";
    warnings.push_back({{"kind", "energy_rise"}, {"message", what}});
    spdlog::warn("{}: {}", scene.label, what);
  }
  return warnings;
}

/// Fills in how the run ended: status, steps, times, contacts, rows written, energy,
/// warnings, the solver's figures and the state hash.
void report(const Scene& scene, const Simulation& sim, const RunFiles& files, const RunEnd& end,
            double wall, double cpu, double scale0, nlohmann::json& summary) {
  const double e_end = end_energy(sim);
  summary["status"] = end.status;
  summary["steps"] = sim.step_index();
  summary["t_end"] = sim.state().t;
  summary["wall_time_s"] = wall;
  summary["cpu_time_s"] = cpu;
  summary["contacts"] = end.contacts;
  if (files.rec)
    summary["events"] = {{"mode", scene.output_events},
                         {"events_rows", files.rec->event_rows()},
                         {"contacts_rows", files.rec->contact_rows()}};
  summary["force_evaluations"] = sim.force_evaluations();
  summary["energy"] = {{"start", sim.energy_start()},
                       {"end", std::isfinite(e_end) ? nlohmann::json(e_end) : nlohmann::json()},
                       {"max_relative_drift", sim.max_energy_drift()},
                       {"checked_every_steps", scene.energy_every},
                       {"complete", sim.energy_complete()}};
  if (const nlohmann::json warnings = energy_warnings(scene, sim, end, e_end, scale0);
      !warnings.empty())
    summary["warnings"] = warnings;
  if (const nlohmann::json solver = sim.integrator_stats(); !solver.is_null())
    summary["solver"] = solver;
  summary["state_hash"] = fmt::format("{:016x}", sim.state().hash());
}

/// Writes the final summary.json: the run is over, so from here it says how the run ended.
/// On a full disk it goes into the space the crash guard reserved; if that fails too, the
/// summary of the start ("running") stays, which still parses, and the run fails.
void write_end(const Scene& scene, RunFiles& files, RunEnd& end, nlohmann::json& summary) {
  if (!files.rec) return;
  files.crash->disarm();
  try {
    files.rec->write_summary(summary);
  } catch (const OutputError& e) {
    if (files.crash->write_instead(summary.dump(2) + "\n") == 0) {
      spdlog::warn("{}; summary.json written into the space reserved for it", e.what());
    } else {
      spdlog::error("{}: {}", scene.label, e.what());
      end.exit_code = 1;
      if (end.status == "ok") summary["status"] = "error";
      summary["error"] = {{"kind", "output"}, {"message", e.what()}};
    }
  }
}
}  // namespace

RunResult run_scene(const Scene& scene, PluginLoader& loader, const RunSettings& settings) {
  // Plan: the simulation, the output folder, the summary of the start and the energy scale
  // the energy-rise warning compares with (kinetic plus |potential| energy, 1 if both are 0).
  Simulation sim(scene, loader, settings.options);
  RunFiles files;
  if (settings.out)
    files.rec = std::make_unique<Recorder>(*settings.out, scene, settings.overwrite);
  nlohmann::json summary = start_summary(scene, sim);
  write_start(files, summary, sim.state());
  double scale0 = sim.kinetic_energy(sim.state()) + std::abs(sim.potential_energy(sim.state()));
  if (!(scale0 > 0.0)) scale0 = 1.0;

  // Loop: the steps with their output, then the files closed.
  const Stopwatch clock;
  RunEnd end = run_steps(scene, sim, files, settings, summary);
  close_files(scene, sim, files, end, summary);
  const double wall = clock.wall(), cpu = clock.cpu();

  // Report: how the run ended, into summary.json.
  report(scene, sim, files, end, wall, cpu, scale0, summary);
  write_end(scene, files, end, summary);
  files.crash.reset();
  return RunResult{std::move(summary), end.exit_code};
}

}  // namespace pinsim
