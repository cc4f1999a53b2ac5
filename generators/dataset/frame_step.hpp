// The frame step of a dataset's frame times, which the SINR generator's
// loader and the ns-3 table both take as the time a frame stays in force.
#pragma once

#include <vector>

namespace raysweep::generators {

// Median spacing of increasing times (0.1 s when fewer than two).
double median_step(const std::vector<double>& times);

}  // namespace raysweep::generators
