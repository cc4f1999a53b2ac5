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

namespace raysweep::pipeline {

struct TrafficArgs {
  std::string net;      // SUMO network
  std::string sumocfg;  // demand from a SUMO config, or empty to generate trips
  std::string out;      // output folder
  std::uint64_t seed = 42;       // SUMO's --seed and randomTrips' --seed
  double begin_s = 0, end_s = 300;
  double step_length_s = 0.1;    // FCD sampling (10 Hz)
  // Generated demand (randomTrips.py): a trip every `period_s` seconds.
  double period_s = 1.0;
  double fringe_factor = 5.0;
  std::map<std::string, double> classes = {{"passenger", 8}, {"truck", 1}, {"bus", 1}};  // vClass -> weight
};

// The [traffic] table of a city file: SUMO's settings, or a finished FCD trace
// taken as given. `sumo.net` and `sumo.out` come from [city] and the run.
struct TrafficSettings {
  std::string fcd;   // absolute; empty: run SUMO
  TrafficArgs sumo;  // sumocfg (absolute), seed, time span, random-trip demand
  nlohmann::json to_json() const;  // the effective table (config_tables.hpp)
};

// The path of a program on PATH (or `env_override` when set), or "" when absent.
std::string find_program(const std::string& name, const char* env_override = nullptr);

// Runs argv[0] with arguments, stdout+stderr appended to `log`; throws
// std::runtime_error naming the command and the log when it fails.
void run_program(const std::vector<std::string>& argv, const std::string& log);

nlohmann::json run_traffic_stage(const TrafficArgs& args, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
