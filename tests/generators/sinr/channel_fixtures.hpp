// Node states, link records and vehicles shared by the channel model and
// channel trace tests (tests/generators/sinr/).
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "generators/dataset/dataset.hpp"
#include "generators/sinr/channel_trace.hpp"

namespace raysweep::generators::sinr::channel_fixtures {

inline constexpr double kFc = 5.9e9;
inline constexpr float kNoGain = -std::numeric_limits<float>::infinity();

inline NodeState at(std::uint32_t node, double x, double y, double z = 0) {
  NodeState s;
  s.node = node;
  s.x = x, s.y = y, s.z = z;
  return s;
}

inline LinkRecord link_rec(std::uint32_t tx, std::uint32_t rx, float gain, std::uint8_t los, std::uint8_t flags = 0) {
  LinkRecord l;
  l.tx = tx, l.rx = rx, l.los_class = los, l.flags = flags;
  l.gain_coherent_db = l.gain_incoherent_db = gain;
  return l;
}

inline std::vector<NodeInfo> vehicles(std::size_t n) {
  std::vector<NodeInfo> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i].id = "veh" + std::to_string(i);
  return v;
}

}  // namespace raysweep::generators::sinr::channel_fixtures
