// One HDF5 file opened for reading, shared by every reader of generators/ (the
// channel dataset and its SINR loader, the SINR outcome file, the ns-3 table and
// the summaries of all three): opening with a clear error, typed attributes, and
// datasets whose type, rank and extents are checked before anything is allocated
// for them. Every error is a meshkit::InputError naming the file and the object
// (dataset, group or attribute), so a fuzzed or damaged file is reported where
// it is wrong rather than where a later computation trips on it.
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "generators/hdf5_columns.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators::hdf5 {

// Expected extents of a dataset, one per dimension (so also its rank); nullopt
// accepts any length.
using Extents = std::vector<std::optional<hsize_t>>;

// The native memory type of a numeric T.
template <class T>
hid_t native_type() {
  if constexpr (std::is_same_v<T, std::uint8_t>) return H5T_NATIVE_UINT8;
  else if constexpr (std::is_same_v<T, std::uint16_t>) return H5T_NATIVE_UINT16;
  else if constexpr (std::is_same_v<T, std::uint32_t>) return H5T_NATIVE_UINT32;
  else if constexpr (std::is_same_v<T, std::uint64_t>) return H5T_NATIVE_UINT64;
  else if constexpr (std::is_same_v<T, float>) return H5T_NATIVE_FLOAT;
  else if constexpr (std::is_same_v<T, double>) return H5T_NATIVE_DOUBLE;
  else static_assert(sizeof(T) == 0, "no native HDF5 type for T");
}

class CheckedFile;

// An open dataset of a CheckedFile. Its errors name the file and the dataset.
class Dataset {
 public:
  Dataset(const CheckedFile& file, std::string path, Handle id)
      : file_(&file), path_(std::move(path)), id_(std::move(id)) {}
  const std::string& path() const { return path_; }
  hid_t get() const { return id_.get(); }

  std::vector<hsize_t> dims() const;
  // The first extent; an error for a scalar.
  hsize_t rows() const;
  // The type is exactly the schema's dtype ("u8", "f64", "str", "c64", ...).
  const Dataset& expect_dtype(const std::string& dtype) const;
  // The rank is extents.size() and every fixed extent matches.
  const Dataset& expect(const Extents& extents) const;
  // [rows] when width is 1, else [rows, width]. Built without braces: clang 14
  // reads Extents{rows} inside a template as a vector of `rows` free extents.
  static Extents row_extents(hsize_t rows, hsize_t width) {
    Extents e(1, rows);
    if (width != 1) e.emplace_back(width);
    return e;
  }

  // Rows [start, start + rows) of `width` elements converted to mtype; the type
  // must convert to mtype and the selection must lie in the dataset, both checked
  // before the buffer is allocated.
  template <class T>
  std::vector<T> read(hid_t mtype, hsize_t start, hsize_t rows, hsize_t width = 1) const {
    if (rows == 0) return std::vector<T>();
    named([&] { return check_selection(get(), path_, start, rows, width); });
    check_convertible(mtype);
    return named([&] { return read_rows<T>(get(), path_, mtype, start, rows, width); });
  }
  // Every element of a dataset of extents [rows] (width 1) or [rows, width].
  template <class T>
  std::vector<T> read_all(hid_t mtype, hsize_t rows, hsize_t width = 1) const {
    expect(row_extents(rows, width));
    return read<T>(mtype, 0, rows, width);
  }
  // Every element of a one-dimensional variable-length string dataset.
  std::vector<std::string> strings() const;

  // Calls fn(first_row, block) for consecutive blocks of at most `block` rows of a
  // dataset of extents [rows] (width 1) or [rows, width] converted to mtype;
  // T = char* reads variable-length strings (reclaimed after each call).
  template <class T, class Fn>
  void scan(hid_t mtype, hsize_t rows, hsize_t width, Fn&& fn, hsize_t block = kBlockRows) const {
    expect(row_extents(rows, width));
    if (rows > 0) check_convertible(mtype);
    for (hsize_t start = 0; start < rows; start += block) {
      const hsize_t n = std::min(block, rows - start);
      std::vector<T> buf = named([&] { return read_rows<T>(get(), path_, mtype, start, n, width); });
      fn(static_cast<std::size_t>(start), buf);
      if constexpr (std::is_same_v<T, char*>) reclaim(mtype, n, width, buf.data());
    }
  }

 private:
  const CheckedFile* file_;
  std::string path_;
  Handle id_;

  void check_convertible(hid_t mtype) const;
  void reclaim(hid_t mtype, hsize_t rows, hsize_t width, void* buf) const;
  // Runs f; a ReadError of the column readers becomes an InputError naming file and dataset.
  template <class F>
  auto named(F&& f) const -> decltype(f());
};

class CheckedFile {
 public:
  explicit CheckedFile(std::string path) : path_(std::move(path)) {}
  // Its datasets point at it.
  CheckedFile(const CheckedFile&) = delete;
  CheckedFile& operator=(const CheckedFile&) = delete;

  // Opens read-only; an error when the path is not a regular file, has no HDF5
  // signature, or HDF5 cannot open it.
  void open();
  const std::string& path() const { return path_; }
  hid_t id() const { return fid_.get(); }

  // Throws InputError(file, object, what), with HDF5's most specific message when it left one.
  [[noreturn]] void fail(const std::string& object, const std::string& what) const;
  // Runs f; a ReadError of the column readers (its text starts with the object)
  // becomes InputError(file, object, the rest of its text).
  template <class F>
  auto named(const std::string& object, F&& f) const -> decltype(f());
  // The same keeping the whole text (dataset_info's messages, which name the
  // object twice: "FILE: /x: /x: not an array").
  template <class F>
  auto guard(const std::string& object, F&& f) const -> decltype(f()) {
    try {
      return f();
    } catch (const ReadError& e) {
      throw meshkit::InputError(path_, object, e.what());
    }
  }

  // Every link of the absolute path exists ("/links/tx": "/links", then "/links/tx").
  bool exists(const std::string& object) const;
  // `object` is "/" for the root.
  bool has_attr(const std::string& object, const std::string& name) const;
  // "attribute NAME" for the root, "OBJECT attribute NAME" otherwise.
  static std::string attr_label(const std::string& object, const std::string& name);

  // A scalar attribute of `object` as T (std::string or a numeric type HDF5
  // converts the attribute's type to); an error naming it when it is missing,
  // not a single value or of another kind.
  template <class T>
  T attr(const std::string& object, const std::string& name) const {
    if constexpr (std::is_same_v<T, std::string>) {
      return str_attr(object, name);
    } else {
      T v{};
      num_attr(object, name, native_type<T>(), &v);
      return v;
    }
  }
  // nullopt when the attribute is missing.
  template <class T>
  std::optional<T> attr_if(const std::string& object, const std::string& name) const {
    if (!has_attr(object, name)) return std::nullopt;
    return attr<T>(object, name);
  }

  Handle group(const std::string& p) const;
  // Opens an existing dataset ("missing dataset" otherwise).
  Dataset dataset(const std::string& p) const;

 private:
  std::string path_;
  Handle fid_;

  std::string str_attr(const std::string& object, const std::string& name) const;
  void num_attr(const std::string& object, const std::string& name, hid_t mtype, void* out) const;
};

template <class F>
auto CheckedFile::named(const std::string& object, F&& f) const -> decltype(f()) {
  try {
    return f();
  } catch (const ReadError& e) {
    // The column readers' messages start with the object, which the InputError names already.
    const std::string what = e.what(), prefix = object + ": ";
    fail(object, what.rfind(prefix, 0) == 0 ? what.substr(prefix.size()) : what);
  }
}

template <class F>
auto Dataset::named(F&& f) const -> decltype(f()) {
  return file_->named(path_, std::forward<F>(f));
}

}  // namespace raysweep::generators::hdf5
