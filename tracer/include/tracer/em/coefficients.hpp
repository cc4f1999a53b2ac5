// Reflection and transmission coefficients: an air / half-space interface
// (Fresnel), a single-layer slab (P.2040), and per material of one scene
// at its carrier (Electromagnetics). Conventions (used by the path solver,
// tested in test_em):
//  - TE ("s"): field perpendicular to the plane of incidence, basis vector
//    e_s = k x n (normalised); TM ("p"): e_p = e_s x k, for the incident and
//    the outgoing direction alike. With this basis P.2040's R_TM is +1 for a
//    perfect conductor at normal incidence and both R -> -1 at grazing.
//  - exp(+j w t) time dependence: a lossy material has eta = eps_r - j sigma/(w eps0).
//  - Slab transmission phase is referenced to free-space propagation over the
//    same thickness, so a zero-thickness mesh surface stands in for the slab
//    and the path length stays geometric.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "tracer/config.hpp"
#include "tracer/em/materials.hpp"
#include "tracer/vec.hpp"

namespace raysweep::tracer {

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

// TE basis vector for direction k on a surface with normal n (k x n, any
// perpendicular of k at normal incidence).
inline Vec3 te_basis(const Vec3& k, const Vec3& n) {
  const Vec3 s = cross(k, n);
  const double l = norm(s);
  return l > 1e-12 ? (1.0 / l) * s : any_perpendicular(k);
}

// Materials evaluated at the carrier for one scene (errors for materials
// used by the scene whose P.2040 range excludes the carrier).
class Electromagnetics {
 public:
  // `rough`: diffuse scattering is traced, so specular reflections keep
  // sqrt(1 - S^2) of their field (specular_keep), in reflected and
  // diffracted paths alike.
  Electromagnetics(const std::vector<std::string>& material_names, const RadioConfig& radio,
                   const std::map<std::string, MaterialOverride>& overrides, bool rough = false);
  const RadioMaterial& material(std::uint16_t i) const { return materials_.at(i); }
  SlabCoefficients coefficients(std::uint16_t i, double cos_theta) const;
  TeTm reflection(std::uint16_t i, double cos_theta) const;  // coefficients(i, cos_theta).r, bit for bit
  // Half spaces and good conductors: nothing gets through.
  bool opaque(std::uint16_t i) const { return opaque_.at(i); }
  // Loss of the stronger polarisation through the slab at normal incidence (dB).
  double normal_transmission_loss_db(std::uint16_t i) const { return normal_loss_db_.at(i); }
  double wavelength() const { return kSpeedOfLight / radio_.frequency_hz; }
  double specular_keep(std::uint16_t i) const { return keep_.at(i); }
  const RadioConfig& radio() const { return radio_; }

 private:
  RadioConfig radio_;
  std::vector<RadioMaterial> materials_;
  std::vector<bool> opaque_;
  std::vector<double> normal_loss_db_;
  std::vector<double> keep_;
};

}  // namespace raysweep::tracer
