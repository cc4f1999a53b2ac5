// Stage `raysweep tradeoff`: accuracy against cost of the tracer settings.
//
// A few snapshots of a city's traffic (the vehicles a sweep would trace) are
// traced over a grid of settings (grid.hpp: rays per source, maximum depth,
// each mechanism on/off; scenes.hpp: vehicle LOD, coarser static geometry)
// and against a high-effort reference. Per setting (metrics.hpp): the time
// of trace_snapshot per snapshot, and against the reference on the same
// snapshots the per-pair path-gain error (median and 95th percentile, dB),
// the LoS-class agreement and the fraction of the reference power found.
// report.hpp writes tradeoff.csv, tradeoff.json (with provenance) and
// tradeoff.png (time against error, the Pareto front marked;
// python/tradeoff_chart.py). The coherence toggle (coherence.hpp): a short
// window of consecutive frames swept with [sweep] coherence off and on, in
// tradeoff.json's "coherence".
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/settings.hpp"

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
  // coherence off and on (coherence.hpp); 0: none; < 0: 20 (--quick 4).
  int coherence_window = -1;
  // Its lattice_frames axis, comma-separated; empty: 1,2,4,8 (--quick 1,4).
  std::string lattice_frames;
  bool chart = true;
};

// `settings`: the city file's (load_city_settings) when args.city is given,
// else --config's (load_settings), with args.set applied either way.
nlohmann::json run_tradeoff_stage(const TradeoffArgs& args, const Settings& settings,
                                  const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
