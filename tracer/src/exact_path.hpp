// The exact path through a face sequence (compute_path's engine), shared by
// the direct and specular mechanisms.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "tracer/solver.hpp"

namespace raysweep::tracer {

// compute_path; `through_vehicles`: vehicle faces on the way are ignored
// (the direct path that the knife-edge model attenuates instead).
// `blocked` (optional): 1 when the path exists geometrically but an opaque
// static face is the first thing found blocking a leg, 2 when a vehicle's
// is (a path that traffic can unblock: PairResult::near_misses, which a
// coherent sweep carries), 0 otherwise.
std::optional<Path> exact_path(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& config,
                               const Node& from, const Node& to, const std::vector<FaceRef>& faces, bool* over_cap,
                               std::uint64_t* rays, bool through_vehicles, int* blocked = nullptr);

}  // namespace raysweep::tracer
