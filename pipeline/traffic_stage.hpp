// Stage `raysweep traffic`: real SUMO traffic as an FCD trace.
//
// Demand comes from a SUMO config (.sumocfg) or is generated on the network
// with SUMO's randomTrips.py (fixed seed, period, fringe factor, a vType mix).
// The `sumo` binary then runs with a fixed seed and writes gzip FCD. The
// output folder holds fcd.xml.gz, the vType files the sweep needs, SUMO's
// log and traffic.json (provenance, commands, time span); it appears only
// when complete.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/traffic.hpp"

namespace raysweep::pipeline {

// The path of a program on PATH (or `env_override` when set), or "" when absent.
std::string find_program(const std::string& name, const char* env_override = nullptr);

// Runs argv[0] with arguments, stdout+stderr appended to `log`; throws
// std::runtime_error naming the command and the log when it fails.
void run_program(const std::vector<std::string>& argv, const std::string& log);

nlohmann::json run_traffic_stage(const TrafficArgs& args, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
