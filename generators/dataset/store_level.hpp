// Dataset store levels (dataset.hpp's StoreLevel): their names, and the
// reduction of a frame's records to what a level stores.
#pragma once

#include <cstdint>
#include <string>

#include "generators/dataset/dataset.hpp"

namespace raysweep::generators {

namespace hdf5 {
class CheckedFile;
}

const char* store_level_name(StoreLevel level);  // "links" | "cfr" | "paths" | "full"
// std::invalid_argument naming the accepted names otherwise.
StoreLevel parse_store_level(const std::string& name);

// Drops from `frame` what `level` does not store: the CFR below cfr; the
// paths and interactions below paths (each link's path_count then counts the
// paths its gains sum); the interaction points below full (set to NaN). With
// `paths_top_k` > 0 (paths and full), a link keeps only its k strongest
// paths (the first of equal powers; still in delay order), path_count
// counts those and paths_beyond_top_k the rest. Link columns and CFR are
// never changed otherwise. Idempotent: a reduced frame reduces to itself.
void reduce_frame(FrameRecord& frame, StoreLevel level, std::uint32_t paths_top_k);

// The store level of an open channel dataset (root attribute `store`; files
// written before schema 1.4.0 have none and are full).
StoreLevel file_store_level(const hdf5::CheckedFile& file);

// For a stage that reads `needed` of a channel dataset: throws
// meshkit::InputError naming the file, its level and the level to sweep with
// when the file holds less.
void require_store_level(const hdf5::CheckedFile& file, StoreLevel needed, const std::string& stage);

}  // namespace raysweep::generators
