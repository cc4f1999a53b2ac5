// Extruded buildings are closed, outward-facing prisms whose volume is
// footprint area x height.
#include <gtest/gtest.h>

#include <cmath>

#include "meshkit/extrude.hpp"

using namespace raysweep::meshkit;

namespace {

Footprint footprint_of(std::vector<std::vector<Vec2>> outers, std::vector<std::vector<Vec2>> inners = {}) {
  FootprintOptions o;
  o.simplify_tolerance_m = 0;
  auto r = make_footprint(outers, inners, o);
  EXPECT_TRUE(r.footprint);
  return *r.footprint;
}

// Every triangle's normal points out of the solid: a point just outside along
// the normal is outside the prism, a point just inside is inside it.
void expect_outward(const Mesh& m, const Footprint& f, double base, double top) {
  auto inside = [&](const Vec3& p) {
    return p[2] > base && p[2] < top && footprint_contains(f, {p[0], p[1]});
  };
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const Vec3 n = triangle_normal(m, t);
    Vec3 c{0, 0, 0};
    for (auto v : m.triangles[t])
      for (int k = 0; k < 3; ++k) c[k] += m.vertices[v][k] / 3;
    const double e = 1e-3;
    EXPECT_FALSE(inside({c[0] + e * n[0], c[1] + e * n[1], c[2] + e * n[2]})) << "triangle " << t;
    EXPECT_TRUE(inside({c[0] - e * n[0], c[1] - e * n[1], c[2] - e * n[2]})) << "triangle " << t;
  }
}

}  // namespace

TEST(Extrude, BoxIsWatertightWithExactVolume) {
  Footprint f = footprint_of({{{0, 0}, {10, 0}, {10, 20}, {0, 20}}});
  Mesh m;
  std::uint32_t next_face = 0;
  auto stats = extrude_footprint(f, 0, 7, 0, next_face, m);
  EXPECT_EQ(stats.triangles, 12u);
  EXPECT_EQ(stats.faces, 6u);
  EXPECT_EQ(next_face, 6u);
  EXPECT_TRUE(edge_report(m).watertight());
  EXPECT_NEAR(signed_volume(m), 1400, 1e-9);
  expect_outward(m, f, 0, 7);
}

TEST(Extrude, ConcaveLShape) {
  Footprint f = footprint_of({{{0, 0}, {10, 0}, {10, 4}, {4, 4}, {4, 10}, {0, 10}}});
  Mesh m;
  std::uint32_t next_face = 100;
  auto stats = extrude_footprint(f, 0, 3, 0, next_face, m);
  EXPECT_EQ(stats.faces, 8u);  // roof, floor, six walls
  EXPECT_TRUE(edge_report(m).watertight());
  EXPECT_NEAR(signed_volume(m), (100 - 36) * 3, 1e-9);
  expect_outward(m, f, 0, 3);
  for (auto id : m.triangle_face) EXPECT_GE(id, 100u);
}

TEST(Extrude, CourtyardHoleFacesInward) {
  Footprint f = footprint_of({{{0, 0}, {30, 0}, {30, 30}, {0, 30}}}, {{{10, 10}, {20, 10}, {20, 20}, {10, 20}}});
  Mesh m;
  std::uint32_t next_face = 0;
  extrude_footprint(f, 0, 12, 0, next_face, m);
  EXPECT_TRUE(edge_report(m).watertight());
  EXPECT_NEAR(signed_volume(m), (900 - 100) * 12, 1e-6);
  expect_outward(m, f, 0, 12);
}

TEST(Extrude, BuildingPartAboveGround) {
  Footprint f = footprint_of({{{0, 0}, {5, 0}, {5, 5}, {0, 5}}});
  Mesh m;
  std::uint32_t next_face = 0;
  extrude_footprint(f, 12, 20, 3, next_face, m);
  EXPECT_NEAR(signed_volume(m), 25 * 8, 1e-9);
  EXPECT_NEAR(m.bounds().min[2], 12, 1e-12);
  for (auto o : m.triangle_object) EXPECT_EQ(o, 3u);
}

TEST(Extrude, RepairedFootprintsStayClosed) {
  // Bowtie and touching hole: the repaired shapes must still extrude closed.
  Footprint bowtie = footprint_of({{{0, 0}, {10, 10}, {10, 0}, {0, 10}}});
  Mesh a;
  std::uint32_t nf = 0;
  extrude_footprint(bowtie, 0, 5, 0, nf, a);
  EXPECT_TRUE(edge_report(a).watertight()) << "the pinch vertex must not join the two lobes";
  EXPECT_NEAR(signed_volume(a), 50 * 5, 1e-9);

  Footprint touching = footprint_of({{{0, 0}, {10, 0}, {10, 10}, {0, 10}}}, {{{0, 5}, {5, 3}, {5, 7}}});
  Mesh b;
  extrude_footprint(touching, 0, 5, 0, nf, b);
  EXPECT_TRUE(edge_report(b).watertight());
  EXPECT_NEAR(signed_volume(b), 90 * 5, 1e-9);
}
