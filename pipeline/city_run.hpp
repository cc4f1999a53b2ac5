// `raysweep run CITY.toml`: scene -> vehicles -> traffic -> sweep for one
// city, each stage skipped when its inputs and settings did not change since
// its last successful run (a stamp per stage under <out>/.stamps/).
//
// The city file's [city] table names the inputs (paths relative to the
// file); [scene], [vehicles], [traffic], [sweep], [radio], [tracer] and
// [materials.*] configure the stages (see datasets/demo/city.toml).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace raysweep::pipeline {

struct CityRunArgs {
  std::string city;  // CITY.toml
  std::string out;   // default: [city] out, else out/<name>
  bool resume = false;
  bool force = false;  // run every stage even when up to date
};

struct CityConfig {
  std::string name;
  std::string osm, net;       // absolute paths
  std::string sumocfg, fcd;   // [traffic] sources (absolute; empty when generated)
  std::string rsus;           // [city] rsus CSV (absolute; optional)
  std::string out;
  std::string mitsuba;        // [city] mitsuba: a Sionna scene.xml instead of osm
};
CityConfig load_city_config(const std::string& path);

nlohmann::json run_city(const CityRunArgs& args, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
