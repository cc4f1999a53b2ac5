// [traffic]: SUMO's settings for `raysweep run`, or a finished FCD trace.
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

namespace raysweep::pipeline {

// One SUMO run (`raysweep traffic`'s options; `raysweep run` fills them from
// [traffic], the network from [city] and the folder from its output).
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
  nlohmann::json to_json() const;  // the effective table
};

}  // namespace raysweep::pipeline
