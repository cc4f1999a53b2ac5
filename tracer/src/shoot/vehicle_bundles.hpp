// Vehicle bundles (TracerConfig::vehicle_bundles, docs/tracer.md): rays
// aimed at the vehicles the lattice covers sparsely.
#pragma once

#include "search/face_index.hpp"
#include "shoot/shoot.hpp"

namespace raysweep::tracer {

// Rays aimed at the vehicles the lattice covers sparsely (two vehicles in a
// chain, a car's cabin and then another car, a wall, a car and a car): their
// face sequences join the lattice's candidates (reception spheres:
// Shooter::reception_spacing). Then,
// through every vehicle face those rays reflect on towards another vehicle,
// a bundle at that vehicle. No diffuse gathering: the diffuse estimator
// weights its rays by the lattice's solid angle.
void shoot_vehicle_bundles(const SnapshotPlan& plan, const ImageFaces& faces, ShootPass& pass);

}  // namespace raysweep::tracer
