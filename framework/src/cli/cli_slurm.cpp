#include "cli_slurm.hpp"

#include <spdlog/spdlog.h>

#include "core/input_error.hpp"
#include "tools/sweep.hpp"

namespace pinsim::cli {

void add_slurm_options(CLI::App* c, SlurmArgs& a) {
  const char* g = "Slurm (a job array, one task per shard)";
  c->add_flag("--slurm", a.slurm,
              "Run the shards as one Slurm job array, wait for them and merge (see docs)")
      ->group(g);
  c->add_option("--shards", a.request.shards, "With --slurm: number of shards (default 8)")
      ->group(g);
  c->add_option("--partition", a.request.partition, "With --slurm: sbatch --partition")->group(g);
  c->add_option("--time", a.request.time,
                "With --slurm: time limit per shard, Slurm's form (30, 1:30:00, 1-00:00)")
      ->group(g);
  c->add_option("--mem", a.request.mem, "With --slurm: memory per shard (2000, 2G)")->group(g);
  c->add_option("--cpus", a.request.cpus, "With --slurm: CPUs per shard (default 1)")->group(g);
  c->add_option("--sbatch-arg", a.request.sbatch_args,
                "With --slurm: one more #SBATCH option, e.g. --sbatch-arg=--account=phys101")
      ->group(g);
  c->add_flag("--no-wait", a.no_wait, "With --slurm: print the job id and return")->group(g);
  c->add_flag("--resume", a.request.resume,
              "With --slurm: follow the shards still queued and resubmit only those without a "
              "result, then merge")
      ->group(g);
}

void check_slurm_options(const CLI::App* c, const SlurmArgs& a, bool shard_given) {
  if (a.slurm && shard_given)
    throw InputError("--slurm runs every shard itself: drop --shard (use --shards N)");
  if (a.slurm) return;
  for (const char* o : {"--shards", "--partition", "--time", "--mem", "--cpus", "--sbatch-arg",
                        "--no-wait", "--resume"})
    if (c->count(o)) throw InputError(std::string(o) + " needs --slurm");
}

std::filesystem::path self_exe() { return std::filesystem::read_symlink("/proc/self/exe"); }

int run_on_slurm(const slurm::ArrayJob& job, const SlurmArgs& a) {
  slurm::Request r = a.request;
  r.wait = !a.no_wait;
  const slurm::Outcome o = slurm::run(job, r);
  switch (o.state) {
    case slurm::Outcome::State::submitted:
      return 0;
    case slurm::Outcome::State::interrupted:
      return 130;
    case slurm::Outcome::State::failed:
      return 1;
    case slurm::Outcome::State::complete:
      break;
  }
  const int merged = merge_shards(o.results, job.out);
  const double total = slurm::now_unix() - o.submitted_at;
  spdlog::info(
      "slurm: {} shards, submission to merged result {:.1f} s, shards running {:.1f} s (union "
      "of their run times), Slurm overhead {:.1f} s",
      o.shards, total, o.busy_seconds, total - o.busy_seconds);
  return std::max(merged, o.worst_exit);
}

int sweep_on_slurm(const std::string& tool, const std::string& config, const std::string& out,
                   const std::vector<std::string>& extra, const SlurmArgs& a) {
  slurm::ArrayJob job;
  job.tool = tool;
  job.out = std::filesystem::absolute(out).lexically_normal();
  job.command = {self_exe().string(), tool,
                 std::filesystem::absolute(config).lexically_normal().string(), "--out",
                 job.out.string()};
  job.command.insert(job.command.end(), extra.begin(), extra.end());
  job.result = [tool, out = job.out](int i, int n) {
    return sweep::csv_path(out, tool, sweep::Shard{i, n});
  };
  return run_on_slurm(job, a);
}

}  // namespace pinsim::cli
