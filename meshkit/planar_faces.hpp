// Planar face ids for meshes that arrive as bare triangles (PLY, glTF without
// raysweep extras): the tracer needs them to treat the two triangles of a wall
// as one reflecting surface.
#pragma once

#include <cstdint>
#include <vector>

#include "meshkit/scene.hpp"

namespace raysweep::meshkit {

// Per-triangle face ids, numbered first_id, first_id + 1, ... in order of the
// first triangle of each face. Triangles sharing an edge (vertices matched by
// position, so split seams still connect) whose normals agree within about
// 0.08 degrees get the same id; so do triangles with equal `seed` entries (for
// instance fans cut from one PLY polygon). `seed` may be empty.
std::vector<std::uint32_t> group_planar_faces(const std::vector<Vec3>& vertices,
                                              const std::vector<Tri>& triangles,
                                              std::uint32_t first_id,
                                              const std::vector<std::uint32_t>& seed = {});

}  // namespace raysweep::meshkit
