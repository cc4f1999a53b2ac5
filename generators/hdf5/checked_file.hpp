// The reading side of the HDF5 layer: one HDF5 file opened for reading, used
// by every reader of generators/ (the channel dataset and its SINR loader, the
// SINR outcome file, the ns-3 table, the context features), by the schema
// validator and by the summaries of all of them: opening with a clear error,
// typed attributes, and datasets whose type, rank and extents are checked
// before anything is allocated for them. Every error is a meshkit::InputError
// naming the file and the object (dataset, group or attribute), so a fuzzed or
// damaged file is reported where it is wrong rather than where a later
// computation trips on it. The element type of a read is the C++ type read
// into (types.hpp's dtype_of).
#pragma once

#include <hdf5.h>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "generators/hdf5/handle.hpp"
#include "generators/hdf5/types.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators::hdf5 {

// Expected extents of a dataset, one per dimension (so also its rank); nullopt
// accepts any length.
using Extents = std::vector<std::optional<hsize_t>>;

inline constexpr hsize_t kBlockRows = hsize_t{1} << 18;  // rows per read while streaming a column

// MAJOR of a MAJOR.MINOR.PATCH version; nullopt when malformed.
std::optional<int> major_version(const std::string& v);

class CheckedFile;

// An open dataset of a CheckedFile. Its errors name the file and the dataset.
class Dataset {
 public:
  Dataset(const CheckedFile& file, std::string path, Handle id)
      : file_(&file), path_(std::move(path)), id_(std::move(id)) {}
  const std::string& path() const { return path_; }
  // Throws InputError(file, dataset, what).
  [[noreturn]] void fail(const std::string& what) const;

  std::vector<hsize_t> dims() const;
  // The first extent; an error for a scalar.
  hsize_t rows() const;
  // The type is exactly the schema's dtype ("u8", "f64", "str", "c64", ...).
  const Dataset& expect_dtype(const std::string& dtype) const;
  // "" when the type is the schema's dtype, else a description of it; nullopt
  // when HDF5 cannot tell the type.
  std::optional<std::string> type_mismatch(const std::string& dtype) const;
  // The rank is extents.size() and every fixed extent matches.
  const Dataset& expect(const Extents& extents) const;
  // [rows] when width is 1, else [rows, width]. Built without braces: clang 14
  // reads Extents{rows} inside a template as a vector of `rows` free extents.
  static Extents row_extents(hsize_t rows, hsize_t width) {
    Extents e(1, rows);
    if (width != 1) e.emplace_back(width);
    return e;
  }

  // Rows [start, start + rows) of `width` elements converted to T; the type
  // must convert to T and the selection must lie in the dataset, both checked
  // before the buffer is allocated.
  template <class T>
  std::vector<T> read(hsize_t start, hsize_t rows, hsize_t width = 1) const {
    if (rows == 0) return std::vector<T>();
    check_read(dtype_of<T>(), start, rows, width);
    std::vector<T> out(static_cast<std::size_t>(rows * width));
    read_into(dtype_of<T>(), start, rows, width, out.data());
    return out;
  }
  // Every element of a dataset of extents [rows] (width 1) or [rows, width].
  template <class T>
  std::vector<T> read_all(hsize_t rows, hsize_t width = 1) const {
    expect(row_extents(rows, width));
    return read<T>(0, rows, width);
  }
  // Every element of a one-dimensional variable-length string dataset.
  std::vector<std::string> strings() const;

  // Calls fn(first_row, block) for consecutive blocks of at most `block` rows of a
  // dataset of extents [rows] (width 1) or [rows, width] converted to T;
  // T = char* reads variable-length strings (reclaimed after each call).
  template <class T, class Fn>
  void scan(hsize_t rows, hsize_t width, Fn&& fn, hsize_t block = kBlockRows) const {
    expect(row_extents(rows, width));
    if (rows > 0) check_convertible(dtype_of<T>());
    for (hsize_t start = 0; start < rows; start += block) {
      const hsize_t n = std::min(block, rows - start);
      std::vector<T> buf(static_cast<std::size_t>(n * width));
      read_into(dtype_of<T>(), start, n, width, buf.data());
      fn(static_cast<std::size_t>(start), buf);
      if constexpr (std::is_same_v<T, char*>) reclaim(n, width, buf.data());
    }
  }

  // Reads every row (decompressing every chunk) and drops them, so that damaged
  // data is found even where no reader looks.
  void read_every_row() const;

 private:
  const CheckedFile* file_;
  std::string path_;
  Handle id_;

  void check_convertible(Dtype t) const;
  void check_read(Dtype t, hsize_t start, hsize_t rows, hsize_t width) const;
  void read_into(Dtype t, hsize_t start, hsize_t rows, hsize_t width, void* out) const;
  void reclaim(hsize_t rows, hsize_t width, void* buf) const;
  friend class CheckedFile;
};

// Sequential access to one column in blocks of kBlockRows: cheap when rows are
// visited in increasing order, correct (re-reading blocks) in any order.
template <class T>
class BlockReader {
 public:
  BlockReader(const Dataset& dataset, hsize_t rows) : dataset_(&dataset), rows_(rows) {}
  T at(hsize_t row) {
    if (row < start_ || row >= start_ + buf_.size()) {
      if (row >= rows_)
        dataset_->fail("row " + std::to_string(row) + " beyond its " + std::to_string(rows_) + " rows");
      start_ = row;
      buf_ = dataset_->read<T>(row, std::min(kBlockRows, rows_ - row));
    }
    return buf_[static_cast<std::size_t>(row - start_)];
  }
  hsize_t rows() const { return rows_; }

 private:
  const Dataset* dataset_;
  hsize_t rows_;
  hsize_t start_ = 0;
  std::vector<T> buf_;
};

// An open attribute of a CheckedFile (find_attr), for checks beyond its value.
class Attribute {
 public:
  Attribute(const CheckedFile& file, Handle id, Handle type, Handle space)
      : file_(&file), id_(std::move(id)), type_(std::move(type)), space_(std::move(space)) {}
  // "" when the type is the schema's dtype, else a description of it.
  std::string type_mismatch(const std::string& dtype) const;
  bool scalar() const;
  // The value, as a string or as a number HDF5 converts the type to; errors
  // name `label`.
  std::string str(const std::string& label) const;
  template <class T>
  T num(const std::string& label) const {
    T v{};
    num(label, dtype_of<T>(), &v);
    return v;
  }

 private:
  const CheckedFile* file_;
  Handle id_, type_, space_;
  void num(const std::string& label, Dtype t, void* out) const;
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

  // Throws InputError(file, object, what), with HDF5's most specific message when it left one.
  [[noreturn]] void fail(const std::string& object, const std::string& what) const;

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
      num_attr(object, name, dtype_of<T>(), &v);
      return v;
    }
  }
  // nullopt when the attribute is missing.
  template <class T>
  std::optional<T> attr_if(const std::string& object, const std::string& name) const {
    if (!has_attr(object, name)) return std::nullopt;
    return attr<T>(object, name);
  }

  // An error unless `p` is a group.
  void group(const std::string& p) const;
  // Opens an existing dataset ("missing dataset" otherwise).
  Dataset dataset(const std::string& p) const;

  // For the validator, which reports what it finds instead of stopping at it:
  // false, or nullopt, with HDF5's message in *why when `p` does not open as
  // a group, a dataset, or `object` has no attribute `name` that opens.
  bool is_group(const std::string& p, std::string* why) const;
  std::optional<Dataset> find_dataset(const std::string& p, std::string* why) const;
  std::optional<Attribute> find_attr(const std::string& object, const std::string& name, std::string* why) const;

  // For the summaries (dataset_info): numeric columns read whole, their
  // errors keeping the column readers' text after the dataset's name ("FILE:
  // /x: /x: not an array"), which tests pin. The first extent; every value;
  // fn(block) for consecutive blocks of an integer column.
  hsize_t column_rows(const std::string& p) const;
  std::vector<double> all_f64(const std::string& p) const;
  std::vector<std::uint64_t> all_u64(const std::string& p) const;
  void scan_u64(const std::string& p, const std::function<void(const std::vector<std::uint64_t>&)>& fn) const;

 private:
  friend class Dataset;
  friend class Attribute;

  std::string path_;
  Handle fid_;
  mutable std::optional<Types> types_;  // made on the first read that needs them

  const Types& types() const;
  std::string str_attr(const std::string& object, const std::string& name) const;
  void num_attr(const std::string& object, const std::string& name, Dtype t, void* out) const;
};

}  // namespace raysweep::generators::hdf5
