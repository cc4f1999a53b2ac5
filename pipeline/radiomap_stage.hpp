// Stage `raysweep radiomap`: the path gain from one or more transmitters at
// every voxel of the streets (or the open air of the scene box), written as
// one OpenVDB file (pipeline/radiomap_vdb.hpp), with an optional PNG slice.
// The solver is tracer/radiomap_solver.hpp; docs/radiomap.md describes
// the file and the error against `raysweep trace`.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/settings.hpp"

namespace raysweep::pipeline {

struct RadioMapArgs {
  std::string scene;     // `raysweep scene` folder
  std::string vehicles;  // vehicle library; empty: built-in parametric models
  std::string poses;     // CSV of vehicles in the map (optional)
  std::string net;       // SUMO network for region "streets"; default: the scene manifest's
  std::vector<std::string> tx;  // "ID,X,Y,Z[,P]": added to the config's
  std::string out;       // MAP.vdb
  std::string config;    // TOML: [radiomap], [radio], [tracer], [materials.*]
  std::string png;       // optional slice picture
  int check = 0;         // trace this many voxels with the per-point tracer and report the agreement
  int lod = -1;
};

// [radiomap], [radio], [tracer] and [materials.<name>] from `settings`.
nlohmann::json run_radiomap_stage(const RadioMapArgs& args, const Settings& settings,
                                  const std::vector<std::string>& argv);

// `raysweep run`: <out>/radiomap.vdb and radiomap.png from the city's
// [radiomap] table, then <out>/render.png (the scene and the map) when Blender
// is installed. Redone when the scene or the city file is newer (or `force`).
nlohmann::json run_city_radiomap(const Settings& city, const std::string& out, const std::string& scene_dir,
                                 const std::string& net, bool force, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
