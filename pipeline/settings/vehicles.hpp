// [vehicles]: the vehicle library `raysweep vehicles` builds.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "meshkit/vehicle_model.hpp"
#include "meshkit/vehicle_segment.hpp"

namespace raysweep::pipeline {

// [vehicles.class.<name>]: overrides for one library entry.
struct VehicleEntrySettings {
  meshkit::VehicleDims dims;         // zero components: the class default
  std::optional<meshkit::Vec3> antenna;  // explicit mount in the library frame
  std::string model_unit;            // the imported model file's unit ("mm"); empty: its own or guessed
};

struct VehiclesSettings {
  std::vector<std::string> classes;  // empty: every built-in class
  std::vector<double> lod_ratios = {1.0, 0.5, 0.25, 0.1};
  double lod_tolerance_m = 0.02;     // default LOD: the smallest within this Hausdorff distance
  double lod_max_error_m = 0.1;      // no decimation step may move the surface more (about 2 wavelengths)
  double antenna_offset_m = 0.05;
  bool scale_to_class = true;        // imported models take the class dimensions
  bool draco = false;
  int draco_position_bits = 0;       // lossless by default: vehicles are small
  meshkit::SegmentationRules rules = meshkit::default_segmentation_rules();
  std::map<std::string, VehicleEntrySettings> entries;  // [vehicles.class.<name>]
  nlohmann::json to_json() const;
};

}  // namespace raysweep::pipeline
