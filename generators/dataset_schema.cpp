// Validation and summary of channel dataset files, driven by the embedded schema
// (schemas/raysweep_dataset.schema.json): structure, types and shapes come from
// the schema's groups/datasets/attributes, codes from its code tables, offset and
// reference checks from the datasets' "offsets" and "references" entries; the
// cross-dataset rules of links (sorting, presence of nodes, flags vs paths) are
// written out below.
#include "generators/dataset_schema.hpp"

#include <hdf5.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "generators/dataset_writer.hpp"
#include "generators/hdf5_util.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators {

namespace embedded {
extern const char kDatasetSchemaJson[];  // generated from schemas/raysweep_dataset.schema.json
}

const std::string& dataset_schema_json() {
  static const std::string text(embedded::kDatasetSchemaJson);
  return text;
}

const nlohmann::json& dataset_schema() {
  static const nlohmann::json schema = nlohmann::json::parse(dataset_schema_json());
  return schema;
}

namespace {

using hdf5::Closer;
using hdf5::Handle;
using hdf5::QuietHdf5;
using hdf5::hdf5_error_text;


// Thrown by the readers below; the validator turns it into a problem.
struct ReadError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

[[noreturn]] void read_fail(const std::string& object, const std::string& what) {
  std::string msg = object + ": " + what;
  const std::string h5 = hdf5_error_text();
  if (!h5.empty()) msg += " (" + h5 + ")";
  throw ReadError(msg);
}

// ---------------------------------------------------------------------------
// Types.

// "" when the HDF5 type matches the schema dtype, else a description of the type.
std::string type_mismatch(hid_t type, const std::string& dtype) {
  const H5T_class_t cls = H5Tget_class(type);
  const std::size_t size = H5Tget_size(type);
  auto describe = [&]() -> std::string {
    switch (cls) {
      case H5T_INTEGER:
        return (H5Tget_sign(type) == H5T_SGN_NONE ? "unsigned " : "signed ") + std::to_string(8 * size) + "-bit integer";
      case H5T_FLOAT: return std::to_string(8 * size) + "-bit float";
      case H5T_STRING:
        return H5Tis_variable_str(type) > 0 ? "variable-length string" : std::to_string(size) + "-byte fixed string";
      case H5T_COMPOUND: return "compound of " + std::to_string(H5Tget_nmembers(type)) + " members";
      default: return "type class " + std::to_string(static_cast<int>(cls));
    }
  };
  bool ok = false;
  if (dtype.size() >= 2 && dtype[0] == 'u' && std::isdigit(static_cast<unsigned char>(dtype[1]))) {
    ok = cls == H5T_INTEGER && H5Tget_sign(type) == H5T_SGN_NONE && 8 * size == std::stoul(dtype.substr(1));
  } else if (dtype == "f32" || dtype == "f64") {
    ok = cls == H5T_FLOAT && 8 * size == std::stoul(dtype.substr(1));
  } else if (dtype == "str") {
    ok = cls == H5T_STRING && H5Tis_variable_str(type) > 0;
  } else if (dtype == "c64") {
    ok = cls == H5T_COMPOUND && size == 8 && H5Tget_nmembers(type) == 2;
    for (unsigned m = 0; ok && m < 2; ++m) {
      char* name = H5Tget_member_name(type, m);
      const std::string expect = m == 0 ? "r" : "i";
      ok = name && expect == name && H5Tget_member_offset(type, m) == 4 * m;
      if (name) H5free_memory(name);
      Handle mt(H5Tget_member_type(type, m), H5Tclose);
      ok = ok && mt.valid() && H5Tget_class(mt.get()) == H5T_FLOAT && H5Tget_size(mt.get()) == 4;
    }
    if (cls == H5T_COMPOUND && !ok) return "compound other than {r: f32, i: f32}";
  }
  return ok ? std::string() : describe();
}

bool has_link(hid_t loc, const std::string& name) {
  const htri_t r = H5Lexists(loc, name.c_str(), H5P_DEFAULT);
  H5Eclear2(H5E_DEFAULT);
  return r > 0;
}

bool has_attr(hid_t loc, const std::string& name) {
  const htri_t r = H5Aexists(loc, name.c_str());
  H5Eclear2(H5E_DEFAULT);
  return r > 0;
}

// Scalar attribute readers (the type has been checked; the library converts).
std::string read_str_attr(hid_t loc, const std::string& where, const std::string& name) {
  Handle attr(H5Aopen(loc, name.c_str(), H5P_DEFAULT), H5Aclose);
  if (!attr.valid()) read_fail(where + "attribute " + name, "cannot open");
  Handle ftype(H5Aget_type(attr.get()), H5Tclose);
  if (!ftype.valid()) read_fail(where + "attribute " + name, "cannot get type");
  if (H5Tget_class(ftype.get()) != H5T_STRING) read_fail(where + "attribute " + name, "not a string");
  Handle mtype(H5Tcopy(H5T_C_S1), H5Tclose);
  if (H5Tis_variable_str(ftype.get()) > 0) {
    if (!mtype.valid() || H5Tset_size(mtype.get(), H5T_VARIABLE) < 0 ||
        H5Tset_cset(mtype.get(), H5Tget_cset(ftype.get())) < 0)
      read_fail(where + "attribute " + name, "cannot make string type");
    char* p = nullptr;
    if (H5Aread(attr.get(), mtype.get(), &p) < 0) read_fail(where + "attribute " + name, "cannot read");
    std::string s = p ? p : "";
    if (p) H5free_memory(p);
    return s;
  }
  const std::size_t size = H5Tget_size(ftype.get());
  std::string s(size + 1, '\0');
  if (!mtype.valid() || H5Tset_size(mtype.get(), size + 1) < 0 ||
      H5Aread(attr.get(), mtype.get(), s.data()) < 0)
    read_fail(where + "attribute " + name, "cannot read");
  s.resize(std::strlen(s.c_str()));
  return s;
}

template <class T>
T read_num_attr(hid_t loc, const std::string& where, const std::string& name, hid_t mtype) {
  Handle attr(H5Aopen(loc, name.c_str(), H5P_DEFAULT), H5Aclose);
  if (!attr.valid()) read_fail(where + "attribute " + name, "cannot open");
  Handle space(H5Aget_space(attr.get()), H5Sclose);
  if (!space.valid() || H5Sget_simple_extent_npoints(space.get()) != 1)
    read_fail(where + "attribute " + name, "not a single value");
  T v{};
  if (H5Aread(attr.get(), mtype, &v) < 0) read_fail(where + "attribute " + name, "cannot read");
  return v;
}

std::vector<hsize_t> dataset_dims(hid_t dset, const std::string& name) {
  Handle space(H5Dget_space(dset), H5Sclose);
  if (!space.valid()) read_fail(name, "cannot get dataspace");
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0) read_fail(name, "cannot get rank");
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
  if (rank > 0 && H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr) < 0) read_fail(name, "cannot get shape");
  return dims;
}

// Reads rows [start, start + rows) of a dataset (width elements per row) converted
// to the memory type of T.
template <class T>
std::vector<T> read_rows(hid_t dset, const std::string& name, hid_t mtype, hsize_t start, hsize_t rows,
                         hsize_t width = 1) {
  std::vector<T> out(static_cast<std::size_t>(rows * width));
  if (rows == 0) return out;
  const auto dims = dataset_dims(dset, name);
  const int rank = static_cast<int>(dims.size());
  Handle fspace(H5Dget_space(dset), H5Sclose);
  const hsize_t s[2] = {start, 0};
  const hsize_t c[2] = {rows, width};
  if (!fspace.valid() || rank < 1 || rank > 2 ||
      H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, s, nullptr, c, nullptr) < 0)
    read_fail(name, "cannot select rows");
  Handle mspace(H5Screate_simple(rank, c, nullptr), H5Sclose);
  if (!mspace.valid() || H5Dread(dset, mtype, mspace.get(), fspace.get(), H5P_DEFAULT, out.data()) < 0)
    read_fail(name, "cannot read rows " + std::to_string(start) + ".." + std::to_string(start + rows - 1));
  return out;
}

std::vector<std::uint64_t> read_u64(hid_t dset, const std::string& name, hsize_t start, hsize_t rows) {
  return read_rows<std::uint64_t>(dset, name, H5T_NATIVE_UINT64, start, rows);
}
std::vector<double> read_f64(hid_t dset, const std::string& name, hsize_t start, hsize_t rows) {
  return read_rows<double>(dset, name, H5T_NATIVE_DOUBLE, start, rows);
}

constexpr hsize_t kBlockRows = hsize_t{1} << 18;  // rows per read while streaming a column

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

std::optional<int> major_version(const std::string& v) {
  int major = 0, minor = 0, patch = 0;
  char tail = 0;
  if (std::sscanf(v.c_str(), "%d.%d.%d%c", &major, &minor, &patch, &tail) != 3 || major < 0) return std::nullopt;
  return major;
}

int supported_major() { return *major_version(kDatasetSchemaVersion); }

// ---------------------------------------------------------------------------

class Validator {
 public:
  Validator(std::string path, std::vector<std::string>& problems) : path_(std::move(path)), problems_(problems) {}

  void run() {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path_, ec)) {
      problem(path_ + ": not a readable file");
      return;
    }
    if (H5Fis_hdf5(path_.c_str()) <= 0) {
      hdf5_error_text();
      problem(path_ + ": not an HDF5 file (or unreadable)");
      return;
    }
    fid_ = Handle(H5Fopen(path_.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    if (!fid_.valid()) {
      const std::string h5 = hdf5_error_text();
      problem(path_ + ": cannot open as HDF5 (truncated or corrupt?)" + (h5.empty() ? "" : ": " + h5));
      return;
    }
    const auto& schema = dataset_schema();
    check_attributes(fid_.get(), "/", schema.at("attributes"));
    for (const auto& g : schema.at("groups")) check_group(g);
    check_root_counts(schema.at("attributes"));
    for (const auto& g : schema.at("groups"))
      for (const auto& d : g.at("datasets")) guarded(path_of(g, d), [&] { check_values(g, d); });
    guarded("/frames/time_s", [&] { check_times(); });
    guarded("/node_states", [&] { check_node_states(); });
    guarded("/links", [&] { check_links(); });
    for (const auto& [p, ds] : good_) guarded(p, [&] { check_readable(p, ds.get()); });
  }

 private:
  std::string path_;
  std::vector<std::string>& problems_;
  Handle fid_;
  std::map<std::string, Handle> groups_;
  std::map<std::string, Handle> good_;                         // datasets with the right type and shape
  std::map<std::string, std::pair<hsize_t, std::string>> dims_;  // symbol -> value, where it came from
  std::set<std::string> offsets_ok_;                           // offset datasets that passed
  bool node_states_sorted_ = false;

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
          if (name == "schema_version") {
            const auto major = major_version(v);
            if (!major)
              problem(label + " \"" + v + "\" is not a MAJOR.MINOR.PATCH version");
            else if (*major != supported_major())
              problem(label + " is " + v + ": major version " + std::to_string(*major) +
                      " is not supported (this program reads " + std::to_string(supported_major()) + ".x)");
          }
        } else if (dtype[0] == 'u') {
          const auto v = read_num_attr<std::uint64_t>(loc, where, name, H5T_NATIVE_UINT64);
          attr_values_[where + name] = v;
          if (a.contains("value") && v != a.at("value").get<std::uint64_t>())
            problem(label + " is " + std::to_string(v) + ", expected " + a.at("value").dump());
          if (a.contains("defines_dim")) bind(a.at("defines_dim"), v, label, "is");
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

  void check_group(const nlohmann::json& g) {
    const std::string name = g.at("name");
    const std::string gpath = "/" + name;
    if (!has_link(fid_.get(), name)) {
      if (!g.value("optional", false)) problem(gpath + ": group missing");
      return;
    }
    Handle gid(H5Gopen2(fid_.get(), name.c_str(), H5P_DEFAULT), H5Gclose);
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
    const auto& codes = dataset_schema().at("codes");
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

// ---------------------------------------------------------------------------
// dataset_info helpers: readers that throw meshkit::InputError naming the file.

struct InfoReader {
  std::string path;
  Handle fid;

  [[noreturn]] void fail(const std::string& element, const std::string& what) const {
    const std::string h5 = hdf5_error_text();
    throw meshkit::InputError(path, element, what + (h5.empty() ? "" : " (" + h5 + ")"));
  }
  template <class F>
  auto guard(const std::string& element, F&& f) const {
    try {
      return f();
    } catch (const ReadError& e) {
      throw meshkit::InputError(path, element, e.what());
    }
  }
  Handle open(const std::string& p) const {
    const auto slash = p.find('/', 1);
    if (!has_link(fid.get(), p.substr(1, slash - 1)) || !has_link(fid.get(), p.substr(1))) fail(p, "missing dataset");
    Handle d(H5Dopen2(fid.get(), p.c_str(), H5P_DEFAULT), H5Dclose);
    if (!d.valid()) fail(p, "cannot open dataset");
    return d;
  }
  bool exists(const std::string& p) const {
    const auto slash = p.find('/', 1);
    return has_link(fid.get(), p.substr(1, slash - 1)) && (slash == std::string::npos || has_link(fid.get(), p.substr(1)));
  }
  hsize_t rows(const std::string& p) const {
    Handle d = open(p);
    return guard(p, [&] {
      const auto dims = dataset_dims(d.get(), p);
      if (dims.empty()) throw ReadError(p + ": not an array");
      return dims[0];
    });
  }
  // Calls fn(block) for consecutive blocks of an integer column.
  template <class Fn>
  void scan_u64(const std::string& p, Fn&& fn) const {
    Handle d = open(p);
    guard(p, [&] {
      const hsize_t n = dataset_dims(d.get(), p).at(0);
      for (hsize_t start = 0; start < n; start += kBlockRows) fn(read_u64(d.get(), p, start, std::min(kBlockRows, n - start)));
      return 0;
    });
  }
  std::string str_attr(const std::string& name, const std::string& fallback) const {
    if (!has_attr(fid.get(), name)) return fallback;
    return guard("attribute " + name, [&] { return read_str_attr(fid.get(), "/", name); });
  }
  template <class T>
  std::optional<T> num_attr(hid_t loc, const std::string& name, hid_t mtype) const {
    if (!has_attr(loc, name)) return std::nullopt;
    return guard("attribute " + name, [&] { return read_num_attr<T>(loc, "/", name, mtype); });
  }
};

std::string human_bytes(double b) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (b >= 1024 && u < 4) b /= 1024, ++u;
  char buf[64];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", b, units[u]);
  return buf;
}

}  // namespace

namespace {

std::vector<std::string> validate_in_process(const std::string& path) {
  QuietHdf5 quiet;
  std::vector<std::string> problems;
  try {
    Validator(path, problems).run();
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
  InfoReader r{path, {}};
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw meshkit::InputError(path, "", "not a readable file");
  if (H5Fis_hdf5(path.c_str()) <= 0) {
    hdf5_error_text();
    throw meshkit::InputError(path, "", "not an HDF5 file");
  }
  r.fid = Handle(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!r.fid.valid()) r.fail("", "cannot open as HDF5 (truncated or corrupt?)");

  nlohmann::json info;
  info["file"] = path;
  info["format"] = r.str_attr("format", "");
  if (info["format"] != kDatasetFormat)
    throw meshkit::InputError(path, "attribute format", "not a raysweep channel dataset (format \"" +
                                                             info["format"].get<std::string>() + "\")");
  info["schema_version"] = r.str_attr("schema_version", "");
  info["raysweep_version"] = r.str_attr("raysweep_version", "");
  info["git_hash"] = r.str_attr("git_hash", "");
  info["complete"] = r.num_attr<std::uint64_t>(r.fid.get(), "complete", H5T_NATIVE_UINT64).value_or(0) == 1;
  info["carrier_hz"] = r.num_attr<double>(r.fid.get(), "carrier_hz", H5T_NATIVE_DOUBLE).value_or(0.0);
  info["bandwidth_hz"] = r.num_attr<double>(r.fid.get(), "bandwidth_hz", H5T_NATIVE_DOUBLE).value_or(0.0);

  // Frames and their time span.
  {
    Handle d = r.open("/frames/time_s");
    const auto t = r.guard("/frames/time_s", [&] {
      return read_f64(d.get(), "/frames/time_s", 0, dataset_dims(d.get(), "/frames/time_s").at(0));
    });
    info["frames"] = t.size();
    info["time_start_s"] = t.empty() ? 0.0 : t.front();
    info["time_end_s"] = t.empty() ? 0.0 : t.back();
  }

  // Nodes by kind (the node table is written by finish(): absent in an unfinished file).
  std::uint64_t vehicles = 0, rsus = 0, nodes = 0;
  if (r.exists("/nodes/kind")) {
    r.scan_u64("/nodes/kind", [&](const std::vector<std::uint64_t>& k) {
      for (auto v : k) (v == 1 ? rsus : vehicles) += 1;
      nodes += k.size();
    });
  }
  info["nodes"] = nodes;
  info["vehicles"] = vehicles;
  info["rsus"] = rsus;

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
  info["cached_links"] = cached;
  info["out_of_range_links"] = out_of_range;
  info["paths"] = paths;
  info["interactions"] = r.rows("/interactions/type");
  info["objects"] = r.exists("/objects/name") ? r.rows("/objects/name") : 0;
  info["mean_paths_per_link"] = links ? static_cast<double>(paths) / static_cast<double>(links) : 0.0;
  const std::uint64_t in_range = links - std::min<std::uint64_t>(links, out_of_range);
  info["mean_paths_per_in_range_link"] = in_range ? static_cast<double>(paths) / static_cast<double>(in_range) : 0.0;

  // Frequency responses.
  const bool has_cfr = has_link(r.fid.get(), "cfr");
  info["has_cfr"] = has_cfr;
  std::uint64_t subcarriers = 0;
  if (has_cfr) {
    Handle g(H5Gopen2(r.fid.get(), "cfr", H5P_DEFAULT), H5Gclose);
    if (!g.valid()) r.fail("/cfr", "cannot open group");
    subcarriers = r.num_attr<std::uint64_t>(g.get(), "subcarriers", H5T_NATIVE_UINT64).value_or(0);
  }
  info["subcarriers"] = subcarriers;

  const auto bytes = std::filesystem::file_size(path, ec);
  info["file_bytes"] = ec ? 0 : bytes;
  info["bytes_per_link"] = links && !ec ? static_cast<double>(bytes) / static_cast<double>(links) : 0.0;
  return info;
}

std::string format_dataset_info(const nlohmann::json& info) {
  auto num = [&](const char* k) { return info.value(k, nlohmann::json(0)).get<std::uint64_t>(); };
  auto real = [&](const char* k) { return info.value(k, nlohmann::json(0.0)).get<double>(); };
  auto text = [&](const char* k) { return info.value(k, std::string()); };
  std::ostringstream o;
  char buf[256];
  o << "file          " << text("file") << (info.value("complete", false) ? "" : "  (INCOMPLETE: writer did not finish)")
    << "\n";
  o << "format        " << text("format") << " " << text("schema_version") << ", written by raysweep "
    << text("raysweep_version") << " (" << text("git_hash") << ")\n";
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
  std::snprintf(buf, sizeof buf, "size          %s (%llu bytes), %.1f bytes per link\n",
                human_bytes(static_cast<double>(num("file_bytes"))).c_str(),
                static_cast<unsigned long long>(num("file_bytes")), real("bytes_per_link"));
  o << buf;
  return o.str();
}

}  // namespace raysweep::generators
