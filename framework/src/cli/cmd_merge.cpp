// pinsim merge [--out DIR] CSV...   (joins the shard CSVs of a bench or stress sweep, or of
// a sharded grade --batch)
#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>

#include "cli_slurm.hpp"
#include "commands.hpp"
#include "core/input_error.hpp"
#include "tools/bench.hpp"
#include "tools/stress.hpp"

namespace pinsim::cli {
namespace {

struct MergeArgs {
  std::vector<std::string> files;
  std::string out = ".";
};

/// The CSV header of grade --batch's batch-i-of-N.csv.
const std::vector<std::string> kBatchColumns = {"submission", "score", "max_score"};

}  // namespace

int merge_shards(const std::vector<std::filesystem::path>& files,
                 const std::filesystem::path& out) {
  const sweep::Table t = sweep::merge(files);
  const bool is_bench = t.header == bench::columns();
  const bool is_stress = t.header == stress::columns();
  const bool is_batch = t.header == kBatchColumns;
  if (!is_bench && !is_stress && !is_batch)
    throw InputError(files[0].string() +
                     ": not a bench, stress or grade --batch CSV (unknown "
                     "header)");
  const auto csv = out / (is_bench ? "bench.csv" : is_stress ? "stress.csv" : "batch-0-of-1.csv");
  t.write(csv);
  spdlog::info("merged {} rows from {} files into {}", t.rows.size(), files.size(), csv.string());
  if (is_bench) bench::report(t, out);
  if (is_stress) stress::report(t, out);
  return 0;
}

void add_merge_command(CLI::App& app) {
  auto m = std::make_shared<MergeArgs>();
  CLI::App* mc = app.add_subcommand(
      "merge",
      "Join the shard CSVs of a bench or stress sweep or of grade --batch; then report and plot");
  mc->add_option("csv", m->files,
                 "Shard CSV files (bench.shard-*.csv, stress.shard-*.csv, batch-*-of-N.csv), "
                 "each with its manifest (.json) beside it")
      ->required();
  mc->add_option("--out,-o", m->out, "Output folder for the merged CSV and figures");
  mc->callback([m] {
    const std::vector<std::filesystem::path> files(m->files.begin(), m->files.end());
    throw CLI::RuntimeError(merge_shards(files, m->out));
  });
}

}  // namespace pinsim::cli
