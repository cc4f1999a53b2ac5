// Outputs appear only when complete: a stage writes into a sibling temporary
// path and renames it into place at the end. An interrupted or failed stage
// leaves the previous output (or nothing) behind, never a half-written one.
#pragma once

#include <filesystem>
#include <string>

namespace raysweep::pipeline {

class StagedDirectory {
 public:
  explicit StagedDirectory(std::filesystem::path final_dir);
  ~StagedDirectory();  // removes the temporary directory unless committed
  StagedDirectory(const StagedDirectory&) = delete;
  StagedDirectory& operator=(const StagedDirectory&) = delete;

  const std::filesystem::path& path() const { return tmp_; }  // write here
  void commit();  // replaces final_dir atomically as far as the filesystem allows

 private:
  std::filesystem::path final_;
  std::filesystem::path tmp_;
  bool committed_ = false;
};

// Writes `content` to `path` through a temporary file and a rename.
void write_file_atomic(const std::filesystem::path& path, const std::string& content);

}  // namespace raysweep::pipeline
