#include "pipeline/tradeoff/measure.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

namespace raysweep::pipeline {

// Snapshot-major, settings interleaved (and every repeat another full
// round), so a burst of load from elsewhere on the machine spreads over all
// settings instead of falsifying one; a snapshot's time is its fastest repeat.
GridTraces trace_grid(const std::vector<TradeoffSetting>& grid, const std::vector<SnapshotPoses>& snapshots,
                      const std::vector<NodeRow>& rsus, const tracer::RadioConfig& radio, int repeats,
                      TradeoffScenes& scenes) {
  for (const auto& s : grid) scenes.scene_for(s.simplify_m);
  GridTraces t{std::vector<std::vector<PairGains>>(grid.size()), std::vector<double>(grid.size(), 0),
               std::vector<double>(grid.size(), 0),
               std::vector<std::vector<double>>(grid.size(), std::vector<double>(snapshots.size(), INFINITY))};
  for (int rep = 0; rep < repeats; ++rep)
    for (std::size_t k = 0; k < snapshots.size(); ++k) {
      const auto t_snap = std::chrono::steady_clock::now();
      for (std::size_t g = 0; g < grid.size(); ++g) {
        const auto& s = grid[g];
        SceneVariant& sv = scenes.scene_for(s.simplify_m);
        const auto nodes = scenes.place(sv, s.lod, snapshots[k], rsus);
        const auto t0 = std::chrono::steady_clock::now();
        const tracer::Snapshot traced = tracer::trace_snapshot(*sv.scene, nodes, s.tracer, radio);
        t.best[g][k] = std::min(t.best[g][k], std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        if (rep > 0) continue;  // deterministic: the first round has the results
        t.gains[g].push_back(pair_gains(traced));
        t.paths[g] += static_cast<double>(traced.stats.paths);
        t.rays_traced[g] += static_cast<double>(traced.stats.rays);
      }
      spdlog::info("snapshot {}/{}{} (t = {:.1f} s, {} vehicles): {} settings in {:.1f} s", k + 1, snapshots.size(),
                   repeats > 1 ? fmt::format(", round {}/{}", rep + 1, repeats) : std::string(), snapshots[k].time_s,
                   snapshots[k].vehicles.size(), grid.size(),
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - t_snap).count());
    }
  return t;
}

}  // namespace raysweep::pipeline
