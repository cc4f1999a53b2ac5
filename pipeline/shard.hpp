// Sharding a sweep: shard I of N traces only its blocks of frames and writes a
// shard file; `raysweep merge` puts the shards back together into the dataset
// one process would have written (docs/scaleout.md).
//
// Blocks are assigned interleaved, block b to shard b mod N: a shard needs no
// total frame count up front (the FCD is read streaming) and busy and quiet
// stretches of the traffic spread over every shard. Every shard still reads
// the whole FCD, cheaply, because the node table (vehicles in order of first
// appearance) and [sweep] max_vehicles depend on every frame before a block.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace raysweep::pipeline {

struct ShardSpec {
  std::uint32_t index = 0, count = 1;
  bool owns(std::uint64_t block) const { return block % count == index; }
  std::string name() const;  // "I-of-N"
};

// "I/N" with 0 <= I < N; std::invalid_argument naming the option otherwise.
ShardSpec parse_shard(const std::string& text, const std::string& option = "--shard");

// The `shard` attribute of a shard file (schemas/README.md).
struct ShardRecord {
  ShardSpec spec;
  std::uint64_t block_frames = 0, blocks_total = 0, frames_total = 0;
  std::vector<std::uint64_t> blocks;  // in order
  std::string run_key;  // SHA-256 of config, inputs and program version
  std::string out;      // --out as the shard's command recorded it
  nlohmann::json to_json() const;
  // Throws std::invalid_argument naming `file` when a field is missing or inconsistent.
  static ShardRecord from_json(const nlohmann::json& j, const std::string& file);
  std::uint64_t frames_of(std::uint64_t block) const;  // frames in block b of the whole sweep
};

// `<out>/shards/dataset.I-of-N.h5` of `raysweep run`.
std::string shard_file_name(const ShardSpec& s);

}  // namespace raysweep::pipeline
