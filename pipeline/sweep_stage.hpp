// Stage `raysweep sweep`: a SUMO FCD trace swept through the tracer, frame by
// frame, into an HDF5 channel dataset (schemas/).
//
// Crash safety: frames are committed in blocks (generators/frame_block.hpp)
// under <out>.parts/; the dataset is assembled from the blocks at the end into
// a temporary file that is renamed into place. After a kill, --resume keeps
// the committed blocks (when config and inputs are unchanged) and traces the
// rest; the Sweep restarts its cache at every block, so the result equals an
// uninterrupted run's.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generators/sweep.hpp"

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
};

// [sweep] table. Unknown keys and bad values are ConfigErrors naming file,
// key and line.
struct SweepConfig {
  double begin_s = -1e300, end_s = 1e300, step_s = 0;
  std::vector<std::string> ids, types;
  std::vector<double> area;      // empty or xmin, ymin, xmax, ymax
  std::size_t max_vehicles = 0;  // 0: all; else the first vehicles to appear, refilled as they leave
  std::string outside = "error"; // vehicles outside the scene: "error" or "drop"
  std::string cfr;               // "" | "80211p" | "nr:MU:NRB"
  int lod = -1;
  std::string exclude_objects;
  generators::SweepOptions options;
  nlohmann::json to_json() const;
};
SweepConfig load_sweep_config(const std::string& path);

nlohmann::json run_sweep_stage(const SweepArgs& args, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
