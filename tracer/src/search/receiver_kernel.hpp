// The searches' vectorised passes: the receivers in structure-of-arrays
// form, the receivers that see an image through a face's sphere
// (mark_crossings) and the spheres that meet a beam (BeamSphereTest).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "search/face_index.hpp"

namespace raysweep::tracer {

// Receivers in structure-of-arrays form, relative to the source (so the
// branch-free passes below vectorise and stay exact at city offsets).
struct Receivers {
  static constexpr std::size_t kLanes = 8;
  std::vector<double> x, y, z;  // padded to whole lanes with NaN (never marked)
  std::vector<std::int64_t> hit;  // 0 or 1; as wide as a lane, so no packing to bytes
  std::size_t n = 0;
  std::size_t size() const { return n; }
  void push(const Vec3& w) {
    x.resize(n), y.resize(n), z.resize(n);
    x.push_back(w[0]);
    y.push_back(w[1]);
    z.push_back(w[2]);
    ++n;
    pad();
  }
  void pad() {
    const std::size_t padded = (n + kLanes - 1) / kLanes * kLanes;
    x.resize(padded, std::numeric_limits<double>::quiet_NaN());
    y.resize(padded, std::numeric_limits<double>::quiet_NaN());
    z.resize(padded, std::numeric_limits<double>::quiet_NaN());
    hit.resize(padded);
  }
};

// The kernel of mark_crossings on raw arrays (receiver_kernel.cpp).
unsigned mark_crossings_kernel(const double* __restrict x, const double* __restrict y, const double* __restrict z,
                               std::int64_t* __restrict hit, std::size_t begin, std::size_t n, const double* nrm,
                               double plane_offset_rel, double ds, const double* img, const double* c, double r2);

// Marks the receivers r whose line from image `img` (signed distance -ds
// from the plane, the source at +ds) crosses the plane inside `sphere`
// (+ tol): the cheap necessary part of "the reflection point is on the
// face". Returns whether any is marked. Inlined at every call: a wrapper
// call per image otherwise.
[[gnu::always_inline]] inline bool mark_crossings(const Receivers& rx, std::size_t begin, const Plane& pl,
                                                  double plane_offset_rel, double ds, const Vec3& img,
                                                  const TraceScene::Sphere& sphere, const Vec3& centre_rel, double tol,
                                                  Receivers& scratch) {
  const double r2 = (sphere.radius + tol) * (sphere.radius + tol);
  return mark_crossings_kernel(rx.x.data(), rx.y.data(), rx.z.data(), scratch.hit.data(), begin, rx.size(),
                               pl.normal.data(), plane_offset_rel, ds, img.data(), centre_rel.data(), r2) != 0;
}

// BeamSphereTest's kernel on raw arrays (receiver_kernel.cpp).
void beam_keep_kernel(const double* __restrict x, const double* __restrict y, const double* __restrict z,
                      const double* __restrict r, const double* __restrict tol, std::size_t n, const double* planes,
                      std::size_t np, const double* apex, double spread_per_m, const double* p2n, double p2off,
                      double side, double* __restrict wx, double* __restrict wy, double* __restrict wz,
                      double* __restrict lim, std::int64_t* __restrict keep);

// beam_keep_kernel over the spheres [begin, begin + count) of
// ImageFaces::beam_spheres, with its scratch kept between calls.
struct BeamSphereTest {
  std::vector<double> planes, wx, wy, wz, lim;
  // The pyramid's inward normals, as the kernel takes them.
  void set_pyramid(const std::vector<Vec3>& pyramid) {
    planes.clear();
    for (const auto& nrm : pyramid) planes.insert(planes.end(), nrm.begin(), nrm.end());
  }
  // keep[0, count): the spheres in the pyramid (set_pyramid) through `apex`
  // and not behind `plane` seen from `side` (a zero normal: no plane).
  void run(const ImageFaces& faces, std::uint32_t begin, std::uint32_t count, const Vec3& apex, double spread_per_m,
           const Plane& plane, double side, std::vector<std::int64_t>& keep) {
    if (keep.size() < count) keep.resize(count);
    if (lim.size() < count) wx.resize(count), wy.resize(count), wz.resize(count), lim.resize(count);
    const auto& c = faces.beam_spheres;
    beam_keep_kernel(c.x.data() + begin, c.y.data() + begin, c.z.data() + begin, c.r.data() + begin,
                     c.tol.data() + begin, count, planes.data(), planes.size() / 3, apex.data(), spread_per_m,
                     plane.normal.data(), plane.offset, side, wx.data(), wy.data(), wz.data(), lim.data(),
                     keep.data());
  }
};

}  // namespace raysweep::tracer
