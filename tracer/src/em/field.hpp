// Complex field vectors: the polarised field a path carries from face to
// face (exact paths, diffracted paths and the shoot-and-bounce rays' tubes
// alike), in the faces' TE/TM bases.
#pragma once

#include <array>

#include "tracer/em/coefficients.hpp"

namespace raysweep::tracer {

using CVec3 = std::array<cdouble, 3>;

inline cdouble cdot(const CVec3& e, const Vec3& v) { return e[0] * v[0] + e[1] * v[1] + e[2] * v[2]; }
inline CVec3 cvec(const Vec3& v) { return {cdouble(v[0]), cdouble(v[1]), cdouble(v[2])}; }
inline CVec3 combine(cdouble a, const Vec3& u, cdouble b, const Vec3& w) {
  return {a * u[0] + b * w[0], a * u[1] + b * w[1], a * u[2] + b * w[2]};
}

// Field e, travelling along k_in, reflected by a face of plane normal n
// with reflection coefficients r (TE/TM in the face's basis), keeping `keep` of
// it (a rough surface's specular share).
inline CVec3 reflect_field(const CVec3& e, const Vec3& k_in, const Vec3& n, const TeTm& r, double keep) {
  const Vec3 es = te_basis(k_in, n);
  const Vec3 k_out = k_in - (2 * dot(k_in, n)) * n;
  return combine(keep * r.te * cdot(e, es), es, keep * r.tm * cdot(e, cross(es, k_in)), cross(es, k_out));
}

}  // namespace raysweep::tracer
