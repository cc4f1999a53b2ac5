// The embedded schemas, and validation and summary of raysweep files told apart
// by their root `format` attribute: channel datasets, SINR outcome files and
// ns-3 tables (schemas/raysweep_*.schema.json). The generic, schema-driven
// checks are in schema_validator.cpp, each format's own rules and summary in
// schema_channels.cpp, schema_sinr.cpp and schema_ns3_table.cpp.
#include "generators/dataset_schema.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "generators/dataset_writer.hpp"
#include "generators/hdf5/checked_file.hpp"
#include "generators/context_features.hpp"
#include "generators/ns3_table.hpp"
#include "generators/schema_validator.hpp"
#include "generators/sinr/sinr_file.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators {

namespace embedded {
extern const char kDatasetSchemaJson[];  // generated from schemas/raysweep_dataset.schema.json
extern const char kSinrSchemaJson[];     // generated from schemas/raysweep_sinr.schema.json
extern const char kNs3TableSchemaJson[]; // generated from schemas/raysweep_ns3_table.schema.json
extern const char kFeaturesSchemaJson[]; // generated from schemas/raysweep_features.schema.json
}  // namespace embedded

namespace {

// An embedded schema: its text, and the JSON parsed once.
struct EmbeddedSchema {
  std::string text;
  nlohmann::json json;
  explicit EmbeddedSchema(const char* t) : text(t), json(nlohmann::json::parse(text)) {}
};
const EmbeddedSchema& dataset_embedded() {
  static const EmbeddedSchema s(embedded::kDatasetSchemaJson);
  return s;
}
const EmbeddedSchema& sinr_embedded() {
  static const EmbeddedSchema s(embedded::kSinrSchemaJson);
  return s;
}
const EmbeddedSchema& ns3_table_embedded() {
  static const EmbeddedSchema s(embedded::kNs3TableSchemaJson);
  return s;
}
const EmbeddedSchema& features_embedded() {
  static const EmbeddedSchema s(embedded::kFeaturesSchemaJson);
  return s;
}

}  // namespace

const std::string& dataset_schema_json() { return dataset_embedded().text; }
const nlohmann::json& dataset_schema() { return dataset_embedded().json; }
const std::string& sinr_schema_json() { return sinr_embedded().text; }
const nlohmann::json& sinr_schema() { return sinr_embedded().json; }
const std::string& ns3_table_schema_json() { return ns3_table_embedded().text; }
const nlohmann::json& ns3_table_schema() { return ns3_table_embedded().json; }
const std::string& features_schema_json() { return features_embedded().text; }
const nlohmann::json& features_schema() { return features_embedded().json; }

namespace {

using hdf5::QuietHdf5;

// The schema of a format name; nullptr for formats this program does not know.
const nlohmann::json* schema_of(const std::string& format) {
  if (format == kDatasetFormat) return &dataset_schema();
  if (format == sinr::kSinrFormat) return &sinr_schema();
  if (format == kNs3TableFormat) return &ns3_table_schema();
  if (format == kFeaturesFormat) return &features_schema();
  return nullptr;
}

std::string known_formats() {
  return std::string(kDatasetFormat) + ", " + sinr::kSinrFormat + ", " + kNs3TableFormat + ", " + kFeaturesFormat;
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
  const nlohmann::json* schema = schema_of(format);
  if (!schema) {
    problems.push_back(path + ": unknown format \"" + format + "\" (this program reads " + known_formats() + ")");
    return;
  }
  if (format == kDatasetFormat)
    schema::validate_channels(file, *schema, problems);
  else if (format == kNs3TableFormat)
    schema::validate_ns3_table(file, *schema, problems);
  else if (format == kFeaturesFormat)
    schema::validate_features(file, *schema, problems);
  else
    schema::validate_sinr(file, *schema, problems);
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
  if (format == kDatasetFormat) return schema::channel_info(r);
  if (format == sinr::kSinrFormat) return schema::sinr_info(r);
  if (format == kNs3TableFormat) return schema::ns3_table_info(r);
  if (format == kFeaturesFormat) return schema::features_info(r);
  throw meshkit::InputError(path, "attribute format",
                            "not a raysweep file (format \"" + format + "\"; this program reads " + known_formats() + ")");
}

std::string format_dataset_info(const nlohmann::json& info) {
  if (info.value("format", std::string()) == sinr::kSinrFormat) return schema::format_sinr_info(info);
  if (info.value("format", std::string()) == kNs3TableFormat) return schema::format_ns3_table_info(info);
  if (info.value("format", std::string()) == kFeaturesFormat) return schema::format_features_info(info);
  return schema::format_channel_info(info);
}

}  // namespace raysweep::generators
