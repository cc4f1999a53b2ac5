// Tables that depend only on a vehicle model (its multi-bounce sequences,
// the faces its antenna mount sees), kept between processes. The tracer
// names each table by a content key (a hash of the geometry, the materials
// and the settings that shape it, the format and Embree's version) and frames
// it with its length and a checksum; the caller supplies where the bytes live
// (pipeline/precompute_store.hpp: files beside the scene). A table that does
// not load, does not check or does not decode is rebuilt and stored again,
// never trusted, so a stale or damaged cache costs time, not accuracy.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace raysweep::tracer {

class PrecomputeStore {
 public:
  virtual ~PrecomputeStore() = default;
  // The bytes stored under `key` ([0-9a-z-]+), or nullopt when there are none.
  virtual std::optional<std::string> load(const std::string& key) const = 0;
  // Best effort: a store that cannot write keeps working without.
  virtual void save(const std::string& key, const std::string& bytes) const = 0;
  // `key` was present but unusable (why); it is being rebuilt.
  virtual void rejected(const std::string& key, const std::string& why) const = 0;
};

// A 128-bit content hash (two FNV-1a streams), as 32 hex digits.
class ContentKey {
 public:
  ContentKey& add(const void* data, std::size_t bytes);
  ContentKey& add(std::string_view s) { return add(s.data(), s.size()).add_u64(s.size()); }
  ContentKey& add_u64(std::uint64_t v) { return add(&v, sizeof v); }
  template <class T>
  ContentKey& add_vector(const std::vector<T>& v) {
    return add(v.data(), v.size() * sizeof(T)).add_u64(v.size());
  }
  std::string hex() const;

 private:
  std::uint64_t a_ = 0xcbf29ce484222325ull, b_ = 0x84222325cbf29ce4ull;
};

// Little-endian u32 records, framed: "RSPC", format version, payload length,
// payload checksum. unframe gives the payload back, or nullopt with why.
std::string frame_table(const std::vector<std::uint32_t>& words);
std::optional<std::vector<std::uint32_t>> unframe_table(const std::string& bytes, std::string& why);

}  // namespace raysweep::tracer
