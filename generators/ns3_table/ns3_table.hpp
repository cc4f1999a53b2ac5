// The ns-3 lookup table (format raysweep-ns3-table): per (frame, unordered node
// pair) the wideband power gain, the LoS class and, when the channel dataset
// stores frequency responses, per-band gains; per frame the node positions and
// velocities. What ns-3's Raysweep models (ns3/) read. Layout: schemas/README.md;
// machine-readable: schemas/raysweep_ns3_table.schema.json (embedded at build
// time). validate_dataset() and dataset_info() accept it.
//
//   Ns3TableWriter w(path, header, bands);
//   for (...) w.add_frame(time, states, pairs, band_gains);  // frames in time order
//   w.finish(nodes);                                          // node table, counts, complete = 1
//   Ns3Table t = Ns3Table::load(path);                        // everything in memory, for lookups
#pragma once

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "generators/dataset/dataset.hpp"

namespace raysweep::generators {

inline constexpr const char* kNs3TableFormat = "raysweep-ns3-table";
inline constexpr const char* kNs3TableSchemaVersion = "1.0.0";
// The embedded schemas/raysweep_ns3_table.schema.json text, and parsed.
const std::string& ns3_table_schema_json();
const nlohmann::json& ns3_table_schema();

// Codes of the root attribute gain_source.
enum class GainSource : std::uint8_t { cfr = 0, incoherent = 1 };
const char* gain_source_name(GainSource s);

struct Ns3TableHeader {
  std::string raysweep_version, git_hash;
  nlohmann::json config, inputs, provenance;  // JSON text attributes
  std::uint64_t seed = 0;
  double carrier_hz = 0, bandwidth_hz = 0;
  GainSource gain_source = GainSource::incoherent;
};

// The per-band gains' frequency grid; empty center_hz: the table has none.
struct Ns3TableBands {
  std::uint32_t subcarriers_per_band = 0;
  double band_width_hz = 0;
  std::vector<double> center_hz;  // increasing
  std::size_t count() const { return center_hz.size(); }
};

struct Ns3Pair {
  std::uint32_t a = 0, b = 0;  // a < b
  float gain_db = 0;           // -inf: no path
  std::uint8_t los_class = 0;  // 0 LOS, 1 NLOSV, 2 NLOS
};

class Ns3TableWriter {
 public:
  // Creates (truncates) the file and writes the header. Throws std::runtime_error
  // naming the file when it cannot be created, std::invalid_argument for a bad header.
  Ns3TableWriter(const std::filesystem::path& path, const Ns3TableHeader& header, const Ns3TableBands& bands);
  ~Ns3TableWriter();  // without finish(): flushes, closes, no `complete`
  Ns3TableWriter(const Ns3TableWriter&) = delete;
  Ns3TableWriter& operator=(const Ns3TableWriter&) = delete;

  // Appends a frame. `states` sorted by node, `pairs` strictly sorted by (a, b)
  // with a < b between nodes of `states`; `band_gain_db` holds pairs.size() x
  // bands.count() values (row per pair). Throws std::invalid_argument naming the
  // file, frame and element when the records break these rules or the time is not
  // after the previous frame's.
  void add_frame(double time_s, const std::vector<NodeState>& states, const std::vector<Ns3Pair>& pairs,
                 const std::vector<float>& band_gain_db);

  // Writes the node table, the counts and complete = 1, and closes the file.
  // Throws std::invalid_argument when a record names a node >= nodes.size().
  void finish(const std::vector<NodeInfo>& nodes);

  std::uint64_t frames() const;
  std::uint64_t pairs() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// A whole table in memory: about 9 bytes per pair-frame (+ 4 per band), 40 per
// node state. Lookups are a binary search over the frame times, then over the
// frame's pairs.
class Ns3Table {
 public:
  // Reads the file. Throws meshkit::InputError naming the file and the dataset or
  // attribute when it is not a complete raysweep-ns3-table of a supported major
  // version, is unreadable, or is inconsistent (offsets, order, references).
  static Ns3Table load(const std::string& path);

  const std::string& path() const { return path_; }
  const std::vector<std::string>& node_ids() const { return ids_; }
  const std::vector<NodeKind>& node_kinds() const { return kinds_; }
  std::size_t node_count() const { return ids_.size(); }
  double carrier_hz() const { return carrier_hz_; }
  double bandwidth_hz() const { return bandwidth_hz_; }
  GainSource gain_source() const { return gain_source_; }
  const Ns3TableBands& bands() const { return bands_; }
  const nlohmann::json& provenance() const { return provenance_; }

  std::size_t frames() const { return time_.size(); }
  double time(std::size_t frame) const { return time_[frame]; }
  double frame_step() const { return step_; }
  // The frame in force at t (the last frame with time <= t); nullopt when t is
  // before the first frame or later than the last frame's time + frame_step().
  std::optional<std::size_t> frame_at(double t) const;

  // A node's state in a frame; nullptr when the node is absent from it.
  const NodeState* state(std::size_t frame, std::uint32_t node) const;
  // The pair's row in a frame (either order); nullopt when the frame has no channel for it.
  std::optional<std::size_t> pair_row(std::size_t frame, std::uint32_t a, std::uint32_t b) const;
  float gain_db(std::size_t row) const { return gain_[row]; }
  std::uint8_t los_class(std::size_t row) const { return los_[row]; }
  // bands().count() gains of a row; nullptr when the table has no bands.
  const float* band_gain_db(std::size_t row) const {
    return bands_.count() ? band_gain_.data() + row * bands_.count() : nullptr;
  }
  std::uint64_t pair_count() const { return gain_.size(); }
  std::uint64_t state_count() const { return states_.size(); }

  std::size_t memory_bytes() const;  // heap held by the loaded table

 private:
  std::string path_;
  std::vector<std::string> ids_;
  std::vector<NodeKind> kinds_;
  double carrier_hz_ = 0, bandwidth_hz_ = 0, step_ = 0.1;
  GainSource gain_source_ = GainSource::incoherent;
  Ns3TableBands bands_;
  nlohmann::json provenance_;
  std::vector<double> time_;
  std::vector<std::uint64_t> state_offset_, pair_offset_;  // frames + 1 entries
  std::vector<NodeState> states_;
  std::vector<std::uint32_t> key_;  // a * N + b, sorted within a frame
  std::vector<float> gain_;
  std::vector<std::uint8_t> los_;
  std::vector<float> band_gain_;
};

}  // namespace raysweep::generators

namespace raysweep::generators {

// What build_ns3_table() did.
struct Ns3TableBuildStats {
  std::uint64_t frames = 0, pairs = 0, nodes = 0, bands = 0;
  GainSource gain_source = GainSource::incoherent;
};

// Writes the ns-3 table of a channel dataset to `out`: every link of every frame
// becomes a pair row (wideband gain from the CFR when the dataset stores one,
// else its incoherent gain; header.gain_source is set accordingly), every node
// state a state row. With a CFR and subcarriers_per_band > 0, the per-band gains
// average |H|^2 over groups of that many subcarriers (the subcarrier count must be
// a multiple of it). Throws meshkit::InputError naming the dataset and element
// when it cannot be read, std::invalid_argument for a bad subcarriers_per_band.
Ns3TableBuildStats build_ns3_table(const std::string& dataset, const std::filesystem::path& out, Ns3TableHeader header,
                                   std::uint32_t subcarriers_per_band);

}  // namespace raysweep::generators

namespace raysweep::generators::schema {
struct FileFormat;
extern const FileFormat kNs3TableFile;  // for validate_dataset() (schema_ns3_table.cpp)
}  // namespace raysweep::generators::schema
