// [radiomap]: the path gain map of `raysweep radiomap` (docs/radiomap.md).
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

}  // namespace raysweep::pipeline
