// Row-major 4x4 affine transforms, shared by the scene and model readers
// (glTF node hierarchies, Mitsuba to_world).
#pragma once

#include <array>

namespace raysweep::meshkit {

using Mat4 = std::array<double, 16>;  // row-major

inline Mat4 identity() { return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}; }

inline Mat4 multiply(const Mat4& a, const Mat4& b) {
  Mat4 c{};
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k) c[i * 4 + j] += a[i * 4 + k] * b[k * 4 + j];
  return c;
}

}  // namespace raysweep::meshkit
