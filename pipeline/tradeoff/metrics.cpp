#include "pipeline/tradeoff/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <stdexcept>

#include "pipeline/quantile.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::pipeline {

namespace {

constexpr double kFloorDb = -200.0;  // gains are floored here; pairs whose reference is at the floor are not compared

double gain_db(double p) { return p > 0 ? std::max(kFloorDb, 10.0 * std::log10(p)) : kFloorDb; }

std::size_t mechanism_of(const tracer::Path& path) {
  std::size_t reflections = 0;
  for (const auto& i : path.interactions) {
    if (i.type == tracer::InteractionType::diffuse) return 5;
    if (i.type == tracer::InteractionType::diffraction) return 4;
    if (i.type == tracer::InteractionType::specular) ++reflections;
  }
  return std::min<std::size_t>(reflections, 3);
}

}  // namespace

std::vector<bool> pareto_front(const std::vector<std::pair<double, double>>& pts) {
  std::vector<bool> front(pts.size(), false);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto [ti, ei] = pts[i];
    if (std::isnan(ti) || std::isnan(ei)) continue;
    bool dominated = false;
    for (std::size_t j = 0; j < pts.size() && !dominated; ++j) {
      if (j == i) continue;
      const auto [tj, ej] = pts[j];
      if (std::isnan(tj) || std::isnan(ej)) continue;
      dominated = tj <= ti && ej <= ei && (tj < ti || ej < ei);
    }
    front[i] = !dominated;
  }
  return front;
}

void compare_to_reference(const std::vector<PairGains>& setting, const std::vector<PairGains>& reference,
                          TradeoffResult& r, double rx_gain_db) {
  if (setting.size() != reference.size()) throw std::logic_error("tradeoff: snapshot counts differ");
  std::vector<double> errors, errors_rx, ratios;
  std::size_t pairs = 0, agree = 0, missed = 0;
  r.tail_pairs = 0;
  r.tail_by_mechanism.assign(kMechanismCount, 0);
  double sum_min = 0, sum_ref = 0;
  for (std::size_t s = 0; s < setting.size(); ++s) {
    const auto& a = setting[s];
    const auto& b = reference[s];
    if (a.power.size() != b.power.size()) throw std::logic_error("tradeoff: pair counts differ");
    for (std::size_t p = 0; p < a.power.size(); ++p) {
      ++pairs;
      if (a.los[p] == b.los[p]) ++agree;
      const double P = a.power[p], R = b.power[p];
      sum_ref += R;
      sum_min += std::min(P, R);
      if (R > 0) ratios.push_back(std::min(1.0, P / R));
      const double gr = gain_db(R);
      if (gr > kFloorDb) {
        const double g = gain_db(P);
        errors.push_back(std::abs(g - gr));
        if (gr >= rx_gain_db) {
          const double e = std::abs(std::max(g, rx_gain_db) - gr);
          errors_rx.push_back(e);
          if (e > kAttributionDb && p < a.by_mechanism.size() && p < b.by_mechanism.size()) {
            std::size_t worst = 0;
            double worst_diff = -1;
            for (std::size_t m = 0; m < kMechanismCount; ++m) {
              const double d = std::abs(a.by_mechanism[p][m] - b.by_mechanism[p][m]);
              if (d > worst_diff) worst_diff = d, worst = m;
            }
            ++r.tail_pairs;
            ++r.tail_by_mechanism[worst];
          }
        }
        if (g <= kFloorDb) ++missed;
      }
    }
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  r.pairs = pairs;
  r.compared_pairs = errors.size();
  r.err_median_db = quantile(errors, 0.5);
  r.err_p95_db = quantile(errors, 0.95);
  r.los_agreement = pairs ? static_cast<double>(agree) / static_cast<double>(pairs) : nan;
  r.power_fraction = sum_ref > 0 ? sum_min / sum_ref : nan;
  r.power_fraction_median = quantile(ratios, 0.5);
  r.missed_pairs = errors.empty() ? nan : static_cast<double>(missed) / static_cast<double>(errors.size());
  r.rx_pairs = errors_rx.size();
  r.err_median_rx_db = quantile(errors_rx, 0.5);
  r.err_p95_rx_db = quantile(errors_rx, 0.95);
}

PairGains pair_gains(const tracer::Snapshot& traced) {
  PairGains pg;
  for (const auto& p : traced.pairs) {
    pg.power.push_back(p.stats.gain_incoherent);
    pg.los.push_back(static_cast<int>(p.los_class));
    std::array<double, kMechanismCount> m{};
    for (const auto& path : p.paths) m[mechanism_of(path)] += std::norm(path.a);
    pg.by_mechanism.push_back(m);
  }
  return pg;
}

std::vector<TradeoffResult> score(const GridTraces& t, std::size_t n_snapshots, double rx_gain_db) {
  const double n = static_cast<double>(n_snapshots);
  std::vector<TradeoffResult> results(t.gains.size());
  for (std::size_t g = 0; g < results.size(); ++g) {
    auto& r = results[g];
    r.times_s = t.best[g];
    r.paths = t.paths[g] / n;
    r.rays_traced = t.rays_traced[g] / n;
    r.time_per_snapshot_s = quantile(r.times_s, 0.5);
    double sum = 0;
    for (double x : r.times_s) sum += x;
    r.time_mean_s = sum / n;
    compare_to_reference(t.gains[g], t.gains[0], r, rx_gain_db);
  }
  std::vector<std::pair<double, double>> points;
  for (const auto& r : results) points.emplace_back(r.time_per_snapshot_s, r.err_p95_db);
  const auto front = pareto_front(points);
  for (std::size_t g = 0; g < results.size(); ++g) results[g].pareto = front[g];
  return results;
}

int suggest(const std::vector<TradeoffSetting>& grid, const std::vector<TradeoffResult>& results, double target_p95_db) {
  int suggested = -1;
  for (std::size_t g = 0; g < grid.size(); ++g) {
    const auto& r = results[g];
    if (grid[g].reference || !(r.err_p95_db <= target_p95_db) || !(r.los_agreement >= 0.99)) continue;
    if (suggested < 0 || r.time_per_snapshot_s < results[suggested].time_per_snapshot_s) suggested = static_cast<int>(g);
  }
  return suggested;
}

}  // namespace raysweep::pipeline
