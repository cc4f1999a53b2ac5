// Small double-precision vector helpers for path geometry. Embree works in
// float; every quantity a user sees (lengths, delays, angles) is computed here
// in double so single precision never costs centimetres.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "meshkit/scene.hpp"

namespace raysweep::tracer {

using meshkit::Vec3;

inline Vec3 operator+(const Vec3& a, const Vec3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
inline Vec3 operator-(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline Vec3 operator-(const Vec3& a) { return {-a[0], -a[1], -a[2]}; }
inline Vec3 operator*(double s, const Vec3& a) { return {s * a[0], s * a[1], s * a[2]}; }
inline double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }
inline Vec3 normalize(const Vec3& a) {
  const double n = norm(a);
  return n > 0 ? (1.0 / n) * a : Vec3{0, 0, 0};
}
// Any unit vector perpendicular to unit `a` (deterministic).
inline Vec3 any_perpendicular(const Vec3& a) {
  const Vec3 helper = std::fabs(a[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  return normalize(cross(a, helper));
}
// Spherical angles of a unit direction: theta from +z, phi from +x towards +y.
inline double zenith(const Vec3& d) { return std::acos(std::fmax(-1.0, std::fmin(1.0, d[2]))); }
inline double azimuth(const Vec3& d) { return std::atan2(d[1], d[0]); }

// n directions of a spherical Fibonacci lattice (deterministic, near-uniform).
inline std::vector<Vec3> fibonacci_sphere(int n) {
  std::vector<Vec3> dirs(static_cast<std::size_t>(n > 0 ? n : 0));
  const double golden = 3.14159265358979323846 * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(std::fmax(0.0, 1.0 - z * z));
    dirs[i] = Vec3{r * std::cos(golden * i), r * std::sin(golden * i), z};
  }
  return dirs;
}

// The lattice above turned by a rotation drawn from `turn` (0: not turned).
// A rotation keeps every direction's cell area, so a turned lattice is as
// good a quadrature as the original; sweeps turn it frame by frame so that
// consecutive frames sample different directions (docs/tracer.md).
inline std::vector<Vec3> fibonacci_sphere(int n, std::uint64_t turn) {
  std::vector<Vec3> dirs = fibonacci_sphere(n);
  if (turn == 0) return dirs;
  // splitmix64: three uniforms, then Shoemake's uniform random unit quaternion.
  std::uint64_t state = turn;
  auto uniform = [&state] {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return static_cast<double>((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
  };
  const double u1 = uniform(), u2 = uniform(), u3 = uniform(), two_pi = 6.283185307179586;
  const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
  const double x = a * std::sin(two_pi * u2), y = a * std::cos(two_pi * u2);
  const double z = b * std::sin(two_pi * u3), w = b * std::cos(two_pi * u3);
  const double m[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                          {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                          {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
  for (auto& d : dirs) {
    const Vec3 v = d;
    for (int r = 0; r < 3; ++r) d[r] = m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2];
  }
  return dirs;
}

}  // namespace raysweep::tracer
