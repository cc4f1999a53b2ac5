// The vehicle library's built-in models (meshkit/vehicle_library.hpp) in a
// trace scene.
#pragma once

#include <cstdint>
#include <string>

#include "meshkit/vehicle_library.hpp"
#include "meshkit/vehicle_model.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::test {

// Registers the built-in parametric model of a class; returns its index.
inline std::uint32_t add_library_model(tracer::TraceScene& scene, const std::string& vclass) {
  meshkit::VehicleLibrary lib;
  const auto& m = lib.model(vclass);
  return scene.add_vehicle_model(vclass, meshkit::to_scene(m), m.antenna);
}

}  // namespace raysweep::test
