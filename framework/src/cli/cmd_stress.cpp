// pinsim stress CONFIG [--out DIR] [--shard i/N] [--slurm [--shards N] ...]
#include <filesystem>
#include <memory>

#include "cli_slurm.hpp"
#include "commands.hpp"
#include "core/input_error.hpp"
#include "core/stop_signals.hpp"
#include "tools/stress.hpp"

namespace pinsim::cli {
namespace {

struct StressArgs {
  std::string config, out = "out/stress", shard = "0/1";
  bool resume = false;
  SlurmArgs slurm;
};

int stress_on_slurm(const StressArgs& a) {
  stress::Options check;  // a bad config fails here, not in every shard
  check.config = a.config;
  check.check_only = true;
  stress::run(check);
  return sweep_on_slurm("stress", a.config, a.out, {}, a.slurm);
}

}  // namespace

void add_stress_command(CLI::App& app) {
  auto a = std::make_shared<StressArgs>();
  CLI::App* c = app.add_subcommand(
      "stress", "Stability maps: stiffness x dt x integrator, tunnelling, contacts, long runs");
  c->add_option("config", a->config, "Stress config (configs/stress/*.json)")->required();
  c->add_option("--out,-o", a->out, "Output folder for stress.csv and heat maps");
  c->add_option("--shard", a->shard, "Run only every N-th point: i/N, 0 <= i < N (default 0/1)");
  c->add_flag("--continue", a->resume,
              "Continue an interrupted run in --out from its partial CSV: run only the points "
              "not in it, then write the whole table");
  add_slurm_options(c, a->slurm);
  c->callback([a, c] {
    check_slurm_options(c, a->slurm, c->count("--shard") > 0);
    if (a->slurm.slurm && a->resume)
      throw InputError("--continue is for a run without --slurm (with it: --resume)");
    if (a->slurm.slurm) throw CLI::RuntimeError(stress_on_slurm(*a));
    stress::Options o;
    o.config = a->config;
    o.resume = a->resume;
    install_stop_handlers();
    o.out = a->out;
    o.shard = sweep::parse_shard(a->shard);
    throw CLI::RuntimeError(stress::run(o));
  });
}

}  // namespace pinsim::cli
