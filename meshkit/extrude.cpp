#include "meshkit/extrude.hpp"

#include <cmath>
#include <map>
#include <tuple>

namespace raysweep::meshkit {

ExtrudeStats extrude_footprint(const Footprint& footprint, double base, double top, std::uint32_t object,
                               std::uint32_t& next_face, Mesh& mesh) {
  ExtrudeStats stats;
  const std::size_t tri_start = mesh.triangles.size();
  const std::uint32_t roof_face = next_face++;
  const std::uint32_t floor_face = next_face++;
  stats.faces += 2;
  // Wall planes keyed by their quantised line (direction, offset) so collinear
  // pieces of one wall share a face id; 1e-6 rad and 1 mm are far below the
  // simplification tolerance.
  std::map<std::tuple<long long, long long, long long>, std::uint32_t> wall_faces;

  for (const Polygon2& poly : footprint.polygons) {
    TriangulatedPolygon t = triangulate(poly);
    const auto n = static_cast<std::uint32_t>(t.vertices.size());
    const auto v0 = static_cast<std::uint32_t>(mesh.vertices.size());
    for (const Vec2& v : t.vertices) mesh.vertices.push_back({v[0], v[1], base});
    for (const Vec2& v : t.vertices) mesh.vertices.push_back({v[0], v[1], top});
    auto bot = [v0](std::uint32_t i) { return v0 + i; };
    auto up = [v0, n](std::uint32_t i) { return v0 + n + i; };
    auto add = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t face) {
      mesh.triangles.push_back({a, b, c});
      mesh.triangle_object.push_back(object);
      mesh.triangle_face.push_back(face);
    };
    for (const auto& tri : t.triangles) {
      add(up(tri[0]), up(tri[1]), up(tri[2]), roof_face);     // CCW seen from above
      add(bot(tri[0]), bot(tri[2]), bot(tri[1]), floor_face); // CCW seen from below
    }
    for (const auto& e : t.boundary_edges) {
      const Vec2& a = t.vertices[e[0]];
      const Vec2& b = t.vertices[e[1]];
      double dx = b[0] - a[0], dy = b[1] - a[1];
      const double len = std::hypot(dx, dy);
      if (len == 0) continue;
      dx /= len, dy /= len;
      // Outward normal (dy, -dx): the interior is on the left of a->b.
      const double offset = dy * a[0] - dx * a[1];
      auto key = std::make_tuple(std::llround(std::atan2(dy, dx) * 1e6), std::llround(offset * 1e3), 0LL);
      auto [it, fresh] = wall_faces.emplace(key, next_face);
      if (fresh) {
        ++next_face;
        ++stats.faces;
      }
      add(bot(e[0]), bot(e[1]), up(e[1]), it->second);
      add(bot(e[0]), up(e[1]), up(e[0]), it->second);
    }
  }
  stats.triangles = mesh.triangles.size() - tri_start;
  return stats;
}

}  // namespace raysweep::meshkit
