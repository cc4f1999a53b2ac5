#include "pipeline/preview.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <optional>

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

constexpr const char* kPython = "/usr/bin/python3";

// Runs `python3 args` with environment `envp` and waits: the wait status, or
// nullopt when it cannot start. quiet_stdout: the child's stdout to /dev/null.
std::optional<int> spawn_python(const std::vector<std::string>& args, char* const* envp, bool quiet_stdout) {
  std::vector<std::string> argv_s{kPython};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (quiet_stdout) posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, kPython, &actions, nullptr, argv.data(), envp);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) return std::nullopt;
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}
}  // namespace

bool run_python_script(const std::string& script, const std::vector<std::string>& args) {
  const std::filesystem::path path = python_dir() / script;
  if (!std::filesystem::exists(path) || ::access(kPython, X_OK) != 0) {
    spdlog::warn("preview skipped: {} or {} not found", path.string(), kPython);
    return false;
  }
  std::vector<std::string> argv{path.string()};
  argv.insert(argv.end(), args.begin(), args.end());
  // Silence the child's stdout (it prints the file name) but keep stderr for errors.
  const auto status = spawn_python(argv, environ, true);
  if (!status) {
    spdlog::warn("preview skipped: cannot start {}", kPython);
    return false;
  }
  if (!WIFEXITED(*status) || WEXITSTATUS(*status) != 0) {
    spdlog::warn("preview script {} failed (status {})", script, *status);
    return false;
  }
  return true;
}

int run_python_module(const std::string& module, const std::vector<std::string>& args) {
  if (::access(kPython, X_OK) != 0) {
    spdlog::error("{} not found (Debian's python3 with numpy, h5py, matplotlib, scikit-learn, torch)", kPython);
    return 127;
  }
  std::vector<std::string> argv{"-m", module};
  argv.insert(argv.end(), args.begin(), args.end());
  // The child's environment: ours with python/ first on PYTHONPATH.
  std::vector<std::string> env_s;
  std::string path = python_dir().string();
  for (char** e = environ; *e; ++e) {
    const std::string kv = *e;
    if (kv.rfind("PYTHONPATH=", 0) == 0)
      path += ":" + kv.substr(11);
    else
      env_s.push_back(kv);
  }
  env_s.push_back("PYTHONPATH=" + path);
  std::vector<char*> envp;
  for (auto& kv : env_s) envp.push_back(kv.data());
  envp.push_back(nullptr);
  const auto status = spawn_python(argv, envp.data(), false);
  if (!status) {
    spdlog::error("cannot start {}", kPython);
    return 127;
  }
  return WIFEXITED(*status) ? WEXITSTATUS(*status) : 128 + (WIFSIGNALED(*status) ? WTERMSIG(*status) : 0);
}

}  // namespace raysweep::pipeline
