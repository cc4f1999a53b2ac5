// Closed-form validation of the path solver: free space (Friis), two-ray over
// ground with the Fresnel coefficient, wall reflection (TE and TM) and slab
// transmission against the ITU-R P.2040 formulas, street-canyon image paths
// and the exhaustive image method. Expected values are computed here from the
// textbook formulas, independently of the tracer's own EM code.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>
#include <set>

#include "closed_forms.hpp"
#include "tracer_fixtures.hpp"

using namespace raysweep;
using namespace raysweep::test;
using cd = std::complex<double>;
using tracer::operator+;
using tracer::operator-;
using tracer::operator*;

namespace {

constexpr double kC = 299792458.0, kEps0 = 8.8541878128e-12, kPi = 3.14159265358979323846;
constexpr double kF = 5.9e9;
const double kLambda = kC / kF;

double db(double x) { return 10 * std::log10(x); }

// Free-space baseband gain of a path of length L (isotropic, matched polarisation).
cd friis(double L) { return kLambda / (4 * kPi * L) * std::polar(1.0, -2 * kPi * L / kLambda); }

// P.2040 complex permittivity from Table 3 constants (f in GHz).
cd eta_p2040(double a, double b, double c, double d) {
  const double g = kF / 1e9;
  return cd(a * std::pow(g, b), -c * std::pow(g, d) / (2 * kPi * kF * kEps0));
}
const cd kGround = eta_p2040(15, -0.1, 0.035, 1.63);      // medium dry ground
const cd kConcrete = eta_p2040(5.24, 0, 0.0462, 0.7822);  // concrete
const cd kGlass = eta_p2040(6.31, 0, 0.0036, 1.3394);     // glass

using closed_form::r_te;
using closed_form::r_tm;
using closed_form::Slab;
Slab slab(cd eta, double d, double c, bool te) { return closed_form::slab(eta, d, c, te, kLambda); }

// Geometrical optics against its closed forms: diffraction and diffuse
// scattering (test_diffraction, test_diffuse) are off, every path is kept.
tracer::TracerConfig config(int depth = 3) {
  tracer::TracerConfig c;
  c.max_depth = depth;
  c.diffuse = false;
  c.diffraction = false;
  c.path_threshold_db = 0;
  return c;
}

const tracer::Path* find_path(const tracer::PairResult& p, std::size_t interactions) {
  for (const auto& path : p.paths)
    if (path.interactions.size() == interactions) return &path;
  return nullptr;
}

}  // namespace

TEST(TracerPhysics, FreeSpaceMatchesFriis) {
  meshkit::Scene empty;
  tracer::TraceScene scene(empty);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (double d : {1.0, 3.7, 10.0, 55.5, 100.0, 333.3, 1000.0}) {
    tracer::Vec3 dir = tracer::normalize({u(rng), u(rng), u(rng)});
    const tracer::Vec3 a{10 * u(rng), 10 * u(rng), 1.5};
    const auto snap = tracer::trace_snapshot(scene, {node("a", a), node("b", a + d * dir)}, config(), {});
    ASSERT_EQ(snap.pairs.size(), 1u);
    const auto& p = snap.pairs[0];
    ASSERT_EQ(p.paths.size(), 1u) << d;
    EXPECT_EQ(p.los_class, tracer::LosClass::LOS);
    // Isotropic vertical polarisation: theta_hat of the two ends lie in the
    // vertical plane of the link and coincide, so a is exactly Friis.
    EXPECT_NEAR(db(std::norm(p.paths[0].a)), db(std::norm(friis(d))), 1e-3) << d;
    EXPECT_NEAR(std::arg(p.paths[0].a / friis(d)), 0.0, 1e-6) << d;
    EXPECT_NEAR(p.paths[0].tau_s, d / kC, 1e-13);
    EXPECT_NEAR(p.paths[0].theta_t, std::acos(dir[2]), 1e-9);
    EXPECT_NEAR(p.paths[0].theta_r, std::acos(-dir[2]), 1e-9);
    EXPECT_NEAR(std::remainder(p.paths[0].phi_t - std::atan2(dir[1], dir[0]), 2 * kPi), 0.0, 1e-9);
  }
}

TEST(TracerPhysics, DipolesScaleFriisByTheirGains) {
  meshkit::Scene empty;
  tracer::TraceScene scene(empty);
  tracer::RadioConfig radio;
  for (auto pattern : {tracer::AntennaPattern::short_dipole, tracer::AntennaPattern::halfwave_dipole}) {
    radio.antenna.pattern = pattern;
    const double g = pattern == tracer::AntennaPattern::short_dipole ? 1.5 : 1.6409224;
    for (double d : {5.0, 50.0, 500.0}) {
      const auto snap = tracer::trace_snapshot(scene, {node("a", {0, 0, 2}), node("b", {d, 0, 2})}, config(), radio);
      ASSERT_EQ(snap.pairs[0].paths.size(), 1u);
      EXPECT_NEAR(db(std::norm(snap.pairs[0].paths[0].a)), db(std::norm(friis(d)) * g * g), 1e-3);
    }
    // Polarisation mismatch: V transmit, H receive gives nothing (checked with
    // antenna_field directly: one pattern per snapshot).
    const auto fv = tracer::antenna_field({pattern, tracer::Polarization::V}, {1, 0, 0}, {1, 0, 0});
    const auto fh = tracer::antenna_field({pattern, tracer::Polarization::H}, {-1, 0, 0}, {0, 1, 0});
    EXPECT_NEAR(tracer::dot(fv, fh), 0.0, 1e-12);
  }
}

// Two-ray model over medium-dry ground: direct + ground-reflected path with
// the TM (vertical polarisation) or TE (horizontal) Fresnel coefficient.
void two_ray(const tracer::Vec3& offset) {
  meshkit::Scene s;
  add_ground(s, 3000, "medium_dry_ground", offset[0], offset[1], offset[2]);
  tracer::TraceScene scene(s);
  for (auto pol : {tracer::Polarization::V, tracer::Polarization::H}) {
    tracer::RadioConfig radio;
    radio.antenna.polarization = pol;
    for (double d : {1.0, 2.0, 5.0, 10.0, 31.6, 100.0, 316.0, 1000.0}) {
      const double h1 = 1.5, h2 = 2.7;
      const auto snap = tracer::trace_snapshot(
          scene, {node("a", offset + tracer::Vec3{0, 0, h1}), node("b", offset + tracer::Vec3{d, 0, h2})}, config(),
          radio);
      const auto& p = snap.pairs[0];
      ASSERT_EQ(p.paths.size(), 2u) << d;
      const double d1 = std::hypot(d, h2 - h1), d2 = std::hypot(d, h1 + h2);
      const double cos_inc = (h1 + h2) / d2;
      // V: pure TM, theta_hat at both ends maps onto e_p with the same sign.
      // H: pure TE; phi_hat of opposite directions are opposite vectors, so
      // both paths carry a factor -1 (the ratio is R_TE, as in the model).
      const bool v = pol == tracer::Polarization::V;
      const cd r = v ? r_tm(kGround, cos_inc) : r_te(kGround, cos_inc);
      const double sign = v ? 1.0 : -1.0;
      const cd a1 = sign * friis(d1), a2 = sign * friis(d2) * r;
      const auto* los = find_path(p, 0);
      const auto* gnd = find_path(p, 1);
      ASSERT_TRUE(los && gnd);
      EXPECT_NEAR(db(std::norm(los->a)), db(std::norm(a1)), 0.01) << d;
      EXPECT_NEAR(db(std::norm(gnd->a)), db(std::norm(a2)), 0.01) << d;
      EXPECT_LT(std::abs(gnd->a - a2), 1e-3 * std::abs(a2)) << d;  // phase too
      EXPECT_LT(std::abs(los->a - a1), 1e-6 * std::abs(a1)) << d;
      EXPECT_NEAR(los->tau_s, d1 / kC, 1e-12);
      EXPECT_NEAR(gnd->tau_s, d2 / kC, 1e-12);
      EXPECT_NEAR(db(p.stats.gain_coherent), db(std::norm(a1 + a2)), 0.01) << d;
      EXPECT_NEAR(db(p.stats.gain_incoherent), db(std::norm(a1) + std::norm(a2)), 0.01) << d;
      EXPECT_EQ(gnd->interactions[0].type, tracer::InteractionType::specular);
      EXPECT_NEAR(gnd->interactions[0].point[2], offset[2], 1e-9);
    }
  }
}

TEST(TracerPhysics, TwoRayOverGroundMatchesFresnelModel) { two_ray({0, 0, 0}); }

// The same far from the origin (UTM-like coordinates): double precision paths.
TEST(TracerPhysics, TwoRayFarFromOrigin) { two_ray({512345.0, 5412345.0, 95.0}); }

TEST(TracerPhysics, WallReflectionTeAndTmMatchP2040Slab) {
  meshkit::Scene s;
  add_wall_x(s, 10, 500, "concrete", "wall");
  tracer::TraceScene scene(s);
  for (auto pol : {tracer::Polarization::V, tracer::Polarization::H}) {
    tracer::RadioConfig radio;
    radio.antenna.polarization = pol;
    for (double y0 : {0.5, 2.0, 5.0, 10.0, 20.0, 50.0, 150.0}) {
      // Incidence plane horizontal: V is TE, H is TM.
      const auto snap =
          tracer::trace_snapshot(scene, {node("a", {0, -y0, 1}), node("b", {0, y0, 1})}, config(1), radio);
      const auto* refl = find_path(snap.pairs[0], 1);
      ASSERT_TRUE(refl) << y0;
      const double L = 2 * std::hypot(10.0, y0);
      const double cos_inc = 10.0 / std::hypot(10.0, y0);
      const bool te = pol == tracer::Polarization::V;
      // phi_hat at tx and rx point the same way along the wall while the TM
      // basis turns with the ray: H sees -R_TM in these antenna bases.
      const cd expect = friis(L) * (te ? 1.0 : -1.0) * slab(kConcrete, 0.3, cos_inc, te).r;
      EXPECT_NEAR(db(std::norm(refl->a)), db(std::norm(expect)), 0.01) << y0;
      EXPECT_LT(std::abs(refl->a - expect), 1e-3 * std::abs(expect)) << y0;
      EXPECT_NEAR(refl->interactions[0].point[0], 10.0, 1e-9);
      EXPECT_NEAR(refl->interactions[0].point[1], 0.0, 1e-9);
    }
  }
}

TEST(TracerPhysics, SlabTransmissionThroughGlassAndConcrete) {
  for (auto [material, eta, thickness] : {std::tuple{"glass", kGlass, 0.005}, std::tuple{"concrete", kConcrete, 0.3}}) {
    meshkit::Scene s;
    add_wall_x(s, 5, 500, material, "pane");
    tracer::TraceScene scene(s);
    for (auto pol : {tracer::Polarization::V, tracer::Polarization::H}) {
      tracer::RadioConfig radio;
      radio.antenna.polarization = pol;
      for (double y : {0.0, 3.0, 10.0, 40.0}) {
        const auto snap = tracer::trace_snapshot(scene, {node("a", {0, 0, 1}), node("b", {10, y, 1})}, config(), radio);
        const auto& p = snap.pairs[0];
        EXPECT_EQ(p.los_class, tracer::LosClass::NLOS);
        ASSERT_EQ(p.paths.size(), 1u) << material << " " << y;
        ASSERT_EQ(p.paths[0].interactions.size(), 1u);
        EXPECT_EQ(p.paths[0].interactions[0].type, tracer::InteractionType::refraction);
        const double d = std::hypot(10.0, y);
        const bool v = pol == tracer::Polarization::V;  // TE; H is TM (and phi_hat flips: -1)
        const cd expect = (v ? 1.0 : -1.0) * friis(d) * slab(eta, thickness, 10.0 / d, v).t;
        EXPECT_NEAR(db(std::norm(p.paths[0].a)), db(std::norm(expect)), 0.01) << material << " " << y;
        EXPECT_LT(std::abs(p.paths[0].a - expect), 1e-3 * std::abs(expect));
      }
    }
  }
}

TEST(TracerPhysics, MaterialOverridesReachThePaths) {
  meshkit::Scene s;
  add_wall_x(s, 5, 500, "glass", "pane");
  tracer::TraceScene scene(s);
  auto cfg = config();
  cfg.materials["glass"].thickness_m = 0.02;
  const auto snap = tracer::trace_snapshot(scene, {node("a", {0, 0, 1}), node("b", {10, 0, 1})}, cfg, {});
  ASSERT_EQ(snap.pairs[0].paths.size(), 1u);
  EXPECT_NEAR(db(std::norm(snap.pairs[0].paths[0].a)), db(std::norm(friis(10) * slab(kGlass, 0.02, 1, true).t)), 0.01);
}

// Two parallel walls y = +-W/2: images alternate between them, so depth k
// adds exactly two paths, of lengths known from the 1-D image positions.
void street_canyon(int depth, tracer::CandidateSearch search) {
  const double W = 20, D = 120, yt = 3, yr = -6;
  meshkit::Scene s;
  add_wall_y(s, W / 2, 600, "concrete", "north");
  add_wall_y(s, -W / 2, 600, "concrete", "south");
  tracer::TraceScene scene(s);
  auto cfg = config(depth);
  cfg.candidates = search;
  cfg.rays_per_source = 16384;
  const auto snap = tracer::trace_snapshot(scene, {node("a", {0, yt, 0}), node("b", {D, yr, 0})}, cfg, {});
  const auto& p = snap.pairs[0];
  std::multiset<long long> expected;  // path lengths in micrometres
  expected.insert(std::llround(std::hypot(D, yt - yr) * 1e6));
  for (int first = 0; first < 2; ++first)
    for (int k = 1; k <= depth; ++k) {
      double y = yt;
      for (int i = 0; i < k; ++i) y = ((i + first) % 2 == 0) ? W - y : -W - y;
      expected.insert(std::llround(std::hypot(D, y - yr) * 1e6));
    }
  std::multiset<long long> found;
  for (const auto& path : p.paths) found.insert(std::llround(path.tau_s * kC * 1e6));
  EXPECT_EQ(p.paths.size(), static_cast<std::size_t>(1 + 2 * depth));
  EXPECT_EQ(found, expected);
}

TEST(TracerPhysics, StreetCanyonDepth3HasTheSevenImagePaths) {
  street_canyon(3, tracer::CandidateSearch::sbr);
  street_canyon(3, tracer::CandidateSearch::exhaustive);
}

TEST(TracerPhysics, StreetCanyonDepth6) { street_canyon(6, tracer::CandidateSearch::sbr); }

// Shoot-and-bounce must find what the exhaustive image method finds.
TEST(TracerPhysics, ShootAndBounceFindsEveryExhaustivePath) {
  meshkit::Scene s;
  add_ground(s, 500);
  add_wall_y(s, 12, 300, "brick", "north");
  add_box_object(s, {20, -30, 0}, {35, -8, 12}, "concrete", "block");
  add_box_object(s, {-25, 5, 0}, {-15, 11, 2.5}, "glass", "kiosk");
  tracer::TraceScene scene(s);
  const std::vector<tracer::Node> nodes = {node("a", {0, 0, 1.5}), node("b", {40, 3, 1.6}), node("c", {-30, -2, 5}),
                                           node("d", {10, -20, 2})};
  auto cfg = config(3);
  cfg.sbr_transmission_loss_db = 1e9;  // same search space as the exhaustive method
  cfg.rays_per_source = 16384;
  auto exhaustive = cfg;
  exhaustive.candidates = tracer::CandidateSearch::exhaustive;
  const auto a = tracer::trace_snapshot(scene, nodes, cfg, {});
  const auto b = tracer::trace_snapshot(scene, nodes, exhaustive, {});
  std::size_t total = 0;
  for (std::size_t i = 0; i < a.pairs.size(); ++i) {
    std::set<long long> sbr;
    for (const auto& p : a.pairs[i].paths) sbr.insert(std::llround(p.tau_s * 1e14));
    for (const auto& p : b.pairs[i].paths) {
      EXPECT_TRUE(sbr.count(std::llround(p.tau_s * 1e14)))
          << "pair " << i << ": missing path of " << p.interactions.size() << " interactions, "
          << db(std::norm(p.a)) << " dB";
      ++total;
    }
    EXPECT_EQ(a.pairs[i].paths.size(), b.pairs[i].paths.size()) << "pair " << i;
  }
  EXPECT_GT(total, 40u);
}
