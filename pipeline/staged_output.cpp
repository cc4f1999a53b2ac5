#include "pipeline/staged_output.hpp"

#include <unistd.h>

#include <fstream>
#include <stdexcept>

namespace raysweep::pipeline {

namespace fs = std::filesystem;

namespace {
fs::path sibling(const fs::path& p, const std::string& tag) {
  fs::path parent = p.parent_path();
  return parent / (p.filename().string() + "." + tag + "-" + std::to_string(::getpid()));
}
}  // namespace

StagedDirectory::StagedDirectory(fs::path final_dir) : final_(std::move(final_dir)) {
  if (final_.filename().empty()) final_ = final_.parent_path();  // "out/" -> "out"
  if (!final_.parent_path().empty()) fs::create_directories(final_.parent_path());
  tmp_ = sibling(final_, "tmp");
  fs::remove_all(tmp_);
  fs::create_directories(tmp_);
}

StagedDirectory::~StagedDirectory() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(tmp_, ec);
  }
}

void StagedDirectory::commit() {
  // rename(2) cannot replace a non-empty directory: move the old one aside first.
  const fs::path old = sibling(final_, "old");
  if (fs::exists(final_)) {
    fs::remove_all(old);
    fs::rename(final_, old);
  }
  fs::rename(tmp_, final_);
  committed_ = true;
  std::error_code ec;
  fs::remove_all(old, ec);
}

StagedFile::StagedFile(fs::path final_path) : StagedFile(final_path, final_path.string() + ".tmp") {}

StagedFile::StagedFile(fs::path final_path, fs::path tmp_path) : final_(std::move(final_path)), tmp_(std::move(tmp_path)) {
  if (final_.has_parent_path()) fs::create_directories(final_.parent_path());
}

StagedFile::~StagedFile() {
  if (!committed_) {
    std::error_code ec;
    fs::remove(tmp_, ec);
  }
}

void StagedFile::commit() {
  fs::rename(tmp_, final_);
  committed_ = true;
}

void write_file_atomic(const fs::path& path, const std::string& content) {
  if (!path.parent_path().empty()) fs::create_directories(path.parent_path());
  const fs::path tmp = sibling(path, "tmp");
  {
    std::ofstream out(tmp, std::ios::binary);
    out << content;
    out.flush();
    if (!out) throw std::runtime_error(tmp.string() + ": write failed");
  }
  fs::rename(tmp, path);
}

}  // namespace raysweep::pipeline
