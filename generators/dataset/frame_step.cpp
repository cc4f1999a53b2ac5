#include "generators/dataset/frame_step.hpp"

#include <algorithm>
#include <cstddef>

namespace raysweep::generators {

double median_step(const std::vector<double>& times) {
  std::vector<double> dt;
  for (std::size_t f = 1; f < times.size(); ++f) dt.push_back(times[f] - times[f - 1]);
  if (dt.empty()) return 0.1;
  const std::size_t mid = dt.size() / 2;
  std::nth_element(dt.begin(), dt.begin() + mid, dt.end());
  double step = dt[mid];
  if (dt.size() % 2 == 0) step = 0.5 * (step + *std::max_element(dt.begin(), dt.begin() + mid));
  return step;
}

}  // namespace raysweep::generators
