// Levels of detail for vehicle models: each part simplified on its own with
// its border locked (OpenMesh decimater: quadric error, no normal flips,
// only collapses that keep the surface manifold), so material boundaries and
// closed surfaces survive; the geometric cost is the symmetric Hausdorff distance to
// the full model.
#pragma once

#include <cmath>
#include <cstddef>

#include "meshkit/vehicle_model.hpp"

namespace raysweep::meshkit {

// Simplified copy with about `ratio` of each part's triangles; no collapse
// may move the surface by more than about `max_error_m` (quadric error), so
// parts that cannot shrink within it keep what they have.
VehicleModel simplify_vehicle(const VehicleModel& model, double ratio, double max_error_m = INFINITY);

// Symmetric Hausdorff distance between the two surfaces, estimated from
// about `samples` deterministic points spread over each by area (plus every
// vertex), with exact point-to-surface distances (CGAL AABB tree).
double hausdorff_distance(const VehicleModel& a, const VehicleModel& b, std::size_t samples = 20000);

}  // namespace raysweep::meshkit
