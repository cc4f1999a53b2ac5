#include "tracer/channel_summary.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>

namespace raysweep::tracer {

namespace {

// Circular spread of power-weighted angles: the resultant's length R of the
// unit phasors gives sqrt(-2 ln R); rounding can put R a hair above 1.
double circular_spread(const std::vector<Path>& paths, double total, double Path::*angle) {
  std::complex<double> r{0, 0};
  for (const Path& p : paths) r += std::norm(p.a) * std::polar(1.0, p.*angle);
  const double len = std::min(1.0, std::abs(r) / total);
  return len > 0 ? std::sqrt(std::max(0.0, -2 * std::log(len))) : std::numeric_limits<double>::infinity();
}

// RMS spread about the power-weighted mean, centred on the first path's
// value so that large offsets do not cancel the spread away.
double rms_spread(const std::vector<Path>& paths, double total, double Path::*value) {
  const double ref = paths.front().*value;
  double m1 = 0, m2 = 0;
  for (const Path& p : paths) {
    const double w = std::norm(p.a), d = p.*value - ref;
    m1 += w * d;
    m2 += w * d * d;
  }
  m1 /= total;
  m2 /= total;
  return std::sqrt(std::max(0.0, m2 - m1 * m1));
}

}  // namespace

ChannelSummary channel_summary(const std::vector<Path>& paths) {
  ChannelSummary s;
  if (paths.empty()) return s;
  double total = 0, strongest_power = -1;
  const Path* strongest = &paths.front();
  for (const Path& p : paths) {
    const double w = std::norm(p.a);
    total += w;
    if (w > strongest_power) strongest_power = w, strongest = &p;
    for (const Interaction& in : p.interactions)
      if (in.type == InteractionType::diffuse) {
        s.diffuse_gain += w;
        break;
      }
  }
  s.strongest_delay_s = strongest->tau_s;
  s.strongest_theta_t = strongest->theta_t;
  s.strongest_phi_t = strongest->phi_t;
  s.strongest_theta_r = strongest->theta_r;
  s.strongest_phi_r = strongest->phi_r;
  if (!(total > 0)) return s;  // all-zero gains: nothing to weigh with
  const double rest = total - strongest_power;
  s.k_factor = rest > 0 ? strongest_power / rest : std::numeric_limits<double>::infinity();
  if (paths.size() < 2) return s;
  s.zenith_spread_t = rms_spread(paths, total, &Path::theta_t);
  s.zenith_spread_r = rms_spread(paths, total, &Path::theta_r);
  s.azimuth_spread_t = circular_spread(paths, total, &Path::phi_t);
  s.azimuth_spread_r = circular_spread(paths, total, &Path::phi_r);
  s.rms_doppler_spread_hz = rms_spread(paths, total, &Path::doppler_hz);
  return s;
}

}  // namespace raysweep::tracer
