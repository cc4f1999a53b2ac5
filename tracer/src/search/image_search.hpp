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
// combinations the shoot-and-bounce rays' beams reach (BeamVehicle,
// search/beam_search.hpp): the rays sample a wall densely where they miss a
// small, far car's faces.
//   order 3, a wall, a vehicle and the ground in any order: from the same
//            (face, vehicle) combinations, the ground before or after the
//            vehicle (BeamVehicle);
//   a small static face first (a kerb-side box, a corner strip): its beam's
//            vehicles and second faces exactly, without the rays;
//   order 3 beginning on a static face: the lit beam pairs of the rays
//            (BeamPair, search/beam_search.hpp), their third faces
//            exactly.
//   orders 2 and 3 on one vehicle (its concave corners, its cabin through
//            the windows): the sequences the model's table lists for the
//            direction the wave arrives from (TraceScene::
//            vehicle_bounce_sequences), each decided by images and on-face
//            tests.
// Other vehicle-vehicle sequences and orders >= 3 come from shoot-and-bounce
// (tracer/src/shoot/), merged with these.
#pragma once

#include <cstdint>
#include <vector>

#include "search/face_index.hpp"
#include "search/visibility.hpp"
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

// True when the image search enumerates every sequence of this kind
// (order 1; order 2 of static faces, or of the ground and a vehicle; with
// `ground_order3` (the search ran with it, at order 3) three static faces
// of which one or more is the ground).
bool image_complete(const TraceScene& scene, const ImageFaces& faces, const std::vector<FaceRef>& sequence,
                    bool ground_order3 = false);

// What image_candidates searches beyond order 1 (everything by default).
struct ImageSearchOptions {
  // Orders 2 and 3 on one vehicle, from its model's table
  // (TracerConfig::vehicle_multi_bounce).
  bool multi_bounce = true;
  // Order 3 among static faces with one on the ground (TracerConfig::
  // ground_order3), with static_pairs.
  bool ground_order3 = true;
  // No static sequence whose legs these bounds put over their cap (null:
  // no bounds).
  const SlabBounds* slabs = nullptr;
};

// Face sequences of order 1..max_order (at most 3: on one vehicle, or
// static faces with one on the ground) from node `src` to each node in
// `receivers` (sorted; lower and higher indices) whose reflection points lie
// on their faces. Sequences that are their own reverse's counterpart (order
// 1, static-static, static-ground-static) are searched towards higher
// receivers only; ground-vehicle and static-static-ground sequences towards
// all, so that the other end's search yields vehicle-ground and
// ground-static-static. Deterministic: the output depends only on the scene
// and the nodes. What it searches beyond order 1: ImageSearchOptions.
void image_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                      std::uint32_t src, const std::vector<std::uint32_t>& receivers, int max_order,
                      std::vector<ImageCandidate>& out, const ImageSearchOptions& options = {},
                      ImageSearchStats* stats = nullptr);

}  // namespace raysweep::tracer
