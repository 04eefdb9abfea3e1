#include "tools/slurm.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <sstream>
#include <thread>

#include "core/input_error.hpp"
#include "core/json_read.hpp"
#include "tools/child_process.hpp"
#include "tools/sweep.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace pinsim::slurm {
namespace {

// ---- small helpers ------------------------------------------------------------------------

bool on_path(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::stringstream ss(path ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(ss, dir, ':'))
    if (!dir.empty() && ::access((fs::path(dir) / name).c_str(), X_OK) == 0) return true;
  return false;
}

/// 'text' for bash, with ' escaped.
std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  std::size_t b = 0;
  while (b < s.size() && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  return s.substr(b);
}

/// "0-2,5,7-8" for {0,1,2,5,7,8}.
std::string ranges(const std::vector<int>& v) {
  std::string out;
  for (std::size_t i = 0; i < v.size();) {
    std::size_t j = i;
    while (j + 1 < v.size() && v[j + 1] == v[j] + 1) ++j;
    if (!out.empty()) out += ',';
    out += std::to_string(v[i]);
    if (j > i) {
      out += '-';
      out += std::to_string(v[j]);
    }
    i = j + 1;
  }
  return out;
}

std::string last_lines(const fs::path& file, int n) {
  std::ifstream in(file);
  if (!in) return "";
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  std::string out;
  for (std::size_t i = lines.size() > static_cast<std::size_t>(n) ? lines.size() - n : 0;
       i < lines.size(); ++i)
    out += "    " + lines[i] + "\n";
  return out;
}

// Ctrl-C while following: stop following, leave the job running.
volatile std::sig_atomic_t g_interrupted = 0;
extern "C" void on_sigint(int) { g_interrupted = 1; }

// ---- the run's folder: OUT/slurm/ ---------------------------------------------------------
//   job.sh            the array's script (also for resubmitting by hand)
//   job.json          what was submitted: tool, N, the shard command, each shard's job id
//   shard-I.log       Slurm's output of shard I (appended over attempts)
//   shard-I.status    written by the script when shard I's command has ended (exit code,
//                     start and end time), atomically; removed when the shard starts again

fs::path slurm_dir(const ArrayJob& j) { return j.out / "slurm"; }
fs::path status_file(const ArrayJob& j, int i) {
  return slurm_dir(j) / ("shard-" + std::to_string(i) + ".status");
}
fs::path log_file(const ArrayJob& j, int i) {
  return slurm_dir(j) / ("shard-" + std::to_string(i) + ".log");
}

struct Status {
  int exit = -1;
  double start = 0, end = 0;
};

std::optional<Status> read_status(const ArrayJob& j, int i) {
  if (!fs::exists(status_file(j, i))) return std::nullopt;
  json s;
  try {
    s = read_json_file(status_file(j, i));
  } catch (const InputError&) {
    return std::nullopt;  // being written, or not a status line: no status yet
  }
  if (!s.is_object() || !s.contains("exit")) return std::nullopt;
  return Status{s.value("exit", -1), s.value("start", 0.0), s.value("end", 0.0)};
}

/// Shard i has a complete result: its manifest exists and matches its CSV's bytes.
bool result_complete(const ArrayJob& j, int i, int n) {
  const fs::path csv = j.result(i, n);
  try {
    const auto m = sweep::read_manifest(csv);
    if (!m || m->shard.index != i || m->shard.count != n) return false;
    std::ifstream in(csv, std::ios::binary);
    if (!in) return false;
    std::stringstream bytes;
    bytes << in.rdbuf();
    return sweep::fingerprint(bytes.str()) == m->csv_hash;
  } catch (const InputError&) {
    return false;
  }
}

struct Submission {
  int shards = 0;
  std::vector<std::string> command;
  std::vector<std::string> job_of;  ///< job id of the array each shard was last submitted in
};

std::optional<Submission> read_submission(const ArrayJob& j) {
  if (!fs::exists(slurm_dir(j) / "job.json")) return std::nullopt;
  json d;
  try {
    d = read_json_file(slurm_dir(j) / "job.json");
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) + "; remove it");
  }
  if (!d.is_object())
    throw InputError((slurm_dir(j) / "job.json").string() + ": not a JSON object; remove it");
  Submission s;
  s.shards = d.value("shards", 0);
  s.command = d.value("command", std::vector<std::string>());
  s.job_of = d.value("jobs", std::vector<std::string>());
  if (s.shards < 1 || static_cast<int>(s.job_of.size()) != s.shards)
    throw InputError((slurm_dir(j) / "job.json").string() + ": malformed; remove it");
  return s;
}

void write_submission(const ArrayJob& j, const Submission& s) {
  const json d = {
      {"tool", j.tool}, {"shards", s.shards}, {"command", s.command}, {"jobs", s.job_of}};
  sweep::write_atomically(slurm_dir(j) / "job.json", d.dump(1) + "\n");
}

/// The job script: array task i runs shard i of n, then records how it ended.
std::string job_script(const ArrayJob& j, const Request& r, int n) {
  std::ostringstream s;
  const std::string dir = slurm_dir(j).string();
  s << "#!/bin/bash\n"
    << "# pinsim " << j.tool << " on Slurm, written by `pinsim " << j.tool << " --slurm`:\n"
    << "# array task i runs shard i of " << n << " and records its exit in "
    << "slurm/shard-i.status.\n"
    << "# Resubmit some shards by hand:  sbatch --array=I,J " << dir << "/job.sh\n"
    << "# or rerun the pinsim command with --resume: it resubmits the shards without a result.\n"
    << "#SBATCH --job-name=pinsim-" << j.tool << "\n"
    << "#SBATCH --output=" << dir << "/shard-%a.log\n"
    << "#SBATCH --open-mode=append\n"
    << "#SBATCH --ntasks=1\n"
    << "#SBATCH --cpus-per-task=" << r.cpus << "\n"
    << "#SBATCH --chdir=" << fs::current_path().string() << "\n";
  if (!r.partition.empty()) s << "#SBATCH --partition=" << r.partition << "\n";
  if (!r.time.empty()) s << "#SBATCH --time=" << r.time << "\n";
  if (!r.mem.empty()) s << "#SBATCH --mem=" << r.mem << "\n";
  for (const auto& a : r.sbatch_args) s << "#SBATCH " << a << "\n";
  s << "i=${SLURM_ARRAY_TASK_ID:?submit this script as a job array: sbatch --array=0-" << n - 1
    << " " << dir << "/job.sh}\n"
    << "n=" << n << "\n"
    << "status=" << quote(dir) << "/shard-$i.status\n"
    << "rm -f \"$status\"\n"
    << "start=$(date +%s.%N)\n"
    << "echo \"== pinsim shard $i of $n: job ${SLURM_ARRAY_JOB_ID}_$i on $(hostname), "
       "$(date '+%F %T')\"\n";
  for (const auto& a : j.command) s << quote(a) << " ";
  s << "--shard \"$i/$n\"\n"
    << "code=$?\n"
    << "echo \"== pinsim shard $i of $n: exit code $code, $(date '+%F %T')\"\n"
    << "printf '{\"shard\": %d, \"exit\": %d, \"start\": %s, \"end\": %s, \"job\": \"%s_%s\"}\\n' "
       "\"$i\" \"$code\" \"$start\" \"$(date +%s.%N)\" \"$SLURM_ARRAY_JOB_ID\" \"$i\" "
       ">\"$status.tmp.$$\" && mv -f \"$status.tmp.$$\" \"$status\"\n"
    << "exit $code\n";
  return s.str();
}

/// The array tasks in the queue that run `script` (whichever submission made them, also one
/// by hand): task index -> state (PENDING, RUNNING, ...). nullopt if squeue failed (a busy
/// controller): then nothing is concluded from it.
std::optional<std::map<int, std::string>> queue_states(const fs::path& script) {
  const Captured c = capture({"squeue", "--noheader", "--array", "--me", "--format=%i %T %o"});
  if (c.code != 0) {
    spdlog::warn("squeue failed (exit {}): {}", c.code, trim(c.output));
    return std::nullopt;
  }
  std::map<int, std::string> q;
  std::stringstream ss(c.output);
  std::string line;
  while (std::getline(ss, line)) {
    std::stringstream ls(line);
    std::string id, state, command;
    ls >> id >> state >> command;
    const auto us = id.find('_');
    if (command != script.string() || us == std::string::npos) continue;
    try {
      const int task = std::stoi(id.substr(us + 1));
      if (!q.count(task) || state == "RUNNING") q[task] = state;
    } catch (const std::exception&) {
      // "12_[3-5]": a pending range squeue did not expand; not ours to guess
    }
  }
  return q;
}

/// What Slurm remembers of a job that has left the queue: "TIMEOUT (reason ..., exit 0:15)";
/// "" when the controller has forgotten it.
std::string ended_state(const std::string& task) {
  const Captured c = capture({"scontrol", "--oneliner", "show", "job", task});
  if (c.code != 0) return "";
  auto field = [&c](const std::string& key) {
    const auto p = c.output.find(" " + key + "=");
    if (p == std::string::npos) return std::string();
    const auto b = p + key.size() + 2;
    return c.output.substr(b, c.output.find(' ', b) - b);
  };
  std::string s = field("JobState");
  if (s.empty()) return "";
  const std::string reason = field("Reason"), code = field("ExitCode");
  if (!reason.empty() && reason != "None") s += ", reason " + reason;
  if (!code.empty()) s += ", exit code " + code;
  return s;
}

/// The command line of this process with --resume added and --no-wait dropped.
std::string resume_command() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::string arg, out;
  bool has_resume = false;
  while (std::getline(in, arg, '\0')) {
    if (arg == "--no-wait") continue;
    has_resume = has_resume || arg == "--resume";
    const bool plain = std::all_of(arg.begin(), arg.end(), [](unsigned char c) {
      return std::isalnum(c) || c == '/' || c == '.' || c == '-' || c == '_' || c == '=' ||
             c == ':';
    });
    if (!out.empty()) out += ' ';
    out += plain && !arg.empty() ? arg : quote(arg);
  }
  if (!has_resume) out += " --resume";
  return out;
}

enum class Phase { pending, running, done, failed };

/// Refuses what cannot be submitted (an option's form, Slurm's commands missing, an output
/// path that cannot go into #SBATCH lines), then creates OUT/slurm.
void prepare(const ArrayJob& job, const Request& r) {
  validate(r);
  for (const char* tool : {"sbatch", "squeue", "scontrol"})
    if (!on_path(tool))
      throw InputError(std::string(tool) +
                       " not found on PATH: --slurm needs Slurm's client commands (Debian: "
                       "slurm-client; on a cluster, a login node or `module load slurm`)");
  const std::string out_s = job.out.string();
  if (out_s.find_first_of(" \t\n'\"") != std::string::npos)
    throw InputError("--out " + out_s +
                     ": with --slurm the output folder's path must not hold "
                     "spaces or quotes (it goes into #SBATCH lines)");
  fs::create_directories(slurm_dir(job));
}

/// What this run submits and follows.
struct Plan {
  Submission sub;              ///< the submission as job.json will say it
  std::vector<int> to_submit;  ///< shards to (re)submit now, ascending
  std::vector<bool> follow;    ///< shards this run waits for: (re)submitted now, or still queued
};

/// --resume: the previous submission's shards without a complete result that are no longer
/// queued are resubmitted; those still queued are followed.
Plan plan_resume(const ArrayJob& job, const Request& r, const std::optional<Submission>& prev,
                 const std::function<bool(int)>& queued) {
  const std::string out_s = job.out.string();
  if (!prev)
    throw InputError("--resume: nothing to resume in " + out_s +
                     " (no slurm/job.json); "
                     "submit without --resume first");
  if (r.shards && r.shards != prev->shards)
    throw InputError("--resume --shards " + std::to_string(r.shards) + ": " + out_s +
                     " was submitted with " + std::to_string(prev->shards) +
                     " shards; drop --shards, or start over without --resume");
  if (prev->command != job.command)
    throw InputError("--resume: " + out_s +
                     " was submitted for a different command (config, options or "
                     "program); start over without --resume");
  Plan p;
  p.sub = *prev;
  p.follow.assign(p.sub.shards, true);
  for (int i = 0; i < p.sub.shards; ++i) {
    if (queued(i)) continue;  // still queued or running: follow it
    if (result_complete(job, i, p.sub.shards))
      p.follow[i] = false;
    else
      p.to_submit.push_back(i);
  }
  if (p.to_submit.empty())
    spdlog::info("--resume: no shard to resubmit ({} complete or still queued)", p.sub.shards);
  else
    spdlog::info("--resume: resubmitting shard{} {} of {}", p.to_submit.size() > 1 ? "s" : "",
                 ranges(p.to_submit), p.sub.shards);
  return p;
}

/// A fresh start: every shard is submitted. Refused while shards of the previous submission
/// are still queued; no result, status or log of an earlier submission may be mistaken for
/// one of this one, so they are removed.
Plan plan_fresh(const ArrayJob& job, const Request& r, const std::optional<Submission>& prev,
                const std::function<bool(int)>& queued) {
  const std::string out_s = job.out.string();
  if (prev)
    for (int i = 0; i < prev->shards; ++i)
      if (queued(i))
        throw InputError(out_s + " has shards of job " + prev->job_of[i] +
                         " still queued or running; follow them with --resume, or "
                         "`scancel " +
                         prev->job_of[i] + "` first");
  Plan p;
  p.sub.shards = r.shards ? r.shards : kDefaultShards;
  p.sub.command = job.command;
  p.sub.job_of.assign(p.sub.shards, "");
  std::error_code ec;
  const int old_n = prev ? prev->shards : 0;
  for (int n : {old_n, p.sub.shards})
    for (int i = 0; i < n; ++i) {
      fs::remove(job.result(i, n), ec);
      fs::remove(sweep::manifest_path(job.result(i, n)), ec);
    }
  for (int i = 0; i < std::max(old_n, p.sub.shards); ++i) {
    fs::remove(status_file(job, i), ec);
    fs::remove(log_file(job, i), ec);
  }
  for (int i = 0; i < p.sub.shards; ++i) p.to_submit.push_back(i);
  p.follow.assign(p.sub.shards, true);
  return p;
}

/// Which shards to submit and follow, from the previous submission (job.json) and the queue.
Plan plan_submission(const ArrayJob& job, const Request& r, const fs::path& script) {
  const auto prev = read_submission(job);
  const auto queue = queue_states(script);
  auto queued = [&queue](int i) { return queue && queue->count(i) > 0; };
  if (prev && !queue)
    throw InputError(
        "squeue failed, so it is unknown whether shards of the previous "
        "submission in " +
        job.out.string() + " are still queued; try again");
  return r.resume ? plan_resume(job, r, prev, queued) : plan_fresh(job, r, prev, queued);
}

/// Writes the job script and submits one array of the shards to (re)run; records the job in
/// job.json and returns its id ("" if there was nothing to submit).
std::string submit(const ArrayJob& job, const Request& r, const fs::path& script, Plan& p) {
  sweep::write_atomically(script, job_script(job, r, p.sub.shards));
  fs::permissions(script, fs::perms::owner_exec, fs::perm_options::add);
  if (p.to_submit.empty()) return "";
  for (int i : p.to_submit) {
    std::error_code ec;
    fs::remove(status_file(job, i), ec);
  }
  const Captured c =
      capture({"sbatch", "--parsable", "--array=" + ranges(p.to_submit), script.string()});
  const std::string id = trim(c.output.substr(0, c.output.find(';')));
  if (c.code != 0 || id.empty() ||
      !std::all_of(id.begin(), id.end(), [](unsigned char ch) { return std::isdigit(ch); }))
    throw InputError("sbatch refused the job array (exit " + std::to_string(c.code) +
                     "): " + trim(c.output));
  for (int i : p.to_submit) p.sub.job_of[i] = id;
  write_submission(job, p.sub);
  spdlog::info("submitted job {}: shard{} {} of {} ({}), logs in {}/shard-I.log", id,
               p.to_submit.size() > 1 ? "s" : "", ranges(p.to_submit), p.sub.shards,
               script.string(), slurm_dir(job).string());
  return id;
}

/// What is known of each shard while it is followed.
struct Tracker {
  std::vector<Phase> phase;
  std::vector<std::string> why;    ///< a failed shard's reason
  std::vector<int> absent;         ///< squeue looks that did not find it
  std::vector<int> exit_code;      ///< from its status file
  std::vector<double> gone_since;  ///< when it was first missing from the queue, s; -1 if not
  bool ended(int i) const { return phase[i] == Phase::done || phase[i] == Phase::failed; }
};

/// The shards' own files: a status file is written when a shard's command ends.
void read_statuses(const ArrayJob& job, int n, Tracker& t) {
  for (int i = 0; i < n; ++i) {
    if (t.ended(i)) continue;
    if (const auto st = read_status(job, i)) {
      t.exit_code[i] = st->exit;
      if ((st->exit == 0 || st->exit == 1) && result_complete(job, i, n)) {
        t.phase[i] = Phase::done;
      } else {
        t.phase[i] = Phase::failed;
        t.why[i] = st->exit == 2 ? "exit code 2 (bad input: nothing ran)"
                                 : "exit code " + std::to_string(st->exit);
        if (st->exit == 0 || st->exit == 1) t.why[i] += ", but its result is incomplete";
      }
    }
  }
}

/// The queue: a shard in it is pending or running; one that left it without a status file
/// is looked up in Slurm's records. `elapsed` is the time since following began, s.
void read_queue(const ArrayJob& job, const fs::path& script, const Submission& sub, double elapsed,
                Tracker& t) {
  const auto q = queue_states(script);
  if (!q) return;
  for (int i = 0; i < sub.shards; ++i) {
    if (t.ended(i)) continue;
    const std::string task = sub.job_of[i] + "_" + std::to_string(i);
    const auto it = q->find(i);
    if (it != q->end()) {
      t.absent[i] = 0;
      t.gone_since[i] = -1.0;
      t.phase[i] =
          it->second == "RUNNING" || it->second == "COMPLETING" ? Phase::running : Phase::pending;
      continue;
    }
    // Its command ended between the two looks (read_statuses found no status file, and the
    // job has left the queue since): its own status file, read on the next look, says how.
    if (read_status(job, i)) continue;
    // Left the queue without a status file: ask Slurm how it ended. A shard that
    // completed but whose status file is not visible yet (a slow shared file system)
    // gets two minutes; one Slurm has forgotten counts as failed on the second look.
    const std::string ended = ended_state(task);
    ++t.absent[i];
    if (t.gone_since[i] < 0) t.gone_since[i] = elapsed;
    if (ended.rfind("COMPLETED", 0) == 0 && elapsed - t.gone_since[i] < 120.0) continue;
    if (ended.empty() && t.absent[i] < 2) continue;
    // Killed after its command had written the whole result (a cancel or a time limit
    // between the result's rename and the status file): the result is checked against
    // its manifest's hash, so it is as good as a completed shard's.
    if (result_complete(job, i, sub.shards)) {
      spdlog::info(
          "shard {} of {} (job {}) ended {} after writing its complete result; "
          "using it",
          i, sub.shards, task, ended.empty() ? "without a record" : ended);
      t.phase[i] = Phase::done;
      continue;
    }
    t.phase[i] = Phase::failed;
    t.why[i] = ended.empty() ? "left the queue without a result, and Slurm has no record of "
                               "it (cancelled before it started?)"
                             : ended;
  }
}

/// "3/8 done, 2 running, 3 pending, 0 failed"; `all` is set when every shard has ended.
std::string progress_line(const Tracker& t, int n, bool& all) {
  int n_done = 0, n_run = 0, n_pend = 0, n_fail = 0;
  for (Phase p : t.phase) {
    n_done += p == Phase::done;
    n_run += p == Phase::running;
    n_pend += p == Phase::pending;
    n_fail += p == Phase::failed;
  }
  all = n_done + n_fail == n;
  return fmt::format("{}/{} done, {} running, {} pending, {} failed", n_done, n, n_run, n_pend,
                     n_fail);
}

/// Follows every shard until it is done or has failed, logging each change of the counts.
/// Returns false when Ctrl-C stopped following (the shards keep running).
bool follow_shards(const ArrayJob& job, const fs::path& script, const Plan& p, Tracker& t) {
  const Submission& sub = p.sub;
  const int n = sub.shards;
  t.phase.assign(n, Phase::pending);
  t.why.assign(n, "");
  t.absent.assign(n, 0);
  t.exit_code.assign(n, 0);
  t.gone_since.assign(n, -1.0);
  std::string jobs_label;
  for (int i = 0; i < n; ++i) {
    if (!p.follow[i]) {
      t.phase[i] = Phase::done;  // complete before this run
      if (const auto st = read_status(job, i)) t.exit_code[i] = st->exit;
    } else if (jobs_label.find(sub.job_of[i]) == std::string::npos) {
      jobs_label += (jobs_label.empty() ? "" : ",") + sub.job_of[i];
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  auto elapsed = [&t0] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  double next_squeue = 0.0;
  std::string last_line;
  g_interrupted = 0;
  const auto old_handler = std::signal(SIGINT, on_sigint);
  for (;;) {
    read_statuses(job, n, t);
    bool all_ended = true;
    for (int i = 0; i < n; ++i) all_ended = all_ended && t.ended(i);
    // Then the queue, less often the longer the wait (1 s at first, at most every 10 s).
    if (!all_ended && elapsed() >= next_squeue) {
      next_squeue = elapsed() + std::min(10.0, 1.0 + elapsed() / 30.0);
      read_queue(job, script, sub, elapsed(), t);
    }
    bool all = false;
    const std::string line = progress_line(t, n, all);
    if (line != last_line) {
      if (jobs_label.empty())
        spdlog::info("slurm: {} ({:.1f} s)", line, elapsed());
      else
        spdlog::info("slurm job {}: {} ({:.1f} s)", jobs_label, line, elapsed());
      last_line = line;
    }
    if (all) break;
    if (g_interrupted) {
      std::signal(SIGINT, old_handler);
      spdlog::warn("stopped following; the shards keep running. Collect them with:\n  {}",
                   resume_command());
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  std::signal(SIGINT, old_handler);
  return true;
}

/// Run time of the shards of this submission: the union of their [start, end], s.
double busy_seconds(const ArrayJob& job, int n, double submitted_at) {
  std::vector<std::pair<double, double>> spans;
  for (int i = 0; i < n; ++i)
    if (const auto st = read_status(job, i))
      if (st->end >= submitted_at - 1.0 && st->end >= st->start)
        spans.emplace_back(std::max(st->start, submitted_at), st->end);
  std::sort(spans.begin(), spans.end());
  double busy = 0, cur_b = 0, cur_e = -1;
  for (const auto& [b, e] : spans) {
    if (b > cur_e) {
      busy += std::max(0.0, cur_e - cur_b);
      cur_b = b;
      cur_e = e;
    } else {
      cur_e = std::max(cur_e, e);
    }
  }
  busy += std::max(0.0, cur_e - cur_b);
  return busy;
}

/// Logs each failed shard with its reason and its log's last lines, then how to resubmit
/// only those. False if none failed.
bool report_failed(const ArrayJob& job, const Submission& sub, const Tracker& t) {
  std::vector<int> failed;
  for (int i = 0; i < sub.shards; ++i)
    if (t.phase[i] == Phase::failed) failed.push_back(i);
  if (failed.empty()) return false;
  for (int i : failed) {
    const fs::path log = log_file(job, i);
    const std::string tail = last_lines(log, 12);
    spdlog::error("shard {} of {} (job {}_{}) failed: {}; log {}{}", i, sub.shards, sub.job_of[i],
                  i, t.why[i], log.string(),
                  tail.empty() ? " (none: it never started)" : ", last lines:\n" + tail);
  }
  spdlog::error("{} of {} shards failed (shard{} {}); resubmit only those with:\n  {}",
                failed.size(), sub.shards, failed.size() > 1 ? "s" : "", ranges(failed),
                resume_command());
  return true;
}

}  // namespace

double now_unix() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

void validate(const Request& r) {
  if (r.shards < 0 || r.shards > 100000)
    throw InputError("--shards " + std::to_string(r.shards) + ": expected 1 to 100000");
  if (r.cpus < 1 || r.cpus > 4096)
    throw InputError("--cpus " + std::to_string(r.cpus) + ": expected 1 to 4096");
  // Slurm's time forms: M, M:S, H:M:S, D-H, D-H:M, D-H:M:S, or UNLIMITED.
  static const std::regex time_re(
      R"(^(\d+(:\d{1,2}){0,2}|\d+-\d{1,2}(:\d{1,2}){0,2}|UNLIMITED|INFINITE)$)");
  if (!r.time.empty() && !std::regex_match(r.time, time_re))
    throw InputError("--time " + r.time +
                     ": expected Slurm's form: minutes, MM:SS, HH:MM:SS, D-HH, D-HH:MM or "
                     "D-HH:MM:SS (e.g. 30 or 1:30:00)");
  static const std::regex mem_re(R"(^\d+[KMGT]?$)");
  if (!r.mem.empty() && !std::regex_match(r.mem, mem_re))
    throw InputError("--mem " + r.mem +
                     ": expected a size in MB or with a unit K, M, G, T "
                     "(e.g. 2000 or 2G)");
  static const std::regex part_re(R"(^[A-Za-z0-9_.,-]+$)");
  if (!r.partition.empty() && !std::regex_match(r.partition, part_re))
    throw InputError("--partition " + r.partition +
                     ": expected a partition name (letters, digits, _ . -; several with commas)");
  for (const auto& a : r.sbatch_args)
    if (a.size() < 2 || a[0] != '-' || a.find('\n') != std::string::npos)
      throw InputError("--sbatch-arg " + a +
                       ": expected one sbatch option such as --account=phys101");
}

Outcome run(const ArrayJob& job, const Request& r) {
  prepare(job, r);
  Outcome o;
  o.submitted_at = now_unix();
  // Plan: which shards to (re)submit and which to follow; then submit them.
  const fs::path script = slurm_dir(job) / "job.sh";
  Plan plan = plan_submission(job, r, script);
  o.shards = plan.sub.shards;
  o.jobs = submit(job, r, script, plan);
  if (!r.wait) {
    std::cout << (o.jobs.empty() ? "none" : o.jobs) << "\n";
    spdlog::info("not waiting; collect the results later with:\n  {}", resume_command());
    return o;
  }

  // Loop: follow every shard until it is done or has failed.
  Tracker track;
  if (!follow_shards(job, script, plan, track)) {
    o.state = Outcome::State::interrupted;
    return o;
  }

  // Report: the shards' run time, then the failed shards or the results.
  o.busy_seconds = busy_seconds(job, plan.sub.shards, o.submitted_at);
  if (report_failed(job, plan.sub, track)) {
    o.state = Outcome::State::failed;
    return o;
  }
  o.state = Outcome::State::complete;
  for (int i = 0; i < plan.sub.shards; ++i) {
    o.results.push_back(job.result(i, plan.sub.shards));
    o.worst_exit = std::max(o.worst_exit, track.exit_code[i]);
  }
  return o;
}

}  // namespace pinsim::slurm
