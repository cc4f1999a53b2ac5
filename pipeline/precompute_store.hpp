// The tracer's precomputed model tables (tracer/precompute.hpp) as files in
// a scene folder's cache/ (one file per table, named by its content key), so
// that `trace`, `sweep`, `tradeoff` and `radiomap` processes after the first
// load them instead of building them. Files appear through a temporary and a
// rename; a folder that cannot be written only costs the rebuild (one warning).
#pragma once

#include <filesystem>
#include <memory>
#include <mutex>

#include "tracer/precompute.hpp"

namespace raysweep::pipeline {

class FilePrecomputeStore : public tracer::PrecomputeStore {
 public:
  explicit FilePrecomputeStore(std::filesystem::path dir) : dir_(std::move(dir)) {}
  std::optional<std::string> load(const std::string& key) const override;
  void save(const std::string& key, const std::string& bytes) const override;
  void rejected(const std::string& key, const std::string& why) const override;
  std::filesystem::path file(const std::string& key) const { return dir_ / (key + ".bin"); }

 private:
  std::filesystem::path dir_;
  mutable std::mutex mutex_;
  mutable bool warned_ = false;
};

// The store of the scene folder `scene_dir` (its cache/ subfolder).
std::shared_ptr<const tracer::PrecomputeStore> scene_precompute_store(const std::filesystem::path& scene_dir);

}  // namespace raysweep::pipeline
