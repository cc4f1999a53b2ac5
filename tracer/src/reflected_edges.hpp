// The reflection-diffraction combinations a source can reach: a static
// face, then a diffracting edge in its beam (the diffraction mechanism's
// and the radio-map solver's candidates; diffraction_path.hpp solves each).
#pragma once

#include <compare>
#include <cstdint>
#include <vector>

#include "search/face_index.hpp"
#include "search/visibility.hpp"
#include "tracer/solver.hpp"

namespace raysweep::tracer {

// A static face and a diffracting edge (index into TraceScene::edges())
// that a reflection on the face can reach from a source: the part of the
// edge in the face's beam (the pyramid from the source's image through its
// outline, on the source's side of the face, padded by the on-face
// tolerance), within `range` of the image, seen by the image from outside
// the wedge. A face in one of the wedge's planes is left out (the UTD
// coefficient's reflection terms hold it), and so is a face that one convex
// face hides whole from the source (hidden_by_convex_face), or the
// reflection points of the part alone.
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

// Every such combination from `src`, sorted (reflection-diffraction; from
// the other end, diffraction-reflection). With `only` (edge ids, sorted),
// just the combinations on those edges: the same entries, in the same
// order, as the whole list filtered to them. A pair uses only the edges its
// other end sees, and a source's partners see a small part of a city's
// edges: the walk then runs down a tree over those alone. With `slabs` (the
// source is their node `node`), a face whose bound is one or more is hidden
// whole (the face the bound counts lies across every segment to it, first
// in line or not), and the source's walls are tried on the parts first.
void reflected_edges(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, double range,
                     std::vector<ReflectedEdge>& out, const std::vector<std::uint32_t>* only = nullptr,
                     const SlabBounds* slabs = nullptr, std::uint32_t node = 0);

}  // namespace raysweep::tracer
