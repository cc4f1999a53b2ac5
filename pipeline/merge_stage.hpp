// `raysweep merge SHARD.h5 ... --out DATASET.h5 [--virtual]`: the shard files
// of one sweep (`--shard I/N`) back into the dataset one process would have
// written.
//
// Checks first, writes after: every shard complete, made by the same program
// from the same inputs and settings (config, input SHA-256s, version: the
// run key and every root attribute, the node and object tables), and the
// shards together covering every block of the sweep exactly once; a
// missing, duplicate or foreign shard is an error naming the files. Then
// - by copy (default): the frames of every block, in order, go through the
//   dataset writer with the shards' header: the file has the same bytes as
//   the single-process run's (provenance included: it records the command of
//   the single-process run, see recorded_command());
// - `--virtual`: an HDF5 virtual dataset over the shard files
//   (generators/dataset/dataset_virtual.hpp) that reads the same values; it needs
//   the shards where they are.
// The merge is recorded next to the output, in DATASET.h5.merge.json
// (shards, their SHA-256 and blocks), not inside it: inside, it would break
// the byte identity with the single-process dataset.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace raysweep::pipeline {

struct MergeArgs {
  std::vector<std::string> shards;
  std::string out;
  bool virtual_dataset = false;
};

// Throws std::invalid_argument (bad or mismatched shards, coverage) or
// meshkit::InputError (unreadable file), writing nothing.
nlohmann::json run_merge_stage(const MergeArgs& args);

}  // namespace raysweep::pipeline
