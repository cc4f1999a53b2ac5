#include "pipeline/precompute_store.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <fstream>
#include <iterator>
#include <system_error>

namespace raysweep::pipeline {

namespace fs = std::filesystem;

std::optional<std::string> FilePrecomputeStore::load(const std::string& key) const {
  std::ifstream in(file(key), std::ios::binary);
  if (!in) return std::nullopt;
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void FilePrecomputeStore::save(const std::string& key, const std::string& bytes) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::error_code ec;
  fs::create_directories(dir_, ec);
  // A temporary of this process: two processes filling the same cache each rename a whole file.
  const fs::path tmp = dir_ / (key + ".tmp-" + std::to_string(::getpid()));
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (out) fs::rename(tmp, file(key), ec);
    else ec = std::make_error_code(std::errc::io_error);
  }
  if (!ec) return;
  fs::remove(tmp, ec);
  if (!warned_) spdlog::warn("{}: cannot store precomputed tables here; they are rebuilt in every process", dir_.string());
  warned_ = true;
}

void FilePrecomputeStore::rejected(const std::string& key, const std::string& why) const {
  spdlog::warn("{}: {}; rebuilding it", file(key).string(), why);
}

std::shared_ptr<const tracer::PrecomputeStore> scene_precompute_store(const fs::path& scene_dir) {
  return std::make_shared<FilePrecomputeStore>(scene_dir / "cache");
}

}  // namespace raysweep::pipeline
