#include "grading/grader.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>

#include "core/base64.hpp"
#include "core/format.hpp"
#include "core/stop_signals.hpp"
#include "grading/path_record.hpp"
#include "grading/private_paths.hpp"
#include "grading/remote_plugin.hpp"
#include "grading/results.hpp"
#include "grading/submission.hpp"
#include "grading/verdicts.hpp"
#include "grading/wire.hpp"
#include "grading/worker.hpp"

namespace fs = std::filesystem;

namespace pinsim {
namespace {

using grading::RemoteWorker;
using grading::WorkerFault;

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// One plugin's sandboxed worker, reused by that plugin's tests until it fails.
struct PluginWorker {
  std::unique_ptr<RemoteWorker> worker;
  std::shared_ptr<const LoadedPlugin> table;
  /// Set once the plugin cannot be graded at all (it cannot be opened, or it hung while
  /// loading or in create): the test `fatal_at` shows this cause in full, every other test
  /// of the plugin fails at once with "not run: <fatal_short>, see test <fatal_at + 1>".
  std::string fatal;
  std::string fatal_short;
  std::size_t fatal_at = 0;
};

constexpr std::size_t kNone = static_cast<std::size_t>(-1);

/// The cause at the head of a message: up to its first ':' or line end ("the submission
/// does not compile: the build ..." gives "the submission does not compile").
std::string first_clause(const std::string& s) {
  return s.substr(0, std::min(s.find(':'), s.find('\n')));
}

class Grading {
 public:
  Grading(const Rubric& rubric, const GradeOptions& opt) : rubric_(rubric), opt_(opt) {}

  nlohmann::json run() {
    start_ = now();
    grading::PreparedSubmission prep;
    grading::prepare_submission(opt_.submission, opt_.sdk_prefix, rubric_, prep);
    grading::stage_worker_program(opt_.pinsim_exe, prep);
    tests_ = nlohmann::json::array();
    for (std::size_t i = 0; i < rubric_.tests.size(); ++i) {
      if ((stopped_by_ = stop_signal().load()) != 0) break;
      const RubricTest& t = rubric_.tests[i];
      const double t0 = now();
      grading::Verdict v = run_test(t, i, prep);
      // What the copy of the submission left out is said once, on the first visible test.
      if (i == carrier(0, "") && !prep.copy_notes.empty())
        v.output = prep.copy_notes + "\n\n" + v.output;
      add(i, v, now() - t0);
      // Progress on disk after every test: valid files, score 0 until the end.
      write_interim(i + 1);
    }
    for (auto& [name, w] : workers_)
      if (w.worker) w.worker->finish();
    return results(stopped_by_ != 0);
  }

  /// The stop signal that ended grading before the last test, or 0.
  int stopped_by() const { return stopped_by_; }

 private:
  /// The test that states a cause shared by the tests from `from` on (those of `plugin`, or
  /// all of them when it is empty): the first visible one, so that a student who sees the
  /// others sees it too; `from` when none is visible.
  std::size_t carrier(std::size_t from, const std::string& plugin) const {
    for (std::size_t i = from; i < rubric_.tests.size(); ++i)
      if ((plugin.empty() || rubric_.tests[i].plugin == plugin) &&
          rubric_.tests[i].visibility == "visible")
        return i;
    return from;
  }

  /// A cause that stops several tests, stated once: in full on the test `at`, and on the
  /// others as "not run: <short>, see test N".
  static grading::Verdict stated_once(std::size_t index, std::size_t at, const std::string& full,
                                      const std::string& short_cause) {
    if (index == at) return {false, full, false};
    return {false, "not run: " + short_cause + ", see test " + std::to_string(at + 1), false};
  }

  grading::Verdict run_test(const RubricTest& t, std::size_t index,
                            const grading::PreparedSubmission& prep) {
    if (!prep.problem.empty()) {
      if (problem_at_ == kNone) problem_at_ = carrier(index, "");
      return stated_once(index, problem_at_, prep.problem, first_clause(prep.problem));
    }
    // A plugin that cannot be graded: the test that states why does so even past the time
    // budget (the others point to it); the budget stops the rest first.
    const auto it = workers_.find(t.plugin);
    const bool fatal = it != workers_.end() && !it->second.fatal.empty();
    if (fatal && index == it->second.fatal_at) return {false, it->second.fatal, false};
    if (now() - start_ > rubric_.time_budget_seconds)
      return {false,
              "not run: the submission used up its time budget of " +
                  num(rubric_.time_budget_seconds) + " s",
              false};
    if (fatal)
      return stated_once(index, it->second.fatal_at, it->second.fatal, it->second.fatal_short);
    // One sandbox at a time: another plugin's worker ends before this one is used (the
    // fallback sandbox sweeps the one uid of every step when a step ends).
    for (auto& [name, other] : workers_)
      if (name != t.plugin && other.worker) {
        other.worker->finish();
        other.worker.reset();
      }
    PluginWorker& pw = workers_[t.plugin];
    if (!pw.worker || pw.worker->fault() != WorkerFault::None) {
      pw.worker.reset();
      open(pw, t, index, prep);
      if (!pw.fatal.empty()) return stated_once(index, pw.fatal_at, pw.fatal, pw.fatal_short);
    }
    RemoteWorker& w = *pw.worker;
    w.begin_test(now() + rubric_.limits.wall_seconds);
    grading::Verdict v;
    try {
      v = grading::run_check(t, pw.table, rubric_.file.parent_path());
    } catch (const std::exception& e) {
      v = {false, e.what()};
    }
    if (w.fault() != WorkerFault::None) {
      v = {false, "The submission " + w.failure() + "."};
      if (w.fault() == WorkerFault::TimedOut && w.failed_during() == "create") {
        pw.fatal = v.output;
        pw.fatal_short = "'" + t.plugin + "' hangs in create";
        pw.fatal_at = index;
      }
    }
    printed_ = w.end_test();
    printed_bytes_ = w.printed_bytes();
    return v;
  }

  /// Starts the plugin's worker and opens the plugin in it.
  void open(PluginWorker& pw, const RubricTest& t, std::size_t index,
            const grading::PreparedSubmission& prep) {
    grading::SandboxSpec spec;
    spec.limits = rubric_.limits;
    std::size_t tests_of_plugin = 0;
    for (const auto& u : rubric_.tests) tests_of_plugin += u.plugin == t.plugin;
    // RLIMIT_CPU counts the worker's whole life; each test has its own wall-clock limit.
    spec.limits.cpu_seconds = rubric_.limits.cpu_seconds * static_cast<double>(tests_of_plugin);
    spec.channel = true;
    spec.mounts = {{prep.worker_program.string(), "/grader/pinsim", false},
                   {prep.libraries.string(), "/submission/lib", false}};
    grading::Sandboxed proc;
    try {
      proc = grading::start_sandboxed(
          {"/grader/pinsim", "-q", "grade-worker", "--libraries", "/submission/lib"}, spec);
    } catch (const std::exception& e) {
      pw.fatal = std::string("the grader could not start a sandbox: ") + e.what();
      pw.fatal_short = "the grader could not start a sandbox";
      pw.fatal_at = carrier(index, t.plugin);
      return;
    }
    pw.worker = std::make_unique<RemoteWorker>(proc, rubric_.limits,
                                               now() + rubric_.limits.wall_seconds, output_limit());
    try {
      pw.table = pw.worker->open(t.plugin,
                                 rubric_.kind == "force" ? PINSIM_KIND_FORCE : PINSIM_KIND_BACKEND);
    } catch (const grading::WorkerGone&) {
      pw.fatal = "The submission " + pw.worker->failure() + " while '" + t.plugin +
                 "' was loading; its tests are not run.";
      pw.fatal_short = "'" + t.plugin + "' did not load (the submission " +
                       first_clause(pw.worker->failure()) + ")";
    } catch (const std::exception& e) {
      pw.fatal = e.what();
      const bool missing = pw.fatal.find("no library of the submission declares") == 0;
      pw.fatal_short = !missing ? "'" + t.plugin + "' could not be loaded"
                       : !prep.build_log.empty()
                           ? "'" + t.plugin + "' did not build"
                           : "the submission has no plugin '" + t.plugin + "'";
    }
    if (!pw.fatal.empty()) {
      pw.fatal_at = carrier(index, t.plugin);
      // A build's log is shown once, on the first test of a plugin it left out.
      if (pw.fatal_short.find("did not build") != std::string::npos) {
        if (build_log_at_ == kNone) {
          build_log_at_ = pw.fatal_at;
          pw.fatal += "\n" + prep.build_log;
        } else {
          pw.fatal += "\nThe build's log is in test " + std::to_string(build_log_at_ + 1) + ".";
        }
      }
      printed_open_ = pw.worker->end_test();
      pw.worker->finish();
      pw.worker.reset();
    }
  }

  std::size_t output_limit() const {
    return static_cast<std::size_t>(rubric_.output_limit_kb * 1024.0);
  }

  /// The picture of a failed simulation or path test, as results.hpp's "picture" (null when
  /// there is none); `note` says why one was left out.
  nlohmann::json picture(const RubricTest& t, const grading::Verdict& v, std::string& note) {
    if (v.passed || !v.figure || !opt_.draw_comparison) return nullptr;
    ComparisonPicture pic;
    try {
      pic = opt_.draw_comparison(*v.figure);
    } catch (const std::exception& e) {
      spdlog::warn("no picture for test '{}': {}", t.name, e.what());
      return nullptr;
    }
    std::string png = base64(pic.png);
    if (png.size() > grading::kPictureMaxBytes) {
      spdlog::warn("no picture for test '{}': {} bytes of base64, over the limit of {}", t.name,
                   png.size(), grading::kPictureMaxBytes);
      return nullptr;
    }
    if (picture_bytes_ + png.size() > grading::kPicturesMaxBytes) {
      note = "\n(Its picture is left out: the pictures of these results have reached their " +
             std::to_string(grading::kPicturesMaxBytes / 1024) + " KiB.)";
      return nullptr;
    }
    picture_bytes_ += png.size();
    return {{"png_base64", std::move(png)},
            {"width", pic.width},
            {"height", pic.height},
            {"caption",
             grading::sanitize_text(pic.legend + " " + grading::comparison_caption(*v.figure))}};
  }

  void add(std::size_t i, grading::Verdict v, double seconds) {
    const RubricTest& t = rubric_.tests[i];
    std::string out = v.output;
    if (!v.passed && v.ran && !t.hint.empty()) out += "\nHint: " + t.hint;
    std::string note;
    nlohmann::json pic = picture(t, v, note);
    out += note;
    // The picture goes between the verdict and what the code printed.
    const std::string head = grading::sanitize_text(out);
    const std::string printed = !printed_.empty() ? printed_ : printed_open_;
    if (!printed.empty())
      out += "\n\n--- what your code printed during this test (" + std::to_string(printed_bytes_) +
             " bytes; shown, never graded) ---\n" + printed;
    printed_.clear();
    printed_open_.clear();
    printed_bytes_ = 0;
    const double score = v.passed ? t.points : 0.0;
    nlohmann::json entry = {{"name", grading::sanitize_text(t.name)},
                            {"number", std::to_string(i + 1)},
                            {"score", score},
                            {"max_score", t.points},
                            {"status", v.passed ? "passed" : "failed"},
                            {"output", grading::sanitize_text(out)},
                            {"visibility", t.visibility},
                            {"execution_time", seconds}};
    if (!pic.is_null()) {
      const std::string& text = entry["output"].get_ref<const std::string&>();
      pic["at"] = text.compare(0, head.size(), head) == 0 ? head.size() : text.size();
      entry["picture"] = std::move(pic);
    }
    tests_.push_back(std::move(entry));
    spdlog::debug("{} {}: {}", v.passed ? "pass" : "FAIL", t.name, v.output);
  }

  nlohmann::json results(bool interim) const {
    double score = 0.0, max_score = 0.0;
    for (const auto& t : tests_) score += t["score"].get<double>();
    for (const auto& t : rubric_.tests) max_score += t.points;
    nlohmann::json r = {{"score", interim ? 0.0 : score},
                        {"max_score", max_score},
                        {"execution_time", now() - start_},
                        {"visibility", rubric_.visibility},
                        {"stdout_visibility", rubric_.stdout_visibility},
                        {"tests", tests_},
                        {"extra_data", grading::sandbox_extra_data()}};
    const std::string how =
        stopped_by_ != 0 ? "was interrupted (" + signal_name(stopped_by_) + ")" : "stopped";
    r["output"] = interim
                      ? "Grading did not finish: the grader " + how + " after test " +
                            std::to_string(tests_.size()) + " of " +
                            std::to_string(rubric_.tests.size()) + ". Please tell the course staff."
                      : grading::summary_text(r, rubric_.name, false);
    return r;
  }

  void write_interim(std::size_t) const {
    grading::write_results(opt_.out, results(true), rubric_.name);
  }

  const Rubric& rubric_;
  const GradeOptions& opt_;
  double start_ = 0.0;
  nlohmann::json tests_;
  std::map<std::string, PluginWorker> workers_;
  std::string printed_, printed_open_;
  std::size_t printed_bytes_ = 0;
  std::size_t picture_bytes_ = 0;  ///< the base64 text of the pictures so far
  int stopped_by_ = 0;
  std::size_t problem_at_ = kNone;    ///< the test that shows prep.problem in full
  std::size_t build_log_at_ = kNone;  ///< the test that shows the build's log
};

}  // namespace

GradeReport grade_submission(const Rubric& rubric, const GradeOptions& opt) {
  double total = 0.0;
  for (const auto& t : rubric.tests) total += t.points;
  const auto failed = [&rubric, total](const std::string& why) {
    nlohmann::json r = grading::failed_results(why, total);
    r["stdout_visibility"] = rubric.stdout_visibility;
    return r;
  };
  GradeReport report;
  std::error_code ec;
  fs::create_directories(opt.out, ec);
  if (ec || !fs::is_directory(opt.out, ec)) {
    report.refused = true;
    report.write_error = "cannot make the output folder " + opt.out.string() + ": " +
                         (ec ? ec.message() : "a file of that name is in the way");
    report.results = failed(report.write_error);
    return report;
  }
  try {
    grading::write_results(opt.out,
                           failed("Grading started but did not finish. Please tell the "
                                  "course staff."),
                           rubric.name);
    const std::string exposed = grading::sandbox_mode() == grading::SandboxMode::Fallback
                                    ? grading::exposed_private_paths(rubric, opt.out)
                                    : "";
    if (!grading::unsafe_no_sandbox() && !grading::sandbox_unavailable().empty()) {
      report.refused = true;
      report.results = failed("The autograder cannot isolate submissions on this machine (" +
                              grading::sandbox_unavailable() +
                              "), so it refuses to grade. Course staff: fix the sandbox, or pass "
                              "--unsafe-no-sandbox to grade without isolation.");
    } else if (!exposed.empty()) {
      report.refused = true;
      report.results = failed(
          "The autograder refuses to grade: in its fallback sandbox the submission could "
          "reach " +
          exposed +
          ". Course staff: make these readable only by root (chmod -R go-rwx), see "
          "docs/grading.md.");
    } else {
      spdlog::info("sandbox: {}", grading::sandbox_description());
      Grading g(rubric, opt);
      report.results = g.run();
      report.stopped_by = g.stopped_by();
    }
  } catch (const std::exception& e) {
    report.refused = true;
    report.results =
        failed(std::string("The autograder failed (its own error, not your submission's): ") +
               e.what() + ". Please tell the course staff.");
  }
  try {
    grading::write_results(opt.out, report.results, rubric.name);
  } catch (const std::exception& e) {
    report.write_error = e.what();
    report.refused = true;
  }
  return report;
}

int grade_worker(const fs::path& libraries) {
  return grading::serve_worker(grading::kChannelFd, libraries);
}

}  // namespace pinsim
