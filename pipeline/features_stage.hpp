// `raysweep features`: the context features of a channel dataset's links
// (generators/sweep/context_features.hpp) into a sidecar file, from the scene and
// the dataset's node states only. `raysweep ml`: the learning benchmark
// (python/ml/) over the cities' runs, their features built first.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/settings.hpp"

namespace raysweep::pipeline {

struct FeaturesArgs {
  std::string city;      // CITY.toml: the outputs of `raysweep run` (or --dataset and --scene)
  std::string city_out;  // that run's --out
  std::vector<std::string> set;
  std::string dataset;  // channel dataset (default: <city out>/dataset.h5)
  std::string scene;    // scene folder holding scene.glb (default: <city out>/scene)
  std::string config;   // TOML with [features] (and [sweep] exclude_objects) without a city file
  std::string out;      // default: features.h5 beside the dataset
  bool force = false;   // rebuild even when the file is up to date
};

// Builds the feature file unless one made from the same dataset, scene and
// settings is there (its recorded inputs and config match). Returns a
// summary (out, city name, rows, frames, bytes, seconds, up_to_date).
nlohmann::json run_features_stage(const FeaturesArgs& args, const std::vector<std::string>& argv);

struct MlArgs {
  std::vector<std::string> cities;    // CITY.toml, in order
  std::vector<std::string> city_outs; // their runs' --out, in order (fewer: the rest default)
  std::vector<std::string> set;       // --set over every city file
  std::string out;
  unsigned seed = 1;
  double max_train_s = 600;
  std::uint64_t max_links = 200000;
};

// Checks each city's run, builds its features when missing or stale, then
// runs `python3 -m ml` (python/ml/) into args.out. Returns its exit status.
int run_ml_stage(const MlArgs& args, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
