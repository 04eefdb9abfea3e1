// The picture of a failed comparison (comparison_png): a PNG of the documented size, small,
// with the obstacles filled and both paths in their colours, the marks where the test failed
// and where a ball went into a wall; a path that flies off to 1e300 or NaN is clipped.
#include <cairo.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <string>

#include "core/plugin_loader.hpp"
#include "core/scene.hpp"
#include "pictures/comparison.hpp"

using namespace pinsim;

namespace {

/// A ball flying at a thin wall at x = 0 (from x = -1): the reference's bounces back, the
/// other one passes through.
const char* kScene = R"({
  "time": {"dt": 0.01, "duration": 0.2},
  "backend": {"name": "sdf"},
  "particles": [{"x": [-1, 0.2], "v": [10, 1], "radius": 0.02}],
  "obstacles": [{"id": "wall", "shape": {"type": "box", "center": [0, 0], "half_size": [0.002, 1]}}]
})";

PathComparison tunnelled() {
  PathComparison c;
  c.scene = parse_scene(kScene, "comparison test", ".");
  c.reference.resize(1);
  c.mine.resize(1);
  for (int n = 0; n <= 20; ++n) {
    const double t = 0.01 * n, x = -1 + 10 * t, y = 0.2 + t;
    c.reference[0].emplace_back(x <= -0.02 ? x : -0.04 - x, y);
    c.mine[0].emplace_back(x, y);
  }
  c.step = 20;
  c.steps = 20;
  c.t = 0.2;
  c.mine_at = c.mine[0].back();
  c.reference_at = c.reference[0].back();
  c.crossing = PathComparison::Crossing{10, 0.1, 0, {0.0, 0.3}, "wall"};
  return c;
}

/// A decoded PNG; counts pixels of one colour.
class Decoded {
 public:
  explicit Decoded(const std::string& png) : bytes_(png) {
    s_ = cairo_image_surface_create_from_png_stream(
        [](void* self, unsigned char* data, unsigned int n) {
          auto* d = static_cast<Decoded*>(self);
          if (d->read_ + n > d->bytes_.size()) return CAIRO_STATUS_READ_ERROR;
          std::memcpy(data, d->bytes_.data() + d->read_, n);
          d->read_ += n;
          return CAIRO_STATUS_SUCCESS;
        },
        this);
  }
  ~Decoded() { cairo_surface_destroy(s_); }
  Decoded(const Decoded&) = delete;
  Decoded& operator=(const Decoded&) = delete;
  bool ok() const { return cairo_surface_status(s_) == CAIRO_STATUS_SUCCESS; }
  int width() const { return cairo_image_surface_get_width(s_); }
  int height() const { return cairo_image_surface_get_height(s_); }
  int count(uint32_t rgb) const {
    cairo_surface_flush(s_);
    const unsigned char* d = cairo_image_surface_get_data(s_);
    const int stride = cairo_image_surface_get_stride(s_);
    int n = 0;
    for (int y = 0; y < height(); ++y)
      for (int x = 0; x < width(); ++x) {
        uint32_t v = 0;
        std::memcpy(&v, d + static_cast<std::ptrdiff_t>(y) * stride + 4 * x, 4);
        n += (v & 0xffffff) == rgb;
      }
    return n;
  }

 private:
  std::string bytes_;
  std::size_t read_ = 0;
  cairo_surface_t* s_ = nullptr;
};

}  // namespace

TEST_CASE("comparison picture: the table, both paths and the marks, in a small PNG") {
  PluginLoader loader(plugin_search_dirs());
  const ComparisonPicture p = comparison_png(tunnelled(), loader);
  CHECK(p.width == kComparisonWidth);
  CHECK(p.height == kComparisonHeight);
  // Flat colours compress: far under the grader's limit of 48 KiB of base64 per picture.
  CHECK(p.png.size() < 24 * 1024);
  const Decoded d(p.png);
  REQUIRE(d.ok());
  CHECK(d.width() == 480);
  CHECK(d.height() == 320);
  CHECK(d.count(kComparisonReferenceRgb) > 100);
  CHECK(d.count(kComparisonMineRgb) > 100);
  CHECK(d.count(0x4a505c) > 50);  // the wall, 0.004 wide: at least a line of pixels
  CHECK(d.count(0xc0102f) > 10);  // the ring where the test failed
  CHECK(d.count(0xa000b0) > 10);  // the cross where the ball went into the wall
  CHECK_THAT(p.legend, Catch::Matchers::Contains("purple cross"));
}

TEST_CASE("comparison picture: a path that flies off or turns NaN is clipped, not followed") {
  PluginLoader loader(plugin_search_dirs());
  PathComparison c = tunnelled();
  c.crossing.reset();
  c.mine[0].back() = {1e300, -1e300};
  c.mine[0].emplace_back(std::nan(""), 0.0);
  c.mine_at = {1e300, -1e300};
  const ComparisonPicture p = comparison_png(c, loader);
  const Decoded d(p.png);
  REQUIRE(d.ok());
  // The view still holds the table: the reference's path is as long as before.
  CHECK(d.count(kComparisonReferenceRgb) > 100);
  CHECK(d.count(kComparisonMineRgb) > 100);
  CHECK(d.count(0xa000b0) == 0);
  CHECK_THAT(p.legend, !Catch::Matchers::Contains("cross"));
}
