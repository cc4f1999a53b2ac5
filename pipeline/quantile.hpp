// The q-quantile of a sample (0 <= q <= 1), linear between order
// statistics (NumPy's default); NaN for an empty sample.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace raysweep::pipeline {

inline double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

}  // namespace raysweep::pipeline
