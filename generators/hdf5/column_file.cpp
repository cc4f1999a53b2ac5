// Schema-driven HDF5 columns (see column_file.hpp). The sequence of HDF5 calls
// made for a given sequence of requests is fixed, which together with disabled
// object time stamps is what makes the files byte-identical for identical input:
// keep it that way when changing anything here.
#include "generators/hdf5/column_file.hpp"

#include <libdeflate.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <memory>

namespace raysweep::generators::hdf5 {

namespace {

void write_attr(const std::string& file, hid_t loc, const std::string& where, const std::string& name, hid_t ftype,
                hid_t mtype, const void* value) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  if (space.get() < 0) write_fail(file, where + " attribute " + name, "cannot create dataspace");
  Handle attr(H5Acreate2(loc, name.c_str(), ftype, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (attr.get() < 0) write_fail(file, where + " attribute " + name, "cannot create");
  if (H5Awrite(attr.get(), mtype, value) < 0) write_fail(file, where + " attribute " + name, "cannot write");
  if (attr.close() < 0) write_fail(file, where + " attribute " + name, "cannot close");
}

void write_str_attr(const std::string& file, const Types& types, hid_t loc, const std::string& where,
                    const std::string& name, const std::string& value) {
  const char* p = value.c_str();
  write_attr(file, loc, where, name, types.str(), types.str(), &p);
}

}  // namespace

constexpr std::size_t kFlushBytes = std::size_t{1} << 20;  // write when a buffer holds about this much
constexpr int kDeflateLevel = 2;  // see shuffle_deflate
// Chunks handed to H5Dwrite_chunk are in the file's byte order (little endian).
constexpr bool kLittleEndian = __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__;

std::vector<unsigned char> shuffle_bytes(const unsigned char* in, std::size_t bytes, std::size_t element) {
  std::vector<unsigned char> shuffled(in, in + bytes);
  const std::size_t n = element > 1 ? bytes / element : 0;
  if (n > 1) {
    unsigned char* out = shuffled.data();
    for (std::size_t b = 0; b < element; ++b)
      for (std::size_t i = 0; i < n; ++i) *out++ = in[i * element + b];
    // (the partial element's bytes are already last)
  }
  return shuffled;
}

namespace {

// What HDF5's shuffle then deflate filters make of one chunk (H5Zshuffle.c's
// byte planes, then a zlib stream, which H5Zdeflate.c's inflate reads), so
// chunks can be compressed on every core and handed to H5Dwrite_chunk: the
// library's own filter pipeline runs on the calling thread only. Readers see
// an ordinary shuffle + deflate chunk. The stream comes from libdeflate, not
// zlib: on a ring-road sweep's columns its level 2 is 2.1 x as fast as zlib's
// level 4 and 1.2 % smaller (bench/bench_dataset.cpp); its output depends only
// on the input and the level, so files stay byte-identical for identical input
// whatever the thread count.
std::vector<unsigned char> shuffle_deflate(const unsigned char* in, std::size_t bytes, std::size_t element) {
  std::vector<unsigned char> shuffled;
  if (element > 1 && bytes / element > 1) {  // else the filter leaves the bytes as they are
    shuffled = shuffle_bytes(in, bytes, element);
    in = shuffled.data();
  }
  // A compressor per thread: allocating one per chunk costs about as much as
  // compressing a small chunk.
  struct Free {
    void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
  };
  thread_local std::unique_ptr<libdeflate_compressor, Free> compressor(libdeflate_alloc_compressor(kDeflateLevel));
  if (!compressor) throw std::runtime_error("libdeflate: cannot allocate a compressor");
  std::vector<unsigned char> z(libdeflate_zlib_compress_bound(compressor.get(), bytes));
  const std::size_t size = libdeflate_zlib_compress(compressor.get(), in, bytes, z.data(), z.size());
  if (size == 0) throw std::runtime_error("libdeflate: cannot deflate a chunk");
  z.resize(size);
  return z;
}

}  // namespace

void Column::flush(const std::string& file, bool all) {
  hsize_t rows = buffered_rows();
  if (!all) rows = rows / chunk_rows * chunk_rows;
  if (rows == 0) return;
  const hsize_t new_dims[2] = {rows_written + rows, width};
  if (H5Dset_extent(dset.get(), new_dims) < 0) write_fail(file, name, "cannot extend dataset");
  Handle fspace(H5Dget_space(dset.get()), H5Sclose);
  if (fspace.get() < 0) write_fail(file, name, "cannot get dataspace");
  const hsize_t start[2] = {rows_written, 0};
  const hsize_t count[2] = {rows, width};
  if (H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start, nullptr, count, nullptr) < 0)
    write_fail(file, name, "cannot select rows");
  Handle mspace(H5Screate_simple(rank, count, nullptr), H5Sclose);
  if (mspace.get() < 0) write_fail(file, name, "cannot create memory dataspace");
  if (H5Dwrite(dset.get(), mem_type, mspace.get(), fspace.get(), H5P_DEFAULT, buf.data()) < 0)
    write_fail(file, name, "cannot write rows");
  const std::size_t bytes = static_cast<std::size_t>(rows) * row_bytes();
  buf.erase(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(bytes));
  rows_written += rows;
}

void Column::maybe_flush(const std::string& file) {
  if (buf.size() >= kFlushBytes && buffered_rows() >= chunk_rows) flush(file, false);
}

const nlohmann::json& schema_group(const nlohmann::json& schema, const std::string& group) {
  for (const auto& g : schema.at("groups"))
    if (g.at("name") == group) return g;
  throw std::logic_error(schema.value("format", std::string("schema")) + " schema: no group " + group);
}

const nlohmann::json& schema_dataset(const nlohmann::json& schema, const std::string& group, const std::string& name) {
  for (const auto& d : schema_group(schema, group).at("datasets"))
    if (d.at("name") == name) return d;
  throw std::logic_error(schema.value("format", std::string("schema")) + " schema: no dataset /" + group + "/" + name);
}

ColumnFile::ColumnFile(std::string file, const nlohmann::json& schema, std::map<std::string, hsize_t> fixed_dims)
    : file_(std::move(file)), schema_(schema), fixed_dims_(std::move(fixed_dims)), types_(file_) {}

void ColumnFile::create() {
  Handle fcpl(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
  // The root group has no time stamps either (file creation lists are group creation lists).
  if (fcpl.get() < 0 || H5Pset_obj_track_times(fcpl.get(), 0) < 0) write_fail(file_, "/", "cannot set file properties");
  fid_ = Handle(H5Fcreate(file_.c_str(), H5F_ACC_TRUNC, fcpl.get(), H5P_DEFAULT), H5Fclose);
  if (fid_.get() < 0) write_fail(file_, "/", "cannot create file");
}

hid_t ColumnFile::group(const std::string& name) {
  auto it = groups_.find(name);
  if (it != groups_.end()) return it->second.get();
  Handle gcpl(H5Pcreate(H5P_GROUP_CREATE), H5Pclose);
  if (gcpl.get() < 0 || H5Pset_obj_track_times(gcpl.get(), 0) < 0)
    write_fail(file_, "/" + name, "cannot set group properties");
  Handle g(H5Gcreate2(fid_.get(), ("/" + name).c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose);
  if (g.get() < 0) write_fail(file_, "/" + name, "cannot create group");
  const hid_t id = g.get();
  groups_.emplace(name, std::move(g));
  return id;
}

const nlohmann::json& ColumnFile::attr_spec(const std::string& group, const std::string& name, const char* dtype) const {
  const auto& list = group.empty() ? schema_.at("attributes") : schema_group(schema_, group).at("attributes");
  for (const auto& a : list) {
    if (a.at("name") != name) continue;
    if (a.at("dtype") != dtype)
      throw std::logic_error("schema: attribute " + group + "@" + name + " is " + a.at("dtype").get<std::string>() +
                             ", the writer writes " + dtype);
    return a;
  }
  throw std::logic_error("schema: no attribute " + group + "@" + name);
}

void ColumnFile::attr(const std::string& group, const std::string& name, const std::string& value) {
  attr_spec(group, name, "str");
  const hid_t loc = group.empty() ? fid_.get() : this->group(group);
  write_str_attr(file_, types_, loc, group.empty() ? "/" : "/" + group, name, value);
}

void ColumnFile::attr(const std::string& group, const std::string& name, std::uint8_t value) {
  attr_spec(group, name, "u8");
  const hid_t loc = group.empty() ? fid_.get() : this->group(group);
  write_attr(file_, loc, group.empty() ? "/" : "/" + group, name, H5T_STD_U8LE, H5T_NATIVE_UINT8, &value);
}

void ColumnFile::attr(const std::string& group, const std::string& name, std::uint32_t value) {
  attr_spec(group, name, "u32");
  const hid_t loc = group.empty() ? fid_.get() : this->group(group);
  write_attr(file_, loc, group.empty() ? "/" : "/" + group, name, H5T_STD_U32LE, H5T_NATIVE_UINT32, &value);
}

void ColumnFile::attr(const std::string& group, const std::string& name, std::uint64_t value) {
  attr_spec(group, name, "u64");
  const hid_t loc = group.empty() ? fid_.get() : this->group(group);
  write_attr(file_, loc, group.empty() ? "/" : "/" + group, name, H5T_STD_U64LE, H5T_NATIVE_UINT64, &value);
}

void ColumnFile::attr(const std::string& group, const std::string& name, double value) {
  attr_spec(group, name, "f64");
  const hid_t loc = group.empty() ? fid_.get() : this->group(group);
  write_attr(file_, loc, group.empty() ? "/" : "/" + group, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value);
}

void ColumnFile::dataset_attrs(hid_t dset, const std::string& where, const nlohmann::json& spec) {
  write_str_attr(file_, types_, dset, where, "units", spec.at("units").get<std::string>());
  write_str_attr(file_, types_, dset, where, "description", spec.at("description").get<std::string>());
}

// A number, or a symbol given in fixed_dims; other symbols are the growing first axis.
hsize_t ColumnFile::fixed_dim(const nlohmann::json& d) const {
  if (d.is_number_unsigned()) return d.get<hsize_t>();
  if (d.is_string()) {
    auto it = fixed_dims_.find(d.get<std::string>());
    if (it != fixed_dims_.end()) return it->second;
  }
  throw std::logic_error("schema: unexpected dimension " + d.dump());
}

Column* ColumnFile::column(const std::string& group_name, const std::string& name, Dtype expect) {
  const auto& spec = schema_dataset(schema_, group_name, name);
  auto c = std::make_unique<Column>();
  c->name = "/" + group_name + "/" + name;
  c->dtype = parse_dtype(spec.at("dtype").get<std::string>());
  if (c->dtype != expect) throw std::logic_error("schema: " + c->name + " dtype differs from the writer's");
  c->mem_type = types_.mem(c->dtype);
  const auto& shape = spec.at("shape");
  const auto& chunk = spec.at("chunk");
  if (!chunk.is_array() || shape.empty() || shape.size() > 2)
    throw std::logic_error("schema: " + c->name + " is not a chunked column of rank 1 or 2");
  c->rank = static_cast<int>(shape.size());
  if (c->rank == 2) c->width = fixed_dim(shape[1]);
  c->chunk_rows = chunk[0].get<hsize_t>();
  if (shape[0].is_string())
    if (auto it = expected_rows_.find(shape[0].get<std::string>()); it != expected_rows_.end()) {
      constexpr hsize_t kMinChunk = 1024;
      const hsize_t rounded = (it->second + kMinChunk - 1) / kMinChunk * kMinChunk;
      c->chunk_rows = std::min(c->chunk_rows, std::max(kMinChunk, rounded));
    }
  const hsize_t dims[2] = {0, c->width};
  const hsize_t maxdims[2] = {H5S_UNLIMITED, c->width};
  const hsize_t chunk_dims[2] = {c->chunk_rows, std::max<hsize_t>(1, c->width)};
  Handle space(H5Screate_simple(c->rank, dims, maxdims), H5Sclose);
  if (space.get() < 0) write_fail(file_, c->name, "cannot create dataspace");
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (dcpl.get() < 0 || H5Pset_chunk(dcpl.get(), c->rank, chunk_dims) < 0 || H5Pset_shuffle(dcpl.get()) < 0 ||
      H5Pset_deflate(dcpl.get(), kDeflateLevel) < 0 || H5Pset_obj_track_times(dcpl.get(), 0) < 0 ||
      H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_NEVER) < 0)
    write_fail(file_, c->name, "cannot set dataset creation properties");
  c->dset = Handle(H5Dcreate2(group(group_name), name.c_str(), types_.file(c->dtype), space.get(), H5P_DEFAULT,
                              dcpl.get(), H5P_DEFAULT),
                   H5Dclose);
  if (c->dset.get() < 0) write_fail(file_, c->name, "cannot create dataset");
  dataset_attrs(c->dset.get(), c->name, spec);
  columns_.push_back(std::move(c));
  return columns_.back().get();
}

void ColumnFile::table(const std::string& group_name, const std::string& name, Dtype expect, hsize_t rows,
                       const void* data) {
  const auto& spec = schema_dataset(schema_, group_name, name);
  const std::string where = "/" + group_name + "/" + name;
  const Dtype dtype = parse_dtype(spec.at("dtype").get<std::string>());
  if (dtype != expect) throw std::logic_error("schema: " + where + " dtype differs from the writer's");
  const auto& shape = spec.at("shape");
  const int rank = static_cast<int>(shape.size());
  if (rank < 1 || rank > 2) throw std::logic_error("schema: " + where + " is not of rank 1 or 2");
  const hsize_t dims[2] = {rows, rank == 2 ? fixed_dim(shape[1]) : 1};
  Handle space(H5Screate_simple(rank, dims, nullptr), H5Sclose);
  if (space.get() < 0) write_fail(file_, where, "cannot create dataspace");
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (dcpl.get() < 0 || H5Pset_obj_track_times(dcpl.get(), 0) < 0) write_fail(file_, where, "cannot set properties");
  Handle dset(H5Dcreate2(group(group_name), name.c_str(), types_.file(dtype), space.get(), H5P_DEFAULT, dcpl.get(),
                         H5P_DEFAULT),
              H5Dclose);
  if (dset.get() < 0) write_fail(file_, where, "cannot create dataset");
  // The type conversion buffer sized to the table: the library's default is a
  // MiB, allocated and cleared on every write that converts (strings), which
  // cost a one-frame file's small tables about a millisecond each.
  Handle dxpl(H5Pcreate(H5P_DATASET_XFER), H5Pclose);
  const std::size_t element = std::max(H5Tget_size(types_.file(dtype)), H5Tget_size(types_.mem(dtype)));
  if (dxpl.get() < 0 || H5Pset_buffer(dxpl.get(), std::max<hsize_t>(1, rows * dims[1]) * element, nullptr, nullptr) < 0)
    write_fail(file_, where, "cannot set transfer properties");
  if (rows > 0 && H5Dwrite(dset.get(), types_.mem(dtype), H5S_ALL, H5S_ALL, dxpl.get(), data) < 0)
    write_fail(file_, where, "cannot write");
  dataset_attrs(dset.get(), where, spec);
  if (dset.close() < 0) write_fail(file_, where, "cannot close dataset");
}

void ColumnFile::virtual_table(const std::string& group_name, const std::string& name, hsize_t rows,
                               const std::vector<VirtualSource>& sources) {
  const auto& spec = schema_dataset(schema_, group_name, name);
  const std::string where = "/" + group_name + "/" + name;
  const Dtype dtype = parse_dtype(spec.at("dtype").get<std::string>());
  const auto& shape = spec.at("shape");
  const int rank = static_cast<int>(shape.size());
  const hsize_t width = rank == 2 ? fixed_dim(shape[1]) : 1;
  const hsize_t dims[2] = {rows, width};
  Handle vspace(H5Screate_simple(rank, dims, nullptr), H5Sclose);
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (!vspace.valid() || !dcpl.valid() || H5Pset_obj_track_times(dcpl.get(), 0) < 0)
    write_fail(file_, where, "cannot set virtual dataset properties");
  hsize_t dst = 0;
  for (const auto& src : sources) {
    if (src.rows == 0) continue;
    const hsize_t src_dims[2] = {src.file_rows, width};
    Handle sspace(H5Screate_simple(rank, src_dims, nullptr), H5Sclose);
    const hsize_t s0[2] = {src.first, 0}, d0[2] = {dst, 0}, cnt[2] = {src.rows, width};
    if (!sspace.valid() || H5Sselect_hyperslab(sspace.get(), H5S_SELECT_SET, s0, nullptr, cnt, nullptr) < 0 ||
        H5Sselect_hyperslab(vspace.get(), H5S_SELECT_SET, d0, nullptr, cnt, nullptr) < 0 ||
        H5Pset_virtual(dcpl.get(), vspace.get(), src.file.c_str(), where.c_str(), sspace.get()) < 0)
      write_fail(file_, where, "cannot map rows of " + src.file);
    dst += src.rows;
  }
  H5Sselect_all(vspace.get());
  Handle dset(H5Dcreate2(group(group_name), name.c_str(), types_.file(dtype), vspace.get(), H5P_DEFAULT, dcpl.get(),
                         H5P_DEFAULT),
              H5Dclose);
  if (!dset.valid()) write_fail(file_, where, "cannot create virtual dataset");
  dataset_attrs(dset.get(), where, spec);
  if (dset.close() < 0) write_fail(file_, where, "cannot close virtual dataset");
}

void ColumnFile::write_whole_chunks(bool full_buffers_only, bool tail) {
  struct Job {
    Column* column;
    std::size_t chunk;  // index among the column's buffered chunks
    std::vector<unsigned char> z;
  };
  if (!kLittleEndian) return;  // the library's path converts
  std::vector<Job> jobs;
  for (auto& c : columns_) {
    // Strings are pointers in memory; a column that ever wrote a partial
    // chunk is no longer chunk-aligned. Both take the library's path.
    if (c->dtype == Dtype::str || c->rows_written % c->chunk_rows != 0) continue;
    if (full_buffers_only && c->buf.size() < kFlushBytes) continue;
    const hsize_t rows = c->buffered_rows();
    const hsize_t chunks = tail ? (rows + c->chunk_rows - 1) / c->chunk_rows : rows / c->chunk_rows;
    for (hsize_t k = 0; k < chunks; ++k) jobs.push_back({c.get(), static_cast<std::size_t>(k), {}});
  }
  if (jobs.empty()) return;
  // A partial chunk is stored as a whole one: the rows past the dataset's
  // extent are zeros, what the library's own path (H5Dwrite, compressed at
  // H5Dclose on one thread, half of a one-frame trace's writing) stores too.
  tbb::parallel_for(std::size_t{0}, jobs.size(), [&](std::size_t j) {
    Job& job = jobs[j];
    const Column& c = *job.column;
    const std::size_t bytes = static_cast<std::size_t>(c.chunk_rows) * c.row_bytes();
    const std::size_t from = job.chunk * bytes;
    if (from + bytes <= c.buf.size()) {
      job.z = shuffle_deflate(c.buf.data() + from, bytes, dtype_bytes(c.dtype));
    } else {
      std::vector<unsigned char> padded(bytes, 0);
      std::copy(c.buf.begin() + static_cast<std::ptrdiff_t>(from), c.buf.end(), padded.begin());
      job.z = shuffle_deflate(padded.data(), bytes, dtype_bytes(c.dtype));
    }
  });
  // Written in column then chunk order, on this thread: the same calls for the same input.
  for (std::size_t j = 0; j < jobs.size();) {
    Column& c = *jobs[j].column;
    std::size_t e = j;
    while (e < jobs.size() && jobs[e].column == &c) ++e;
    const hsize_t rows = std::min<hsize_t>(static_cast<hsize_t>(e - j) * c.chunk_rows, c.buffered_rows());
    const hsize_t new_dims[2] = {c.rows_written + rows, c.width};
    if (H5Dset_extent(c.dset.get(), new_dims) < 0) write_fail(file_, c.name, "cannot extend dataset");
    for (; j < e; ++j) {
      const hsize_t offset[2] = {c.rows_written + jobs[j].chunk * c.chunk_rows, 0};
      if (H5Dwrite_chunk(c.dset.get(), H5P_DEFAULT, 0, offset, jobs[j].z.size(), jobs[j].z.data()) < 0)
        write_fail(file_, c.name, "cannot write a chunk");
      jobs[j].z = {};
    }
    c.buf.erase(c.buf.begin(), c.buf.begin() + static_cast<std::ptrdiff_t>(rows * c.row_bytes()));
    c.rows_written += rows;
  }
}

void ColumnFile::maybe_flush() {
  write_whole_chunks(true);
  for (auto& c : columns_) c->maybe_flush(file_);
}

void ColumnFile::flush_all() {
  write_whole_chunks(false, true);
  for (auto& c : columns_) c->flush(file_, true);
}

void ColumnFile::close_all(bool mark_complete) {
  for (auto& c : columns_)
    if (c->dset.close() < 0) write_fail(file_, c->name, "cannot close dataset");
  columns_.clear();
  for (auto& [name, g] : groups_)
    if (g.close() < 0) write_fail(file_, "/" + name, "cannot close group");
  groups_.clear();
  if (mark_complete) {
    const std::uint8_t one = 1;
    write_attr(file_, fid_.get(), "/", "complete", H5T_STD_U8LE, H5T_NATIVE_UINT8, &one);
  }
  if (fid_.get() >= 0 && fid_.close() < 0) write_fail(file_, "/", "cannot close file");
}

void ColumnFile::abandon() noexcept {
  if (!open()) return;
  QuietHdf5 quiet;
  try {
    flush_all();
  } catch (...) {
  }
  try {
    close_all(false);
  } catch (...) {
  }
}

void ColumnFile::identity_attrs(const std::string& format, const std::string& schema_version,
                                const std::string& raysweep_version, const std::string& git_hash,
                                const nlohmann::json& config, const nlohmann::json& inputs,
                                const nlohmann::json& provenance, std::uint64_t seed) {
  attr("", "format", format);
  attr("", "schema_version", schema_version);
  attr("", "raysweep_version", raysweep_version);
  attr("", "git_hash", git_hash);
  attr("", "config", config.dump());
  attr("", "inputs", inputs.dump());
  attr("", "provenance", provenance.dump());
  attr("", "seed", seed);
}

}  // namespace raysweep::generators::hdf5
