// A traced snapshot as another ray tracer reads it (`raysweep trace
// --mitsuba DIR`): the static scene and every vehicle where it stands, in
// world coordinates, with each material's parameters at the carrier
// (Sionna RT 2's radio-material plugin), plus peer.json with the antennas
// and the settings. A peer comparison (bench/peers/sionna) then runs on
// exactly the geometry, materials and antennas raysweep traces.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "meshkit/mitsuba_io.hpp"
#include "meshkit/scene.hpp"
#include "pipeline/settings/trace.hpp"
#include "tracer/solver.hpp"
#include "tracer/trace_scene.hpp"

namespace raysweep::pipeline {

// Half spaces (the grounds) have no thickness in raysweep; a peer that
// models every surface as a slab gets this one, where a lossy ground's
// inner wave has died out (medium dry ground at 5.9 GHz: over 100 dB per
// metre), so its reflection is the half space's.
constexpr double kHalfSpaceExportThicknessM = 1.0;

// The scene's faces as meshes: "static-<material>" and "veh<k>-<material>",
// vertices welded where faces share them (a peer finds wedges from shared
// edges), objects "static" and "vehicle/<id>".
meshkit::Scene snapshot_meshes(const tracer::TraceScene& scene);

// Each material the scene uses at the carrier, as the tracer evaluates it
// (its scattering coefficients 0 when diffuse scattering is off: what
// raysweep traces then is a smooth surface).
std::map<std::string, meshkit::MitsubaRadioMaterial> peer_materials(const tracer::TraceScene& scene,
                                                                    const TraceSettings& settings);

// Writes dir/scene.xml, dir/meshes/*.ply and dir/peer.json through a
// temporary sibling directory (nothing half-written).
void write_peer_scene(const tracer::TraceScene& scene, const std::vector<tracer::Node>& nodes,
                      const TraceSettings& settings, const nlohmann::json& provenance, const std::string& dir);

}  // namespace raysweep::pipeline
