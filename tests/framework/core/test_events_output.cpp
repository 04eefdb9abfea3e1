// output.events: "impacts" (the impulse that begins each touch in events.csv, one
// contacts.csv row per touch), "all" (every impulse, the format crosscheck compares) and
// "none"; on a ball dropped onto a floor, against free fall.
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <sstream>

#include "core/runner.hpp"
#include "core/scene.hpp"
#include "test_support.hpp"

using namespace pinsim;
namespace fs = std::filesystem;

namespace {

std::vector<std::vector<std::string>> csv(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::vector<std::string>> out;
  for (std::string l; std::getline(in, l);) {
    std::vector<std::string> f;
    std::stringstream ss(l);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    if (!l.empty() && l.back() == ',') f.emplace_back();
    out.push_back(f);
  }
  return out;
}

constexpr double kG = 9.81, kH = 0.5, kR = 0.05, kMass = 0.2, kDt = 1e-4, kT = 0.6;

// A ball of radius R dropped from rest with its bottom h above a floor (the top of a box at
// y = 0), restitution 0 and the sdf backend's default rest_speed 0: it lands and then lies on
// the floor, an impulse every step holding it against gravity.
Scene drop_scene(const std::string& events) {
  std::ostringstream s;
  s.precision(17);
  s << R"({"time": {"dt": )" << kDt << R"(, "duration": )" << kT << R"(},
    "backend": {"name": "sdf"},
    "particles": [{"x": [0, )"
    << kH + kR << R"(], "mass": )" << kMass << R"(, "radius": )" << kR << R"(}],
    "forces": [{"type": "gravity", "params": {"g": [0, )"
    << -kG << R"(]}}],
    "obstacles": [{"id": "floor", "shape": {"type": "box", "center": [0, -0.5],
                   "half_size": [2, 0.5]}, "material": {"restitution": 0, "friction": 0}}],
    "output": {"every": 100)"
    << (events.empty() ? "" : R"(, "events": ")" + events + "\"") << "}}";
  return parse_scene(s.str(), "drop.json", ".");
}

nlohmann::json run(const Scene& s, const fs::path& dir) {
  PluginLoader loader(plugin_search_dirs());
  RunSettings rs;
  rs.out = dir;
  const RunResult r = run_scene(s, loader, rs);
  REQUIRE(r.exit_code == 0);
  return r.summary;
}

}  // namespace

TEST_CASE("events: a dropped ball gives one impact at free fall's time and one open contact") {
  // Free fall from rest (constant acceleration): the ball's bottom falls h at
  // t = sqrt(2 h / g) with speed sqrt(2 g h). Symplectic Euler is O(dt) off: y_n falls
  // g dt^2 n (n + 1) / 2, half a step early, so 2 dt of slack in time and 2 g dt in speed.
  const double t_hit = std::sqrt(2 * kH / kG), v_hit = std::sqrt(2 * kG * kH);
  const auto dir = test::temp_dir("events_impacts");
  const Scene s = drop_scene("");  // the default
  CHECK(s.output_events == "impacts");
  const auto summary = run(s, dir);
  CHECK(summary["events"]["mode"] == "impacts");

  const auto ev = csv(dir / "events.csv");
  REQUIRE(ev.size() == 2);  // header + the impact
  CHECK(ev[0].size() == 10);
  CHECK(std::stod(ev[1][0]) == Approx(t_hit).margin(2 * kDt));
  CHECK(ev[1][2] == "floor");
  CHECK(-std::stod(ev[1][8]) == Approx(v_hit).margin(2 * kG * kDt));

  const auto ct = csv(dir / "contacts.csv");
  REQUIRE(ct.size() == 2);  // header + one touch, from the landing to the end of the run
  CHECK(ct[0] == std::vector<std::string>{"t_begin", "t_end", "particle", "obstacle",
                                          "other_particle", "impulses", "impulse", "open"});
  const auto& c = ct[1];
  CHECK(std::stod(c[0]) == Approx(t_hit).margin(2 * kDt));
  CHECK(std::stod(c[1]) == Approx(kT).margin(kDt));  // still touching: its last impulse
  CHECK(c[2] == "0");
  CHECK(c[3] == "floor");
  CHECK(c[4].empty());
  CHECK(c[7] == "1");  // open at the end
  // One impulse per step from the landing on (the backend reports every one with rest_speed 0).
  CHECK(std::stod(c[5]) == Approx((kT - t_hit) / kDt).margin(3));
  // Impulse-momentum: the floor stops the ball (m v_hit) and then holds it against gravity
  // (m g per second) until the end: J = m v_hit + m g (T - t_hit).
  CHECK(std::stod(c[6]) ==
        Approx(kMass * v_hit + kMass * kG * (kT - t_hit)).margin(3 * kMass * kG * kDt));
  CHECK(summary["events"]["events_rows"] == 1);
  CHECK(summary["events"]["contacts_rows"] == 1);
  // Every impulse is still counted in the summary.
  CHECK(summary["contacts"].get<double>() == Approx(std::stod(c[5])));
}

TEST_CASE("events: \"all\" writes every impulse, \"none\" none, the trajectory never changes") {
  const auto d_imp = test::temp_dir("events_mode_impacts");
  const auto d_all = test::temp_dir("events_mode_all");
  const auto d_none = test::temp_dir("events_mode_none");
  run(drop_scene("impacts"), d_imp);
  const auto s_all = run(drop_scene("all"), d_all);
  const auto s_none = run(drop_scene("none"), d_none);

  const auto all = csv(d_all / "events.csv");
  const auto contact = csv(d_imp / "contacts.csv");
  REQUIRE(contact.size() == 2);
  // "all": one row per impulse, today's columns; as many as the one touch counted.
  CHECK(all[0] == csv(d_imp / "events.csv")[0]);
  CHECK(all.size() - 1 == std::stoull(contact[1][5]));
  CHECK(all[1] == csv(d_imp / "events.csv")[1]);  // the first impulse is the impact
  CHECK(s_all["contacts"] == all.size() - 1);
  CHECK_FALSE(fs::exists(d_all / "contacts.csv"));
  // "none": the header only.
  CHECK(csv(d_none / "events.csv").size() == 1);
  CHECK_FALSE(fs::exists(d_none / "contacts.csv"));
  CHECK(s_none["contacts"] == s_all["contacts"]);
  // The trajectory is the same in every mode.
  const std::string traj = test::read_file(d_imp / "trajectory.csv");
  CHECK(test::read_file(d_all / "trajectory.csv") == traj);
  CHECK(test::read_file(d_none / "trajectory.csv") == traj);
}

TEST_CASE("events: a ball bouncing between walls: each touch is its own impact") {
  // Restitution 1, no gravity, inside a 2 m box: at 5 m/s it hits a wall at t = (1 - R) / v
  // and every (2 - 2 R) / v after (0.19, 0.57, 0.95 s); each touch is one impulse. The
  // backend stops depth_min (1e-6 by default) short: 1e-5 s of slack.
  const auto dir = test::temp_dir("events_bounces");
  const double l = 2.0 - 2 * kR, v = 5.0;
  const Scene s = parse_scene(R"({"time": {"dt": 1e-4, "duration": 1.0},
    "backend": {"name": "sdf"},
    "particles": [{"x": [0, 0], "v": [5, 0], "radius": 0.05}],
    "obstacles": [{"id": "box", "shape": {"type": "inside", "shape": {"type": "box",
                   "center": [0, 0], "half_size": [1, 1]}}, "material": {"restitution": 1}}]})",
                              "bounce.json", ".");
  run(s, dir);
  const auto ev = csv(dir / "events.csv");
  const auto ct = csv(dir / "contacts.csv");
  const double t1 = (1.0 - kR) / v;
  const std::size_t hits = static_cast<std::size_t>(std::floor((1.0 - t1) / (l / v))) + 1;
  REQUIRE(ev.size() == 1 + hits);
  REQUIRE(ct.size() == 1 + hits);
  for (std::size_t k = 0; k < hits; ++k) {
    const double t = t1 + static_cast<double>(k) * l / v;
    CHECK(std::stod(ev[1 + k][0]) == Approx(t).margin(1e-5));
    CHECK(std::stod(ct[1 + k][0]) == Approx(t).margin(1e-5));
    CHECK(ct[1 + k][5] == "1");
    CHECK(ct[1 + k][7] == "0");
    // Impulse of an elastic bounce: 2 m v (m = 1 by default).
    CHECK(std::stod(ct[1 + k][6]) == Approx(2 * v).epsilon(1e-9));
  }
}

TEST_CASE("events: output.events other than impacts, all, none is an error naming it") {
  const std::string bad = R"({"time": {"dt": 0.01, "duration": 0.1},
    "particles": [{"x": [0, 0]}], "output": {"events": "some"}})";
  CHECK_THROWS_WITH(parse_scene(bad, "bad.json", "."),
                    Catch::Matchers::Contains("bad.json") &&
                        Catch::Matchers::Contains("output.events") &&
                        Catch::Matchers::Contains("\"impacts\", \"all\" or \"none\""));
}

namespace {
// Hits per wall of a ball in a W x H box, no gravity, restitution 1, friction 0, from the
// unfolded straight line: along x the centre moves in a free range of length L = W - 2 r
// (walls at -L/2 and +L/2); unfolded, u(t) = (x0 + L/2) + |vx| t grows from the left wall.
// The wall ahead (right for vx > 0) is hit when u = L, 3 L, 5 L, ...:
//   n_ahead = floor((u(T) / L + 1) / 2), and the wall behind at u = 2 L, 4 L, ...:
//   n_behind = floor(u(T) / (2 L)). The same along y.
struct WallHits {
  long ahead, behind;
};
WallHits hits_1d(double x0, double v, double l, double t) {
  const double u = (v >= 0 ? x0 : -x0) + l / 2 + std::abs(v) * t;
  return {static_cast<long>(std::floor((u / l + 1) / 2)),
          static_cast<long>(std::floor(u / (2 * l)))};
}
}  // namespace

TEST_CASE("events: a ball in a box: one impact per wall hit, corners included, per backend") {
  // A 3.1 x 1.3 box, a ball of radius 0.05 at (0.3, -0.2) with v = (6, 5.4) for 20 s (dt
  // 1 ms). Ten of its 130 hits follow a hit on the other wall by 3.7 ms (t = 1.7, 3.7, ... 19.7 s:
  // a periodic orbit): the ball approaches the second wall within the first touch's
  // gap of kGapSteps steps; each is its own impact. Counts against the closed form above, per wall
  // (the wall is the normal's direction; events.csv names the obstacle, "box", for all four).
  const double w = 3.1, h = 1.3, r = 0.05, x0 = 0.3, y0 = -0.2, vx = 6.0, vy = 5.4, T = 20.0;
  const WallHits hx = hits_1d(x0, vx, w - 2 * r, T), hy = hits_1d(y0, vy, h - 2 * r, T);
  for (const std::string backend : {"sdf", "box2d"}) {
    CAPTURE(backend);
    std::ostringstream s;
    s.precision(17);
    s << R"({"time": {"dt": 1e-3, "duration": )" << T << R"(}, "backend": {"name": ")" << backend
      << R"("}, "particles": [{"x": [)" << x0 << ", " << y0 << R"(], "v": [)" << vx << ", " << vy
      << R"(], "radius": )" << r
      << R"(}], "obstacles": [{"id": "box", "shape": {"type": "inside", "shape": {"type": "box",
        "center": [0, 0], "half_size": [)"
      << w / 2 << ", " << h / 2 << R"(]}}, "material": {"restitution": 1, "friction": 0}}],
      "output": {"every": 1000}})";
    const auto dir = test::temp_dir("events_box_" + backend);
    run(parse_scene(s.str(), "box.json", "."), dir);
    const auto ev = csv(dir / "events.csv");
    long right = 0, left = 0, top = 0, bottom = 0;
    for (std::size_t k = 1; k < ev.size(); ++k) {
      const double nx = std::stod(ev[k][6]), ny = std::stod(ev[k][7]);
      CHECK(ev[k][2] == "box");
      if (nx < -0.9) ++right;  // the normal points from the wall into the box
      if (nx > 0.9) ++left;
      if (ny < -0.9) ++top;
      if (ny > 0.9) ++bottom;
    }
    CHECK(right == hx.ahead);
    CHECK(left == hx.behind);
    CHECK(top == hy.ahead);
    CHECK(bottom == hy.behind);
    CHECK(ev.size() - 1 == static_cast<std::size_t>(hx.ahead + hx.behind + hy.ahead + hy.behind));
  }
}
