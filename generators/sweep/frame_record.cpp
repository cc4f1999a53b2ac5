#include "generators/sweep/frame_record.hpp"

#include <algorithm>

#include "tracer/channel_summary.hpp"

namespace raysweep::generators {

LinkRecord link_record(const tracer::PairResult& res, std::uint32_t tx, std::uint32_t rx) {
  LinkRecord L;
  L.tx = tx;
  L.rx = rx;
  L.los_class = static_cast<std::uint8_t>(res.los_class);
  L.blocker_count = static_cast<std::uint16_t>(std::min<std::size_t>(res.blockers.size(), 65535));
  L.gain_coherent_db = static_cast<float>(tracer::to_db(res.stats.gain_coherent));
  L.gain_incoherent_db = static_cast<float>(tracer::to_db(res.stats.gain_incoherent));
  L.first_delay_s = res.stats.first_delay_s;
  L.rms_delay_spread_s = static_cast<float>(res.stats.rms_delay_spread_s);
  L.path_count = static_cast<std::uint32_t>(res.paths.size());
  L.paths_below_threshold = res.dropped_threshold;
  L.los_class_fresnel = static_cast<std::uint8_t>(res.fresnel_class);
  L.fresnel_clearance = static_cast<float>(res.fresnel_clearance);
  L.vehicle_loss_db = static_cast<float>(res.vehicle_loss_db);
  if (res.out_of_range) L.flags |= kLinkOutOfRange;
  const tracer::ChannelSummary sum = tracer::channel_summary(res.paths);
  L.diffuse_gain_db = static_cast<float>(tracer::to_db(sum.diffuse_gain));
  L.k_factor_db = static_cast<float>(tracer::to_db(sum.k_factor));
  L.rms_doppler_spread_hz = static_cast<float>(sum.rms_doppler_spread_hz);
  L.aod_spread[0] = static_cast<float>(sum.zenith_spread_t);
  L.aod_spread[1] = static_cast<float>(sum.azimuth_spread_t);
  L.aoa_spread[0] = static_cast<float>(sum.zenith_spread_r);
  L.aoa_spread[1] = static_cast<float>(sum.azimuth_spread_r);
  L.strongest_excess_delay_s = static_cast<float>(sum.strongest_delay_s - res.stats.first_delay_s);
  L.strongest_aod[0] = static_cast<float>(sum.strongest_theta_t);
  L.strongest_aod[1] = static_cast<float>(sum.strongest_phi_t);
  L.strongest_aoa[0] = static_cast<float>(sum.strongest_theta_r);
  L.strongest_aoa[1] = static_cast<float>(sum.strongest_phi_r);
  return L;
}

PathRecord path_record(const tracer::Path& path) {
  PathRecord pr;
  pr.a = std::complex<float>(static_cast<float>(path.a.real()), static_cast<float>(path.a.imag()));
  pr.tau_s = path.tau_s;
  pr.theta_t = static_cast<float>(path.theta_t);
  pr.phi_t = static_cast<float>(path.phi_t);
  pr.theta_r = static_cast<float>(path.theta_r);
  pr.phi_r = static_cast<float>(path.phi_r);
  pr.doppler_hz = static_cast<float>(path.doppler_hz);
  pr.interaction_count = static_cast<std::uint8_t>(path.interactions.size());
  return pr;
}

InteractionRecord interaction_record(const tracer::Interaction& in, std::uint32_t object) {
  InteractionRecord ir;
  ir.type = static_cast<std::uint8_t>(in.type);
  ir.object = object;
  ir.x = static_cast<float>(in.point[0]);
  ir.y = static_cast<float>(in.point[1]);
  ir.z = static_cast<float>(in.point[2]);
  return ir;
}

std::vector<std::complex<float>> cfr_record(const std::vector<tracer::Path>& paths, const tracer::OfdmGrid& grid) {
  std::vector<std::complex<float>> out;
  for (const auto& h : tracer::frequency_response(paths, grid))
    out.emplace_back(static_cast<float>(h.real()), static_cast<float>(h.imag()));
  return out;
}

}  // namespace raysweep::generators
