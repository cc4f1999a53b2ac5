// The radio map's OpenVDB file (Debian's OpenVDB 10, C++ API). The only
// translation unit that includes OpenVDB (it costs ~20 s to compile) is
// built as a module of its own (libraysweep_vdb.so beside the binary),
// loaded on first use: these functions throw std::runtime_error naming the
// module when it cannot be loaded.
//
// Every grid shares one linear transform: voxel (i, j, k) is the point
// transform.indexToWorld(i, j, k) = (i v, j v, z0 + k v), v the voxel size;
// a voxel's value is the value at that point (its centre). Only the listed
// voxels are active; the background is inactive.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace raysweep::pipeline {

struct VdbGrid {
  std::string name;
  bool is_float = true;
  std::vector<float> f;         // per voxel (is_float)
  std::vector<std::int32_t> i;  // per voxel (!is_float)
  float float_background = 0;
  std::int32_t int_background = 0;
  // Grid metadata: numbers become doubles (integers int64), strings stay
  // strings, anything else is stored as its JSON text.
  nlohmann::json meta = nlohmann::json::object();
};

// Writes `grids` (values in the order of `voxels`) with file metadata `meta`
// to `path` through a temporary file and a rename.
void write_radiomap_vdb(const std::string& path, double voxel_m, double z0_m,
                        const std::vector<std::array<std::int32_t, 3>>& voxels, const std::vector<VdbGrid>& grids,
                        const nlohmann::json& meta);

// What a reader sees: per grid its name, type, active voxel count and the
// value range; the file metadata as JSON (for tests and `raysweep info`-like
// checks through OpenVDB's own reader).
struct VdbSummary {
  struct Grid {
    std::string name, type;
    std::uint64_t active = 0;
    double min = 0, max = 0;
    double voxel_m = 0;
    nlohmann::json meta;
  };
  std::vector<Grid> grids;
  nlohmann::json meta;
};
VdbSummary read_radiomap_vdb(const std::string& path);

// Every active voxel of grid `grid` (float or int, as double) with its world
// position transform.indexToWorld(i, j, k), in index order.
struct VdbVoxel {
  std::array<std::int32_t, 3> ijk;
  std::array<double, 3> world;
  double value;
};
std::vector<VdbVoxel> read_vdb_voxels(const std::string& path, const std::string& grid);

// The module's entry points (radiomap_vdb.cpp), found by the loader
// (radiomap_vdb_loader.cpp) through the C symbol raysweep_vdb_module.
constexpr int kVdbModuleVersion = 1;
struct VdbModule {
  int version;
  void (*write)(const std::string&, double, double, const std::vector<std::array<std::int32_t, 3>>&,
                const std::vector<VdbGrid>&, const nlohmann::json&);
  VdbSummary (*summary)(const std::string&);
  std::vector<VdbVoxel> (*voxels)(const std::string&, const std::string&);
};

}  // namespace raysweep::pipeline
