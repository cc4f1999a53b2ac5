// The SINR outcome file (format raysweep-sinr): the transmissions on the shared
// channel, one row per reception attempt with the SINR that decided it, the
// transmissions that overlapped each reception, and PRR per link and per RAT.
// Layout: schemas/README.md; machine-readable: schemas/raysweep_sinr.schema.json
// (embedded at build time, like the channel schema). validate_dataset() and
// dataset_info() (generators/formats.hpp) accept both formats.
//
//   SinrWriter w(path, header);
//   for (...) w.add_transmission(t);       // all transmissions, in schedule order
//   for (...) w.add_reception(r, overlaps); // sorted by (transmission, rx)
//   w.finish(nodes, prr_links, prr_rats);   // node and PRR tables, counts, complete = 1
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "generators/dataset/dataset.hpp"
#include "generators/sinr/types.hpp"

namespace raysweep::generators::sinr {

inline constexpr const char* kSinrFormat = "raysweep-sinr";
inline constexpr const char* kSinrSchemaVersion = "1.0.0";

struct SinrHeader {
  std::string raysweep_version, git_hash;
  nlohmann::json config, inputs, provenance;  // JSON text attributes
  std::uint64_t seed = 0;
  std::string channel_model;   // channel_model_name()
  bool los_from_ray = false;
  double carrier_hz = 0;
  double sinr_threshold_db = 0, sensitivity_dbm = 0, gain_threshold_db = 0;
  double time_start_s = 0, time_end_s = 0;  // simulated interval
};

struct SinrNode {
  std::string id;
  NodeKind kind = NodeKind::vehicle;
  Rat rat = Rat::none;
};

class SinrWriter {
 public:
  // Creates (truncates) the file and writes the header. Throws std::runtime_error
  // naming the file when it cannot be created.
  SinrWriter(const std::filesystem::path& path, const SinrHeader& header);
  ~SinrWriter();  // without finish(): flushes, closes, no `complete`
  SinrWriter(const SinrWriter&) = delete;
  SinrWriter& operator=(const SinrWriter&) = delete;

  // Appends a transmission (its row is the number added before it). Throws
  // std::invalid_argument when it is inconsistent: start before the previous one's,
  // non-finite or non-positive duration, f_hi <= f_lo, rat none, after a reception.
  void add_transmission(const Transmission& t);

  // Appends a reception attempt and the transmissions that overlapped it. Throws
  // std::invalid_argument when (transmission, rx) is not after the previous
  // reception's, the transmission row is unknown, rx is the sender, an overlap
  // names the reception's own transmission or an unknown row, or `interferers`
  // differs from the number of counted overlaps.
  void add_reception(const Reception& r, const std::vector<Interferer>& overlaps);

  // Writes the node table and the PRR tables, the counts, complete = 1, and closes
  // the file. Throws std::invalid_argument when a record names a node >= nodes.size().
  void finish(const std::vector<SinrNode>& nodes, const std::vector<PrrEntry>& prr_links,
              const std::vector<PrrEntry>& prr_rats);

  std::uint64_t transmissions() const;
  std::uint64_t receptions() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// What `raysweep sinr --schedule-from` reuses of an earlier SINR file: its
// transmissions (in file order), node table and config. Throws meshkit::InputError
// naming the file and dataset when it is not a complete raysweep-sinr file.
struct SinrSchedule {
  std::vector<Transmission> transmissions;
  std::vector<SinrNode> nodes;
  nlohmann::json config;
};
SinrSchedule read_sinr_schedule(const std::string& path);

}  // namespace raysweep::generators::sinr

namespace raysweep::generators {

// The embedded schemas/raysweep_sinr.schema.json text, and parsed.
const std::string& sinr_schema_json();
const nlohmann::json& sinr_schema();

}  // namespace raysweep::generators

namespace raysweep::generators::schema {
struct FileFormat;
extern const FileFormat kSinrFile;  // for validate_dataset() (schema_sinr.cpp)
}  // namespace raysweep::generators::schema
