// A small picture of a failed comparison (core/path_comparison.hpp): the table with its
// obstacles filled, the reference's paths and the other run's over it, a ring where the
// comparison failed and a cross where a ball went into an obstacle. Drawn in few flat
// colours, so that the PNG stays small enough to embed in a grader's results.
#pragma once

#include <cstdint>

#include "core/path_comparison.hpp"
#include "core/plugin_loader.hpp"

namespace pinsim {

/// The picture's size, pixels.
inline constexpr int kComparisonWidth = 480;
inline constexpr int kComparisonHeight = 320;
/// The colours of the paths as drawn (0xRRGGBB): the reference's is blue, the other's orange.
inline constexpr uint32_t kComparisonReferenceRgb = 0x1f5fd8;
inline constexpr uint32_t kComparisonMineRgb = 0xe66e00;

/// Draws `c` as a PNG of kComparisonWidth x kComparisonHeight pixels. The table is the
/// scene's backend (loaded by `loader`) at the failing time. Throws std::runtime_error.
ComparisonPicture comparison_png(const PathComparison& c, PluginLoader& loader);

}  // namespace pinsim
