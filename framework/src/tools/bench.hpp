// pinsim bench: work-precision sweeps of dt x integrator x backend on scenes with a known
// answer (closed forms, or a very fine reference run).
#pragma once

#include <filesystem>
#include <string>

#include "tools/sweep.hpp"

namespace pinsim::bench {

struct Options {
  std::filesystem::path config;
  std::filesystem::path out = "out/bench";
  sweep::Shard shard;
  bool resume = false;      ///< continue an interrupted run from its partial CSV (sweep::drive)
  bool check_only = false;  ///< read and check the config, run and write nothing
  int repeats = -1;         ///< overrides the config's "repeats" when >= 0
};

/// Runs this shard's points, writes OUT/bench[.shard-i-of-N].csv; for a whole sweep also
/// prints the observed orders and draws the work-precision figures. Returns the exit code
/// (0; 1 if some point failed numerically). Config errors throw InputError.
int run(const Options& o);

/// Observed convergence order per (case, backend, integrator) from a bench table, printed
/// to stdout; and one work-precision figure per case in `out` (gnuplot, skipped if absent).
void report(const sweep::Table& t, const std::filesystem::path& out);

/// The CSV header of a bench table (first column "point").
const std::vector<std::string>& columns();

}  // namespace pinsim::bench
