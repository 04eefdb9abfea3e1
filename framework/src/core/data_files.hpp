// The files pinsim ships beside the program: scenes (configs/), rubrics (configs/grading/)
// and the plugin templates (sdk/). An installed pinsim finds them in PREFIX/share/pinsim,
// relative to its own executable (so a moved install finds its own); a pinsim in a build
// tree finds them in its source tree.
#pragma once

#include <filesystem>
#include <string_view>

namespace pinsim {

/// PREFIX/share/pinsim beside this program when it exists (an installed pinsim), else the
/// source tree this program was built from.
std::filesystem::path data_dir();

/// `file` as given when it exists; else, for a relative path, data_dir()/subdir/file, or that
/// with ".json" appended when `file` has no extension, whichever exists first. Otherwise
/// `file` unchanged (the caller reports it missing).
std::filesystem::path find_data_file(const std::filesystem::path& file, std::string_view subdir);

}  // namespace pinsim
