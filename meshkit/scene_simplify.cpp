#include "meshkit/scene_simplify.hpp"

#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModHausdorffT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <map>

#include "meshkit/openmesh_util.hpp"
#include "meshkit/planar_faces.hpp"

namespace raysweep::meshkit {

namespace {

struct Piece {
  std::vector<Vec3> vertices;
  std::vector<Tri> triangles;
};

// Decimates one object's triangles; returns false (piece untouched) when
// nothing could be removed.
bool decimate(Piece& piece, double max_error_m) {
  if (piece.triangles.size() < 4) return false;
  WeldedMesh welded(piece.vertices, piece.triangles);
  OMMesh& mesh = welded.mesh;
  const auto& kept_vertices = welded.kept_vertices;
  const auto& kept = welded.kept;
  const auto& pinned = welded.pinned;
  // Open borders stay where they are (the ground's edge, a facade's rim), and
  // so do the corners of the faces OpenMesh refused.
  for (auto v : mesh.vertices())
    if (mesh.is_boundary(v)) mesh.status(v).set_locked(true);
  for (auto v : pinned) mesh.status(v).set_locked(true);

  OpenMesh::Decimater::DecimaterT<OMMesh> decimater(mesh);
  OpenMesh::Decimater::ModQuadricT<OMMesh>::Handle quadric;      // order: cheapest collapses first
  OpenMesh::Decimater::ModHausdorffT<OMMesh>::Handle hausdorff;  // bound: original vertices within max_error_m
  OpenMesh::Decimater::ModNormalFlippingT<OMMesh>::Handle flipping;
  decimater.add(quadric);
  decimater.add(hausdorff);
  decimater.add(flipping);
  // ModQuadric's error is area-weighted (not a distance): it only orders the
  // collapses; ModHausdorff keeps every original vertex within the bound.
  decimater.module(quadric).unset_max_err();
  decimater.module(hausdorff).set_tolerance(max_error_m);
  if (!decimater.initialize()) return false;
  if (decimater.decimate(0) == 0) return false;
  mesh.garbage_collection();

  Piece out;
  for (auto v : mesh.vertices()) {
    const auto& p = mesh.point(v);
    out.vertices.push_back({p[0], p[1], p[2]});
  }
  for (auto f : mesh.faces()) {
    Tri t;
    int k = 0;
    for (auto v : mesh.fv_range(f)) t[k++] = static_cast<std::uint32_t>(v.idx());
    out.triangles.push_back(t);
  }
  const auto base = static_cast<std::uint32_t>(out.vertices.size());
  out.vertices.insert(out.vertices.end(), kept_vertices.begin(), kept_vertices.end());
  for (const auto& t : kept) out.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  if (out.triangles.size() >= piece.triangles.size()) return false;
  piece = std::move(out);
  return true;
}

}  // namespace

Scene simplify_scene(const Scene& scene, double max_error_m, SimplifyStats* stats) {
  SimplifyStats st;
  st.triangles_before = scene.triangle_count();
  if (!(max_error_m > 0)) {
    st.triangles_after = st.triangles_before;
    if (stats) *stats = st;
    return scene;
  }
  Scene out;
  out.objects = scene.objects;
  std::uint32_t next_face = 0;
  for (const auto& mesh : scene.meshes) {
    // The mesh's triangles by object, each object's vertices compacted.
    std::map<std::uint32_t, Piece> pieces;
    std::map<std::uint32_t, std::map<std::uint32_t, std::uint32_t>> remap;
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      const std::uint32_t obj = mesh.triangle_object.at(t);
      Piece& p = pieces[obj];
      auto& m = remap[obj];
      Tri tri;
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t v = mesh.triangles[t][k];
        auto [it, fresh] = m.emplace(v, static_cast<std::uint32_t>(p.vertices.size()));
        if (fresh) p.vertices.push_back(mesh.vertices.at(v));
        tri[k] = it->second;
      }
      p.triangles.push_back(tri);
    }
    Mesh m;
    m.name = mesh.name;
    m.material = mesh.material;
    for (auto& [obj, piece] : pieces) {
      if (decimate(piece, max_error_m)) ++st.objects_simplified;
      const auto faces = group_planar_faces(piece.vertices, piece.triangles, next_face);
      for (auto f : faces) next_face = std::max(next_face, f + 1);
      const auto base = static_cast<std::uint32_t>(m.vertices.size());
      m.vertices.insert(m.vertices.end(), piece.vertices.begin(), piece.vertices.end());
      for (const auto& t : piece.triangles) m.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
      m.triangle_object.insert(m.triangle_object.end(), piece.triangles.size(), obj);
      m.triangle_face.insert(m.triangle_face.end(), faces.begin(), faces.end());
    }
    out.meshes.push_back(std::move(m));
  }
  st.triangles_after = out.triangle_count();
  if (stats) *stats = st;
  return out;
}

}  // namespace raysweep::meshkit
