// Shared by the SINR generator's tests (tests/generators/sinr/): node states
// and vehicles, and a channel model whose gains the test chooses.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "generators/sinr/channel_models.hpp"
#include "generators/sinr/channel_trace.hpp"
#include "generators/sinr/types.hpp"

namespace raysweep::generators::sinr::fixtures {

inline constexpr double kFc = 5.9e9;
inline constexpr double kInfD = std::numeric_limits<double>::infinity();

inline NodeState at(std::uint32_t node, double x, double y, float vx = 0, float vy = 0, float heading = 0) {
  NodeState s;
  s.node = node;
  s.x = x, s.y = y, s.z = 0;
  s.vx = vx, s.vy = vy;
  s.heading_deg = heading;
  return s;
}

inline std::vector<NodeInfo> vehicles(std::size_t n) {
  std::vector<NodeInfo> v(n);
  for (std::size_t i = 0; i < n; ++i) {
    v[i].id = "veh" + std::to_string(i);
    v[i].kind = NodeKind::vehicle;
    v[i].vtype = "car";
  }
  return v;
}

// Free-space-like gain -(40 + 20 log10 d) (d >= 1 m), no channel beyond `cutoff_m`.
inline double log_distance_gain(double d) { return -(40.0 + 20.0 * std::log10(std::max(d, 1.0))); }

// A channel model whose gains the test chooses: gain(a, b, d) with a < b.
class FakeChannel : public ChannelModel {
 public:
  using GainFn = std::function<double(std::uint32_t, std::uint32_t, double)>;
  FakeChannel(const ChannelTrace& trace, GainFn gain) : trace_(trace), gain_(std::move(gain)) {}
  LinkState link(std::size_t frame, std::uint32_t a, std::uint32_t b) const override {
    LinkState s;
    s.gain_db = -kInfD;
    s.los_class = 2;
    const NodeState* sa = trace_.state(frame, a);
    const NodeState* sb = trace_.state(frame, b);
    if (!sa || !sb || a == b) return s;
    const double d = std::sqrt((sa->x - sb->x) * (sa->x - sb->x) + (sa->y - sb->y) * (sa->y - sb->y) +
                               (sa->z - sb->z) * (sa->z - sb->z));
    s.distance_m = d;
    s.gain_db = gain_(std::min(a, b), std::max(a, b), d);
    s.los_class = 0;
    return s;
  }
  ChannelModelKind kind() const override { return ChannelModelKind::ray; }

 private:
  const ChannelTrace& trace_;
  GainFn gain_;
};

inline FakeChannel::GainFn distance_gain(double cutoff_m) {
  return [cutoff_m](std::uint32_t, std::uint32_t, double d) { return d > cutoff_m ? -kInfD : log_distance_gain(d); };
}

}  // namespace raysweep::generators::sinr::fixtures
