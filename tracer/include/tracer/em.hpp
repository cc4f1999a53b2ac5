// Electromagnetics: ITU-R P.2040 materials at the carrier, interface (Fresnel)
// and single-layer slab reflection/transmission coefficients, antenna
// patterns. Conventions (used by the path solver, tested in test_em):
//  - TE ("s"): field perpendicular to the plane of incidence, basis vector
//    e_s = k x n (normalised); TM ("p"): e_p = e_s x k, for the incident and
//    the outgoing direction alike. With this basis P.2040's R_TM is +1 for a
//    perfect conductor at normal incidence and both R -> -1 at grazing.
//  - exp(+j w t) time dependence: a lossy material has eta = eps_r - j sigma/(w eps0).
//  - Slab transmission phase is referenced to free-space propagation over the
//    same thickness, so a zero-thickness mesh surface stands in for the slab
//    and the path length stays geometric.
#pragma once

#include <complex>
#include <optional>
#include <utility>
#include <string>
#include <vector>

#include "tracer/vec.hpp"

namespace raysweep::tracer {

using cdouble = std::complex<double>;

constexpr double kSpeedOfLight = 299792458.0;    // m/s
constexpr double kVacuumPermittivity = 8.8541878128e-12;  // F/m
constexpr double kPi = 3.14159265358979323846;

// One row of ITU-R P.2040 Table 3: eps_r = a f^b, sigma = c f^d with f in GHz,
// valid for f_min_ghz <= f <= f_max_ghz.
struct P2040Row {
  std::string name;  // meshkit name without "itu_" ("concrete", "medium_dry_ground"...)
  double a, b, c, d;
  double f_min_ghz, f_max_ghz;
};
const std::vector<P2040Row>& p2040_table();

// Diffuse scattering of a rough surface, effective roughness model
// (Degli-Esposti et al., IEEE TAP 55(1), 2007): a fraction S^2 of the power a
// smooth surface would reflect is scattered; of it, a fraction `xpd` goes to
// the cross polarisation. The lobe sets the angular spread:
//  - lambertian: f ~ cos theta_s;
//  - directive: f ~ ((1 + cos psi_R) / 2)^alpha_r around the specular direction;
//  - backscatter: lambda_r of the directive lobe plus (1 - lambda_r) of a lobe
//    ((1 + cos psi_i) / 2)^alpha_i around the direction back to the source.
enum class ScatteringLobe { lambertian, directive, backscatter };
ScatteringLobe parse_scattering_lobe(const std::string& s);  // "lambertian" | "directive" | "backscatter"
const char* scattering_lobe_name(ScatteringLobe l);

struct Scattering {
  double s = 0;    // scattering coefficient S in [0, 1]
  double xpd = 0;  // cross-polarised fraction K_x of the scattered power, [0, 1]
  ScatteringLobe lobe = ScatteringLobe::directive;
  int alpha_r = 4, alpha_i = 4;  // lobe widths (integers 1..20)
  double lambda_r = 0.75;        // backscatter: weight of the specular lobe against the back lobe, [0, 1]
                                 // (both normalised together, as in Degli-Esposti)
};

// Default roughness by material: building facades (concrete, brick) S = 0.4
// and wood, plasterboard, boards S = 0.2 with a directive lobe alpha_r = 4 and
// K_x = 0.1 (Degli-Esposti's urban fits); glass, metal and grounds (smooth at
// a few cm wavelength) and custom materials S = 0.
Scattering default_scattering(const std::string& name);

// Scattering pattern f (1/sr), normalised so its integral over the
// hemisphere in front of the surface is 1, for a wave arriving along unit
// `k_in` on a surface with unit normal `n` (either orientation), scattered
// towards unit `k_out` (0 when k_out is behind the surface).
double scattering_pattern(const Scattering& sc, const Vec3& k_in, const Vec3& k_out, const Vec3& n);

// The same pattern for one incidence and many scattering directions: what
// depends on the incidence alone (front normal, specular direction, the
// lobes' normalisation) is computed once.
class ScatteringLobeAt {
 public:
  ScatteringLobeAt() = default;
  ScatteringLobeAt(const Scattering& sc, const Vec3& k_in, const Vec3& n_any);
  double operator()(const Vec3& k_out) const;

 private:
  const Scattering* sc_ = nullptr;
  Vec3 k_in_{0, 0, 0}, n_{0, 0, 1}, spec_{0, 0, 0};
  double inv_norm_ = 0;  // 1 / the lobes' hemisphere integral
};
// Integral over the hemisphere of ((1 + cos psi)/2)^alpha, psi the angle to
// a direction at `theta` from the normal (Degli-Esposti's F_alpha, closed form).
double lobe_integral(int alpha, double theta);

// A material evaluated at one carrier frequency.
struct RadioMaterial {
  std::string name;
  double eps_r = 1;         // real relative permittivity
  double sigma = 0;         // conductivity, S/m
  double thickness_m = 0;   // slab thickness; 0 = half space (reflects, never transmits)
  double frequency_hz = 0;  // the carrier it was evaluated at
  Scattering scattering;
  // Complex relative permittivity eps_r - j sigma / (2 pi f eps0).
  cdouble eta() const;
};

// Config overrides of a material ([materials.<name>] in the TOML config).
struct MaterialOverride {
  std::optional<double> eps_r, sigma, thickness_m;
  std::optional<double> scattering_coefficient, xpd, lambda_r;
  std::optional<ScatteringLobe> lobe;
  std::optional<int> alpha_r, alpha_i;
};

// Default slab thickness by name: glass 5 mm, concrete 0.3 m, brick 0.25 m,
// plasterboard 12.5 mm, wood 40 mm, ceiling board / chipboard / floorboard
// 20 mm, metal 2 mm, grounds 0 (half space); custom materials: their own.
double default_thickness_m(const std::string& name);

// The material `name` (a P.2040 name or a meshkit custom material) at
// `frequency_hz`. Throws std::invalid_argument naming the material and its
// validity range when the frequency is outside it, or when the name is
// unknown. Overrides replace the computed values (an override of both eps_r
// and sigma lifts the validity check).
RadioMaterial radio_material(const std::string& name, double frequency_hz, const MaterialOverride& override = {});

// TE/TM pair of complex coefficients.
struct TeTm {
  cdouble te, tm;
};

// Reflection at an air / half-space interface (P.2040 eqs. for R_TE, R_TM),
// `cos_theta` = cosine of the incidence angle from the normal, in [0, 1].
TeTm interface_reflection(cdouble eta, double cos_theta);

// Single-layer slab of thickness d (P.2040 section on the single-layer slab):
// q = (2 pi d / lambda) sqrt(eta - sin^2 theta),
// R = R'(1 - e^{-j2q}) / (1 - R'^2 e^{-j2q}),
// T = (1 - R'^2) e^{-j(q - q0)} / (1 - R'^2 e^{-j2q}), q0 = (2 pi d / lambda) cos theta.
// A half space (thickness 0) gives the interface reflection and T = 0.
struct SlabCoefficients {
  TeTm r, t;
};
SlabCoefficients slab_coefficients(const RadioMaterial& m, double cos_theta);
// Its reflection alone: slab_coefficients(m, cos_theta).r bit for bit,
// without the transmission's exponential and divisions (most callers
// reflect only).
TeTm slab_reflection(const RadioMaterial& m, double cos_theta);

// The UTD transition function F(X) = 2j sqrt(X) e^{jX} int_{sqrt X}^inf e^{-j t^2} dt
// (Kouyoumjian and Pathak, Proc. IEEE 1974), X >= 0; F(0) = 0, F -> 1 for large X.
cdouble utd_transition(double x);

// Fresnel integrals C(x) = int_0^x cos(pi t^2 / 2) dt and S(x) likewise.
std::pair<double, double> fresnel_cs(double x);

// UTD wedge diffraction coefficients (soft: E parallel to the edge, hard:
// H parallel to it) for an exterior wedge angle n*pi (1 < n <= 2; n = 2 is a
// half plane), incidence angle phi_i and observation angle phi_d measured
// from face 0 through the exterior (0..n pi), beta0 the angle between the
// rays and the edge, distance parameter L (m) and wavenumber k. The faces'
// reflection coefficients enter by Luebbers' rule (IEEE TAP 32(1), 1984):
// face 0 at the grazing angle phi_i, face n at n pi - phi_d, each evaluated
// as a slab of its material; made reciprocal (D(phi_i, phi_d) =
// D(phi_d, phi_i)) by taking each face's coefficient at the grazing angles of
// the ends that see it (the mean when both do); nullptr means a perfect
// conductor (R = -1 soft, +1 hard). Near the shadow and reflection boundaries the products cot * F
// are replaced by their finite limits, so the coefficients never blow up.
struct DiffractionCoefficients {
  cdouble soft, hard;
};
// keep0 / keep_n scale the faces' reflection coefficients (rough faces:
// sqrt(1 - S^2), as in their specular reflections).
DiffractionCoefficients utd_wedge(double n, double phi_i, double phi_d, double beta0, double L, double k,
                                  const RadioMaterial* face0, const RadioMaterial* face_n, double keep0 = 1.0,
                                  double keep_n = 1.0);
// An upper bound on max(|soft|, |hard|) of utd_wedge for any faces whose
// (kept) reflection coefficients are at most 1 in magnitude: each cot * F
// term bounded by |F(x)| <= min(1, sqrt(pi x)): no transition function and
// no slab coefficients, so weak candidates can stop before them.
double utd_wedge_bound(double n, double phi_i, double phi_d, double beta0, double L, double k);

enum class AntennaPattern { isotropic, short_dipole, halfwave_dipole };
enum class Polarization { V, H };

struct AntennaSpec {
  AntennaPattern pattern = AntennaPattern::isotropic;
  Polarization polarization = Polarization::V;
};

// Parses "isotropic" | "dipole" (short dipole) | "halfwave"; "V" | "H".
// Throw std::invalid_argument on anything else.
AntennaPattern parse_antenna_pattern(const std::string& s);
Polarization parse_polarization(const std::string& s);

// Far-field vector pattern: a vector perpendicular to `dir` whose length is
// the amplitude gain sqrt(G(dir)) and whose direction is the radiated field's
// polarisation. `dir` is a unit direction in the world frame; the antenna's
// local frame has z up and x along `forward` (unit, horizontal; the vehicle
// heading). Vertical polarisation: isotropic -> theta_hat; dipoles along z
// (short: G = 1.5 sin^2 theta; half-wave: G = 1.64 (cos(pi/2 cos theta)/sin theta)^2),
// field along theta_hat. Horizontal: isotropic -> phi_hat of the local frame;
// dipoles along the local y axis (broadside to the driving direction). At the
// poles of the pattern (where theta_hat/phi_hat are undefined) a deterministic
// perpendicular vector is used.
Vec3 antenna_field(const AntennaSpec& antenna, const Vec3& dir, const Vec3& forward);

// TE basis vector for direction k on a surface with normal n (k x n, any
// perpendicular of k at normal incidence).
inline Vec3 te_basis(const Vec3& k, const Vec3& n) {
  const Vec3 s = cross(k, n);
  const double l = norm(s);
  return l > 1e-12 ? (1.0 / l) * s : any_perpendicular(k);
}

}  // namespace raysweep::tracer
