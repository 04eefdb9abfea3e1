// pinsim merge [--out DIR] CSV...   (joins shard CSVs of a bench or stress sweep)
#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>

#include "commands.hpp"
#include "core/scene_error.hpp"
#include "tools/bench.hpp"
#include "tools/stress.hpp"

namespace pinsim::cli {
namespace {

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

void add_merge_command(CLI::App& app) {
  auto m = std::make_shared<MergeArgs>();
  CLI::App* mc = app.add_subcommand(
      "merge", "Join the shard CSVs of a bench or stress sweep, then report and plot");
  mc->add_option("csv", m->files, "Shard CSV files (bench.shard-*.csv or stress.shard-*.csv)")
      ->required();
  mc->add_option("--out,-o", m->out, "Output folder for the merged CSV and figures");
  mc->callback([m] { throw CLI::RuntimeError(merge_command(*m)); });
}

}  // namespace pinsim::cli
