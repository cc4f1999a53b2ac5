// The frame's faces as the candidate searches index them (ImageFaces),
// built once per snapshot and shared by every source: planes, bounding
// spheres and on-face tolerances, the ground and its planes, the small
// static faces, the static faces' convex outlines, and sphere trees over
// the static faces and over the diffracting edges.
#pragma once

#include <cstdint>
#include <type_traits>
#include <vector>

#include "tracer/solver.hpp"

namespace raysweep::tracer {

// Every face of the current frame in world coordinates: built once per
// snapshot and shared by all sources.
struct ImageFaces {
  std::vector<FaceRef> refs;  // static faces first (instance 0), then each vehicle's
  std::vector<Plane> planes;
  std::vector<TraceScene::Sphere> spheres;
  std::vector<double> tol;    // border tolerance of the on-face test
  std::uint32_t static_count = 0;
  std::vector<std::uint32_t> vehicle_begin;  // first face of vehicle v in refs (size vehicles + 1)
  std::vector<TraceScene::Sphere> vehicle_spheres;
  // The vehicles' faces' spheres and tolerances (from vehicle_begin[0]), then
  // the vehicles' own spheres (tolerance 0), in structure-of-arrays form for
  // the beams' vectorised tests.
  struct SphereColumns {
    std::vector<double> x, y, z, r, tol;
  } beam_spheres;
  std::uint32_t beam_vehicles_begin = 0;  // where the vehicles' spheres start in beam_spheres
  std::vector<std::uint32_t> ground;         // static faces that are ground (TraceScene::is_ground)
  // The ground faces by plane (bitwise the same plane, either orientation:
  // a ground split into patches, building floors at its level): one mirror
  // image per receiver and one mirrored beam serve every face of a plane.
  struct GroundPlane {
    Plane plane;                        // its first face's
    std::vector<std::uint32_t> faces;   // ascending
    std::vector<signed char> flipped;   // per face: its normal is -plane.normal
  };
  std::vector<GroundPlane> ground_planes;
  // Static faces of vehicle size or less (bounding radius under kSmallFace:
  // a kerb-side box, a bus shelter's side): shoot and bounce's rays pass
  // them as they pass vehicles, so BeamPair marks them by the same widened
  // test, not only when a ray hits them.
  static constexpr double kSmallFace = 2.5;
  std::vector<std::uint32_t> small;
  // Static faces' convex outlines (world vertices, in order around the
  // face): the beam a face reflects is the pyramid from the image through it.
  std::vector<std::uint32_t> outline_begin;  // static faces + 1
  std::vector<Vec3> outline;
  // Per outline vertex k: the unit normal, in the face's plane and pointing
  // inwards, of the outline's side from vertex k to the next (a point's
  // distance inside that side is its dot with p - outline[k]).
  std::vector<Vec3> outline_inward;
  std::vector<char> convex;  // per static face: its triangles fill its convex outline
  // Static faces' distinct vertices (CSR) and, per face, how far off its
  // plane a vertex must lie to count as off it (its flatness): for
  // face_reaches, asked per candidate (a table over every pair of faces
  // grows as the faces squared: 0.8 s and 27 MB more peak memory for the
  // 1.2 km town box; about 2 GB at nine times its faces).
  std::vector<std::uint32_t> vertex_begin;
  std::vector<Vec3> vertices;
  std::vector<double> off_plane;
  // A bounding-sphere tree over the static faces (depth-first; a node's
  // left child follows it): the order-2 search culls whole groups of second
  // faces against the first face's beam instead of testing each.
  struct SphereNode {
    TraceScene::Sphere sphere;
    double tol = 0;               // the largest on-face tolerance below
    std::uint32_t right = 0;      // inner node: its right child
    std::uint32_t begin = 0, count = 0;  // leaf (count > 0): static_order[begin, begin + count)
  };
  std::vector<SphereNode> static_tree;
  std::vector<std::uint32_t> static_order;
  // The diffracting edges (TraceScene::edges()): bounding spheres and the
  // same kind of tree over them.
  std::vector<TraceScene::Sphere> edge_spheres;
  std::vector<SphereNode> edge_tree;
  std::vector<std::uint32_t> edge_order;
};

// The current frame's faces (SnapshotPlan::faces() builds them once per
// snapshot).
ImageFaces image_faces(const TraceScene& scene);

// Whether static face g has a vertex strictly on the `side` (> 0: front,
// < 0: back) of static face f's plane (beyond f's flatness): the only faces
// a path reflected by f can go on to. False for g == f. g's bounding sphere
// answers when it clears that band by more than the rounding of these dot
// products (then every vertex agrees); otherwise each vertex does.
inline bool face_reaches(const ImageFaces& faces, std::uint32_t f, int side, std::uint32_t g) {
  if (g == f) return false;
  const Plane& p = faces.planes[f];
  const double eps = faces.off_plane[f];
  const double sgn = side > 0 ? 1 : -1;
  const TraceScene::Sphere& b = faces.spheres[g];
  const double hc = sgn * (dot(p.normal, b.centre) - p.offset);
  constexpr double kRounding = 1e-6;
  if (hc - b.radius > eps + kRounding) return true;
  if (hc + b.radius < eps - kRounding) return false;
  for (std::uint32_t k = faces.vertex_begin[g]; k < faces.vertex_begin[g + 1]; ++k)
    if (sgn * (dot(p.normal, faces.vertices[k]) - p.offset) > eps) return true;
  return false;
}

// Builds a sphere tree over items order[b, e) (spheres[i], tol[i]) into
// `tree`: median split on the longest axis of the spheres' box, four items
// per leaf. Each node's sphere holds its items' spheres; its tol is their
// largest.
void build_sphere_tree(const std::vector<TraceScene::Sphere>& spheres, const std::vector<double>& tols,
                       std::vector<ImageFaces::SphereNode>& tree, std::vector<std::uint32_t>& order, std::uint32_t b,
                       std::uint32_t e);

// Depth-first down a sphere tree (`order` its items): prune(sphere, tol)
// true skips a node and everything below it (its sphere and tol bound
// theirs); leaf(i) for each item of the leaves reached, in the tree's order.
// A prune that also takes the node's index (sphere, tol, index) can look up
// what the caller keeps per node.
template <class Prune, class Leaf>
void walk_tree(const std::vector<ImageFaces::SphereNode>& tree, const std::vector<std::uint32_t>& order,
               std::vector<std::uint32_t>& stack, Prune&& prune, Leaf&& leaf) {
  if (tree.empty()) return;
  stack.assign(1, 0);
  while (!stack.empty()) {
    const std::uint32_t at = stack.back();
    stack.pop_back();
    const auto& node = tree[at];
    if constexpr (std::is_invocable_v<Prune&, const TraceScene::Sphere&, double, std::uint32_t>) {
      if (prune(node.sphere, node.tol, at)) continue;
    } else if (prune(node.sphere, node.tol)) {
      continue;
    }
    if (node.count == 0) {
      stack.push_back(node.right);
      stack.push_back(at + 1);
      continue;
    }
    for (std::uint32_t k = node.begin; k < node.begin + node.count; ++k) leaf(order[k]);
  }
}
template <class Prune, class Leaf>
void walk_static_tree(const ImageFaces& faces, std::vector<std::uint32_t>& stack, Prune&& prune, Leaf&& leaf) {
  walk_tree(faces.static_tree, faces.static_order, stack, prune, leaf);
}

}  // namespace raysweep::tracer
