#include "pipeline/preview.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>

#include <spdlog/spdlog.h>

extern char** environ;

namespace raysweep::pipeline {

namespace {
// The scripts ship with the source tree; RAYSWEEP_PYTHON_DIR overrides it for
// installed copies.
std::filesystem::path python_dir() {
  if (const char* env = std::getenv("RAYSWEEP_PYTHON_DIR")) return env;
  return RAYSWEEP_DEFAULT_PYTHON_DIR;
}
}  // namespace

bool run_python_script(const std::string& script, const std::vector<std::string>& args) {
  const std::filesystem::path path = python_dir() / script;
  const char* python = "/usr/bin/python3";
  if (!std::filesystem::exists(path) || ::access(python, X_OK) != 0) {
    spdlog::warn("preview skipped: {} or {} not found", path.string(), python);
    return false;
  }
  std::vector<std::string> argv_s{python, path.string()};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  // Silence the child's stdout (it prints the file name) but keep stderr for errors.
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, python, &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    spdlog::warn("preview skipped: cannot start {}", python);
    return false;
  }
  int status = 0;
  waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    spdlog::warn("preview script {} failed (status {})", script, status);
    return false;
  }
  return true;
}

}  // namespace raysweep::pipeline
