// SUMO vehicle classes the traffic may contain, with SUMO's default
// dimensions (sumo.dlr.de/docs/Vehicle_Type_Parameter_Defaults.html, SUMO 1.15).
#pragma once

#include <string>
#include <vector>

#include "meshkit/vehicle_model.hpp"

namespace raysweep::meshkit {

struct VehicleClassInfo {
  std::string vclass;
  VehicleDims dims;
  std::string archetype;  // parametric shape: car, van, truck, bus, semitrailer, motorcycle, bicycle
};

// The built-in library: every class the demo and the issues need.
const std::vector<VehicleClassInfo>& vehicle_classes();
// nullptr for classes SUMO has but raysweep does not model (pedestrian, rail...).
const VehicleClassInfo* find_vehicle_class(const std::string& vclass);

}  // namespace raysweep::meshkit
