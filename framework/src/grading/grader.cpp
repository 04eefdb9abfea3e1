#include "grading/grader.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <fstream>
#include <set>
#include <sstream>

#include "core/json_read.hpp"

namespace fs = std::filesystem;

namespace pinsim {
namespace {

const std::set<std::string> kForceChecks = {"load",
                                            "gradient",
                                            "dfdx",
                                            "dfdv",
                                            "momentum",
                                            "angular_momentum",
                                            "rigid_invariance",
                                            "degenerate",
                                            "dissipation",
                                            "reference",
                                            "simulation"};
const std::set<std::string> kBackendChecks = {"load", "backend_agreement", "backend_no_tunnelling",
                                              "backend_approaching_only"};

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string tail(const std::string& s, std::size_t n) {
  return s.size() <= n ? s : "..." + s.substr(s.size() - n);
}

ChildLimits read_limits(const nlohmann::json& j, const Loc& at, ChildLimits l) {
  require_object(j, at);
  check_keys(j, {"cpu_seconds", "memory_mb", "wall_seconds"}, at);
  l.cpu_seconds = read_number_or(j, "cpu_seconds", l.cpu_seconds, at);
  l.memory_mb = read_number_or(j, "memory_mb", l.memory_mb, at);
  l.wall_seconds = read_number_or(j, "wall_seconds", l.wall_seconds, at);
  if (!(l.cpu_seconds > 0 && l.memory_mb > 0 && l.wall_seconds > 0))
    throw at.error("limits must be > 0");
  return l;
}

/// Prepares the submission's libraries in `dir`: builds a source folder, or copies libraries.
/// Returns "" on success, else what went wrong.
std::string prepare_libraries(const GradeOptions& opt, const Rubric& rubric, const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  const fs::path& sub = opt.submission;
  if (!fs::exists(sub, ec)) return "the submission " + sub.string() + " does not exist";
  if (fs::is_regular_file(sub, ec)) {
    fs::copy_file(sub, dir / sub.filename(), fs::copy_options::overwrite_existing, ec);
    return ec ? "cannot copy " + sub.string() + ": " + ec.message() : "";
  }
  if (fs::exists(sub / "CMakeLists.txt", ec)) {
    const fs::path build = dir / "build";
    const std::string cmake = "/usr/bin/cmake";
    auto conf =
        run_limited({cmake, "-S", sub.string(), "-B", build.string(), "-DCMAKE_BUILD_TYPE=Release",
                     "-DCMAKE_PREFIX_PATH=" + opt.sdk_prefix.string(),
                     "-DCMAKE_LIBRARY_OUTPUT_DIRECTORY=" + dir.string()},
                    rubric.build_limits);
    if (!conf.exited || conf.exit_code != 0)
      return "the submission does not configure with CMake: " +
             (conf.failure(rubric.build_limits).empty()
                  ? ""
                  : conf.failure(rubric.build_limits) + "\n") +
             tail(conf.output + conf.stderr_text, 3000);
    auto b = run_limited({cmake, "--build", build.string(), "-j", "2"}, rubric.build_limits);
    if (!b.exited || b.exit_code != 0)
      return "the submission does not compile:\n" + tail(b.output + b.stderr_text, 3000);
    // Collect every built plugin library.
    for (const auto& e : fs::recursive_directory_iterator(build, ec))
      if (e.path().extension() == ".so" && e.path().parent_path() != dir)
        fs::copy_file(e.path(), dir / e.path().filename(), fs::copy_options::overwrite_existing,
                      ec);
  } else {
    for (const auto& e : fs::directory_iterator(sub, ec))
      if (e.path().extension() == ".so")
        fs::copy_file(e.path(), dir / e.path().filename(), fs::copy_options::overwrite_existing,
                      ec);
  }
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().extension() == ".so") return "";
  return "the submission holds no plugin library (.so) and no CMakeLists.txt to build one";
}

std::string xml_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '<':
        o += "&lt;";
        break;
      case '>':
        o += "&gt;";
        break;
      case '&':
        o += "&amp;";
        break;
      case '"':
        o += "&quot;";
        break;
      default:
        o += c;
    }
  }
  return o;
}

}  // namespace

Rubric load_rubric(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) throw SceneError(file.string() + ": rubric file not found");
  const nlohmann::json j = parse_json_text(read_text(file), file.string());
  const Loc root{file.string(), ""};
  require_object(j, root);
  check_keys(j, {"$schema", "name", "kind", "limits", "build_limits", "tests"}, root);
  Rubric r;
  r.file = fs::absolute(file);
  r.name = read_string_or(j, "name", file.stem().string(), root);
  r.kind = read_string_or(j, "kind", "force", root);
  if (r.kind != "force" && r.kind != "backend")
    throw(root / "kind").error("expected \"force\" or \"backend\", got \"" + r.kind + "\"");
  if (j.contains("limits")) r.limits = read_limits(j["limits"], root / "limits", r.limits);
  if (j.contains("build_limits"))
    r.build_limits = read_limits(j["build_limits"], root / "build_limits", r.build_limits);
  if (!j.contains("tests") || !j["tests"].is_array() || j["tests"].empty())
    throw(root / "tests").error("expected a non-empty array of tests");
  const auto& checks = r.kind == "force" ? kForceChecks : kBackendChecks;
  for (std::size_t i = 0; i < j["tests"].size(); ++i) {
    const auto& t = j["tests"][i];
    const Loc at = (root / "tests")[i];
    require_object(t, at);
    check_keys(t,
               {"name", "check", "plugin", "points", "visibility", "hint", "params", "reference",
                "scene", "tolerance", "trials", "seed", "assume_internal", "second_opinion",
                "second_opinion_params"},
               at);
    RubricTest rt;
    rt.spec = t;
    rt.name = read_string_or(t, "name", "", at);
    if (rt.name.empty()) throw(at / "name").error("required test name is missing");
    rt.check = read_string_or(t, "check", "", at);
    if (!checks.count(rt.check)) {
      std::string list;
      for (const auto& c : checks) list += (list.empty() ? "" : ", ") + c;
      throw(at / "check")
          .error("unknown check '" + rt.check + "' for a " + r.kind + " rubric (known: " + list +
                 ")");
    }
    rt.plugin = read_string_or(t, "plugin", "", at);
    if (rt.plugin.empty()) throw(at / "plugin").error("required: the submission's plugin name");
    rt.points = read_number_or(t, "points", 1.0, at);
    if (!(rt.points >= 0)) throw(at / "points").error("must be >= 0");
    rt.visibility = read_string_or(t, "visibility", "visible", at);
    if (rt.visibility != "visible" && rt.visibility != "hidden" &&
        rt.visibility != "after_due_date" && rt.visibility != "after_published")
      throw(at / "visibility").error("expected visible, hidden, after_due_date or after_published");
    rt.hint = read_string_or(t, "hint", "", at);
    if ((rt.check == "reference" || rt.check.rfind("backend_", 0) == 0) && !t.contains("reference"))
      throw(at / "reference").error("required: the reference plugin to compare with");
    if ((rt.check == "simulation" || rt.check.rfind("backend_", 0) == 0) && !t.contains("scene"))
      throw(at / "scene").error("required: the scene file (relative to the rubric)");
    r.tests.push_back(std::move(rt));
  }
  return r;
}

nlohmann::json grade_submission(const Rubric& rubric, const GradeOptions& opt) {
  const auto start = std::chrono::steady_clock::now();
  std::error_code ec;
  fs::create_directories(opt.out, ec);
  const fs::path libs = opt.out / "libraries";
  fs::remove_all(libs, ec);
  const std::string prep = prepare_libraries(opt, rubric, libs);

  nlohmann::json tests = nlohmann::json::array();
  double score = 0.0, max_score = 0.0;
  int passed = 0;
  for (std::size_t i = 0; i < rubric.tests.size(); ++i) {
    const RubricTest& t = rubric.tests[i];
    TestOutcome o;
    if (!prep.empty()) {
      o.output = prep;
    } else {
      const auto r = run_limited(
          {opt.pinsim_exe.string(), "-q", "grade-worker", "--rubric", rubric.file.string(),
           "--test", std::to_string(i), "--libraries", libs.string()},
          rubric.limits);
      o.seconds = r.wall_seconds;
      const std::string why = r.failure(rubric.limits);
      if (!why.empty()) {
        o.output = "The submission " + why + " during this test." +
                   (r.stderr_text.empty() ? "" : "\n" + tail(r.stderr_text, 1500));
      } else {
        const auto res = nlohmann::json::parse(r.output, nullptr, false);
        if (res.is_discarded() || !res.is_object() || !res.contains("passed")) {
          o.output = "The grader could not read this test's result (exit code " +
                     std::to_string(r.exit_code) + "): " + tail(r.output + r.stderr_text, 1500);
        } else {
          o.passed = res["passed"].get<bool>();
          o.output = res.value("output", std::string());
        }
      }
    }
    if (!o.passed && !t.hint.empty()) o.output += "\nHint: " + t.hint;
    o.score = o.passed ? t.points : 0.0;
    score += o.score;
    max_score += t.points;
    passed += o.passed;
    tests.push_back({{"name", t.name},
                     {"number", std::to_string(i + 1)},
                     {"score", o.score},
                     {"max_score", t.points},
                     {"status", o.passed ? "passed" : "failed"},
                     {"output", o.output},
                     {"visibility", t.visibility},
                     {"execution_time", o.seconds}});
    spdlog::debug("{} {}: {}", o.passed ? "pass" : "FAIL", t.name, o.output);
  }
  const double secs =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::ostringstream summary;
  summary << rubric.name << ": " << score << " / " << max_score << " points, " << passed << " of "
          << rubric.tests.size() << " tests passed\n";
  for (const auto& t : tests) {
    summary << "  [" << (t["status"] == "passed" ? "pass" : "FAIL") << "] "
            << t["number"].get<std::string>() << ". " << t["name"].get<std::string>() << " ("
            << t["score"].get<double>() << "/" << t["max_score"].get<double>() << ")\n";
    if (t["status"] != "passed") {
      std::istringstream lines(t["output"].get<std::string>());
      for (std::string l; std::getline(lines, l);) summary << "        " << l << "\n";
    }
  }
  nlohmann::json results = {{"score", score},          {"max_score", max_score},
                            {"execution_time", secs},  {"output", summary.str()},
                            {"visibility", "visible"}, {"tests", tests}};
  std::ofstream(opt.out / "results.json") << results.dump(2) << "\n";
  std::ofstream(opt.out / "junit.xml") << junit_xml(results, rubric.name);
  std::ofstream(opt.out / "summary.txt") << summary.str();
  return results;
}

std::string junit_xml(const nlohmann::json& results, const std::string& suite) {
  std::ostringstream x;
  int failures = 0;
  for (const auto& t : results["tests"]) failures += t["status"] != "passed";
  x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuite name=\"" << xml_escape(suite)
    << "\" tests=\"" << results["tests"].size() << "\" failures=\"" << failures << "\" time=\""
    << results["execution_time"].get<double>() << "\">\n";
  for (const auto& t : results["tests"]) {
    x << "  <testcase name=\"" << xml_escape(t["name"].get<std::string>()) << "\" time=\""
      << t.value("execution_time", 0.0) << "\"";
    if (t["status"] == "passed") {
      x << "/>\n";
    } else {
      x << ">\n    <failure message=\"" << xml_escape(t["name"].get<std::string>()) << "\">"
        << xml_escape(t["output"].get<std::string>()) << "</failure>\n  </testcase>\n";
    }
  }
  x << "</testsuite>\n";
  return x.str();
}

}  // namespace pinsim
