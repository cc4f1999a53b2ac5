// [scene]: what `raysweep scene` builds from OSM buildings.
#pragma once

#include <nlohmann/json.hpp>

#include "meshkit/city.hpp"

namespace raysweep::pipeline {

struct SceneSettings {
  meshkit::CityOptions city;
  bool draco = false;
  // Draco quantises over each mesh's whole extent: 20 bits keep a 5 km city
  // mesh within 2.4 mm (16 bits would allow 3.8 cm, near a 5.9 GHz wavelength).
  int draco_position_bits = 20;
  // The effective configuration (defaults filled in) for provenance records.
  nlohmann::json to_json() const;
};

}  // namespace raysweep::pipeline
