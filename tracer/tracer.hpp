// tracer: public entry point. The Embree path solver arrives with the tracer
// core issue; for now the target exists so the dependency chain
// pipeline -> generators -> tracer -> meshkit is in place and enforced.
#pragma once
#include <string>
namespace raysweep::tracer {
// Embree's version string, proving the library links and initialises.
std::string embree_version();
}  // namespace raysweep::tracer
