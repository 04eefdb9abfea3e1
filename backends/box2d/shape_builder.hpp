// ShapeBuilder: turns one obstacle's shape, as the one obstacle reader (sdf::ShapeTree,
// inside sdf::ObstacleField) compiled and validated it, into Box2D-expressible pieces in
// scene units, in the obstacle's own frame: circles, convex polygons of at most
// b2_maxPolygonVertices (concave polygons decomposed), capsule edges and chains. Features Box2D
// cannot express are errors naming the obstacle, the JSON path and the feature.
#pragma once

#include <pinsim/plugin.hpp>
#include <pinsim/scene_field/shape.hpp>
#include <pinsim/transform.hpp>
#include <string>
#include <vector>

namespace pinsim::box2d {

/// One Box2D shape, scene units, obstacle frame.
struct Piece {
  enum class Kind { kCircle, kPolygon, kEdge, kChainLoop, kChain };
  Kind kind = Kind::kCircle;
  std::vector<Vec2> v;  ///< circle: {centre}; polygon: counter-clockwise convex (<= 8);
                        ///< edge: {a, b}; chain: vertices, the solid on the left
  double radius = 0.0;  ///< circle radius; rounding radius of a polygon or edge (capsule)
  Vec2 ghost0{0.0, 0.0}, ghost1{0.0, 0.0};  ///< kChain: vertices before the first / after the last
  bool one_sided = false;                   ///< kEdge: collides on the right of a->b only
};

struct BuildOptions {
  int curve_segments = 0;  ///< segments per full circle for curved container walls (0: error)
  double half_plane_extent = 1e3;  ///< half-planes become one-sided edges this long each way
  Vec2 centre{0.0, 0.0};           ///< where half-plane edges are centred (the scene's middle)
};

/// Builds the pieces of obstacle `id` from its shape tree, whose JSON path is `path`
/// (e.g. "obstacles[3].shape"); throws pinsim::Error "ctx: path: ... unsupported by box2d".
std::vector<Piece> build_pieces(const sdf::ShapeTree& shape, const std::string& ctx,
                                const std::string& path, const std::string& id,
                                const BuildOptions& opt);

/// Splits a simple counter-clockwise polygon into convex counter-clockwise pieces of at most
/// `max_vertices` vertices (ear clipping, then Hertel-Mehlhorn merging of triangles).
std::vector<std::vector<Vec2>> convex_decompose(const std::vector<Vec2>& ccw, int max_vertices);

/// True if the counter-clockwise polygon is strictly convex (no reflex vertex).
bool is_convex(const std::vector<Vec2>& ccw);

}  // namespace pinsim::box2d
