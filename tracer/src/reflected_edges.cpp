#include "reflected_edges.hpp"

#include <algorithm>
#include <cmath>

#include "search/beam_geometry.hpp"
#include "search/visibility.hpp"

namespace raysweep::tracer {

void reflected_edges(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, double range,
                     std::vector<ReflectedEdge>& out, const std::vector<std::uint32_t>* only,
                     const SlabBounds* slabs, std::uint32_t node) {
  const auto& edges = scene.edges();
  if (edges.empty() || (only && only->empty())) return;
  // The tree the walk runs down: every edge's, or one over `only`.
  const std::vector<ImageFaces::SphereNode>* tree = &faces.edge_tree;
  const std::vector<std::uint32_t>* order = &faces.edge_order;
  std::vector<ImageFaces::SphereNode> only_tree;
  std::vector<std::uint32_t> only_order;
  if (only) {
    only_order = *only;
    const std::vector<double> no_tol(edges.size(), 0.0);
    build_sphere_tree(faces.edge_spheres, no_tol, only_tree, only_order, 0,
                      static_cast<std::uint32_t>(only_order.size()));
    tree = &only_tree;
    order = &only_order;
  }
  std::vector<Vec3> pyramid;
  std::vector<std::uint32_t> stack;
  const std::vector<std::uint32_t>* walls = slabs ? &slabs->walls[node] : nullptr;
  RecentBlockers blockers;
  for (std::uint32_t f = 0; f < faces.static_count; ++f) {
    const Plane& pl = faces.planes[f];
    const double ds = dot(pl.normal, src) - pl.offset;
    if (ds == 0) continue;
    // A face hidden whole from src by one convex face reflects nothing to
    // its edges (a few rays, or none: cheaper than the walk below).
    const FaceRef self{0, f};
    if (slabs ? slabs->at(node, f) >= 1
              : hidden_by_convex_face(scene, faces, src, &faces.outline[faces.outline_begin[f]],
                                      faces.outline_begin[f + 1] - faces.outline_begin[f], &self, faces.tol[f]))
      continue;
    const Vec3 img = src - (2 * ds) * pl.normal;
    pyramid.clear();
    outline_pyramid(faces, f, img, pyramid);
    const double spread_per_m = 2 * faces.tol[f] / std::fabs(ds);
    const double side = ds > 0 ? 1 : -1;
    // Outside the beam: wholly behind the face (seen from the source), out
    // of range of the image, or outside the pyramid through the outline.
    auto outside = [&](const TraceScene::Sphere& sp, double tol) {
      const double h = dot(pl.normal, sp.centre) - pl.offset;
      if (side * h + sp.radius <= 0) return true;
      if (norm(sp.centre - img) - sp.radius > range) return true;
      return outside_pyramid(pyramid, img, sp, tol + faces.tol[f], spread_per_m);
    };
    walk_tree(*tree, *order, stack, outside, [&](std::uint32_t k) {
      if (outside(faces.edge_spheres[k], 0)) return;
      const Edge& e = edges[k];
      // The part of the edge inside the beam: the segment clipped by the
      // face's plane (the source's side) and the pyramid's planes, each
      // padded as the tests above pad them (at the edge's far end).
      const double len = norm(e.b - e.a);
      const double far = norm(faces.edge_spheres[k].centre - img) + 0.5 * len;
      const double pad = faces.tol[f] + (spread_per_m + 1e-6) * far + 1e-9 * len;
      double z0 = 0, z1 = len;
      auto clip = [&](const Vec3& nrm, double h_a) {  // keep z where h_a + z (nrm . e) >= -pad
        const double slope = dot(nrm, e.e);
        if (slope == 0) {
          if (h_a < -pad) z1 = -1;
          return;
        }
        const double z = (-pad - h_a) / slope;
        if (slope > 0) z0 = std::max(z0, z);
        else z1 = std::min(z1, z);
      };
      clip(side * pl.normal, side * (dot(pl.normal, e.a) - pl.offset));
      for (const auto& nrm : pyramid) clip(nrm, dot(nrm, e.a - img));
      if (!(z0 <= z1)) return;
      // The image must see the edge from outside its wedge.
      const Vec3 w = img - e.a;
      const double zt = dot(w, e.e);
      const Vec3 v = w - zt * e.e;
      double angle = std::atan2(dot(v, e.n0), dot(v, e.t0));
      if (angle < 0) angle += 2 * kPi;
      if (angle > e.n * kPi) return;
      // A face in the wedge's own planes reflects onto its edge at grazing
      // incidence: the UTD coefficient's reflection terms hold that already.
      for (const FaceRef* wf : {&e.face0, &e.face_n}) {
        const Plane& pw = faces.planes[wf->face];
        if (wf->face == f || (std::fabs(dot(pw.normal, pl.normal)) > 1 - 1e-9 &&
                              std::fabs(dot(pw.normal, pl.normal) * pw.offset - pl.offset) < 1e-6))
          return;
      }
      // The reflection points of this part: a segment on f (the central
      // projection of the part from the image); hidden whole from src, no
      // path reflected there reaches the edge.
      const Vec3 ends[2] = {crossing(img, -ds, e.a + z0 * e.e, dot(pl.normal, e.a + z0 * e.e) - pl.offset),
                            crossing(img, -ds, e.a + z1 * e.e, dot(pl.normal, e.a + z1 * e.e) - pl.offset)};
      if (blockers.hidden(scene, faces, src, ends, 2, &self, faces.tol[f], walls)) return;
      out.push_back({f, k, z0, z1, zt, norm(v)});
    });
  }
  std::sort(out.begin(), out.end());
}

}  // namespace raysweep::tracer
