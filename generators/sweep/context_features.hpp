// Context features for learning: per link of a channel dataset, what a
// deployed model could know without a ray tracer, namely the static map along
// the link and the other vehicles near it. They come from the scene and from
// the node states the sweep was given (FCD), never from the tracer's output:
// the builder reads only /frames, /nodes, /node_states and /links/tx, rx of the
// dataset. Layout: schemas/raysweep_features.schema.json (format
// raysweep-features), documented in schemas/README.md.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "generators/dataset/dataset.hpp"
#include "meshkit/scene.hpp"

namespace raysweep::tracer {
class TraceScene;
}

namespace raysweep::generators {

inline constexpr const char* kFeaturesFormat = "raysweep-features";
inline constexpr const char* kFeaturesSchemaVersion = "1.0.0";
// The embedded schemas/raysweep_features.schema.json text, and parsed.
const std::string& features_schema_json();
const nlohmann::json& features_schema();

struct FeatureGridSpec {
  std::uint32_t along_cells = 64;
  std::uint32_t across_cells = 16;
  double half_width_m = 20;
  std::uint32_t max_vehicles = 16;
  double height_scale_m = 0.25;   // one step of /corridor/height
  double map_resolution_m = 0.5;  // the static height map's cell edge
  std::uint32_t frame_stride = 1;
  std::uint32_t cells() const { return along_cells * across_cells; }
  void check() const;  // std::invalid_argument naming the key
};

// Codes of the schema's tables (the schema is their single source):
// material_class (0 none, "other" for names outside the table) and
// vehicle_class ("other" likewise; kNoVehicle marks an empty slot).
std::uint8_t material_code(std::string_view material);
std::uint8_t vehicle_class_code(std::string_view vclass);
inline constexpr std::uint8_t kNoVehicle = 255;

// The static city seen from above: per square cell, the highest static
// surface's height above the lowest one under it (the ground) and its
// material code. A cell with one surface only is open ground.
class HeightMap {
 public:
  struct Sample {
    float height_m = 0;
    std::uint8_t material = 0;
  };
  // One vertical ray per cell through the static scene (no vehicles placed).
  static HeightMap build(const tracer::TraceScene& scene, const meshkit::Bounds& bounds, double resolution_m);
  // The cell holding (x, y); open ground outside the map.
  Sample at(double x, double y) const;
  std::size_t cells() const { return samples_.size(); }

 private:
  double x0_ = 0, y0_ = 0, res_ = 1;
  std::size_t nx_ = 0, ny_ = 0;
  std::vector<Sample> samples_;  // row-major, y then x
};

// A node as the features see it: vehicles at the centre of their body.
struct FeatureNode {
  std::uint32_t node = 0;
  double x = 0, y = 0;  // body centre (vehicles), antenna (RSUs)
  double yaw_rad = 0;   // counter-clockwise from +x
  bool vehicle = true;
  float length_m = 0, width_m = 0, height_m = 0;  // RSUs: height_m is the antenna's z
  std::uint8_t vclass = kNoVehicle;
};
FeatureNode feature_node(const NodeInfo& info, const NodeState& state);

struct CorridorVehicle {
  float along_m = 0, across_m = 0, height_m = 0, length_m = 0, width_m = 0, yaw_rad = 0;
  std::uint8_t vclass = kNoVehicle;
};

struct LinkFeatures {
  float distance_2d_m = 0;
  float height_m[2] = {0, 0};
  std::vector<std::uint8_t> height, material;  // spec.cells() each, along-major
  std::uint32_t in_corridor = 0;
  std::vector<CorridorVehicle> vehicles;  // at most max_vehicles, by along
};

// The features of the link between nodes[tx] and nodes[rx] of one frame.
LinkFeatures link_features(const FeatureGridSpec& spec, const HeightMap& map, const std::vector<FeatureNode>& nodes,
                           std::size_t tx, std::size_t rx);

struct FeaturesHeader {
  std::string raysweep_version, git_hash;
  nlohmann::json config, inputs, provenance;
};

struct FeaturesStats {
  std::uint64_t frames = 0, rows = 0;
  double seconds = 0;
};

// Streams the dataset a block of frames at a time (memory bounded by a
// block) and writes the feature file `out`. `progress(done, total)` is
// called per block. Throws meshkit::InputError naming the dataset and the
// object when it cannot be read.
FeaturesStats write_features(const FeatureGridSpec& spec, const HeightMap& map, const std::filesystem::path& dataset,
                             const std::filesystem::path& out, const FeaturesHeader& header,
                             const std::function<void(std::uint64_t, std::uint64_t)>& progress = {});

// The provenance record of a finished feature file; nullopt when the file is
// missing, unfinished or unreadable (a caller then builds it again).
std::optional<nlohmann::json> finished_features_provenance(const std::filesystem::path& path);

}  // namespace raysweep::generators

namespace raysweep::generators::schema {
struct FileFormat;
extern const FileFormat kFeaturesFile;  // for validate_dataset() (schema_features.cpp)
}  // namespace raysweep::generators::schema
