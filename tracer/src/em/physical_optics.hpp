// Physical optics on a finite planar facet, as a factor on the geometrical-
// optics reflection: the facet's field relative to an infinite mirror's.
//
// Around the specular point P the path length over the facet's plane is
// L(p) = L0 + p^T H p / 2 + O(p^3), H = (I - t_i t_i^T) / d1 + (I - t_o t_o^T) / d2
// on the plane (t_i, t_o the incident and reflected directions, d1 and d2 the
// unfolded lengths to the ends). The Kirchhoff integral over the facet with the
// slowly varying amplitude taken at P, divided by the same integral over the
// whole plane (2 pi / (j k sqrt(det H)), which is GO's image field), is
//   F = (j k sqrt(det H) / 2 pi) * int_facet exp(-j k p^T H p / 2) dA,
// 1 for a facet that covers many Fresnel zones, (area / (lambda d)) for a
// small one at normal incidence (d = d1 d2 / (d1 + d2)).
#pragma once

#include <array>
#include <cmath>
#include <vector>

#include "tracer/em/constants.hpp"
#include "tracer/vec.hpp"

namespace raysweep::tracer {

// With physical optics on vehicle facets, a reflection point this many
// first-Fresnel-zone radii (sqrt(lambda d1 d2 / (d1 + d2))) off its facet,
// on the facet's plane, still makes a path: the facet's Kirchhoff integral
// lights it (an edge's tail, about -19 dB of a mirror's at two radii off a
// large facet; a facet smaller than its zone nearly as much as when the
// point lies on it). Beyond, its part is left out.
constexpr double kNearMissFresnelRadii = 2;

// The first Fresnel zone's radius at a point d1 and d2 (unfolded) from the
// ends, wavelength lambda.
inline double fresnel_radius(double lambda, double d1, double d2) {
  return d1 + d2 > 0 ? std::sqrt(lambda * d1 * d2 / (d1 + d2)) : 0.0;
}

// (1 / 2 pi) * sum over the directed edges (a -> b) of int (1 - exp(-j R^2)) dtheta,
// theta the angle of the edge's points seen from the origin and R their distance:
// the integral of (j / pi) exp(-j |q|^2) over the region the edges bound
// (counter-clockwise positive), by polar coordinates about the origin and
// Green's theorem. Each edge's integrand is bounded (it tends to j * (a x b) /
// |b - a|^2-like values at the origin), so a region whose boundary passes through
// the origin needs no special case. 8-point Gauss-Legendre on panels over which
// the phase R^2 turns by at most one radian.
cdouble fresnel_region_factor(const std::vector<std::array<double, 4>>& edges);

// The PO factor for the facet made of `triangles` (world vertices, coplanar,
// unit normal `normal`) between a point source and a receiver on its front
// side, wavenumber k (rad/m). The phase is expanded about the specular point
// when it lies on the facet (about the centroid, with a linear term, when it
// does not); a facet whose edges all lie 4 Fresnel radii from its specular
// point gives GO's 1. Edges shared by two triangles cancel and are skipped.
cdouble facet_factor(const std::vector<std::array<Vec3, 3>>& triangles, const Vec3& normal, const Vec3& source,
                     const Vec3& receiver, double k);

}  // namespace raysweep::tracer
