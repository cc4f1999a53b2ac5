// Shared by the libFuzzer harnesses of tests/fuzz: every raysweep reader
// takes a path, so each input is written to a file first (one per process
// and target, in RAYSWEEP_FUZZ_TMP, else /dev/shm, else the temp folder) and
// the real reader, the one the CLI calls, opens it.
//
// What counts as a finding. The CLI (pipeline/main.cpp) turns
// meshkit::InputError, pipeline::ConfigError and std::invalid_argument into a
// clear error and exit status 2: those are the documented answer to bad input,
// and their message must name the file. Anything else is a finding: a crash,
// an ASan/UBSan report, a leak, a hang (-timeout), a huge allocation
// (-malloc_limit_mb / -rss_limit_mb), any other exception type (the CLI
// would exit 1 with a bare library message), or a clear error that does not
// name the file. Findings abort with "raysweep-fuzz finding:" on stderr.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <typeinfo>

#include <spdlog/spdlog.h>

#include "meshkit/errors.hpp"
#include "pipeline/settings/config_error.hpp"

namespace raysweep::fuzz {

namespace fs = std::filesystem;

[[noreturn]] inline void finding(const std::string& what) {
  std::fprintf(stderr, "raysweep-fuzz finding: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

// Readers warn through spdlog; at fuzzing speed that is only noise.
inline void quiet() { spdlog::set_level(spdlog::level::off); }

// A scratch folder for this process (removed at exit).
inline const fs::path& scratch() {
  static const fs::path dir = [] {
    fs::path base;
    if (const char* env = std::getenv("RAYSWEEP_FUZZ_TMP"); env && *env) base = env;
    else if (fs::is_directory("/dev/shm")) base = "/dev/shm";
    else base = fs::temp_directory_path();
    fs::path d = base / ("raysweep-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  static const struct Cleanup {
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  } cleanup;
  return dir;
}

// Writes `data` to scratch()/name and returns the path.
inline std::string write_input(const std::string& name, const std::uint8_t* data, std::size_t size) {
  const fs::path p = scratch() / name;
  fs::create_directories(p.parent_path());
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  out.close();
  if (!out) finding("cannot write the fuzz input to " + p.string());
  return p.string();
}

// Runs `read`, which reads `path`: the documented errors pass when their
// message names `path` (by its file name); everything else is a finding.
template <class F>
void expect_clear_errors(const char* reader, const std::string& path, F&& read) {
  const std::string name = fs::path(path).filename().string();
  auto check_message = [&](const char* type, const std::exception& e) {
    const std::string msg = e.what();
    if (msg.find(name) == std::string::npos)
      finding(std::string(reader) + ": " + type + " does not name the file " + name + ": " + msg);
  };
  try {
    read();
  } catch (const meshkit::InputError& e) {
    check_message("InputError", e);
  } catch (const pipeline::ConfigError& e) {
    check_message("ConfigError", e);
  } catch (const std::invalid_argument& e) {
    check_message("invalid_argument", e);
  } catch (const std::exception& e) {
    finding(std::string(reader) + ": unexpected exception " + typeid(e).name() + ": " + e.what());
  } catch (...) {
    finding(std::string(reader) + ": unexpected non-std exception");
  }
}

}  // namespace raysweep::fuzz
