// Stage `raysweep sweep`: a SUMO FCD trace swept through the tracer, frame by
// frame, into an HDF5 channel dataset (schemas/).
//
// Crash safety: frames are committed in blocks (generators/sweep/frame_block.hpp)
// under <out>.parts/; the dataset is assembled from the blocks at the end into
// a temporary file that is renamed into place. After a kill, --resume keeps
// the committed blocks (when config and inputs are unchanged) and traces the
// rest; the Sweep restarts its cache at every block, so the result equals an
// uninterrupted run's. The same independence of blocks lets a shard trace
// every N-th block only (shard.hpp).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generators/sweep/sweep.hpp"
#include "meshkit/scene.hpp"
#include "pipeline/fcd.hpp"
#include "pipeline/settings/settings.hpp"
#include "pipeline/shard.hpp"
#include "pipeline/trace_inputs.hpp"
#include "pipeline/vtypes.hpp"

namespace raysweep::pipeline {

struct SweepArgs {
  std::string scene;     // folder from `raysweep scene`
  std::string vehicles;  // vehicle library folder; empty: built-in parametric models
  std::string fcd;       // SUMO FCD (.xml or .xml.gz)
  std::vector<std::string> vtypes;  // .sumocfg or route/additional files with the vTypes
  std::string rsus;      // CSV id,x,y,z of road-side-unit antennas
  std::string out;       // .h5
  std::string config;    // TOML: [sweep], [radio], [tracer], [materials.*]
  bool resume = false;
  double eta_end_s = -1;  // simulation end known by the caller (progress ETA); < 0 unknown
  // Trace only this shard's blocks and write a shard file (root attribute
  // `shard`) instead of the whole dataset; `raysweep merge` joins the shards.
  std::optional<ShardSpec> shard;
};

// What a sweep reads of an FCD trace, shared with `raysweep tradeoff` so that
// both trace the same vehicles.

// The FCD filter of a [sweep] table: time window, step, ids, types, area.
FcdFilter sweep_fcd_filter(const SweepSettings& cfg);

// An FCD vehicle type resolved to a library model.
struct FcdTypeModel {
  std::string key;     // name the library found the model under: the type id, else its class
  std::string vclass;  // library class of the type
  const meshkit::VehicleModel* model = nullptr;
  double length_m = 0, width_m = 0, height_m = 0;  // the larger of the model's and the vType's
};

// FCD vehicle types -> models: the vType files give the class (unknown ids are
// passenger cars, with a warning naming the FCD line); a library entry named
// like the type is preferred to the class's. Each type is resolved once.
class FcdTypeModels {
 public:
  // `use_type_entries`: look for library entries named like the type (a
  // `raysweep vehicles` folder; the built-in models only have classes).
  FcdTypeModels(const VTypeMap& vtypes, VehicleLibrary& library, bool use_type_entries, std::string fcd_path);
  // nullptr for types whose class raysweep does not model (warned once).
  const FcdTypeModel* resolve(const FcdVehicle& v);

 private:
  const VTypeMap& vtypes_;
  VehicleLibrary& library_;
  bool use_type_entries_;
  std::string fcd_;
  std::map<std::string, std::optional<FcdTypeModel>> cache_;
};

// An FCD vehicle as the sweep steps it: dataset node `node`, scene model
// `model`, the type's dimensions for its bounding sphere.
generators::SweepVehicle sweep_vehicle(const FcdVehicle& v, const FcdTypeModel& tm, std::uint32_t node,
                                       std::uint32_t model);

// Which vehicles of each frame a sweep traces: [sweep] max_vehicles (the
// first N to appear, refilled as they leave) and outside (a vehicle outside
// the scene's x/y bounds is an InputError naming the FCD line, or dropped and
// counted). Frames must be passed in order, every one of them.
class SweepSelection {
 public:
  SweepSelection(const SweepSettings& cfg, const meshkit::Bounds& scene_bounds, std::string fcd_path);
  // The vehicles to trace, in FCD order, among those `traceable` accepts
  // (vehicles of types without a model are skipped before selection).
  std::vector<const FcdVehicle*> select(const FcdFrame& frame,
                                        const std::function<bool(const FcdVehicle&)>& traceable);
  std::uint64_t dropped_outside() const { return dropped_outside_; }

 private:
  std::size_t max_vehicles_;
  bool drop_outside_;
  meshkit::Bounds bounds_;
  std::string fcd_;
  std::set<std::string> selected_;
  std::uint64_t dropped_outside_ = 0;
};

// [sweep], [radio], [tracer] and [materials.<name>] from `settings`.
nlohmann::json run_sweep_stage(const SweepArgs& args, const Settings& settings, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
