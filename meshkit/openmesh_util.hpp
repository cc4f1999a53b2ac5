// OpenMesh in double precision with vertices welded by position: shared by
// the geometric segmentation and the LOD decimation.
#pragma once

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <array>
#include <map>

#include "meshkit/scene.hpp"

namespace raysweep::meshkit {

// Double precision: OpenMesh's default float points would move vertices by
// ~1e-7 m and break welding with the original geometry.
struct OpenMeshDoubleTraits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
  using Normal = OpenMesh::Vec3d;
};
using OMMesh = OpenMesh::TriMesh_ArrayKernelT<OpenMeshDoubleTraits>;

// OpenMesh reports every rejected (non-manifold) face on stderr; callers
// count and keep such faces themselves, so its messages are only noise.
inline void quiet_openmesh() {
  static const bool quiet = [] {
    omerr().disable();
    return true;
  }();
  (void)quiet;
}

// Adds triangles to an OpenMesh mesh, sharing vertices at equal positions.
class OpenMeshWelder {
 public:
  explicit OpenMeshWelder(OMMesh& mesh) : mesh_(mesh) { quiet_openmesh(); }

  // False when the face is degenerate after welding or OpenMesh refuses it
  // (non-manifold); `corners` holds its welded vertices either way.
  bool add(const Vec3& a, const Vec3& b, const Vec3& c, std::array<OMMesh::VertexHandle, 3>& corners) {
    const Vec3* p[3] = {&a, &b, &c};
    for (int k = 0; k < 3; ++k) {
      auto it = weld_.find(*p[k]);
      if (it == weld_.end()) it = weld_.emplace(*p[k], mesh_.add_vertex(OMMesh::Point((*p[k])[0], (*p[k])[1], (*p[k])[2]))).first;
      corners[k] = it->second;
    }
    if (corners[0] == corners[1] || corners[1] == corners[2] || corners[0] == corners[2]) return false;
    return mesh_.add_face(corners[0], corners[1], corners[2]).is_valid();
  }

 private:
  OMMesh& mesh_;
  std::map<Vec3, OMMesh::VertexHandle> weld_;
};

}  // namespace raysweep::meshkit
