// Built-in parametric vehicles, so the demo needs no external model: each is
// a set of closed convex solids (body, glazed cabin, wheels, lights, riders)
// whose faces belong to separate parts with radio materials.
#pragma once

#include <string>

#include "meshkit/vehicle_classes.hpp"
#include "meshkit/vehicle_model.hpp"

namespace raysweep::meshkit {

// Model of `archetype` (see VehicleClassInfo) filling exactly `dims`, in the
// library frame, segmented (rule "parametric") with its antenna mount set.
VehicleModel parametric_vehicle(const std::string& name, const std::string& vclass, const std::string& archetype,
                                const VehicleDims& dims, double antenna_offset_m = 0.05);

}  // namespace raysweep::meshkit
