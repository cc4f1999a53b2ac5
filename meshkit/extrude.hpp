// Footprint -> closed prism: floor at `base`, roof at `top`, one wall quad per
// boundary edge, all outward-facing. Planar face ids: one for the roof, one for
// the floor, one per wall plane (collinear wall edges share it).
#pragma once

#include <cstdint>

#include "meshkit/footprint.hpp"
#include "meshkit/scene.hpp"

namespace raysweep::meshkit {

struct ExtrudeStats {
  std::size_t triangles = 0;
  std::size_t faces = 0;  // planar faces
};

// Appends the prism to `mesh`, tagging triangles with `object` and consuming
// planar face ids from `next_face`.
ExtrudeStats extrude_footprint(const Footprint& footprint, double base, double top, std::uint32_t object,
                               std::uint32_t& next_face, Mesh& mesh);

}  // namespace raysweep::meshkit
