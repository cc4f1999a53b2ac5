#include "tracer/em.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

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
  m.scattering = default_scattering(m.name);
  auto& sc = m.scattering;
  if (override.scattering_coefficient) sc.s = *override.scattering_coefficient;
  if (override.xpd) sc.xpd = *override.xpd;
  if (override.lobe) sc.lobe = *override.lobe;
  if (override.alpha_r) sc.alpha_r = *override.alpha_r;
  if (override.alpha_i) sc.alpha_i = *override.alpha_i;
  if (override.lambda_r) sc.lambda_r = *override.lambda_r;
  auto unit = [&](double v, const char* what) {
    if (!(v >= 0 && v <= 1))
      throw std::invalid_argument("material '" + m.name + "': " + what + " must be within [0, 1], got " + fmt(v));
  };
  unit(sc.s, "scattering_coefficient");
  unit(sc.xpd, "xpd");
  unit(sc.lambda_r, "lambda_r");
  for (int a : {sc.alpha_r, sc.alpha_i})
    if (a < 1 || a > 20)
      throw std::invalid_argument("material '" + m.name + "': alpha_r and alpha_i must be within 1..20, got " +
                                  std::to_string(a));

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

namespace {

// slab_coefficients, with the transmission when kTransmission: one body, so
// the reflection is the same arithmetic either way.
template <bool kTransmission>
SlabCoefficients slab(const RadioMaterial& m, double cos_theta) {
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
  // Written out as exp(real) * phase so the decaying factors underflow to 0
  // (metal: Im q ~ -1e3) instead of forming inf * 0 anywhere.
  const cdouble e2 = std::polar(std::exp(2 * q.imag()), -2 * q.real());  // e^{-j2q}
  auto reflection = [&](cdouble rp, cdouble& den) {
    const cdouble rp2 = rp * rp;
    den = 1.0 - rp2 * e2;
    return rp * (1.0 - e2) / den;
  };
  cdouble den_te, den_tm;
  const TeTm r{reflection(r_if.te, den_te), reflection(r_if.tm, den_tm)};
  if constexpr (!kTransmission) {
    return {r, {0.0, 0.0}};
  } else {
    const double q0 = k0d * c;
    const cdouble e1 = std::polar(std::exp(q.imag()), -(q.real() - q0));  // e^{-j(q-q0)}
    auto transmission = [&](cdouble rp, cdouble den) { return (1.0 - rp * rp) * e1 / den; };
    return {r, {transmission(r_if.te, den_te), transmission(r_if.tm, den_tm)}};
  }
}

}  // namespace

SlabCoefficients slab_coefficients(const RadioMaterial& m, double cos_theta) { return slab<true>(m, cos_theta); }

TeTm slab_reflection(const RadioMaterial& m, double cos_theta) { return slab<false>(m, cos_theta).r; }

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


ScatteringLobe parse_scattering_lobe(const std::string& s) {
  if (s == "lambertian") return ScatteringLobe::lambertian;
  if (s == "directive") return ScatteringLobe::directive;
  if (s == "backscatter") return ScatteringLobe::backscatter;
  throw std::invalid_argument("unknown scattering lobe '" + s + "' (expected lambertian, directive or backscatter)");
}
const char* scattering_lobe_name(ScatteringLobe l) {
  switch (l) {
    case ScatteringLobe::lambertian: return "lambertian";
    case ScatteringLobe::directive: return "directive";
    case ScatteringLobe::backscatter: return "backscatter";
  }
  return "?";
}
Scattering default_scattering(const std::string& name) {
  Scattering sc;
  if (name == "concrete" || name == "brick") sc.s = 0.4;
  else if (name == "wood" || name == "plasterboard" || name == "ceiling_board" || name == "chipboard" ||
           name == "floorboard")
    sc.s = 0.2;
  else
    return sc;
  sc.xpd = 0.1;
  sc.lobe = ScatteringLobe::directive;
  sc.alpha_r = 4;
  return sc;
}

namespace {

double ipow(double x, int n) {
  double r = 1;
  for (; n > 0; n >>= 1, x *= x)
    if (n & 1) r *= x;
  return r;
}

// The factors of lobe_integral_cos's sum that do not depend on the angle,
// for one alpha: C(alpha, j), 2 pi / (j + 1), C(2w, w) and 2^alpha, by the
// recurrences the sum once ran on every call, so it gives the same bits.
// Every view of a diffuse tile and every rough-surface hit builds a lobe,
// and these divisions were most of its cost.
struct LobeTerms {
  std::vector<double> binom, ij, cw;
  double pow2 = 1;
};

LobeTerms lobe_terms(int alpha) {
  LobeTerms t;
  double binom = 1, cw = 1;
  for (int j = 0; j <= alpha; ++j) {
    t.binom.push_back(binom);
    t.ij.push_back(2 * kPi / (j + 1));
    binom = binom * (alpha - j) / (j + 1.0);
  }
  for (int w = 0; w <= (alpha - 1) / 2; ++w) {
    t.cw.push_back(cw);
    cw = cw * (2.0 * w + 1) * (2.0 * w + 2) / ((w + 1.0) * (w + 1.0));
  }
  t.pow2 = ipow(2.0, alpha);
  return t;
}

// Tabled up to this alpha (the config allows 1..20); beyond, built per call.
constexpr int kTabledAlpha = 64;

// lobe_integral with theta given by its cosine.
double lobe_integral_cos(int alpha, double ct) {
  // ((1 + cos psi)/2)^alpha = 2^-alpha sum_j C(alpha, j) cos^j psi, and the
  // hemisphere integral of cos^j psi is 2 pi / (j + 1) for even j and
  // 2 pi / (j + 1) cos(theta) sum_{w <= (j-1)/2} C(2w, w) sin^2w(theta) / 4^w
  // for odd j (Degli-Esposti et al. 2007, eq. 9).
  static const std::vector<LobeTerms> table = [] {
    std::vector<LobeTerms> t;
    for (int a = 0; a <= kTabledAlpha; ++a) t.push_back(lobe_terms(a));
    return t;
  }();
  LobeTerms own;
  const bool tabled = alpha >= 0 && alpha <= kTabledAlpha;
  if (!tabled) own = lobe_terms(alpha);
  const LobeTerms& t = tabled ? table[static_cast<std::size_t>(alpha)] : own;
  const double st2 = std::max(0.0, 1 - ct * ct);
  // The odd terms' inner sums are prefixes of one sum: each odd j adds the
  // term w = (j - 1) / 2 to the previous one's.
  double sum = 0, inner = 0, pw = 1;  // pw = (sin^2 / 4)^w
  std::size_t w = 0;
  for (int j = 0; j <= alpha; ++j) {
    const auto uj = static_cast<std::size_t>(j);
    double ij = t.ij[uj];
    if (j % 2) {
      inner += t.cw[w++] * pw;
      pw *= st2 / 4;
      ij *= ct * inner;
    }
    sum += t.binom[uj] * ij;
  }
  return sum / t.pow2;
}

}  // namespace

double lobe_integral(int alpha, double theta) { return lobe_integral_cos(alpha, std::cos(theta)); }

ScatteringLobeAt::ScatteringLobeAt(const Scattering& sc, const Vec3& k_in, const Vec3& n_any) : sc_(&sc), k_in_(k_in) {
  // The front side is where the incident wave comes from.
  n_ = dot(k_in, n_any) < 0 ? n_any : -n_any;
  const double cos_i = std::clamp(-dot(k_in, n_), 0.0, 1.0);
  spec_ = k_in + (2 * cos_i) * n_;
  if (sc.lobe == ScatteringLobe::lambertian) inv_norm_ = 1 / kPi;
  else if (sc.lobe == ScatteringLobe::directive) inv_norm_ = 1 / lobe_integral_cos(sc.alpha_r, cos_i);
  // The back lobe points along -k_in, also theta_i from the normal.
  else
    inv_norm_ = 1 / (sc.lambda_r * lobe_integral_cos(sc.alpha_r, cos_i) +
                     (1 - sc.lambda_r) * lobe_integral_cos(sc.alpha_i, cos_i));
}

double ScatteringLobeAt::operator()(const Vec3& k_out) const {
  const double cos_s = dot(k_out, n_);
  if (!(cos_s > 0)) return 0;
  if (sc_->lobe == ScatteringLobe::lambertian) return cos_s * inv_norm_;
  const double lobe_r = ipow((1 + std::clamp(dot(k_out, spec_), -1.0, 1.0)) / 2, sc_->alpha_r);
  if (sc_->lobe == ScatteringLobe::directive) return lobe_r * inv_norm_;
  const double lobe_i = ipow((1 + std::clamp(-dot(k_out, k_in_), -1.0, 1.0)) / 2, sc_->alpha_i);
  return (sc_->lambda_r * lobe_r + (1 - sc_->lambda_r) * lobe_i) * inv_norm_;
}

double scattering_pattern(const Scattering& sc, const Vec3& k_in, const Vec3& k_out, const Vec3& n_any) {
  return ScatteringLobeAt(sc, k_in, n_any)(k_out);
}

namespace {

// erfc(z) for z = r e^{j pi/4}, r >= 0 (the ray the Fresnel integrals live
// on): Maclaurin series of erf for small |z| (terms stay below e^{|z|^2}, so
// about 4 digits are lost at |z| = 3), the Laplace continued fraction
// (modified Lentz) beyond.
cdouble erfc_diagonal(cdouble z) {
  const double r = std::abs(z);
  if (r < 3.0) {
    const cdouble z2 = z * z;
    cdouble term = z, sum = z;  // term = (-1)^n z^{2n+1} / n!
    for (int k = 1; k < 200; ++k) {
      term *= -z2 / static_cast<double>(k);
      const cdouble add = term / (2.0 * k + 1);
      sum += add;
      if (std::abs(add) < 1e-17 * std::abs(sum)) break;
    }
    return 1.0 - (2.0 / std::sqrt(kPi)) * sum;
  }
  // erfc z = e^{-z^2}/sqrt(pi) * 1/(z + (1/2)/(z + 1/(z + (3/2)/(z + ...)))).
  const double tiny = 1e-300;
  cdouble f = z, c = z, d = 0.0;
  for (int k = 1; k < 5000; ++k) {
    const double a = k / 2.0;
    d = z + a * d;
    if (std::abs(d) < tiny) d = tiny;
    c = z + a / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const cdouble delta = c * d;
    f *= delta;
    if (std::abs(delta - 1.0) < 1e-16) break;
  }
  return std::exp(-z * z) / (std::sqrt(kPi) * f);
}

// G(x) = int_x^inf e^{-j pi t^2 / 2} dt = (1 - j)/2 erfc(sqrt(pi)/2 (1 + j) x), x >= 0.
cdouble fresnel_tail(double x) {
  const cdouble z = (std::sqrt(kPi) / 2) * cdouble(1, 1) * x;
  return cdouble(0.5, -0.5) * erfc_diagonal(z);
}

}  // namespace

std::pair<double, double> fresnel_cs(double x) {
  const double ax = std::fabs(x);
  const cdouble g = fresnel_tail(ax);  // (1/2 - C) - j (1/2 - S)
  const double c = 0.5 - g.real(), s = 0.5 + g.imag();
  return x < 0 ? std::pair{-c, -s} : std::pair{c, s};
}

cdouble utd_transition(double x) {
  if (!(x > 0)) return 0.0;
  // Far from the shadow and reflection boundaries (most terms of most
  // paths: kL is hundreds to thousands) the asymptotic series
  // F(x) ~ sum_m (2m - 1)!! (j / 2x)^m: its terms shrink while 2m + 1 < 2x,
  // and from x = 40 on they fall below 1e-16 before turning (the smallest
  // is about e^-x), so the sum is as exact as the continued fraction
  // below without its complex divisions, exponential and hypot (a
  // snapshot's diffraction: 0.78-0.88 of its thread time; docs/tracer.md).
  if (x >= 40) {
    const double h = 0.5 / x;
    double re = 1, im = 0, t = 1;  // t = (2m - 1)!! h^m
    for (int m = 1; m < 64; ++m) {
      t *= (2 * m - 1) * h;
      switch (m & 3) {  // j^m
        case 1: im += t; break;
        case 2: re -= t; break;
        case 3: im -= t; break;
        default: re += t; break;
      }
      if (t < 1e-17) break;
    }
    return {re, im};
  }
  const double u = std::sqrt(x);
  // int_u^inf e^{-j t^2} dt = sqrt(pi/2) G(u sqrt(2/pi)).
  const cdouble tail = std::sqrt(kPi / 2) * fresnel_tail(u * std::sqrt(2 / kPi));
  return cdouble(0, 2) * u * std::polar(1.0, x) * tail;
}

namespace {

// One cot * F term's geometry: N, the integer most nearly satisfying
// 2 pi n N - beta = sign * pi; eps, 0 on the shadow or reflection boundary;
// a = a^{sign}(beta), F's argument over kL; and the cotangent's angle.
struct CotTerm {
  double eps, a, angle;
};
CotTerm cot_term(int sign, double beta, double n) {
  const double N = std::round((sign * kPi + beta) / (2 * kPi * n));
  return {kPi + sign * (beta - 2 * kPi * n * N), 2 * std::pow(std::cos((2 * kPi * n * N - beta) / 2), 2),
          (kPi + sign * beta) / (2 * n)};
}
// Within this of a boundary the term takes its finite limit.
constexpr double kBoundaryEps = 1e-5;

// cot((pi + sign*beta)/(2n)) F(kL a^{sign}(beta)), with the finite limit
// n [sqrt(2 pi kL) sgn(eps) - 2 kL eps e^{j pi/4}] e^{j pi/4} close to the
// boundary where eps -> 0 (Kouyoumjian and Pathak's eq. for the transition
// region), so a receiver on a shadow or reflection boundary gets a finite
// coefficient.
cdouble cot_f(int sign, double beta, double n, double kL) {
  const CotTerm t = cot_term(sign, beta, n);
  if (std::fabs(t.eps) < kBoundaryEps) {
    const cdouble ej = std::polar(1.0, kPi / 4);
    return n * (std::sqrt(2 * kPi * kL) * (t.eps >= 0 ? 1.0 : -1.0) - 2 * kL * t.eps * ej) * ej;
  }
  return utd_transition(kL * t.a) / std::tan(t.angle);
}

// A bound on |cot_f|: |F(x)| <= min(1, sqrt(pi x)) (F(x) = 2j sqrt(x) e^{jx}
// times a Fresnel tail of modulus at most sqrt(pi) / 2, and |F| rises to 1).
double cot_f_bound(int sign, double beta, double n, double kL) {
  const CotTerm t = cot_term(sign, beta, n);
  if (std::fabs(t.eps) < kBoundaryEps) return n * (std::sqrt(2 * kPi * kL) + 2 * kL * std::fabs(t.eps));
  return std::min(1.0, std::sqrt(kPi * kL * t.a)) / std::fabs(std::tan(t.angle));
}

}  // namespace

double utd_wedge_bound(double n, double phi_i, double phi_d, double beta0, double L, double k) {
  const double kL = k * L;
  const double pre = 1 / (2 * n * std::sqrt(2 * kPi * k) * std::fabs(std::sin(beta0)));
  const double dm = phi_d - phi_i, dp = phi_d + phi_i;
  const double sum = cot_f_bound(+1, dm, n, kL) + cot_f_bound(-1, dm, n, kL) + cot_f_bound(-1, dp, n, kL) +
                     cot_f_bound(+1, dp, n, kL);
  return (1 + 1e-9) * pre * sum;  // the margin covers rounding
}

DiffractionCoefficients utd_wedge(double n, double phi_i, double phi_d, double beta0, double L, double k,
                                  const RadioMaterial* face0, const RadioMaterial* face_n, double keep0,
                                  double keep_n) {
  const double kL = k * L;
  const double sb = std::sin(beta0);
  const cdouble pre = -std::polar(1.0, -kPi / 4) / (2 * n * std::sqrt(2 * kPi * k) * sb);
  const double dm = phi_d - phi_i, dp = phi_d + phi_i;
  const cdouble t1 = cot_f(+1, dm, n, kL), t2 = cot_f(-1, dm, n, kL);
  const cdouble t3 = cot_f(-1, dp, n, kL), t4 = cot_f(+1, dp, n, kL);
  // Luebbers: face 0 seen at the grazing angle phi_i, face n at n pi - phi_d.
  // That rule is not reciprocal (swapping the ends swaps the angles), so each
  // face takes the mean of its coefficients at the grazing angles of the ends
  // that see it (angle from the face in (0, pi)), or of both when neither
  // does. At a face's reflection boundary both ends see it at angles of equal
  // sine, so the boundary values, hence continuity, are Luebbers'.
  auto refl = [&](const RadioMaterial* m, double a, double b) -> TeTm {
    if (!m) return {-1.0, 1.0};
    auto at = [&](double grazing) {
      return slab_reflection(*m, std::clamp(sb * std::fabs(std::sin(grazing)), 0.0, 1.0));
    };
    const bool sa = a > 0 && a < kPi, sb_ = b > 0 && b < kPi;
    if (sa != sb_) return at(sa ? a : b);
    const TeTm x = at(a), y = at(b);
    return {0.5 * (x.te + y.te), 0.5 * (x.tm + y.tm)};
  };
  TeTm r0 = refl(face0, phi_i, phi_d);
  TeTm rn = refl(face_n, n * kPi - phi_d, n * kPi - phi_i);
  r0 = {keep0 * r0.te, keep0 * r0.tm};
  rn = {keep_n * rn.te, keep_n * rn.tm};
  return {pre * (t1 + t2 + r0.te * t3 + rn.te * t4), pre * (t1 + t2 + r0.tm * t3 + rn.tm * t4)};
}

}  // namespace raysweep::tracer
