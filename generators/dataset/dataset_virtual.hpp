// A channel dataset assembled without copying its bulk: the row tables
// (/node_states, /links, /paths, /interactions, /cfr) are HDF5 1.10 virtual
// datasets mapping, piece after piece, row ranges of other channel datasets
// (the shards of a sweep). What a mapping cannot express is stored: /frames
// and the three columns holding global row numbers (/links/frame,
// /links/path_offset, /paths/interaction_offset) are recomputed for the
// concatenation, as are the node and object tables and the root attributes.
// Read through HDF5, the file holds the same values as the file a
// DatasetWriter would write from the same frames; it needs its sources
// where the mappings say (names relative to the virtual file's folder).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "generators/dataset/dataset.hpp"
#include "generators/dataset/dataset_writer.hpp"

namespace raysweep::generators {

struct VirtualPiece {
  std::filesystem::path file;  // the source, read for its row counts and offsets
  std::string mapped_name;     // the source's name as the mappings store it
  std::uint64_t first_frame = 0, frame_count = 0;  // frames of the source, in order
};

// Writes `out` (created or truncated). Throws meshkit::InputError naming a
// source that cannot be read, std::runtime_error on HDF5 write failures.
void write_virtual_dataset(const std::filesystem::path& out, const DatasetHeader& header,
                           const std::vector<NodeInfo>& nodes, const std::vector<std::string>& objects,
                           const std::vector<VirtualPiece>& pieces);

}  // namespace raysweep::generators
