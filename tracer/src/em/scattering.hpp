// The scattering pattern of a rough surface (the effective roughness
// model's lobes, tracer/em/materials.hpp's Scattering).
#pragma once

#include "tracer/em/materials.hpp"
#include "tracer/vec.hpp"

namespace raysweep::tracer {

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

}  // namespace raysweep::tracer
