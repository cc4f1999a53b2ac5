#include "tracer/config.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace raysweep::tracer {

void validate(const TracerConfig& t, const RadioConfig& r) {
  auto bad = [](const std::string& what) { throw std::invalid_argument(what); };
  if (!(r.frequency_hz > 0) || !std::isfinite(r.frequency_hz)) bad("radio.frequency_hz must be positive");
  if (!(r.bandwidth_hz > 0) || !std::isfinite(r.bandwidth_hz)) bad("radio.bandwidth_hz must be positive");
  if (!std::isfinite(r.tx_power_dbm)) bad("radio.tx_power_dbm must be finite");
  if (t.max_depth < 0 || t.max_depth > kMaxDepth)
    bad("tracer.max_depth must be within 0.." + std::to_string(kMaxDepth));
  if (t.rays_per_source < 1) bad("tracer.rays_per_source must be at least 1");
  if (t.vehicle_bundle_rays < 1) bad("tracer.vehicle_bundle_rays must be at least 1");
  if (!(t.reception_radius_factor > 0)) bad("tracer.reception_radius_factor must be positive");
  if (t.max_transmissions < 0) bad("tracer.max_transmissions must be >= 0");
  if (!(t.sbr_transmission_loss_db >= 0)) bad("tracer.sbr_transmission_loss_db must be >= 0");
  if (!(t.diffuse_tile_m > 0) || !std::isfinite(t.diffuse_tile_m)) bad("tracer.diffuse_tile_m must be positive");
  if (!(t.diffuse_tile_ratio > 0) || !std::isfinite(t.diffuse_tile_ratio))
    bad("tracer.diffuse_tile_ratio must be positive");
  if (!(t.diffuse_shadow_ratio >= 0) || !std::isfinite(t.diffuse_shadow_ratio))
    bad("tracer.diffuse_shadow_ratio must be >= 0");
  if (!(t.diffuse_roulette_db >= 0)) bad("tracer.diffuse_roulette_db must be >= 0 (300 or more: off)");
  if (!std::isfinite(t.path_threshold_db)) bad("tracer.path_threshold_db must be finite (<= 0 keeps every path)");
  if (std::isnan(t.range_margin_db)) bad("tracer.range_margin_db must be a number");
  if (!std::isfinite(t.vehicle_edge_floor_db)) bad("tracer.vehicle_edge_floor_db must be finite");
  if (!std::isfinite(r.sensitivity_dbm)) bad("radio.sensitivity_dbm must be finite");
}

double max_range_m(const TracerConfig& t, const RadioConfig& r) {
  // Free space: P_rx = P_tx G^2 (lambda / (4 pi d))^2.
  const double budget_db = r.tx_power_dbm - r.sensitivity_dbm + 20 * std::log10(peak_gain(r.antenna.pattern)) +
                           t.range_margin_db;
  const double lambda = kSpeedOfLight / r.frequency_hz;
  return lambda / (4 * kPi) * std::pow(10.0, budget_db / 20);
}

}  // namespace raysweep::tracer
