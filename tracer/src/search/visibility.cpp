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
  for (std::uint32_t k = o0; k < o1; ++k)
    if (dot(faces.outline_inward[k], p - faces.outline[k]) < margin) return false;
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

// The margin of the tests that hide static face f (or points on it) from src.
double hiding_margin(const TraceScene& scene, const Vec3& src, double tol) {
  return 0.01 + 4 * scene.slack(src, 0) + 4 * tol;
}

// Whether every segment from src to points[0, count) crosses static face g
// deep (crosses_deep), from g's plane alone: no ray.
bool crosses_all(const ImageFaces& faces, std::uint32_t g, const Vec3& src, const Vec3* points, std::size_t count,
                 double margin) {
  const Plane& pg = faces.planes[g];
  const double hs = dot(pg.normal, src) - pg.offset;
  for (std::size_t k = 0; k < count; ++k) {
    // The sides first: most walls tried leave the points on the source's side.
    const double hp = dot(pg.normal, points[k]) - pg.offset;
    if (!(hs * hp < 0)) return false;
    const Vec3 w = points[k] - src;
    const double len = norm(w);
    if (!(len > 2 * margin)) return false;
    if (!crosses_deep(faces, g, src, points[k], (1.0 / len) * w, len * hs / (hs - hp), margin)) return false;
  }
  return true;
}

// How many of `walls` (not `skip`) every segment from src to the points
// crosses deep, up to `limit`; with `which`, those walls.
int walls_across(const ImageFaces& faces, const std::vector<std::uint32_t>& walls, const Vec3& src,
                 const Vec3* points, std::size_t count, std::uint32_t skip, double margin, int limit,
                 std::vector<std::uint32_t>* which = nullptr) {
  int found = 0;
  for (const std::uint32_t g : walls)
    if (g != skip && crosses_all(faces, g, src, points, count, margin)) {
      if (which) which->push_back(g);
      if (++found >= limit) break;
    }
  return found;
}

// SlabBounds::at(node at src, f): the faces every segment from src to f's
// outline vertices crosses deep. The ray to the first vertex proposes them
// (its first 16 hits: a lower bound either way); the other vertices keep
// those whose planes they cross deep (crosses_all, no ray).
int slabs_to_face(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, std::uint32_t f, int limit,
                  std::vector<Hit>& hits, std::vector<std::uint32_t>& common) {
  const std::uint32_t o0 = faces.outline_begin[f], o1 = faces.outline_begin[f + 1];
  if (o1 - o0 < 3) return 0;
  const double margin = hiding_margin(scene, src, faces.tol[f]);
  const FaceRef self{0, f};
  const Vec3 w = faces.outline[o0] - src;
  const double len = norm(w);
  if (!(len > 2 * margin)) return 0;
  const Vec3 dir = (1.0 / len) * w;
  scene.all_hits(src, dir, 0, len, hits, 16, &self);
  common.clear();
  for (const Hit& h : hits)
    if (h.face.instance == 0 && crosses_deep(faces, h.face.face, src, faces.outline[o0], dir, h.t, margin))
      common.push_back(h.face.face);
  std::sort(common.begin(), common.end());
  common.erase(std::unique(common.begin(), common.end()), common.end());
  const auto gone = [&](std::uint32_t g) {
    return !crosses_all(faces, g, src, &faces.outline[o0 + 1], o1 - o0 - 1, margin);
  };
  common.erase(std::remove_if(common.begin(), common.end(), gone), common.end());
  return std::min(static_cast<int>(common.size()), limit);
}

// One node's bounds over every static face (lb[f]), the walls that counted
// last tried first; its most counted walls into `walls`.
void node_slab_bounds(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, int limit,
                      std::uint8_t* lb, std::vector<std::uint32_t>& walls) {
  constexpr std::size_t kRecent = 12;
  std::vector<Hit> hits;
  std::vector<std::uint32_t> common, recent;  // recent: most recent first
  std::vector<std::pair<std::uint32_t, std::uint32_t>> counted;  // (face, faces it counted for)
  auto count = [&](std::uint32_t g) {
    auto it = std::find_if(counted.begin(), counted.end(), [g](const auto& c) { return c.first == g; });
    if (it == counted.end()) counted.emplace_back(g, 1);
    else ++it->second;
  };
  for (std::uint32_t f = 0; f < faces.static_count; ++f) {
    const std::uint32_t o0 = faces.outline_begin[f], o1 = faces.outline_begin[f + 1];
    const double margin = hiding_margin(scene, src, faces.tol[f]);
    common.clear();
    const int known =
        o1 - o0 >= 3 ? walls_across(faces, recent, src, &faces.outline[o0], o1 - o0, f, margin, limit, &common) : 0;
    const int cast = known < limit ? slabs_to_face(scene, faces, src, f, limit, hits, common) : 0;
    lb[f] = static_cast<std::uint8_t>(std::max(known, cast));
    for (const std::uint32_t g : common) {
      count(g);
      const auto at = std::find(recent.begin(), recent.end(), g);
      if (at != recent.end()) recent.erase(at);
      else if (recent.size() == kRecent) recent.pop_back();
      recent.insert(recent.begin(), g);
    }
  }
  std::sort(counted.begin(), counted.end(),
            [](const auto& a, const auto& b) { return a.second != b.second ? a.second > b.second : a.first < b.first; });
  for (std::size_t k = 0; k < counted.size() && k < SlabBounds::kWalls; ++k) walls.push_back(counted[k].first);
}

}  // namespace

SlabBounds slab_bounds(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                       const std::vector<char>& wanted, int cap) {
  SlabBounds b;
  b.cap = cap;
  b.static_count = faces.static_count;
  b.lb.assign(nodes.size() * faces.static_count, 0);
  b.walls.resize(nodes.size());
  tbb::parallel_for(std::size_t{0}, nodes.size(), [&](std::size_t n) {
    if (wanted[n] && faces.static_count > 0)
      node_slab_bounds(scene, faces, nodes[n].position, cap + 1, &b.lb[n * faces.static_count], b.walls[n]);
  });
  return b;
}

namespace {

// One of `walls` (not `self`) that every segment from src to the points
// crosses deep (its plane alone), or ~0u.
std::uint32_t wall_across(const ImageFaces& faces, const std::vector<std::uint32_t>& walls, const Vec3& src,
                          const Vec3* points, std::size_t count, std::uint32_t self, double margin) {
  for (const std::uint32_t g : walls)
    if (g != self && crosses_all(faces, g, src, points, count, margin)) return g;
  return ~0u;
}

// hidden_by_convex_face with the face that hides the points (~0u: none).
std::uint32_t convex_blocker(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, const Vec3* points,
                             std::size_t count, const FaceRef* skip, double tol,
                             const std::vector<std::uint32_t>* walls) {
  if (count < 2) return ~0u;
  const double margin = hiding_margin(scene, src, tol);
  const std::uint32_t self = skip && skip->instance == 0 ? skip->face : ~0u;
  if (walls) {
    const std::uint32_t g = wall_across(faces, *walls, src, points, count, self, margin);
    if (g != ~0u) return g;
  }
  std::uint32_t blocker = ~0u;
  for (std::size_t k = 0; k < count; ++k) {
    const Vec3 w = points[k] - src;
    const double len = norm(w);
    if (!(len > 2 * margin)) return ~0u;
    const Vec3 dir = (1.0 / len) * w;
    Hit hit;
    if (!scene.closest_hit(src, dir, 0, len, hit, skip)) return ~0u;
    if (hit.face.instance != 0 || !faces.convex[hit.face.face]) return ~0u;
    if (blocker != ~0u && hit.face.face != blocker) return ~0u;
    blocker = hit.face.face;
    if (!crosses_deep(faces, blocker, src, points[k], dir, hit.t, margin)) return ~0u;
  }
  return blocker;
}

}  // namespace

bool hidden_by_convex_face(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, const Vec3* points,
                           std::size_t count, const FaceRef* skip, double tol,
                           const std::vector<std::uint32_t>* walls) {
  return convex_blocker(scene, faces, src, points, count, skip, tol, walls) != ~0u;
}

bool RecentBlockers::hidden(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, const Vec3* points,
                            std::size_t count, const FaceRef* skip, double tol,
                            const std::vector<std::uint32_t>* walls) {
  if (count < 2) return false;
  const std::uint32_t self = skip && skip->instance == 0 ? skip->face : ~0u;
  std::uint32_t g = wall_across(faces, recent_, src, points, count, self, hiding_margin(scene, src, tol));
  if (g == ~0u) g = convex_blocker(scene, faces, src, points, count, skip, tol, walls);
  if (g == ~0u) return false;
  const auto at = std::find(recent_.begin(), recent_.end(), g);
  if (at != recent_.end()) recent_.erase(at);
  else if (recent_.size() == kRecent) recent_.pop_back();
  recent_.insert(recent_.begin(), g);
  return true;
}

}  // namespace raysweep::tracer
