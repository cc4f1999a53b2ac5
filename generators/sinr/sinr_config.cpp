#include "generators/sinr/sinr_config.hpp"

#include <cmath>
#include <stdexcept>

#include "generators/sinr/schedule.hpp"

namespace raysweep::generators::sinr {

namespace {

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

void check_curve(const std::vector<std::pair<double, double>>& curve, const std::string& name) {
  for (std::size_t i = 0; i < curve.size(); ++i) {
    require(std::isfinite(curve[i].first) && curve[i].second >= 0 && curve[i].second <= 1,
            name + ": point " + std::to_string(i) + " needs a finite SINR and a BLER in [0, 1]");
    require(i == 0 || curve[i].first > curve[i - 1].first, name + ": SINR values must increase");
  }
}

}  // namespace

void SinrConfig::check() const {
  require(rats.nr_fraction >= 0 && rats.nr_fraction <= 1, "nr_fraction must be in [0, 1]");
  require(rats.enabled == "both" || rats.enabled == "80211p-only" || rats.enabled == "nrv2x-only",
          "rats_enabled must be both, 80211p-only or nrv2x-only");
  require(cam.t_gen_min_s > 0 && cam.t_gen_max_s >= cam.t_gen_min_s, "CAM intervals need 0 < T_GenCamMin <= T_GenCamMax");
  require(cam.check_period_s > 0 && cam.check_period_s <= cam.t_gen_min_s, "cam_check_period_s must be in (0, T_GenCamMin]");
  require(cam.n_gen_cam >= 1, "cam_n_gen_cam must be >= 1");
  require(cam.bytes > 0, "cam_bytes must be positive");
  require(!cpm.enabled || (cpm.period_s > 0 && cpm.bytes > 0), "CPMs need a positive period and size");
  wifi.check();
  nr.check();
  (void)edca_params(wifi_mac.access_category);
  require(nr_mac.reservation_period_s > 0, "nr_reservation_period_s must be positive");
  const double slots = nr_mac.reservation_period_s / nr.slot_s();
  require(std::abs(slots - std::round(slots)) < 1e-6,
          "nr_reservation_period_s must be a whole number of " + std::to_string(nr.slot_s() * 1e3) + " ms slots");
  require(nr_mac.retransmissions >= 0 && nr_mac.retransmissions <= 31, "nr_retransmissions must be in 0..31");
  require(nr_mac.keep_probability >= 0 && nr_mac.keep_probability <= 1, "nr_keep_probability must be in [0, 1]");
  require(nr_mac.min_candidate_ratio > 0 && nr_mac.min_candidate_ratio <= 1, "nr_min_candidate_ratio must be in (0, 1]");
  require(nr_mac.t1_slots >= 0 && (nr_mac.t2_slots == 0 || nr_mac.t2_slots > nr_mac.t1_slots),
          "NR selection window needs 0 <= T1 < T2");
  const std::uint32_t largest = std::max(cam.enabled ? cam.bytes + cam.low_frequency_bytes : 0u, cpm.enabled ? cpm.bytes : 0u);
  require(nr.subchannels_for(largest) <= nr.subchannels(),
          "a " + std::to_string(largest) + "-byte message needs " + std::to_string(nr.subchannels_for(largest)) +
              " NR subchannels at MCS " + std::to_string(nr.mcs) + " but the channel has " +
              std::to_string(nr.subchannels()) + " (raise nr_bandwidth_hz or nr_mcs, or send smaller messages)");
  for (double v : {tx_power_dbm, sensitivity_dbm, sinr_threshold_db, noise_figure_db, gain_threshold_db})
    require(std::isfinite(v), "power, sensitivity, thresholds and noise figure must be finite");
  check_curve(wifi_bler, "wifi_bler");
  check_curve(nr_bler, "nr_bler");
  require(prr_range_m > 0, "prr_range_m must be positive");
  require(max_receiver_distance_m >= 0, "max_receiver_distance_m must be >= 0");
}

}  // namespace raysweep::generators::sinr
