// Reading a channel dataset back into the records it was written from
// (dataset.hpp), a range of frames at a time: what merging shard files needs.
// Appending the frames read from a file to a DatasetWriter with the file's
// header and finishing it with its node and object tables writes the same
// bytes again (tests/cli/test_cli_shard.cpp checks it).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "generators/dataset/dataset.hpp"
#include "generators/dataset/dataset_writer.hpp"

namespace raysweep::generators {

// Where a frame's rows start in each row table of its file.
struct FrameRows {
  std::uint64_t states = 0, links = 0, paths = 0, interactions = 0;
};

class DatasetReader {
 public:
  // Opens a channel dataset of this major schema version. Throws
  // meshkit::InputError naming the file (and the dataset or attribute) when it
  // is not one or cannot be read.
  explicit DatasetReader(const std::filesystem::path& path);
  ~DatasetReader();
  DatasetReader(const DatasetReader&) = delete;
  DatasetReader& operator=(const DatasetReader&) = delete;

  const std::string& path() const;
  const DatasetHeader& header() const;  // root attributes, `shard` included ("" when absent)
  const std::string& schema_version() const;
  bool complete() const;  // the writer finished the file
  std::uint64_t frame_count() const;
  const std::vector<NodeInfo>& nodes() const;
  const std::vector<std::string>& objects() const;

  // Frames [first, first + count), checked for consistent offsets and counts.
  std::vector<FrameRecord> frames(std::uint64_t first, std::uint64_t count);

  // First row of frame f in each row table (f == frame_count(): the tables' sizes).
  FrameRows rows_at(std::uint64_t frame);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace raysweep::generators
