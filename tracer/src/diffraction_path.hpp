// Edge geometry shared by the diffraction paths and the diffraction
// mechanism's per-node visibility pre-pass.
#pragma once

#include <cmath>

#include "tracer/solver.hpp"

namespace raysweep::tracer {

// Vehicle edges shorter than this many wavelengths do not diffract (wheels'
// facets, mirrors): Keller's stationary point needs room along the edge.
constexpr double kVehicleEdgeMinWavelengths = 5;

// Angle of `v` around an edge, from t0 towards n0, in [0, 2 pi).
inline double edge_angle(const Edge& e, const Vec3& v) {
  double a = std::atan2(dot(v, e.n0), dot(v, e.t0));
  return a < 0 ? a + 2 * kPi : a;
}

}  // namespace raysweep::tracer
