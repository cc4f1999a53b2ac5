// OpenMesh in double precision with vertices welded by position: shared by
// the geometric segmentation and the LOD decimation.
#pragma once

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <array>
#include <map>
#include <vector>

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

// A triangle soup welded into OpenMesh for decimation, with status and face
// normals requested. Faces OpenMesh cannot hold (non-manifold) stay out as
// they are (`kept`, over `kept_vertices`); their corners are `pinned`, since
// moving them would orphan those faces.
struct WeldedMesh {
  OMMesh mesh;
  std::vector<Vec3> kept_vertices;
  std::vector<Tri> kept;
  std::vector<OMMesh::VertexHandle> pinned;

  WeldedMesh(const std::vector<Vec3>& vertices, const std::vector<Tri>& triangles) {
    OpenMeshWelder welder(mesh);
    for (const auto& t : triangles) {
      std::array<OMMesh::VertexHandle, 3> vh;
      if (!welder.add(vertices[t[0]], vertices[t[1]], vertices[t[2]], vh)) {
        for (auto h : vh) pinned.push_back(h);
        const auto base = static_cast<std::uint32_t>(kept_vertices.size());
        for (auto v : t) kept_vertices.push_back(vertices[v]);
        kept.push_back({base, base + 1, base + 2});
      }
    }
    mesh.request_vertex_status();
    mesh.request_edge_status();
    mesh.request_face_status();
    mesh.request_face_normals();
    mesh.update_face_normals();
  }
};

}  // namespace raysweep::meshkit
