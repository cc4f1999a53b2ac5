// Validation and summary of raysweep files, driven by the embedded schemas:
// channel datasets (schemas/raysweep_dataset.schema.json) and SINR outcome files
// (schemas/raysweep_sinr.schema.json), told apart by the root `format`
// attribute. Structure, types and shapes come from the schema's groups/datasets/
// attributes, codes from its code tables, offset and reference checks from the
// datasets' "offsets" and "references" entries; each format's cross-dataset
// rules (channel: link sorting, presence of nodes, flags vs paths; SINR:
// schedule order, receptions vs transmissions, overlaps, PRR) are written out below.
#include "generators/dataset_schema.hpp"

#include <hdf5.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "generators/dataset_writer.hpp"
#include "generators/hdf5_columns.hpp"
#include "generators/hdf5_file.hpp"
#include "generators/ns3_table.hpp"
#include "generators/sinr/sinr_file.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators {

namespace embedded {
extern const char kDatasetSchemaJson[];  // generated from schemas/raysweep_dataset.schema.json
extern const char kSinrSchemaJson[];     // generated from schemas/raysweep_sinr.schema.json
extern const char kNs3TableSchemaJson[]; // generated from schemas/raysweep_ns3_table.schema.json
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

}  // namespace

const std::string& dataset_schema_json() { return dataset_embedded().text; }
const nlohmann::json& dataset_schema() { return dataset_embedded().json; }
const std::string& sinr_schema_json() { return sinr_embedded().text; }
const nlohmann::json& sinr_schema() { return sinr_embedded().json; }
const std::string& ns3_table_schema_json() { return ns3_table_embedded().text; }
const nlohmann::json& ns3_table_schema() { return ns3_table_embedded().json; }

namespace {

using hdf5::BlockReader;

// The file's size, and per row of its main table (`per_key`).
void add_file_size(nlohmann::json& info, const std::string& path, std::uint64_t rows, const char* per_key) {
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(path, ec);
  info["file_bytes"] = ec ? 0 : bytes;
  info[per_key] = rows && !ec ? static_cast<double>(bytes) / static_cast<double>(rows) : 0.0;
}
using hdf5::dataset_dims;
using hdf5::Handle;
using hdf5::has_attr;
using hdf5::has_link;
using hdf5::hdf5_error_text;
using hdf5::kBlockRows;
using hdf5::major_version;
using hdf5::QuietHdf5;
using hdf5::read_f64;
using hdf5::read_fail;
using hdf5::read_num_attr;
using hdf5::read_rows;
using hdf5::read_str_attr;
using hdf5::read_u64;
using hdf5::ReadError;
using hdf5::type_mismatch;

// The schema of a format name; nullptr for formats this program does not know.
const nlohmann::json* schema_of(const std::string& format) {
  if (format == kDatasetFormat) return &dataset_schema();
  if (format == sinr::kSinrFormat) return &sinr_schema();
  if (format == kNs3TableFormat) return &ns3_table_schema();
  return nullptr;
}

std::string known_formats() {
  return std::string(kDatasetFormat) + ", " + sinr::kSinrFormat + ", " + kNs3TableFormat;
}

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

// ---------------------------------------------------------------------------

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

  void run() {
    check_attributes(file_.id(), "/", schema_.at("attributes"));
    for (const auto& g : schema_.at("groups")) check_group(g);
    check_root_counts(schema_.at("attributes"));
    for (const auto& g : schema_.at("groups"))
      for (const auto& d : g.at("datasets")) guarded(path_of(g, d), [&] { check_values(g, d); });
    rules();
    for (const auto& entry : good_) guarded(entry.first, [&] { check_readable(entry.first, entry.second.get()); });
  }

 protected:
  virtual void rules() {}

  std::string path_;
  std::vector<std::string>& problems_;
  const hdf5::CheckedFile& file_;
  const nlohmann::json& schema_;
  int supported_major_;
  std::map<std::string, Handle> groups_;
  std::map<std::string, Handle> good_;                         // datasets with the right type and shape
  std::map<std::string, std::pair<hsize_t, std::string>> dims_;  // symbol -> value, where it came from
  std::set<std::string> offsets_ok_;                           // offset datasets that passed

  void problem(std::string s) { problems_.push_back(std::move(s)); }

  template <class F>
  void guarded(const std::string& where, F&& f) {
    try {
      f();
    } catch (const std::exception& e) {
      const std::string what = e.what();
      problem(what.rfind(where, 0) == 0 ? what : where + ": " + what);  // readers' messages name the dataset
    }
  }

  // Reads every row (decompressing every chunk), so damaged data is found even in
  // datasets no rule looks at.
  void check_readable(const std::string& p, hid_t ds) {
    Handle ftype(H5Dget_type(ds), H5Tclose);
    if (!ftype.valid()) read_fail(p, "cannot get type");
    const bool vlen = H5Tget_class(ftype.get()) == H5T_STRING && H5Tis_variable_str(ftype.get()) > 0;
    Handle mtype(vlen ? H5Tcopy(ftype.get()) : H5Tget_native_type(ftype.get(), H5T_DIR_ASCEND), H5Tclose);
    if (!mtype.valid()) read_fail(p, "cannot make memory type");
    const auto dims = dataset_dims(ds, p);
    if (dims.empty() || dims.size() > 2) return;
    const hsize_t width = dims.size() == 2 ? dims[1] : 1;
    const std::size_t row_bytes = std::max<std::size_t>(1, H5Tget_size(mtype.get()) * width);
    const hsize_t block = std::max<hsize_t>(1, (hsize_t{16} << 20) / row_bytes);
    std::vector<unsigned char> buf;
    for (hsize_t start = 0; start < dims[0]; start += block) {
      const hsize_t n = std::min(block, dims[0] - start);
      buf.resize(static_cast<std::size_t>(n) * row_bytes);
      Handle fspace(H5Dget_space(ds), H5Sclose);
      const hsize_t s[2] = {start, 0};
      const hsize_t c[2] = {n, width};
      const int rank = static_cast<int>(dims.size());
      if (!fspace.valid() || H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, s, nullptr, c, nullptr) < 0)
        read_fail(p, "cannot select rows");
      Handle mspace(H5Screate_simple(rank, c, nullptr), H5Sclose);
      if (!mspace.valid() || H5Dread(ds, mtype.get(), mspace.get(), fspace.get(), H5P_DEFAULT, buf.data()) < 0)
        read_fail(p, "cannot read rows " + std::to_string(start) + ".." + std::to_string(start + n - 1) +
                         " (damaged data?)");
      if (vlen) H5Dvlen_reclaim(mtype.get(), mspace.get(), H5P_DEFAULT, buf.data());
    }
  }

  static std::string path_of(const nlohmann::json& g, const nlohmann::json& d) {
    return "/" + g.at("name").get<std::string>() + "/" + d.at("name").get<std::string>();
  }

  hid_t dset(const std::string& p) const {
    auto it = good_.find(p);
    return it == good_.end() ? H5I_INVALID_HID : it->second.get();
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

  void check_attributes(hid_t loc, const std::string& where, const nlohmann::json& specs) {
    const std::string prefix = where == "/" ? "attribute " : "attribute " + where + "@";
    for (const auto& a : specs) {
      const std::string name = a.at("name");
      const std::string dtype = a.at("dtype");
      const std::string label = prefix + name;
      if (!has_attr(loc, name)) {
        if (a.value("optional", false)) continue;
        if (name == "complete")
          problem(label + " missing: the file was not finished (its writer stopped before finish())");
        else
          problem(label + " missing");
        continue;
      }
      Handle attr(H5Aopen(loc, name.c_str(), H5P_DEFAULT), H5Aclose);
      Handle type(attr.valid() ? H5Aget_type(attr.get()) : H5I_INVALID_HID, H5Tclose);
      Handle space(attr.valid() ? H5Aget_space(attr.get()) : H5I_INVALID_HID, H5Sclose);
      if (!type.valid() || !space.valid()) {
        problem(label + ": cannot open (" + hdf5_error_text() + ")");
        continue;
      }
      if (auto m = type_mismatch(type.get(), dtype); !m.empty()) {
        problem(label + ": type is " + m + ", expected " + dtype);
        continue;
      }
      if (H5Sget_simple_extent_type(space.get()) != H5S_SCALAR) {
        problem(label + ": not a scalar");
        continue;
      }
      try {
        if (dtype == "str") {
          const std::string v = read_str_attr(loc, where == "/" ? "/" : where + " ", name);
          if (a.contains("value") && v != a.at("value").get<std::string>())
            problem(label + " is \"" + v + "\", expected \"" + a.at("value").get<std::string>() + "\"");
          if (a.value("json", false) && !nlohmann::json::accept(v)) problem(label + ": not valid JSON text");
          if (a.contains("one_of")) {
            const auto& allowed = a.at("one_of");
            if (std::find(allowed.begin(), allowed.end(), v) == allowed.end())
              problem(label + " is \"" + v + "\", expected one of " + allowed.dump());
          }
          if (name == "schema_version") {
            file_version_ = v;
            const auto major = major_version(v);
            if (!major)
              problem(label + " \"" + v + "\" is not a MAJOR.MINOR.PATCH version");
            else if (*major != supported_major_)
              problem(label + " is " + v + ": major version " + std::to_string(*major) +
                      " is not supported (this program reads " + std::to_string(supported_major_) + ".x)");
          }
        } else if (dtype[0] == 'u') {
          const auto v = read_num_attr<std::uint64_t>(loc, where, name, H5T_NATIVE_UINT64);
          attr_values_[where + name] = v;
          if (a.contains("value") && v != a.at("value").get<std::uint64_t>())
            problem(label + " is " + std::to_string(v) + ", expected " + a.at("value").dump());
          if (a.contains("defines_dim")) bind(a.at("defines_dim"), v, label, "is");
          if (a.contains("codes") &&
              !schema_.at("codes").at(a.at("codes").get<std::string>()).at("values").contains(std::to_string(v)))
            problem(label + " is " + std::to_string(v) + ", not in the code table " + a.at("codes").get<std::string>());
        } else {
          const auto v = read_num_attr<double>(loc, where, name, H5T_NATIVE_DOUBLE);
          if (!std::isfinite(v)) problem(label + " is not finite");
        }
      } catch (const std::exception& e) {
        problem(label + ": " + e.what());
      }
    }
  }
  std::map<std::string, std::uint64_t> attr_values_;
  std::string file_version_;  // the file's schema_version

  // MAJOR.MINOR.PATCH as a comparable triple (zeros when unparsable).
  static std::array<int, 3> version_triple(const std::string& v) {
    std::array<int, 3> t{0, 0, 0};
    std::sscanf(v.c_str(), "%d.%d.%d", &t[0], &t[1], &t[2]);
    return t;
  }

  void check_group(const nlohmann::json& g) {
    const std::string name = g.at("name");
    const std::string gpath = "/" + name;
    if (!has_link(file_.id(), name)) {
      if (!g.value("optional", false)) problem(gpath + ": group missing");
      return;
    }
    Handle gid(H5Gopen2(file_.id(), name.c_str(), H5P_DEFAULT), H5Gclose);
    if (!gid.valid()) {
      problem(gpath + ": not a group (" + hdf5_error_text() + ")");
      return;
    }
    if (g.contains("attributes")) check_attributes(gid.get(), gpath, g.at("attributes"));
    for (const auto& d : g.at("datasets")) check_dataset(gid.get(), g, d);
    groups_.emplace(name, std::move(gid));
  }

  void check_dataset(hid_t gid, const nlohmann::json& g, const nlohmann::json& d) {
    const std::string name = d.at("name");
    const std::string p = path_of(g, d);
    if (!has_link(gid, name)) {
      // Added in a later minor version: files written before it lack it.
      if (d.contains("since") &&
          version_triple(file_version_) < version_triple(d.at("since").get<std::string>()))
        return;
      problem(p + ": dataset missing");
      return;
    }
    Handle ds(H5Dopen2(gid, name.c_str(), H5P_DEFAULT), H5Dclose);
    if (!ds.valid()) {
      problem(p + ": not a dataset or unreadable (" + hdf5_error_text() + ")");
      return;
    }
    Handle type(H5Dget_type(ds.get()), H5Tclose);
    if (!type.valid()) {
      problem(p + ": cannot get type");
      return;
    }
    const std::string dtype = d.at("dtype");
    if (auto m = type_mismatch(type.get(), dtype); !m.empty()) {
      problem(p + ": type is " + m + ", expected " + dtype);
      return;
    }
    std::vector<hsize_t> dims;
    try {
      dims = dataset_dims(ds.get(), p);
    } catch (const std::exception& e) {
      problem(e.what());
      return;
    }
    const auto& shape = d.at("shape");
    if (dims.size() != shape.size()) {
      problem(p + ": rank " + std::to_string(dims.size()) + ", expected " + std::to_string(shape.size()) + " (shape " +
              shape.dump() + ")");
      return;
    }
    bool ok = true;
    for (std::size_t i = 0; i < dims.size(); ++i) {
      if (shape[i].is_number()) {
        if (dims[i] != shape[i].get<hsize_t>()) {
          problem(p + ": dimension " + std::to_string(i) + " is " + std::to_string(dims[i]) + ", expected " +
                  shape[i].dump());
          ok = false;
        }
      } else {
        ok = bind(shape[i].get<std::string>(), dims[i], p, i == 0 ? "has length" : "dimension " + std::to_string(i) + " is") && ok;
      }
    }
    for (const char* attr : {"units", "description"}) {
      if (!has_attr(ds.get(), attr)) {
        problem(p + ": attribute " + std::string(attr) + " missing");
        continue;
      }
      try {
        const std::string v = read_str_attr(ds.get(), p + " ", attr);
        if (std::string(attr) == "units" && v != d.at("units").get<std::string>())
          problem(p + ": units are \"" + v + "\", expected \"" + d.at("units").get<std::string>() + "\"");
      } catch (const std::exception& e) {
        problem(p + ": " + e.what());
      }
    }
    if (ok) good_.emplace(p, std::move(ds));
  }

  void check_root_counts(const nlohmann::json& specs) {
    for (const auto& a : specs) {
      if (!a.contains("equals_dim")) continue;
      const std::string name = a.at("name");
      auto it = attr_values_.find("/" + name);
      const auto d = dim(a.at("equals_dim"));
      if (it == attr_values_.end() || !d) continue;
      if (it->second != *d)
        problem("attribute " + name + " is " + std::to_string(it->second) + " but " + a.at("equals_dim").get<std::string>() +
                " = " + std::to_string(*d) + " (from " + dims_.at(a.at("equals_dim")).second + ")");
    }
  }

  // Codes, flag bits, references and offsets of one dataset.
  void check_values(const nlohmann::json& g, const nlohmann::json& d) {
    const std::string p = path_of(g, d);
    const hid_t ds = dset(p);
    if (ds < 0) return;
    const auto& codes = schema_.at("codes");
    std::set<std::uint64_t> allowed;
    std::string allowed_text;
    if (d.contains("codes")) {
      for (const auto& [k, v] : codes.at(d.at("codes").get<std::string>()).at("values").items()) {
        allowed.insert(std::stoull(k));
        allowed_text += (allowed_text.empty() ? "" : ", ") + k;
      }
    }
    std::uint64_t mask = ~std::uint64_t{0};
    if (d.contains("bits")) {
      mask = 0;
      for (const auto& [k, v] : codes.at(d.at("bits").get<std::string>()).at("bits").items())
        mask |= std::uint64_t{1} << std::stoul(k);
    }
    std::optional<hsize_t> limit;
    std::string ref;
    if (d.contains("references")) {
      ref = d.at("references");
      limit = dim(ref);
      if (!limit) return;  // the referenced table is missing: reported already
    }
    const bool offsets = d.contains("offsets");
    hid_t count_ds = H5I_INVALID_HID;
    std::string count_path, total_sym;
    if (offsets) {
      count_path = "/" + g.at("name").get<std::string>() + "/" + d.at("offsets").at("count").get<std::string>();
      total_sym = d.at("offsets").at("total");
      count_ds = dset(count_path);
      if (count_ds < 0) return;
    }
    if (allowed.empty() && mask == ~std::uint64_t{0} && !limit && !offsets) return;

    const hsize_t rows = dataset_dims(ds, p)[0];
    Tally bad_code, bad_bits, bad_ref, bad_offset;
    std::uint64_t running = 0;
    for (hsize_t start = 0; start < rows; start += kBlockRows) {
      const hsize_t n = std::min(kBlockRows, rows - start);
      const auto v = read_u64(ds, p, start, n);
      std::vector<std::uint64_t> counts;
      if (offsets) counts = read_u64(count_ds, count_path, start, n);
      for (hsize_t i = 0; i < n; ++i) {
        const std::uint64_t x = v[i];
        if (!allowed.empty() && !allowed.count(x)) bad_code.add(start + i, std::to_string(x));
        if (x & ~mask) bad_bits.add(start + i, std::to_string(x));
        if (limit && x >= *limit) bad_ref.add(start + i, std::to_string(x));
        if (offsets) {
          if (x != running)
            bad_offset.add(start + i, std::to_string(x) + ", expected " + std::to_string(running));
          running += counts[i];
        }
      }
    }
    bad_code.report(problems_, p, "not in the code table {" + allowed_text + "}");
    bad_bits.report(problems_, p, "with unknown flag bits");
    bad_ref.report(problems_, p, "not below " + ref + " = " + std::to_string(limit.value_or(0)));
    bad_offset.report(problems_, p, "not equal to the running sum of " + count_path);
    if (offsets) {
      const auto total = dim(total_sym);
      bool ok = bad_offset.count == 0;
      if (total && running != *total) {
        problem(p + ": the counts in " + count_path + " sum to " + std::to_string(running) + " but " + total_sym + " = " +
                std::to_string(*total) + " (from " + dims_.at(total_sym).second + ")");
        ok = false;
      }
      if (ok && total) offsets_ok_.insert(p);
    }
  }
};

// Rules of the channel dataset (raysweep-channels) beyond the schema.
class ChannelValidator : public Validator {
 public:
  using Validator::Validator;

 protected:
  void rules() override {
    guarded("/frames/time_s", [&] { check_times(); });
    guarded("/node_states", [&] { check_node_states(); });
    guarded("/links", [&] { check_links(); });
  }

 private:
  bool node_states_sorted_ = false;

  void check_times() {
    const hid_t ds = dset("/frames/time_s");
    if (ds < 0) return;
    const auto t = read_f64(ds, "/frames/time_s", 0, dataset_dims(ds, "/frames/time_s")[0]);
    Tally bad;
    for (std::size_t i = 0; i < t.size(); ++i) {
      if (!std::isfinite(t[i]))
        bad.add(i, "not finite");
      else if (i > 0 && t[i] < t[i - 1])
        bad.add(i, "before the previous frame");
    }
    bad.report(problems_, "/frames/time_s", "not finite or decreasing");
  }

  // Node states of a frame sorted by node.
  void check_node_states() {
    const hid_t off = dset("/frames/node_offset"), cnt = dset("/frames/node_count"), node = dset("/node_states/node");
    if (off < 0 || cnt < 0 || node < 0 || !offsets_ok_.count("/frames/node_offset")) return;
    const hsize_t f = dataset_dims(off, "/frames/node_offset")[0];
    const auto offset = read_u64(off, "/frames/node_offset", 0, f);
    const auto count = read_u64(cnt, "/frames/node_count", 0, f);
    nodes_ = read_u64(node, "/node_states/node", 0, dataset_dims(node, "/node_states/node")[0]);
    node_offset_ = offset;
    node_count_ = count;
    Tally bad;
    for (hsize_t fr = 0; fr < f; ++fr)
      for (std::uint64_t i = offset[fr] + 1; i < offset[fr] + count[fr]; ++i)
        if (nodes_[i] <= nodes_[i - 1]) bad.add(i, "frame " + std::to_string(fr) + ", node " + std::to_string(nodes_[i]));
    bad.report(problems_, "/node_states/node", "not strictly sorted by node within their frame");
    node_states_sorted_ = bad.count == 0;
  }
  std::vector<std::uint64_t> nodes_, node_offset_, node_count_;

  bool node_present(std::uint64_t frame, std::uint64_t node) const {
    const auto b = nodes_.begin() + static_cast<std::ptrdiff_t>(node_offset_[frame]);
    const auto e = b + static_cast<std::ptrdiff_t>(node_count_[frame]);
    return std::binary_search(b, e, node);
  }

  void check_links() {
    const hid_t tx = dset("/links/tx"), rx = dset("/links/rx");
    if (tx < 0 || rx < 0) return;
    const hid_t fr = dset("/links/frame"), flags = dset("/links/flags"), pc = dset("/links/path_count");
    const hid_t gc = dset("/links/gain_coherent_db"), gi = dset("/links/gain_incoherent_db");
    const hid_t loff = dset("/frames/link_offset"), lcnt = dset("/frames/link_count");
    const bool frames_ok = fr >= 0 && loff >= 0 && lcnt >= 0 && offsets_ok_.count("/frames/link_offset");
    const bool presence = frames_ok && node_states_sorted_ && node_offset_.size() == dim("F").value_or(~hsize_t{0});
    std::vector<std::uint64_t> link_offset, link_count;
    if (frames_ok) {
      const hsize_t f = dataset_dims(loff, "/frames/link_offset")[0];
      link_offset = read_u64(loff, "/frames/link_offset", 0, f);
      link_count = read_u64(lcnt, "/frames/link_count", 0, f);
    }
    const hsize_t rows = dataset_dims(tx, "/links/tx")[0];
    Tally order, frame_bad, sorted, absent, oor_paths, no_path_gain;
    std::uint64_t f = 0;
    for (hsize_t start = 0; start < rows; start += kBlockRows) {
      const hsize_t n = std::min(kBlockRows, rows - start);
      const auto t = read_u64(tx, "/links/tx", start, n);
      const auto r = read_u64(rx, "/links/rx", start, n);
      std::vector<std::uint64_t> frame, fl, paths;
      std::vector<double> gain_c, gain_i;
      if (frames_ok) frame = read_u64(fr, "/links/frame", start, n);
      if (flags >= 0 && pc >= 0) {
        fl = read_u64(flags, "/links/flags", start, n);
        paths = read_u64(pc, "/links/path_count", start, n);
      }
      if (pc >= 0 && gc >= 0 && gi >= 0) {
        if (paths.empty()) paths = read_u64(pc, "/links/path_count", start, n);
        gain_c = read_f64(gc, "/links/gain_coherent_db", start, n);
        gain_i = read_f64(gi, "/links/gain_incoherent_db", start, n);
      }
      for (hsize_t i = 0; i < n; ++i) {
        const std::uint64_t row = start + i;
        const std::string pair = "(" + std::to_string(t[i]) + ", " + std::to_string(r[i]) + ")";
        if (t[i] >= r[i]) order.add(row, pair);
        if (frames_ok) {
          while (f < link_offset.size() && row >= link_offset[f] + link_count[f]) ++f;
          if (f < link_offset.size()) {
            if (frame[i] != f) frame_bad.add(row, "frame " + std::to_string(frame[i]) + ", expected " + std::to_string(f));
            if (row > link_offset[f] && !(prev_ < std::pair(t[i], r[i]))) sorted.add(row, pair);
            if (presence && (!node_present(f, t[i]) || !node_present(f, r[i])))
              absent.add(row, pair + " in frame " + std::to_string(f));
          }
        }
        prev_ = {t[i], r[i]};
        if (!fl.empty() && (fl[i] & 2u) && paths[i] != 0) oor_paths.add(row, std::to_string(paths[i]) + " paths");
        if (!gain_c.empty() && paths[i] == 0 && !(std::isinf(gain_c[i]) && gain_c[i] < 0 && std::isinf(gain_i[i]) && gain_i[i] < 0))
          no_path_gain.add(row, "gains " + std::to_string(gain_c[i]) + ", " + std::to_string(gain_i[i]) + " dB");
      }
    }
    order.report(problems_, "/links/tx", "with tx >= /links/rx");
    frame_bad.report(problems_, "/links/frame", "outside their frame's row range (/frames/link_offset, link_count)");
    sorted.report(problems_, "/links/tx", "not strictly sorted by (tx, rx) within their frame");
    absent.report(problems_, "/links/tx", "naming a node absent from the frame's /node_states");
    oor_paths.report(problems_, "/links/path_count", "out of range (/links/flags bit 1) but with paths");
    no_path_gain.report(problems_, "/links/gain_coherent_db", "without paths but with gains other than -inf");
  }
  std::pair<std::uint64_t, std::uint64_t> prev_{0, 0};
};

// Rules of the SINR outcome file (raysweep-sinr) beyond the schema: schedule
// order and physical sanity of the transmissions, receptions sorted and agreeing
// with their transmission, overlap rows agreeing with their reception, PRR values.
class SinrValidator : public Validator {
 public:
  using Validator::Validator;

 protected:
  void rules() override {
    guarded("/transmissions", [&] { check_transmissions(); });
    guarded("/receptions", [&] { check_receptions(); });
    guarded("/prr_links", [&] { check_prr("prr_links"); });
    guarded("/prr_rats", [&] { check_prr("prr_rats"); });
  }

 private:
  void check_transmissions() {
    const hid_t start = dset("/transmissions/start_s"), dur = dset("/transmissions/duration_s");
    const hid_t band = dset("/transmissions/band_hz"), rat = dset("/transmissions/rat");
    Tally order, duration, band_bad, rat_none;
    double prev = -std::numeric_limits<double>::infinity();
    if (start >= 0) {
      const hsize_t rows = dataset_dims(start, "/transmissions/start_s")[0];
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const auto t = read_f64(start, "/transmissions/start_s", s, std::min(kBlockRows, rows - s));
        for (std::size_t i = 0; i < t.size(); ++i) {
          if (!std::isfinite(t[i]))
            order.add(s + i, "not finite");
          else if (t[i] < prev)
            order.add(s + i, std::to_string(t[i]) + " s after " + std::to_string(prev) + " s");
          if (std::isfinite(t[i])) prev = t[i];
        }
      }
    }
    if (dur >= 0) {
      const hsize_t rows = dataset_dims(dur, "/transmissions/duration_s")[0];
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const auto d = read_f64(dur, "/transmissions/duration_s", s, std::min(kBlockRows, rows - s));
        for (std::size_t i = 0; i < d.size(); ++i)
          if (!(std::isfinite(d[i]) && d[i] > 0)) duration.add(s + i, std::to_string(d[i]) + " s");
      }
    }
    if (band >= 0) {
      const hsize_t rows = dataset_dims(band, "/transmissions/band_hz")[0];
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const hsize_t n = std::min(kBlockRows, rows - s);
        const auto b = read_rows<double>(band, "/transmissions/band_hz", H5T_NATIVE_DOUBLE, s, n, 2);
        for (hsize_t i = 0; i < n; ++i) {
          const double lo = b[2 * i], hi = b[2 * i + 1];
          if (!(std::isfinite(lo) && std::isfinite(hi) && lo < hi))
            band_bad.add(s + i, "[" + std::to_string(lo) + ", " + std::to_string(hi) + "] Hz");
        }
      }
    }
    if (rat >= 0) {
      const hsize_t rows = dataset_dims(rat, "/transmissions/rat")[0];
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const auto r = read_u64(rat, "/transmissions/rat", s, std::min(kBlockRows, rows - s));
        for (std::size_t i = 0; i < r.size(); ++i)
          if (r[i] == 0) rat_none.add(s + i, "rat 0");
      }
    }
    order.report(problems_, "/transmissions/start_s", "not finite or before the previous transmission's start");
    duration.report(problems_, "/transmissions/duration_s", "not finite and > 0");
    band_bad.report(problems_, "/transmissions/band_hz", "without finite f_lo < f_hi");
    rat_none.report(problems_, "/transmissions/rat", "of RAT none (0)");
  }

  // A column of /transmissions read as u64 or f64 for lookups by row; empty reader
  // when the dataset failed the structural checks.
  std::optional<BlockReader<std::uint64_t>> tx_u64(const std::string& name) const {
    const std::string p = "/transmissions/" + name;
    const hid_t ds = dset(p);
    if (ds < 0) return std::nullopt;
    return BlockReader<std::uint64_t>(ds, p, H5T_NATIVE_UINT64, dataset_dims(ds, p)[0]);
  }

  void check_receptions() {
    const hid_t tr = dset("/receptions/transmission"), tx = dset("/receptions/tx"), rx = dset("/receptions/rx");
    if (tr < 0) return;
    const hsize_t rows = dataset_dims(tr, "/receptions/transmission")[0];
    const hsize_t transmissions = dim("T").value_or(0);
    auto t_node = tx_u64("node"), t_rat = tx_u64("rat"), t_packet = tx_u64("packet"), t_attempt = tx_u64("attempt");
    std::optional<BlockReader<double>> t_start;
    if (const hid_t ds = dset("/transmissions/start_s"); ds >= 0)
      t_start.emplace(ds, "/transmissions/start_s", H5T_NATIVE_DOUBLE, dataset_dims(ds, "/transmissions/start_s")[0]);

    // The RAT of every transmission, for the inter_rat flag of overlaps (random access).
    std::vector<std::uint8_t> rat_of;
    if (t_rat)
      for (hsize_t i = 0; i < t_rat->rows(); ++i) rat_of.push_back(static_cast<std::uint8_t>(t_rat->at(i)));

    // Overlap rows, when their offsets passed (so every range lies inside /interferers).
    const bool overlaps = offsets_ok_.count("/receptions/overlap_offset") > 0;
    const hid_t o_tr = dset("/interferers/transmission"), o_counted = dset("/interferers/counted");
    const hid_t o_inter = dset("/interferers/inter_rat");
    std::optional<BlockReader<std::uint64_t>> ov_tr, ov_counted, ov_inter;
    const hsize_t x = dim("X").value_or(0);
    if (overlaps && o_tr >= 0) ov_tr.emplace(o_tr, "/interferers/transmission", H5T_NATIVE_UINT64, x);
    if (overlaps && o_counted >= 0) ov_counted.emplace(o_counted, "/interferers/counted", H5T_NATIVE_UINT64, x);
    if (overlaps && o_inter >= 0) ov_inter.emplace(o_inter, "/interferers/inter_rat", H5T_NATIVE_UINT64, x);

    auto column = [&](const char* name, hsize_t start, hsize_t n) {
      const std::string p = std::string("/receptions/") + name;
      const hid_t ds = dset(p);
      return ds < 0 ? std::vector<std::uint64_t>() : read_u64(ds, p, start, n);
    };
    Tally unsorted, self, tx_bad, rat_bad, packet_bad, attempt_bad, time_bad, count_bad, own, inter_bad;
    std::pair<std::uint64_t, std::uint64_t> prev{0, 0};
    for (hsize_t start = 0; start < rows; start += kBlockRows) {
      const hsize_t n = std::min(kBlockRows, rows - start);
      const auto t = read_u64(tr, "/receptions/transmission", start, n);
      const auto s = tx >= 0 ? read_u64(tx, "/receptions/tx", start, n) : std::vector<std::uint64_t>();
      const auto r = rx >= 0 ? read_u64(rx, "/receptions/rx", start, n) : std::vector<std::uint64_t>();
      const auto rat = column("rat", start, n), packet = column("packet", start, n), attempt = column("attempt", start, n);
      const auto counted = column("interferers", start, n);
      const auto ocount = overlaps ? column("overlap_count", start, n) : std::vector<std::uint64_t>();
      const auto ooffset = overlaps ? column("overlap_offset", start, n) : std::vector<std::uint64_t>();
      std::vector<double> time;
      if (const hid_t ds = dset("/receptions/time_s"); ds >= 0) time = read_f64(ds, "/receptions/time_s", start, n);
      for (hsize_t i = 0; i < n; ++i) {
        const std::uint64_t row = start + i;
        if (!r.empty()) {
          const std::pair<std::uint64_t, std::uint64_t> key{t[i], r[i]};
          if (row > 0 && !(prev < key))
            unsorted.add(row, "(" + std::to_string(t[i]) + ", " + std::to_string(r[i]) + ") after (" +
                                  std::to_string(prev.first) + ", " + std::to_string(prev.second) + ")");
          prev = key;
          if (!s.empty() && s[i] == r[i]) self.add(row, "node " + std::to_string(r[i]));
        }
        if (t[i] >= transmissions) continue;  // out of range: reported by the reference check
        auto at = [&] { return "transmission " + std::to_string(t[i]); };
        if (!s.empty() && t_node && s[i] != t_node->at(t[i]))
          tx_bad.add(row, "tx " + std::to_string(s[i]) + ", " + at() + " is sent by node " + std::to_string(t_node->at(t[i])));
        if (!rat.empty() && t_rat && rat[i] != t_rat->at(t[i]))
          rat_bad.add(row, "rat " + std::to_string(rat[i]) + ", " + at() + " has " + std::to_string(t_rat->at(t[i])));
        if (!packet.empty() && t_packet && packet[i] != t_packet->at(t[i]))
          packet_bad.add(row, "packet " + std::to_string(packet[i]) + ", " + at() + " has " + std::to_string(t_packet->at(t[i])));
        if (!attempt.empty() && t_attempt && attempt[i] != t_attempt->at(t[i]))
          attempt_bad.add(row, "attempt " + std::to_string(attempt[i]) + ", " + at() + " has " +
                                   std::to_string(t_attempt->at(t[i])));
        if (!time.empty() && t_start && !(time[i] == t_start->at(t[i])))
          time_bad.add(row, std::to_string(time[i]) + " s, " + at() + " starts at " + std::to_string(t_start->at(t[i])) + " s");
        if (!ooffset.empty() && ov_tr) {
          std::uint64_t c = 0;
          for (std::uint64_t k = ooffset[i]; k < ooffset[i] + ocount[i]; ++k) {
            const std::uint64_t other = ov_tr->at(k);
            if (other == t[i]) own.add(k, "reception row " + std::to_string(row) + " overlaps its own " + at());
            if (ov_counted && ov_counted->at(k) == 1) ++c;
            if (ov_inter && !rat.empty() && other < rat_of.size() && ov_inter->at(k) != (rat_of[other] != rat[i] ? 1u : 0u))
              inter_bad.add(k, "inter_rat " + std::to_string(ov_inter->at(k)) + " but transmission " +
                                   std::to_string(other) + " has rat " + std::to_string(rat_of[other]) +
                                   " and the reception " + std::to_string(rat[i]));
          }
          if (ov_counted && !counted.empty() && counted[i] != c)
            count_bad.add(row, std::to_string(counted[i]) + " interferers, " + std::to_string(c) + " counted overlap rows");
        }
      }
    }
    unsorted.report(problems_, "/receptions/transmission", "not strictly sorted by (transmission, rx)");
    self.report(problems_, "/receptions/rx", "equal to /receptions/tx");
    tx_bad.report(problems_, "/receptions/tx", "differing from /transmissions/node of their transmission");
    rat_bad.report(problems_, "/receptions/rat", "differing from /transmissions/rat of their transmission");
    packet_bad.report(problems_, "/receptions/packet", "differing from /transmissions/packet of their transmission");
    attempt_bad.report(problems_, "/receptions/attempt", "differing from /transmissions/attempt of their transmission");
    time_bad.report(problems_, "/receptions/time_s", "differing from /transmissions/start_s of their transmission");
    count_bad.report(problems_, "/receptions/interferers",
                     "differing from the number of their /interferers rows with counted = 1");
    own.report(problems_, "/interferers/transmission", "naming the reception's own transmission");
    inter_bad.report(problems_, "/interferers/inter_rat", "disagreeing with the RATs of the transmissions");
  }

  // received <= packets; prr = received / packets (NaN when packets = 0); links tx != rx.
  void check_prr(const std::string& group) {
    const std::string g = "/" + group + "/";
    const hid_t pk = dset(g + "packets"), rc = dset(g + "received"), pr = dset(g + "prr");
    const hid_t tx = dset(g + "tx"), rx = dset(g + "rx");
    Tally too_many, bad_prr, self;
    if (pk >= 0 && rc >= 0) {
      const hsize_t rows = dataset_dims(pk, g + "packets")[0];
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const hsize_t n = std::min(kBlockRows, rows - s);
        const auto p = read_u64(pk, g + "packets", s, n), r = read_u64(rc, g + "received", s, n);
        const auto q = pr >= 0 ? read_f64(pr, g + "prr", s, n) : std::vector<double>();
        for (hsize_t i = 0; i < n; ++i) {
          if (r[i] > p[i]) too_many.add(s + i, std::to_string(r[i]) + " received of " + std::to_string(p[i]) + " packets");
          if (q.empty()) continue;
          auto detail = [&] {
            return "prr " + std::to_string(q[i]) + " with " + std::to_string(r[i]) + " of " + std::to_string(p[i]) +
                   " packets";
          };
          if (p[i] == 0) {
            if (!std::isnan(q[i])) bad_prr.add(s + i, detail());
          } else if (!(q[i] >= 0 && q[i] <= 1) ||
                     (r[i] <= p[i] && std::abs(q[i] - static_cast<double>(r[i]) / static_cast<double>(p[i])) > 1e-6)) {
            bad_prr.add(s + i, detail());
          }
        }
      }
    }
    if (tx >= 0 && rx >= 0) {
      const hsize_t rows = dataset_dims(tx, g + "tx")[0];
      for (hsize_t s = 0; s < rows; s += kBlockRows) {
        const hsize_t n = std::min(kBlockRows, rows - s);
        const auto a = read_u64(tx, g + "tx", s, n), b = read_u64(rx, g + "rx", s, n);
        for (hsize_t i = 0; i < n; ++i)
          if (a[i] == b[i]) self.add(s + i, "node " + std::to_string(a[i]));
      }
    }
    too_many.report(problems_, g + "received", "above " + g + "packets");
    bad_prr.report(problems_, g + "prr", "not received / packets in [0, 1] (NaN when packets = 0)");
    self.report(problems_, g + "rx", "equal to " + g + "tx");
  }
};

// Rules of the ns-3 lookup table (raysweep-ns3-table) beyond the schema: the
// reader's own checks (frame times increasing, states sorted by node, pairs
// a < b strictly sorted within their frame, LoS classes, no NaN gains), run
// when the structure is sound.
class Ns3TableValidator : public Validator {
 public:
  using Validator::Validator;

 protected:
  void rules() override {
    if (!problems_.empty()) return;
    try {
      Ns3Table::load(path_);
    } catch (const meshkit::InputError& e) {
      const std::string what = e.what();
      problem(what.rfind(path_ + ": ", 0) == 0 ? what.substr(path_.size() + 2) : what);
    }
  }
};

// ---------------------------------------------------------------------------
// dataset_info helpers over the checked file. Their dataset errors keep the
// column readers' whole text after the object ("FILE: /x: /x: not an array"),
// which tests pin.

struct InfoReader {
  std::string path;
  hdf5::CheckedFile file;

  [[noreturn]] void fail(const std::string& element, const std::string& what) const { file.fail(element, what); }
  template <class F>
  auto guard(const std::string& element, F&& f) const {
    return file.guard(element, std::forward<F>(f));
  }
  bool exists(const std::string& p) const { return file.exists(p); }
  // The first dimension; a ReadError for a scalar dataset (fuzz_sinr_h5 found
  // dims.at(0) throwing std::out_of_range past guard() here).
  static hsize_t length(hid_t d, const std::string& p) {
    const auto dims = dataset_dims(d, p);
    if (dims.empty()) throw ReadError(p + ": not an array");
    return dims[0];
  }
  hsize_t rows(const std::string& p) const {
    const hdf5::Dataset d = file.dataset(p);
    return guard(p, [&] { return length(d.get(), p); });
  }
  // Calls fn(block) for consecutive blocks of an integer column.
  template <class Fn>
  void scan_u64(const std::string& p, Fn&& fn) const {
    const hdf5::Dataset d = file.dataset(p);
    guard(p, [&] {
      const hsize_t n = length(d.get(), p);
      for (hsize_t start = 0; start < n; start += kBlockRows) fn(read_u64(d.get(), p, start, std::min(kBlockRows, n - start)));
      return 0;
    });
  }
  std::string str_attr(const std::string& name, const std::string& fallback) const {
    return file.attr_if<std::string>("/", name).value_or(fallback);
  }
  // Every element of a numeric column.
  std::vector<double> all_f64(const std::string& p) const {
    const hdf5::Dataset d = file.dataset(p);
    return guard(p, [&] { return read_f64(d.get(), p, 0, length(d.get(), p)); });
  }
  std::vector<std::uint64_t> all_u64(const std::string& p) const {
    const hdf5::Dataset d = file.dataset(p);
    return guard(p, [&] { return read_u64(d.get(), p, 0, length(d.get(), p)); });
  }
  // An attribute of `object` ("/" for the root); nullopt when missing.
  template <class T>
  std::optional<T> num_attr(const std::string& object, const std::string& name) const {
    return file.attr_if<T>(object, name);
  }
};

// Nodes by kind (the node table is written by finish(): absent in an unfinished file).
void add_node_kinds(nlohmann::json& info, const InfoReader& r) {
  std::uint64_t vehicles = 0, rsus = 0, nodes = 0;
  if (r.exists("/nodes/kind"))
    r.scan_u64("/nodes/kind", [&](const std::vector<std::uint64_t>& k) {
      for (auto v : k) (v == 1 ? rsus : vehicles) += 1;
      nodes += k.size();
    });
  info["nodes"] = nodes;
  info["vehicles"] = vehicles;
  info["rsus"] = rsus;
}

std::string human_bytes(double b) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (b >= 1024 && u < 4) b /= 1024, ++u;
  char buf[64];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", b, units[u]);
  return buf;
}

// Summary of a channel dataset (format checked by the caller).
nlohmann::json channel_info(const InfoReader& r) {
  nlohmann::json info;
  info["file"] = r.path;
  info["format"] = kDatasetFormat;
  info["schema_version"] = r.str_attr("schema_version", "");
  info["raysweep_version"] = r.str_attr("raysweep_version", "");
  info["git_hash"] = r.str_attr("git_hash", "");
  info["complete"] = r.num_attr<std::uint64_t>("/", "complete").value_or(0) == 1;
  info["carrier_hz"] = r.num_attr<double>("/", "carrier_hz").value_or(0.0);
  info["bandwidth_hz"] = r.num_attr<double>("/", "bandwidth_hz").value_or(0.0);

  // Frames and their time span.
  {
    const auto t = r.all_f64("/frames/time_s");
    info["frames"] = t.size();
    info["time_start_s"] = t.empty() ? 0.0 : t.front();
    info["time_end_s"] = t.empty() ? 0.0 : t.back();
  }

  add_node_kinds(info, r);

  // Links: LoS classes, flags, paths.
  const hsize_t links = r.rows("/links/los_class");
  std::uint64_t los[3] = {0, 0, 0}, other_class = 0, cached = 0, out_of_range = 0;
  r.scan_u64("/links/los_class", [&](const std::vector<std::uint64_t>& v) {
    for (auto c : v) (c < 3 ? los[c] : other_class) += 1;
  });
  r.scan_u64("/links/flags", [&](const std::vector<std::uint64_t>& v) {
    for (auto f : v) {
      if (f & 1u) ++cached;
      if (f & 2u) ++out_of_range;
    }
  });
  const hsize_t paths = r.rows("/paths/tau_s");
  info["links"] = links;
  info["los_counts"] = {{"LOS", los[0]}, {"NLOSV", los[1]}, {"NLOS", los[2]}};
  if (other_class) info["los_counts"]["invalid"] = other_class;
  if (r.exists("/links/los_class_fresnel")) {
    std::uint64_t zone[3] = {0, 0, 0};
    r.scan_u64("/links/los_class_fresnel", [&](const std::vector<std::uint64_t>& v) {
      for (auto c : v) zone[std::min<std::uint64_t>(c, 2)] += 1;
    });
    info["los_counts_fresnel"] = {{"LOS", zone[0]}, {"NLOSV", zone[1]}, {"NLOS", zone[2]}};
  }
  info["cached_links"] = cached;
  info["out_of_range_links"] = out_of_range;
  info["paths"] = paths;
  info["interactions"] = r.rows("/interactions/type");
  info["objects"] = r.exists("/objects/name") ? r.rows("/objects/name") : 0;
  info["mean_paths_per_link"] = links ? static_cast<double>(paths) / static_cast<double>(links) : 0.0;
  const std::uint64_t in_range = links - std::min<std::uint64_t>(links, out_of_range);
  info["mean_paths_per_in_range_link"] = in_range ? static_cast<double>(paths) / static_cast<double>(in_range) : 0.0;

  // Frequency responses.
  const bool has_cfr = r.exists("/cfr");
  info["has_cfr"] = has_cfr;
  std::uint64_t subcarriers = 0;
  if (has_cfr) {
    r.file.group("/cfr");
    subcarriers = r.num_attr<std::uint64_t>("/cfr", "subcarriers").value_or(0);
  }
  info["subcarriers"] = subcarriers;
  // Shard files of a split sweep say which part of it they hold.
  if (r.file.has_attr("/", "shard")) {
    const std::string text = r.str_attr("shard", "");
    if (nlohmann::json::accept(text)) info["shard"] = nlohmann::json::parse(text);
  }

  add_file_size(info, r.path, links, "bytes_per_link");
  return info;
}


// The first lines of both formats' summaries: file, completeness, format and writer.
std::string identity_lines(const nlohmann::json& info) {
  auto text = [&](const char* k) { return info.value(k, std::string()); };
  return "file          " + text("file") + (info.value("complete", false) ? "" : "  (INCOMPLETE: writer did not finish)") +
         "\nformat        " + text("format") + " " + text("schema_version") + ", written by raysweep " +
         text("raysweep_version") + " (" + text("git_hash") + ")\n";
}

std::string format_channel_info(const nlohmann::json& info) {
  auto num = [&](const char* k) { return info.value(k, nlohmann::json(0)).get<std::uint64_t>(); };
  auto real = [&](const char* k) { return info.value(k, nlohmann::json(0.0)).get<double>(); };
  std::ostringstream o;
  char buf[256];
  o << identity_lines(info);
  std::snprintf(buf, sizeof buf, "frames        %llu (%.3f s .. %.3f s)\n", static_cast<unsigned long long>(num("frames")),
                real("time_start_s"), real("time_end_s"));
  o << buf;
  o << "nodes         " << num("nodes") << " (" << num("vehicles") << " vehicles, " << num("rsus") << " RSUs)\n";
  const std::uint64_t links = num("links");
  o << "links         " << links << " pair-frames (" << num("cached_links") << " cached, " << num("out_of_range_links")
    << " out of range)\n";
  o << "LoS classes  ";
  if (info.contains("los_counts")) {
    for (const char* c : {"LOS", "NLOSV", "NLOS"}) {
      const auto n = info["los_counts"].value(c, std::uint64_t{0});
      std::snprintf(buf, sizeof buf, " %s %llu (%.1f %%)", c, static_cast<unsigned long long>(n),
                    links ? 100.0 * static_cast<double>(n) / static_cast<double>(links) : 0.0);
      o << buf;
    }
  }
  o << "\n";
  if (info.contains("los_counts_fresnel")) {
    o << "Fresnel zone ";
    for (const char* c : {"LOS", "NLOSV", "NLOS"}) {
      const auto n = info["los_counts_fresnel"].value(c, std::uint64_t{0});
      std::snprintf(buf, sizeof buf, " %s %llu (%.1f %%)", c, static_cast<unsigned long long>(n),
                    links ? 100.0 * static_cast<double>(n) / static_cast<double>(links) : 0.0);
      o << buf;
    }
    o << "  (0.6 F1)\n";
  }
  std::snprintf(buf, sizeof buf, "paths         %llu (%.2f per link, %.2f per in-range link)\n",
                static_cast<unsigned long long>(num("paths")), real("mean_paths_per_link"),
                real("mean_paths_per_in_range_link"));
  o << buf;
  o << "interactions  " << num("interactions") << "\n";
  o << "objects       " << num("objects") << "\n";
  std::snprintf(buf, sizeof buf, "carrier       %.6g GHz, bandwidth %.6g MHz\n", real("carrier_hz") / 1e9,
                real("bandwidth_hz") / 1e6);
  o << buf;
  o << "cfr           " << (info.value("has_cfr", false) ? std::to_string(num("subcarriers")) + " subcarriers" : "none")
    << "\n";
  if (info.contains("shard") && info["shard"].is_object()) {
    const auto& sh = info["shard"];
    o << "shard         " << sh.value("index", 0) << " of " << sh.value("count", 0) << ": "
      << sh.value("blocks", nlohmann::json::array()).size() << " of the sweep's " << sh.value("blocks_total", 0)
      << " blocks (" << sh.value("frames_total", 0) << " frames); raysweep merge joins the shards\n";
  }
  std::snprintf(buf, sizeof buf, "size          %s (%llu bytes), %.1f bytes per link\n",
                human_bytes(static_cast<double>(num("file_bytes"))).c_str(),
                static_cast<unsigned long long>(num("file_bytes")), real("bytes_per_link"));
  o << buf;
  return o.str();
}


// Summary of a SINR outcome file (format checked by the caller).
nlohmann::json sinr_info(const InfoReader& r) {
  nlohmann::json info;
  info["file"] = r.path;
  info["format"] = sinr::kSinrFormat;
  info["schema_version"] = r.str_attr("schema_version", "");
  info["raysweep_version"] = r.str_attr("raysweep_version", "");
  info["git_hash"] = r.str_attr("git_hash", "");
  info["complete"] = r.num_attr<std::uint64_t>("/", "complete").value_or(0) == 1;
  info["channel_model"] = r.str_attr("channel_model", "");
  info["los_from_ray"] = r.num_attr<std::uint64_t>("/", "los_from_ray").value_or(0) != 0;
  for (const char* k :
       {"carrier_hz", "sinr_threshold_db", "sensitivity_dbm", "gain_threshold_db", "time_start_s", "time_end_s"})
    info[k] = r.num_attr<double>("/", k).value_or(0.0);

  // The node and PRR tables are written by finish(): absent in an unfinished file.
  info["nodes"] = r.exists("/nodes/id") ? r.rows("/nodes/id") : 0;
  info["transmissions"] = r.rows("/transmissions/start_s");
  info["receptions"] = r.rows("/receptions/decoded");
  info["interferers"] = r.rows("/interferers/transmission");
  std::uint64_t decoded = 0;
  r.scan_u64("/receptions/decoded", [&](const std::vector<std::uint64_t>& v) {
    for (auto d : v) decoded += d == 1 ? 1 : 0;
  });
  info["decoded"] = decoded;
  info["prr_links"] = r.exists("/prr_links/prr") ? r.rows("/prr_links/prr") : 0;

  nlohmann::json prr = nlohmann::json::object();
  if (r.exists("/prr_rats/rat")) {
    const auto rat = r.all_u64("/prr_rats/rat");
    const auto packets = r.all_u64("/prr_rats/packets");
    const auto received = r.all_u64("/prr_rats/received");
    const auto ratio = r.all_f64("/prr_rats/prr");
    if (packets.size() != rat.size() || received.size() != rat.size() || ratio.size() != rat.size())
      r.fail("/prr_rats", "datasets of different lengths");
    const auto& names = sinr_schema().at("codes").at("rat").at("values");
    for (std::size_t i = 0; i < rat.size(); ++i) {
      const std::string code = std::to_string(rat[i]);
      const std::string name = names.contains(code) ? names.at(code).get<std::string>() : "rat " + code;
      nlohmann::json entry = {{"packets", packets[i]}, {"received", received[i]}};
      entry["prr"] = std::isnan(ratio[i]) ? nlohmann::json(nullptr) : nlohmann::json(ratio[i]);
      prr[name] = entry;
    }
  }
  info["prr"] = prr;

  std::error_code ec;
  const auto bytes = std::filesystem::file_size(r.path, ec);
  info["file_bytes"] = ec ? 0 : bytes;
  return info;
}

std::string format_sinr_info(const nlohmann::json& info) {
  auto num = [&](const char* k) { return info.value(k, nlohmann::json(0)).get<std::uint64_t>(); };
  auto real = [&](const char* k) { return info.value(k, nlohmann::json(0.0)).get<double>(); };
  auto text = [&](const char* k) { return info.value(k, std::string()); };
  std::ostringstream o;
  char buf[256];
  o << identity_lines(info);
  std::snprintf(buf, sizeof buf, "channel       %s%s, carrier %.6g GHz\n", text("channel_model").c_str(),
                info.value("los_from_ray", false) ? " (LoS class from the traced links)" : "", real("carrier_hz") / 1e9);
  o << buf;
  std::snprintf(buf, sizeof buf, "decoding      SINR >= %.6g dB, sensitivity %.6g dBm, inter-RAT gain >= %.6g dB\n",
                real("sinr_threshold_db"), real("sensitivity_dbm"), real("gain_threshold_db"));
  o << buf;
  std::snprintf(buf, sizeof buf, "interval      %.3f s .. %.3f s\n", real("time_start_s"), real("time_end_s"));
  o << buf;
  o << "nodes         " << num("nodes") << "\n";
  o << "transmissions " << num("transmissions") << "\n";
  const std::uint64_t receptions = num("receptions");
  std::snprintf(buf, sizeof buf, "receptions    %llu (%llu decoded, %.1f %%)\n", static_cast<unsigned long long>(receptions),
                static_cast<unsigned long long>(num("decoded")),
                receptions ? 100.0 * static_cast<double>(num("decoded")) / static_cast<double>(receptions) : 0.0);
  o << buf;
  o << "interferers   " << num("interferers") << " overlap rows\n";
  o << "PRR links     " << num("prr_links") << "\n";
  const auto prr = info.value("prr", nlohmann::json::object());
  if (prr.empty()) o << "PRR           none\n";
  bool first = true;
  for (const auto& [name, e] : prr.items()) {
    const auto packets = e.value("packets", std::uint64_t{0}), received = e.value("received", std::uint64_t{0});
    const std::string ratio = e.contains("prr") && e.at("prr").is_number()
                                  ? (std::snprintf(buf, sizeof buf, "%.4f", e.at("prr").get<double>()), std::string(buf))
                                  : std::string("n/a");
    std::snprintf(buf, sizeof buf, "%s%-7s %s (%llu of %llu packets)\n", first ? "PRR           " : "              ",
                  name.c_str(), ratio.c_str(), static_cast<unsigned long long>(received),
                  static_cast<unsigned long long>(packets));
    o << buf;
    first = false;
  }
  std::snprintf(buf, sizeof buf, "size          %s (%llu bytes)\n", human_bytes(static_cast<double>(num("file_bytes"))).c_str(),
                static_cast<unsigned long long>(num("file_bytes")));
  o << buf;
  return o.str();
}

// Summary of an ns-3 lookup table (format checked by the caller).
nlohmann::json ns3_table_info(const InfoReader& r) {
  nlohmann::json info;
  info["file"] = r.path;
  info["format"] = kNs3TableFormat;
  info["schema_version"] = r.str_attr("schema_version", "");
  info["raysweep_version"] = r.str_attr("raysweep_version", "");
  info["git_hash"] = r.str_attr("git_hash", "");
  info["complete"] = r.num_attr<std::uint64_t>("/", "complete").value_or(0) == 1;
  for (const char* k : {"carrier_hz", "bandwidth_hz", "time_start_s", "time_end_s", "frame_step_s"})
    info[k] = r.num_attr<double>("/", k).value_or(0.0);
  const auto source = r.num_attr<std::uint64_t>("/", "gain_source").value_or(255);
  info["gain_source"] = source <= 1 ? gain_source_name(static_cast<GainSource>(source)) : "unknown";
  add_node_kinds(info, r);
  info["frames"] = r.rows("/frames/time_s");
  info["node_states"] = r.rows("/node_states/node");
  const hsize_t pairs = r.rows("/pairs/los_class");
  std::uint64_t los[3] = {0, 0, 0}, other_class = 0;
  r.scan_u64("/pairs/los_class", [&](const std::vector<std::uint64_t>& v) {
    for (auto c : v) (c < 3 ? los[c] : other_class) += 1;
  });
  info["pairs"] = pairs;
  info["los_counts"] = {{"LOS", los[0]}, {"NLOSV", los[1]}, {"NLOS", los[2]}};
  if (other_class) info["los_counts"]["invalid"] = other_class;
  std::uint64_t bands = 0;
  if (r.exists("/spectrum")) {
    r.file.group("/spectrum");
    bands = r.num_attr<std::uint64_t>("/spectrum", "band_count").value_or(0);
    info["band_width_hz"] = r.num_attr<double>("/spectrum", "band_width_hz").value_or(0.0);
  }
  info["bands"] = bands;
  add_file_size(info, r.path, pairs, "bytes_per_pair_frame");
  return info;
}

std::string format_ns3_table_info(const nlohmann::json& info) {
  auto num = [&](const char* k) { return info.value(k, nlohmann::json(0)).get<std::uint64_t>(); };
  auto real = [&](const char* k) { return info.value(k, nlohmann::json(0.0)).get<double>(); };
  std::ostringstream o;
  char buf[256];
  o << identity_lines(info);
  std::snprintf(buf, sizeof buf, "frames        %llu (%.3f s .. %.3f s, step %.3g s)\n",
                static_cast<unsigned long long>(num("frames")), real("time_start_s"), real("time_end_s"),
                real("frame_step_s"));
  o << buf;
  std::snprintf(buf, sizeof buf, "nodes         %llu (%llu vehicles, %llu RSUs), %llu node states\n",
                static_cast<unsigned long long>(num("nodes")), static_cast<unsigned long long>(num("vehicles")),
                static_cast<unsigned long long>(num("rsus")), static_cast<unsigned long long>(num("node_states")));
  o << buf;
  const double pairs = static_cast<double>(num("pairs"));
  const auto& los = info.value("los_counts", nlohmann::json::object());
  auto pct = [&](const char* k) { return pairs > 0 ? 100.0 * los.value(k, 0.0) / pairs : 0.0; };
  std::snprintf(buf, sizeof buf, "pairs         %llu pair-frames: LOS %.1f %%, NLOSV %.1f %%, NLOS %.1f %%\n",
                static_cast<unsigned long long>(num("pairs")), pct("LOS"), pct("NLOSV"), pct("NLOS"));
  o << buf;
  std::snprintf(buf, sizeof buf, "gain          wideband from %s; carrier %.6g GHz, bandwidth %.6g MHz\n",
                info.value("gain_source", std::string()).c_str(), real("carrier_hz") / 1e9, real("bandwidth_hz") / 1e6);
  o << buf;
  if (num("bands"))
    std::snprintf(buf, sizeof buf, "spectrum      %llu bands of %.6g kHz\n", static_cast<unsigned long long>(num("bands")),
                  real("band_width_hz") / 1e3);
  else
    std::snprintf(buf, sizeof buf, "spectrum      none\n");
  o << buf;
  std::snprintf(buf, sizeof buf, "size          %s (%llu bytes), %.2f bytes per pair-frame\n",
                human_bytes(static_cast<double>(num("file_bytes"))).c_str(),
                static_cast<unsigned long long>(num("file_bytes")), real("bytes_per_pair_frame"));
  o << buf;
  return o.str();
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
    ChannelValidator(file, *schema, problems).run();
  else if (format == kNs3TableFormat)
    Ns3TableValidator(file, *schema, problems).run();
  else
    SinrValidator(file, *schema, problems).run();
}

std::vector<std::string> validate_in_process(const std::string& path) {
  QuietHdf5 quiet;
  std::vector<std::string> problems;
  try {
    validate_file(path, problems);
  } catch (const std::exception& e) {
    problems.push_back(path + ": " + e.what());
  }
  H5Eclear2(H5E_DEFAULT);
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
  InfoReader r{path, hdf5::CheckedFile(path)};
  r.file.open();

  const std::string format = r.str_attr("format", "");
  if (format == kDatasetFormat) return channel_info(r);
  if (format == sinr::kSinrFormat) return sinr_info(r);
  if (format == kNs3TableFormat) return ns3_table_info(r);
  throw meshkit::InputError(path, "attribute format",
                            "not a raysweep file (format \"" + format + "\"; this program reads " + known_formats() + ")");
}

std::string format_dataset_info(const nlohmann::json& info) {
  if (info.value("format", std::string()) == sinr::kSinrFormat) return format_sinr_info(info);
  if (info.value("format", std::string()) == kNs3TableFormat) return format_ns3_table_info(info);
  return format_channel_info(info);
}

}  // namespace raysweep::generators
