// The keys of a --set path, shared by the scene's --set and the gradients' --wrt paths.
#pragma once

#include <string>
#include <vector>

namespace pinsim {

/// Splits "forces[0].params.k" or "forces.0.params.k" into {"forces", "0", "params", "k"}.
std::vector<std::string> split_set_path(const std::string& path);

}  // namespace pinsim
