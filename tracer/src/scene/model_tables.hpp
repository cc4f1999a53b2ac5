// The tables that depend on a vehicle model alone, built once per model or
// taken from the precompute store (tracer/precompute.hpp): the model's
// content key and the faces its antenna mount sees; the store's round trip
// (cached_table) that the multi-bounce table (bounce_table.cpp) shares.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "scene/shape.hpp"
#include "tracer/precompute.hpp"

namespace raysweep::tracer {

// What a model's tables depend on: its triangles, faces and materials, and
// the Embree that traces them (its float traversal decides grazing hits).
std::string model_content_key(const TraceScene::Shape& s, const std::vector<std::string>& materials,
                              long embree_version);

// Faces the antenna sees on its own vehicle (through its windows too: rays
// continue through every face until they leave the model).
std::vector<std::uint32_t> faces_seen_from(const TraceScene::Shape& s, const Vec3& antenna);

// Face ids, strictly increasing, each below `faces`.
bool decode_increasing(const std::vector<std::uint32_t>& w, std::uint32_t faces, std::vector<std::uint32_t>& out);

// Table `key` from the store when it unframes and decodes (decode fills the
// outputs), else built here (build fills them) and stored (encode).
template <class Decode, class Build, class Encode>
void cached_table(const PrecomputeStore* store, const std::string& key, Decode&& decode, Build&& build,
                              Encode&& encode) {
  if (store) {
    if (auto bytes = store->load(key)) {
      std::string why;
      if (auto words = unframe_table(*bytes, why)) {
        if (decode(*words)) return;
        why = "contents do not fit the model";
      }
      store->rejected(key, why);
    }
  }
  build();
  if (store) store->save(key, frame_table(encode()));
}

}  // namespace raysweep::tracer
