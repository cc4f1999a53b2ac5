#include "tracer/em/antenna.hpp"

#include <cmath>
#include <stdexcept>

#include "tracer/em/constants.hpp"

namespace raysweep::tracer {

AntennaPattern parse_antenna_pattern(const std::string& s) {
  if (s == "isotropic") return AntennaPattern::isotropic;
  if (s == "dipole") return AntennaPattern::short_dipole;
  if (s == "halfwave") return AntennaPattern::halfwave_dipole;
  throw std::invalid_argument("unknown antenna pattern '" + s + "' (expected isotropic, dipole or halfwave)");
}

Polarization parse_polarization(const std::string& s) {
  if (s == "V") return Polarization::V;
  if (s == "H") return Polarization::H;
  throw std::invalid_argument("unknown polarization '" + s + "' (expected V or H)");
}

namespace {

// Cin(x) = integral_0^x (1 - cos t)/t dt by its power series (alternating,
// converges fast for x = 2 pi).
double cin(double x) {
  double sum = 0, term = 1;  // term = x^{2k} / (2k)!
  for (int k = 1; k <= 60; ++k) {
    term *= x * x / ((2.0 * k - 1) * (2.0 * k));
    sum += (k % 2 ? 1 : -1) * term / (2.0 * k);
  }
  return sum;
}

// Half-wave dipole directivity: 4 pi / integral of (cos(pi/2 cos t)/sin t)^2
// over the sphere = 4 / Cin(2 pi) = 1.64092..., the "1.64" of the header,
// computed so the pattern integrates to exactly 4 pi.
double halfwave_max_gain() {
  static const double g = 4.0 / cin(2 * kPi);
  return g;
}

// Field of a dipole along unit `axis`, pointing along the axis' projection
// onto the plane perpendicular to dir (|proj| = sin theta).
Vec3 dipole_field(AntennaPattern pattern, const Vec3& axis, const Vec3& dir) {
  const double ct = dot(axis, dir);
  const Vec3 proj = axis - ct * dir;
  const double sin2 = dot(proj, proj);
  if (pattern == AntennaPattern::short_dipole) return std::sqrt(1.5) * proj;  // sqrt(1.5) sin theta
  if (sin2 < 1e-300) return {0, 0, 0};
  // cos(pi/2 cos t) = sin(pi/2 (1 - |cos t|)), with 1 - |cos t| from sin^2
  // so the null on the axis keeps its relative precision.
  const double f = std::sin(0.5 * kPi * sin2 / (1 + std::fabs(ct)));
  return (std::sqrt(halfwave_max_gain()) * f / sin2) * proj;  // amplitude f / sin theta
}

}  // namespace

Vec3 antenna_field(const AntennaSpec& antenna, const Vec3& dir, const Vec3& forward) {
  const Vec3 z{0, 0, 1};
  // Tolerate a heading with a small vertical component or length error.
  const Vec3 horizontal{forward[0], forward[1], 0};
  const double h = norm(horizontal);
  if (!(h > 0)) throw std::invalid_argument("antenna_field: forward must have a horizontal component");
  // A vertical dipole does not depend on the heading (the tracer's default;
  // the diffuse integrations evaluate it millions of times a snapshot).
  if (antenna.pattern != AntennaPattern::isotropic && antenna.polarization == Polarization::V)
    // -projection of z = theta_hat, so V dipoles and V isotropic agree in sign.
    return -dipole_field(antenna.pattern, z, dir);
  const Vec3 x = (1.0 / h) * horizontal;  // normalize(), without its second square root
  const Vec3 y = cross(z, x);
  if (antenna.pattern == AntennaPattern::isotropic) {
    Vec3 phi_hat = cross(z, dir);
    if (norm(phi_hat) < 1e-12) {
      // On the local z axis: use the limit approached from the forward
      // direction (phi = 0): phi_hat = y, theta_hat = +-x.
      phi_hat = y;
    }
    phi_hat = normalize(phi_hat);
    if (antenna.polarization == Polarization::H) return phi_hat;
    return cross(phi_hat, dir);  // theta_hat
  }
  // +projection of y = phi_hat in the forward direction (isotropic H agrees there).
  return dipole_field(antenna.pattern, y, dir);
}

double peak_gain(AntennaPattern p) {
  switch (p) {
    case AntennaPattern::isotropic: return 1.0;
    case AntennaPattern::short_dipole: return 1.5;
    case AntennaPattern::halfwave_dipole: return 1.641;
  }
  return 1.0;
}

}  // namespace raysweep::tracer
