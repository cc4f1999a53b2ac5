// tracer: public entry point. A TraceScene holds the static city and the
// vehicle models (Embree scenes, vehicles as instances); trace_snapshot
// computes every pair's paths for the vehicles' current poses.
#pragma once

#include <string>

#include "tracer/channel.hpp"
#include "tracer/config.hpp"
#include "tracer/em/antenna.hpp"
#include "tracer/em/coefficients.hpp"
#include "tracer/em/materials.hpp"
#include "tracer/path.hpp"
#include "tracer/solver.hpp"
#include "tracer/trace_scene.hpp"

namespace raysweep::tracer {
// Embree's version string (for provenance records).
std::string embree_version();
}  // namespace raysweep::tracer
