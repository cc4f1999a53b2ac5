// Coarser static geometry for accuracy/cost studies (`raysweep tradeoff`):
// every object of a scene (a building, the ground, an imported mesh) is
// decimated on its own within a geometric error bound, whatever the scene
// came from (OSM extrusion or an imported Sionna/Mitsuba scene).
#pragma once

#include <cstddef>

#include "meshkit/scene.hpp"

namespace raysweep::meshkit {

struct SimplifyStats {
  std::size_t triangles_before = 0, triangles_after = 0;
  std::size_t objects_simplified = 0;  // objects that lost at least one triangle
};

// A copy of `scene` in which the triangles of each (mesh, object) are
// decimated (OpenMesh quadric decimater) as long as no collapse moves the
// surface by more than about `max_error_m` from the planes of the original
// triangles it replaces; open borders (the ground's edge, the rim of an
// imported facade) and faces OpenMesh cannot hold (non-manifold) are kept.
// Planar-face ids are regrouped per object (coplanar, connected triangles:
// group_planar_faces), unique in the result; objects, materials and mesh
// names stay. max_error_m <= 0 returns the scene unchanged.
Scene simplify_scene(const Scene& scene, double max_error_m, SimplifyStats* stats = nullptr);

}  // namespace raysweep::meshkit
