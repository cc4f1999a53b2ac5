// `raysweep tradeoff`'s measurement: every setting of the grid traced on
// every snapshot, timed, with the gains the metrics compare.
#pragma once

#include <vector>

#include "pipeline/trace_inputs.hpp"
#include "pipeline/tradeoff/grid.hpp"
#include "pipeline/tradeoff/metrics.hpp"
#include "pipeline/tradeoff/scenes.hpp"
#include "pipeline/tradeoff/snapshots.hpp"

namespace raysweep::pipeline {

// `repeats` rounds over every snapshot and setting; the gains come from the
// first (tracing is deterministic), a snapshot's time is its fastest round.
GridTraces trace_grid(const std::vector<TradeoffSetting>& grid, const std::vector<SnapshotPoses>& snapshots,
                      const std::vector<NodeRow>& rsus, const tracer::RadioConfig& radio, int repeats,
                      TradeoffScenes& scenes);

}  // namespace raysweep::pipeline
