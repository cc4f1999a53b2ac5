// The diffracting edges of a shape (TraceScene::edges(), the vehicle
// models' wedges) and the parts of the static edges that other solids do
// not bury.
#pragma once

#include <string>
#include <vector>

#include "scene/shape.hpp"

namespace raysweep::tracer {

// Diffracting edges of a shape: triangle edges (matched by position, so
// meshes with duplicated vertices still connect) between two planar faces
// that turn convexly by at least 10 degrees, and free borders of faces.
// `floor_on_ground`: a downward face is a floor only at z = 0 (a vehicle
// model's underside is a face of its body above the ground, whose edges
// diffract; a building's floor lies on the ground).
std::vector<Edge> extract_edges(const TraceScene::Shape& s, const std::vector<std::string>& object_names,
                                bool floor_on_ground = false);

// The parts of `edges` that no other solid buries (buildings that touch
// keep each other's corners inside the block): each edge is probed every
// 0.5 m (at least twice) and cut where the state changes, the cut found by
// bisection to 1 mm. Order kept (deterministic).
std::vector<Edge> exposed_parts(const TraceScene& scene, const std::vector<Edge>& edges);

}  // namespace raysweep::tracer
