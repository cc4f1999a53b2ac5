// What `raysweep tradeoff` reads and where it writes: the outputs of an
// earlier `raysweep run CITY.toml`, or explicit inputs as for `raysweep
// sweep`. Everything is checked before anything is traced or written.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "pipeline/settings/settings.hpp"
#include "pipeline/tradeoff/stage.hpp"

namespace raysweep::pipeline {

struct TradeoffInputs {
  std::string scene_dir, vehicles_dir, fcd, config, rsus_file, out, title;
  std::vector<std::string> vtype_files;
  std::filesystem::path scene_file;
  bool library_mode() const { return !vehicles_dir.empty(); }
};

// `settings`: the city file's when args.city is given (its outputs are
// found through it), else --config's. std::invalid_argument naming what is
// missing or given twice.
TradeoffInputs resolve_inputs(const TradeoffArgs& args, const Settings& settings);

}  // namespace raysweep::pipeline
