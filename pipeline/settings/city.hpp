// [city]: the inputs of `raysweep run CITY.toml` (paths relative to the file).
#pragma once

#include <string>

namespace raysweep::pipeline {

struct CitySettings {
  std::string name;
  std::string osm, net;       // absolute paths
  std::string sumocfg, fcd;   // [traffic] sources (absolute; empty when generated)
  std::string rsus;           // [city] rsus CSV (absolute; optional)
  std::string out;
  std::string mitsuba;        // [city] mitsuba: a Sionna scene.xml instead of osm
};

}  // namespace raysweep::pipeline
