// What one convex static face hides: lower bounds on the slabs a leg
// between a node and a static face crosses (SlabBounds), and whether a face
// hides a set of points whole from a source (hidden_by_convex_face).
#pragma once

#include <cstdint>
#include <vector>

#include "search/face_index.hpp"
#include "tracer/solver.hpp"

namespace raysweep::tracer {

// Lower bounds on the slabs a leg between a node and a static face crosses:
// at(n, f) distinct convex static faces that every segment from node n to a
// point of f's convex outline crosses well inside them (the argument of
// hidden_by_convex_face below, for each face every ray to the outline's
// vertices crosses), counted up to cap + 1. exact_path counts every static
// face a leg crosses as a slab (or stops at an opaque one), so a sequence
// whose first leg from the source and last leg to the receiver together
// cross more than `cap` (TracerConfig::max_transmissions, 0 without
// refraction) is never a path: the static searches skip it. In an old town
// most faces lie behind buildings (Bad Hersfeld: 97 % of the candidates
// died at the two-slab cap). A source meets the same few walls (its own
// street's) face after face: the walls that counted for the faces before
// are tried on the next by their planes (crosses_deep, no ray), and the
// rays are cast only where those do not reach the cap. Either way a counted
// face lies across every segment, so the count is a lower bound.
struct SlabBounds {
  int cap = 0;
  std::uint32_t static_count = 0;
  std::vector<std::uint8_t> lb;  // node-major; nodes not asked for: 0
  // Per node, the convex faces that counted for the most static faces (at
  // most kWalls, most first): the walls that hide most of the city from it.
  static constexpr std::size_t kWalls = 16;
  std::vector<std::vector<std::uint32_t>> walls;
  int at(std::uint32_t node, std::uint32_t f) const { return lb[std::size_t{node} * static_count + f]; }
};
// For the nodes with `wanted` set.
SlabBounds slab_bounds(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                       const std::vector<char>& wanted, int cap);

// Whether one convex static face hides the convex hull of `points` (a
// face's outline, an edge's two ends) whole from `src`: the rays to every
// point first meet the same convex face (ImageFaces::convex; `skip`
// ignored), well inside it, with src and the points well apart from its
// plane (a margin over `tol`, the on-face tolerance of what is hidden). A
// point of the hull is a convex combination of the points, and the ray to
// it crosses the face's plane inside the convex hull of those hits (a
// central projection keeps convex hulls): every segment from src to the
// hull crosses that face. Exact, and conservative: false whenever unsure.
// With `walls` (SlabBounds::walls of the source), one of them that every
// segment crosses deep hides the points as well, whether or not the rays
// meet it first: tried by its plane before any ray is cast.
bool hidden_by_convex_face(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, const Vec3* points,
                           std::size_t count, const FaceRef* skip, double tol,
                           const std::vector<std::uint32_t>* walls = nullptr);

// hidden_by_convex_face for one source's many point sets (edges, parts of
// faces), the faces that hid the last ones tried first by their planes:
// neighbouring parts mostly hide behind the same few walls. The same
// answers as hidden_by_convex_face wherever that finds a face; where a
// recent face that is not first in line hides the points, true as well
// (every segment crosses it deep all the same).
class RecentBlockers {
 public:
  bool hidden(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, const Vec3* points,
              std::size_t count, const FaceRef* skip, double tol, const std::vector<std::uint32_t>* walls);

 private:
  static constexpr std::size_t kRecent = 4;
  std::vector<std::uint32_t> recent_;  // most recent first
};

}  // namespace raysweep::tracer
