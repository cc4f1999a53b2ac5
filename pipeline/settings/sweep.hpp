// [sweep]: which frames and vehicles `raysweep sweep` traces, and how.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generators/dataset/dataset.hpp"
#include "generators/sweep/sweep.hpp"
#include "tracer/channel.hpp"

namespace raysweep::pipeline {

struct SweepSettings {
  double begin_s = -1e300, end_s = 1e300, step_s = 0;
  std::vector<std::string> ids, types;
  std::vector<double> area;      // empty or xmin, ymin, xmax, ymax
  std::size_t max_vehicles = 0;  // 0: all; else the first vehicles to appear, refilled as they leave
  std::string outside = "error"; // vehicles outside the scene: "error" or "drop"
  // "80211p" | "nr:MU:NRB", checked when read; the grid needs [radio]'s carrier.
  std::optional<tracer::OfdmGridSpec> cfr;
  int lod = -1;
  std::string exclude_objects;
  generators::SweepOptions options;
  // What the dataset stores (schemas/README.md, "Store levels"): the
  // smallest level every stage downstream reads by default.
  generators::StoreLevel store = generators::StoreLevel::cfr;
  std::uint32_t paths_top_k = 0;  // paths and full: only each link's k strongest paths (0: all)
  nlohmann::json to_json() const;
};

}  // namespace raysweep::pipeline
