// The checked HDF5 file of the readers (see hdf5_file.hpp).
#include "generators/hdf5_file.hpp"

#include <filesystem>
#include <system_error>

namespace raysweep::generators::hdf5 {

namespace {

std::string extents_text(const std::vector<std::optional<hsize_t>>& e) {
  std::string s = "[";
  for (std::size_t i = 0; i < e.size(); ++i) s += (i ? ", " : "") + (e[i] ? std::to_string(*e[i]) : std::string("*"));
  return s + "]";
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
  return named(label, [&] { return read_str_attr(a.get(), label); });
}

void CheckedFile::num_attr(const std::string& object, const std::string& name, hid_t mtype, void* out) const {
  const std::string label = attr_label(object, name);
  if (!has_attr(object, name)) fail(label, "missing");
  Handle a(H5Aopen_by_name(fid_.get(), object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a.valid()) fail(label, "cannot open");
  named(label, [&] { read_num_attr(a.get(), label, mtype, out); });
}

Handle CheckedFile::group(const std::string& p) const {
  if (!exists(p)) fail(p, "missing group");
  Handle g(H5Gopen2(fid_.get(), p.c_str(), H5P_DEFAULT), H5Gclose);
  if (!g.valid()) fail(p, "not a group");
  return g;
}

Dataset CheckedFile::dataset(const std::string& p) const {
  if (!exists(p)) fail(p, "missing dataset");
  Handle d(H5Dopen2(fid_.get(), p.c_str(), H5P_DEFAULT), H5Dclose);
  if (!d.valid()) fail(p, "cannot open dataset");
  return Dataset(*this, p, std::move(d));
}

// ---------------------------------------------------------------------------
// Dataset.

std::vector<hsize_t> Dataset::dims() const {
  return named([&] { return dataset_dims(get(), path_); });
}

hsize_t Dataset::rows() const {
  const auto d = dims();
  if (d.empty()) file_->fail(path_, "not an array");
  return d[0];
}

const Dataset& Dataset::expect_dtype(const std::string& dtype) const {
  Handle type(H5Dget_type(get()), H5Tclose);
  if (!type.valid()) file_->fail(path_, "cannot get type");
  if (auto m = type_mismatch(type.get(), dtype); !m.empty()) file_->fail(path_, "type is " + m + ", expected " + dtype);
  return *this;
}

const Dataset& Dataset::expect(const Extents& extents) const {
  const auto d = dims();
  bool ok = d.size() == extents.size();
  for (std::size_t i = 0; ok && i < d.size(); ++i) ok = !extents[i] || *extents[i] == d[i];
  if (!ok) file_->fail(path_, "shape is " + extents_text({d.begin(), d.end()}) + ", expected " + extents_text(extents));
  return *this;
}

void Dataset::check_convertible(hid_t mtype) const {
  Handle ftype(H5Dget_type(get()), H5Tclose);
  if (!ftype.valid()) file_->fail(path_, "cannot get type");
  // H5Dread would fail on the same missing conversion path, after the buffer was allocated.
  H5T_cdata_t* cdata = nullptr;
  if (!H5Tfind(ftype.get(), mtype, &cdata))
    file_->fail(path_, "type is " + describe_type(ftype.get()) + ", which cannot be read as " + describe_type(mtype));
}

void Dataset::reclaim(hid_t mtype, hsize_t rows, hsize_t width, void* buf) const {
  const hsize_t c[2] = {rows, width};
  Handle ms(H5Screate_simple(width == 1 ? 1 : 2, c, nullptr), H5Sclose);
  if (ms.valid()) H5Dvlen_reclaim(mtype, ms.get(), H5P_DEFAULT, buf);
}

std::vector<std::string> Dataset::strings() const {
  return named([&] { return read_strings(get(), path_); });
}

}  // namespace raysweep::generators::hdf5
