// pinsim bench CONFIG [--out DIR] [--shard i/N] [--repeats N]
// pinsim merge [--out DIR] CSV...   (joins shard CSVs of a bench or stress sweep)
#include <spdlog/spdlog.h>

#include <memory>

#include "bench.hpp"
#include "commands.hpp"
#include "stress.hpp"

namespace pinsim::cli {
namespace {

struct BenchArgs {
  std::string config, out = "out/bench", shard = "0/1";
  int repeats = -1;
};

struct MergeArgs {
  std::vector<std::string> files;
  std::string out = ".";
};

int merge_command(const MergeArgs& a) {
  std::vector<std::filesystem::path> files(a.files.begin(), a.files.end());
  const sweep::Table t = sweep::merge(files);
  const bool is_bench = t.header == bench::columns();
  const bool is_stress = t.header == stress::columns();
  if (!is_bench && !is_stress)
    throw SceneError(a.files[0] + ": not a bench or stress CSV (unknown header)");
  const std::filesystem::path out = a.out;
  const auto csv = out / (is_bench ? "bench.csv" : "stress.csv");
  t.write(csv);
  spdlog::info("merged {} rows from {} files into {}", t.rows.size(), files.size(), csv.string());
  if (is_bench)
    bench::report(t, out);
  else
    stress::report(t, out);
  return 0;
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
  c->callback([a] {
    bench::Options o;
    o.config = a->config;
    o.out = a->out;
    o.shard = sweep::parse_shard(a->shard);
    o.repeats = a->repeats;
    throw CLI::RuntimeError(bench::run(o));
  });

  auto m = std::make_shared<MergeArgs>();
  CLI::App* mc = app.add_subcommand(
      "merge", "Join the shard CSVs of a bench or stress sweep, then report and plot");
  mc->add_option("csv", m->files, "Shard CSV files (bench.shard-*.csv or stress.shard-*.csv)")
      ->required();
  mc->add_option("--out,-o", m->out, "Output folder for the merged CSV and figures");
  mc->callback([m] { throw CLI::RuntimeError(merge_command(*m)); });
}

}  // namespace pinsim::cli
