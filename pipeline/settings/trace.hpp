// [radio], [tracer] and [materials.<name>]: the link and the path solver
// every tracing stage shares.
#pragma once

#include <nlohmann/json.hpp>

#include "tracer/config.hpp"

namespace raysweep::pipeline {

struct TraceSettings {
  tracer::RadioConfig radio;
  tracer::TracerConfig tracer;
  nlohmann::json to_json() const;  // effective settings, defaults filled in
};

}  // namespace raysweep::pipeline
