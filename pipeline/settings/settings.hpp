// Every stage's settings, read once per run from one parsed config file and
// handed to the stages: `raysweep run CITY.toml` and each stage command load a
// Settings and pass it on; no stage opens the file again.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/city.hpp"
#include "pipeline/settings/features.hpp"
#include "pipeline/settings/ns3.hpp"
#include "pipeline/settings/radiomap.hpp"
#include "pipeline/settings/scene.hpp"
#include "pipeline/settings/sinr.hpp"
#include "pipeline/settings/sweep.hpp"
#include "pipeline/settings/trace.hpp"
#include "pipeline/settings/traffic.hpp"
#include "pipeline/settings/vehicles.hpp"

namespace raysweep::pipeline {

struct Settings {
  std::string file;  // the config file read; empty: the defaults
  std::vector<std::string> sets;  // `--set TABLE.KEY=VALUE` applied over it, in order
  CitySettings city;  // only from load_city_settings
  SceneSettings scene;
  VehiclesSettings vehicles;
  TrafficSettings traffic;
  SweepSettings sweep;
  TraceSettings trace;
  SinrSettings sinr;
  Ns3Settings ns3;
  RadioMapSettings radiomap;
  FeaturesSettings features;
  // Every table with every key, defaults filled in: what `raysweep config`
  // prints and what `raysweep run` stamps its stages with.
  nlohmann::json effective;

  // Adds the --set options (when any) to a stage's provenance record; the
  // effective config it records already holds their values.
  void record_sets(nlohmann::json& provenance) const;
};

// The stage tables of `path` (an empty path gives the defaults): every table
// and key checked against the schema, then the settings that span keys
// ([radio] with [tracer], [sweep] begin and end, [sinr]). Throws ConfigError
// naming file, key and line. `sets`: `--set TABLE.KEY=VALUE` options changing
// the file (overrides.hpp); errors in them name the option.
Settings load_settings(const std::string& path, const std::vector<std::string>& sets = {});

// A city file for `raysweep run`: its [city] table is required, its inputs
// must exist, and [traffic]'s time span is checked when SUMO is to run.
Settings load_city_settings(const std::string& path, const std::vector<std::string>& sets = {});

}  // namespace raysweep::pipeline
