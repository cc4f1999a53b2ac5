// Stage `raysweep vehicles`: the vehicle library the tracer instances at every
// vehicle position: one GLB per entry and LOD plus manifest.json.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "meshkit/vehicle_model.hpp"
#include "pipeline/settings/settings.hpp"

namespace raysweep::pipeline {

struct VehiclesArgs {
  std::string out;
  std::vector<std::string> models;  // CLASS=FILE
  // [CLASS=]UNIT: a model file's length unit. CLASS=UNIT wins over model_unit
  // in [vehicles.class.CLASS], which wins over a bare UNIT (every model).
  std::vector<std::string> model_units;
  std::string vtypes;               // SUMO file with <vType> elements
  bool preview = true;
};

// Builds one library entry (exposed for tests and benchmarks).
struct BuiltVehicle {
  meshkit::VehicleModel model;
  nlohmann::json record;  // manifest entry, without the LOD list
};
BuiltVehicle build_vehicle(const std::string& name, const std::string& vclass, const std::string& model_file,
                           const VehiclesSettings& cfg);

// [vehicles] from `settings`.
nlohmann::json run_vehicles_stage(const VehiclesArgs& args, const Settings& settings,
                                  const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
