// Stage `raysweep ns3-table`: a channel dataset -> the lookup table ns-3's
// Raysweep models read (generators/ns3_table.hpp, schemas/raysweep_ns3_table.schema.json).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace raysweep::pipeline {

// The [ns3] table. Unknown keys and bad values are ConfigErrors naming file, key and line.
struct Ns3Settings {
  bool present = false;  // the file has an [ns3] table (`raysweep run` then writes <out>/ns3/table.h5)
  bool enabled = true;
  std::uint32_t subcarriers_per_band = 4;  // per-band gains from the CFR; 0: none
  nlohmann::json to_json() const;
};
Ns3Settings load_ns3_settings(const std::string& path);

struct Ns3TableArgs {
  std::string channels;  // channel dataset .h5
  std::string out;       // table .h5
  std::string config;    // TOML with an [ns3] table (optional)
};

// Writes the table through a temporary file renamed into place; returns a summary
// (out, frames, pairs, nodes, bands, gain_source, bytes, bytes_per_pair_frame, wall_seconds).
nlohmann::json run_ns3_table_stage(const Ns3TableArgs& args, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
