// `pinsim bench`, `pinsim stress` and `pinsim merge` as a user runs them: the CSV columns,
// observed orders against theory, stability limits bracketing theory (h w = 2 for symplectic
// Euler and Verlet, 2 sqrt 2 for RK4, never for explicit Euler, always for implicit Euler),
// the tunnelling grid, sharding + merge reproducing an unsharded sweep, and the plots.
#include <sys/wait.h>

#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "../oscillator_bench.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

using pinsim::test::pinsim_cli;

/// A CSV as rows of named fields.
using Row = std::map<std::string, std::string>;
std::vector<Row> read_csv(const fs::path& file) {
  std::ifstream in(file);
  REQUIRE(in.good());
  auto split = [](const std::string& line) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    std::string x;
    while (std::getline(ss, x, ',')) f.push_back(x);
    return f;
  };
  std::string line;
  std::getline(in, line);
  const auto header = split(line);
  std::vector<Row> rows;
  while (std::getline(in, line)) {
    const auto f = split(line);
    REQUIRE(f.size() == header.size());
    Row r;
    for (std::size_t i = 0; i < f.size(); ++i) r[header[i]] = f[i];
    rows.push_back(r);
  }
  return rows;
}

const std::string kConfigs = PINSIM_SOURCE_DIR "/configs";

}  // namespace

TEST_CASE("bench: CSV, observed orders within 0.15 of theory, work-precision plot") {
  const fs::path dir = pinsim::test::temp_dir("bench");
  pinsim::test::write_file(dir / "osc.json", kBench);
  const auto r =
      pinsim_cli("-q bench " + (dir / "osc.json").string() + " --out " + (dir / "out").string());
  INFO(r.output);
  REQUIRE(r.code == 0);
  const auto rows = read_csv(dir / "out" / "bench.csv");
  REQUIRE(rows.size() == 8);                                          // 2 integrators x 4 dt
  std::map<std::string, std::vector<std::pair<double, double>>> err;  // integrator: (dt, err)
  for (const auto& row : rows) {
    CHECK(row.at("status") == "ok");
    CHECK(std::stod(row.at("time_median_s")) > 0);
    // Force evaluations: 1 per step for symplectic Euler, 2 for velocity Verlet.
    const double steps = std::stod(row.at("steps"));
    CHECK(std::stod(row.at("force_evals")) ==
          steps * (row.at("integrator") == "velocity_verlet" ? 2 : 1));
    err[row.at("integrator")].emplace_back(std::stod(row.at("dt")), std::stod(row.at("error_max")));
  }
  // Halving dt divides the error by 2^order: first order for symplectic Euler, second for
  // velocity Verlet (least-squares slope of log error against log dt).
  for (const auto& [name, pts] : err) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (const auto& [h, e] : pts) {
      sx += std::log(h), sy += std::log(e), sxx += std::log(h) * std::log(h),
          sxy += std::log(h) * std::log(e);
    }
    const double n = static_cast<double>(pts.size());
    const double order = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    INFO(name << " order " << order);
    CHECK(std::abs(order - (name == "velocity_verlet" ? 2.0 : 1.0)) <= 0.15);
  }
  // The printed orders agree with the CSV.
  CHECK_THAT(r.output, Catch::Contains("observed convergence order"));
  const fs::path svg = dir / "out" / "work_precision_oscillator.svg";
  REQUIRE(fs::exists(svg));
  const std::string text = pinsim::test::read_file(svg);
  CHECK_THAT(text, Catch::Contains("<svg"));
  CHECK_THAT(text, Catch::Contains("velocity_verlet / none"));  // names drawn as written
}

TEST_CASE("bench: an integrator exact for a case is listed as exact, not as nan") {
  // Under constant gravity velocity Verlet is exact: x_{n+1} = x_n + v_n dt + g dt^2 / 2 is
  // the Taylor series of x(t) = x0 + v0 t + g t^2 / 2 to its last term, so its error is
  // rounding at every dt. Symplectic Euler is first order: x(T) error = g T dt / 2.
  const fs::path dir = pinsim::test::temp_dir("bench-exact");
  pinsim::test::write_file(dir / "proj.json", R"({
    "repeats": 1, "integrators": ["symplectic_euler", "velocity_verlet"],
    "cases": [{"name": "toss",
      "scene": {"time": {"dt": 0.01, "duration": 0.25},
                "particles": [{"x": [0, 0], "v": [0.5, 1.0]}],
                "forces": [{"type": "gravity", "params": {"g": [0.0, -2.0]}}]},
      "answer": {"type": "projectile", "particle": 0, "g": [0.0, -2.0]},
      "dt": [0.01, 0.005, 0.0025]}]})");
  const auto r =
      pinsim_cli("-q bench " + (dir / "proj.json").string() + " --out " + (dir / "out").string());
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(r.output.find("nan") == std::string::npos);
  std::string verlet, euler;
  std::istringstream lines(r.output);
  for (std::string l; std::getline(lines, l);) {
    if (l.rfind("toss ", 0) != 0) continue;
    (l.find("velocity_verlet") != std::string::npos ? verlet : euler) = l;
  }
  CHECK_THAT(verlet, Catch::Contains("exact"));
  std::istringstream e(euler.substr(euler.find("/ none") + 6));
  double order_max = 0;
  e >> order_max;
  CHECK(std::abs(order_max - 1.0) <= 0.15);
  CHECK_THAT(r.output, Catch::Contains("exact: the error is at rounding level"));
}

TEST_CASE("bench --shard i/N and merge reproduce the unsharded errors") {
  const fs::path dir = pinsim::test::temp_dir("bench-shards");
  pinsim::test::write_file(dir / "osc.json", kBench);
  const std::string cfg = (dir / "osc.json").string(), out = (dir / "out").string();
  REQUIRE(pinsim_cli("-q bench " + cfg + " --out " + (dir / "whole").string()).code == 0);
  REQUIRE(pinsim_cli("-q bench " + cfg + " --out " + out + " --shard 0/3").code == 0);
  REQUIRE(pinsim_cli("-q bench " + cfg + " --out " + out + " --shard 1/3").code == 0);
  REQUIRE(pinsim_cli("-q bench " + cfg + " --out " + out + " --shard 2/3").code == 0);
  const auto s0 = read_csv(dir / "out" / "bench.shard-0-of-3.csv");
  const auto s1 = read_csv(dir / "out" / "bench.shard-1-of-3.csv");
  const auto s2 = read_csv(dir / "out" / "bench.shard-2-of-3.csv");
  CHECK(s0.size() + s1.size() + s2.size() == 8);
  CHECK(s0.size() == 3);  // points 0, 3, 6
  const auto m = pinsim_cli("-q merge --out " + out + " " + out + "/bench.shard-0-of-3.csv " + out +
                            "/bench.shard-1-of-3.csv " + out + "/bench.shard-2-of-3.csv");
  INFO(m.output);
  REQUIRE(m.code == 0);
  const auto merged = read_csv(dir / "out" / "bench.csv");
  const auto whole = read_csv(dir / "whole" / "bench.csv");
  REQUIRE(merged.size() == whole.size());
  for (std::size_t i = 0; i < whole.size(); ++i) {
    CHECK(merged[i].at("point") == whole[i].at("point"));
    CHECK(merged[i].at("integrator") == whole[i].at("integrator"));
    CHECK(merged[i].at("error_max") == whole[i].at("error_max"));  // deterministic runs
  }
  // A shard that names a missing file is an error naming it.
  const auto bad = pinsim_cli("-q merge --out " + out + " " + out + "/nope.csv");
  CHECK(bad.code != 0);
  CHECK_THAT(bad.output, Catch::Contains("nope.csv"));
  // An edited manifest's counts: "shards": 1e18 once read as -1486618624 shards, 1e300 was
  // cast from a double to int (undefined behaviour), "shard": -1 counted as a shard.
  const fs::path manifest = dir / "out" / "bench.shard-0-of-3.json";
  const std::string good = pinsim::test::read_file(manifest);
  for (const auto& [from, to, message] : std::vector<std::array<std::string, 3>>{
           {"\"shards\": 3", "\"shards\": 1000000000000000000",
            "bench.shard-0-of-3.json: (top level): expected shard i of N with N >= 1 and 0 <= i "
            "< N, got 0 of 1000000000000000000"},
           {"\"shards\": 3", "\"shards\": 1e300",
            "bench.shard-0-of-3.json: shards: expected a non-negative integer, got number 1e+300"},
           {"\"shard\": 0", "\"shard\": -1",
            "bench.shard-0-of-3.json: shard: expected a non-negative integer, got number -1"}}) {
    std::string text = good;
    REQUIRE(text.find(from) != std::string::npos);
    text.replace(text.find(from), from.size(), to);
    pinsim::test::write_file(manifest, text);
    const auto r = pinsim_cli("-q merge --out " + out + " " + out + "/bench.shard-0-of-3.csv " +
                              out + "/bench.shard-1-of-3.csv " + out + "/bench.shard-2-of-3.csv");
    CAPTURE(to);
    CHECK(r.code == 2);
    CHECK_THAT(r.output, Catch::Contains(message));
  }
}

TEST_CASE("bench: a bad --shard value is exit 2 naming the flag and the form expected") {
  const fs::path dir = pinsim::test::temp_dir("bad-shard");
  pinsim::test::write_file(dir / "osc.json", kBench);
  const std::string bench =
      "-q bench " + (dir / "osc.json").string() + " --out " + (dir / "out").string();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"half", "--shard half: expected i/N, e.g. 0/4 (shard i of N, 0 <= i < N)"},
      {"3/3", "--shard 3/3: need N >= 1 and 0 <= i < N"},
      {"0/0", "--shard 0/0: need N >= 1 and 0 <= i < N"}};
  for (const auto& [shard, message] : cases) {
    const auto r = pinsim_cli(bench + " --shard " + shard);
    INFO(r.output);
    CHECK(r.code == 2);
    CHECK_THAT(r.output, Catch::Contains(message));
  }
  CHECK(!fs::exists(dir / "out"));  // nothing ran
}

TEST_CASE("stress: a dt that makes no step is an error row, not a stable point") {
  // Duration 1 s: dt 5 s gives llround(1 / 5) = 0 steps. Such a point was once classed
  // "stable" and shown as the last stable h w (here 5 x 10 = 50, theory: 2).
  const fs::path dir = pinsim::test::temp_dir("stress-no-step");
  pinsim::test::write_file(dir / "stress.json", R"({"integrators": ["symplectic_euler"],
    "cases": [{"name": "spring", "kind": "stiffness",
      "scene": {"time": {"dt": 0.01, "duration": 1.0},
                "particles": [{"x": [0, 0], "pinned": true}, {"x": [1.2, 0], "v": [0, 0.3]}],
                "forces": [{"type": "linear_spring", "params": {"k": 100.0, "rest_length": 1.0},
                            "elements": [[0, 1]]}]},
      "stiffness": {"path": "forces[0].params.k", "values": [100]}, "dt": [0.01, 5.0]}]})");
  const auto r = pinsim_cli("-q stress " + (dir / "stress.json").string() + " --out " +
                            (dir / "out").string());
  INFO(r.output);
  REQUIRE(r.code == 0);
  const auto rows = read_csv(dir / "out" / "stress.csv");
  REQUIRE(rows.size() == 2);
  CHECK(rows[0].at("class") == "stable");
  CHECK(rows[1].at("class") == "error: dt 5 s makes no step in the scene's 1 s");
}

TEST_CASE("stress: spring and bending stability limits bracket theory") {
  // Theory for x'' = -w^2 x, y = h w: symplectic Euler and velocity Verlet stable iff y < 2,
  // RK4 iff y <= 2 sqrt 2, explicit Euler never (|amplification|^2 = 1 + y^2), implicit
  // Euler always (1 / (1 + y^2)). w_max: largest eigenfrequency of M^-1 K at t = 0.
  const fs::path out = pinsim::test::temp_dir("stress-springs");
  const auto r = pinsim_cli("-q stress " + kConfigs + "/stress/springs.json --out " + out.string());
  INFO(r.output);
  REQUIRE(r.code == 0);
  struct Limit {
    double last_stable = -1, first_unstable = HUGE_VAL;
  };
  std::map<std::string, Limit> limits;  // case|integrator|stiffness
  std::map<std::string, std::vector<std::pair<double, std::string>>> runs;
  for (const auto& row : read_csv(out / "stress.csv")) {
    CHECK(row.at("class").rfind("error", 0) != 0);
    runs[row.at("case") + "|" + row.at("integrator") + "|" + row.at("stiffness")].emplace_back(
        std::stod(row.at("h_omega")), row.at("class"));
  }
  REQUIRE(runs.size() == 5 * (3 + 3));  // 5 integrators x (3 spring + 3 bending stiffnesses)
  for (auto& [key, v] : runs) {
    std::sort(v.begin(), v.end());
    Limit l;
    for (const auto& [y, cls] : v) {
      if (cls == "stable" && l.first_unstable == HUGE_VAL) l.last_stable = y;
      if (cls != "stable") l.first_unstable = std::min(l.first_unstable, y);
    }
    const std::string integ = key.substr(key.find('|') + 1, key.rfind('|') - key.find('|') - 1);
    INFO(key << ": last stable h w = " << l.last_stable << ", first unstable " << l.first_unstable);
    if (integ == "explicit_euler") {
      CHECK(l.last_stable < 0);  // unstable at every dt of the grid
    } else if (integ == "implicit_euler") {
      CHECK(l.first_unstable == HUGE_VAL);
    } else {
      const double theory = integ == "rk4" ? 2 * std::sqrt(2.0) : 2.0;
      // Every grid has a point on each side; at exactly the limit the growth is marginal.
      CHECK(l.last_stable > 0);
      CHECK(l.first_unstable < HUGE_VAL);
      CHECK(l.last_stable <= theory * (1 + 1e-4));
      CHECK(l.first_unstable >= theory * (1 - 1e-4));
    }
  }
  // The stability table lists the stiffnesses of a case and integrator in numeric order
  // (100, 400, 1600; as text 1600 would come first).
  {
    std::vector<std::string> order;
    std::istringstream lines(r.output);
    for (std::string l; std::getline(lines, l);) {
      std::istringstream f(l);
      std::string c, b, integ, k;
      if (f >> c >> b >> integ >> k && c == "spring" && integ == "symplectic_euler")
        order.push_back(k);
    }
    CHECK(order == std::vector<std::string>{"100", "400", "1600"});
  }
  // One heat map per case and integrator: class over (dt, stiffness).
  for (const char* map : {"heat_spring_symplectic_euler.svg", "heat_bending_rk4.svg"}) {
    INFO(map);
    REQUIRE(fs::exists(out / map));
    CHECK_THAT(pinsim::test::read_file(out / map), Catch::Contains("<svg"));
  }
}

TEST_CASE("stress: the sdf backend never tunnels, and Box2D reports its speed cap") {
  const fs::path out = pinsim::test::temp_dir("stress-tunnel");
  const auto r =
      pinsim_cli("-q stress " + kConfigs + "/stress/tunnelling.json --out " + out.string());
  INFO(r.output);
  REQUIRE(r.code == 0);
  int sdf = 0, box2d_errors = 0;
  for (const auto& row : read_csv(out / "stress.csv")) {
    INFO(row.at("backend") << " speed " << row.at("speed") << " thickness " << row.at("thickness")
                           << ": " << row.at("class"));
    if (row.at("backend") == "sdf") {
      ++sdf;
      CHECK(row.at("class") == "stable");  // 1 to 10^4 units/s against walls 1e-3 to 0.1
      CHECK(std::stod(row.at("max_penetration")) == 0.0);
    } else {
      // Box2D: never a silent tunnel; too fast for its translation cap is an error saying so.
      CHECK(row.at("class") != "tunnelled");
      if (row.at("class") != "stable") {
        ++box2d_errors;
        CHECK_THAT(row.at("class"), Catch::Contains("b2_maxTranslation"));
      }
    }
  }
  CHECK(sdf == 15);
  CHECK(box2d_errors > 0);
}

TEST_CASE("bench and stress configs: an unknown key is an error naming the file and path") {
  // A misspelt key would otherwise be ignored and the sweep run half-configured.
  const fs::path dir = pinsim::test::temp_dir("sweep-keys");
  std::string bench = kBench;
  bench.replace(bench.find("\"answer\""), 8, "\"answr\"");
  pinsim::test::write_file(dir / "bench.json", bench);
  auto r =
      pinsim_cli("-q bench " + (dir / "bench.json").string() + " --out " + (dir / "out").string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Catch::Contains("bench.json") && Catch::Contains("cases[0]") &&
                           Catch::Contains("answr"));
  pinsim::test::write_file(dir / "stress.json", R"({"cases": [{"name": "t", "kind": "tunnelling",
    "speeds": [1], "thickness": [0.01], "dt": [0.01], "displacement_limt": 0.2}]})");
  r = pinsim_cli("-q stress " + (dir / "stress.json").string() + " --out " +
                 (dir / "out2").string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Catch::Contains("stress.json") && Catch::Contains("cases[0]") &&
                           Catch::Contains("displacement_limt"));
  // inside an answer: "damping" for damping_ratio would silently compare with no damping
  bench = kBench;
  bench.replace(bench.find("\"omega\""), 7, "\"damping\": 0.1, \"omega\"");
  pinsim::test::write_file(dir / "bench2.json", bench);
  r = pinsim_cli("-q bench " + (dir / "bench2.json").string() + " --out " +
                 (dir / "out3").string());
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Catch::Contains("cases[0].answer.damping"));
}

TEST_CASE("bench and stress configs: a value of the wrong type is exit 2 with file, path, type") {
  // Each of these once came back as nlohmann's own "type_error.302", naming nothing.
  const fs::path dir = pinsim::test::temp_dir("sweep-types");
  const auto bench_with = [&](const std::string& from, const std::string& to) {
    std::string b = kBench;
    b.replace(b.find(from), from.size(), to);
    return b;
  };
  struct Bad {
    std::string tool, text, message;
  };
  const std::vector<Bad> bad = {
      {"bench", bench_with("\"name\": \"oscillator\"", "\"name\": 5"),
       "bench.json: cases[0].name: expected a string, got number 5"},
      {"bench", bench_with("\"repeats\": 1", "\"repeats\": \"1\""),
       "bench.json: repeats: expected a non-negative integer, got string \"1\""},
      {"bench", bench_with("\"type\": \"harmonic\"", "\"type\": [1]"),
       "bench.json: cases[0].answer.type: expected a string, got array [1]"},
      {"bench",
       bench_with("\"answer\": {\"type\": \"harmonic\", \"particle\": 1, \"omega\": 3.0}",
                  "\"answer\": 3"),
       "bench.json: cases[0].answer: expected an object, got number 3"},
      {"bench",
       bench_with("\"answer\": {\"type\": \"harmonic\", \"particle\": 1, \"omega\": 3.0}",
                  "\"reference\": {\"dt\": \"small\"}"),
       "bench.json: cases[0].reference.dt: expected a number, got string \"small\""},
      {"stress", R"({"cases": [{"name": "t", "kind": "tunnelling", "speeds": [1],
         "thickness": [0.01], "dt": [0.01], "displacement_limit": "far"}]})",
       "stress.json: cases[0].displacement_limit: expected a number, got string \"far\""},
      {"stress", R"({"energy_blowup": true, "cases": [{"kind": "tunnelling", "speeds": [1],
         "thickness": [0.01], "dt": [0.01]}]})",
       "stress.json: energy_blowup: expected a number, got boolean true"},
      {"stress", R"({"cases": [{"kind": 7, "speeds": [1], "thickness": [0.01], "dt": [0.01]}]})",
       "stress.json: cases[0].kind: expected a string, got number 7"},
      // Numbers out of the schema's range: energy_blowup -1 (or 0) once made every point an
      // "error: checks.energy_blowup: must be > 0" row and the sweep exit 0.
      {"stress", R"({"energy_blowup": -1, "cases": [{"kind": "tunnelling", "speeds": [1],
         "thickness": [0.01], "dt": [0.01]}]})",
       "stress.json: energy_blowup: must be a number > 0, got -1"},
      {"stress", R"({"cases": [{"kind": "tunnelling", "speeds": [1], "energy_blowup": 0,
         "thickness": [0.01], "dt": [0.01]}]})",
       "stress.json: cases[0].energy_blowup: must be a number > 0, got 0"},
      {"stress", R"({"cases": [{"kind": "tunnelling", "speeds": [1],
         "penetration_tolerance": -0.5, "thickness": [0.01], "dt": [0.01]}]})",
       "stress.json: cases[0].penetration_tolerance: must be a number >= 0, got -0.5"},
      {"stress", R"({"cases": [{"kind": "tunnelling", "speeds": [1],
         "displacement_limit": -1, "thickness": [0.01], "dt": [0.01]}]})",
       "stress.json: cases[0].displacement_limit: must be a number >= 0 (0: off), got -1"},
  };
  for (const Bad& b : bad) {
    CAPTURE(b.text);
    pinsim::test::write_file(dir / (b.tool + ".json"), b.text);
    // The config is checked whole before the first point runs.
    const auto r = pinsim_cli("-q " + b.tool + " " + (dir / (b.tool + ".json")).string() +
                              " --out " + (dir / "out").string());
    CHECK(r.code == 2);
    CHECK_THAT(r.output, Catch::Contains(b.message));
    CHECK_THAT(r.output, !Catch::Contains("type_error"));
  }
  // A dt longer than the scene's 2 s makes no step (llround(2 / 5) = 0): once a point with
  // error 0 and time 0, reported "ok" as the sweep's best error.
  pinsim::test::write_file(dir / "bench.json",
                           bench_with("\"dt\": [0.01, 0.005", "\"dt\": [5.0, 0.005"));
  {
    const auto r = pinsim_cli("-q bench " + (dir / "bench.json").string() + " --out " +
                              (dir / "out3").string());
    CHECK(r.code == 2);
    CHECK_THAT(r.output, Catch::Contains("bench.json: cases[0].dt: 5 s makes no step in the "
                                         "scene's 2 s (a dt must be at most the duration)"));
  }
  // The answer's own numbers are read when the point runs: still located.
  pinsim::test::write_file(dir / "bench.json", bench_with("\"omega\": 3.0", "\"omega\": \"3\""));
  const auto r =
      pinsim_cli("-q bench " + (dir / "bench.json").string() + " --out " + (dir / "out2").string());
  CHECK(r.code != 0);
  CHECK_THAT(r.output, Catch::Contains("bench.json: cases[0].answer.omega: expected a number"));
}
