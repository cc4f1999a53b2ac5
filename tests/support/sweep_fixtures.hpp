// Vehicles for the sweep tests (generators/sweep/sweep.hpp).
#pragma once

#include <cmath>
#include <cstdint>

#include "generators/sweep/sweep.hpp"

namespace raysweep::test {

// A vehicle at (x, y) heading `heading_deg` (SUMO's: clockwise from north)
// at `speed` m/s.
inline generators::SweepVehicle sweep_vehicle(std::uint32_t node, std::uint32_t model, double x, double y,
                                              double heading_deg, double speed) {
  generators::SweepVehicle v;
  v.node = node;
  v.model = model;
  v.position = {x, y, 0};
  v.heading_deg = heading_deg;
  const double yaw = (90 - heading_deg) * M_PI / 180;
  v.velocity = {speed * std::cos(yaw), speed * std::sin(yaw), 0};
  return v;
}

}  // namespace raysweep::test
