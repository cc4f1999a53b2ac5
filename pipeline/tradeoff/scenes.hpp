// The scenes `raysweep tradeoff` traces: the static scene at each
// simplification the grid asks for and the vehicle library at each LOD,
// built when first asked for, and the grid's variants that depend on them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "meshkit/scene.hpp"
#include "meshkit/scene_simplify.hpp"
#include "pipeline/trace_inputs.hpp"
#include "pipeline/tradeoff/grid.hpp"
#include "pipeline/tradeoff/snapshots.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::pipeline {

struct SceneVariant {
  std::unique_ptr<tracer::TraceScene> scene;
  std::map<std::pair<int, std::string>, std::uint32_t> models;  // (lod, library key) -> model index
  meshkit::SimplifyStats stats;
};

class TradeoffScenes {
 public:
  // `store`: where the vehicle models' precomputed tables are kept (the scene's cache/).
  TradeoffScenes(meshkit::Scene static_scene, std::string vehicles_dir,
                 std::shared_ptr<const tracer::PrecomputeStore> store);

  meshkit::Bounds static_bounds() const { return scenes_.at(0.0).scene->static_bounds(); }
  bool library_mode() const { return !vehicles_dir_.empty(); }

  VehicleLibrary& library(int lod);  // by LOD (built-in: one, key 0)
  SceneVariant& scene_for(double simplify_m);
  std::size_t triangles(double simplify_m) const { return scenes_.at(simplify_m).stats.triangles_after; }

  // The scene model of library entry `key` at `lod` (registered on first use).
  std::uint32_t model(SceneVariant& sv, int lod, const std::string& key);

  // The snapshot's vehicles (at `lod`) placed in `sv`; its antennas and the RSUs.
  std::vector<tracer::Node> place(SceneVariant& sv, int lod, const SnapshotPoses& snap, const std::vector<NodeRow>& rsus);

 private:
  const meshkit::Scene static_;
  const std::string vehicles_dir_;
  std::shared_ptr<const tracer::PrecomputeStore> store_;
  std::map<double, SceneVariant> scenes_;
  std::map<int, std::unique_ptr<VehicleLibrary>> libraries_;
};

// The coarsest LOD every entry the snapshots use has (-1: none, or built-in models).
int coarsest_lod(TradeoffScenes& scenes, const std::string& vehicles_dir, const std::vector<SnapshotPoses>& snapshots);

// The variants known only once the snapshots are: the coarsest vehicle LOD,
// and each static simplification that changes the scene.
void add_scene_variants(const GridBase& b, const GridAxes& axes, int coarsest, TradeoffScenes& scenes,
                        std::vector<TradeoffSetting>& grid);

}  // namespace raysweep::pipeline
