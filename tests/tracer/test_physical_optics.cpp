// Physical optics on finite facets (tracer/src/em/physical_optics.hpp)
// against independent truth: rectangles by products of Fresnel integrals,
// square metal plates by brute-force Kirchhoff integration of the exact
// spherical phase and amplitude, the small-facet and large-facet limits.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <complex>
#include <vector>

#include "em/physical_optics.hpp"
#include "em/utd.hpp"
#include "tracer/solver.hpp"
#include "tracer/trace_scene.hpp"
#include "tracer_fixtures.hpp"

namespace {

using namespace raysweep::tracer;

constexpr double kLambda = 299792458.0 / 5.9e9;
constexpr double kK = 2 * kPi / kLambda;

double db(cdouble f) { return 20 * std::log10(std::abs(f)); }

// int_{x0}^{x1} exp(-j x^2) dx by the Fresnel integrals C and S.
cdouble fresnel_1d(double x0, double x1) {
  const double s = std::sqrt(2 / kPi);
  auto at = [&](double x) {
    const auto [c, sn] = fresnel_cs(x * s);
    return std::sqrt(kPi / 2) * cdouble(c, -sn);
  };
  return at(x1) - at(x0);
}

std::vector<std::array<double, 4>> rectangle(double x0, double x1, double y0, double y1) {
  return {{x0, y0, x1, y0}, {x1, y0, x1, y1}, {x1, y1, x0, y1}, {x0, y1, x0, y0}};
}

TEST(PhysicalOptics, RectangleIsTheProductOfFresnelIntegrals) {
  // (j / pi) int int exp(-j (x^2 + y^2)) over [x0, x1] x [y0, y1], the origin
  // inside, on an edge, at a corner and outside; edges beyond a phase of 20
  // radians are summed by their asymptotic series (long and far ones below,
  // one whose edge passes 1e-170 from the origin: its square underflows).
  const std::array<std::array<double, 4>, 10> boxes = {{{-0.3, 0.4, -0.2, 0.1},
                                                       {-2, 3, -4, 1.5},
                                                       {0, 2, -1, 1},
                                                       {0, 1.2, 0, 0.7},
                                                       {1, 6, 0.5, 2},
                                                       {-9, 9, -9, 9},
                                                       {-40, 35, 2, 3},
                                                       {-3, 25, -25, 4},
                                                       {7, 12, -6, 8},
                                                       {-10, 10, 1e-170, 5}}};
  for (const auto& b : boxes) {
    const cdouble truth = cdouble(0, 1 / kPi) * fresnel_1d(b[0], b[1]) * fresnel_1d(b[2], b[3]);
    const cdouble got = fresnel_region_factor(rectangle(b[0], b[1], b[2], b[3]));
    EXPECT_NEAR(std::abs(got - truth), 0, 1e-9 * std::max(1.0, std::abs(truth))) << b[0] << " " << b[2];
  }
}

TEST(PhysicalOptics, RegionsAddUpAndSharedEdgesCancel) {
  // A square as two triangles (the diagonal in both directions) and as one
  // outline; the whole plane's limit is 1, an empty region's 0.
  const std::vector<std::array<double, 4>> t1 = {{-1, -1, 2, -1}, {2, -1, 2, 1.5}, {2, 1.5, -1, -1}};
  const std::vector<std::array<double, 4>> t2 = {{-1, -1, 2, 1.5}, {2, 1.5, -1, 1.5}, {-1, 1.5, -1, -1}};
  const cdouble square = fresnel_region_factor(rectangle(-1, 2, -1, 1.5));
  EXPECT_NEAR(std::abs(fresnel_region_factor(t1) + fresnel_region_factor(t2) - square), 0, 1e-12);
  // Each straight edge q away leaves a ripple of at most 1 / (2 sqrt(pi) q).
  EXPECT_LT(std::abs(fresnel_region_factor(rectangle(-60, 60, -60, 60)) - 1.0), 4 / (2 * std::sqrt(kPi) * 60));
  EXPECT_EQ(fresnel_region_factor({}), cdouble(0));
}

// A metal square plate of side `side` in the plane z = 0, centred at
// (cx, cy), lit from a source at distance d1 and seen at d2, both at angle
// `theta` from the normal in the x-z plane about the origin (the specular
// point on the plate's plane).
struct Plate {
  double side, cx, cy, d1, d2, theta;
  Vec3 tx() const { return {-d1 * std::sin(theta), 0, d1 * std::cos(theta)}; }
  Vec3 rx() const { return {d2 * std::sin(theta), 0, d2 * std::cos(theta)}; }
  std::vector<std::array<Vec3, 3>> triangles() const {
    const double h = side / 2;
    const Vec3 a{cx - h, cy - h, 0}, b{cx + h, cy - h, 0}, c{cx + h, cy + h, 0}, d{cx - h, cy + h, 0};
    return {{a, b, c}, {a, c, d}};
  }
  cdouble po() const {
    return facet_factor(triangles(), {0, 0, 1}, tx(), rx(), kK);
  }
  // Kirchhoff: the field of the PO currents of a perfect conductor over the
  // image field, exact distances, amplitudes and (scalar) obliquity, midpoint rule at
  // about 4 samples per radian of phase.
  cdouble kirchhoff() const {
    const Vec3 s = tx(), r = rx();
    const double h = side / 2;
    const double phase_span = kK * side * (std::fabs(cx) + std::fabs(cy) + side) * (1 / d1 + 1 / d2) + 1;
    const int n = std::max(60, static_cast<int>(4 * phase_span));
    const double step = side / n;
    cdouble sum = 0;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const Vec3 p{cx - h + (i + 0.5) * step, cy - h + (j + 0.5) * step, 0};
        const double r1 = norm(p - s), r2 = norm(r - p);
        const double obliquity = 0.5 * (s[2] / r1 + r[2] / r2);  // Fresnel-Kirchhoff's, reciprocal
        sum += obliquity * std::polar(1.0 / (r1 * r2), -kK * (r1 + r2));
      }
    sum *= step * step;
    const double l0 = d1 + d2;
    return cdouble(0, kK / (2 * kPi)) * l0 * std::polar(1.0, kK * l0) * sum;
  }
};

TEST(PhysicalOptics, SquareMetalPlatesMatchKirchhoffIntegration) {
  // Sides 0.1-2 m, ends 5-50 m, normal and oblique, the specular point at the
  // centre and near an edge (the tracer's case: GO's path exists), and off
  // the plate. Within 0.5 dB, except where the second-order phase reaches
  // its limit: a 2 m plate seen from 5-10 m, 1 dB with the specular point on
  // it; off it, 2 m plates are left out (5 dB at 5 m).
  for (double side : {0.1, 0.3, 1.0, 2.0})
    for (const auto& [d1, d2] : {std::pair{5.0, 5.0}, std::pair{10.0, 30.0}, std::pair{50.0, 50.0}})
      for (double theta : {0.0, 40 * kPi / 180})
        for (const auto& [fx, fy] : {std::pair{0.0, 0.0}, std::pair{0.35, 0.1}, std::pair{0.8, 0.0}}) {
          const bool on_plate = fx < 0.5;
          if (!on_plate && side > 1.5) continue;
          const Plate plate{side, fx * side, fy * side, d1, d2, theta};
          const cdouble truth = plate.kirchhoff();
          if (db(truth) < -30) continue;  // far below GO: relative errors mean nothing there
          const double tol = side > 1.5 && std::min(d1, d2) < 20 ? 1.0 : 0.5;
          EXPECT_NEAR(db(plate.po()), db(truth), tol)
              << "side " << side << " d1 " << d1 << " d2 " << d2 << " theta " << theta << " offset " << fx;
        }
}

TEST(PhysicalOptics, SmallFacetReturnsItsAreaOverLambdaD) {
  // A 5 cm square at 20 m + 20 m, normal incidence: F = j A / (lambda d),
  // d = d1 d2 / (d1 + d2), to within the quadratic phase across it.
  const Plate plate{0.05, 0, 0, 20, 20, 0};
  const cdouble expect(0, 0.05 * 0.05 / (kLambda * 10));
  EXPECT_NEAR(std::abs(plate.po()) / std::abs(expect), 1, 1e-4);
  EXPECT_NEAR(std::arg(plate.po() / expect), 0, 0.01);
}

TEST(PhysicalOptics, LargePlatesTendToTheMirror) {
  // A plate N Fresnel radii wide (r1 = sqrt(lambda d), d = d1 d2 / (d1 + d2)),
  // its specular point near the centre: the factor is the rectangle's closed
  // form in the plate's principal axes (scaled by sqrt(k h / 2), h = (1/d1 +
  // 1/d2) across the plane of incidence and cos^2 theta times that along it),
  // whose ripple about GO is the edges' true field (-1.9 dB at 3 radii, 0.3 dB
  // at 24: "GO within 0.1 dB from 3 radii on" is not a property of PO). Once
  // every edge lies 4 Fresnel radii from the specular point (scaled: 4 sqrt(pi);
  // the zone is 1 / cos(theta) longer along the plane of incidence) the
  // factor is GO's 1.
  const double d1 = 10, d2 = 30, theta = 0.5;
  const double r1 = std::sqrt(kLambda * d1 * d2 / (d1 + d2));
  const double s_across = std::sqrt(kK / 2 * (1 / d1 + 1 / d2)), s_along = s_across * std::cos(theta);
  for (double radii : {3.0, 6.0, 8.5, 10.0, 24.0, 48.0}) {
    const double w = radii * r1, cx = 0.1 * r1, cy = 0.2 * r1;
    const Plate plate{w, cx, cy, d1, d2, theta};
    const cdouble closed = cdouble(0, 1 / kPi) * fresnel_1d(s_along * (cx - w / 2), s_along * (cx + w / 2)) *
                           fresnel_1d(s_across * (cy - w / 2), s_across * (cy + w / 2));
    const bool covers =
        std::min(s_along * (w / 2 - cx), s_across * (w / 2 - cy)) >= 4 * std::sqrt(kPi);  // 4 r1 in scaled units
    if (covers)
      EXPECT_EQ(plate.po(), cdouble(1.0)) << radii;
    else
      EXPECT_NEAR(std::abs(plate.po() - closed), 0, 1e-6) << radii;
    EXPECT_LT(std::abs(closed - 1.0) * radii, 1.5) << radii;
  }
}

// The tracer with `facet_reflection`: a vehicle whose body is one metal
// plate (side `side`, vertical, facing +y, centred at x = 0 of the model,
// z in [1, 1 + side]) at `offset` along x, and two fixed antennas 8 m in
// front of it, 12 m apart; the reflection path's amplitude.
cdouble plate_vehicle_path(double side, double offset, raysweep::tracer::FacetReflection mode) {
  namespace mk = raysweep::meshkit;
  mk::Scene plate;
  const double h = side / 2;
  raysweep::test::add_quad(plate, "metal", "plate", {-h, 0, 1}, {h, 0, 1}, {h, 0, 1 + side}, {-h, 0, 1 + side});
  TraceScene scene{mk::Scene{}};
  const auto model = scene.add_vehicle_model("plate", plate, {0, 0, 3});
  scene.set_vehicles({VehiclePose{"v", model, {offset, 0, 0}, 0, {0, 0, 0}}});
  const double z = 1 + h;
  const std::vector<Node> nodes = {raysweep::test::node("a", {-6, 8, z}), raysweep::test::node("b", {6, 8, z})};
  TracerConfig cfg;
  cfg.max_depth = 1;
  cfg.candidates = CandidateSearch::exhaustive;
  cfg.diffuse = false;
  cfg.diffraction = false;
  cfg.vehicle_diffraction = false;
  cfg.path_threshold_db = 0;
  cfg.range_margin_db = 1000;
  cfg.facet_reflection = mode;
  const auto snap = trace_pairs(scene, nodes, {{0, 1}}, cfg, {});
  for (const auto& p : snap.pairs.at(0).paths)
    if (p.interactions.size() == 1) return p.a;
  return 0.0;
}

TEST(PhysicalOptics, TracerWeightsAVehicleFacetByItsKirchhoffField) {
  // The PO path over the GO path is the plate's Kirchhoff field over its
  // image (brute force, as above): the same path, a fraction of its power.
  using raysweep::tracer::FacetReflection;
  for (double side : {0.2, 0.5, 1.5})
    for (double offset : {0.0, 0.3}) {
      if (offset >= side / 2) continue;
      const cdouble go = plate_vehicle_path(side, offset, FacetReflection::go);
      const cdouble po = plate_vehicle_path(side, offset, FacetReflection::po);
      ASSERT_GT(std::abs(go), 0) << side;
      // The plate's frame: centred at (offset, 0) in its plane, the ends 10 m
      // away at 36.87 degrees from its normal.
      const Plate plate{side, offset, 0, 10, 10, std::atan2(6.0, 8.0)};
      const cdouble truth = plate.kirchhoff();
      EXPECT_NEAR(db(po / go), db(truth), 0.5) << "side " << side << " offset " << offset;
      EXPECT_LT(std::abs(std::arg(po / go / truth)), 0.2) << "side " << side << " offset " << offset;
    }
}

// The plate slid along so that the specular point lies off it: as infinite
// mirrors there is no path; by physical optics the plate still lights the
// receiver with its Kirchhoff field (an edge's tail), up to two first-zone
// radii off its outline (r1 = 0.50 m here), and not beyond. The same power
// as brute-force integration over the plate times the mirror's path.
TEST(PhysicalOptics, TracerKeepsAFacetWhoseSpecularPointLiesJustOffIt) {
  using raysweep::tracer::FacetReflection;
  const double side = 0.5;
  const cdouble mirror = plate_vehicle_path(side, 0.0, FacetReflection::go);
  ASSERT_GT(std::abs(mirror), 0);
  const double r1 = std::sqrt(kLambda * 5.0);
  for (double off : {0.3, 0.6, 0.9}) {  // the specular point's distance from the plate's edge
    const double offset = side / 2 + off;
    EXPECT_EQ(plate_vehicle_path(side, offset, FacetReflection::go), cdouble(0)) << off;
    const cdouble po = plate_vehicle_path(side, offset, FacetReflection::po);
    const Plate plate{side, offset, 0, 10, 10, std::atan2(6.0, 8.0)};
    const cdouble truth = plate.kirchhoff();
    ASSERT_GT(std::abs(po), 0) << off;
    std::printf("specular point %.1f m off the plate: tracer %.2f dB, Kirchhoff %.2f dB of the mirror\n", off,
                db(po / mirror), db(truth));
    EXPECT_NEAR(db(po / mirror), db(truth), 1.0) << off;
    EXPECT_LT(db(truth), -6) << off;  // an edge's tail, well below the mirror
  }
  EXPECT_EQ(plate_vehicle_path(side, side / 2 + 2.3 * r1, FacetReflection::po), cdouble(0));
}

}  // namespace
