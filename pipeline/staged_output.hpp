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

// One output file written through a temporary sibling: write to path(), then
// commit() renames it into place. Without commit() (an exception on the way)
// the temporary is removed and the previous output stays as it was.
class StagedFile {
 public:
  // The temporary is `final_path` + ".tmp".
  explicit StagedFile(std::filesystem::path final_path);
  // A temporary of the caller's choice (e.g. one keeping the extension a writer
  // infers the format from); it must lie on the same filesystem.
  StagedFile(std::filesystem::path final_path, std::filesystem::path tmp_path);
  ~StagedFile();  // removes the temporary unless committed
  StagedFile(const StagedFile&) = delete;
  StagedFile& operator=(const StagedFile&) = delete;

  const std::filesystem::path& path() const { return tmp_; }  // write here
  const std::filesystem::path& final_path() const { return final_; }
  void commit();  // renames the temporary to final_path

 private:
  std::filesystem::path final_;
  std::filesystem::path tmp_;
  bool committed_ = false;
};

// Writes `content` to `path` through a temporary file and a rename.
void write_file_atomic(const std::filesystem::path& path, const std::string& content);

}  // namespace raysweep::pipeline
