#include "grading/rubric.hpp"

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
const std::set<std::string> kBackendChecks = {
    "load",          "backend_agreement",   "backend_no_tunnelling", "backend_approaching_only",
    "backend_path",  "backend_free_flight", "backend_bounce",        "backend_rest",
    "backend_energy"};

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Gradescope's four visibility values; anything else fails naming the JSON path.
std::string read_visibility(const nlohmann::json& j, const char* key, const std::string& fallback,
                            const Loc& at) {
  const std::string v = read_string_or(j, key, fallback, at);
  if (v != "visible" && v != "hidden" && v != "after_due_date" && v != "after_published")
    (at / key).fail("expected visible, hidden, after_due_date or after_published, got \"" + v +
                    "\"");
  return v;
}

double positive(const nlohmann::json& j, const char* key, double fallback, const Loc& at,
                double max) {
  const double v = read_number_or(j, key, fallback, at);
  if (!(v > 0 && v <= max))
    (at / key).fail("must be > 0 and <= " + nlohmann::json(max).dump() + ", got " +
                    nlohmann::json(v).dump());
  return v;
}

grading::SandboxLimits read_limits(const nlohmann::json& j, const Loc& at,
                                   grading::SandboxLimits l) {
  require_object(j, at);
  check_keys(
      j,
      {"cpu_seconds", "memory_mb", "wall_seconds", "processes", "file_mb", "open_files", "tmp_mb"},
      at);
  l.cpu_seconds = positive(j, "cpu_seconds", l.cpu_seconds, at, 86400);
  l.memory_mb = positive(j, "memory_mb", l.memory_mb, at, 1 << 20);
  l.wall_seconds = positive(j, "wall_seconds", l.wall_seconds, at, 86400);
  l.processes = static_cast<int>(positive(j, "processes", l.processes, at, 100000));
  l.file_mb = positive(j, "file_mb", l.file_mb, at, 1 << 20);
  l.open_files = static_cast<int>(positive(j, "open_files", l.open_files, at, 65536));
  l.tmp_mb = positive(j, "tmp_mb", l.tmp_mb, at, 1 << 20);
  return l;
}

}  // namespace

Rubric load_rubric(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) throw InputError(file.string() + ": rubric file not found");
  const nlohmann::json j = parse_json_text(read_text(file), file.string());
  const Loc root{file.string(), ""};
  require_object(j, root);
  check_keys(j,
             {"$schema", "name", "kind", "visibility", "stdout_visibility", "limits",
              "build_limits", "time_budget_seconds", "output_limit_kb", "tests"},
             root);
  Rubric r;
  r.file = fs::absolute(file);
  r.name = read_string_or(j, "name", file.stem().string(), root);
  r.kind = read_string_or(j, "kind", "force", root);
  if (r.kind != "force" && r.kind != "backend")
    (root / "kind").fail("expected \"force\" or \"backend\", got \"" + r.kind + "\"");
  r.visibility = read_visibility(j, "visibility", r.visibility, root);
  r.stdout_visibility = read_visibility(j, "stdout_visibility", r.stdout_visibility, root);
  if (j.contains("limits")) r.limits = read_limits(j["limits"], root / "limits", r.limits);
  if (j.contains("build_limits"))
    r.build_limits = read_limits(j["build_limits"], root / "build_limits", r.build_limits);
  r.time_budget_seconds = positive(j, "time_budget_seconds", r.time_budget_seconds, root, 1e6);
  r.output_limit_kb = positive(j, "output_limit_kb", r.output_limit_kb, root, 1 << 20);
  if (!j.contains("tests") || !j["tests"].is_array() || j["tests"].empty())
    (root / "tests").fail("expected a non-empty array of tests");
  const auto& checks = r.kind == "force" ? kForceChecks : kBackendChecks;
  for (std::size_t i = 0; i < j["tests"].size(); ++i) {
    const auto& t = j["tests"][i];
    const Loc at = (root / "tests")[i];
    require_object(t, at);
    check_keys(t,
               {"name", "check", "plugin", "points", "visibility", "hint", "params", "reference",
                "scene", "tolerance", "velocity_tolerance", "path_tolerance", "trials", "seed",
                "assume_internal", "second_opinion", "second_opinion_params"},
               at);
    RubricTest rt;
    rt.spec = t;
    rt.name = read_string_or(t, "name", "", at);
    if (rt.name.empty()) (at / "name").fail("required test name is missing");
    rt.check = read_string_or(t, "check", "", at);
    if (!checks.count(rt.check)) {
      std::string list;
      for (const auto& c : checks) list += (list.empty() ? "" : ", ") + c;
      (at / "check")
          .fail("unknown check '" + rt.check + "' for a " + r.kind + " rubric (known: " + list +
                ")");
    }
    rt.plugin = read_string_or(t, "plugin", "", at);
    if (rt.plugin.empty()) (at / "plugin").fail("required: the submission's plugin name");
    rt.points = read_number_or(t, "points", 1.0, at);
    if (!(rt.points >= 0)) (at / "points").fail("must be >= 0");
    rt.visibility = read_visibility(t, "visibility", r.visibility, at);
    rt.hint = read_string_or(t, "hint", "", at);
    if (t.contains("params")) require_object(t["params"], at / "params");
    if (t.contains("second_opinion_params"))
      require_object(t["second_opinion_params"], at / "second_opinion_params");
    for (const char* k : {"reference", "scene", "second_opinion"})
      if (t.contains(k)) read_string_or(t, k, "", at);
    for (const char* k : {"tolerance", "velocity_tolerance", "path_tolerance", "trials", "seed"})
      if (t.contains(k)) read_number_or(t, k, 0.0, at);
    if (t.contains("assume_internal") && !t["assume_internal"].is_boolean())
      (at / "assume_internal").fail("expected true or false");
    if ((rt.check == "reference" || rt.check.rfind("backend_", 0) == 0) && !t.contains("reference"))
      (at / "reference").fail("required: the reference plugin to compare with");
    if ((rt.check == "simulation" || rt.check.rfind("backend_", 0) == 0) && !t.contains("scene"))
      (at / "scene").fail("required: the scene file (relative to the rubric)");
    if (t.contains("scene")) {
      const fs::path scene = r.file.parent_path() / t["scene"].get<std::string>();
      if (!fs::is_regular_file(scene, ec))
        (at / "scene").fail("no such scene file: " + scene.string());
    }
    r.tests.push_back(std::move(rt));
  }
  return r;
}

}  // namespace pinsim
