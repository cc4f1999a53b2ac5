// Vehicle poses in SUMO conventions, and vehicles placed along the lanes of a
// SUMO network (`raysweep poses`, the benchmarks' snapshots).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "meshkit/sumo_net.hpp"

namespace raysweep::meshkit {

// One vehicle of a snapshot, in SUMO conventions: (x, y) is the front-bumper
// centre, heading clockwise from north in degrees.
struct PoseRow {
  std::string id, vclass;
  double x = 0, y = 0, z = 0;
  double heading_deg = 0, speed_mps = 0;
};

// `count` vehicles on the network's lanes: evenly spaced along the total lane
// length with a random jitter (random positions when a slot is taken), no
// two footprints closer than (min_gap_m - 5 m) / 2 + 0.25 m, classes drawn
// from `class_mix` (name -> weight), speeds uniform in [5, 15] m/s. The same
// seed gives the same poses.
std::vector<PoseRow> place_on_lanes(const SumoNetwork& net, int count, std::uint64_t seed,
                                    const std::map<std::string, double>& class_mix = {{"passenger", 1.0}},
                                    double min_gap_m = 6.0);

}  // namespace raysweep::meshkit
