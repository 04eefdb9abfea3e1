// The Slurm options shared by bench, stress and grade --batch (--slurm, --shards, ...), and
// running a command's shards as one job array, then merging them as `pinsim merge` does.
#pragma once

#include <CLI/CLI.hpp>
#include <filesystem>
#include <string>
#include <vector>

#include "tools/slurm.hpp"

namespace pinsim::cli {

struct SlurmArgs {
  bool slurm = false;
  bool no_wait = false;
  slurm::Request request;
};

/// Adds --slurm, --shards, --partition, --time, --mem, --cpus, --sbatch-arg, --no-wait and
/// --resume to a subcommand.
void add_slurm_options(CLI::App* c, SlurmArgs& a);

/// Throws InputError (exit 2) if a Slurm option is given without --slurm, or --slurm
/// together with --shard (`shard_given`).
void check_slurm_options(const CLI::App* c, const SlurmArgs& a, bool shard_given);

/// Runs `job` on Slurm (see slurm::run), then merges the shards into `job.out` exactly as
/// `pinsim merge` does and prints the Slurm overhead. Returns the exit code: 0, 1 (a shard
/// failed, or a point failed as in an unsharded run), 130 (stopped following).
int run_on_slurm(const slurm::ArrayJob& job, const SlurmArgs& a);

/// Runs a sweep tool's shards (tool "bench" or "stress") on Slurm: array task i of n runs
/// `pinsim TOOL CONFIG --out OUT EXTRA... --shard i/n` and writes sweep::csv_path(OUT, TOOL,
/// i/n); then merges them as run_on_slurm does. Check the config before calling this.
int sweep_on_slurm(const std::string& tool, const std::string& config, const std::string& out,
                   const std::vector<std::string>& extra, const SlurmArgs& a);

/// `pinsim merge`'s work: joins shard CSVs (bench, stress, or grade --batch) into the file an
/// unsharded run writes in `out` (bench.csv, stress.csv, batch-0-of-1.csv), then reports and
/// plots as an unsharded run does. Throws InputError for an incomplete or inconsistent set.
int merge_shards(const std::vector<std::filesystem::path>& files, const std::filesystem::path& out);

/// This program's absolute path (/proc/self/exe).
std::filesystem::path self_exe();

}  // namespace pinsim::cli
