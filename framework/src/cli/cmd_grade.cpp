// pinsim grade --rubric R --submission PATH [--out DIR] [--batch [--jobs J] [--shard i/N]]
// [--batch --slurm [--shards N] ...] and the hidden child `pinsim grade-worker` that runs
// one test.
#include <signal.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <set>

#include "cli_slurm.hpp"
#include "commands.hpp"
#include "core/data_files.hpp"
#include "core/input_error.hpp"
#include "core/plugin_loader.hpp"
#include "core/stop_signals.hpp"
#include "grading/grader.hpp"
#include "grading/results.hpp"
#include "grading/sandbox.hpp"
#include "pictures/comparison.hpp"
#include "tools/child_process.hpp"
#include "tools/sweep.hpp"

namespace fs = std::filesystem;

namespace pinsim::cli {
namespace {

/// A submission's file name as one CSV cell: '%', ',', '"' and control characters as %XX
/// (percent-encoding). A name holding "\nalice,10.0,10.0" once wrote a forged row into the
/// class table, and "bob,10.0" shifted bob's columns.
std::string csv_cell(const std::string& name) {
  std::string out;
  for (const char ch : name) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x20 || c == 0x7f || c == '%' || c == ',' || c == '"') {
      static const char* hex = "0123456789ABCDEF";
      out += '%';
      out += hex[c >> 4];
      out += hex[c & 15];
    } else {
      out += ch;
    }
  }
  return out;
}

struct GradeArgs {
  std::string rubric, submission, out = "grade-out", sdk_prefix, shard = "0/1";
  bool batch = false, unsafe = false;
  int jobs = 0;
  SlurmArgs slurm;
};

int grade_one(const GradeArgs& a) {
  Rubric rubric;
  try {
    rubric = load_rubric(a.rubric);
  } catch (const std::exception& e) {
    // Gradescope still gets a valid results.json that says why nothing was graded.
    std::error_code ec;
    fs::create_directories(a.out, ec);
    try {
      grading::write_results(a.out,
                             grading::failed_results(std::string("The autograder's rubric is "
                                                                 "invalid (course staff: ") +
                                                     e.what() + ")"),
                             "rubric");
    } catch (const std::exception&) {
    }
    throw;
  }
  GradeOptions opt;
  opt.submission = fs::absolute(a.submission);
  opt.out = fs::absolute(a.out);
  opt.pinsim_exe = self_exe();
  // Default: the build tree's package (build/<preset>/sdk-package) or the install prefix.
  const fs::path prefix = opt.pinsim_exe.parent_path().parent_path();
  opt.sdk_prefix = !a.sdk_prefix.empty()                ? fs::path(a.sdk_prefix)
                   : fs::exists(prefix / "sdk-package") ? prefix / "sdk-package"
                                                        : prefix;
  // The picture of a failed simulation or path test: drawn by pictures (cairo), which
  // grading does not link; the table is the scene's backend, the reference's.
  opt.draw_comparison = [](const PathComparison& c) {
    PluginLoader loader(plugin_search_dirs(c.scene.plugin_path));
    return comparison_png(c, loader);
  };
  install_stop_handlers();
  const GradeReport r = grade_submission(rubric, opt);
  if (!r.write_error.empty()) {
    std::cerr << "pinsim grade: " << r.write_error << "\n";
    return 2;
  }
  // What summary.txt says: the score, each test, and the failed tests' outputs.
  std::cout << grading::summary_text(r.results, rubric.name);
  std::cout.flush();
  spdlog::info("results written to {}", (fs::path(a.out) / "results.json").string());
  if (r.stopped_by != 0) {
    spdlog::warn("grading stopped by {} after {} test(s); grade again for a score",
                 signal_name(r.stopped_by), r.results["tests"].size());
    return stop_exit_code(r.stopped_by);
  }
  return r.refused ? 2 : 0;
}

// Grades every entry of a folder of submissions (this shard's share), `jobs` at a time, each
// in its own `pinsim grade` process, and writes batch.csv.
int grade_batch(const GradeArgs& a) {
  load_rubric(a.rubric);  // fail early on a bad rubric
  const sweep::Shard shard = sweep::parse_shard(a.shard);
  std::vector<fs::path> subs;
  for (const auto& e : fs::directory_iterator(a.submission)) subs.push_back(e.path());
  std::sort(subs.begin(), subs.end());
  std::vector<fs::path> mine;
  for (std::size_t i = 0; i < subs.size(); ++i)
    if (shard.owns(i)) mine.push_back(subs[i]);
  const int jobs = a.jobs > 0 ? a.jobs : std::max(1L, ::sysconf(_SC_NPROCESSORS_ONLN));
  install_stop_handlers();
  std::size_t next = 0, running = 0;
  std::set<pid_t> children;
  int forwarded = 0;
  std::size_t started = mine.size();
  while (next < mine.size() || running > 0) {
    // A stop signal: start no more, pass it on to the running ones (each writes its
    // results.json saying so) and wait for them.
    if (const int sig = stop_signal().load(); sig != 0 && forwarded == 0) {
      forwarded = sig;
      for (pid_t pid : children) ::kill(pid, sig);
      started = next;
      next = mine.size();
      if (running == 0) break;
    }
    while (next < mine.size() && static_cast<int>(running) < jobs) {
      const fs::path s = mine[next++];
      const std::string out = (fs::path(a.out) / s.filename()).string();
      std::vector<std::string> argv = {self_exe().string(), "-q",     "grade",
                                       "--rubric",          a.rubric, "--submission",
                                       s.string(),          "--out",  out};
      if (!a.sdk_prefix.empty()) argv.insert(argv.end(), {"--sdk-prefix", a.sdk_prefix});
      if (a.unsafe) argv.push_back("--unsafe-no-sandbox");
      children.insert(start_child(argv, ChildOutput::Discard).pid);
      ++running;
    }
    // Until a stop signal is passed on, waiting returns 0 when one arrives.
    const pid_t done = wait_any_child(forwarded != 0 ? nullptr : &stop_signal());
    if (done < 0) break;  // no child left: none can still be running
    if (done == 0) continue;
    children.erase(done);
    --running;
  }
  if (const int sig = stop_signal().load(); sig != 0) {
    spdlog::warn(
        "grading stopped by {}: {} of this shard's {} submission(s) started, each with its "
        "results.json in {}; no batch CSV written; grade the batch again for it",
        signal_name(sig), started, mine.size(), a.out);
    return stop_exit_code(sig);
  }
  // The CSV is written atomically; a shard's gets a manifest (what the whole batch is) so
  // that `pinsim merge` can refuse shards of different batches or a missing one.
  const fs::path csv = fs::path(a.out) / ("batch-" + std::to_string(shard.index) + "-of-" +
                                          std::to_string(shard.count) + ".csv");
  sweep::Table t;
  t.header = {"submission", "score", "max_score"};
  for (const auto& s : mine) {
    std::ifstream in(fs::path(a.out) / s.filename() / "results.json");
    const auto r = nlohmann::json::parse(in, nullptr, false);
    const std::string name = csv_cell(s.filename().string());
    if (r.is_discarded())
      t.rows.push_back({name, "", ""});  // the grader failed: visible, not 0
    else
      t.rows.push_back({name, r["score"].dump(), r["max_score"].dump()});
  }
  if (shard.count == 1) {
    t.write(csv);
  } else {
    std::ifstream rubric(a.rubric);
    std::string inputs = std::string(std::istreambuf_iterator<char>(rubric), {}) + "\n" +
                         a.sdk_prefix + (a.unsafe ? "\nunsafe" : "");
    for (const auto& s : subs) inputs += "\n" + s.filename().string();
    sweep::Manifest m;
    m.tool = "grade";
    m.sweep = sweep::fingerprint(inputs);
    m.shard = shard;
    m.points = subs.size();
    sweep::write_shard(t, csv, m);
  }
  std::cout << "graded " << mine.size() << " submission(s) of " << subs.size() << " (shard "
            << shard.index << "/" << shard.count << "); " << csv.string() << "\n";
  return 0;
}

// Every shard of the batch as one Slurm array task; then the shards' CSVs merged into the
// batch-0-of-1.csv an unsharded batch writes.
int grade_batch_on_slurm(const GradeArgs& a) {
  load_rubric(a.rubric);  // fail early on a bad rubric
  if (!fs::is_directory(a.submission))
    throw InputError("--submission " + a.submission + ": with --batch, expected a folder");
  slurm::ArrayJob job;
  job.tool = "grade";
  job.out = fs::absolute(a.out).lexically_normal();
  job.command = {self_exe().string(),
                 "grade",
                 "--batch",
                 "--rubric",
                 fs::absolute(a.rubric).lexically_normal().string(),
                 "--submission",
                 fs::absolute(a.submission).lexically_normal().string(),
                 "--out",
                 job.out.string(),
                 "--jobs",
                 std::to_string(a.jobs > 0 ? a.jobs : a.slurm.request.cpus)};
  if (!a.sdk_prefix.empty())
    job.command.insert(job.command.end(), {"--sdk-prefix", fs::absolute(a.sdk_prefix).string()});
  if (a.unsafe) job.command.push_back("--unsafe-no-sandbox");
  job.result = [out = job.out](int i, int n) {
    return out / ("batch-" + std::to_string(i) + "-of-" + std::to_string(n) + ".csv");
  };
  return run_on_slurm(job, a.slurm);
}

}  // namespace

void add_grade_command(CLI::App& app) {
  auto a = std::make_shared<GradeArgs>();
  CLI::App* c = app.add_subcommand("grade", "Grade a submitted plugin or backend against a rubric");
  c->add_option("--rubric", a->rubric,
                "Rubric file, or the name of a shipped one (configs/grading/NAME.json)")
      ->required();
  c->add_option("--submission", a->submission,
                "Source folder (CMakeLists.txt using find_package(pinsim)), folder of libraries, "
                "or one library; with --batch, a folder of such submissions")
      ->required();
  c->add_option("--out", a->out, "Folder for results.json, junit.xml, summary.txt");
  c->add_option("--sdk-prefix", a->sdk_prefix,
                "Where find_package(pinsim) finds the SDK (default: this program's prefix)");
  c->add_flag("--batch", a->batch, "Grade every entry of the --submission folder");
  c->add_flag("--unsafe-no-sandbox", a->unsafe,
              "Grade even where no sandbox can be made (submissions then see the machine)");
  c->add_option("--jobs", a->jobs, "Submissions graded at once (default: cores)");
  c->add_option("--shard", a->shard, "With --batch: grade every N-th submission from i (i/N)");
  add_slurm_options(c, a->slurm);
  c->callback([a, c] {
    // A rubric named relative to the shipped ones (configs/grading; core/data_files.hpp).
    a->rubric = find_data_file(a->rubric, "configs/grading").string();
    check_slurm_options(c, a->slurm, c->count("--shard") > 0);
    if (a->slurm.slurm && !a->batch) throw InputError("--slurm grades with --batch only");
    grading::set_unsafe_no_sandbox(a->unsafe);
    if (a->unsafe)
      spdlog::warn("grading WITHOUT a sandbox: submissions can read and write what this user can");
    if (a->slurm.slurm) throw CLI::RuntimeError(grade_batch_on_slurm(*a));
    throw CLI::RuntimeError(a->batch ? grade_batch(*a) : grade_one(*a));
  });

  auto libraries = std::make_shared<std::string>();
  CLI::App* wc = app.add_subcommand(
      "grade-worker", "(internal) serve the grader's requests inside the sandbox, on fd 3");
  wc->group("");  // hidden from --help
  wc->add_option("--libraries", *libraries)->required();
  wc->callback([libraries] { throw CLI::RuntimeError(grade_worker(*libraries)); });
}

}  // namespace pinsim::cli
