// Loads the OpenVDB module (radiomap_vdb.cpp) on first use. Where from: the
// RAYSWEEP_VDB_MODULE environment variable, else the module beside the
// running executable, else the one of the build tree this was built in.
#include <dlfcn.h>

#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "pipeline/radiomap_vdb.hpp"

namespace raysweep::pipeline {

namespace {

namespace fs = std::filesystem;

std::vector<std::string> module_candidates() {
  std::vector<std::string> out;
  if (const char* env = std::getenv("RAYSWEEP_VDB_MODULE"); env && *env) return {env};
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) out.push_back((exe.parent_path() / "libraysweep_vdb.so").string());
  out.push_back(RAYSWEEP_VDB_MODULE_PATH);
  return out;
}

const VdbModule& module() {
  static const VdbModule* loaded = nullptr;
  static std::string error;
  static std::once_flag once;
  std::call_once(once, [] {
    for (const auto& path : module_candidates()) {
      if (!fs::exists(path)) {
        error += "\n  " + path + ": not found";
        continue;
      }
      void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (!handle) {
        error += "\n  " + path + ": " + dlerror();
        continue;
      }
      using Entry = const VdbModule* (*)();
      auto entry = reinterpret_cast<Entry>(dlsym(handle, "raysweep_vdb_module"));
      if (entry && entry()->version == kVdbModuleVersion) {
        loaded = entry();
        return;
      }
      error += "\n  " + path + ": not this version's OpenVDB module";
    }
  });
  if (!loaded)
    throw std::runtime_error("the OpenVDB module (libraysweep_vdb.so, build target raysweep_vdb) cannot be loaded:" +
                             error);
  return *loaded;
}

}  // namespace

void write_radiomap_vdb(const std::string& path, double voxel_m, double z0_m,
                        const std::vector<std::array<std::int32_t, 3>>& voxels, const std::vector<VdbGrid>& grids,
                        const nlohmann::json& meta) {
  module().write(path, voxel_m, z0_m, voxels, grids, meta);
}

VdbSummary read_radiomap_vdb(const std::string& path) { return module().summary(path); }

std::vector<VdbVoxel> read_vdb_voxels(const std::string& path, const std::string& grid) {
  return module().voxels(path, grid);
}

}  // namespace raysweep::pipeline
