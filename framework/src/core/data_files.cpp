#include "core/data_files.hpp"

namespace fs = std::filesystem;

namespace pinsim {

fs::path data_dir() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = (exe.parent_path() / PINSIM_INSTALL_DATA_RELDIR).lexically_normal();
    if (fs::is_directory(installed, ec)) return installed;
  }
  return PINSIM_SOURCE_DIR;
}

fs::path find_data_file(const fs::path& file, std::string_view subdir) {
  std::error_code ec;
  if (file.empty() || file.is_absolute() || fs::exists(file, ec)) return file;
  const fs::path base = data_dir() / subdir;
  if (fs::is_regular_file(base / file, ec)) return base / file;
  if (!file.has_extension()) {
    const fs::path with_json = base / fs::path(file.string() + ".json");
    if (fs::is_regular_file(with_json, ec)) return with_json;
  }
  return file;
}

}  // namespace pinsim
