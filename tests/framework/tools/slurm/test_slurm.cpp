// The Slurm path as a TA or researcher runs it. Without a cluster: `pinsim merge` refuses
// incomplete or inconsistent shard sets, and bad --slurm input is exit 2 naming the option.
// With a real one-node Slurm cluster (slurmctld, slurmd, munged from Debian's slurm-wlm and
// munge, started by scripts/slurm/cluster.sh and stopped at the end, also on failure): a
// 3-shard bench sweep and a 2-shard batch grade through `--slurm` give the unsharded runs'
// results, a cancelled shard is reported by index and `--resume` resubmits only that one.
#include <algorithm>
#include <catch2/catch.hpp>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../oscillator_bench.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using Catch::Contains;
using pinsim::test::pinsim_cli;
using pinsim::test::read_file;
using pinsim::test::shell;

namespace {

const std::string kCluster = PINSIM_REPO_DIR "/scripts/slurm/cluster.sh";

/// CSV rows as cells, header first.
std::vector<std::vector<std::string>> csv(const fs::path& file) {
  std::ifstream in(file);
  REQUIRE(in.good());
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) cells.push_back(c);
    rows.push_back(cells);
  }
  return rows;
}

/// Two bench tables are the same sweep result: same header, same rows cell by cell, except
/// the wall-clock columns (time_median_s, time_min_s), which are measurements.
void same_bench(const fs::path& a, const fs::path& b) {
  const auto ra = csv(a), rb = csv(b);
  REQUIRE(ra.size() == rb.size());
  REQUIRE(!ra.empty());
  const auto& h = ra[0];
  REQUIRE(h == rb[0]);
  for (std::size_t i = 1; i < ra.size(); ++i) {
    REQUIRE(ra[i].size() == h.size());
    REQUIRE(rb[i].size() == h.size());
    for (std::size_t c = 0; c < h.size(); ++c) {
      if (h[c] == "time_median_s" || h[c] == "time_min_s") continue;
      INFO(a.string() << " row " << i << " column " << h[c]);
      CHECK(ra[i][c] == rb[i][c]);
    }
  }
}

/// The one-node cluster of scripts/slurm/cluster.sh; stopped when the test ends, also when a
/// REQUIRE fails (stack unwinding).
struct Cluster {
  fs::path dir;
  pinsim::test::CommandResult started;
  explicit Cluster(fs::path d) : dir(std::move(d)) {
    started = shell("bash " + kCluster + " start " + dir.string());
  }
  ~Cluster() {
    const auto r = shell("bash " + kCluster + " stop " + dir.string());
    std::cout << r.output;
  }
  Cluster(const Cluster&) = delete;
  Cluster& operator=(const Cluster&) = delete;
};

/// Waits up to `seconds` (4x that under ASan, whose shards run several times slower) for a
/// file to exist.
bool wait_for(const fs::path& file, double seconds) {
  if (pinsim::test::kAddressSanitizer) seconds *= 4;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!fs::exists(file)) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return true;
}

/// The line of a command's output that holds `key` ("" if none).
std::string line_with(const std::string& text, const std::string& key) {
  std::stringstream ss(text);
  std::string line;
  while (std::getline(ss, line))
    if (line.find(key) != std::string::npos) return line;
  return "";
}

}  // namespace

TEST_CASE("merge refuses a shard set that is incomplete or mixes sweeps") {
  const fs::path dir = pinsim::test::temp_dir("merge-refuses");
  pinsim::test::write_file(dir / "osc.json", kBench);
  std::string other = kBench;
  other.replace(other.find("\"repeats\": 1"), 12, "\"repeats\": 2");  // another sweep
  pinsim::test::write_file(dir / "other.json", other);
  const std::string out = (dir / "out").string(), alt = (dir / "alt").string();
  for (int i = 0; i < 3; ++i)
    REQUIRE(pinsim_cli("-q bench " + (dir / "osc.json").string() + " --out " + out + " --shard " +
                       std::to_string(i) + "/3")
                .code == 0);
  REQUIRE(pinsim_cli("-q bench " + (dir / "other.json").string() + " --out " + alt + " --shard 2/3")
              .code == 0);
  // Each shard CSV has its manifest beside it.
  const auto m = nlohmann::json::parse(read_file(dir / "out" / "bench.shard-1-of-3.json"));
  CHECK(m["tool"] == "bench");
  CHECK(m["shard"] == 1);
  CHECK(m["shards"] == 3);
  CHECK(m["points"] == 8);
  CHECK(m["rows"] == 3);  // points 1, 4, 7
  const std::string s0 = out + "/bench.shard-0-of-3.csv", s1 = out + "/bench.shard-1-of-3.csv",
                    s2 = out + "/bench.shard-2-of-3.csv";

  auto r = pinsim_cli("-q merge --out " + out + " " + s0 + " " + s1);
  INFO(r.output);
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("shard 2 of 3 missing"));

  r = pinsim_cli("-q merge --out " + out + " " + s0 + " " + s1 + " " + alt +
                 "/bench.shard-2-of-3.csv");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("from a different sweep"));

  r = pinsim_cli("-q merge --out " + out + " " + s0 + " " + s1 + " " + s1);
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("shard 1 is given twice"));

  // A shard rewritten after its manifest (or cut short) is not trusted.
  fs::copy_file(s2, dir / "s2.bak");
  std::ofstream(s2, std::ios::app)
      << "99,oscillator,harmonic,none,rk4,0.1,1,1,0,0,0,0,0,0,0,0,ok\n";
  r = pinsim_cli("-q merge --out " + out + " " + s0 + " " + s1 + " " + s2);
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("its bytes differ from its manifest"));
  fs::copy_file(dir / "s2.bak", s2, fs::copy_options::overwrite_existing);

  // A CSV without a manifest (an unsharded run's) is no shard.
  REQUIRE(pinsim_cli("-q bench " + (dir / "osc.json").string() + " --out " + alt).code == 0);
  r = pinsim_cli("-q merge --out " + out + " " + alt + "/bench.csv");
  CHECK(r.code == 2);
  CHECK_THAT(r.output, Contains("no shard manifest"));

  // The complete set merges.
  r = pinsim_cli("-q merge --out " + out + " " + s2 + " " + s0 + " " + s1);
  CHECK(r.code == 0);
  same_bench(dir / "out" / "bench.csv", dir / "alt" / "bench.csv");
}

TEST_CASE("slurm options: bad input is exit 2 naming the option, before anything is submitted") {
  const fs::path dir = pinsim::test::temp_dir("slurm-input");
  pinsim::test::write_file(dir / "osc.json", kBench);
  const std::string bench =
      "bench " + (dir / "osc.json").string() + " --out " + (dir / "out").string();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {bench + " --slurm --time 90min", "--time 90min: expected Slurm's form"},
      {bench + " --slurm --mem 2X", "--mem 2X: expected a size"},
      {bench + " --slurm --partition 'a b'", "--partition a b: expected a partition name"},
      {bench + " --slurm --shards -1", "--shards -1: expected 1 to 100000"},
      {bench + " --slurm --cpus 0", "--cpus 0: expected 1 to 4096"},
      {bench + " --slurm --sbatch-arg account", "--sbatch-arg account: expected one sbatch"},
      {bench + " --shards 3", "--shards needs --slurm"},
      {bench + " --resume", "--resume needs --slurm"},
      {bench + " --slurm --shard 0/2", "drop --shard"},
      {"grade --slurm --rubric r.json --submission s", "--slurm grades with --batch only"},
      {"bench " + (dir / "missing.json").string() + " --slurm", "missing.json"}};
  for (const auto& [args, message] : cases) {
    const auto r = pinsim_cli(args);
    INFO(args << "\n" << r.output);
    CHECK(r.code == 2);
    CHECK_THAT(r.output, Contains(message));
  }
  CHECK(!fs::exists(dir / "out" / "slurm" / "job.json"));  // nothing was submitted
}

TEST_CASE("slurm: 3-shard bench and 2-shard batch grade on a one-node cluster equal unsharded") {
  const auto t_test = std::chrono::steady_clock::now();
  const fs::path dir = pinsim::test::temp_dir("slurm");
  pinsim::test::write_file(dir / "osc.json", kBench);
  const std::string cfg = (dir / "osc.json").string();

  // Every submission has a time limit (--time 2, minutes), so a hanging shard ends as
  // TIMEOUT and the test fails instead of hanging until ctest kills it with the cluster up.
  // The cluster: if it cannot start (no munge or Slurm, ports taken, not root), this fails
  // here with the daemons' logs.
  Cluster cluster(dir / "cluster");
  INFO(cluster.started.output);
  REQUIRE(cluster.started.code == 0);
  const fs::path cdir = fs::weakly_canonical(cluster.dir);
  ::setenv("SLURM_CONF", (cdir / "slurm" / "slurm.conf").c_str(), 1);
  // Shard processes carry the cluster's marker, so that `stop` ends them even if Slurm did
  // not (the test process itself must not carry it).
  const std::string env = "PINSIM_SLURM_CLUSTER=" + cdir.string() + " ";
  const std::string pinsim = env + PINSIM_BIN;
  std::cout << "slurm test: cluster up after "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - t_test).count()
            << " s\n";

  {  // bench: 3 shards, merged = unsharded; a cancelled shard, then --resume
    REQUIRE(pinsim_cli("-q bench " + cfg + " --out " + (dir / "whole").string()).code == 0);

    const auto r = shell(pinsim + " bench " + cfg + " --out " + (dir / "sl").string() +
                         " --slurm --shards 3 --time 2");
    INFO(r.output);
    REQUIRE(r.code == 0);
    CHECK_THAT(r.output, Contains("3/3 done, 0 running, 0 pending, 0 failed"));
    same_bench(dir / "sl" / "bench.csv", dir / "whole" / "bench.csv");
    CHECK(fs::exists(dir / "sl" / "work_precision_oscillator.gp"));  // reported as unsharded
    const std::string script = read_file(dir / "sl" / "slurm" / "job.sh");
    CHECK_THAT(script, Contains("#SBATCH --time=2"));
    CHECK_THAT(script, Contains("--shard \"$i/$n\""));
    for (int i = 0; i < 3; ++i) {
      CHECK(fs::exists(dir / "sl" / ("bench.shard-" + std::to_string(i) + "-of-3.json")));
      CHECK_THAT(read_file(dir / "sl" / "slurm" / ("shard-" + std::to_string(i) + ".log")),
                 Contains("exit code 0"));
    }
    // The measured overhead (not asserted: the figure is for the log).
    const std::string overhead = line_with(r.output, "Slurm overhead");
    CHECK(!overhead.empty());
    std::cout << "slurm test, bench 3 shards: " << overhead << "\n";

    // Two shards fail, each in a way that does not race with the shard's own run time: the
    // array is submitted held, shard 0 is cancelled while pending (it never starts), and
    // shard 1 finds a folder where its result file goes, so its command fails after starting.
    // The run reports both by index, with Slurm's verdict or the exit code and the log.
    const fs::path fr = dir / "fr";
    // Fewer timing repeats under ASan (each several times slower): the sharded and unsharded
    // runs below use the same number, and only their agreement is checked.
    const std::string repeats = pinsim::test::kAddressSanitizer ? "600" : "6000";
    const std::string cpus = std::to_string(std::max(1u, std::thread::hardware_concurrency()));
    const std::string cmd = pinsim + " bench " + cfg + " --out " + fr.string() +
                            " --slurm --shards 3 --cpus " + cpus + " --repeats " + repeats +
                            " --time 2";
    shell("(" + cmd + " --sbatch-arg=--hold > " + (dir / "fr.log").string() + " 2>&1; echo $? > " +
          (dir / "fr.code").string() + ") > /dev/null 2>&1 &");
    REQUIRE(wait_for(fr / "slurm" / "job.json", 30));
    const auto job = nlohmann::json::parse(read_file(fr / "slurm" / "job.json"));
    const std::string id = job["jobs"][0];
    const auto cancel = shell("scancel " + id + "_0");
    INFO(cancel.output);
    REQUIRE(cancel.code == 0);
    fs::create_directories(fr / "bench.shard-1-of-3.csv");
    const auto release = shell("scontrol release " + id);
    INFO(release.output);
    REQUIRE(release.code == 0);
    REQUIRE(wait_for(dir / "fr.code", 60));
    const std::string failed = read_file(dir / "fr.log");
    INFO(failed);
    CHECK(std::stoi(read_file(dir / "fr.code")) == 1);
    // Slurm may already have forgotten a task cancelled while pending; either way it failed.
    CHECK_THAT(failed, Contains("shard 0 of 3 (job " + id + "_0) failed: "));
    CHECK_THAT(failed, Contains("(none: it never started)"));
    CHECK_THAT(failed, Contains("shard 1 of 3 (job " + id + "_1) failed: exit code"));
    CHECK_THAT(failed, Contains("== pinsim shard 1 of 3: job " + id + "_1"));  // its log
    CHECK_THAT(failed, Contains("bench.shard-1-of-3.csv"));  // the log's error names the file
    CHECK_THAT(failed, Contains("2 of 3 shards failed (shards 0-1)"));
    CHECK_THAT(failed, Contains("--resume"));
    CHECK(!fs::exists(fr / "bench.shard-0-of-3.csv"));  // no result from the cancelled shard
    CHECK(fs::exists(fr / "bench.shard-2-of-3.csv"));
    CHECK(!fs::exists(fr / "bench.csv"));
    fs::remove(fr / "bench.shard-1-of-3.csv");
    const fs::path kept = dir / "kept";  // shard 2's complete result, for the last case below
    fs::create_directories(kept);
    for (const char* f : {"bench.shard-2-of-3.csv", "bench.shard-2-of-3.json"})
      fs::copy_file(fr / f, kept / f);

    // --resume resubmits shards 0 and 1 only, then merges; the result is the unsharded run's.
    const auto res = shell(cmd + " --resume");
    INFO(res.output);
    REQUIRE(res.code == 0);
    CHECK_THAT(res.output, Contains("resubmitting shards 0-1 of 3"));
    const auto job2 = nlohmann::json::parse(read_file(fr / "slurm" / "job.json"));
    CHECK(job2["jobs"][0] != id);
    CHECK(job2["jobs"][1] == job2["jobs"][0]);
    CHECK(job2["jobs"][2] == id);
    REQUIRE(pinsim_cli("-q bench " + cfg + " --repeats " + repeats + " --out " +
                       (dir / "whole2").string())
                .code == 0);
    same_bench(fr / "bench.csv", dir / "whole2" / "bench.csv");

    // Nothing left to do: --resume submits nothing and merges again.
    const auto again = shell(cmd + " --resume");
    INFO(again.output);
    CHECK(again.code == 0);
    CHECK_THAT(again.output, Contains("no shard to resubmit"));

    // A shard that Slurm ends as CANCELLED (or TIMEOUT) after its command wrote the whole
    // result, before the job script's status line: the result is checked against its
    // manifest's hash and used. Made deterministic by a held fresh submission: shard 2's
    // complete result (kept from above) is put back before all three are cancelled.
    shell("(" + cmd + " --sbatch-arg=--hold > " + (dir / "late.log").string() +
          " 2>&1; echo $? > " + (dir / "late.code").string() + ") > /dev/null 2>&1 &");
    REQUIRE(wait_for(fr / "slurm" / "job.json", 30));
    std::string late_id;
    for (int tries = 0; tries < 600 && (late_id.empty() || late_id == job2["jobs"][0]); ++tries) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      const auto j = nlohmann::json::parse(read_file(fr / "slurm" / "job.json"), nullptr, false);
      if (j.is_object() && j.contains("jobs")) late_id = j["jobs"][0].get<std::string>();
    }
    REQUIRE(late_id != job2["jobs"][0]);
    for (const char* f : {"bench.shard-2-of-3.csv", "bench.shard-2-of-3.json"})
      fs::copy_file(kept / f, fr / f, fs::copy_options::overwrite_existing);
    REQUIRE(shell("scancel " + late_id).code == 0);
    REQUIRE(wait_for(dir / "late.code", 60));
    const std::string late = read_file(dir / "late.log");
    INFO(late);
    CHECK(std::stoi(read_file(dir / "late.code")) == 1);
    CHECK_THAT(late, Contains("shard 2 of 3 (job " + late_id + "_2) ended CANCELLED"));
    CHECK_THAT(late, Contains("after writing its complete result; using it"));
    CHECK_THAT(late, Contains("2 of 3 shards failed (shards 0-1)"));
  }

  {  // grade --batch: 2 shards, merged = unsharded, scores per test identical
    const fs::path subs = dir / "class";
    fs::create_directories(subs);
    for (const char* n : {"sign_error", "wrong_jacobian", "segfault"})
      fs::copy(fs::path(PINSIM_GRADING_SUBMISSIONS) / n, subs / n, fs::copy_options::recursive);
    const std::string rubric = PINSIM_TEST_SOURCE_DIR "/framework/grading/rubric_springs.json";
    const std::string common =
        " grade --batch --rubric " + rubric + " --submission " + subs.string() + " --out ";
    const auto whole =
        shell(std::string(PINSIM_BIN) + " -q" + common + (dir / "gwhole").string() + " --jobs 2");
    INFO(whole.output);
    REQUIRE(whole.code == 0);
    const auto r = shell(pinsim + common + (dir / "gsl").string() + " --slurm --shards 2 --time 2");
    INFO(r.output);
    REQUIRE(r.code == 0);
    CHECK_THAT(r.output, Contains("2/2 done"));
    const std::string merged = read_file(dir / "gsl" / "batch-0-of-1.csv");
    CHECK(merged == read_file(dir / "gwhole" / "batch-0-of-1.csv"));
    CHECK(merged ==
          "submission,score,max_score\nsegfault,1.0,10.0\nsign_error,3.0,10.0\n"
          "wrong_jacobian,9.0,10.0\n");
    for (const char* n : {"sign_error", "wrong_jacobian", "segfault"}) {
      const auto a = nlohmann::json::parse(read_file(dir / "gsl" / n / "results.json"));
      const auto b = nlohmann::json::parse(read_file(dir / "gwhole" / n / "results.json"));
      CHECK(a["score"] == b["score"]);
      REQUIRE(a["tests"].size() == b["tests"].size());
      for (std::size_t t = 0; t < a["tests"].size(); ++t) {
        INFO(n << " test " << t);
        CHECK(a["tests"][t]["name"] == b["tests"][t]["name"]);
        CHECK(a["tests"][t]["score"] == b["tests"][t]["score"]);
      }
    }
    std::cout << "slurm test, grade 2 shards: " << line_with(r.output, "Slurm overhead") << "\n";
  }
  std::cout << "slurm test: done after "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - t_test).count()
            << " s\n";
}
