// Electromagnetics checked against independent truth: energy conservation,
// a characteristic-matrix (thin-film optics) solution of the same slab,
// Brewster's angle, perfect-conductor limits, hand-computed P.2040 values and
// the directivity integral of each antenna pattern.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "meshkit/materials.hpp"
#include "tracer/em/antenna.hpp"
#include "tracer/em/coefficients.hpp"
#include "tracer/em/materials.hpp"

namespace {

using namespace raysweep::tracer;

constexpr double kF = 5.9e9;  // ITS band carrier
constexpr double kDeg = kPi / 180;

RadioMaterial slab(double eps_r, double sigma, double thickness_m, double f = kF) {
  RadioMaterial m;
  m.name = "test";
  m.eps_r = eps_r;
  m.sigma = sigma;
  m.thickness_m = thickness_m;
  m.frequency_hz = f;
  return m;
}

// Single layer in air by the characteristic matrix of thin-film optics
// (Macleod), derived for exp(+jwt) from continuity of the tangential fields:
//   [B; C] = [[cos d, j sin d / Y], [j Y sin d, cos d]] [1; Y0],
//   r = (Y0 B - C) / (Y0 B + C), t = 2 Y0 / (Y0 B + C), d = k0 h kz/k0.
// TE works on (E_y, H_x) with admittances Y = kz/k0 (air: cos theta); TM on
// (H_y, E_x) with impedances Z = (kz/k0) / eta (air: cos theta), whose r is the
// H-field ratio, i.e. E along e_p = e_s x k as P.2040's R_TM. The matrix is
// even in kz, so it does not depend on which square root em.cpp picks.
struct MatrixResult {
  cdouble r_te, t_te, r_tm, t_tm;
};
MatrixResult characteristic_matrix(cdouble eta, double thickness_m, double f, double cos_theta) {
  const double k0 = 2 * kPi * f / kSpeedOfLight;
  const double sin2 = 1 - cos_theta * cos_theta;
  const cdouble kz_rel = std::sqrt(eta - sin2);
  const cdouble delta = k0 * thickness_m * kz_rel;
  const cdouble j(0, 1);
  auto solve = [&](cdouble y, double y0, cdouble& r, cdouble& t) {
    const cdouble b = std::cos(delta) + j * std::sin(delta) / y * y0;
    const cdouble c = j * y * std::sin(delta) + std::cos(delta) * y0;
    r = (y0 * b - c) / (y0 * b + c);
    // t relates the fields at the back face to those at the front; the slab
    // convention refers T to free space over the same thickness.
    t = 2 * y0 / (y0 * b + c) * std::exp(j * k0 * thickness_m * cos_theta);
  };
  MatrixResult out;
  solve(kz_rel, cos_theta, out.r_te, out.t_te);
  solve(kz_rel / eta, cos_theta, out.r_tm, out.t_tm);
  return out;
}

void expect_near_c(cdouble a, cdouble b, double tol, const std::string& what) {
  EXPECT_NEAR(a.real(), b.real(), tol) << what;
  EXPECT_NEAR(a.imag(), b.imag(), tol) << what;
}

bool finite(cdouble z) { return std::isfinite(z.real()) && std::isfinite(z.imag()); }

// ---------------------------------------------------------------- slabs

TEST(Slab, LosslessConservesEnergy) {
  for (double thickness : {0.001, 0.005, 0.0127, 0.05, 0.3})
    for (int deg = 0; deg <= 89; ++deg) {
      const auto s = slab_coefficients(slab(6.31, 0, thickness), std::cos(deg * kDeg));
      const std::string at = "d=" + std::to_string(thickness) + " deg=" + std::to_string(deg);
      EXPECT_NEAR(std::norm(s.r.te) + std::norm(s.t.te), 1.0, 1e-12) << "TE " << at;
      EXPECT_NEAR(std::norm(s.r.tm) + std::norm(s.t.tm), 1.0, 1e-12) << "TM " << at;
    }
}

TEST(Slab, LossyNeverCreatesEnergy) {
  for (const char* name : {"concrete", "glass", "brick", "wood", "plasterboard"}) {
    const auto m = radio_material(name, kF);
    for (int deg = 0; deg <= 89; deg += 2) {
      const auto s = slab_coefficients(m, std::cos(deg * kDeg));
      EXPECT_LT(std::norm(s.r.te) + std::norm(s.t.te), 1.0) << name << " " << deg;
      EXPECT_LT(std::norm(s.r.tm) + std::norm(s.t.tm), 1.0) << name << " " << deg;
    }
  }
}

// Most callers reflect only: slab_reflection skips the transmission's
// exponential and divisions and must give the same bits as the full slab.
TEST(Slab, ReflectionAloneIsTheFullSlabsReflectionBitForBit) {
  auto same = [](cdouble a, cdouble b) {
    return std::memcmp(&a, &b, sizeof a) == 0;
  };
  std::vector<RadioMaterial> materials;
  for (const char* name : {"concrete", "glass", "brick", "wood", "plasterboard", "metal", "medium_dry_ground"})
    materials.push_back(radio_material(name, kF));
  for (double thickness : {0.001, 0.0127, 0.3}) materials.push_back(slab(6.31, 0, thickness));  // lossless
  materials.push_back(slab(1.0, 0, 0.05));                                                     // vacuum
  int compared = 0;
  for (const auto& m : materials)
    for (int k = 0; k <= 2000; ++k) {
      const double c = k / 2000.0;  // 0 (grazing) and 1 (normal) included
      const TeTm r = slab_reflection(m, c);
      const SlabCoefficients full = slab_coefficients(m, c);
      EXPECT_TRUE(same(r.te, full.r.te) && same(r.tm, full.r.tm)) << m.name << " cos " << c;
      ++compared;
    }
  EXPECT_EQ(compared, 11 * 2001);
  RadioMaterial no_frequency = slab(4.0, 0, 0.1);
  no_frequency.frequency_hz = 0;
  EXPECT_THROW(slab_reflection(no_frequency, 0.5), std::invalid_argument);
}

TEST(Slab, MatchesCharacteristicMatrixAtNormalAndOblique) {
  for (const char* name : {"glass", "concrete"}) {
    for (double thickness : {0.001, 0.005, 0.02, 0.1, 0.3}) {
      MaterialOverride o;
      o.thickness_m = thickness;
      const auto m = radio_material(name, kF, o);
      ASSERT_GT(-m.eta().imag(), 0.0) << "the comparison is meant to cover a lossy slab";
      for (int deg : {0, 10, 30, 45, 60, 75, 85, 89}) {
        const double c = std::cos(deg * kDeg);
        const auto s = slab_coefficients(m, c);
        const auto ref = characteristic_matrix(m.eta(), thickness, kF, c);
        const std::string at = std::string(name) + " d=" + std::to_string(thickness) + " deg=" + std::to_string(deg);
        expect_near_c(s.r.te, ref.r_te, 1e-9, "R_TE " + at);
        expect_near_c(s.t.te, ref.t_te, 1e-9, "T_TE " + at);
        expect_near_c(s.r.tm, ref.r_tm, 1e-9, "R_TM " + at);
        expect_near_c(s.t.tm, ref.t_tm, 1e-9, "T_TM " + at);
      }
    }
  }
}

TEST(Slab, HalfWaveLayerIsTransparentAtNormalIncidence) {
  // Optical thickness lambda/2: the two face reflections cancel exactly.
  const double eps = 6.31;
  const double lambda = kSpeedOfLight / kF;
  const double d = lambda / (2 * std::sqrt(eps));
  const auto s = slab_coefficients(slab(eps, 0, d), 1.0);
  EXPECT_LT(std::abs(s.r.te), 1e-12);
  EXPECT_LT(std::abs(s.r.tm), 1e-12);
  EXPECT_NEAR(std::abs(s.t.te), 1.0, 1e-12);
}

TEST(Slab, VacuumSlabIsInvisible) {
  // Transmission referenced to free space: no material, no phase.
  for (double c : {0.1, 0.5, 1.0}) {
    const auto s = slab_coefficients(slab(1, 0, 0.2), c);
    expect_near_c(s.r.te, 0.0, 1e-13, "R_TE");
    expect_near_c(s.r.tm, 0.0, 1e-13, "R_TM");
    expect_near_c(s.t.te, 1.0, 1e-12, "T_TE");
    expect_near_c(s.t.tm, 1.0, 1e-12, "T_TM");
  }
}

TEST(Slab, ThickLossyApproachesHalfSpace) {
  MaterialOverride o;
  o.thickness_m = 5.0;  // concrete at 5.9 GHz: amplitude decays ~15 Np/m
  const auto m = radio_material("concrete", kF, o);
  for (int deg = 0; deg <= 85; deg += 5) {
    const double c = std::cos(deg * kDeg);
    const auto s = slab_coefficients(m, c);
    const auto r = interface_reflection(m.eta(), c);
    expect_near_c(s.r.te, r.te, 1e-12, "TE " + std::to_string(deg));
    expect_near_c(s.r.tm, r.tm, 1e-12, "TM " + std::to_string(deg));
    EXPECT_LT(std::abs(s.t.te), 1e-12);
    EXPECT_LT(std::abs(s.t.tm), 1e-12);
  }
}

TEST(Slab, ZeroThicknessIsHalfSpace) {
  const auto m = radio_material("medium_dry_ground", kF);
  ASSERT_EQ(m.thickness_m, 0.0);
  for (double c : {0.0, 0.3, 1.0}) {
    const auto s = slab_coefficients(m, c);
    const auto r = interface_reflection(m.eta(), c);
    EXPECT_EQ(s.r.te, r.te);
    EXPECT_EQ(s.r.tm, r.tm);
    EXPECT_EQ(s.t.te, 0.0);
    EXPECT_EQ(s.t.tm, 0.0);
  }
}

// ------------------------------------------------------------ interfaces

TEST(Interface, NormalIncidenceIsTextbookFresnel) {
  // (1 - n) / (1 + n) for E; TM in the e_p = e_s x k basis has the other sign.
  const double n = std::sqrt(6.31);
  const auto r = interface_reflection(6.31, 1.0);
  EXPECT_NEAR(r.te.real(), (1 - n) / (1 + n), 1e-15);
  EXPECT_NEAR(r.tm.real(), (n - 1) / (n + 1), 1e-15);
}

TEST(Interface, BrewsterAngleOnlyForTM) {
  for (double eps : {2.73, 5.24, 6.31, 30.0}) {
    const double theta_b = std::atan(std::sqrt(eps));
    const auto r = interface_reflection(eps, std::cos(theta_b));
    EXPECT_LT(std::abs(r.tm), 1e-12) << eps;
    // |R_TE| grows monotonically from its normal-incidence value.
    const double te_min = (std::sqrt(eps) - 1) / (std::sqrt(eps) + 1);
    for (int deg = 0; deg <= 90; ++deg)
      EXPECT_GE(std::abs(interface_reflection(eps, std::cos(deg * kDeg)).te), te_min - 1e-15) << eps << " " << deg;
    // Away from Brewster the TM reflection is not zero.
    EXPECT_GT(std::abs(interface_reflection(eps, std::cos(theta_b - 5 * kDeg)).tm), 1e-3);
    EXPECT_GT(std::abs(interface_reflection(eps, std::cos(theta_b + 5 * kDeg)).tm), 1e-3);
  }
}

TEST(Interface, GrazingReflectsWithMinusOne) {
  for (const char* name : {"concrete", "glass", "metal", "wet_ground", "very_dry_ground"}) {
    const auto m = radio_material(name, kF);
    const auto r = interface_reflection(m.eta(), 0.0);
    expect_near_c(r.te, -1.0, 1e-12, std::string(name) + " TE");
    expect_near_c(r.tm, -1.0, 1e-12, std::string(name) + " TM");
    const auto s = slab_coefficients(m, 0.0);
    expect_near_c(s.r.te, -1.0, 1e-12, std::string(name) + " slab TE");
    expect_near_c(s.r.tm, -1.0, 1e-12, std::string(name) + " slab TM");
    EXPECT_EQ(s.t.te, 0.0);
    EXPECT_EQ(s.t.tm, 0.0);
  }
  // Lossless slab whose q is a multiple of pi at grazing: 0/0 in the formula.
  const double lambda = kSpeedOfLight / kF;
  const auto s = slab_coefficients(slab(5.0, 0, lambda / 4), 0.0);  // q = k0 d sqrt(4) = pi
  EXPECT_TRUE(finite(s.r.te) && finite(s.r.tm));
  expect_near_c(s.r.te, -1.0, 1e-12, "resonant TE");
}

TEST(Interface, LossyRootDecays) {
  // The wave inside must decay: Im sqrt(eta - sin^2) <= 0 for exp(+jwt), so
  // transmission through a lossy slab falls with thickness.
  const auto thin = slab_coefficients(slab(5.24, 0.185, 0.1), 0.7);
  const auto thick = slab_coefficients(slab(5.24, 0.185, 0.2), 0.7);
  EXPECT_LT(std::abs(thick.t.te), std::abs(thin.t.te));
  EXPECT_LT(std::abs(thick.t.tm), std::abs(thin.t.tm));
}

TEST(Metal, ActsAsAPerfectConductor) {
  const auto m = radio_material("metal", kF);
  const auto normal = slab_coefficients(m, 1.0);
  expect_near_c(normal.r.te, -1.0, 1e-3, "R_TE normal");
  expect_near_c(normal.r.tm, 1.0, 1e-3, "R_TM normal");
  // Up to 70 deg; closer to grazing a good conductor has a pseudo-Brewster
  // TM dip (at cos theta ~ 1/|n| ~ 3e-4) so |R_TM| legitimately leaves 1.
  for (int deg = 0; deg <= 70; ++deg) {
    const auto s = slab_coefficients(m, std::cos(deg * kDeg));
    EXPECT_NEAR(std::abs(s.r.te), 1.0, 1e-3) << deg;
    EXPECT_NEAR(std::abs(s.r.tm), 1.0, 1e-3) << deg;
    EXPECT_LT(std::abs(s.t.te), 1e-6) << deg;
    EXPECT_LT(std::abs(s.t.tm), 1e-6) << deg;
  }
  for (double c : {0.0, 1e-300, 1e-12, 1e-4, 0.01, 0.5, 1 - 1e-16, 1.0}) {
    for (double thickness : {0.0, 1e-6, 0.002, 10.0}) {
      MaterialOverride o;
      o.thickness_m = thickness;
      const auto s = slab_coefficients(radio_material("metal", kF, o), c);
      EXPECT_TRUE(finite(s.r.te) && finite(s.r.tm) && finite(s.t.te) && finite(s.t.tm)) << c << " " << thickness;
      EXPECT_LE(std::abs(s.r.te), 1.0 + 1e-12);
      EXPECT_LE(std::abs(s.r.tm), 1.0 + 1e-12);
    }
  }
}

// ------------------------------------------------------------- materials

TEST(Materials, ConcreteAtItsBand) {
  const auto m = radio_material("concrete", kF);
  EXPECT_EQ(m.name, "concrete");
  EXPECT_DOUBLE_EQ(m.eps_r, 5.24);
  // 0.0462 * 5.9^0.7822 = 0.0462 * exp(0.7822 * ln 5.9) = 0.0462 * exp(0.7822 * 1.774952)
  //                     = 0.0462 * 4.0083021 = 0.18518356 S/m
  EXPECT_NEAR(m.sigma, 0.18518356, 1e-8);
  // eps'' = sigma / (2 pi f eps0) = 0.18518356 / (2 pi 5.9e9 * 8.8541878e-12) = 0.18518356 / 0.32823 = 0.564185
  EXPECT_NEAR(m.eta().real(), 5.24, 1e-15);
  EXPECT_NEAR(m.eta().imag(), -0.564185, 1e-6);
  EXPECT_DOUBLE_EQ(m.thickness_m, 0.3);
  EXPECT_EQ(m.frequency_hz, kF);
  const auto prefixed = radio_material("itu_concrete", kF);
  EXPECT_EQ(prefixed.name, "concrete");
  EXPECT_EQ(prefixed.sigma, m.sigma);
}

TEST(Materials, FrequencyDependentGround) {
  // eps = 15 * 5.9^-0.1, sigma = 0.035 * 5.9^1.63
  const auto m = radio_material("medium_dry_ground", kF);
  EXPECT_NEAR(m.eps_r, 12.560475, 1e-6);  // 15 * exp(-0.1 * 1.774952) = 15 * 0.83736499
  EXPECT_NEAR(m.sigma, 0.631767, 1e-6);   // 0.035 * exp(1.63 * 1.774952) = 0.035 * 18.050481
}

TEST(Materials, OutOfBandThrowsWithRange) {
  try {
    radio_material("floorboard", kF);
    FAIL() << "floorboard is only valid 50-100 GHz";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("floorboard"), std::string::npos) << msg;
    EXPECT_NE(msg.find("50"), std::string::npos) << msg;
    EXPECT_NE(msg.find("100"), std::string::npos) << msg;
    EXPECT_NE(msg.find("5.9"), std::string::npos) << msg;
  }
  EXPECT_THROW(radio_material("medium_dry_ground", 20e9), std::invalid_argument);
  EXPECT_THROW(radio_material("wet_ground", 28e9), std::invalid_argument);
  EXPECT_THROW(radio_material("concrete", 0.5e9), std::invalid_argument);
  EXPECT_THROW(radio_material("brick", 60e9), std::invalid_argument);
  EXPECT_NO_THROW(radio_material("wet_ground", 10e9));  // band edge inclusive
  EXPECT_NO_THROW(radio_material("concrete", 1e9));
  EXPECT_NO_THROW(radio_material("floorboard", 60e9));
  EXPECT_THROW(radio_material("concrete", 0), std::invalid_argument);
  EXPECT_THROW(radio_material("concrete", NAN), std::invalid_argument);
}

TEST(Materials, CustomHaveNoRange) {
  for (double f : {1e8, kF, 77e9, 300e9}) {
    const auto m = radio_material("rubber", f);
    EXPECT_EQ(m.eps_r, 10.0);
    EXPECT_EQ(m.sigma, 0.98);
    EXPECT_EQ(m.thickness_m, 0.012);
  }
}

TEST(Materials, OverridesReplaceAndLiftRange) {
  MaterialOverride both;
  both.eps_r = 3.66;
  both.sigma = 0.01;
  const auto m = radio_material("floorboard", kF, both);
  EXPECT_EQ(m.eps_r, 3.66);
  EXPECT_EQ(m.sigma, 0.01);
  EXPECT_EQ(m.thickness_m, 0.02);

  MaterialOverride eps_only;
  eps_only.eps_r = 4;
  EXPECT_THROW(radio_material("floorboard", kF, eps_only), std::invalid_argument);
  const auto c = radio_material("concrete", kF, eps_only);
  EXPECT_EQ(c.eps_r, 4.0);
  EXPECT_NEAR(c.sigma, 0.18518356, 1e-8);

  MaterialOverride thick;
  thick.thickness_m = 0.1;
  EXPECT_EQ(radio_material("glass", kF, thick).thickness_m, 0.1);
  EXPECT_EQ(radio_material("rubber", kF, thick).thickness_m, 0.1);
}

TEST(Materials, InvalidValuesThrow) {
  auto with = [](std::optional<double> e, std::optional<double> s, std::optional<double> t) {
    MaterialOverride o;
    o.eps_r = e;
    o.sigma = s;
    o.thickness_m = t;
    return o;
  };
  EXPECT_THROW(radio_material("glass", kF, with(0.5, {}, {})), std::invalid_argument);
  EXPECT_THROW(radio_material("glass", kF, with({}, -1, {})), std::invalid_argument);
  EXPECT_THROW(radio_material("glass", kF, with({}, {}, -0.1)), std::invalid_argument);
  EXPECT_THROW(radio_material("glass", kF, with(NAN, {}, {})), std::invalid_argument);
  EXPECT_THROW(radio_material("glass", kF, with({}, INFINITY, {})), std::invalid_argument);
  EXPECT_NO_THROW(radio_material("glass", kF, with(1.0, 0.0, 0.0)));
}

TEST(Materials, UnknownNameThrows) {
  try {
    radio_material("unobtainium", kF);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unobtainium"), std::string::npos);
  }
  EXPECT_THROW(default_thickness_m("unobtainium"), std::invalid_argument);
}

TEST(Materials, TableCoversMeshkitNames) {
  const auto& names = raysweep::meshkit::itu_material_names();
  EXPECT_EQ(p2040_table().size(), names.size());
  for (const auto& n : names) {
    int rows = 0;
    for (const auto& r : p2040_table()) rows += r.name == n;
    EXPECT_EQ(rows, 1) << n;
    EXPECT_GE(default_thickness_m(n), 0.0) << n;
  }
  EXPECT_EQ(default_thickness_m("glass"), 0.005);
  EXPECT_EQ(default_thickness_m("plasterboard"), 0.0125);
  EXPECT_EQ(default_thickness_m("wet_ground"), 0.0);
  EXPECT_EQ(default_thickness_m("itu_metal"), 0.002);
  EXPECT_EQ(default_thickness_m("human"), 0.3);
}

// -------------------------------------------------------------- antennas

double gain(const AntennaSpec& a, const Vec3& dir, const Vec3& fwd = {1, 0, 0}) {
  const Vec3 e = antenna_field(a, dir, fwd);
  return dot(e, e);
}

Vec3 spherical(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

const AntennaSpec kAll[] = {
    {AntennaPattern::isotropic, Polarization::V},       {AntennaPattern::isotropic, Polarization::H},
    {AntennaPattern::short_dipole, Polarization::V},    {AntennaPattern::short_dipole, Polarization::H},
    {AntennaPattern::halfwave_dipole, Polarization::V}, {AntennaPattern::halfwave_dipole, Polarization::H},
};

TEST(Antenna, Parse) {
  EXPECT_EQ(parse_antenna_pattern("isotropic"), AntennaPattern::isotropic);
  EXPECT_EQ(parse_antenna_pattern("dipole"), AntennaPattern::short_dipole);
  EXPECT_EQ(parse_antenna_pattern("halfwave"), AntennaPattern::halfwave_dipole);
  EXPECT_THROW(parse_antenna_pattern("patch"), std::invalid_argument);
  EXPECT_EQ(parse_polarization("V"), Polarization::V);
  EXPECT_EQ(parse_polarization("H"), Polarization::H);
  EXPECT_THROW(parse_polarization("X"), std::invalid_argument);
}

TEST(Antenna, IsotropicVertical) {
  const Vec3 e = antenna_field({AntennaPattern::isotropic, Polarization::V}, {1, 0, 0}, {1, 0, 0});
  EXPECT_NEAR(e[0], 0, 1e-15);
  EXPECT_NEAR(e[1], 0, 1e-15);
  EXPECT_NEAR(e[2], -1, 1e-15);
}

TEST(Antenna, IsotropicHorizontalIsHorizontalAtHorizon) {
  for (int k = 0; k < 12; ++k) {
    const Vec3 e = antenna_field({AntennaPattern::isotropic, Polarization::H}, spherical(kPi / 2, k * 0.5), {0, 1, 0});
    EXPECT_NEAR(e[2], 0, 1e-15);
    EXPECT_NEAR(norm(e), 1, 1e-15);
  }
}

TEST(Antenna, DipoleGains) {
  const AntennaSpec shortv{AntennaPattern::short_dipole, Polarization::V};
  const AntennaSpec halfv{AntennaPattern::halfwave_dipole, Polarization::V};
  EXPECT_NEAR(gain(shortv, {1, 0, 0}), 1.5, 1e-14);
  EXPECT_NEAR(gain(shortv, {0, 0, 1}), 0, 1e-30);
  EXPECT_NEAR(gain(shortv, {0, 0, -1}), 0, 1e-30);
  // Half-wave directivity 4 / Cin(2 pi) = 1.640922377 (2.15 dBi), evaluated
  // independently with mpmath: 4 / (euler + log(2 pi) - ci(2 pi)).
  EXPECT_NEAR(gain(halfv, {0, 1, 0}), 1.64092237698459, 1e-12);
  EXPECT_NEAR(gain(halfv, {0, 0, 1}), 0, 1e-30);
  // 60 deg from the axis: 1.6409 * (cos(pi/4) / sin(60 deg))^2 = 1.6409 * 0.5 / 0.75
  EXPECT_NEAR(gain(halfv, spherical(kPi / 3, 0.2)), 1.64092237698459 * 2 / 3, 1e-12);
  EXPECT_NEAR(gain(shortv, spherical(kPi / 3, 0.2)), 1.5 * 0.75, 1e-14);
}

TEST(Antenna, GainIntegratesToFourPi) {
  // Directivity normalisation: the average gain over the sphere is 1.
  const int nt = 360, np = 720;
  const Vec3 fwd = normalize(Vec3{std::cos(0.3), std::sin(0.3), 0});
  for (const auto& a : kAll) {
    double sum = 0;
    for (int i = 0; i < nt; ++i) {
      const double th = (i + 0.5) * kPi / nt;
      for (int k = 0; k < np; ++k) sum += gain(a, spherical(th, (k + 0.5) * 2 * kPi / np), fwd) * std::sin(th);
    }
    sum *= (kPi / nt) * (2 * kPi / np);
    EXPECT_NEAR(sum / (4 * kPi), 1.0, 5e-3) << static_cast<int>(a.pattern) << static_cast<int>(a.polarization);
  }
}

TEST(Antenna, FieldPerpendicularToDirectionAndFinite) {
  const Vec3 fwd = normalize(Vec3{1, 2, 0});
  for (const auto& a : kAll) {
    for (int i = 0; i <= 18; ++i)
      for (int k = 0; k < 12; ++k) {
        const Vec3 d = spherical(i * kPi / 18, k * 0.52);
        const Vec3 e = antenna_field(a, d, fwd);
        ASSERT_TRUE(std::isfinite(e[0]) && std::isfinite(e[1]) && std::isfinite(e[2]));
        EXPECT_NEAR(dot(e, d), 0, 1e-12);
      }
    // Poles and the H dipole's axis.
    for (const Vec3& d : {Vec3{0, 0, 1}, Vec3{0, 0, -1}, cross(Vec3{0, 0, 1}, fwd), -cross(Vec3{0, 0, 1}, fwd)}) {
      const Vec3 e = antenna_field(a, d, fwd);
      ASSERT_TRUE(std::isfinite(e[0]) && std::isfinite(e[1]) && std::isfinite(e[2]));
      EXPECT_NEAR(dot(e, d), 0, 1e-12);
    }
  }
  // Isotropic stays unit length at the poles.
  EXPECT_NEAR(norm(antenna_field({AntennaPattern::isotropic, Polarization::V}, {0, 0, 1}, fwd)), 1, 1e-15);
  EXPECT_NEAR(norm(antenna_field({AntennaPattern::isotropic, Polarization::H}, {0, 0, -1}, fwd)), 1, 1e-15);
}

TEST(Antenna, HorizontalDipoleTurnsWithForward) {
  for (auto p : {AntennaPattern::short_dipole, AntennaPattern::halfwave_dipole}) {
    const AntennaSpec h{p, Polarization::H};
    const double gmax = p == AntennaPattern::short_dipole ? 1.5 : 1.64092237698459;
    // Heading +x: dipole along y, broadside ahead.
    EXPECT_NEAR(gain(h, {1, 0, 0}, {1, 0, 0}), gmax, 1e-12);
    EXPECT_NEAR(gain(h, {0, 1, 0}, {1, 0, 0}), 0, 1e-30);
    // Heading +y: dipole along x.
    EXPECT_NEAR(gain(h, {1, 0, 0}, {0, 1, 0}), 0, 1e-30);
    EXPECT_NEAR(gain(h, {0, 1, 0}, {0, 1, 0}), gmax, 1e-12);
    // Zenith is broadside for any heading.
    EXPECT_NEAR(gain(h, {0, 0, 1}, {0, 1, 0}), gmax, 1e-12);
    // The vertical dipole does not care about heading.
    const AntennaSpec v{p, Polarization::V};
    EXPECT_NEAR(gain(v, spherical(1.0, 0.4), {1, 0, 0}), gain(v, spherical(1.0, 0.4), {0, -1, 0}), 1e-15);
  }
}

TEST(Antenna, CrossPolarizationMismatch) {
  const Vec3 d{1, 0, 0};
  const Vec3 tx = antenna_field({AntennaPattern::halfwave_dipole, Polarization::V}, d, {1, 0, 0});
  const Vec3 rx = antenna_field({AntennaPattern::short_dipole, Polarization::H}, -d, {-1, 0, 0});
  EXPECT_GT(norm(tx), 1.2);
  EXPECT_GT(norm(rx), 1.2);
  EXPECT_NEAR(dot(tx, rx), 0, 1e-15);
  // Co-polarised V/V couples fully: |cos| = 1.
  const Vec3 rxv = antenna_field({AntennaPattern::short_dipole, Polarization::V}, -d, {-1, 0, 0});
  EXPECT_NEAR(std::fabs(dot(tx, rxv)) / (norm(tx) * norm(rxv)), 1, 1e-15);
}

}  // namespace
