// Stage `raysweep vehicles`: the vehicle library the tracer instances at every
// vehicle position: one GLB per entry and LOD plus manifest.json.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "meshkit/vehicle_model.hpp"
#include "meshkit/vehicle_segment.hpp"

namespace raysweep::pipeline {

struct VehicleEntryConfig {
  meshkit::VehicleDims dims;         // zero components: the class default
  std::optional<meshkit::Vec3> antenna;  // explicit mount in the library frame
  std::string model_unit;            // the imported model file's unit ("mm"); empty: its own or guessed
};

struct VehiclesConfig {
  std::vector<std::string> classes;  // empty: every built-in class
  std::vector<double> lod_ratios = {1.0, 0.5, 0.25, 0.1};
  double lod_tolerance_m = 0.02;     // default LOD: the smallest within this Hausdorff distance
  double lod_max_error_m = 0.1;      // no decimation step may move the surface more (about 2 wavelengths)
  double antenna_offset_m = 0.05;
  bool scale_to_class = true;        // imported models take the class dimensions
  bool draco = false;
  int draco_position_bits = 0;       // lossless by default: vehicles are small
  meshkit::SegmentationRules rules = meshkit::default_segmentation_rules();
  std::map<std::string, VehicleEntryConfig> entries;  // [vehicles.class.<name>]
  nlohmann::json to_json() const;
};

// Reads the [vehicles] table (unknown keys are errors naming file and line).
VehiclesConfig load_vehicles_config(const std::string& path);

struct VehiclesArgs {
  std::string out;
  std::string config;
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
                           const VehiclesConfig& cfg);

nlohmann::json run_vehicles_stage(const VehiclesArgs& args, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
