// Stage `raysweep render`: a picture of the scene (one colour per radio
// material), vehicles at their poses, the strongest paths of a trace as thin
// tubes coloured by interaction, antennas as spheres and a radio map as a
// coloured slice, rendered by Debian's `blender` (headless, Cycles on CPU)
// driven by python/render_blender.py. Blender is needed by this stage only.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace raysweep::pipeline {

struct RenderArgs {
  std::string scene;     // `raysweep scene` folder (scene.glb)
  std::string vehicles;  // vehicle library; empty: built-in parametric models
  std::string poses;     // vehicles to draw (CSV)
  std::string paths;     // `raysweep trace` JSON: antennas and the strongest paths of a few pairs
  std::string radiomap;  // `raysweep radiomap` .vdb: drawn as a slice at antenna height
  std::string out;       // .png
  std::string camera = "oblique";  // top | oblique | X,Y,Z:TX,TY,TZ
  std::string size = "1280,720";
  int samples = 16;
  int max_pairs = 4;     // pairs of the trace drawn (strongest first)
};

// The blender binary: $RAYSWEEP_BLENDER, else `blender` on PATH; empty when none.
std::string find_blender();

nlohmann::json run_render_stage(const RenderArgs& args, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
