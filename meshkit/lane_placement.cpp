#include "meshkit/lane_placement.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <stdexcept>

#include "meshkit/vehicle_classes.hpp"

namespace raysweep::meshkit {

namespace {

// Footprint of a vehicle in the ground plane: front point, unit heading, size.
struct Footprint {
  double x, y, ux, uy, length, width;
  std::array<std::array<double, 2>, 4> corners() const {
    const double px = -uy * width / 2, py = ux * width / 2;
    const double bx = x - ux * length, by = y - uy * length;
    return {{{x + px, y + py}, {x - px, y - py}, {bx - px, by - py}, {bx + px, by + py}}};
  }
};

// Separating-axis test on the two rectangles grown by `margin`.
bool overlap(const Footprint& a, const Footprint& b, double margin) {
  const auto ca = a.corners(), cb = b.corners();
  const std::array<std::array<double, 2>, 4> axes = {{{a.ux, a.uy}, {-a.uy, a.ux}, {b.ux, b.uy}, {-b.uy, b.ux}}};
  for (const auto& ax : axes) {
    double amin = 1e300, amax = -1e300, bmin = 1e300, bmax = -1e300;
    for (const auto& c : ca) {
      const double p = c[0] * ax[0] + c[1] * ax[1];
      amin = std::min(amin, p);
      amax = std::max(amax, p);
    }
    for (const auto& c : cb) {
      const double p = c[0] * ax[0] + c[1] * ax[1];
      bmin = std::min(bmin, p);
      bmax = std::max(bmax, p);
    }
    if (amax + margin < bmin || bmax + margin < amin) return false;
  }
  return true;
}

}  // namespace

std::vector<PoseRow> place_on_lanes(const SumoNetwork& net, int count, std::uint64_t seed,
                                    const std::map<std::string, double>& class_mix, double min_gap_m) {
  struct Segment {
    Vec2 a, b;
    double len;
  };
  std::vector<Segment> segments;
  std::vector<double> cumulative;
  double total = 0;
  for (const auto& lane : net.lane_shapes)
    for (std::size_t i = 1; i < lane.size(); ++i) {
      const double len = std::hypot(lane[i][0] - lane[i - 1][0], lane[i][1] - lane[i - 1][1]);
      if (len < 1e-6) continue;
      segments.push_back({lane[i - 1], lane[i], len});
      total += len;
      cumulative.push_back(total);
    }
  if (segments.empty()) throw std::invalid_argument(net.path + ": the network has no lanes to place vehicles on");
  double weight_sum = 0;
  for (const auto& [c, w] : class_mix) {
    if (!find_vehicle_class(c)) throw std::invalid_argument("unknown vehicle class '" + c + "'");
    if (!(w >= 0)) throw std::invalid_argument("class weight for '" + c + "' must be >= 0");
    weight_sum += w;
  }
  if (!(weight_sum > 0)) throw std::invalid_argument("class mix has no positive weight");
  std::mt19937_64 rng(seed);
  auto uniform = [&rng] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  std::vector<PoseRow> rows;
  std::vector<Footprint> placed;
  // Stratified along the lanes (even spacing, jittered), so dense snapshots
  // fill the network instead of jamming early; then random retries.
  const double spacing = total / count;
  const double margin = std::max(0.0, min_gap_m - 5.0) / 2 + 0.25;
  for (int k = 0, attempt = 0; static_cast<int>(rows.size()) < count; ++attempt) {
    if (attempt > 200 * count)
      throw std::invalid_argument(net.path + ": cannot place " + std::to_string(count) + " vehicles without overlap on " +
                                  std::to_string(total) + " m of lanes (placed " + std::to_string(rows.size()) + ")");
    const double s = k < count ? (k + 0.5 + 0.4 * (uniform() - 0.5)) * spacing : uniform() * total;
    ++k;
    double pick = uniform() * weight_sum;
    std::string vclass = class_mix.begin()->first;
    for (const auto& [c, w] : class_mix) {
      if (pick < w) {
        vclass = c;
        break;
      }
      pick -= w;
    }
    const double speed = 5 + 10 * uniform();
    const auto idx = static_cast<std::size_t>(std::lower_bound(cumulative.begin(), cumulative.end(), s) - cumulative.begin());
    const auto& seg = segments[std::min(idx, segments.size() - 1)];
    const double along = std::clamp(1.0 - (cumulative[std::min(idx, segments.size() - 1)] - s) / seg.len, 0.0, 1.0);
    const double ux = (seg.b[0] - seg.a[0]) / seg.len, uy = (seg.b[1] - seg.a[1]) / seg.len;
    const auto& dims = find_vehicle_class(vclass)->dims;
    const Footprint f{seg.a[0] + along * (seg.b[0] - seg.a[0]), seg.a[1] + along * (seg.b[1] - seg.a[1]), ux, uy,
                      dims.length, dims.width};
    bool clear = true;
    for (const auto& o : placed) clear = clear && !overlap(f, o, margin);
    if (!clear) continue;
    placed.push_back(f);
    PoseRow r;
    r.id = "veh" + std::to_string(rows.size());
    r.vclass = vclass;
    r.x = f.x;
    r.y = f.y;
    r.heading_deg = std::fmod(std::atan2(ux, uy) * 180 / M_PI + 360, 360);
    r.speed_mps = speed;
    rows.push_back(r);
  }
  return rows;
}

}  // namespace raysweep::meshkit
