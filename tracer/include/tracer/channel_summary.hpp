// Per-link summaries of a channel's paths that outlive the paths themselves:
// a dataset stored without its paths (generators' `links` and `cfr` levels)
// still answers the questions users ask most of a channel (how dominant its
// strongest path is, where that path comes from, how spread in angle and
// Doppler the power is, how much of it is diffuse).
#pragma once

#include <vector>

#include "tracer/path.hpp"

namespace raysweep::tracer {

struct ChannelSummary {
  double diffuse_gain = 0;  // sum |a|^2 of the paths with a diffuse interaction
  // Rician K-factor: the strongest path's power over the others'. +inf with
  // a single path (or when the others carry nothing), 0 without paths (or
  // without power).
  double k_factor = 0;
  // The strongest path (the first of equals in the paths' order); zeros without paths.
  double strongest_delay_s = 0;
  double strongest_theta_t = 0, strongest_phi_t = 0, strongest_theta_r = 0, strongest_phi_r = 0;
  // Power-weighted angular spreads (rad): azimuth as the circular spread
  // sqrt(-2 ln |sum P e^{j phi}| / sum P) of 3GPP TR 38.901, which
  // ignores where the azimuth wraps; zenith as the RMS about the weighted
  // mean. 0 with fewer than two paths; an azimuth spread is +inf when the
  // phasors cancel exactly.
  double zenith_spread_t = 0, azimuth_spread_t = 0, zenith_spread_r = 0, azimuth_spread_r = 0;
  double rms_doppler_spread_hz = 0;  // power-weighted RMS about the mean Doppler
};

ChannelSummary channel_summary(const std::vector<Path>& paths);

}  // namespace raysweep::tracer
