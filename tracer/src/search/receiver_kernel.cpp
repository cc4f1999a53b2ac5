#include "search/receiver_kernel.hpp"

#include <cmath>

namespace raysweep::tracer {

// The kernel of mark_crossings on raw arrays. Branch-free, so it
// vectorises; x86-64's baseline (SSE2) has no packed double-to-byte
// conversion, so an AVX-512 or AVX2 clone is chosen at load time where the
// CPU has it (eight or four receivers a vector: the receivers are padded to
// eight). AVX-512 carries FMA, so contraction is off: every clone computes
// bitwise the same flags.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("avx512f", "avx2", "default"), optimize("fp-contract=off")))
#endif
unsigned mark_crossings_kernel(const double* __restrict x, const double* __restrict y, const double* __restrict z,
                               std::int64_t* __restrict hit, std::size_t begin, std::size_t n, const double* nrm,
                               double plane_offset_rel, double ds, const double* img, const double* c, double r2) {
  const double nx = nrm[0], ny = nrm[1], nz = nrm[2];
  const double ix = img[0], iy = img[1], iz = img[2];
  // The crossing is img + s (x - img), s = ds / (ds + d); its offset from
  // the centre, scaled by den = ds + d, needs no division (a divide per
  // receiver was this loop's bottleneck): |den (img - c) + ds (x - img)|^2
  // <= r2 den^2. den != 0 wherever ds d > 0.
  const double ax = ix - c[0], ay = iy - c[1], az = iz - c[2];
  // Whole lanes only (the arrays are padded with NaN, which no test
  // passes): a scalar remainder loop cost as much as the vector body at
  // the few dozen receivers a source has. Lanes before `begin` are masked.
  constexpr std::size_t kLanes = Receivers::kLanes;
  const std::size_t from = begin / kLanes * kLanes, to = (n + kLanes - 1) / kLanes * kLanes;
  std::int64_t any = 0;
  for (std::size_t r = from; r < to; ++r) {
    const double d = nx * x[r] + ny * y[r] + nz * z[r] - plane_offset_rel;
    const double den = ds + d;
    const double px = den * ax + ds * (x[r] - ix), py = den * ay + ds * (y[r] - iy), pz = den * az + ds * (z[r] - iz);
    const std::int64_t in = static_cast<std::int64_t>(r >= begin) & static_cast<std::int64_t>(ds * d > 0) &
                            static_cast<std::int64_t>(px * px + py * py + pz * pz <= r2 * (den * den));
    hit[r] = in;
    any |= in;
  }
  return any != 0;
}

// Which spheres k < n (columns x..tol) meet a beam: keep[k] = 1 when the
// sphere is not wholly behind the plane (p2n, p2off) seen from `side` and
// not wholly outside the pyramid of inward unit normals `planes` (np of
// them, x y z each) through `apex`, padded by spread_per_m per metre from
// the apex, 1e-6 per metre and the sphere's tol: beam_pair_candidates'
// scalar tests, sphere by sphere, over whole vectors of spheres. Contraction
// off in every clone, so the flags are bitwise the scalar tests'.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("avx512f", "avx2", "default"), optimize("fp-contract=off")))
#endif
void beam_keep_kernel(const double* __restrict x, const double* __restrict y, const double* __restrict z,
                      const double* __restrict r, const double* __restrict tol, std::size_t n, const double* planes,
                      std::size_t np, const double* apex, double spread_per_m, const double* p2n, double p2off,
                      double side, double* __restrict wx, double* __restrict wy, double* __restrict wz,
                      double* __restrict lim, std::int64_t* __restrict keep) {
  const double ax = apex[0], ay = apex[1], az = apex[2];
  const double nx = p2n[0], ny = p2n[1], nz = p2n[2];
  for (std::size_t k = 0; k < n; ++k) {
    wx[k] = x[k] - ax, wy[k] = y[k] - ay, wz[k] = z[k] - az;
    const double d = std::sqrt(wx[k] * wx[k] + wy[k] * wy[k] + wz[k] * wz[k]);
    const double pad = spread_per_m * (d + r[k]) + tol[k] + 1e-6 * (d + r[k]);
    lim[k] = -(r[k] + pad);
    keep[k] = static_cast<std::int64_t>(!(side * (nx * x[k] + ny * y[k] + nz * z[k] - p2off) + r[k] <= 0));
  }
  for (std::size_t p = 0; p < np; ++p) {
    const double px = planes[3 * p], py = planes[3 * p + 1], pz = planes[3 * p + 2];
    for (std::size_t k = 0; k < n; ++k)
      keep[k] &= static_cast<std::int64_t>(!(px * wx[k] + py * wy[k] + pz * wz[k] < lim[k]));
  }
}

}  // namespace raysweep::tracer
