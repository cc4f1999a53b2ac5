// The marks one source's rays leave for the beam searches
// (search/beam_search.hpp) and for the next round of vehicle bundles.
#pragma once

#include <cstdint>
#include <vector>

#include "shoot/ray.hpp"
#include "shoot/shoot.hpp"

namespace raysweep::tracer {

class BeamMarks {
 public:
  // `spacing`: the rays' angular spacing; a null list takes no marks.
  BeamMarks(const ImageFaces* faces, const std::vector<Node>& nodes, std::uint32_t src, double spacing,
            std::vector<BeamVehicle>* beams, std::vector<BeamPair>* beam_pairs,
            std::vector<BeamVehicle>* bundle_marks);

  // The beams segment [0, seg_end] of st lies in.
  void note_beams(const RayState& st, const std::vector<Link>& chain, double seg_end);
  bool bundle_marks() const { return bundle_marks_ != nullptr; }
  // A bundle ray reflected once, on a vehicle's face: the other vehicles
  // it passes (within its bundle's spacing) are in that face's beam, and
  // get a bundle of their own through the face (a car's echo off a car).
  // (`bundle_spacing`: the ray's bundle's own spacing.)
  void note_bundle_marks(const RayState& st, const std::vector<Link>& chain, double seg_end, double bundle_spacing);
  // Beams and beam pairs sorted, once per task.
  void finish();

 private:
  // Whether the segment [0, seg_end] of st passes within `radius` of
  // `centre`, widened by twice the ray spacing at that distance (what it may
  // miss between rays: a vehicle, a small face).
  bool passes(const RayState& st, double seg_end, const Vec3& centre, double radius) const {
    return passes(st, seg_end, centre, radius, spacing_);
  }
  bool passes(const RayState& st, double seg_end, const Vec3& centre, double radius, double spacing) const {
    const Vec3 c = centre - st.o;
    const double t = std::clamp(dot(c, st.d), 0.0, seg_end);
    const Vec3 q = c - t * st.d;
    const double reach = radius + 2 * spacing * (st.len + t);
    return dot(q, q) <= reach * reach;
  }

  const ImageFaces* beam_faces_;
  const std::vector<Node>& nodes_;
  const std::uint32_t src_;
  const double spacing_;
  std::vector<BeamVehicle>* beams_;
  std::vector<BeamPair>* beam_pairs_;
  std::vector<BeamVehicle>* bundle_marks_;
};

}  // namespace raysweep::tracer
