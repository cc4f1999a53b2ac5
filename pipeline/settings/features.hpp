// [features]: the context features `raysweep features` (and `raysweep ml`)
// compute per link from the scene and the traffic (generators/sweep/context_features.hpp).
#pragma once

#include <nlohmann/json.hpp>

#include "generators/sweep/context_features.hpp"

namespace raysweep::pipeline {

struct FeaturesSettings {
  generators::FeatureGridSpec grid;
  nlohmann::json to_json() const;
};

}  // namespace raysweep::pipeline
