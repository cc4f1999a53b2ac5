#include "tracer/em.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "meshkit/materials.hpp"

namespace raysweep::tracer {

namespace {

// "itu_concrete", "mat-itu_concrete", "concrete", "rubber" -> canonical name.
std::string canonical_name(const std::string& name) {
  if (auto n = meshkit::radio_material_from_id(name)) return *n;
  throw std::invalid_argument("unknown radio material '" + name + "'");
}

const P2040Row* find_p2040(const std::string& name) {
  for (const auto& row : p2040_table())
    if (row.name == name) return &row;
  return nullptr;
}

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

const std::vector<P2040Row>& p2040_table() {
  // ITU-R P.2040-2/-3 Table 3 (the -1 edition had e.g. concrete 5.31/0.0326/
  // 0.8095; the later fits are the ones Sionna RT ships, so scenes agree).
  static const std::vector<P2040Row> table = {
      {"concrete", 5.24, 0.0, 0.0462, 0.7822, 1, 100},
      {"brick", 3.91, 0.0, 0.0238, 0.16, 1, 40},
      {"plasterboard", 2.73, 0.0, 0.0085, 0.9395, 1, 100},
      {"wood", 1.99, 0.0, 0.0047, 1.0718, 0.001, 100},
      {"glass", 6.31, 0.0, 0.0036, 1.3394, 0.1, 100},
      {"ceiling_board", 1.48, 0.0, 0.0011, 1.0750, 1, 100},
      {"chipboard", 2.58, 0.0, 0.0217, 0.7800, 1, 100},
      {"floorboard", 3.66, 0.0, 0.0044, 1.3515, 50, 100},
      {"metal", 1.0, 0.0, 1e7, 0.0, 1, 100},
      {"very_dry_ground", 3.0, 0.0, 0.00015, 2.52, 1, 10},
      {"medium_dry_ground", 15.0, -0.1, 0.035, 1.63, 1, 10},
      {"wet_ground", 30.0, -0.4, 0.15, 1.30, 1, 10},
  };
  return table;
}

cdouble RadioMaterial::eta() const {
  if (sigma == 0) return {eps_r, 0.0};
  if (!(frequency_hz > 0))
    throw std::invalid_argument("material '" + name + "': conductive material needs a positive frequency");
  return {eps_r, -sigma / (2 * kPi * frequency_hz * kVacuumPermittivity)};
}

double default_thickness_m(const std::string& name) {
  const std::string n = canonical_name(name);
  if (const auto* c = meshkit::find_custom_material(n)) return c->thickness_m;
  if (n == "glass") return 0.005;
  if (n == "concrete") return 0.3;
  if (n == "brick") return 0.25;
  if (n == "plasterboard") return 0.0125;
  if (n == "wood") return 0.04;
  if (n == "ceiling_board" || n == "chipboard" || n == "floorboard") return 0.02;
  if (n == "metal") return 0.002;
  if (n == "very_dry_ground" || n == "medium_dry_ground" || n == "wet_ground") return 0.0;
  throw std::invalid_argument("no default thickness for radio material '" + n + "'");
}

RadioMaterial radio_material(const std::string& name, double frequency_hz, const MaterialOverride& override) {
  RadioMaterial m;
  m.name = canonical_name(name);
  m.frequency_hz = frequency_hz;
  if (!std::isfinite(frequency_hz) || frequency_hz <= 0)
    throw std::invalid_argument("material '" + m.name + "': invalid frequency " + fmt(frequency_hz) + " Hz");

  const bool fully_overridden = override.eps_r && override.sigma;
  if (const auto* c = meshkit::find_custom_material(m.name)) {
    m.eps_r = c->eps_r;
    m.sigma = c->sigma_s_per_m;
  } else if (!fully_overridden) {
    const P2040Row* row = find_p2040(m.name);
    if (!row) throw std::invalid_argument("radio material '" + m.name + "' has no ITU-R P.2040 parameters");
    const double f_ghz = frequency_hz / 1e9;
    // The relative slack keeps band edges given as e.g. 10e9 Hz inside.
    const double slack = 1e-9;
    if (f_ghz < row->f_min_ghz * (1 - slack) || f_ghz > row->f_max_ghz * (1 + slack))
      throw std::invalid_argument("material '" + m.name + "': ITU-R P.2040 parameters are valid for " +
                                  fmt(row->f_min_ghz) + "-" + fmt(row->f_max_ghz) + " GHz, not " + fmt(f_ghz) +
                                  " GHz (override eps_r and sigma to use it there)");
    m.eps_r = row->a * std::pow(f_ghz, row->b);
    m.sigma = row->c * std::pow(f_ghz, row->d);
  }
  m.thickness_m = default_thickness_m(m.name);
  if (override.eps_r) m.eps_r = *override.eps_r;
  if (override.sigma) m.sigma = *override.sigma;
  if (override.thickness_m) m.thickness_m = *override.thickness_m;

  if (!std::isfinite(m.eps_r) || m.eps_r < 1)
    throw std::invalid_argument("material '" + m.name + "': eps_r must be finite and >= 1, got " + fmt(m.eps_r));
  if (!std::isfinite(m.sigma) || m.sigma < 0)
    throw std::invalid_argument("material '" + m.name + "': sigma must be finite and >= 0, got " + fmt(m.sigma));
  if (!std::isfinite(m.thickness_m) || m.thickness_m < 0)
    throw std::invalid_argument("material '" + m.name + "': thickness must be finite and >= 0, got " +
                                fmt(m.thickness_m));
  return m;
}

namespace {

// sqrt(eta - sin^2 theta): the principal root has Re >= 0 and, because
// Im(eta) <= 0, Im <= 0, so exp(-j k0 d s) decays inside a lossy slab.
cdouble normal_wavenumber_ratio(cdouble eta, double cos_theta) {
  const double sin2 = (1 - cos_theta) * (1 + cos_theta);
  return std::sqrt(eta - sin2);
}

TeTm interface_from_root(cdouble eta, double c, cdouble s) {
  const cdouble te_den = c + s;
  const cdouble tm_den = eta * c + s;
  // Both vanish only for eta = 1 at grazing: no contrast, no reflection
  // (the limit along any other angle).
  if (te_den == 0.0 || tm_den == 0.0) return {0.0, 0.0};
  return {(c - s) / te_den, (eta * c - s) / tm_den};
}

}  // namespace

TeTm interface_reflection(cdouble eta, double cos_theta) {
  const double c = std::clamp(cos_theta, 0.0, 1.0);
  return interface_from_root(eta, c, normal_wavenumber_ratio(eta, c));
}

SlabCoefficients slab_coefficients(const RadioMaterial& m, double cos_theta) {
  const double c = std::clamp(cos_theta, 0.0, 1.0);
  const cdouble eta = m.eta();
  const cdouble s = normal_wavenumber_ratio(eta, c);
  const TeTm r_if = interface_from_root(eta, c, s);
  // A half space never transmits; at exact grazing the slab formula is 0/0
  // for a lossless slab whose q is a multiple of pi, and its limit is the
  // interface value (R' = -1 -> R = -1, T = 0) for every other q.
  if (m.thickness_m == 0) return {r_if, {0.0, 0.0}};
  if (c == 0) return {r_if, eta == 1.0 ? TeTm{1.0, 1.0} : TeTm{0.0, 0.0}};
  if (!(m.frequency_hz > 0))
    throw std::invalid_argument("material '" + m.name + "': a slab needs a positive frequency");

  const double k0d = 2 * kPi * m.frequency_hz / kSpeedOfLight * m.thickness_m;
  const cdouble q = k0d * s;
  const double q0 = k0d * c;
  // Written out as exp(real) * phase so the decaying factors underflow to 0
  // (metal: Im q ~ -1e3) instead of forming inf * 0 anywhere.
  const cdouble e2 = std::polar(std::exp(2 * q.imag()), -2 * q.real());  // e^{-j2q}
  const cdouble e1 = std::polar(std::exp(q.imag()), -(q.real() - q0));  // e^{-j(q-q0)}
  auto one = [&](cdouble rp) {
    const cdouble rp2 = rp * rp;
    const cdouble den = 1.0 - rp2 * e2;
    return std::pair<cdouble, cdouble>{rp * (1.0 - e2) / den, (1.0 - rp2) * e1 / den};
  };
  const auto [r_te, t_te] = one(r_if.te);
  const auto [r_tm, t_tm] = one(r_if.tm);
  return {{r_te, r_tm}, {t_te, t_tm}};
}

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
  const Vec3 x = normalize(Vec3{forward[0], forward[1], 0});
  if (norm(x) == 0) throw std::invalid_argument("antenna_field: forward must have a horizontal component");
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
  if (antenna.polarization == Polarization::V)
    // -projection of z = theta_hat, so V dipoles and V isotropic agree in sign.
    return -dipole_field(antenna.pattern, z, dir);
  // +projection of y = phi_hat in the forward direction (isotropic H agrees there).
  return dipole_field(antenna.pattern, y, dir);
}

}  // namespace raysweep::tracer
