// Stage `raysweep scene`: OSM (+ SUMO network or projection) or a Mitsuba
// scene in; scene.glb, mitsuba/scene.xml (+ PLY) and manifest.json out.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "meshkit/projection.hpp"
#include "pipeline/settings/settings.hpp"

namespace raysweep::pipeline {

struct SceneArgs {
  std::string osm;
  std::string net;
  std::string proj;                        // explicit projection instead of --net
  std::optional<meshkit::Vec2> net_offset; // with --proj
  std::string from_mitsuba;
  std::string out;
  std::optional<bool> draco;  // overrides [scene] draco
  bool preview = true;        // write preview.png (python/scene_preview.py)
};

// Runs the stage; returns the manifest it wrote. Throws meshkit::InputError,
// ConfigError or std::exception with a message naming file and element.
nlohmann::json run_scene_stage(const SceneArgs& args, const Settings& settings, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
