// Stage `raysweep radiomap`: the path gain from one or more transmitters at
// every voxel of the streets (or the open air of the scene box), written as
// one OpenVDB file (pipeline/radiomap_vdb.hpp), with an optional PNG slice.
// The solver is generators/radiomap_solver.hpp; docs/radiomap.md describes
// the file and the error against `raysweep trace`.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tracer/vec.hpp"

namespace raysweep::pipeline {

struct RadioMapTx {
  std::string id;
  tracer::Vec3 position{0, 0, 0};
  double power_dbm = 0;  // [radio] tx_power_dbm unless given
  bool power_given = false;
};

// "ID,X,Y,Z[,POWER_DBM]"; std::invalid_argument naming `what` otherwise.
RadioMapTx parse_radiomap_tx(const std::string& spec, const std::string& what);

// The [radiomap] table (unknown keys are ConfigErrors naming file, key, line).
struct RadioMapSettings {
  double voxel_m = 1.0;
  double z_min_m = 0.5, z_max_m = 3.0;  // voxel centres k: z_min + k voxel_m <= z_max
  std::string region;                   // "streets" | "all"; empty: streets when a network is known
  double street_margin_m = 3.0;         // streets: voxel centres within this distance of a lane centre line
  // Diffuse scattering (tracer.diffuse, "rays"): gathered exactly at one voxel
  // per block of this size (m) and layer, the voxel nearest the block's
  // centre, and given to every voxel of the block; 0: at every voxel.
  double diffuse_block_m = 2.0;
  std::vector<RadioMapTx> tx;           // tx = ["ID,X,Y,Z[,P]", ...]
  bool png = true;                      // `raysweep run`: the slice picture
  bool present = false;                 // the file has a [radiomap] table
  nlohmann::json to_json() const;
};
RadioMapSettings load_radiomap_settings(const std::string& path);

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

nlohmann::json run_radiomap_stage(const RadioMapArgs& args, const std::vector<std::string>& argv);

// `raysweep run`: <out>/radiomap.vdb and radiomap.png from the city's
// [radiomap] table, then <out>/render.png (the scene and the map) when Blender
// is installed. Redone when the scene or the city file is newer (or `force`).
nlohmann::json run_city_radiomap(const std::string& city_file, const std::string& out, const std::string& scene_dir,
                                 const std::string& net, bool force, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
