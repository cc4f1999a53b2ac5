// Schema-driven HDF5 columns shared by the file formats of generators/ (internal):
// the channel dataset (schemas/raysweep_dataset.schema.json) and the SINR outcome
// file (schemas/raysweep_sinr.schema.json). A writer names a group and a dataset;
// the schema supplies its file type, shape, chunk shape, units and description, so
// the JSON file stays the single source of the layout. Writing: extendible chunked
// shuffle + deflate columns filled a chunk at a time, one-shot tables, attributes,
// and a file without object time stamps (the same calls give the same bytes) whose
// `complete` attribute is written last. Reading: typed row and attribute readers
// that throw ReadError naming the dataset or attribute; the readers of the file
// formats reach them through hdf5_file.hpp's CheckedFile, which names the file too.
#pragma once

#include <hdf5.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <vector>

#include "generators/hdf5_util.hpp"

namespace raysweep::generators::hdf5 {

// ---------------------------------------------------------------------------
// Writing.

// Throws std::runtime_error "HDF5 <file>: <object>: <what> (<HDF5 error>)".
[[noreturn]] void write_fail(const std::string& file, const std::string& object, const std::string& what);

enum class Dtype { u8, u16, u32, u64, f32, f64, c64, str };
Dtype parse_dtype(const std::string& s);  // schema dtype name; std::logic_error when unknown
std::size_t dtype_bytes(Dtype t);         // bytes of one element in memory

// What HDF5's shuffle filter makes of one chunk of `bytes` bytes (H5Zshuffle.c):
// the elements' first bytes, then their second bytes, ...; a partial element
// stays last. The column writer deflates this (bench/bench_dataset.cpp too).
std::vector<unsigned char> shuffle_bytes(const unsigned char* in, std::size_t bytes, std::size_t element);

// Memory and file types. Predefined types are not owned; the compound and string
// types are created once per file.
class Types {
 public:
  explicit Types(const std::string& file);
  hid_t mem(Dtype t) const;
  hid_t file(Dtype t) const;
  hid_t str() const { return str_.get(); }

 private:
  Handle c64_mem_, c64_file_, str_;
};

void write_attr(const std::string& file, hid_t loc, const std::string& where, const std::string& name, hid_t ftype,
                hid_t mtype, const void* value);
void write_str_attr(const std::string& file, const Types& types, hid_t loc, const std::string& where,
                    const std::string& name, const std::string& value);

// One extendible dataset plus the rows buffered for it.
struct Column {
  std::string name;  // "/links/tx"
  Dtype dtype = Dtype::u8;
  hid_t mem_type = H5I_INVALID_HID;
  Handle dset;
  int rank = 1;
  hsize_t width = 1;       // elements per row (second dimension, 1 for 1-D)
  hsize_t chunk_rows = 1;  // rows per chunk
  hsize_t rows_written = 0;
  std::vector<unsigned char> buf;

  std::size_t row_bytes() const { return static_cast<std::size_t>(width) * dtype_bytes(dtype); }
  hsize_t buffered_rows() const { return buf.size() / row_bytes(); }
  hsize_t total_rows() const { return rows_written + buffered_rows(); }

  // Appends one element. A value of another size than the column's elements would
  // shift every later row, so that is a programming error caught here.
  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    if (sizeof(T) != dtype_bytes(dtype)) throw std::logic_error(name + ": value size differs from the column's dtype");
    const std::size_t n = buf.size();
    buf.resize(n + sizeof(T));
    std::memcpy(buf.data() + n, &v, sizeof(T));
  }
  void reserve_rows(std::size_t rows) { buf.reserve(buf.size() + rows * row_bytes()); }

  // Writes the buffered rows: all of them, or only whole chunks (the rest stays
  // buffered, so every chunk is compressed and written exactly once).
  void flush(const std::string& file, bool all);
  void maybe_flush(const std::string& file);
};

const nlohmann::json& schema_group(const nlohmann::json& schema, const std::string& group);
const nlohmann::json& schema_dataset(const nlohmann::json& schema, const std::string& group, const std::string& name);

// An HDF5 file being written against a schema. `fixed_dims` gives the values of the
// symbolic dimensions that are not a growing first axis (the channel schema's K).
class ColumnFile {
 public:
  ColumnFile(std::string file, const nlohmann::json& schema, std::map<std::string, hsize_t> fixed_dims = {});
  ColumnFile(const ColumnFile&) = delete;
  ColumnFile& operator=(const ColumnFile&) = delete;

  // Creates (truncates) the file, without object time stamps.
  void create();

  // Rows a first-axis dimension (the schema's "L", "P", ...) will end with,
  // when the writer knows it before creating its columns (a one-frame trace):
  // their chunks are then no longer than that, rounded up to 1,024 rows,
  // instead of the schema's, so a small file does not compress mostly padding.
  void expect_rows(const std::string& dim, hsize_t rows) { expected_rows_[dim] = rows; }

  const std::string& file() const { return file_; }
  const Types& types() const { return types_; }
  hid_t root() const { return fid_.get(); }
  bool open() const { return fid_.valid(); }

  // The group, created on first use.
  hid_t group(const std::string& name);

  // Attributes checked against the schema's entry (root when group is empty):
  // the value's type must be the schema's dtype.
  void attr(const std::string& group, const std::string& name, const std::string& value);
  void attr(const std::string& group, const std::string& name, std::uint8_t value);
  void attr(const std::string& group, const std::string& name, std::uint32_t value);
  void attr(const std::string& group, const std::string& name, std::uint64_t value);
  void attr(const std::string& group, const std::string& name, double value);
  // The root attributes both formats open with: format, schema_version,
  // raysweep_version, git_hash, config, inputs, provenance (JSON text) and seed.
  void identity_attrs(const std::string& format, const std::string& schema_version,
                      const std::string& raysweep_version, const std::string& git_hash, const nlohmann::json& config,
                      const nlohmann::json& inputs, const nlohmann::json& provenance, std::uint64_t seed);

  // An extendible, chunked, compressed dataset from its schema entry; `expect` is
  // the dtype the caller writes (std::logic_error when the schema says otherwise).
  Column* column(const std::string& group, const std::string& name, Dtype expect);

  // A fixed-size contiguous dataset written in one go (`rows` rows of `data`).
  void table(const std::string& group, const std::string& name, Dtype expect, hsize_t rows, const void* data);

  void maybe_flush();  // whole chunks of the columns holding enough
  void flush_all();    // every buffered row

  // Closes datasets, groups and the file, in that order. complete = 1 is written
  // last, just before the file is closed, so a file that has it has everything.
  void close_all(bool mark_complete);
  // For writers' destructors: flushes and closes without `complete`, ignoring errors.
  void abandon() noexcept;

 private:
  std::string file_;
  const nlohmann::json& schema_;
  std::map<std::string, hsize_t> fixed_dims_;
  std::map<std::string, hsize_t> expected_rows_;
  Types types_;
  Handle fid_;
  std::unordered_map<std::string, Handle> groups_;
  std::vector<std::unique_ptr<Column>> columns_;

  // The buffered whole chunks of the chunk-aligned columns (of those holding
  // about a flush's worth when full_buffers_only), compressed in parallel;
  // with `tail`, each one's last, partial chunk as well (zero-padded).
  void write_whole_chunks(bool full_buffers_only, bool tail = false);

  hsize_t fixed_dim(const nlohmann::json& d) const;
  const nlohmann::json& attr_spec(const std::string& group, const std::string& name, const char* dtype) const;
  void dataset_attrs(hid_t dset, const std::string& where, const nlohmann::json& spec);
};

// ---------------------------------------------------------------------------
// Reading.

// Thrown by the readers; the message starts with the dataset or attribute.
struct ReadError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

[[noreturn]] void read_fail(const std::string& object, const std::string& what);

// "" when the HDF5 type matches the schema dtype, else a description of the type.
std::string type_mismatch(hid_t type, const std::string& dtype);
// "unsigned 8-bit integer", "64-bit float", "variable-length string", ...
std::string describe_type(hid_t type);

bool has_link(hid_t loc, const std::string& name);
bool has_attr(hid_t loc, const std::string& name);

// Scalar attribute readers; `where` prefixes messages ("/" or "/cfr ").
std::string read_str_attr(hid_t loc, const std::string& where, const std::string& name);
// The same of an open attribute; messages start with `label`. A string needs a
// string attribute; a number, a type HDF5 converts to mtype.
std::string read_str_attr(hid_t attr, const std::string& label);
void read_num_attr(hid_t attr, const std::string& label, hid_t mtype, void* out);

template <class T>
T read_num_attr(hid_t loc, const std::string& where, const std::string& name, hid_t mtype) {
  Handle attr(H5Aopen(loc, name.c_str(), H5P_DEFAULT), H5Aclose);
  if (!attr.valid()) read_fail(where + "attribute " + name, "cannot open");
  T v{};
  read_num_attr(attr.get(), where + "attribute " + name, mtype, &v);
  return v;
}

std::vector<hsize_t> dataset_dims(hid_t dset, const std::string& name);

// A ReadError naming the dataset unless rows [start, start + rows) of `width`
// elements lie in it; returns its rank. A row count or width taken from another
// (bad) dataset or attribute asked for 219 GB before this was checked first
// (tests/fuzz/fuzz_dataset_h5: /cfr's subcarriers).
int check_selection(hid_t dset, const std::string& name, hsize_t start, hsize_t rows, hsize_t width);

// Reads rows [start, start + rows) of a dataset (width elements per row) converted
// to the memory type of T.
template <class T>
std::vector<T> read_rows(hid_t dset, const std::string& name, hid_t mtype, hsize_t start, hsize_t rows,
                         hsize_t width = 1) {
  if (rows == 0) return std::vector<T>();
  const int rank = check_selection(dset, name, start, rows, width);
  std::vector<T> out(static_cast<std::size_t>(rows * width));
  Handle fspace(H5Dget_space(dset), H5Sclose);
  const hsize_t s[2] = {start, 0};
  const hsize_t c[2] = {rows, width};
  if (!fspace.valid() || H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, s, nullptr, c, nullptr) < 0)
    read_fail(name, "cannot select rows");
  Handle mspace(H5Screate_simple(rank, c, nullptr), H5Sclose);
  if (!mspace.valid() || H5Dread(dset, mtype, mspace.get(), fspace.get(), H5P_DEFAULT, out.data()) < 0)
    read_fail(name, "cannot read rows " + std::to_string(start) + ".." + std::to_string(start + rows - 1));
  return out;
}

std::vector<std::uint64_t> read_u64(hid_t dset, const std::string& name, hsize_t start, hsize_t rows);
std::vector<double> read_f64(hid_t dset, const std::string& name, hsize_t start, hsize_t rows);
// Every element of a variable-length string dataset.
std::vector<std::string> read_strings(hid_t dset, const std::string& name);

inline constexpr hsize_t kBlockRows = hsize_t{1} << 18;  // rows per read while streaming a column

// Sequential access to one column in blocks of kBlockRows: cheap when rows are
// visited in increasing order, correct (re-reading blocks) in any order.
template <class T>
class BlockReader {
 public:
  BlockReader(hid_t dset, std::string name, hid_t mtype, hsize_t rows)
      : dset_(dset), name_(std::move(name)), mtype_(mtype), rows_(rows) {}
  T at(hsize_t row) {
    if (row < start_ || row >= start_ + buf_.size()) {
      if (row >= rows_) read_fail(name_, "row " + std::to_string(row) + " beyond its " + std::to_string(rows_) + " rows");
      start_ = row;
      buf_ = read_rows<T>(dset_, name_, mtype_, row, std::min(kBlockRows, rows_ - row));
    }
    return buf_[static_cast<std::size_t>(row - start_)];
  }
  hsize_t rows() const { return rows_; }

 private:
  hid_t dset_;
  std::string name_;
  hid_t mtype_;
  hsize_t rows_;
  hsize_t start_ = 0;
  std::vector<T> buf_;
};

// MAJOR of a MAJOR.MINOR.PATCH version; nullopt when malformed.
std::optional<int> major_version(const std::string& v);

}  // namespace raysweep::generators::hdf5
