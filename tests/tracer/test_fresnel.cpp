// First-Fresnel-zone obstruction (the LoS label) against hand-computed
// geometry: r1 = sqrt(lambda d1 d2 / d) at 5.9 GHz, clearances of boxes
// beside, under and across the direct line, and cars in line.
#include <gtest/gtest.h>

#include <cmath>

#include "fresnel_zone.hpp"
#include "tracer_fixtures.hpp"
#include "vehicle_fixtures.hpp"

using namespace raysweep;
using namespace raysweep::test;

namespace {

const double kLambda = tracer::kSpeedOfLight / 5.9e9;

double r1(double d1, double d2) { return std::sqrt(kLambda * d1 * d2 / (d1 + d2)); }

// Ground, and a metal box x in [48, 52], y in [y0, y1], z in [0, top]
// between antennas at (0, 0, 1.5) and (100, 0, 1.5).
tracer::FresnelObstruction box_case(double y0, double y1, double top) {
  meshkit::Scene s;
  add_ground(s, 300);
  add_box_object(s, {48, y0, 0}, {52, y1, top}, "metal", "box");
  tracer::TraceScene scene(s);
  return tracer::fresnel_obstruction(scene, {0, 0, 1.5}, {100, 0, 1.5}, kLambda);
}

}  // namespace

TEST(Fresnel, BoxUnderTheLineClearsByItsGapOverR1) {
  // Top 0.3 m under the line: h = 0.3 m over the box (x 48..52, r1 there
  // within 0.2 % of r1 at mid-path).
  const auto f = box_case(-1, 1, 1.2);
  EXPECT_NEAR(f.static_clearance, 0.3 / r1(50, 50), 2e-3);
  EXPECT_GT(f.static_clearance, 0.3 / r1(50, 50) - 2e-3);
  EXPECT_EQ(f.vehicle_clearance, 1.0);
  EXPECT_EQ(f.clearance, f.static_clearance);
  EXPECT_EQ(tracer::fresnel_class(tracer::LosClass::LOS, f), tracer::LosClass::NLOS);  // 0.27 < 0.6
}

TEST(Fresnel, BoxAcrossTheLineHasNegativeClearanceByItsShallowestSide) {
  // Top 0.3 m above the line, sides 1 m away: the shortest way out is up.
  const auto f = box_case(-1, 1, 1.8);
  EXPECT_NEAR(f.static_clearance, -0.3 / r1(50, 50), 2e-3);
  // Narrow box (0.2 m to each side): out sideways.
  const auto g = box_case(-0.2, 0.2, 3);
  EXPECT_NEAR(g.static_clearance, -0.2 / r1(50, 50), 2e-3);
}

TEST(Fresnel, BoxBesideTheZoneIsClear) {
  const auto f = box_case(3, 5, 3);  // 3 m aside: 2.7 r1
  EXPECT_EQ(f.clearance, 1.0);
  EXPECT_EQ(tracer::fresnel_class(tracer::LosClass::LOS, f), tracer::LosClass::LOS);
  // Just inside 0.6 r1 / just outside.
  const double edge = 0.6 * r1(50, 50);
  EXPECT_LT(box_case(edge - 0.01, 2, 3).clearance, 0.6);
  EXPECT_GT(box_case(edge + 0.01, 2, 3).clearance, 0.6);
}

TEST(Fresnel, ClearanceIsContinuousAsAnObstacleRisesThroughTheLine) {
  double prev = box_case(-1, 1, 1.3).static_clearance;
  for (int cm = 131; cm <= 170; ++cm) {
    const double c = box_case(-1, 1, cm / 100.0).static_clearance;
    EXPECT_LT(c, prev + 1e-9) << cm << " cm";
    EXPECT_LT(prev - c, 0.02) << cm << " cm";  // 1 cm is 0.009 r1
    prev = c;
  }
}

TEST(Fresnel, CarsInLineAreNlosvThoughTheRayClearsTheirRoofs) {
  meshkit::Scene s;
  add_ground(s, 300);
  tracer::TraceScene scene(s);
  const auto car = add_library_model(scene, "passenger");
  scene.set_vehicles({{"a", car, {0, 0, 0}, 0, {0, 0, 0}},
                      {"m", car, {27, 0, 0}, 0, {0, 0, 0}},
                      {"b", car, {54, 0, 0}, 0, {0, 0, 0}}});
  const auto nodes = tracer::vehicle_nodes(scene);
  tracer::TracerConfig cfg;
  cfg.diffuse = cfg.diffraction = false;
  const auto snap = tracer::trace_snapshot(scene, nodes, cfg, {});
  const auto& ab = snap.pairs[1];  // (0, 2): over the middle car
  ASSERT_EQ(ab.tx, 0u);
  ASSERT_EQ(ab.rx, 2u);
  EXPECT_EQ(ab.los_class, tracer::LosClass::LOS);  // the ray passes over its roof
  EXPECT_EQ(ab.fresnel_class, tracer::LosClass::NLOSV);
  EXPECT_LT(ab.fresnel_clearance, 0.6);
  EXPECT_GT(ab.fresnel_clearance, 0.0);
  // Neighbours: only their own cars (excluded) and the ground (excluded).
  EXPECT_EQ(snap.pairs[0].fresnel_class, tracer::LosClass::LOS);
  EXPECT_EQ(snap.pairs[0].fresnel_clearance, 1.0);
}

TEST(Fresnel, GeometricBlockingDecidesFirst) {
  const tracer::FresnelObstruction clear{};
  EXPECT_EQ(tracer::fresnel_class(tracer::LosClass::NLOS, clear), tracer::LosClass::NLOS);
  EXPECT_EQ(tracer::fresnel_class(tracer::LosClass::NLOSV, clear), tracer::LosClass::NLOSV);
  tracer::FresnelObstruction vehicle{0.3, 0.3, 1};
  EXPECT_EQ(tracer::fresnel_class(tracer::LosClass::LOS, vehicle), tracer::LosClass::NLOSV);
  tracer::FresnelObstruction both{0.3, 0.3, 0.5};
  EXPECT_EQ(tracer::fresnel_class(tracer::LosClass::NLOSV, both), tracer::LosClass::NLOS);
}
