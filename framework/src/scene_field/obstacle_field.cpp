#include <algorithm>
#include <cmath>
#include <map>
#include <pinsim/scene_field/limits.hpp>
#include <pinsim/scene_field/obstacle_field.hpp>
#include <set>

namespace pinsim::sdf {
namespace {

using InputMap = std::map<std::string, std::vector<std::pair<double, bool>>>;

InputMap parse_inputs(const JsonIn& scene, std::vector<std::string>& names) {
  InputMap m;
  if (!scene.has("inputs")) return m;
  const auto& arr = scene.array("inputs");
  std::vector<std::tuple<double, std::size_t, std::string, bool>> evs;
  for (std::size_t i = 0; i < arr.size(); ++i) {
    const JsonIn e(arr[i], "inputs[" + std::to_string(i) + "]", scene.ctx());
    e.only({"t", "input", "action"});
    const double t = e.number_if(
        "t", [](double x) { return x >= 0.0; }, "must be >= 0");
    const std::string in = e.string("input");
    const std::string action = e.string("action");
    if (action != "press" && action != "release")
      e.fail("action", "expected \"press\" or \"release\", got \"" + action + "\"");
    evs.emplace_back(t, i, in, action == "press");
    names.push_back(in);
  }
  std::stable_sort(evs.begin(), evs.end(),
                   [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });
  for (const auto& [t, i, in, press] : evs) m[in].emplace_back(t, press);
  return m;
}

Material parse_material(const JsonIn& o) {
  Material m;
  if (!o.has("material")) return m;
  const JsonIn j = o.object("material");
  j.only({"restitution", "friction", "kick"});
  m.restitution = j.number_if(
      "restitution", 1.0, [](double x) { return x >= 0.0 && x <= 1.0; }, "must be in [0, 1]");
  m.friction = j.number_if(
      "friction", 0.0, [](double x) { return x >= 0.0; }, "must be >= 0");
  m.kick = j.number_if(
      "kick", 0.0, [](double x) { return x >= 0.0; }, "must be >= 0");
  return m;
}

}  // namespace

ObstacleField::ObstacleField(const nlohmann::json& scene_json, const std::string& ctx,
                             const std::vector<Vec2>& extra, long grid_cells) {
  const nlohmann::json empty = nlohmann::json::object();
  const JsonIn scene(scene_json.is_object() ? scene_json : empty, "", ctx);
  for (const char* key : {"obstacles", "inputs"}) {
    std::string path = key;
    if (scene.has(key)) check_magnitudes(scene.json().at(key), path, ctx);
  }
  std::vector<std::string> input_names;
  const InputMap inputs = parse_inputs(scene, input_names);
  std::set<std::string> listened;
  std::set<std::string> ids;
  if (!scene.has("obstacles")) return;
  const auto& arr = scene.array("obstacles");
  for (std::size_t i = 0; i < arr.size(); ++i) {
    const JsonIn o(arr[i], "obstacles[" + std::to_string(i) + "]", ctx);
    o.only({"id", "shape", "material", "motion"});
    Obstacle ob;
    ob.id = o.string("id");
    if (ob.id.empty()) o.fail("id", "must be a non-empty string");
    if (!ids.insert(ob.id).second) o.fail("id", "duplicate obstacle id \"" + ob.id + "\"");
    ob.shape = ShapeTree::parse(o.object("shape"));
    ob.material = parse_material(o);
    if (o.has("motion")) {
      const JsonIn m = o.object("motion");
      const std::string type = m.string("type");
      auto pos = [](double x) { return x > 0.0; };
      const Aabb local = ob.shape.bounds();
      if (!local.bounded)
        o.fail("shape", "a moving obstacle must be bounded (no half_plane or inside)");
      std::string input;
      if (type == "flipper") {
        m.only({"type", "pivot", "rest_angle", "raised_angle", "angular_speed",
                "return_angular_speed", "input"});
        ob.motion = MotionType::kFlipper;
        ob.pivot = m.vec2("pivot");
        const double a0 = m.number("rest_angle"), a1 = m.number("raised_angle");
        const double w = m.number_if("angular_speed", pos, "must be > 0");
        const double w2 = m.number_if("return_angular_speed", w, pos, "must be > 0");
        input = m.string("input");
        const auto it = inputs.find(input);
        ob.timeline.emplace(
            a0, a1, w, w2,
            it == inputs.end() ? std::vector<std::pair<double, bool>>{} : it->second);
        for (int k = 0; k < 4; ++k) {
          const Vec2 c((k & 1) ? local.hi.x() : local.lo.x(),
                       (k & 2) ? local.hi.y() : local.lo.y());
          ob.reach = std::max(ob.reach, c.norm());
        }
      } else if (type == "slider") {
        m.only({"type", "offset", "speed", "return_speed", "input"});
        ob.motion = MotionType::kSlider;
        ob.offset = m.vec2("offset");
        const double len = ob.offset.norm();
        if (!(len > 0.0)) m.fail("offset", "must be non-zero");
        const double s = m.number_if("speed", pos, "must be > 0");
        const double s2 = m.number_if("return_speed", s, pos, "must be > 0");
        input = m.string("input");
        const auto it = inputs.find(input);
        ob.timeline.emplace(
            0.0, 1.0, s / len, s2 / len,
            it == inputs.end() ? std::vector<std::pair<double, bool>>{} : it->second);
        ob.sweep = local;
        ob.sweep.add(local.lo + ob.offset);
        ob.sweep.add(local.hi + ob.offset);
      } else {
        m.fail("type", "unknown motion type '" + type + "' (expected flipper or slider)");
      }
      listened.insert(input);
      ob.input = input;
      moving_.push_back(static_cast<uint32_t>(i));
    } else {
      static_.push_back(static_cast<uint32_t>(i));
    }
    obs_.push_back(std::move(ob));
  }
  for (std::size_t i = 0; i < input_names.size(); ++i) {
    // inputs were validated in file order; find the first event naming an unknown input
    if (!listened.count(input_names[i]))
      throw Error(ctx + ": inputs[" + std::to_string(i) +
                  "].input: no obstacle's motion listens to \"" + input_names[i] + "\"");
  }
  build_grid(extra, grid_cells);
}

void ObstacleField::input(const std::string& name, bool pressed, double t) {
  if (!(t >= 0.0))
    throw Error("input \"" + name + "\": time must be >= 0, got " + std::to_string(t));
  bool found = false;
  for (uint32_t k : moving_) {
    Timeline& tl = *obs_[k].timeline;
    if (obs_[k].input != name) continue;
    if (!tl.events().empty() && t < tl.events().back().first)
      throw Error("input \"" + name + "\" at t = " + std::to_string(t) +
                  " s: before its previous event at t = " +
                  std::to_string(tl.events().back().first) + " s (events come in time order)");
    found = true;
  }
  if (!found) throw Error("input \"" + name + "\": no obstacle's motion listens to it");
  for (uint32_t k : moving_)
    if (obs_[k].input == name) obs_[k].timeline->add_event(t, pressed);
}

void ObstacleField::build_grid(const std::vector<Vec2>& extra, long grid_cells) {
  // (a cell counts its candidates in 16 bits)
  if (grid_cells <= 0 || static_.size() < 2 || obs_.size() > 65535) return;
  Aabb region;
  for (uint32_t k : static_) {
    const Aabb b = obs_[k].shape.boundary_bounds();
    if (b.bounded) region.add(b);
  }
  for (uint32_t k : moving_) {
    const Obstacle& o = obs_[k];
    if (o.motion == MotionType::kFlipper) {
      region.add(o.pivot - Vec2(o.reach, o.reach));
      region.add(o.pivot + Vec2(o.reach, o.reach));
    } else {
      region.add(o.sweep);
    }
  }
  for (const Vec2& p : extra) region.add(p);
  if (region.empty() || !region.bounded) return;
  const Vec2 size = region.hi - region.lo;
  const double margin = 0.02 * std::max(size.x(), size.y()) + 1e-9;
  region.lo -= Vec2(margin, margin);
  region.hi += Vec2(margin, margin);
  const Vec2 ext = region.hi - region.lo;
  double cell = std::sqrt(ext.x() * ext.y() / static_cast<double>(grid_cells));
  if (!(cell > 0.0)) cell = std::max(ext.x(), ext.y()) / std::sqrt(static_cast<double>(grid_cells));
  if (!(cell > 0.0)) return;
  g_nx_ = std::clamp(static_cast<int>(std::ceil(ext.x() / cell)), 1, 4096);
  g_ny_ = std::clamp(static_cast<int>(std::ceil(ext.y() / cell)), 1, 4096);
  cell = std::max(ext.x() / g_nx_, ext.y() / g_ny_);
  g_lo_ = region.lo;
  g_inv_ = 1.0 / cell;
  const double hd = 0.5 * cell * std::sqrt(2.0);
  const std::size_t cells = static_cast<std::size_t>(g_nx_) * static_cast<std::size_t>(g_ny_);
  g_cells_.assign(cells, Cell{});
  // (a tree too large for a 15-bit node index: no grid)
  auto fail_grid = [this] {
    g_nx_ = g_ny_ = 0;
    g_cells_.clear();
    g_cand_.clear();
  };
  std::vector<double> f(static_.size());
  std::vector<std::pair<double, uint32_t>> order;
  // a float bound never above the double one, so skipping by it is exact
  auto round_down = [](double x) {
    float y = static_cast<float>(x);
    if (static_cast<double>(y) > x) y = std::nextafter(y, -HUGE_VALF);
    return y;
  };
  for (int iy = 0; iy < g_ny_; ++iy) {
    for (int ix = 0; ix < g_nx_; ++ix) {
      const Vec2 c = g_lo_ + Vec2((ix + 0.5) * cell, (iy + 0.5) * cell);
      double ub = HUGE_VAL;
      for (std::size_t q = 0; q < static_.size(); ++q) {
        f[q] = obs_[static_[q]].shape.eval<false>(c).d;
        ub = std::min(ub, f[q] + hd);
      }
      // 1e-9 relative slack against rounding in the bound itself
      const double lim = ub + 1e-9 * (std::abs(ub) + hd);
      // candidates in increasing order of their lower bound over the cell, so a query can
      // stop at the first whose bound is not below the best distance found
      order.clear();
      for (std::size_t q = 0; q < static_.size(); ++q)
        if (f[q] - hd <= lim) order.emplace_back(f[q] - hd, static_[q]);
      std::sort(order.begin(), order.end());
      Cell& cl = g_cells_[static_cast<std::size_t>(iy) * static_cast<std::size_t>(g_nx_) +
                          static_cast<std::size_t>(ix)];
      cl.first = static_cast<uint32_t>(g_cand_.size());
      // each static candidate's tree reduced to the part that decides it over the cell; the
      // first (there is always one: the least f) is stored in the cell itself
      for (std::size_t q = 0; q < order.size(); ++q) {
        const auto [lb, k] = order[q];
        const ShapeTree::Reduced red = obs_[k].shape.reduce(c, hd * (1.0 + 1e-6) + 1e-12);
        if (red.node >= 0x8000u) return fail_grid();
        const Candidate cand{round_down(lb), static_cast<uint16_t>(k),
                             static_cast<uint16_t>(red.node | (red.neg ? 0x8000u : 0u))};
        if (q == 0) {
          cl.k0 = cand.k;
          cl.node0 = cand.node;
        } else {
          g_cand_.push_back(cand);
        }
      }
      cl.statics = static_cast<uint16_t>(order.size() - 1);
      // a moving obstacle whose lower bound over the cell exceeds ub is never nearest here
      // with its lower bound over the cell and all its poses, so a query can skip it
      // without computing lower_bound
      for (uint32_t k : moving_) {
        const double lb = cell_lower_bound(k, c, hd * (1.0 + 1e-6) + 1e-12);
        if (lb <= lim) g_cand_.push_back({round_down(lb), static_cast<uint16_t>(k), 0});
      }
      cl.moving = static_cast<uint16_t>(g_cand_.size() - cl.first - cl.statics);
    }
  }
}

std::pair<std::size_t, double> ObstacleField::grid_stats() const {
  const std::size_t cells = static_cast<std::size_t>(g_nx_) * g_ny_;
  std::size_t statics = 0;
  for (const Cell& c : g_cells_) statics += c.statics + 1u;
  return {cells, cells ? static_cast<double>(statics) / static_cast<double>(cells) : 0.0};
}

template <bool G>
Sdf ObstacleField::eval_at(const Obstacle& o, const Vec2& p, double t) const {
  switch (o.motion) {
    case MotionType::kStatic:
      return o.shape.eval<G>(p);
    case MotionType::kFlipper: {
      double c = 1.0, s = 0.0;
      o.timeline->value_cos_sin(t, c, s);
      const Rotation rot{c, s};
      Sdf r = o.shape.eval<G>(rot.apply_inverse(p - o.pivot));
      if constexpr (G) r.g = rot.apply(r.g);
      return r;
    }
    case MotionType::kSlider:
      return o.shape.eval<G>(p - o.timeline->value(t) * o.offset);
  }
  return {};
}

Nearest ObstacleField::nearest(const Vec2& p, double t) const { return nearest_impl<false>(p, t); }

Nearest ObstacleField::nearest_with_gradient(const Vec2& p, double t) const {
  return nearest_impl<true>(p, t);
}

// With G the candidates are evaluated with their gradients; the distances are the same
// bits either way (the gradient only adds to the evaluation), and so is the gradient
// kept: eval(k, p, t).g of the nearest.
template <bool G>
Nearest ObstacleField::nearest_impl(const Vec2& p, double t) const {
  Nearest best;
  auto offer = [&](uint32_t k, const Sdf& s) {
    if (s.d < best.d) {
      best.d = s.d;
      best.k = static_cast<int32_t>(k);
      if constexpr (G) best.g = s.g;
    }
  };
  auto offer_moving = [&](uint32_t k) {
    if (lower_bound(k, p) >= best.d) return;
    offer(k, eval_at<G>(obs_[k], p, t));
  };
  if (g_nx_ > 0) {
    const double fx = (p.x() - g_lo_.x()) * g_inv_, fy = (p.y() - g_lo_.y()) * g_inv_;
    if (fx >= 0.0 && fy >= 0.0 && fx < g_nx_ && fy < g_ny_) {
      const Cell cl = g_cells_[static_cast<std::size_t>(fy) * static_cast<std::size_t>(g_nx_) +
                               static_cast<std::size_t>(fx)];
      offer(cl.k0, obs_[cl.k0].shape.eval_reduced<G>(cl.node0 & 0x7FFFu, cl.node0 >> 15, p));
      const Candidate* c = g_cand_.data() + cl.first;
      for (const Candidate* e = c + cl.statics; c != e; ++c) {
        if (static_cast<double>(c->lb) >= best.d) {
          c = e;
          break;
        }
        offer(c->k, obs_[c->k].shape.eval_reduced<G>(c->node & 0x7FFFu, c->node >> 15, p));
      }
      // (no lower_bound here: the candidate's bound over the cell already prunes nearly
      // every pose that could, and skipping a bound never changes the result)
      for (const Candidate* e = c + cl.moving; c != e; ++c)
        if (static_cast<double>(c->lb) < best.d) offer(c->k, eval_at<G>(obs_[c->k], p, t));
      return best;
    }
  }
  for (uint32_t k : static_) offer(k, obs_[k].shape.eval<G>(p));
  for (uint32_t k : moving_) offer_moving(k);
  return best;
}

Sdf ObstacleField::eval(std::size_t k, const Vec2& p, double t) const {
  return eval_at<true>(obs_[k], p, t);
}

Vec2 ObstacleField::velocity(std::size_t k, const Vec2& p, double t) const {
  const Obstacle& o = obs_[k];
  switch (o.motion) {
    case MotionType::kStatic:
      return Vec2::Zero();
    case MotionType::kFlipper: {
      const double w = o.timeline->rate(t);  // omega x r = w (-ry, rx)
      const Vec2 r = p - o.pivot;
      return Vec2(-w * r.y(), w * r.x());
    }
    case MotionType::kSlider:
      return o.timeline->rate(t) * o.offset;
  }
  return Vec2::Zero();
}

double ObstacleField::speed_bound(std::size_t k, double t0, double t1, std::size_t& hint) const {
  const Obstacle& o = obs_[k];
  switch (o.motion) {
    case MotionType::kStatic:
      return 0.0;
    case MotionType::kFlipper:
      return o.timeline->max_rate(t0, t1, hint) * o.reach;
    case MotionType::kSlider:
      return o.timeline->max_rate(t0, t1, hint) * o.offset.norm();
  }
  return 0.0;
}

Vec2 ObstacleField::carry(std::size_t k, const Vec2& p, double t0, double t1) const {
  const Obstacle& o = obs_[k];
  switch (o.motion) {
    case MotionType::kStatic:
      return p;
    case MotionType::kFlipper: {
      const double a = o.timeline->value(t1) - o.timeline->value(t0);
      return o.pivot + Rotation::from_angle(a).apply(p - o.pivot);
    }
    case MotionType::kSlider:
      return p + (o.timeline->value(t1) - o.timeline->value(t0)) * o.offset;
  }
  return p;
}

// Moving obstacle k's SDF at any point within `rad` of c and any time: the poses are
// sampled at N midpoints of the flipper's angle range (slider's stroke); every pose is
// within reach * dtheta / 2 (|offset| / 2N) of a sample in Hausdorff distance, which bounds
// the change of the SDF, and the SDF is 1-Lipschitz in space.
double ObstacleField::cell_lower_bound(std::size_t k, const Vec2& c, double rad) const {
  const Obstacle& o = obs_[k];
  constexpr int kSamples = 32;
  double lb = HUGE_VAL, slack = 0.0;
  if (o.motion == MotionType::kFlipper) {
    const double lo = o.timeline->lo(), step = (o.timeline->hi() - lo) / kSamples;
    for (int i = 0; i < kSamples; ++i) {
      const double a = lo + (i + 0.5) * step;
      lb = std::min(lb, o.shape.eval<false>(Rotation::from_angle(a).apply_inverse(c - o.pivot)).d);
    }
    slack = o.reach * 0.5 * step;
  } else if (o.motion == MotionType::kSlider) {
    const double lo = o.timeline->lo(), step = (o.timeline->hi() - lo) / kSamples;
    for (int i = 0; i < kSamples; ++i)
      lb = std::min(lb, o.shape.eval<false>(c - (lo + (i + 0.5) * step) * o.offset).d);
    slack = o.offset.norm() * 0.5 * step;
  } else {
    return o.shape.eval<false>(c).d - rad;
  }
  // (1e-9 relative: rounding of the samples and the slack itself)
  lb -= slack * (1.0 + 1e-9) + rad + 1e-9 * std::abs(lb);
  return std::max(lb, lower_bound(k, c) - rad);
}

double ObstacleField::clearance_except(std::size_t k, const Vec2& p) const {
  double d = HUGE_VAL;
  for (uint32_t q : static_)
    if (q != k) d = std::min(d, obs_[q].shape.eval<false>(p).d);
  for (uint32_t q : moving_)
    if (q != k) d = std::min(d, lower_bound(q, p));
  return d;
}

double ObstacleField::lower_bound(std::size_t k, const Vec2& p) const {
  const Obstacle& o = obs_[k];
  double lb = -HUGE_VAL;
  if (o.motion == MotionType::kFlipper)
    lb = (p - o.pivot).norm() - o.reach;
  else if (o.motion == MotionType::kSlider)
    lb = o.sweep.distance(p);
  return lb > 0.0 ? lb : -HUGE_VAL;
}

}  // namespace pinsim::sdf
