// The picture of a failed simulation or path test, as a student sees it on Gradescope: the
// test's output is html with an embedded PNG of the documented size showing both paths in
// their colours; passing tests and the other tests stay text; junit.xml and summary.txt hold
// no picture; results.json stays of Gradescope's format; and with many failing tests the
// pictures stop at the documented cap (grading/results.hpp).
#include <cairo.h>

#include <catch2/catch.hpp>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "grade_cli.hpp"
#include "grading/results.hpp"
#include "pictures/comparison.hpp"
#include "test_support.hpp"

using Catch::Matchers::Contains;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const fs::path subs = PINSIM_GRADING_SUBMISSIONS;
const fs::path src = PINSIM_GRADING_SOURCE;
const fs::path collision = PINSIM_SOURCE_DIR "/configs/grading/collision_assignment.json";
const std::string kImg = "<img src=\"data:image/png;base64,";

std::string unbase64(const std::string& text) {
  std::string out;
  uint32_t acc = 0;
  int bits = 0;
  for (const char c : text) {
    const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    const char* at = std::strchr(k, c);
    if (c == '=' || c == '\0' || at == nullptr) break;
    acc = (acc << 6) | static_cast<uint32_t>(at - k);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out += static_cast<char>((acc >> bits) & 255);
    }
  }
  return out;
}

/// The PNG embedded in a test's html output, decoded; empty if there is none.
std::string embedded_png(const json& test) {
  const std::string o = test["output"].get<std::string>();
  const std::size_t a = o.find(kImg);
  if (a == std::string::npos) return "";
  const std::size_t b = o.find('"', a + kImg.size());
  return unbase64(o.substr(a + kImg.size(), b - a - kImg.size()));
}

/// A PNG decoded by cairo: its size and how many pixels have exactly one colour.
struct Pixels {
  int width = 0, height = 0;
  int reference = 0, mine = 0;
};

Pixels decode(const std::string& png) {
  struct Reader {
    const std::string& bytes;
    std::size_t at = 0;
  } r{png};
  cairo_surface_t* s = cairo_image_surface_create_from_png_stream(
      [](void* self, unsigned char* data, unsigned int n) {
        auto* rd = static_cast<Reader*>(self);
        if (rd->at + n > rd->bytes.size()) return CAIRO_STATUS_READ_ERROR;
        std::memcpy(data, rd->bytes.data() + rd->at, n);
        rd->at += n;
        return CAIRO_STATUS_SUCCESS;
      },
      &r);
  Pixels p;
  if (cairo_surface_status(s) == CAIRO_STATUS_SUCCESS) {
    p.width = cairo_image_surface_get_width(s);
    p.height = cairo_image_surface_get_height(s);
    const unsigned char* d = cairo_image_surface_get_data(s);
    const int stride = cairo_image_surface_get_stride(s);
    for (int y = 0; y < p.height; ++y)
      for (int x = 0; x < p.width; ++x) {
        uint32_t v = 0;
        std::memcpy(&v, d + static_cast<std::ptrdiff_t>(y) * stride + 4 * x, 4);
        p.reference += (v & 0xffffff) == pinsim::kComparisonReferenceRgb;
        p.mine += (v & 0xffffff) == pinsim::kComparisonMineRgb;
      }
  }
  cairo_surface_destroy(s);
  return p;
}

bool is_picture_check(const std::string& name) {
  return name.find("no tunnelling") != std::string::npos ||
         name.find("path of the reference") != std::string::npos;
}

}  // namespace

TEST_CASE("pictures: a failed path test shows both paths on the table; the rest stays text") {
  // The assignment's discrete starter: it fails every tunnelling test and the path tests.
  const pinsim::test::Graded g = pinsim::test::grade(collision, subs / "discrete_backend", "pics");
  const fs::path out = g.file.parent_path();
  int pictures = 0;
  for (const auto& t : g.results["tests"]) {
    const std::string name = t["name"].get<std::string>(), o = t["output"].get<std::string>();
    CAPTURE(name, o.substr(0, 2000));
    if (t["status"] == "passed" || !is_picture_check(name)) {
      // Passing tests and the other checks: text, no picture.
      CHECK(!t.contains("output_format"));
      CHECK_THAT(o, !Contains("data:image"));
      continue;
    }
    CHECK(t["output_format"] == "html");
    CHECK_THAT(o, Contains("<pre>"));
    CHECK_THAT(o, Contains("width=\"480\" height=\"320\""));
    CHECK_THAT(o, Contains("Blue: the reference's path; orange: yours"));
    CHECK_THAT(o, Contains("the test failed: your particle"));
    const std::string png = embedded_png(t);
    CHECK((png.size() + 2) / 3 * 4 <= pinsim::grading::kPictureMaxBytes);
    const Pixels p = decode(png);
    CHECK(p.width == pinsim::kComparisonWidth);
    CHECK(p.height == pinsim::kComparisonHeight);
    CHECK(p.reference > 20);
    CHECK(p.mine > 20);
    ++pictures;
  }
  CHECK(pictures >= 6);
  // At 1,000 units/s the ball ends step 3 beyond the wall: the cross marks where it went in.
  for (const auto& t : g.results["tests"])
    if (t["name"] == "thin box and capsule walls at 1,000 units/s: no tunnelling") {
      CHECK_THAT(t["output"].get<std::string>(), Contains("at step 3 "));
      CHECK_THAT(t["output"].get<std::string>(), Contains("centre went into obstacle"));
    }
  // The text files keep the text, and no picture.
  const std::string junit = pinsim::test::read_file(out / "junit.xml");
  const std::string summary = pinsim::test::read_file(out / "summary.txt");
  CHECK_THAT(junit, !Contains("data:image"));
  CHECK_THAT(summary, !Contains("data:image"));
  CHECK_THAT(summary, Contains("at step 3 "));
  CHECK_THAT(junit, Contains("at step 3 "));
  // Of Gradescope's format.
  const auto v = pinsim::test::shell("/usr/bin/python3 " + (src / "check_results.py").string() +
                                     " " + g.file.string() + " 2>&1");
  INFO(v.output);
  CHECK(v.code == 0);
}

TEST_CASE("pictures: a failed simulation shows where the chain first left the reference's") {
  // The spring with a sign error: the chain blows up (the run fails at step 500), after its
  // path has left the reference's; the picture shows that first step. No obstacles here.
  const pinsim::test::Graded g =
      pinsim::test::grade(src / "rubric_springs.json", subs / "sign_error", "pics-sim");
  for (const auto& t : g.results["tests"]) {
    const std::string o = t["output"].get<std::string>();
    CAPTURE(t["name"].get<std::string>(), o.substr(0, 2000));
    if (t["name"] != "hanging chain") {
      CHECK_THAT(o, !Contains("data:image"));
      continue;
    }
    CHECK(t["output_format"] == "html");
    CHECK_THAT(o, Contains("your simulation failed at step 500"));
    CHECK_THAT(o, Contains("your path first leaves the reference's by more than 1e-08"));
    const Pixels p = decode(embedded_png(t));
    CHECK(p.width == pinsim::kComparisonWidth);
    CHECK(p.reference > 20);
    CHECK(p.mine > 20);
  }
}

TEST_CASE("pictures: many failing path tests stop adding pictures at the cap") {
  // 60 path tests on the hidden tables of a backend that never moves the balls: each fails
  // in its first steps, with a picture of about 6 KiB of base64 text.
  const fs::path dir = pinsim::test::temp_dir("pictures-cap");
  json tests = json::array();
  tests.push_back({{"name", "loads"}, {"check", "load"}, {"plugin", "student_sdf"}});
  for (int i = 0; i < 60; ++i)
    tests.push_back({{"name", "path " + std::to_string(i)},
                     {"check", "backend_path"},
                     {"plugin", "student_sdf"},
                     {"reference", "sdf"},
                     {"scene", PINSIM_SOURCE_DIR "/configs/grading/scenes/" +
                                   std::string(i % 2 ? "corner.json" : "hidden_table.json")}});
  pinsim::test::write_file(
      dir / "rubric.json",
      json{{"name", "many paths"}, {"kind", "backend"}, {"tests", tests}}.dump());
  const pinsim::test::Graded g =
      pinsim::test::grade(dir / "rubric.json", subs / "still_backend", "pictures-cap");
  std::size_t total = 0;
  int with = 0, left_out = 0;
  bool after_cap = false;
  for (const auto& t : g.results["tests"]) {
    if (t["status"] == "passed") continue;
    const std::string o = t["output"].get<std::string>();
    CAPTURE(t["name"].get<std::string>(), o.substr(0, 1000));
    const std::size_t a = o.find(kImg);
    if (a != std::string::npos) {
      CHECK(!after_cap);  // the pictures go to the first failing tests
      total += o.find('"', a + kImg.size()) - a - kImg.size();
      ++with;
    } else {
      CHECK_THAT(o, Contains("Its picture is left out"));
      after_cap = true;
      ++left_out;
    }
  }
  CHECK(with >= 8);
  CHECK(left_out >= 1);
  CHECK(total <= pinsim::grading::kPicturesMaxBytes);
  // The whole file: the pictures and each test's text.
  CHECK(fs::file_size(g.file) < pinsim::grading::kPicturesMaxBytes + 64 * 1024);
}
