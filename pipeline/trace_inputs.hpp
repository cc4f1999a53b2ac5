// Inputs of a traced snapshot: vehicle poses and bare antenna nodes (CSV),
// the vehicle library (a `raysweep vehicles` folder or the built-in
// parametric models), and vehicle placement along SUMO lanes.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "meshkit/sumo_net.hpp"
#include "meshkit/vehicle_model.hpp"
#include "tracer/trace_scene.hpp"

namespace raysweep::pipeline {

// One vehicle of a snapshot, in SUMO conventions: (x, y) is the front-bumper
// centre, heading clockwise from north in degrees.
struct PoseRow {
  std::string id, vclass;
  double x = 0, y = 0, z = 0;
  double heading_deg = 0, speed_mps = 0;
};
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

// Vehicle models by library entry name or SUMO class.
class VehicleLibrary {
 public:
  // dir empty: the built-in parametric model of each class. lod < 0: each
  // entry's default LOD.
  explicit VehicleLibrary(const std::string& dir = "", int lod = -1);
  // The model for a pose's class (entry name first, then vclass); throws
  // std::invalid_argument when neither exists.
  const meshkit::VehicleModel& model(const std::string& vclass);
  std::vector<std::string> files() const;  // library files read so far (for provenance)

 private:
  std::string dir_;
  int lod_;
  std::map<std::string, meshkit::VehicleModel> cache_;
  std::vector<std::string> files_;
};

// Adds the models the poses need to `scene` and places the vehicles.
void place_vehicles(tracer::TraceScene& scene, VehicleLibrary& library, const std::vector<PoseRow>& poses);

// `count` vehicles on the network's lanes: evenly spaced along the total lane
// length with a random jitter (random positions when a slot is taken), no
// two footprints closer than (min_gap_m - 5 m) / 2 + 0.25 m, classes drawn
// from `class_mix` (name -> weight), speeds uniform in [5, 15] m/s. The same
// seed gives the same poses.
std::vector<PoseRow> place_on_lanes(const meshkit::SumoNetwork& net, int count, std::uint64_t seed,
                                    const std::map<std::string, double>& class_mix = {{"passenger", 1.0}},
                                    double min_gap_m = 6.0);

}  // namespace raysweep::pipeline
