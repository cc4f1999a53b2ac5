// Hand-built geometry shared by the scene I/O tests.
#pragma once

#include "meshkit/scene.hpp"

namespace raysweep::test {

// Axis-aligned box as 12 outward triangles, two per planar face.
inline void add_box(meshkit::Mesh& m, meshkit::Vec3 lo, meshkit::Vec3 hi, std::uint32_t object,
                    std::uint32_t& next_face) {
  const auto base = static_cast<std::uint32_t>(m.vertices.size());
  for (int i = 0; i < 8; ++i)
    m.vertices.push_back({i & 1 ? hi[0] : lo[0], i & 2 ? hi[1] : lo[1], i & 4 ? hi[2] : lo[2]});
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.triangles.push_back({base + q[0], base + q[1], base + q[2]});
    m.triangles.push_back({base + q[0], base + q[2], base + q[3]});
    m.triangle_object.insert(m.triangle_object.end(), 2, object);
    m.triangle_face.insert(m.triangle_face.end(), 2, next_face++);
  }
}

}  // namespace raysweep::test
