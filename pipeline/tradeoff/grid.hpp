// `raysweep tradeoff`'s grid: the settings traced against the reference.
// The reference first, then rays per source x maximum depth, then around
// the config's own setting one change at a time. The variants that depend
// on the scene and the snapshots (vehicle LOD, static simplification) are
// added by scenes.hpp once those are known.
#pragma once

#include <string>
#include <vector>

#include "tracer/config.hpp"

namespace raysweep::pipeline {

struct TradeoffArgs;

// One setting of the grid.
struct TradeoffSetting {
  std::string label;
  tracer::TracerConfig tracer;
  int lod = -1;              // vehicle LOD; -1: each library entry's default
  double simplify_m = 0;     // static geometry decimated within this error (m); 0: as built
  bool reference = false;
};

// The grid's axes and the reference, from the options (or their defaults).
struct GridAxes {
  int snapshots = 0;
  std::vector<int> rays, depths;
  std::vector<double> simplify;
  int ref_rays = 0, ref_depth = 0;
  int coherence_window = 0;  // frames; 0: no coherence toggle
  std::vector<int> lattice_frames;  // the toggle's K axis
};

// std::invalid_argument naming the option for a value out of range.
GridAxes parse_axes(const TradeoffArgs& args);

// The config's own setting on the grid; each variant differs from it in one respect.
struct GridBase {
  tracer::TracerConfig tracer;
  int rays = 0, depth = 0, lod = 0;

  TradeoffSetting variant(const std::string& what) const;
};

// The config's rays and depth when the grid has them, else its largest.
GridBase grid_base(const tracer::TracerConfig& base, const GridAxes& axes, int lod);

// The reference first, then rays x depths, then the variants of the base.
std::vector<TradeoffSetting> build_grid(const GridBase& b, const GridAxes& axes, const tracer::RadioConfig& radio);

// "r1024 d2": the label of a grid point, and the prefix of its variants'.
std::string setting_label(int rays, int depth);

// "1024,4096" -> {1024, 4096}; std::invalid_argument naming `option` for
// anything but integers in [min, max].
std::vector<int> parse_int_list(const std::string& option, const std::string& text, int min, int max);
std::vector<double> parse_number_list(const std::string& option, const std::string& text, double min);

}  // namespace raysweep::pipeline
