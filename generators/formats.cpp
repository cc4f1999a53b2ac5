// Validation and summary of raysweep files told apart by their root `format`
// attribute, dispatched to the format's checks and summary (FileFormat, in
// each format's library). The generic, schema-driven checks are in
// generators/dataset/schema_validator.cpp.
#include "generators/formats.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdio>
#include <string>
#include <vector>

#include "generators/dataset/schema_validator.hpp"
#include "generators/hdf5/checked_file.hpp"
#include "generators/ns3_table/ns3_table.hpp"
#include "generators/sinr/sinr_file.hpp"
#include "generators/sweep/context_features.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators {

namespace {

using hdf5::QuietHdf5;
using schema::FileFormat;

// Every format this program reads, in the order its messages list them.
std::array<const FileFormat*, 4> formats() {
  return {&schema::kChannelsFile, &schema::kSinrFile, &schema::kNs3TableFile, &schema::kFeaturesFile};
}

// nullptr for formats this program does not know.
const FileFormat* format_named(const std::string& name) {
  for (const FileFormat* f : formats())
    if (name == f->name) return f;
  return nullptr;
}

std::string known_formats() {
  std::string names;
  for (const FileFormat* f : formats()) names += (names.empty() ? "" : ", ") + std::string(f->name);
  return names;
}

// Opens the file, reads its format and runs that format's validator.
void validate_file(const std::string& path, std::vector<std::string>& problems) {
  hdf5::CheckedFile file(path);
  std::string format;
  try {
    file.open();
    // Without a known format there is no schema to check against: one problem.
    if (!file.has_attr("/", "format")) {
      problems.push_back(path + ": attribute format missing: not a raysweep file (expected one of " + known_formats() +
                         ")");
      return;
    }
    format = file.attr<std::string>("/", "format");
  } catch (const meshkit::InputError& e) {
    problems.push_back(e.what());
    return;
  }
  const FileFormat* f = format_named(format);
  if (!f) {
    problems.push_back(path + ": unknown format \"" + format + "\" (this program reads " + known_formats() + ")");
    return;
  }
  f->validate(file, f->schema(), problems);
}

std::vector<std::string> validate_in_process(const std::string& path) {
  QuietHdf5 quiet;
  std::vector<std::string> problems;
  try {
    validate_file(path, problems);
  } catch (const std::exception& e) {
    problems.push_back(path + ": " + e.what());
  }
  hdf5::clear_errors();
  return problems;
}

}  // namespace


// HDF5 1.10 does not bounds-check everything it reads: some corrupt files (a
// damaged global heap behind variable-length strings, for instance) crash the
// library instead of returning an error. The checks therefore run in a forked
// child that sends its problems back through a pipe (NUL-separated); a child that
// dies is reported as one problem naming the file. Without fork (or a pipe) they
// run in this process.
std::vector<std::string> validate_dataset(const std::string& path) {
  int fds[2];
  if (::pipe(fds) != 0) return validate_in_process(path);
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    return validate_in_process(path);
  }
  if (pid == 0) {  // child: validate, send, leave without atexit handlers (HDF5's or the parent's)
    ::close(fds[0]);
    std::string out;
    for (const auto& p : validate_in_process(path)) out.append(p).push_back('\0');
    std::size_t done = 0;
    while (done < out.size()) {
      const ssize_t n = ::write(fds[1], out.data() + done, out.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) ::_exit(3);
      done += static_cast<std::size_t>(n);
    }
    ::_exit(0);
  }
  ::close(fds[1]);
  std::string in;
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    in.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  std::vector<std::string> problems;
  for (std::size_t start = 0; start < in.size();) {
    const std::size_t end = in.find('\0', start);
    problems.push_back(in.substr(start, end - start));
    if (end == std::string::npos) break;
    start = end + 1;
  }
  if (WIFSIGNALED(status))
    problems.push_back(path + ": corrupt file: reading it crashed the HDF5 library (signal " +
                       std::to_string(WTERMSIG(status)) + ")");
  else if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    problems.push_back(path + ": validation failed (checker exit status " + std::to_string(WEXITSTATUS(status)) + ")");
  return problems;
}


nlohmann::json dataset_info(const std::string& path) {
  QuietHdf5 quiet;
  hdf5::CheckedFile r(path);
  r.open();

  const std::string format = schema::root_str(r, "format");
  if (const FileFormat* f = format_named(format)) return f->info(r);
  throw meshkit::InputError(path, "attribute format",
                            "not a raysweep file (format \"" + format + "\"; this program reads " + known_formats() + ")");
}

std::string format_dataset_info(const nlohmann::json& info) {
  // Without a known format, as a channel dataset's.
  const FileFormat* f = format_named(info.value("format", std::string()));
  return (f ? f : &schema::kChannelsFile)->info_text(info);
}

}  // namespace raysweep::generators
