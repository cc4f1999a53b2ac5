// Stage `raysweep ns3-table`: a channel dataset -> the lookup table ns-3's
// Raysweep models read (generators/ns3_table/ns3_table.hpp, schemas/raysweep_ns3_table.schema.json).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/settings.hpp"

namespace raysweep::pipeline {

struct Ns3TableArgs {
  std::string channels;  // channel dataset .h5
  std::string out;       // table .h5
};

// Writes the table through a temporary file renamed into place; returns a summary
// (out, frames, pairs, nodes, bands, gain_source, bytes, bytes_per_pair_frame, wall_seconds).
nlohmann::json run_ns3_table_stage(const Ns3TableArgs& args, const Settings& settings,
                                   const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
