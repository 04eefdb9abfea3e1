// pinsim stress CONFIG [--out DIR] [--shard i/N]
#include <memory>

#include "commands.hpp"
#include "tools/stress.hpp"

namespace pinsim::cli {
namespace {
struct StressArgs {
  std::string config, out = "out/stress", shard = "0/1";
};
}  // namespace

void add_stress_command(CLI::App& app) {
  auto a = std::make_shared<StressArgs>();
  CLI::App* c = app.add_subcommand(
      "stress", "Stability maps: stiffness x dt x integrator, tunnelling, contacts, long runs");
  c->add_option("config", a->config, "Stress config (configs/stress/*.json)")->required();
  c->add_option("--out,-o", a->out, "Output folder for stress.csv and heat maps");
  c->add_option("--shard", a->shard, "Run only every N-th point: i/N, 0 <= i < N (default 0/1)");
  c->callback([a] {
    stress::Options o;
    o.config = a->config;
    o.out = a->out;
    o.shard = sweep::parse_shard(a->shard);
    throw CLI::RuntimeError(stress::run(o));
  });
}

}  // namespace pinsim::cli
