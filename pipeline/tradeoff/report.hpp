// `raysweep tradeoff`'s report: tradeoff.csv (one row per setting, the
// reference first), tradeoff.json (the same with the snapshots, the
// coherence toggle, what each metric means and provenance), tradeoff.png
// (python/tradeoff_chart.py) and the table the command prints.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/settings.hpp"
#include "pipeline/tradeoff/coherence.hpp"
#include "pipeline/tradeoff/grid.hpp"
#include "pipeline/tradeoff/inputs.hpp"
#include "pipeline/tradeoff/metrics.hpp"
#include "pipeline/tradeoff/scenes.hpp"
#include "pipeline/tradeoff/snapshots.hpp"

namespace raysweep::pipeline {

// Everything a run computed, for the outputs.
struct TradeoffRun {
  std::vector<TradeoffSetting> grid;
  std::vector<TradeoffResult> results;
  std::vector<SnapshotPoses> snapshots;
  std::size_t rsus = 0;
  int suggested = -1;
  std::optional<CoherenceWindowResult> coherence;  // the coherence toggle's window
  double coherence_t0 = 0;
};

nlohmann::json tradeoff_provenance(const TradeoffArgs& args, const TradeoffInputs& in, const Settings& settings,
                                   const GridAxes& axes, const GridBase& b, const std::vector<std::string>& argv);

// tradeoff.csv, tradeoff.json and (args.chart) tradeoff.png under in.out;
// the summary without its wall time.
nlohmann::json write_outputs(const TradeoffArgs& args, const TradeoffInputs& in, const TradeoffRun& run,
                             const nlohmann::json& prov, const GridBase& b, const TradeoffScenes& scenes);

}  // namespace raysweep::pipeline
