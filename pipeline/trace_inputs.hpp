// Inputs of a traced snapshot: vehicle poses and bare antenna nodes (CSV),
// and the vehicles of a vehicle library placed in a trace scene. The poses,
// the library and the placement along SUMO lanes are meshkit's
// (meshkit/lane_placement.hpp, meshkit/vehicle_library.hpp).
#pragma once

#include <string>
#include <vector>

#include "meshkit/lane_placement.hpp"
#include "meshkit/vehicle_library.hpp"
#include "tracer/trace_scene.hpp"

namespace raysweep::pipeline {

// The snapshot stages name them as their own.
using meshkit::place_on_lanes;
using meshkit::PoseRow;
using meshkit::VehicleLibrary;

struct NodeRow {
  std::string id;
  double x = 0, y = 0, z = 0;
};

// `id,class,x,y,heading_deg,speed_mps[,z]` per row; `id,x,y,z` per row. A
// first line starting with "id" is a header. Errors (std::invalid_argument)
// name the file and line; ids must be unique and numbers finite.
std::vector<PoseRow> read_poses_csv(const std::string& path);
std::vector<NodeRow> read_nodes_csv(const std::string& path);
std::string poses_csv(const std::vector<PoseRow>& rows);

// The static scene without the objects whose source_id matches the regex
// `pattern` (e.g. the placeholder car boxes of a Sionna scene, which our own
// vehicles replace). Object indices are kept; `dropped` counts the objects.
meshkit::Scene exclude_objects(const meshkit::Scene& scene, const std::string& pattern,
                               std::size_t* dropped = nullptr);

// SUMO heading (clockwise from north, degrees) <-> yaw (counter-clockwise from +x, radians).
double yaw_from_heading(double heading_deg);

// Adds the models the poses need to `scene` and places the vehicles.
void place_vehicles(tracer::TraceScene& scene, VehicleLibrary& library, const std::vector<PoseRow>& poses);

}  // namespace raysweep::pipeline
