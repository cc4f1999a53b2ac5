// Helpers shared by the tests: scratch folders, files, running the CLI.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

namespace raysweep::test {

namespace fs = std::filesystem;

inline fs::path scratch_dir(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  // The process id keeps concurrent runs of the suite (several checkouts,
  // CI) out of each other's folders.
  fs::path p = fs::temp_directory_path() / "raysweep-tests" /
               (std::string(info ? info->test_suite_name() : "t") + "." + (info ? info->name() : "x") + "." + name +
                "." + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

inline void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
}

inline std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

inline fs::path shared_data() { return fs::path(RAYSWEEP_SHARED_DATA); }
inline fs::path source_dir() { return fs::path(RAYSWEEP_SOURCE_DIR); }

struct RunResult {
  int exit_code;
  std::string output;  // stdout and stderr together
};

inline RunResult run_command(const std::string& cmd) {
  RunResult r{-1, {}};
  FILE* pipe = popen((cmd + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf;
  std::size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), pipe)) > 0) r.output.append(buf.data(), n);
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

#ifdef RAYSWEEP_BINARY
inline RunResult run_raysweep(const std::string& args) { return run_command(std::string(RAYSWEEP_BINARY) + " " + args); }

// The demo city's scene, built once per process into a folder named by `tag`
// and the process id (ctest runs each test in its own process, in parallel).
inline fs::path build_demo_scene(const std::string& tag) {
  fs::path d = fs::temp_directory_path() / "raysweep-tests" / (tag + "." + std::to_string(::getpid()));
  fs::remove_all(d);
  const auto demo = source_dir() / "datasets/demo";
  auto r = run_raysweep("-q scene --no-preview --osm " + (demo / "kirchberg.osm").string() + " --net " +
                        (demo / "kirchberg.net.xml").string() + " --out " + d.string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  return d;
}
#endif

}  // namespace raysweep::test
