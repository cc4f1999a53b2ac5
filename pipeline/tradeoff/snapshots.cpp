#include "pipeline/tradeoff/snapshots.hpp"

#include <spdlog/spdlog.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <set>

#include "meshkit/errors.hpp"
#include "pipeline/fcd.hpp"
#include "pipeline/sweep_stage.hpp"
#include "pipeline/tradeoff/scenes.hpp"

namespace raysweep::pipeline {

namespace {

// `n` of the eligible frame times, spread evenly over their span (indices).
std::set<std::size_t> spread_choice(const std::vector<double>& eligible, int n) {
  std::set<std::size_t> chosen;
  if (eligible.size() <= static_cast<std::size_t>(n)) {
    for (std::size_t i = 0; i < eligible.size(); ++i) chosen.insert(i);
    return chosen;
  }
  const double t0 = eligible.front(), t1 = eligible.back();
  for (int k = 0; k < n; ++k) {
    const double target = n == 1 ? 0.5 * (t0 + t1) : t0 + (t1 - t0) * k / (n - 1);
    std::size_t best = SIZE_MAX;
    for (std::size_t i = 0; i < eligible.size(); ++i)
      if (!chosen.count(i) && (best == SIZE_MAX || std::abs(eligible[i] - target) < std::abs(eligible[best] - target)))
        best = i;
    chosen.insert(best);
  }
  return chosen;
}

SnapshotPoses snapshot_poses(const FcdFrame& frame, const std::vector<const FcdVehicle*>& selected,
                             FcdTypeModels& type_models) {
  SnapshotPoses s;
  s.time_s = frame.time_s;
  s.line = frame.line;
  for (const FcdVehicle* v : selected) {
    s.vehicles.push_back(SnapVehicle{v->id, type_models.resolve(*v)->key, v->x, v->y, v->has_z ? v->z : 0.0,
                                     v->angle_deg, v->speed_mps});
  }
  return s;
}

}  // namespace

// Pass 1: the frames with at least two traced vehicles; pass 2 takes the
// chosen ones (the selection depends on every earlier frame).
std::vector<SnapshotPoses> choose_snapshots(const std::string& fcd, const SweepSettings& cfg,
                                            const meshkit::Bounds& bounds, FcdTypeModels& type_models, int n) {
  auto traceable = [&](const FcdVehicle& v) { return type_models.resolve(v) != nullptr; };
  std::vector<double> eligible;
  {
    FcdReader reader(fcd, sweep_fcd_filter(cfg));
    SweepSelection selection(cfg, bounds, fcd);
    FcdFrame frame;
    while (reader.next(frame))
      if (selection.select(frame, traceable).size() >= 2) eligible.push_back(frame.time_s);
    if (selection.dropped_outside())
      spdlog::warn("{}: {} vehicle-frames outside the scene dropped", fcd, selection.dropped_outside());
  }
  if (eligible.empty())
    throw meshkit::InputError(fcd, "", "no frame with at least two vehicles to trace (in the [sweep] time window)");
  const std::set<std::size_t> chosen = spread_choice(eligible, n);
  std::vector<SnapshotPoses> snapshots;
  FcdReader reader(fcd, sweep_fcd_filter(cfg));
  SweepSelection selection(cfg, bounds, fcd);
  FcdFrame frame;
  std::size_t index = 0;
  while (snapshots.size() < chosen.size() && reader.next(frame)) {
    const auto selected = selection.select(frame, traceable);
    if (selected.size() < 2) continue;
    if (!chosen.count(index++)) continue;
    snapshots.push_back(snapshot_poses(frame, selected, type_models));
  }
  return snapshots;
}

std::vector<CoherenceFrame> window_frames(const std::string& fcd, const SweepSettings& cfg, TradeoffScenes& scenes,
                                          FcdTypeModels& type_models, int n, std::size_t rsus, int lod) {
  auto traceable = [&](const FcdVehicle& v) { return type_models.resolve(v) != nullptr; };
  SceneVariant& sv = scenes.scene_for(0);
  std::map<std::string, std::uint32_t> node_of;
  std::vector<CoherenceFrame> frames;
  FcdReader reader(fcd, sweep_fcd_filter(cfg));
  SweepSelection selection(cfg, scenes.static_bounds(), fcd);
  for (FcdFrame frame; frames.size() < static_cast<std::size_t>(n) && reader.next(frame);) {
    const auto selected = selection.select(frame, traceable);
    if (frames.empty() && selected.size() < 2) continue;
    CoherenceFrame f{frame.time_s, {}};
    for (const FcdVehicle* v : selected) {
      const FcdTypeModel* tm = type_models.resolve(*v);
      const auto node = node_of.emplace(v->id, static_cast<std::uint32_t>(rsus + node_of.size())).first->second;
      f.vehicles.push_back(sweep_vehicle(*v, *tm, node, scenes.model(sv, lod, tm->key)));
    }
    frames.push_back(std::move(f));
  }
  return frames;
}

}  // namespace raysweep::pipeline
