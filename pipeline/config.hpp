// Stage configuration from TOML, read through the declared schema
// (config_tables.hpp). Unknown keys and wrong types are errors that name the
// file, the key and its line: a typo must never fall back silently.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "meshkit/city.hpp"

namespace raysweep::pipeline {

struct SceneConfig {
  meshkit::CityOptions city;
  bool draco = false;
  // Draco quantises over each mesh's whole extent: 20 bits keep a 5 km city
  // mesh within 2.4 mm (16 bits would allow 3.8 cm, near a 5.9 GHz wavelength).
  int draco_position_bits = 20;
  // The effective configuration (defaults filled in) for provenance records.
  nlohmann::json to_json() const;
};

// Reads the [scene] table of `path` (the other tables are checked too, and
// read by their stages). An empty path gives the defaults.
SceneConfig load_scene_config(const std::string& path);

// Thrown for config errors; the message names file, key and line.
struct ConfigError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace raysweep::pipeline
