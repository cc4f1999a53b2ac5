// `raysweep tradeoff`'s metrics: each setting's accuracy and cost against
// the reference (the grid's first setting) on the same snapshots, the
// Pareto front in (time, p95 error) and the suggestion.
#pragma once

#include <array>
#include <cstddef>
#include <utility>
#include <vector>

#include "pipeline/tradeoff/grid.hpp"

namespace raysweep::tracer {
struct Snapshot;
}

namespace raysweep::pipeline {

// Accuracy and cost of one setting over the snapshots.
struct TradeoffResult {
  double time_per_snapshot_s = 0;  // median over snapshots of trace_snapshot's wall time
  double time_mean_s = 0;
  double err_median_db = 0, err_p95_db = 0;  // |G - G_ref| over pairs with G_ref > -200 dB
  double los_agreement = 0;                  // fraction of pairs with the reference's LoS class
  double power_fraction = 0;                 // sum min(P, P_ref) / sum P_ref
  double power_fraction_median = 0;          // median over pairs of min(1, P / P_ref)
  double paths = 0;                          // per snapshot (mean)
  double rays_traced = 0;                    // Embree queries per snapshot (mean)
  double missed_pairs = 0;                   // fraction of compared pairs without any path (gain at the floor)
  // The error a receiver sees: over the pairs whose reference gain reaches
  // G_rx = radio.sensitivity_dbm - radio.tx_power_dbm, |max(G, G_rx) - G_ref|
  // (a pair the setting misses counts down to the sensitivity, not the floor).
  double err_median_rx_db = 0, err_p95_rx_db = 0;
  std::size_t pairs = 0, compared_pairs = 0, rx_pairs = 0;
  std::vector<double> times_s;               // per snapshot
  bool pareto = false;
  // Where the error comes from: of the pairs whose receiver-side error
  // exceeds kAttributionDb, how many have each mechanism (kMechanisms) as the
  // largest power difference to the reference (|P_m - P_ref,m|).
  std::size_t tail_pairs = 0;
  std::vector<std::size_t> tail_by_mechanism;
};

// Mechanism classes for the error attribution: a path's class is diffuse or
// diffraction when it has such an interaction, else its number of specular
// reflections (0: the direct path, through slabs and vehicles' knife edges).
inline constexpr const char* kMechanisms[] = {"direct", "order1", "order2", "order3+", "diffraction", "diffuse"};
inline constexpr std::size_t kMechanismCount = 6;
inline constexpr double kAttributionDb = 1.0;

// Per pair of one snapshot: incoherent gain (linear) and LoS class.
struct PairGains {
  std::vector<double> power;
  std::vector<int> los;
  std::vector<std::array<double, kMechanismCount>> by_mechanism;  // power per mechanism class (may be empty)
};

// Error of `setting` against `reference`, pooled over snapshots (same pairs,
// same order). Gains are floored at -200 dB; `rx_gain_db` is G_rx, the
// weakest gain a receiver hears (for the *_rx_db errors).
void compare_to_reference(const std::vector<PairGains>& setting, const std::vector<PairGains>& reference,
                          TradeoffResult& result, double rx_gain_db = -200);

// Pareto flags for (time, error) points: true when no other point has time
// <= and error <= with at least one strictly smaller. NaN errors are never on it.
std::vector<bool> pareto_front(const std::vector<std::pair<double, double>>& time_error);

// Per pair of one snapshot traced: incoherent gain, LoS class and the power
// of each mechanism class.
PairGains pair_gains(const tracer::Snapshot& traced);

// Per setting: per-snapshot gains (first round), path and ray totals, and
// per snapshot its fastest time over the rounds (measure.hpp).
struct GridTraces {
  std::vector<std::vector<PairGains>> gains;
  std::vector<double> paths, rays_traced;
  std::vector<std::vector<double>> best;
};

// Each setting against the reference (grid[0]), and the Pareto front.
// `rx_gain_db`: G_rx, the weakest gain a receiver hears.
std::vector<TradeoffResult> score(const GridTraces& t, std::size_t n_snapshots, double rx_gain_db);

// The cheapest setting within the target error that agrees on the LoS class (-1: none).
int suggest(const std::vector<TradeoffSetting>& grid, const std::vector<TradeoffResult>& results, double target_p95_db);

}  // namespace raysweep::pipeline
