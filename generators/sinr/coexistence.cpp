#include "generators/sinr/coexistence.hpp"

#include <cmath>
#include <limits>

#include "generators/sinr/phy.hpp"

namespace raysweep::generators::sinr {

namespace {

double mw(double dbm) { return std::pow(10.0, dbm / 10.0); }
double dbm(double mw) { return mw > 0 ? 10.0 * std::log10(mw) : -std::numeric_limits<double>::infinity(); }

double bler_at(const std::vector<std::pair<double, double>>& curve, double sinr_db) {
  if (curve.empty()) return 0;
  if (!(sinr_db > curve.front().first)) return curve.front().second;
  if (sinr_db >= curve.back().first) return curve.back().second;
  for (std::size_t i = 1; i < curve.size(); ++i)
    if (sinr_db < curve[i].first) {
      const auto& [x0, y0] = curve[i - 1];
      const auto& [x1, y1] = curve[i];
      return y0 + (y1 - y0) * (sinr_db - x0) / (x1 - x0);
    }
  return curve.back().second;
}

}  // namespace

int resource_blocks(const Transmission& s, const SinrConfig& c) {
  if (s.rat == Rat::nr_v2x) return std::max(1, static_cast<int>(std::lround((s.f_hi_hz - s.f_lo_hz) / c.nr.rb_bandwidth_hz())));
  return std::max(1, static_cast<int>(std::lround((s.f_hi_hz - s.f_lo_hz) / WifiPhy::kSubcarrierHz)));
}

SinrBreakdown coexistence_sinr(const Transmission& s, double signal_gain_db, const std::vector<OverlapInput>& overlaps,
                               const SinrConfig& c) {
  SinrBreakdown out;
  const double bw = s.f_hi_hz - s.f_lo_hz;
  const int blocks = resource_blocks(s, c);
  const double w = bw / blocks;
  const double signal_mw = std::isfinite(signal_gain_db) ? mw(s.power_dbm + signal_gain_db) : 0.0;
  const double n0_mw_per_hz = mw(noise_dbm(1.0, c.noise_figure_db));
  std::vector<double> interference(static_cast<std::size_t>(blocks), 0.0);
  double intra = 0, inter = 0;
  out.overlaps.reserve(overlaps.size());
  for (const auto& o : overlaps) {
    const Transmission& j = *o.tx;
    Interferer rec;
    rec.transmission = o.row;
    rec.gain_db = static_cast<float>(o.gain_db);
    rec.inter_rat = j.rat != s.rat;
    rec.counted = !rec.inter_rat || o.gain_db >= c.gain_threshold_db;
    const double time_share = overlap(s.start_s, s.end_s(), j.start_s, j.end_s()) / s.duration_s;
    const double psd = std::isfinite(o.gain_db) ? mw(j.power_dbm + o.gain_db) / (j.f_hi_hz - j.f_lo_hz) : 0.0;
    const double added = psd * overlap(s.f_lo_hz, s.f_hi_hz, j.f_lo_hz, j.f_hi_hz) * time_share;
    rec.power_dbm = static_cast<float>(dbm(added));
    if (rec.counted) {
      ++out.counted;
      (rec.inter_rat ? inter : intra) += added;
      for (int b = 0; b < blocks; ++b) {
        const double lo = s.f_lo_hz + b * w;
        interference[static_cast<std::size_t>(b)] += psd * overlap(lo, lo + w, j.f_lo_hz, j.f_hi_hz) * time_share;
      }
    }
    out.overlaps.push_back(rec);
  }
  double sinr_sum = 0;
  const double s_block = signal_mw / blocks, n_block = n0_mw_per_hz * w;
  for (double i : interference) sinr_sum += s_block / (n_block + i);
  out.prx_dbm = dbm(signal_mw);
  out.intra_dbm = dbm(intra);
  out.inter_dbm = dbm(inter);
  out.noise_dbm = noise_dbm(bw, c.noise_figure_db);
  out.sinr_db = dbm(sinr_sum / blocks);
  return out;
}

bool decodable(Rat rat, double sinr_db, double prx_dbm, const SinrConfig& c, double u) {
  if (!(prx_dbm >= c.sensitivity_dbm)) return false;
  const auto& curve = rat == Rat::nr_v2x ? c.nr_bler : c.wifi_bler;
  if (curve.empty()) return sinr_db >= c.sinr_threshold_db;
  return u >= bler_at(curve, sinr_db);
}

}  // namespace raysweep::generators::sinr
