#include "cli_common.hpp"

#include <spdlog/spdlog.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/bounded_read.hpp"
#include "core/input_error.hpp"
#include "core/json_read.hpp"

namespace pinsim::cli {

Scene load_scene_or_default(const std::string& file, const std::vector<std::string>& overrides) {
  if (!file.empty()) return load_scene(file, overrides);
  return parse_scene(kDefaultSceneText, std::string("<embedded ") + kDefaultSceneName + ">",
                     std::filesystem::current_path(), overrides);
}

std::vector<std::string> with_backend(const std::string& file, const std::string& backend,
                                      const std::vector<std::string>& overrides) {
  if (backend.empty()) return overrides;
  std::string text = kDefaultSceneText, label = std::string("<embedded ") + kDefaultSceneName + ">";
  if (!file.empty()) {
    text = scene_file_text(file);  // the text load_scene parses next, read once
    label = file;
  }
  const nlohmann::json doc = parse_json_text(text, label);
  if (!doc.is_object()) return overrides;
  const nlohmann::json b = doc.value("backend", nlohmann::json());
  const std::string current =
      b.is_string() ? b.get<std::string>()
                    : (b.is_object() ? b.value("name", std::string("none")) : std::string("none"));
  if (current == backend) return overrides;
  nlohmann::json params = nlohmann::json::object();
  const nlohmann::json cc = doc.value("crosscheck", nlohmann::json());
  const nlohmann::json cp =
      cc.is_object() ? cc.value("params", nlohmann::json()) : nlohmann::json();
  if (cp.is_object() && cp.contains(backend) && cp[backend].is_object()) {
    params = cp[backend];
    spdlog::info("{}: --backend {}: using the scene's crosscheck.params.{} {}", label, backend,
                 backend, params.dump());
  } else {
    spdlog::debug(
        "{}: --backend {}: the scene gives no crosscheck.params.{}; {} starts from its "
        "defaults (--set backend.params.KEY=VALUE sets them)",
        label, backend, backend, backend);
  }
  std::vector<std::string> out;
  out.push_back("backend=" + nlohmann::json{{"name", backend}, {"params", params}}.dump());
  out.insert(out.end(), overrides.begin(), overrides.end());
  return out;
}

RunData read_run_folder(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::exists(dir, ec))
    throw InputError(dir.string() + ": no such run folder (pinsim run --out DIR writes one)");
  if (!is_run_dir(dir))
    throw InputError(dir.string() +
                     ": not a run folder (expected trajectory.csv or trajectory.h5 in it, as " +
                     "pinsim run --out writes)");
  try {
    return load_run(dir);
  } catch (const std::exception& e) {
    throw InputError(dir.string() + ": cannot read the run folder: " + e.what());
  }
}

ViewBox view_option(const std::string& text) {
  try {
    return parse_view(text);
  } catch (const std::invalid_argument& e) {
    throw InputError(e.what());
  }
}

}  // namespace pinsim::cli
