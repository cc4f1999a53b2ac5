// Hand-built geometry and scene comparisons shared by the scene I/O tests.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

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

// Everything but vertex positions must survive exactly; positions within tol
// per coordinate, compared per triangle corner so a vertex reordering by the
// codec could not hide or fake anything.
inline void expect_same_scene(const meshkit::Scene& a, const meshkit::Scene& b, const std::vector<double>& tol) {
  ASSERT_EQ(a.objects.size(), b.objects.size());
  for (std::size_t i = 0; i < a.objects.size(); ++i) {
    EXPECT_EQ(a.objects[i].kind, b.objects[i].kind);
    EXPECT_EQ(a.objects[i].source_id, b.objects[i].source_id);
  }
  ASSERT_EQ(a.meshes.size(), b.meshes.size());
  for (std::size_t i = 0; i < a.meshes.size(); ++i) {
    const meshkit::Mesh& x = a.meshes[i];
    const meshkit::Mesh& y = b.meshes[i];
    SCOPED_TRACE(x.name);
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.material, y.material);
    EXPECT_EQ(x.triangle_object, y.triangle_object);
    EXPECT_EQ(x.triangle_face, y.triangle_face);
    ASSERT_EQ(x.triangles.size(), y.triangles.size());
    double worst = 0;
    for (std::size_t t = 0; t < x.triangles.size(); ++t)
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k)
          worst = std::max(worst, std::abs(x.vertices[x.triangles[t][c]][k] - y.vertices[y.triangles[t][c]][k]));
    EXPECT_LE(worst, tol[i]) << "mesh " << x.name;
  }
}

}  // namespace raysweep::test
