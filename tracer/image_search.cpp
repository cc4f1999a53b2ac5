#include "tracer/image_search.hpp"

#include <algorithm>
#include <cmath>

namespace raysweep::tracer {

namespace {

// Where the line from image `img` (signed distance `d_img` from the plane)
// to `target` (signed distance `d_t`, opposite sign) crosses the plane.
Vec3 crossing(const Vec3& img, double d_img, const Vec3& target, double d_t) {
  const double s = d_img / (d_img - d_t);
  return img + s * (target - img);
}

// The cone from `apex` containing sphere `s`: sine and cosine of its
// half-angle and its unit axis; false when the apex is inside the sphere.
struct Cone {
  Vec3 axis{0, 0, 1};
  double sin_h = 1, cos_h = 0;
};
bool cone_to(const Vec3& apex, const TraceScene::Sphere& s, Cone& c) {
  const Vec3 w = s.centre - apex;
  const double d = norm(w);
  if (d <= s.radius) return false;
  c.axis = (1.0 / d) * w;
  c.sin_h = s.radius / d;
  c.cos_h = std::sqrt(1 - c.sin_h * c.sin_h);
  return true;
}
// Whether two cones from one apex overlap (half-angles summed < pi).
bool cones_overlap(const Cone& a, const Cone& b) {
  const double cos_angle = dot(a.axis, b.axis);
  const double cos_sum = a.cos_h * b.cos_h - a.sin_h * b.sin_h;  // cos(h_a + h_b)
  if (a.cos_h * b.cos_h - a.sin_h * b.sin_h < -1 + 1e-12) return true;
  // cos_sum < 0 with h_a + h_b > pi cannot happen (both < pi / 2).
  return cos_angle >= cos_sum - 1e-12;
}

}  // namespace

ImageFaces image_faces(const TraceScene& scene) {
  ImageFaces t;
  const std::uint32_t instances = static_cast<std::uint32_t>(scene.vehicles().size() + 1);
  for (std::uint32_t inst = 0; inst < instances; ++inst) {
    const auto nf = static_cast<std::uint32_t>(scene.face_count(inst));
    for (std::uint32_t f = 0; f < nf; ++f) {
      const FaceRef ref{inst, f};
      t.refs.push_back(ref);
      t.planes.push_back(scene.plane(ref));
      t.spheres.push_back(scene.face_sphere(ref));
      // Generous against Embree's float rounding (the exact path's own ray
      // test decides) and a bent "planar" face's deviation from its plane.
      const auto& s = t.spheres.back();
      t.tol.push_back(2 * scene.slack(s.centre, s.radius) + 2 * scene.flatness(ref));
    }
    if (inst == 0) t.static_count = static_cast<std::uint32_t>(t.refs.size());
  }
  return t;
}

namespace {

// Receivers in structure-of-arrays form, relative to the source (so the
// branch-free passes below vectorise and stay exact at city offsets).
struct Receivers {
  std::vector<double> x, y, z;
  std::vector<unsigned char> hit;
  std::size_t size() const { return x.size(); }
};

// Marks the receivers r whose line from image `img` (signed distance -ds
// from the plane, the source at +ds) crosses the plane inside `sphere`
// (+ tol): the cheap necessary part of "the reflection point is on the
// face". Returns whether any is marked.
bool mark_crossings(const Receivers& rx, const Plane& pl, double plane_offset_rel, double ds, const Vec3& img,
                    const TraceScene::Sphere& sphere, const Vec3& centre_rel, double tol, Receivers& scratch) {
  const double nx = pl.normal[0], ny = pl.normal[1], nz = pl.normal[2];
  const double ix = img[0], iy = img[1], iz = img[2];
  const double cx = centre_rel[0], cy = centre_rel[1], cz = centre_rel[2];
  const double r2 = (sphere.radius + tol) * (sphere.radius + tol);
  const std::size_t n = rx.size();
  unsigned any = 0;
  for (std::size_t r = 0; r < n; ++r) {
    const double d = nx * rx.x[r] + ny * rx.y[r] + nz * rx.z[r] - plane_offset_rel;
    const double den = ds + d;  // ds and d share their sign when valid
    const double s = ds / (den != 0 ? den : 1.0);
    const double px = ix + s * (rx.x[r] - ix) - cx, py = iy + s * (rx.y[r] - iy) - cy,
                 pz = iz + s * (rx.z[r] - iz) - cz;
    const unsigned in = (ds * d > 0) & (px * px + py * py + pz * pz <= r2);
    scratch.hit[r] = static_cast<unsigned char>(in);
    any |= in;
  }
  return any != 0;
}

}  // namespace

void image_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                      std::uint32_t src, const std::vector<std::uint32_t>& receivers, int max_order,
                      std::vector<ImageCandidate>& out, ImageSearchStats* stats) {
  if (max_order < 1 || receivers.empty()) return;
  ImageSearchStats local;
  const Vec3 xs = nodes[src].position;
  // Everything relative to the source: the source is the origin.
  Receivers rx, scratch;
  for (auto r : receivers) {
    const Vec3 w = nodes[r].position - xs;
    rx.x.push_back(w[0]);
    rx.y.push_back(w[1]);
    rx.z.push_back(w[2]);
  }
  scratch.hit.resize(rx.size());
  auto receiver = [&](std::size_t r) { return Vec3{rx.x[r], rx.y[r], rx.z[r]} + xs; };
  auto on_face = [&](std::size_t f, const Vec3& p) { return scene.face_contains(faces.refs[f], p, faces.tol[f]); };

  // Order 1: every face of every instance.
  for (std::size_t f = 0; f < faces.refs.size(); ++f) {
    const Plane& pl = faces.planes[f];
    const double off = pl.offset - dot(pl.normal, xs);  // plane offset relative to the source
    const double ds = -off;                              // the source's signed distance
    if (ds == 0) continue;  // the source on the plane sees no image
    const Vec3 img = (-2 * ds) * pl.normal;
    ++local.image_sources;
    local.tests += rx.size();
    if (!mark_crossings(rx, pl, off, ds, img, faces.spheres[f], faces.spheres[f].centre - xs, faces.tol[f], scratch))
      continue;
    for (std::size_t r = 0; r < rx.size(); ++r) {
      if (!scratch.hit[r]) continue;
      const Vec3 xr = receiver(r);
      const double d = dot(pl.normal, xr) - pl.offset;
      if (on_face(f, crossing(xs - (2 * ds) * pl.normal, -ds, xr, d))) out.push_back({receivers[r], {faces.refs[f]}});
    }
  }

  // Order 2 over static faces: image I1 of the source in f1, then the image
  // I2 of I1 in f2; the receiver sees I2 through f2, and the line from I1 to
  // that point must cross f1.
  const std::uint32_t ns = max_order >= 2 ? faces.static_count : 0;
  for (std::uint32_t f1 = 0; f1 < ns; ++f1) {
    const Plane& p1 = faces.planes[f1];
    const double ds = dot(p1.normal, xs) - p1.offset;
    if (ds == 0) continue;
    const Vec3 i1 = xs - (2 * ds) * p1.normal;
    // Every continuation of a path reflected by f1 lies in the cone from I1
    // through f1 (on the source's side of f1).
    Cone beam;
    const bool narrow = cone_to(i1, faces.spheres[f1], beam);
    for (std::uint32_t f2 = 0; f2 < ns; ++f2) {
      if (f2 == f1) continue;
      const auto& s2 = faces.spheres[f2];
      // f2 must reach the source's side of f1.
      const double h = dot(p1.normal, s2.centre) - p1.offset;
      if (ds > 0 ? h + s2.radius <= 0 : h - s2.radius >= 0) continue;
      Cone c2;
      if (narrow && cone_to(i1, s2, c2) && !cones_overlap(beam, c2)) continue;
      const Plane& p2 = faces.planes[f2];
      const double di = dot(p2.normal, i1) - p2.offset;
      if (di == 0) continue;
      const Vec3 i2 = i1 - (2 * di) * p2.normal;
      ++local.image_sources;
      local.tests += rx.size();
      // Relative to the source: I1 is at distance di from f2's plane.
      const double off2 = p2.offset - dot(p2.normal, xs);
      if (!mark_crossings(rx, p2, off2, di, i2 - xs, s2, s2.centre - xs, faces.tol[f2], scratch)) continue;
      for (std::size_t r = 0; r < rx.size(); ++r) {
        if (!scratch.hit[r]) continue;
        const Vec3 xr = receiver(r);
        const double d = dot(p2.normal, xr) - p2.offset;
        const Vec3 q2 = crossing(i2, -di, xr, d);
        if (!on_face(f2, q2)) continue;
        const double d2 = dot(p1.normal, q2) - p1.offset;
        if (!(ds * d2 > 0)) continue;
        if (on_face(f1, crossing(i1, -ds, q2, d2))) out.push_back({receivers[r], {faces.refs[f1], faces.refs[f2]}});
      }
    }
  }
  if (stats) {
    stats->image_sources += local.image_sources;
    stats->tests += local.tests;
  }
}

}  // namespace raysweep::tracer
