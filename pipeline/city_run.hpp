// `raysweep run CITY.toml`: scene -> vehicles -> traffic -> sweep for one
// city, each stage skipped when its inputs and settings did not change since
// its last successful run (a stamp per stage under <out>/.stamps/).
//
// The city file's [city] table names the inputs (paths relative to the
// file); [scene], [vehicles], [traffic], [sweep], [radio], [tracer] and
// [materials.*] configure the stages (see datasets/demo/city.toml).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/settings.hpp"
#include "pipeline/shard.hpp"

namespace raysweep::pipeline {

struct CityRunArgs {
  std::string city;  // CITY.toml
  std::vector<std::string> set;  // `--set TABLE.KEY=VALUE` over it (settings/overrides.hpp)
  std::string out;   // default: [city] out, else out/<name>
  bool resume = false;
  bool force = false;  // run every stage even when up to date
  // Scale-out (docs/scaleout.md). `until`: stop after this stage (scene,
  // vehicles, traffic or sweep); `--until traffic` once builds what every shard
  // shares. `shard`: trace this shard's blocks into <out>/shards/ and stop;
  // the earlier stages must be up to date (they are not rebuilt per shard).
  // `merge`: merge <out>/shards/ (the `merge_count` shards, 0: the one count
  // found there) into <out>/dataset.h5, then run the later stages.
  std::string until;
  std::optional<ShardSpec> shard;
  bool merge = false;
  std::uint32_t merge_count = 0;
  bool virtual_dataset = false;  // merge into an HDF5 virtual dataset over the shards
};

// Where `raysweep run CITY.toml [--out OUT]` put the inputs of its sweep: the
// scene and vehicle library folders, the FCD trace (from its traffic stage,
// or [traffic] fcd as given) with its vType files, and the city's RSUs.
struct CityOutputs {
  std::string out, scene, vehicles, fcd, rsus;
  std::vector<std::string> vtypes;
};
// `city` comes from load_city_settings. Throws std::invalid_argument naming
// what is missing and saying to run `raysweep run CITY.toml` first.
CityOutputs city_outputs(const Settings& city, const std::string& out = "");

nlohmann::json run_city(const CityRunArgs& args, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
