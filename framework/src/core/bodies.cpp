#include "core/bodies.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include "core/input_error.hpp"
#include "core/json_read.hpp"
#include "core/value_limits.hpp"

namespace pinsim {

namespace {

using Eigen::Vector2d;

/// "file.json: bodies[1]" -> Loc{file.json, bodies[1]} in a scene.
Loc split_where(const std::string& where) {
  const auto c = where.find(": ");
  if (c == std::string::npos) return {where, "", true};
  return {where.substr(0, c), where.substr(c + 2), true};
}

/// The particle options every body shares.
struct ParticleOptions {
  double inv_mass = 1.0;
  double radius = 0.05;
  Vector2d velocity = Vector2d::Zero();
  bool all_pinned = false;
  std::set<uint64_t> pinned;  ///< local indices
};

/// Reads mass | total_mass, radius, velocity, pinned (bool) and pin (local indices), after
/// checking that `count` more particles than `out` has stay within the particle limit.
ParticleOptions read_particle_options(const nlohmann::json& spec, uint64_t count, const Loc& at,
                                      const ParticleList& out) {
  check_particle_count(out.size(), count, at);
  ParticleOptions o;
  if (spec.contains("mass") && spec.contains("total_mass"))
    (at / "total_mass").fail("give either mass (per particle) or total_mass, not both");
  double m = 1.0;
  if (spec.contains("total_mass"))
    m = read_number(spec, "total_mass", at) / static_cast<double>(count);
  else
    m = read_number_or(spec, "mass", 1.0, at);
  if (!(m > 0.0) || !std::isfinite(m))
    (at / (spec.contains("total_mass") ? "total_mass" : "mass"))
        .fail("must be > 0 (kg), got " + std::to_string(m));
  check_mass(m, at / (spec.contains("total_mass") ? "total_mass" : "mass"));
  o.inv_mass = 1.0 / m;
  o.radius = read_number_or(spec, "radius", 0.05, at);
  if (!(o.radius >= 0.0)) (at / "radius").fail("must be >= 0 (scene units)");
  check_radius(o.radius, at / "radius");
  o.velocity = read_vec2_or(spec, "velocity", Vector2d::Zero(), at);
  check_velocity(o.velocity, at / "velocity");
  o.all_pinned = read_bool_or(spec, "pinned", false, at);
  if (spec.contains("pin")) {
    const auto& p = spec["pin"];
    if (!p.is_array()) (at / "pin").fail("expected a list of particle indices, " + describe(p));
    for (std::size_t i = 0; i < p.size(); ++i) {
      if (!p[i].is_number_integer() || p[i].get<int64_t>() < 0 || p[i].get<uint64_t>() >= count)
        (at / "pin")[i].fail("expected a particle index 0.." + std::to_string(count - 1) + ", " +
                             describe(p[i]));
      o.pinned.insert(p[i].get<uint64_t>());
    }
  }
  return o;
}

uint32_t add_particle(ParticleList& out, const Vector2d& x, const ParticleOptions& o,
                      uint64_t local) {
  const bool pinned = o.all_pinned || o.pinned.count(local) > 0;
  return out.add(x, pinned ? Vector2d::Zero() : o.velocity, pinned ? 0.0 : o.inv_mass, o.radius);
}

void add_pair(ElementSet& s, uint32_t a, uint32_t b) { s.indices.insert(s.indices.end(), {a, b}); }
void add_triple(ElementSet& s, uint32_t a, uint32_t b, uint32_t c) {
  s.indices.insert(s.indices.end(), {a, b, c});
}

ElementSet particle_set(uint32_t first, uint32_t count) {
  ElementSet s{1, {}};
  for (uint32_t i = 0; i < count; ++i) s.indices.push_back(first + i);
  return s;
}

/// One variable-length element (arity 0) holding `particles` in order.
ElementSet whole_set(const std::vector<uint32_t>& particles) {
  ElementSet s{0, {}};
  s.add_whole(particles);
  return s;
}

/// All of a body's particles in storage order, as one element.
std::vector<uint32_t> all_of(uint32_t first, uint32_t count) {
  std::vector<uint32_t> p(count);
  for (uint32_t i = 0; i < count; ++i) p[i] = first + i;
  return p;
}

uint64_t read_count_min(const nlohmann::json& spec, const char* key, uint64_t def, uint64_t min,
                        const Loc& at) {
  const uint64_t n = read_count_or(spec, key, def, at);
  if (n < min || n > 1000000)
    (at / key).fail("must be between " + std::to_string(min) + " and 1000000, got " +
                    std::to_string(n));
  return n;
}

/// ring_blob: count particles on a circle, particle i at angle + 2 pi i / count
/// (counter-clockwise). With m = count and indices taken mod m, the sets are: particles (i);
/// edges (i, i+1) for i = 0..m-1, the last one (m-1, 0) closing the ring; triples
/// (i-1, i, i+1) for i = 0..m-1, the first (m-1, 0, 1); cross (i, i + m/2) for
/// i < m/2 if m is even, for every i if m is odd (m >= 4); shear (i, i+2) for every i
/// (m >= 5); boundary and body: one element, all particles in ring order (closed).
Body ring_blob(const nlohmann::json& spec, const Loc& at, ParticleList& out) {
  check_keys(spec,
             {"type", "name", "center", "ring_radius", "count", "cross", "shear", "mass",
              "total_mass", "radius", "velocity", "pinned", "pin", "angle"},
             at);
  const Vector2d c =
      read_vec2(spec.contains("center") ? spec["center"] : nlohmann::json(), at / "center");
  const double rr = read_number_or(spec, "ring_radius", 1.0, at);
  if (!(rr > 0.0)) (at / "ring_radius").fail("must be > 0 (scene units)");
  const uint64_t n = read_count_min(spec, "count", 16, 3, at);
  const double a0 = read_number_or(spec, "angle", 0.0, at);
  const ParticleOptions o = read_particle_options(spec, n, at, out);
  Body b;
  b.first = static_cast<uint32_t>(out.size());
  b.count = static_cast<uint32_t>(n);
  for (uint64_t i = 0; i < n; ++i) {
    const double th = a0 + 2.0 * M_PI * static_cast<double>(i) / static_cast<double>(n);
    add_particle(out, c + rr * Vector2d(std::cos(th), std::sin(th)), o, i);
  }
  const uint32_t f = b.first, m = b.count;
  auto g = [f, m](uint64_t i) { return f + static_cast<uint32_t>(i % m); };
  b.sets["particles"] = particle_set(f, m);
  ElementSet edges{2, {}}, tri{3, {}};
  for (uint32_t i = 0; i < m; ++i) {
    add_pair(edges, g(i), g(i + 1));
    add_triple(tri, g(i + m - 1), g(i), g(i + 1));
  }
  b.sets["edges"] = edges;
  b.sets["triples"] = tri;
  b.sets["boundary"] = whole_set(all_of(f, m));
  b.sets["body"] = b.sets["boundary"];
  if (read_bool_or(spec, "cross", true, at) && m >= 4) {
    ElementSet cross{2, {}};
    const uint32_t h = m / 2;
    for (uint32_t i = 0; i < (m % 2 == 0 ? h : m); ++i) add_pair(cross, g(i), g(i + h));
    b.sets["cross"] = cross;
  }
  if (read_bool_or(spec, "shear", true, at) && m >= 5) {
    ElementSet shear{2, {}};
    for (uint32_t i = 0; i < m; ++i) add_pair(shear, g(i), g(i + 2));
    b.sets["shear"] = shear;
  }
  return b;
}

/// grid_blob: nx by ny particles from origin (lower left), spacing apart, row by row:
/// particle (i, j) (column i, row j) has index j nx + i. Sets, visiting nodes row by row
/// (j outer, i inner) and per node in this order: edges (i,j)-(i+1,j) then (i,j)-(i,j+1);
/// shear (i,j)-(i+1,j+1) then (i+1,j)-(i,j+1); bend (i,j)-(i+2,j) then (i,j)-(i,j+2);
/// triples (i,j),(i+1,j),(i+2,j) then (i,j),(i,j+1),(i,j+2); particles (index order);
/// boundary: one element, the outline counter-clockwise from (0,0) along the bottom row,
/// up the right column, back along the top row and down the left column (closed);
/// body: one element, every particle in index order.
Body grid_blob(const nlohmann::json& spec, const Loc& at, ParticleList& out) {
  check_keys(spec,
             {"type", "name", "origin", "nx", "ny", "spacing", "mass", "total_mass", "radius",
              "velocity", "pinned", "pin"},
             at);
  const Vector2d o0 = read_vec2_or(spec, "origin", Vector2d::Zero(), at);
  const uint64_t nx = read_count_min(spec, "nx", 4, 2, at),
                 ny = read_count_min(spec, "ny", 4, 2, at);
  // the same bound on the particles of a grid as on those of any other body
  if (nx * ny > 1000000)
    (at / "ny").fail("nx * ny = " + std::to_string(nx * ny) +
                     " particles, more than the 1000000 a body may have");
  const double h = read_number_or(spec, "spacing", 0.1, at);
  if (!(h > 0.0)) (at / "spacing").fail("must be > 0 (scene units)");
  const ParticleOptions o = read_particle_options(spec, nx * ny, at, out);
  Body b;
  b.first = static_cast<uint32_t>(out.size());
  b.count = static_cast<uint32_t>(nx * ny);
  for (uint64_t j = 0; j < ny; ++j)
    for (uint64_t i = 0; i < nx; ++i)
      add_particle(out, o0 + h * Vector2d(static_cast<double>(i), static_cast<double>(j)), o,
                   j * nx + i);
  auto id = [&](uint64_t i, uint64_t j) { return b.first + static_cast<uint32_t>(j * nx + i); };
  ElementSet edges{2, {}}, shear{2, {}}, bend{2, {}}, tri{3, {}};
  for (uint64_t j = 0; j < ny; ++j)
    for (uint64_t i = 0; i < nx; ++i) {
      if (i + 1 < nx) add_pair(edges, id(i, j), id(i + 1, j));
      if (j + 1 < ny) add_pair(edges, id(i, j), id(i, j + 1));
      if (i + 1 < nx && j + 1 < ny) {
        add_pair(shear, id(i, j), id(i + 1, j + 1));
        add_pair(shear, id(i + 1, j), id(i, j + 1));
      }
      if (i + 2 < nx) {
        add_pair(bend, id(i, j), id(i + 2, j));
        add_triple(tri, id(i, j), id(i + 1, j), id(i + 2, j));
      }
      if (j + 2 < ny) {
        add_pair(bend, id(i, j), id(i, j + 2));
        add_triple(tri, id(i, j), id(i, j + 1), id(i, j + 2));
      }
    }
  std::vector<uint32_t> outline;  // counter-clockwise, each corner once
  for (uint64_t i = 0; i < nx; ++i) outline.push_back(id(i, 0));
  for (uint64_t j = 1; j < ny; ++j) outline.push_back(id(nx - 1, j));
  for (uint64_t i = nx - 1; i-- > 0;) outline.push_back(id(i, ny - 1));
  for (uint64_t j = ny - 1; j-- > 1;) outline.push_back(id(0, j));
  b.sets["particles"] = particle_set(b.first, b.count);
  b.sets["boundary"] = whole_set(outline);
  b.sets["body"] = whole_set(all_of(b.first, b.count));
  b.sets["edges"] = edges;
  b.sets["shear"] = shear;
  if (!bend.indices.empty()) b.sets["bend"] = bend;
  if (!tri.indices.empty()) b.sets["triples"] = tri;
  return b;
}

/// strand: a chain of count particles from root along direction, segment_length apart (or
/// length in total); the root is pinned (inverse mass 0) unless pin_root is false. Sets,
/// root first: particles (i); edges (i, i+1); triples (i, i+1, i+2); body: one element,
/// all particles from root to tip (an open chain: nothing joins the tip to the root).
Body strand(const nlohmann::json& spec, const Loc& at, ParticleList& out) {
  check_keys(spec,
             {"type", "name", "root", "direction", "count", "segment_length", "length", "pin_root",
              "mass", "total_mass", "radius", "velocity", "pinned", "pin"},
             at);
  const Vector2d root =
      read_vec2(spec.contains("root") ? spec["root"] : nlohmann::json(), at / "root");
  Vector2d d = read_vec2_or(spec, "direction", Vector2d(0, -1), at);
  if (!(d.norm() > 0.0)) (at / "direction").fail("must be a non-zero vector");
  d.normalize();
  const uint64_t n = read_count_min(spec, "count", 10, 2, at);
  if (spec.contains("segment_length") && spec.contains("length"))
    (at / "length").fail("give either segment_length or length, not both");
  const double seg = spec.contains("length")
                         ? read_number(spec, "length", at) / static_cast<double>(n - 1)
                         : read_number_or(spec, "segment_length", 0.1, at);
  if (!(seg > 0.0))
    (at / (spec.contains("length") ? "length" : "segment_length"))
        .fail("must be > 0 (scene units)");
  ParticleOptions o = read_particle_options(spec, n, at, out);
  if (read_bool_or(spec, "pin_root", true, at)) o.pinned.insert(0);
  Body b;
  b.first = static_cast<uint32_t>(out.size());
  b.count = static_cast<uint32_t>(n);
  for (uint64_t i = 0; i < n; ++i) add_particle(out, root + seg * static_cast<double>(i) * d, o, i);
  ElementSet edges{2, {}}, tri{3, {}};
  for (uint32_t i = 0; i + 1 < b.count; ++i) add_pair(edges, b.first + i, b.first + i + 1);
  for (uint32_t i = 0; i + 2 < b.count; ++i)
    add_triple(tri, b.first + i, b.first + i + 1, b.first + i + 2);
  b.sets["particles"] = particle_set(b.first, b.count);
  b.sets["body"] = whole_set(all_of(b.first, b.count));
  b.sets["edges"] = edges;
  if (!tri.indices.empty()) b.sets["triples"] = tri;
  return b;
}

using Builder = Body (*)(const nlohmann::json&, const Loc&, ParticleList&);
const std::vector<std::pair<std::string, Builder>>& builders() {
  static const std::vector<std::pair<std::string, Builder>> b = {
      {"ring_blob", &ring_blob}, {"grid_blob", &grid_blob}, {"strand", &strand}};
  return b;
}

}  // namespace

std::vector<std::string> body_types() {
  std::vector<std::string> out;
  for (const auto& [name, _] : builders()) out.push_back(name);
  return out;
}

Body build_body(const nlohmann::json& spec, const std::string& where, ParticleList& particles) {
  const Loc at = split_where(where);
  require_object(spec, at);
  const std::string type = read_string_or(spec, "type", "", at);
  for (const auto& [name, fn] : builders()) {
    if (name != type) continue;
    Body b = fn(spec, at, particles);
    b.type = type;
    b.name = read_string_or(spec, "name", type, at);
    return b;
  }
  std::string known;
  for (const auto& t : body_types()) known += (known.empty() ? "" : ", ") + t;
  (at / "type").fail("unknown body type '" + type + "' (known: " + known + ")");
}

}  // namespace pinsim
