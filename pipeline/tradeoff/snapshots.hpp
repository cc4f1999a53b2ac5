// The frames `raysweep tradeoff` traces, taken from the FCD as a sweep would
// select them ([sweep] window, area, max_vehicles, outside, the vehicle
// types the library resolves): snapshots spread over the window for the
// grid, and a run of consecutive frames for the coherence toggle.
#pragma once

#include <string>
#include <vector>

#include "meshkit/scene.hpp"
#include "pipeline/settings/sweep.hpp"
#include "pipeline/tradeoff/coherence.hpp"

namespace raysweep::pipeline {

class FcdTypeModels;
class TradeoffScenes;

// A vehicle of a snapshot, as the sweep would place it.
struct SnapVehicle {
  std::string id, key;  // key: library entry (FcdTypeModel::key)
  double x = 0, y = 0, z = 0, heading_deg = 0, speed_mps = 0;
};
struct SnapshotPoses {
  double time_s = 0;
  long line = 0;
  std::vector<SnapVehicle> vehicles;
};

// `n` of the frames with at least two traced vehicles, spread evenly over
// their time span. meshkit::InputError when there is none.
std::vector<SnapshotPoses> choose_snapshots(const std::string& fcd, const SweepSettings& cfg,
                                            const meshkit::Bounds& bounds, FcdTypeModels& type_models, int n);

// `n` consecutive frames (every one the sweep would trace) from the first
// with at least two traced vehicles, as the sweep steps them (nodes
// numbered RSUs first, then vehicles in order of appearance; models at `lod`
// in the scene as built): the coherence toggle's window.
std::vector<CoherenceFrame> window_frames(const std::string& fcd, const SweepSettings& cfg, TradeoffScenes& scenes,
                                          FcdTypeModels& type_models, int n, std::size_t rsus, int lod);

}  // namespace raysweep::pipeline
