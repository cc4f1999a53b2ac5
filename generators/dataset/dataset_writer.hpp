// Streaming writer of the versioned HDF5 channel dataset (layout: schemas/README.md,
// machine-readable: schemas/raysweep_dataset.schema.json, which is embedded in
// this library and supplies every dataset's units, description and chunk shape).
//
//   DatasetWriter w(path, header);      // creates/truncates the file, writes the header attributes
//   for (...) w.append(frame);          // one call per frame, in time order
//   w.finish(nodes, objects);           // node and object tables, counts, complete = 1
//
// append() buffers rows in memory and writes whole chunks (about 1 MiB per dataset at
// a time); finish() writes the rest. A writer destroyed without finish() flushes what it
// has and closes the file without the `complete` attribute, so validate_dataset()
// reports it as incomplete. Two writers given the same header and records produce
// byte-identical files (object time stamps are disabled).
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <map>
#include <string>
#include <vector>

#include "generators/dataset/dataset.hpp"

namespace raysweep::generators {

inline constexpr const char* kDatasetSchemaVersion = "1.5.0";
inline constexpr const char* kDatasetFormat = "raysweep-channels";

struct DatasetHeader {
  std::string raysweep_version, git_hash;
  nlohmann::json config, inputs, provenance;  // stored as JSON text attributes
  std::uint64_t seed = 0;
  double carrier_hz = 0, bandwidth_hz = 0;
  std::uint32_t cfr_subcarriers = 0;  // 0: no /cfr group; else FrameRecord::cfr has links x K values
  double cfr_subcarrier_spacing_hz = 0;
  // What the file stores (dataset.hpp's StoreLevel; root attributes `store`,
  // `paths_top_k`): append() reduces each frame to it (store_level.hpp).
  StoreLevel store = StoreLevel::full;
  std::uint32_t paths_top_k = 0;
  // Shard files only (JSON text of the root attribute `shard`, see schemas/README.md);
  // empty for whole datasets.
  std::string shard;
  // The rows each first-axis dimension ("S", "L", "P", "I") will end with, when
  // known before the first frame (one-frame files): chunks sized to them
  // (ColumnFile::expect_rows); the values read back are the same.
  std::map<std::string, std::uint64_t> expected_rows;
};

class DatasetWriter {
 public:
  // Creates (truncates) the file and writes the header. Throws std::runtime_error
  // naming the file when it cannot be created.
  DatasetWriter(const std::filesystem::path& path, const DatasetHeader& header);
  ~DatasetWriter();
  DatasetWriter(const DatasetWriter&) = delete;
  DatasetWriter& operator=(const DatasetWriter&) = delete;

  // Appends one frame, reduced to the header's store level. Throws
  // std::invalid_argument (nothing written) when the record is inconsistent:
  // node states not strictly sorted by node, links not strictly sorted by
  // (tx, rx) or with tx >= rx or naming a node absent from the frame, sum of
  // path_count != paths.size() (paths may be empty below the paths level),
  // sum of interaction_count != interactions.size(), cfr.size() !=
  // links.size() x subcarriers (or empty below the cfr level), an
  // out-of-range link with paths, frame time before the previous frame's.
  // std::runtime_error on HDF5 failures or after finish().
  void append(const FrameRecord& frame);

  // Writes the node and object tables, the count attributes and complete = 1, and
  // closes the file. Throws std::invalid_argument when a node state or link names a
  // node >= nodes.size() or an interaction names an object >= objects.size().
  void finish(const std::vector<NodeInfo>& nodes, const std::vector<std::string>& objects);

  std::uint64_t frames() const;
  std::uint64_t links() const;
  std::uint64_t paths() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace raysweep::generators
