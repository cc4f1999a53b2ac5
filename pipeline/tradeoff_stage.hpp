// Stage `raysweep tradeoff`: accuracy against cost of the tracer settings.
//
// A few snapshots of a city's traffic (the vehicles a sweep would trace) are
// traced over a grid of settings (rays per source, maximum depth, each
// mechanism on/off, vehicle LOD, coarser static geometry) and against a
// high-effort reference. Per setting: the time of trace_snapshot per
// snapshot, and against the reference on the same snapshots the per-pair
// path-gain error (median and 95th percentile, dB), the LoS-class agreement
// and the fraction of the reference power found. Writes tradeoff.csv,
// tradeoff.json (with provenance) and tradeoff.png (time against error, the
// Pareto front marked; python/tradeoff_chart.py). The coherence toggle: a
// short window of consecutive frames swept with [sweep] coherence off and on
// (tradeoff_coherence.hpp), in tradeoff.json's "coherence".
#pragma once

#include <array>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "tracer/config.hpp"

namespace raysweep::pipeline {

struct TradeoffArgs {
  // Either a city file (the outputs of an earlier `raysweep run CITY.toml`,
  // under city_out when it ran with --out)...
  std::string city, city_out;
  // ...or explicit inputs, as for `raysweep sweep`.
  std::string scene, vehicles, fcd, config, rsus;
  std::vector<std::string> vtypes;
  std::vector<std::string> set;  // `--set TABLE.KEY=VALUE` over the city or config file
  std::string out;  // default with a city: <city out>/tradeoff
  int snapshots = 0;  // 0: 4 (--quick: 2)
  std::string rays, depths, simplify;  // comma-separated lists; empty: the defaults
  int reference_rays = 0;              // 0: 4 x the largest grid value
  int reference_depth = -1;            // < 0: largest grid depth + 1, at most 5
  bool quick = false;                  // a tiny grid (tests)
  int repeats = 1;                     // rounds over all snapshots and settings; a snapshot's time is its fastest
  double target_p95_db = 3;            // the suggestion: cheapest setting within this p95 error
  // The coherence toggle: this many consecutive frames swept with [sweep]
  // coherence off and on (tradeoff_coherence.hpp); 0: none; < 0: 20 (--quick 4).
  int coherence_window = -1;
  bool chart = true;
};

// One setting of the grid.
struct TradeoffSetting {
  std::string label;
  tracer::TracerConfig tracer;
  int lod = -1;              // vehicle LOD; -1: each library entry's default
  double simplify_m = 0;     // static geometry decimated within this error (m); 0: as built
  bool reference = false;
};

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

// "1024,4096" -> {1024, 4096}; std::invalid_argument naming `option` for
// anything but integers in [min, max].
std::vector<int> parse_int_list(const std::string& option, const std::string& text, int min, int max);
std::vector<double> parse_number_list(const std::string& option, const std::string& text, double min);

nlohmann::json run_tradeoff_stage(const TradeoffArgs& args, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
