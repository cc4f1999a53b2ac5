// The vehicle library's built-in models in a trace scene. The library is the
// pipeline's (pipeline/trace_inputs.hpp): tests that include this header link
// the pipeline library, whatever module they test.
#pragma once

#include <cstdint>
#include <string>

#include "meshkit/vehicle_model.hpp"
#include "pipeline/trace_inputs.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::test {

// Registers the built-in parametric model of a class; returns its index.
inline std::uint32_t add_library_model(tracer::TraceScene& scene, const std::string& vclass) {
  pipeline::VehicleLibrary lib;
  const auto& m = lib.model(vclass);
  return scene.add_vehicle_model(vclass, meshkit::to_scene(m), m.antenna);
}

}  // namespace raysweep::test
