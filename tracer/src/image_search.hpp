// Exact candidate search by the image method (no sampling).
//
// A specular path exists only where every reflection point lies on its face,
// so enumerating image sources and testing where the unfolded line meets each
// face yields a superset of the exact paths of that order; compute_path then
// decides each candidate exactly (occlusion, slabs, the transmission cap).
// Nothing is sampled, so no face is missed for being small or far away:
//   order 1: every face of the scene, static and vehicles;
//   order 2: every pair of static faces (walls, roofs, ground; few and large),
//            pruned by side tests and the beam each first face reflects.
//   order 2: every ground face (large horizontal static faces) with every
//            vehicle face, in both orders (a car body's ground bounce).
//   order 3, two static faces and the ground (ground_order3): once per
//            ground plane (ImageFaces::ground_planes), each face of it
//            tested at the one reflection point.
// Vehicle faces are found through their normals: a vehicle reflects from
// `a` to `b` only on faces whose normal lies within the angle its bounding
// sphere subtends from both ends of the bisector of the two directions.
// Any other static face with any vehicle (a wall's echo off a car, the
// antenna's own included) is enumerated the same way for the (face, vehicle)
// combinations the shoot-and-bounce rays' beams reach (BeamVehicle, below):
// the rays sample a wall densely where they miss a small, far car's faces.
//   order 3, a wall, a vehicle and the ground in any order: from the same
//            (face, vehicle) combinations, the ground before or after the
//            vehicle (BeamVehicle, below);
//   a small static face first (a kerb-side box, a corner strip): its beam's
//            vehicles and second faces exactly, without the rays;
//   order 3 beginning on a static face: the lit beam pairs of the rays
//            (BeamPair, below), their third faces exactly.
//   orders 2 and 3 on one vehicle (its concave corners, its cabin through
//            the windows): the sequences the model's table lists for the
//            direction the wave arrives from (TraceScene::
//            vehicle_bounce_sequences), each decided by images and on-face
//            tests.
// Other vehicle-vehicle sequences and orders >= 3 come from shoot-and-bounce
// (solver.cpp), merged with these.
#pragma once

#include <compare>
#include <cstdint>
#include <vector>

#include "tracer/solver.hpp"

namespace raysweep::tracer {

struct ImageCandidate {
  std::uint32_t rx = 0;
  std::vector<FaceRef> faces;  // in order from the source
};

struct ImageSearchStats {
  std::uint64_t image_sources = 0;  // images built (order 1 and 2)
  std::uint64_t tests = 0;          // (image, receiver) pairs tested against a face
};

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
  std::vector<char> convex;  // per static face: its triangles fill its convex outline
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
// True when the image search enumerates every sequence of this kind
// (order 1; order 2 of static faces, or of the ground and a vehicle; with
// `ground_order3` (the search ran with it, at order 3) three static faces
// of which one or more is the ground).
bool image_complete(const TraceScene& scene, const ImageFaces& faces, const std::vector<FaceRef>& sequence,
                    bool ground_order3 = false);
ImageFaces image_faces(const TraceScene& scene);

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
// died at the two-slab cap).
struct SlabBounds {
  int cap = 0;
  std::uint32_t static_count = 0;
  std::vector<std::uint8_t> lb;  // node-major; nodes not asked for: 0
  int at(std::uint32_t node, std::uint32_t f) const { return lb[std::size_t{node} * static_count + f]; }
};
// For the nodes with `wanted` set.
SlabBounds slab_bounds(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                       const std::vector<char>& wanted, int cap);

// Face sequences of order 1..max_order (at most 3: on one vehicle, or
// static faces with one on the ground) from node `src` to each node in
// `receivers` (sorted; lower and higher indices) whose reflection points lie
// on their faces. Sequences that are their own reverse's counterpart (order
// 1, static-static, static-ground-static) are searched towards higher
// receivers only; ground-vehicle and static-static-ground sequences towards
// all, so that the other end's search yields vehicle-ground and
// ground-static-static. Deterministic: the output depends only on the scene
// and the nodes. Without `static_pairs`, no sequence of two or more static
// faces (the vehicles' own: tracer/coherence.hpp's per-frame pass). With
// `slabs`, no static sequence whose legs it puts over its cap.
void image_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                      std::uint32_t src, const std::vector<std::uint32_t>& receivers, int max_order,
                      std::vector<ImageCandidate>& out, ImageSearchStats* stats = nullptr, bool multi_bounce = true,
                      bool ground_order3 = true, bool static_pairs = true, const SlabBounds* slabs = nullptr);

// A static face and a vehicle the shoot-and-bounce rays of one source reach
// in that order (a ray reflected by the face passes within the vehicle's
// sphere, widened by the ray spacing): where a wall's echo off a
// vehicle can exist. Rays sample a wall's beam densely even where they
// miss every face of a small, far vehicle.
struct BeamVehicle {
  std::uint32_t face = 0;     // static face (index into ImageFaces' static faces)
  std::uint32_t vehicle = 0;
  auto operator<=>(const BeamVehicle&) const = default;
};

// The order-2 sequences (static face f, any face of vehicle v) of every
// listed combination from node `src` to each of `receivers`, enumerated
// exactly through the vehicle's normals as above (towards every receiver:
// from the other end they read vehicle then static face). With
// `with_ground` also the order-3 sequences (f, ground, v) and (f, v,
// ground) of the same combinations: a horizontal ground bends f's beam up
// or down without moving it sideways.
// Two exact enumerations give the same candidates: per vehicle face and
// kind of path, an image and a vectorised pass over the receivers
// (`passes`), or per receiver a lookup in the vehicle's normal table
// (`lookups`); `cheaper` takes, per combination, the one its cost estimate
// favours.
enum class BeamVehicleMethod { cheaper, passes, lookups };
void beam_vehicle_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                             std::uint32_t src, const std::vector<std::uint32_t>& receivers,
                             const std::vector<BeamVehicle>& combos, std::vector<ImageCandidate>& out,
                             ImageSearchStats* stats = nullptr, bool with_ground = false,
                             BeamVehicleMethod method = BeamVehicleMethod::cheaper);

// The combinations (small static face, vehicle) that can exist from `src`,
// exactly: every vehicle in the cone from the source's image through the
// face (a strip of a building's corner, a kerb-side box: the rays reflect on
// it too seldom to show which vehicles its beam reaches). Appended to
// `combos` (unsorted).
void small_face_beams(const ImageFaces& faces, const Vec3& src, std::vector<BeamVehicle>& combos);

// A static face, then a face (static or a vehicle's) that the shoot-and-
// bounce rays of one source reflect on in that order, or a small static face
// they pass after the first: a beam the rays show is lit. Its third
// reflections, which the rays' reception spheres miss (a wall's double echo
// arriving at grazing angles, the small faces of a far car, a third wall
// the vehicles hide from most of the beam's rays), are then enumerated
// exactly.
struct BeamPair {
  std::uint32_t f1 = 0;  // a static face
  std::uint32_t f2 = 0;  // a static face, or a vehicle face (ImageFaces' indices)
  auto operator<=>(const BeamPair&) const = default;
};

// The pairs (small static face, static face in its beam) from `src`,
// exactly: the rays seldom reflect on a small face at all (a kerb-side box
// at 50 m falls between them), so what its beam lights is taken from the
// geometry. Appended to `pairs` (unsorted).
void small_face_pairs(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, std::vector<BeamPair>& pairs);

// The order-3 sequences (f1, f2, f3) of every listed pair from node `src`
// to each of `receivers`: every static face f3 in the beam after f2 (apex
// the source's second image; the pyramid through f2's outline, or for a
// vehicle face the cone through its sphere, inside f1's pyramid mirrored in
// f2; walked down the static sphere tree) and, after a static f2, every
// vehicle face in it, each decided by its image, a vectorised pass over the
// receivers and on-face tests. With `skip_ground`, not the static triples
// with a ground face (image_candidates' ground_order3 has them).
void beam_pair_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                          std::uint32_t src, const std::vector<BeamPair>& beam_pairs,
                          const std::vector<std::uint32_t>& receivers, std::vector<ImageCandidate>& out,
                          ImageSearchStats* stats = nullptr, bool skip_ground = false);

// A static face and a diffracting edge (index into TraceScene::edges())
// that a reflection on the face can reach from a source: the part of the
// edge in the face's beam (the pyramid from the source's image through its
// outline, on the source's side of the face, padded by the on-face
// tolerance), within `range` of the image, seen by the image from outside
// the wedge. A face in one of the wedge's planes is left out (the UTD
// coefficient's reflection terms hold it), and so is a face that one convex
// face hides whole from the source (hidden_by_convex_face).
struct ReflectedEdge {
  std::uint32_t face = 0;
  std::uint32_t edge = 0;
  double z0 = 0, z1 = 0;  // the part in the beam: edge.a + z edge.e, z0 <= z <= z1
  double zt = 0, rt = 0;  // the image's coordinate along the edge, its distance from the edge's line
  // Whether Keller's point between the image and a point at coordinate z
  // along the edge, r from its line, lies on the part in the beam (the
  // cheap per-pair filter before the exact path).
  bool keller_on_part(double z, double r) const {
    const double zq = (zt * r + z * rt) / (rt + r);
    return zq >= z0 && zq <= z1;
  }
  auto operator<=>(const ReflectedEdge&) const = default;
};
// Whether one convex static face hides the convex hull of `points` (a
// face's outline, an edge's two ends) whole from `src`: the rays to every
// point first meet the same convex face (ImageFaces::convex; `skip`
// ignored), well inside it, with src and the points well apart from its
// plane (a margin over `tol`, the on-face tolerance of what is hidden). A
// point of the hull is a convex combination of the points, and the ray to
// it crosses the face's plane inside the convex hull of those hits (a
// central projection keeps convex hulls): every segment from src to the
// hull crosses that face. Exact, and conservative: false whenever unsure.
bool hidden_by_convex_face(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, const Vec3* points,
                           std::size_t count, const FaceRef* skip, double tol);

// Every such combination from `src`, sorted (reflection-diffraction; from
// the other end, diffraction-reflection). With `only` (edge ids, sorted),
// just the combinations on those edges: the same entries, in the same
// order, as the whole list filtered to them. A pair uses only the edges its
// other end sees, and a source's partners see a small part of a city's
// edges: the walk then runs down a tree over those alone.
void reflected_edges(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, double range,
                     std::vector<ReflectedEdge>& out, const std::vector<std::uint32_t>* only = nullptr);

}  // namespace raysweep::tracer
