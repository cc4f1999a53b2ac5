// The checked HDF5 file of the readers (see checked_file.hpp). Below it, the
// column readers: typed row and attribute reads that throw ReadError, whose
// text starts with the dataset or attribute; CheckedFile turns them into
// InputErrors naming the file too.
#include "generators/hdf5/checked_file.hpp"

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace raysweep::generators::hdf5 {

namespace {

// Thrown by the column readers; the message starts with the dataset or attribute.
struct ReadError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

[[noreturn]] void read_fail(const std::string& object, const std::string& what) {
  std::string msg = object + ": " + what;
  const std::string h5 = hdf5_error_text();
  if (!h5.empty()) msg += " (" + h5 + ")";
  throw ReadError(msg);
}

std::string read_str_attr(hid_t attr, const std::string& label) {
  Handle ftype(H5Aget_type(attr), H5Tclose);
  if (!ftype.valid()) read_fail(label, "cannot get type");
  if (H5Tget_class(ftype.get()) != H5T_STRING) read_fail(label, "not a string");
  // One string: H5Aread writes every element, so an array attribute overflowed
  // the one-string buffer below (ASan in tests/fuzz/fuzz_sinr_h5, fuzz_ns3_table_h5).
  Handle space(H5Aget_space(attr), H5Sclose);
  if (!space.valid() || H5Sget_simple_extent_npoints(space.get()) != 1) read_fail(label, "not a single value");
  Handle mtype(H5Tcopy(H5T_C_S1), H5Tclose);
  if (H5Tis_variable_str(ftype.get()) > 0) {
    if (!mtype.valid() || H5Tset_size(mtype.get(), H5T_VARIABLE) < 0 ||
        H5Tset_cset(mtype.get(), H5Tget_cset(ftype.get())) < 0)
      read_fail(label, "cannot make string type");
    char* p = nullptr;
    if (H5Aread(attr, mtype.get(), &p) < 0) read_fail(label, "cannot read");
    std::string s = p ? p : "";
    if (p) H5free_memory(p);
    return s;
  }
  const std::size_t size = H5Tget_size(ftype.get());
  std::string s(size + 1, '\0');
  if (!mtype.valid() || H5Tset_size(mtype.get(), size + 1) < 0 || H5Aread(attr, mtype.get(), s.data()) < 0)
    read_fail(label, "cannot read");
  s.resize(std::strlen(s.c_str()));
  return s;
}

void read_num_attr(hid_t attr, const std::string& label, hid_t mtype, void* out) {
  Handle space(H5Aget_space(attr), H5Sclose);
  if (!space.valid() || H5Sget_simple_extent_npoints(space.get()) != 1) read_fail(label, "not a single value");
  // A type HDF5 cannot convert (a string, a compound) fails H5Aread as well; this names it.
  Handle ftype(H5Aget_type(attr), H5Tclose);
  H5T_cdata_t* cdata = nullptr;
  if (!ftype.valid() || !H5Tfind(ftype.get(), mtype, &cdata))
    read_fail(label, ftype.valid() ? "type is " + describe_type(ftype.get()) + ", not a number" : "cannot get type");
  if (H5Aread(attr, mtype, out) < 0) read_fail(label, "cannot read");
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

int check_selection(hid_t dset, const std::string& name, hsize_t start, hsize_t rows, hsize_t width) {
  const auto dims = dataset_dims(dset, name);
  const int rank = static_cast<int>(dims.size());
  if (rank < 1 || rank > 2) read_fail(name, "not a one- or two-dimensional dataset");
  if (start > dims[0] || rows > dims[0] - start)
    read_fail(name, "rows " + std::to_string(start) + ".." + std::to_string(start + rows - 1) + " beyond its " +
                        std::to_string(dims[0]) + " rows");
  if ((rank == 1 && width != 1) || (rank == 2 && width > dims[1]))
    read_fail(name, std::to_string(width) + " values a row asked of a dataset of " +
                        (rank == 2 ? std::to_string(dims[1]) : std::string("1")) + " a row");
  return rank;
}

// Reads rows [start, start + rows) of a dataset (width elements per row)
// converted to mtype into `out`.
void read_rows(hid_t dset, const std::string& name, hid_t mtype, hsize_t start, hsize_t rows, hsize_t width,
               void* out) {
  const int rank = check_selection(dset, name, start, rows, width);
  Handle fspace(H5Dget_space(dset), H5Sclose);
  const hsize_t s[2] = {start, 0};
  const hsize_t c[2] = {rows, width};
  if (!fspace.valid() || H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, s, nullptr, c, nullptr) < 0)
    read_fail(name, "cannot select rows");
  Handle mspace(H5Screate_simple(rank, c, nullptr), H5Sclose);
  if (!mspace.valid() || H5Dread(dset, mtype, mspace.get(), fspace.get(), H5P_DEFAULT, out) < 0)
    read_fail(name, "cannot read rows " + std::to_string(start) + ".." + std::to_string(start + rows - 1));
}

template <class T>
std::vector<T> read_rows(hid_t dset, const std::string& name, hid_t mtype, hsize_t start, hsize_t rows) {
  if (rows == 0) return std::vector<T>();
  check_selection(dset, name, start, rows, 1);
  std::vector<T> out(static_cast<std::size_t>(rows));
  read_rows(dset, name, mtype, start, rows, 1, out.data());
  return out;
}

std::vector<std::string> read_strings(hid_t dset, const std::string& name) {
  Handle ftype(H5Dget_type(dset), H5Tclose);
  if (!ftype.valid()) read_fail(name, "cannot get type");
  if (H5Tget_class(ftype.get()) != H5T_STRING || H5Tis_variable_str(ftype.get()) <= 0)
    read_fail(name, "not a variable-length string dataset");
  Handle mtype(H5Tcopy(H5T_C_S1), H5Tclose);
  if (!mtype.valid() || H5Tset_size(mtype.get(), H5T_VARIABLE) < 0 ||
      H5Tset_cset(mtype.get(), H5Tget_cset(ftype.get())) < 0)
    read_fail(name, "cannot make string type");
  const auto dims = dataset_dims(dset, name);
  if (dims.size() != 1) read_fail(name, "not one-dimensional");
  std::vector<char*> ptrs(static_cast<std::size_t>(dims[0]), nullptr);
  std::vector<std::string> out;
  if (ptrs.empty()) return out;
  Handle space(H5Dget_space(dset), H5Sclose);
  if (!space.valid() || H5Dread(dset, mtype.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()) < 0)
    read_fail(name, "cannot read");
  out.reserve(ptrs.size());
  for (char* p : ptrs) out.emplace_back(p ? p : "");
  H5Dvlen_reclaim(mtype.get(), space.get(), H5P_DEFAULT, ptrs.data());
  return out;
}

}  // namespace

std::optional<int> major_version(const std::string& v) {
  int major = 0, minor = 0, patch = 0;
  char tail = 0;
  if (std::sscanf(v.c_str(), "%d.%d.%d%c", &major, &minor, &patch, &tail) != 3 || major < 0) return std::nullopt;
  return major;
}


namespace {

std::string extents_text(const std::vector<std::optional<hsize_t>>& e) {
  std::string s = "[";
  for (std::size_t i = 0; i < e.size(); ++i) s += (i ? ", " : "") + (e[i] ? std::to_string(*e[i]) : std::string("*"));
  return s + "]";
}

// The first dimension; a ReadError for a scalar dataset (fuzz_sinr_h5 found
// dims.at(0) throwing std::out_of_range past the summaries' guard here).
hsize_t length(hid_t d, const std::string& p) {
  const auto dims = dataset_dims(d, p);
  if (dims.empty()) throw ReadError(p + ": not an array");
  return dims[0];
}

// Runs f; a ReadError of the column readers (its text starts with the object)
// becomes InputError(file, object, the rest of its text).
template <class F>
auto named(const CheckedFile& file, const std::string& object, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const ReadError& e) {
    // The column readers' messages start with the object, which the InputError names already.
    const std::string what = e.what(), prefix = object + ": ";
    file.fail(object, what.rfind(prefix, 0) == 0 ? what.substr(prefix.size()) : what);
  }
}

// The same keeping the whole text (the summaries' messages, which name the
// object twice: "FILE: /x: /x: not an array").
template <class F>
auto guard(const CheckedFile& file, const std::string& object, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const ReadError& e) {
    throw meshkit::InputError(file.path(), object, e.what());
  }
}

}  // namespace

// ---------------------------------------------------------------------------
// CheckedFile.

void CheckedFile::open() {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path_, ec)) fail("", "no such file (or not a regular file)");
  if (H5Fis_hdf5(path_.c_str()) <= 0) fail("", "not an HDF5 file (or unreadable)");
  fid_ = Handle(H5Fopen(path_.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!fid_.valid()) fail("", "cannot open as HDF5 (truncated or corrupt?)");
}

void CheckedFile::fail(const std::string& object, const std::string& what) const {
  const std::string h5 = hdf5_error_text();
  throw meshkit::InputError(path_, object, what + (h5.empty() ? "" : " (" + h5 + ")"));
}

const Types& CheckedFile::types() const {
  if (!types_) types_.emplace(path_);
  return *types_;
}

bool CheckedFile::exists(const std::string& object) const {
  // H5Lexists fails rather than answers when an intermediate group is missing.
  for (std::size_t slash = object.find('/', 1);; slash = object.find('/', slash + 1)) {
    const htri_t r = H5Lexists(fid_.get(), object.substr(0, slash).c_str(), H5P_DEFAULT);
    H5Eclear2(H5E_DEFAULT);
    if (r <= 0) return false;
    if (slash == std::string::npos) return true;
  }
}

bool CheckedFile::has_attr(const std::string& object, const std::string& name) const {
  const htri_t r = H5Aexists_by_name(fid_.get(), object.c_str(), name.c_str(), H5P_DEFAULT);
  H5Eclear2(H5E_DEFAULT);
  return r > 0;
}

std::string CheckedFile::attr_label(const std::string& object, const std::string& name) {
  return (object.empty() || object == "/" ? "" : object + " ") + "attribute " + name;
}

std::string CheckedFile::str_attr(const std::string& object, const std::string& name) const {
  const std::string label = attr_label(object, name);
  if (!has_attr(object, name)) fail(label, "missing");
  Handle a(H5Aopen_by_name(fid_.get(), object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a.valid()) fail(label, "cannot open");
  return named(*this, label, [&] { return read_str_attr(a.get(), label); });
}

void CheckedFile::num_attr(const std::string& object, const std::string& name, Dtype t, void* out) const {
  const std::string label = attr_label(object, name);
  if (!has_attr(object, name)) fail(label, "missing");
  Handle a(H5Aopen_by_name(fid_.get(), object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a.valid()) fail(label, "cannot open");
  named(*this, label, [&] { read_num_attr(a.get(), label, types().mem(t), out); });
}

void CheckedFile::group(const std::string& p) const {
  if (!exists(p)) fail(p, "missing group");
  Handle g(H5Gopen2(fid_.get(), p.c_str(), H5P_DEFAULT), H5Gclose);
  if (!g.valid()) fail(p, "not a group");
}

Dataset CheckedFile::dataset(const std::string& p) const {
  if (!exists(p)) fail(p, "missing dataset");
  Handle d(H5Dopen2(fid_.get(), p.c_str(), H5P_DEFAULT), H5Dclose);
  if (!d.valid()) fail(p, "cannot open dataset");
  return Dataset(*this, p, std::move(d));
}

bool CheckedFile::is_group(const std::string& p, std::string* why) const {
  Handle g(H5Gopen2(fid_.get(), p.c_str(), H5P_DEFAULT), H5Gclose);
  if (!g.valid()) *why = hdf5_error_text();
  return g.valid();
}

std::optional<Dataset> CheckedFile::find_dataset(const std::string& p, std::string* why) const {
  Handle d(H5Dopen2(fid_.get(), p.c_str(), H5P_DEFAULT), H5Dclose);
  if (!d.valid()) {
    *why = hdf5_error_text();
    return std::nullopt;
  }
  return Dataset(*this, p, std::move(d));
}

std::optional<Attribute> CheckedFile::find_attr(const std::string& object, const std::string& name,
                                                std::string* why) const {
  Handle a(H5Aopen_by_name(fid_.get(), object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  Handle type(a.valid() ? H5Aget_type(a.get()) : H5I_INVALID_HID, H5Tclose);
  Handle space(a.valid() ? H5Aget_space(a.get()) : H5I_INVALID_HID, H5Sclose);
  if (!type.valid() || !space.valid()) {
    *why = hdf5_error_text();
    return std::nullopt;
  }
  return Attribute(*this, std::move(a), std::move(type), std::move(space));
}

hsize_t CheckedFile::column_rows(const std::string& p) const {
  const Dataset d = dataset(p);
  return guard(*this, p, [&] { return length(d.id_.get(), p); });
}

void CheckedFile::scan_u64(const std::string& p,
                           const std::function<void(const std::vector<std::uint64_t>&)>& fn) const {
  const Dataset d = dataset(p);
  guard(*this, p, [&] {
    const hsize_t n = length(d.id_.get(), p);
    for (hsize_t start = 0; start < n; start += kBlockRows)
      fn(read_rows<std::uint64_t>(d.id_.get(), p, H5T_NATIVE_UINT64, start, std::min(kBlockRows, n - start)));
    return 0;
  });
}

std::vector<double> CheckedFile::all_f64(const std::string& p) const {
  const Dataset d = dataset(p);
  return guard(*this, p, [&] { return read_rows<double>(d.id_.get(), p, H5T_NATIVE_DOUBLE, 0, length(d.id_.get(), p)); });
}

std::vector<std::uint64_t> CheckedFile::all_u64(const std::string& p) const {
  const Dataset d = dataset(p);
  return guard(*this, p,
               [&] { return read_rows<std::uint64_t>(d.id_.get(), p, H5T_NATIVE_UINT64, 0, length(d.id_.get(), p)); });
}

// ---------------------------------------------------------------------------
// Dataset.

void Dataset::fail(const std::string& what) const { file_->fail(path_, what); }

std::vector<hsize_t> Dataset::dims() const {
  return named(*file_, path_, [&] { return dataset_dims(id_.get(), path_); });
}

hsize_t Dataset::rows() const {
  const auto d = dims();
  if (d.empty()) fail("not an array");
  return d[0];
}

std::optional<std::string> Dataset::type_mismatch(const std::string& dtype) const {
  Handle type(H5Dget_type(id_.get()), H5Tclose);
  if (!type.valid()) return std::nullopt;
  return hdf5::type_mismatch(type.get(), dtype);
}

const Dataset& Dataset::expect_dtype(const std::string& dtype) const {
  const auto m = type_mismatch(dtype);
  if (!m) fail("cannot get type");
  if (!m->empty()) fail("type is " + *m + ", expected " + dtype);
  return *this;
}

const Dataset& Dataset::expect(const Extents& extents) const {
  const auto d = dims();
  bool ok = d.size() == extents.size();
  for (std::size_t i = 0; ok && i < d.size(); ++i) ok = !extents[i] || *extents[i] == d[i];
  if (!ok) fail("shape is " + extents_text({d.begin(), d.end()}) + ", expected " + extents_text(extents));
  return *this;
}

void Dataset::check_convertible(Dtype t) const {
  const hid_t mtype = file_->types().mem(t);
  Handle ftype(H5Dget_type(id_.get()), H5Tclose);
  if (!ftype.valid()) fail("cannot get type");
  // H5Dread would fail on the same missing conversion path, after the buffer was allocated.
  H5T_cdata_t* cdata = nullptr;
  if (!H5Tfind(ftype.get(), mtype, &cdata))
    fail("type is " + describe_type(ftype.get()) + ", which cannot be read as " + describe_type(mtype));
}

void Dataset::check_read(Dtype t, hsize_t start, hsize_t rows, hsize_t width) const {
  named(*file_, path_, [&] { return check_selection(id_.get(), path_, start, rows, width); });
  check_convertible(t);
}

void Dataset::read_into(Dtype t, hsize_t start, hsize_t rows, hsize_t width, void* out) const {
  named(*file_, path_, [&] { read_rows(id_.get(), path_, file_->types().mem(t), start, rows, width, out); });
}

void Dataset::reclaim(hsize_t rows, hsize_t width, void* buf) const {
  const hsize_t c[2] = {rows, width};
  Handle ms(H5Screate_simple(width == 1 ? 1 : 2, c, nullptr), H5Sclose);
  if (ms.valid()) H5Dvlen_reclaim(file_->types().str(), ms.get(), H5P_DEFAULT, buf);
}

std::vector<std::string> Dataset::strings() const {
  return named(*file_, path_, [&] { return read_strings(id_.get(), path_); });
}

void Dataset::read_every_row() const {
  named(*file_, path_, [&] {
    Handle ftype(H5Dget_type(id_.get()), H5Tclose);
    if (!ftype.valid()) read_fail(path_, "cannot get type");
    const bool vlen = H5Tget_class(ftype.get()) == H5T_STRING && H5Tis_variable_str(ftype.get()) > 0;
    Handle mtype(vlen ? H5Tcopy(ftype.get()) : H5Tget_native_type(ftype.get(), H5T_DIR_ASCEND), H5Tclose);
    if (!mtype.valid()) read_fail(path_, "cannot make memory type");
    const auto dims = dataset_dims(id_.get(), path_);
    if (dims.empty() || dims.size() > 2) return;
    const hsize_t width = dims.size() == 2 ? dims[1] : 1;
    const std::size_t row_bytes = std::max<std::size_t>(1, H5Tget_size(mtype.get()) * width);
    const hsize_t block = std::max<hsize_t>(1, (hsize_t{16} << 20) / row_bytes);
    std::vector<unsigned char> buf;
    for (hsize_t start = 0; start < dims[0]; start += block) {
      const hsize_t n = std::min(block, dims[0] - start);
      buf.resize(static_cast<std::size_t>(n) * row_bytes);
      Handle fspace(H5Dget_space(id_.get()), H5Sclose);
      const hsize_t s[2] = {start, 0};
      const hsize_t c[2] = {n, width};
      const int rank = static_cast<int>(dims.size());
      if (!fspace.valid() || H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, s, nullptr, c, nullptr) < 0)
        read_fail(path_, "cannot select rows");
      Handle mspace(H5Screate_simple(rank, c, nullptr), H5Sclose);
      if (!mspace.valid() || H5Dread(id_.get(), mtype.get(), mspace.get(), fspace.get(), H5P_DEFAULT, buf.data()) < 0)
        read_fail(path_, "cannot read rows " + std::to_string(start) + ".." + std::to_string(start + n - 1) +
                             " (damaged data?)");
      if (vlen) H5Dvlen_reclaim(mtype.get(), mspace.get(), H5P_DEFAULT, buf.data());
    }
  });
}

// ---------------------------------------------------------------------------
// Attribute.

std::string Attribute::type_mismatch(const std::string& dtype) const { return hdf5::type_mismatch(type_.get(), dtype); }

bool Attribute::scalar() const { return H5Sget_simple_extent_type(space_.get()) == H5S_SCALAR; }

std::string Attribute::str(const std::string& label) const {
  return named(*file_, label, [&] { return read_str_attr(id_.get(), label); });
}

void Attribute::num(const std::string& label, Dtype t, void* out) const {
  named(*file_, label, [&] { read_num_attr(id_.get(), label, file_->types().mem(t), out); });
}

}  // namespace raysweep::generators::hdf5
