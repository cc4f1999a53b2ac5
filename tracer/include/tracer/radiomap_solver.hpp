// One transmitter to many receiver points (a radio map's voxel centres),
// beside the path solver (tracer/solver.hpp), with the transmitter's work
// done once: its image sources (order 1 and 2, exact: tracer/src/search/)
// are built once per batch of points and tested against the whole batch,
// and the edges it can see the outside of are listed once.
//
// Per point, the paths are those `raysweep trace` computes for the pair
// (transmitter, bare node at the point) through the same exact routines
// (compute_path, compute_diffraction_path, classify_los), except:
//   - specular/refracted paths of order <= min(max_depth, 2) only: the exact
//     image search is complete there; orders >= 3 come from shoot and bounce
//     in `trace` and are left out here;
//   - no diffuse scattering here: with tracer.diffuse on (integration
//     "rays"), rough surfaces keep sqrt(1 - S^2) of the specular field as in
//     `trace`, and the caller adds diffuse_power (the same gathering
//     from the transmitter's rays); otherwise they reflect their whole
//     |Gamma|^2 (energy kept, no lobe);
//   - diffraction with a reflection: before the edge only (the
//     transmitter's list of reflected edges, once); after it (near the
//     point, which `trace` lists from the pair's other end) each point would
//     need its own list, 7x the map's time (docs/radiomap.md);
//   - the direct path through vehicles (NLOSV) is the free-space path times
//     the vehicles' knife-edge loss (trace also tries it through windows).
// The error against `trace` is measured by test_radiomap and reported in
// docs/radiomap.md.
#pragma once

#include <cstdint>
#include <vector>

#include "tracer/config.hpp"
#include "tracer/path.hpp"
#include "tracer/solver.hpp"
#include "tracer/trace_scene.hpp"

namespace raysweep::tracer {

struct RadioMapPointResult {
  double gain = 0;               // incoherent path gain sum |a|^2 (linear), 0 when no path
  LosClass los = LosClass::LOS;  // geometric class of the direct segment
  std::uint32_t paths = 0;
};

struct RadioMapSolveStats {
  std::uint64_t points = 0, paths = 0, candidates = 0, out_of_range = 0;
  std::uint64_t rays = 0;
};

// Every point's incoherent path gain from `tx` (a bare node, or a vehicle
// antenna of the scene's current frame). Deterministic for any number of
// threads (each point's sum runs in path order).
std::vector<RadioMapPointResult> solve_points(const TraceScene& scene, const Node& tx, const std::vector<Vec3>& points,
                                              const TracerConfig& config, const RadioConfig& radio,
                                              RadioMapSolveStats* stats = nullptr);

// True when `p` lies inside a closed static object (a building): the first
// face straight above it is seen from its back. Points under nothing are outside.
bool inside_static(const TraceScene& scene, const Vec3& p);

}  // namespace raysweep::tracer
