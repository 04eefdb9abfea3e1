// pinsim on a Slurm cluster: the shards of a sweep (bench, stress) or of a batch grade as one
// job array. Writes the job script, submits it with sbatch, follows it with squeue and the
// shards' own status files, reports a failed shard by index with its log, and on --resume
// resubmits only the shards that have no complete result. Merging is the caller's.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace pinsim::slurm {

/// What the user asked for on the command line (--shards, --partition, ...).
struct Request {
  int shards = 0;         ///< shards; 0: not given (8, or the previous submission's on --resume)
  std::string partition;  ///< sbatch --partition; "" for the cluster's default
  std::string time;       ///< sbatch --time per shard (minutes, H:MM:SS, D-HH:MM, ...); ""
  std::string mem;        ///< sbatch --mem per shard (e.g. 2G); ""
  int cpus = 1;           ///< sbatch --cpus-per-task
  std::vector<std::string> sbatch_args;  ///< more #SBATCH options, e.g. --account=phys101
  bool wait = true;                      ///< follow the array until every shard has ended
  bool resume = false;                   ///< resubmit only the shards without a result
};

/// Default shard count of a new submission.
inline constexpr int kDefaultShards = 8;

/// Checks the values' forms (--time as Slurm reads it, --mem as digits and a unit, ...);
/// throws InputError naming the option and what was expected.
void validate(const Request& r);

/// One job array: the command of a shard and where the shards write.
struct ArrayJob {
  std::string tool;           ///< "bench", "stress" or "grade": the job's name is pinsim-TOOL
  std::filesystem::path out;  ///< the run's output folder, absolute, on a shared file system
  /// One shard's command line without --shard (absolute paths; the driver appends
  /// `--shard i/N`).
  std::vector<std::string> command;
  /// The CSV that shard i of n writes (its manifest beside it marks it complete).
  std::function<std::filesystem::path(int i, int n)> result;
};

/// How the array ended (or that it was only submitted).
struct Outcome {
  enum class State { submitted, complete, failed, interrupted };
  State state = State::submitted;
  std::string jobs;  ///< the job ids of this submission, comma separated ("" if none needed)
  int shards = 0;    ///< N
  std::vector<std::filesystem::path> results;  ///< complete: shard i's CSV at [i]
  int worst_exit = 0;       ///< complete: largest shard exit code (1: some point failed)
  double submitted_at = 0;  ///< Unix time of the submission (or of the resume), s
  /// Seconds in which at least one shard of this submission was running (the union of their
  /// run intervals): the shards' own run time, for the overhead figure.
  double busy_seconds = 0;
};

/// Submits the array (with r.resume: resubmits only the shards without a complete result,
/// and follows the previous submission's shards still queued) and, if r.wait, follows it
/// until every shard has ended, printing progress. Throws InputError for bad input (an
/// option, sbatch refusing the job, a resume that does not match the previous submission).
Outcome run(const ArrayJob& job, const Request& r);

/// Unix time now, s.
double now_unix();

}  // namespace pinsim::slurm
