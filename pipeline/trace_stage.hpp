// Stage `raysweep trace`: one snapshot (static scene + vehicles at given
// poses + bare nodes) traced for every pair of antennas, written as JSON.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/settings.hpp"
#include "tracer/channel.hpp"
#include "tracer/solver.hpp"

namespace raysweep::pipeline {

struct TraceArgs {
  std::string scene;     // folder written by `raysweep scene` (scene.glb)
  std::string vehicles;  // vehicle library folder; empty: built-in parametric models
  std::string poses;     // CSV id,class,x,y,heading_deg,speed_mps[,z]
  std::string nodes;     // CSV id,x,y,z
  std::string out;       // .json (trace document) or .h5 (one-frame channel dataset)
  int lod = -1;          // vehicle LOD; -1: each entry's default
  std::string exclude_objects;  // regex on static object ids to leave out (e.g. "^mesh-car_")
  std::string cfr;              // "" | "80211p" | "nr:MU:NRB": add each pair's frequency response
  std::string mitsuba;          // folder: the snapshot for a peer tracer (pipeline/peer_export.hpp)
};

// [radio], [tracer] and [materials.<name>] from `settings`. With `mitsuba`
// set, the snapshot is also exported there; with `out` empty, only exported.
nlohmann::json run_trace_stage(const TraceArgs& args, const Settings& settings, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
