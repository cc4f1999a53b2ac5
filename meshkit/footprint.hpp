// Building footprints: repair of mapped rings (CGAL), simplification within a
// tolerance that keeps area and centroid, and constrained Delaunay
// triangulation with holes. All CGAL use is confined to footprint.cpp.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "meshkit/projection.hpp"

namespace raysweep::meshkit {

// A simple polygon with holes: outer ring counter-clockwise, holes clockwise,
// rings open (first point not repeated).
struct Polygon2 {
  std::vector<Vec2> outer;
  std::vector<std::vector<Vec2>> holes;
};

struct FootprintOptions {
  double simplify_tolerance_m = 0.05;   // max distance of a removed vertex from the kept outline
  double max_area_change = 0.005;       // relative; simplification is undone beyond it
  double max_centroid_shift_m = 0.02;   // likewise
  double min_area_m2 = 0.5;             // smaller footprints are dropped as degenerate
  double duplicate_tolerance_m = 1e-4;  // consecutive nodes closer than this are one node
};

// What repair did, so the manifest can count it.
struct FootprintRepairs {
  int duplicate_nodes = 0;        // consecutive (near-)duplicate nodes removed
  bool reoriented = false;        // a ring had the wrong winding
  bool self_intersection = false; // a ring crossed itself: even-odd rule applied
  bool holes_fixed = false;       // a hole touched, crossed or lay outside the outline
  bool rings_merged = false;      // overlapping outer rings unioned
  bool any() const {
    return duplicate_nodes || reoriented || self_intersection || holes_fixed || rings_merged;
  }
};

struct Footprint {
  std::vector<Polygon2> polygons;
  FootprintRepairs repairs;
  double area_m2 = 0;
  Vec2 centroid{0, 0};
  std::size_t vertices_in = 0, vertices_out = 0;
  bool simplified = false;            // simplification removed vertices and was kept
  bool simplification_undone = false; // it would have broken the area/centroid bounds
};

struct FootprintResult {
  std::optional<Footprint> footprint;
  std::string skip_reason;  // stable code when footprint is empty
  std::string detail;
};

FootprintResult make_footprint(const std::vector<std::vector<Vec2>>& outers,
                               const std::vector<std::vector<Vec2>>& inners,
                               const FootprintOptions& options);

// Area (positive) and centroid of a polygon with holes.
double polygon_area(const Polygon2& p);
Vec2 polygon_centroid(const Polygon2& p);
// Area-weighted centroid of a plain ring (either orientation).
Vec2 ring_centroid(const std::vector<Vec2>& ring);

struct TriangulatedPolygon {
  std::vector<Vec2> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;      // counter-clockwise
  std::vector<std::array<std::uint32_t, 2>> boundary_edges; // interior on the left
};

// Constrained Delaunay triangulation of the interior. Boundary edges follow the
// triangulation (split where constraints meet), so walls built on them close
// the roof and floor exactly.
TriangulatedPolygon triangulate(const Polygon2& polygon);

// Whether `p` lies strictly inside the footprint.
bool footprint_contains(const Footprint& f, Vec2 p);

}  // namespace raysweep::meshkit
