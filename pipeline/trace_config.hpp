// [radio], [tracer] and [materials.<name>] tables of a TOML config.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "tracer/config.hpp"

namespace raysweep::pipeline {

struct TraceSettings {
  tracer::RadioConfig radio;
  tracer::TracerConfig tracer;
  nlohmann::json to_json() const;  // effective settings, defaults filled in
};

// Unknown keys, wrong types and out-of-range values are ConfigErrors naming
// file, key and line. An empty path gives the defaults.
TraceSettings load_trace_config(const std::string& path);

}  // namespace raysweep::pipeline
