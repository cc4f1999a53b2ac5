// The geometry of images and beams that the searches share: where the line
// from an image crosses a plane, cones from an apex, the pyramid from an
// image through a static face's outline, and the window of normals a
// vehicle's reflecting faces lie in.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "search/face_index.hpp"

namespace raysweep::tracer {

// Where the line from image `img` (signed distance `d_img` from the plane)
// to `target` (signed distance `d_t`, opposite sign) crosses the plane.
inline Vec3 crossing(const Vec3& img, double d_img, const Vec3& target, double d_t) {
  const double s = d_img / (d_img - d_t);
  return img + s * (target - img);
}

// The cone from `apex` containing sphere `s`: sine and cosine of its
// half-angle and its unit axis; false when the apex is inside the sphere.
struct Cone {
  Vec3 axis{0, 0, 1};
  double sin_h = 1, cos_h = 0;
};
inline bool cone_to(const Vec3& apex, const TraceScene::Sphere& s, Cone& c) {
  const Vec3 w = s.centre - apex;
  const double d = norm(w);
  if (d <= s.radius) return false;
  c.axis = (1.0 / d) * w;
  c.sin_h = s.radius / d;
  c.cos_h = std::sqrt(1 - c.sin_h * c.sin_h);
  return true;
}
// Whether two cones from one apex overlap (half-angles summed < pi).
inline bool cones_overlap(const Cone& a, const Cone& b) {
  const double cos_angle = dot(a.axis, b.axis);
  const double cos_sum = a.cos_h * b.cos_h - a.sin_h * b.sin_h;  // cos(h_a + h_b)
  if (a.cos_h * b.cos_h - a.sin_h * b.sin_h < -1 + 1e-12) return true;
  // cos_sum < 0 with h_a + h_b > pi cannot happen (both < pi / 2).
  return cos_angle >= cos_sum - 1e-12;
}

// The pyramid from `apex` through static face f's convex outline: one
// plane through the apex per outline edge, as inward unit normals, appended
// to `out` (none for a degenerate edge: conservative).
inline void outline_pyramid(const ImageFaces& faces, std::uint32_t f, const Vec3& apex, std::vector<Vec3>& out) {
  const std::uint32_t o0 = faces.outline_begin[f], o1 = faces.outline_begin[f + 1];
  if (o1 - o0 < 3) return;
  Vec3 centre{0, 0, 0};
  for (std::uint32_t k = o0; k < o1; ++k) centre = centre + faces.outline[k];
  centre = (1.0 / (o1 - o0)) * centre;
  for (std::uint32_t k = o0; k < o1; ++k) {
    const Vec3 a = faces.outline[k] - apex, b = faces.outline[k + 1 < o1 ? k + 1 : o0] - apex;
    Vec3 nrm = cross(a, b);
    const double l = norm(nrm);
    if (!(l > 1e-9 * norm(a) * norm(b))) continue;
    nrm = (1.0 / l) * nrm;
    if (dot(nrm, centre - apex) < 0) nrm = -nrm;
    out.push_back(nrm);
  }
}

// Whether sphere `sp`, grown by `tol`, lies wholly outside the pyramid of
// inward unit normals `planes` through `apex`, padded by `spread_per_m` per
// metre from the apex (the first face's on-face tolerance carried along
// its beam).
inline bool outside_pyramid(const std::vector<Vec3>& planes, const Vec3& apex, const TraceScene::Sphere& sp, double tol,
                            double spread_per_m) {
  const Vec3 w = sp.centre - apex;
  const double reach = sp.radius + tol + (spread_per_m + 1e-6) * (norm(w) + sp.radius);
  for (const auto& nrm : planes)
    if (dot(nrm, w) < -reach) return true;
  return false;
}

// Faces of vehicle v that can reflect from point `a` to point `b`: the
// reflection point lies in the vehicle's sphere, so the directions to a and
// b are within asin(R / distance) of those from its centre, and the face
// normal within delta of their bisector (sin delta <= (alpha + beta) / |u_a + u_b|).
// With an end inside the sphere every face is returned (cos_delta = -1).
// The window itself (its half-angle's cosine and sine): false (any face,
// cos_delta = -1) when it is void.
inline bool normal_window(const TraceScene::Sphere& sv, const Vec3& a, const Vec3& b, Vec3& bisector, double& cos_delta,
                          double& sin_delta) {
  const Vec3 wa = a - sv.centre, wb = b - sv.centre;
  const double da = norm(wa), db = norm(wb);
  cos_delta = -1;
  sin_delta = 1;
  bisector = Vec3{0, 0, 1};
  if (da <= sv.radius || db <= sv.radius) return false;
  const Vec3 m = (1.0 / da) * wa + (1.0 / db) * wb;
  const double lm = norm(m);
  // asin(x) <= x pi / 2 on [0, 1].
  const double eps = (kPi / 2) * (sv.radius / da + sv.radius / db);
  if (eps >= lm) return false;
  bisector = (1.0 / lm) * m;
  sin_delta = eps / lm;
  cos_delta = std::sqrt(1 - sin_delta * sin_delta);
  return true;
}
inline const std::vector<std::uint32_t>& faces_towards(const TraceScene& scene, const TraceScene::Sphere& sv,
                                                       std::size_t v, const Vec3& a, const Vec3& b, Vec3& bisector,
                                                       double& cos_delta) {
  double sin_delta;
  if (!normal_window(sv, a, b, bisector, cos_delta, sin_delta))
    return scene.vehicle_faces_near_normal(v, bisector, 10.0);
  return scene.vehicle_faces_near_normal(v, bisector, std::asin(sin_delta));
}

}  // namespace raysweep::tracer
