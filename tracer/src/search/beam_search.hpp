// The beam searches: the combinations the shoot-and-bounce rays show lit
// (a static face and a vehicle, BeamVehicle; a static face and a second
// face, BeamPair) and those a small static face's beam holds, each then
// enumerated exactly by images, vectorised passes over the receivers and
// on-face tests.
#pragma once

#include <compare>
#include <cstdint>
#include <vector>

#include "search/face_index.hpp"
#include "search/image_search.hpp"
#include "search/visibility.hpp"

namespace raysweep::tracer {

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
// exactly through the vehicle's normals (search/image_search.hpp) (towards every receiver:
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
struct BeamVehicleOptions {
  bool with_ground = false;
  BeamVehicleMethod method = BeamVehicleMethod::cheaper;
};
void beam_vehicle_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                             std::uint32_t src, const std::vector<std::uint32_t>& receivers,
                             const std::vector<BeamVehicle>& combos, std::vector<ImageCandidate>& out,
                             const BeamVehicleOptions& options = {}, ImageSearchStats* stats = nullptr);

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
// with a ground face (image_candidates' ground_order3 has them). With
// `slabs` (every receiver's bounds), not the sequences whose first leg and
// last leg to a static third face cross more slabs than the cap: no path
// (SlabBounds).
void beam_pair_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                          std::uint32_t src, const std::vector<BeamPair>& beam_pairs,
                          const std::vector<std::uint32_t>& receivers, std::vector<ImageCandidate>& out,
                          ImageSearchStats* stats = nullptr, bool skip_ground = false,
                          const SlabBounds* slabs = nullptr);

}  // namespace raysweep::tracer
