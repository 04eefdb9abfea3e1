// pinsim stress: where each integrator and backend stays stable. Grids of stiffness x dt x
// integrator (empirical stability limit next to theory), ball speed x wall thickness
// (tunnelling), many simultaneous contacts and long runs; every run classified.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "tools/sweep.hpp"

namespace pinsim::stress {

struct Options {
  std::filesystem::path config;
  std::filesystem::path out = "out/stress";
  sweep::Shard shard;
  bool resume = false;      ///< continue an interrupted run from its partial CSV (sweep::drive)
  bool check_only = false;  ///< read and check the config, run and write nothing
};

/// Runs this shard's points, writes OUT/stress[.shard-i-of-N].csv; for a whole sweep also
/// prints the stability limits and tunnelling grids and draws heat maps. Returns 0.
int run(const Options& o);

/// Stability limits vs theory and the grids, from a stress table; heat maps into `out`.
void report(const sweep::Table& t, const std::filesystem::path& out);

/// The CSV header of a stress table (first column "point").
const std::vector<std::string>& columns();

/// Theoretical stability limit of h w_max for an undamped oscillator: 2 (symplectic Euler,
/// velocity Verlet), 2 sqrt(2) (RK4), 0 (explicit Euler: unstable for every h), +inf
/// (implicit Euler); NaN for an unknown integrator.
double theory_limit(const std::string& integrator);

}  // namespace pinsim::stress
