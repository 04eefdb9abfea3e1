// pinsim bench CONFIG [--out DIR] [--shard i/N] [--repeats N] [--slurm [--shards N] ...]
#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>

#include "cli_slurm.hpp"
#include "commands.hpp"
#include "core/input_error.hpp"
#include "core/stop_signals.hpp"
#include "tools/bench.hpp"

namespace pinsim::cli {
namespace {

struct BenchArgs {
  std::string config, out = "out/bench", shard = "0/1";
  bool resume = false;
  int repeats = -1;
  SlurmArgs slurm;
};

int bench_on_slurm(const BenchArgs& a) {
  bench::Options check;  // a bad config fails here, not in every shard
  check.config = a.config;
  check.check_only = true;
  bench::run(check);
  std::vector<std::string> extra;
  if (a.repeats >= 0) extra = {"--repeats", std::to_string(a.repeats)};
  return sweep_on_slurm("bench", a.config, a.out, extra, a.slurm);
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto a = std::make_shared<BenchArgs>();
  CLI::App* c = app.add_subcommand(
      "bench", "Work-precision sweep: dt x integrator x backend against known answers");
  c->add_option("config", a->config, "Bench config (configs/bench/*.json)")->required();
  c->add_option("--out,-o", a->out, "Output folder for bench.csv and figures (default out/bench)");
  c->add_option("--shard", a->shard, "Run only every N-th point: i/N, 0 <= i < N (default 0/1)");
  c->add_option("--repeats", a->repeats, "Timed repeats per point (default: the config's, or 3)");
  c->add_flag("--continue", a->resume,
              "Continue an interrupted run in --out from its partial CSV: run only the points "
              "not in it, then write the whole table");
  add_slurm_options(c, a->slurm);
  c->callback([a, c] {
    check_slurm_options(c, a->slurm, c->count("--shard") > 0);
    if (a->slurm.slurm && a->resume)
      throw InputError("--continue is for a run without --slurm (with it: --resume)");
    if (a->slurm.slurm) throw CLI::RuntimeError(bench_on_slurm(*a));
    bench::Options o;
    o.config = a->config;
    o.resume = a->resume;
    install_stop_handlers();
    o.out = a->out;
    o.shard = sweep::parse_shard(a->shard);
    o.repeats = a->repeats;
    throw CLI::RuntimeError(bench::run(o));
  });
}

}  // namespace pinsim::cli
