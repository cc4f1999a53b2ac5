// Footprint repair, simplification bounds and triangulation against
// hand-computed areas and centroids.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "meshkit/footprint.hpp"

using namespace raysweep::meshkit;

namespace {
std::vector<Vec2> square(double x0, double y0, double s) { return {{x0, y0}, {x0 + s, y0}, {x0 + s, y0 + s}, {x0, y0 + s}}; }
FootprintOptions no_simplify() {
  FootprintOptions o;
  o.simplify_tolerance_m = 0;
  return o;
}
double triangulated_area(const TriangulatedPolygon& t) {
  double a = 0;
  for (const auto& tri : t.triangles) {
    const Vec2 &p = t.vertices[tri[0]], &q = t.vertices[tri[1]], &r = t.vertices[tri[2]];
    a += 0.5 * ((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]));
  }
  return a;
}
}  // namespace

TEST(Footprint, SquareAreaCentroidAndWinding) {
  auto r = make_footprint({square(100, 200, 10)}, {}, FootprintOptions{});
  ASSERT_TRUE(r.footprint);
  EXPECT_NEAR(r.footprint->area_m2, 100, 1e-9);
  EXPECT_NEAR(r.footprint->centroid[0], 105, 1e-9);
  EXPECT_NEAR(r.footprint->centroid[1], 205, 1e-9);
  EXPECT_FALSE(r.footprint->repairs.any());
}

TEST(Footprint, ClockwiseRingIsReoriented) {
  auto ring = square(0, 0, 10);
  std::reverse(ring.begin(), ring.end());
  auto r = make_footprint({ring}, {}, FootprintOptions{});
  ASSERT_TRUE(r.footprint);
  EXPECT_TRUE(r.footprint->repairs.reoriented);
  const auto& outer = r.footprint->polygons.at(0).outer;
  double s = 0;
  for (std::size_t i = 0; i < outer.size(); ++i)
    s += outer[i][0] * outer[(i + 1) % outer.size()][1] - outer[(i + 1) % outer.size()][0] * outer[i][1];
  EXPECT_GT(s, 0) << "outer ring must be counter-clockwise";
}

TEST(Footprint, DuplicateNodesRemoved) {
  std::vector<Vec2> ring = {{0, 0}, {10, 0}, {10, 0}, {10, 10}, {10, 10.00000001}, {0, 10}, {0, 0}};
  auto r = make_footprint({ring}, {}, no_simplify());
  ASSERT_TRUE(r.footprint);
  EXPECT_EQ(r.footprint->repairs.duplicate_nodes, 2);
  EXPECT_EQ(r.footprint->vertices_out, 4u);
  EXPECT_NEAR(r.footprint->area_m2, 100, 1e-6);
}

TEST(Footprint, SelfIntersectingBowtieUsesEvenOddRule) {
  // Two triangles of area 25 each meeting at (5,5).
  auto r = make_footprint({{{0, 0}, {10, 10}, {10, 0}, {0, 10}}}, {}, no_simplify());
  ASSERT_TRUE(r.footprint);
  EXPECT_TRUE(r.footprint->repairs.self_intersection);
  EXPECT_NEAR(r.footprint->area_m2, 50, 1e-9);
  EXPECT_NEAR(r.footprint->centroid[0], 5, 1e-9);
  EXPECT_NEAR(r.footprint->centroid[1], 5, 1e-9);
}

TEST(Footprint, ProperHoleIsKept) {
  auto r = make_footprint({square(0, 0, 10)}, {square(3, 3, 4)}, no_simplify());
  ASSERT_TRUE(r.footprint);
  EXPECT_FALSE(r.footprint->repairs.holes_fixed);
  ASSERT_EQ(r.footprint->polygons.size(), 1u);
  EXPECT_EQ(r.footprint->polygons[0].holes.size(), 1u);
  EXPECT_NEAR(r.footprint->area_m2, 84, 1e-9);
}

TEST(Footprint, HoleTouchingOuterRingIsRepaired) {
  // Triangle hole with one corner on the left wall: area 100 - 10.
  auto r = make_footprint({square(0, 0, 10)}, {{{0, 5}, {5, 3}, {5, 7}}}, no_simplify());
  ASSERT_TRUE(r.footprint);
  EXPECT_TRUE(r.footprint->repairs.holes_fixed);
  EXPECT_NEAR(r.footprint->area_m2, 90, 1e-9);
  double tri_area = 0;
  for (const auto& p : r.footprint->polygons) tri_area += triangulated_area(triangulate(p));
  EXPECT_NEAR(tri_area, 90, 1e-9);
}

TEST(Footprint, HoleOutsideIsIgnored) {
  auto r = make_footprint({square(0, 0, 10)}, {square(20, 20, 2)}, no_simplify());
  ASSERT_TRUE(r.footprint);
  EXPECT_TRUE(r.footprint->repairs.holes_fixed);
  EXPECT_NEAR(r.footprint->area_m2, 100, 1e-9);
}

TEST(Footprint, OverlappingOutersAreUnioned) {
  auto r = make_footprint({square(0, 0, 10), square(5, 0, 10)}, {}, no_simplify());
  ASSERT_TRUE(r.footprint);
  EXPECT_TRUE(r.footprint->repairs.rings_merged);
  EXPECT_NEAR(r.footprint->area_m2, 150, 1e-9);
}

TEST(Footprint, DegenerateRingsAreSkipped) {
  auto one = make_footprint({{{1, 1}}}, {}, FootprintOptions{});
  EXPECT_FALSE(one.footprint);
  EXPECT_EQ(one.skip_reason, "degenerate");
  auto line = make_footprint({{{0, 0}, {5, 0}, {10, 0}}}, {}, FootprintOptions{});
  EXPECT_FALSE(line.footprint);
  EXPECT_EQ(line.skip_reason, "zero_area");
  auto tiny = make_footprint({square(0, 0, 0.1)}, {}, FootprintOptions{});
  EXPECT_FALSE(tiny.footprint);
  EXPECT_EQ(tiny.skip_reason, "zero_area");
}

TEST(Footprint, SimplificationRemovesNoiseWithinBounds) {
  // A 20 m square drawn with 40 nodes per side and 5 mm of jitter.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.005, 0.005);
  std::vector<Vec2> ring;
  const Vec2 corners[4] = {{0, 0}, {20, 0}, {20, 20}, {0, 20}};
  for (int s = 0; s < 4; ++s)
    for (int k = 0; k < 40; ++k) {
      const double t = k / 40.0;
      const Vec2 a = corners[s], b = corners[(s + 1) % 4];
      ring.push_back({a[0] + t * (b[0] - a[0]) + (k ? jitter(rng) : 0), a[1] + t * (b[1] - a[1]) + (k ? jitter(rng) : 0)});
    }
  auto raw = make_footprint({ring}, {}, no_simplify());
  auto simp = make_footprint({ring}, {}, FootprintOptions{});
  ASSERT_TRUE(raw.footprint && simp.footprint);
  EXPECT_TRUE(simp.footprint->simplified);
  EXPECT_EQ(simp.footprint->vertices_out, 4u);
  EXPECT_LE(std::abs(simp.footprint->area_m2 - raw.footprint->area_m2), 0.005 * raw.footprint->area_m2);
  EXPECT_LE(std::hypot(simp.footprint->centroid[0] - raw.footprint->centroid[0],
                       simp.footprint->centroid[1] - raw.footprint->centroid[1]),
            0.02);
}

TEST(Footprint, SimplificationNeverBreaksAreaOrCentroidBounds) {
  // Random star polygons of 2-15 m radius: whatever simplification does, the
  // result stays within 0.5 % area and 2 cm centroid of the repaired input.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> radius(2, 15), wobble(0.9, 1.1);
  FootprintOptions aggressive;
  aggressive.simplify_tolerance_m = 0.5;  // would move things far if unchecked
  int undone = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const double r0 = radius(rng);
    const int n = 5 + trial % 40;
    std::vector<Vec2> ring;
    for (int k = 0; k < n; ++k) {
      const double a = 2 * M_PI * k / n;
      const double r = r0 * wobble(rng);
      ring.push_back({1000 + r * std::cos(a), -500 + r * std::sin(a)});
    }
    auto raw = make_footprint({ring}, {}, no_simplify());
    auto simp = make_footprint({ring}, {}, aggressive);
    ASSERT_TRUE(raw.footprint && simp.footprint) << trial;
    EXPECT_LE(std::abs(simp.footprint->area_m2 - raw.footprint->area_m2), 0.005 * raw.footprint->area_m2) << trial;
    EXPECT_LE(std::hypot(simp.footprint->centroid[0] - raw.footprint->centroid[0],
                         simp.footprint->centroid[1] - raw.footprint->centroid[1]),
              0.02)
        << trial;
    undone += simp.footprint->simplification_undone;
  }
  EXPECT_GT(undone, 0) << "the guard must have rejected some aggressive simplifications";
}

TEST(Triangulate, AreaAndBoundaryOfPolygonWithHole) {
  Polygon2 p;
  p.outer = square(0, 0, 10);
  auto hole = square(2, 2, 3);
  std::reverse(hole.begin(), hole.end());
  p.holes.push_back(hole);
  auto t = triangulate(p);
  EXPECT_NEAR(triangulated_area(t), 91, 1e-9);
  EXPECT_EQ(t.boundary_edges.size(), 8u);
  for (const auto& tri : t.triangles) {
    const Vec2 &a = t.vertices[tri[0]], &b = t.vertices[tri[1]], &c = t.vertices[tri[2]];
    EXPECT_GT((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]), 0) << "triangles must be CCW";
  }
}
