#include "meshkit/vehicle_lod.hpp"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <algorithm>
#include <cmath>
#include <map>

#include "meshkit/openmesh_util.hpp"

namespace raysweep::meshkit {

using OM = OMMesh;

static VehicleModel simplify_once(const VehicleModel& model, double ratio, double max_error_m) {
  VehicleModel out = model;
  // Where parts touch (a door's border on the body's interior, a window in its
  // frame), the contact vertices must stay put in both, or the seam opens.
  std::map<Vec3, std::size_t> owner;  // position -> part index, or SIZE_MAX when shared
  for (std::size_t i = 0; i < model.parts.size(); ++i)
    for (const auto& v : model.parts[i].vertices) {
      auto [it, fresh] = owner.emplace(v, i);
      if (!fresh && it->second != i) it->second = SIZE_MAX;
    }
  for (auto& part : out.parts) {
    if (part.triangles.size() < 8) continue;
    // Weld by position first: seams (UV, normals) would otherwise look like
    // borders and stay locked.
    WeldedMesh welded(part.vertices, part.triangles);
    OM& mesh = welded.mesh;
    const auto& kept_vertices = welded.kept_vertices;
    const auto& kept = welded.kept;
    const auto& pinned = welded.pinned;
    // The part's border is a material boundary (or the model's own hole):
    // locking it, and every contact with another part, keeps both, and with
    // them the closedness of the whole.
    for (auto v : mesh.vertices()) {
      const auto& p = mesh.point(v);
      if (mesh.is_boundary(v) || owner.at(Vec3{p[0], p[1], p[2]}) == SIZE_MAX) mesh.status(v).set_locked(true);
    }
    for (auto v : pinned) mesh.status(v).set_locked(true);
    OpenMesh::Decimater::DecimaterT<OM> decimater(mesh);
    OpenMesh::Decimater::ModQuadricT<OM>::Handle quadric;
    OpenMesh::Decimater::ModNormalFlippingT<OM>::Handle flipping;
    decimater.add(quadric);
    decimater.add(flipping);
    // ModQuadric's error is a squared distance to the original planes.
    if (std::isfinite(max_error_m))
      decimater.module(quadric).set_max_err(max_error_m * max_error_m, /*binary=*/false);
    else
      decimater.module(quadric).unset_max_err();
    if (!decimater.initialize()) continue;
    const auto target = static_cast<std::size_t>(std::ceil(ratio * part.triangles.size()));
    decimater.decimate_to_faces(0, target > kept.size() ? target - kept.size() : 1);
    mesh.garbage_collection();

    std::vector<Vec3> verts;
    for (auto v : mesh.vertices()) {
      const auto& p = mesh.point(v);
      verts.push_back({p[0], p[1], p[2]});
    }
    std::vector<Tri> tris;
    for (auto f : mesh.faces()) {
      Tri t;
      int k = 0;
      for (auto v : mesh.fv_range(f)) t[k++] = static_cast<std::uint32_t>(v.idx());
      tris.push_back(t);
    }
    const auto base = static_cast<std::uint32_t>(verts.size());
    verts.insert(verts.end(), kept_vertices.begin(), kept_vertices.end());
    for (const auto& t : kept) tris.push_back({t[0] + base, t[1] + base, t[2] + base});
    if (tris.size() >= part.triangles.size()) continue;
    part.vertices = std::move(verts);
    part.triangles = std::move(tris);
  }
  return out;
}

VehicleModel simplify_vehicle(const VehicleModel& model, double ratio, double max_error_m) {
  // Parts decimated on their own can, at aggressive ratios, fold onto each
  // other along a locked shared border (coincident "ears"): an edge then
  // bounds four faces. Such a level is refused and the ratio relaxed, so no
  // LOD is ever less closed than its source.
  const EdgeReport source = welded_edge_report(model);
  for (double r = ratio; r < 1; r = std::min(1.0, r * 1.5)) {
    VehicleModel lod = simplify_once(model, r, max_error_m);
    const EdgeReport e = welded_edge_report(lod);
    if (e.boundary_edges <= source.boundary_edges && e.nonmanifold_edges <= source.nonmanifold_edges &&
        e.inconsistent_edges <= source.inconsistent_edges)
      return lod;
  }
  return model;
}

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Triangle = K::Triangle_3;
using Iterator = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<K, Iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

std::vector<Triangle> triangles_of(const VehicleModel& m) {
  std::vector<Triangle> tris;
  for (const auto& p : m.parts)
    for (const auto& t : p.triangles) {
      const Vec3 &a = p.vertices[t[0]], &b = p.vertices[t[1]], &c = p.vertices[t[2]];
      Triangle tri(K::Point_3(a[0], a[1], a[2]), K::Point_3(b[0], b[1], b[2]), K::Point_3(c[0], c[1], c[2]));
      if (!tri.is_degenerate()) tris.push_back(tri);
    }
  return tris;
}

// Largest distance from a sample of `from` to the surface `to`.
double one_sided(const std::vector<Triangle>& from, const std::vector<Triangle>& to, std::size_t samples) {
  if (from.empty() || to.empty()) return from.empty() == to.empty() ? 0 : INFINITY;
  Tree tree(to.begin(), to.end());
  tree.accelerate_distance_queries();
  double total = 0;
  for (const auto& t : from) total += std::sqrt(t.squared_area());
  double worst2 = 0;
  // Points from the R2 low-discrepancy sequence folded into each triangle:
  // deterministic and evenly spread.
  const double g = 1.32471795724474602596, a1 = 1 / g, a2 = 1 / (g * g);
  std::size_t seq = 0;
  for (const auto& t : from) {
    const std::size_t n = static_cast<std::size_t>(std::ceil(samples * std::sqrt(t.squared_area()) / total));
    for (int k = 0; k < 3; ++k) worst2 = std::max(worst2, tree.squared_distance(t.vertex(k)));
    for (std::size_t i = 0; i < n; ++i, ++seq) {
      double u = std::fmod(0.5 + a1 * seq, 1.0), v = std::fmod(0.5 + a2 * seq, 1.0);
      if (u + v > 1) u = 1 - u, v = 1 - v;
      const K::Point_3 p = t.vertex(0) + u * (t.vertex(1) - t.vertex(0)) + v * (t.vertex(2) - t.vertex(0));
      worst2 = std::max(worst2, tree.squared_distance(p));
    }
  }
  return std::sqrt(worst2);
}

}  // namespace

double hausdorff_distance(const VehicleModel& a, const VehicleModel& b, std::size_t samples) {
  const auto ta = triangles_of(a), tb = triangles_of(b);
  return std::max(one_sided(ta, tb, samples), one_sided(tb, ta, samples));
}

}  // namespace raysweep::meshkit
