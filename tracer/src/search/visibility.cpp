#include "search/visibility.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace raysweep::tracer {

namespace {

// p inside static face g's convex outline by at least `margin` (the
// outline runs counter-clockwise about the normal: inside is to the left).
bool deep_inside(const ImageFaces& faces, std::uint32_t g, const Vec3& p, double margin) {
  const std::uint32_t o0 = faces.outline_begin[g], o1 = faces.outline_begin[g + 1];
  const Vec3& n = faces.planes[g].normal;
  for (std::uint32_t k = o0; k < o1; ++k) {
    const Vec3 a = faces.outline[k], b = faces.outline[k + 1 < o1 ? k + 1 : o0];
    if (dot(cross(b - a, p - a), n) < margin * norm(b - a)) return false;
  }
  return true;
}

// Whether the segment from src to p crosses static face g (hit at distance
// t along unit dir) as hidden_by_convex_face needs it: g convex, src and p
// on opposite sides of its plane and both at least `margin` from it, the
// crossing at least `margin` inside its outline.
bool crosses_deep(const ImageFaces& faces, std::uint32_t g, const Vec3& src, const Vec3& p, const Vec3& dir,
                  double t, double margin) {
  if (!faces.convex[g]) return false;
  const Plane& pb = faces.planes[g];
  const double h_src = dot(pb.normal, src) - pb.offset, h_p = dot(pb.normal, p) - pb.offset;
  return h_src * h_p < 0 && std::fabs(h_src) >= margin && std::fabs(h_p) >= margin &&
         deep_inside(faces, g, src + t * dir, margin);
}

// SlabBounds::at(node at src, f): the faces every ray from src to f's
// outline vertices crosses deep (ascending, intersected ray by ray).
int slabs_to_face(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, std::uint32_t f, int limit,
                  std::vector<Hit>& hits, std::vector<std::uint32_t>& common, std::vector<std::uint32_t>& next) {
  const std::uint32_t o0 = faces.outline_begin[f], o1 = faces.outline_begin[f + 1];
  if (o1 - o0 < 3) return 0;
  const double margin = 0.01 + 4 * scene.slack(src, 0) + 4 * faces.tol[f];
  const FaceRef self{0, f};
  for (std::uint32_t k = o0; k < o1; ++k) {
    const Vec3 w = faces.outline[k] - src;
    const double len = norm(w);
    if (!(len > 2 * margin)) return 0;
    const Vec3 dir = (1.0 / len) * w;
    scene.all_hits(src, dir, 0, len, hits, 16, &self);  // the first 16 (a lower bound either way)
    next.clear();
    for (const Hit& h : hits)
      if (h.face.instance == 0 && crosses_deep(faces, h.face.face, src, faces.outline[k], dir, h.t, margin))
        next.push_back(h.face.face);
    std::sort(next.begin(), next.end());
    next.erase(std::unique(next.begin(), next.end()), next.end());
    if (k == o0) {
      common.swap(next);
    } else {
      const auto end = std::set_intersection(common.begin(), common.end(), next.begin(), next.end(), common.begin());
      common.erase(end, common.end());
    }
    if (common.empty()) return 0;
  }
  return std::min(static_cast<int>(common.size()), limit);
}

}  // namespace

SlabBounds slab_bounds(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                       const std::vector<char>& wanted, int cap) {
  SlabBounds b;
  b.cap = cap;
  b.static_count = faces.static_count;
  b.lb.assign(nodes.size() * faces.static_count, 0);
  tbb::parallel_for(std::size_t{0}, nodes.size(), [&](std::size_t n) {
    if (!wanted[n]) return;
    std::vector<Hit> hits;
    std::vector<std::uint32_t> common, next;
    for (std::uint32_t f = 0; f < faces.static_count; ++f)
      b.lb[n * faces.static_count + f] =
          static_cast<std::uint8_t>(slabs_to_face(scene, faces, nodes[n].position, f, cap + 1, hits, common, next));
  });
  return b;
}

bool hidden_by_convex_face(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, const Vec3* points,
                           std::size_t count, const FaceRef* skip, double tol) {
  if (count < 2) return false;
  const double margin = 0.01 + 4 * scene.slack(src, 0) + 4 * tol;
  std::uint32_t blocker = ~0u;
  for (std::size_t k = 0; k < count; ++k) {
    const Vec3 w = points[k] - src;
    const double len = norm(w);
    if (!(len > 2 * margin)) return false;
    const Vec3 dir = (1.0 / len) * w;
    Hit hit;
    if (!scene.closest_hit(src, dir, 0, len, hit, skip)) return false;
    if (hit.face.instance != 0 || !faces.convex[hit.face.face]) return false;
    if (blocker != ~0u && hit.face.face != blocker) return false;
    blocker = hit.face.face;
    if (!crosses_deep(faces, blocker, src, points[k], dir, hit.t, margin)) return false;
  }
  return true;
}

}  // namespace raysweep::tracer
