// What the file formats' validators and summaries share: the generic,
// schema-driven Validator each format's rules derive from, the summaries'
// helpers, and the FileFormat each format's library fills in for
// validate_dataset() and dataset_info() (generators/formats.cpp). All of them
// read through the checked file (generators/hdf5/checked_file.hpp).
#pragma once

#include <array>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "generators/hdf5/checked_file.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators::schema {

using hdf5::BlockReader;
using hdf5::kBlockRows;
using hdf5::major_version;

// The file's size, and per row of its main table (`per_key`).
void add_file_size(nlohmann::json& info, const std::string& path, std::uint64_t rows, const char* per_key);

// Counts the rows that break a rule and remembers the first.
struct Tally {
  std::uint64_t count = 0;
  std::string first;
  void add(std::uint64_t row, const std::string& detail) {
    if (count++ == 0) first = "row " + std::to_string(row) + ": " + detail;
  }
  void report(std::vector<std::string>& problems, const std::string& where, const std::string& rule) const {
    if (count == 0) return;
    problems.push_back(where + ": " + std::to_string(count) + " row(s) " + rule + " (first at " + first + ")");
  }
};

// Checks common to every format, driven by the schema: attributes, groups,
// datasets (type, shape, symbolic dimensions, units), root counts, codes, bits,
// references, offsets, and a full read of every dataset. The format's own
// cross-dataset rules come from rules().
class Validator {
 public:
  Validator(const hdf5::CheckedFile& file, const nlohmann::json& schema, std::vector<std::string>& problems)
      : path_(file.path()), problems_(problems), file_(file), schema_(schema),
        supported_major_(major_version(schema.at("schema_version").get<std::string>()).value_or(-1)) {}
  virtual ~Validator() = default;

  void run();

 protected:
  virtual void rules() {}

  std::string path_;
  std::vector<std::string>& problems_;
  const hdf5::CheckedFile& file_;
  const nlohmann::json& schema_;
  int supported_major_;
  std::map<std::string, hdf5::Dataset> good_;                  // datasets with the right type and shape
  std::map<std::string, std::pair<hsize_t, std::string>> dims_;  // symbol -> value, where it came from
  std::set<std::string> offsets_ok_;                           // offset datasets that passed

  void problem(std::string s) { problems_.push_back(std::move(s)); }

  // An error's text; without the file's name, which the problems leave out,
  // when the checked file raised it.
  std::string text_of(const std::exception& e) const {
    const std::string what = e.what(), prefix = path_ + ": ";
    const bool ours = dynamic_cast<const meshkit::InputError*>(&e) && what.rfind(prefix, 0) == 0;
    return ours ? what.substr(prefix.size()) : what;
  }

  template <class F>
  void guarded(const std::string& where, F&& f) {
    try {
      f();
    } catch (const std::exception& e) {
      const std::string what = text_of(e);
      problem(what.rfind(where, 0) == 0 ? what : where + ": " + what);  // readers' messages name the dataset
    }
  }

  static std::string path_of(const nlohmann::json& g, const nlohmann::json& d) {
    return "/" + g.at("name").get<std::string>() + "/" + d.at("name").get<std::string>();
  }

  // nullptr when the dataset failed the structural checks.
  const hdf5::Dataset* dset(const std::string& p) const {
    auto it = good_.find(p);
    return it == good_.end() ? nullptr : &it->second;
  }
  std::optional<hsize_t> dim(const std::string& sym) const {
    auto it = dims_.find(sym);
    if (it == dims_.end()) return std::nullopt;
    return it->second.first;
  }

  // Binds a symbolic dimension or checks it against its earlier binding.
  bool bind(const std::string& sym, hsize_t value, const std::string& where, const std::string& what) {
    auto it = dims_.find(sym);
    if (it == dims_.end()) {
      dims_[sym] = {value, where};
      return true;
    }
    if (it->second.first == value) return true;
    problem(where + ": " + what + " " + std::to_string(value) + " but " + sym + " = " +
            std::to_string(it->second.first) + " (from " + it->second.second + ")");
    return false;
  }

  // `where` is "/" for the root.
  void check_attributes(const std::string& where, const nlohmann::json& specs);
  std::map<std::string, std::uint64_t> attr_values_;
  std::string file_version_;  // the file's schema_version

  // MAJOR.MINOR.PATCH as a comparable triple (zeros when unparsable).
  static std::array<int, 3> version_triple(const std::string& v) {
    std::array<int, 3> t{0, 0, 0};
    std::sscanf(v.c_str(), "%d.%d.%d", &t[0], &t[1], &t[2]);
    return t;
  }

  // Store levels (schemas/README.md): the root attribute `store`'s value as
  // an index into its spec's `one_of` (the levels in order); a file without
  // it holds the top level. A group or dataset with `stored_from` is
  // present exactly at that level and above.
  std::optional<std::size_t> store_rank_;
  std::string store_name_;
  std::optional<std::size_t> level_rank(const std::string& level) const;
  // Whether a `stored_from` spec is stored at the file's level; a present
  // object the level excludes is reported.
  bool stored(const nlohmann::json& spec, const std::string& p, bool present);

  void check_group(const nlohmann::json& g);

  void check_dataset(const nlohmann::json& g, const nlohmann::json& d);

  void check_root_counts(const nlohmann::json& specs);

  // Codes, flag bits, references and offsets of one dataset.
  void check_values(const nlohmann::json& g, const nlohmann::json& d);
};

// A root string attribute; `fallback` when it is missing.
std::string root_str(const hdf5::CheckedFile& r, const std::string& name, const std::string& fallback = "");
// Nodes by kind (the node table is written by finish(): absent in an unfinished file).
void add_node_kinds(nlohmann::json& info, const hdf5::CheckedFile& r);
std::string human_bytes(double b);
// The first lines of both formats' summaries: file, completeness, format and writer.
std::string identity_lines(const nlohmann::json& info);
// The summary's identity fields, which every format has: file, format, schema
// version, writer version and commit, completeness.
nlohmann::json identity_info(const hdf5::CheckedFile& r, const char* format);

// A file format as validate_dataset() and dataset_info() (generators/formats.cpp)
// find it by the root attribute `format`: its schema, its rules beyond the
// schema, its summary and the summary's text. Each format's library has its
// own (schema_channels.cpp, sinr/schema_sinr.cpp, ns3_table/schema_ns3_table.cpp,
// sweep/schema_features.cpp).
struct FileFormat {
  const char* name;
  const nlohmann::json& (*schema)();
  void (*validate)(const hdf5::CheckedFile& file, const nlohmann::json& schema, std::vector<std::string>& problems);
  nlohmann::json (*info)(const hdf5::CheckedFile& file);
  std::string (*info_text)(const nlohmann::json& info);
};

// The channel dataset's (schema_channels.cpp).
extern const FileFormat kChannelsFile;

}  // namespace raysweep::generators::schema
