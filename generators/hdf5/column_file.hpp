// The writing side of the HDF5 layer: schema-driven columns for the file
// formats of generators/ (the channel dataset, the SINR outcome file, the
// ns-3 table, the context features). A writer names a group and a dataset;
// the schema supplies its file type, shape, chunk shape, units and
// description, so the JSON file stays the single source of the layout:
// extendible chunked shuffle + deflate columns filled a chunk at a time,
// one-shot tables, virtual tables over other files, attributes, and a file
// without object time stamps (the same calls give the same bytes) whose
// `complete` attribute is written last. Files are read back through
// checked_file.hpp.
#pragma once

#include <hdf5.h>

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <vector>

#include "generators/hdf5/handle.hpp"
#include "generators/hdf5/types.hpp"

namespace raysweep::generators::hdf5 {

// What HDF5's shuffle filter makes of one chunk of `bytes` bytes (H5Zshuffle.c):
// the elements' first bytes, then their second bytes, ...; a partial element
// stays last. The column writer deflates this (bench/bench_dataset.cpp too).
std::vector<unsigned char> shuffle_bytes(const unsigned char* in, std::size_t bytes, std::size_t element);

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

// Rows [first, first + rows) of the dataset of the same path in `file`,
// which has file_rows rows.
struct VirtualSource {
  std::string file;
  hsize_t file_rows = 0, first = 0, rows = 0;
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

  // A dataset of `rows` rows whose rows are the sources' rows, one source
  // after another (virtual: the data stays in the sources' files).
  void virtual_table(const std::string& group, const std::string& name, hsize_t rows,
                     const std::vector<VirtualSource>& sources);

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

}  // namespace raysweep::generators::hdf5
