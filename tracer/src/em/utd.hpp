// The uniform theory of diffraction: the transition function, the Fresnel
// integrals, and wedge diffraction coefficients for finite conductivity.
#pragma once

#include <utility>

#include "tracer/em/materials.hpp"

namespace raysweep::tracer {

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

}  // namespace raysweep::tracer
