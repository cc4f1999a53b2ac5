// Dataset compression benchmark: the chunks of a real sweep's dataset,
// shuffled as HDF5's shuffle filter lays them out, deflated by zlib and by
// libdeflate at several levels, on one thread. The dataset writer compresses
// its chunks this way on every core (generators/hdf5/column_file.cpp); the choice
// of compressor and level is made from these numbers (docs/performance.md,
// docs/decisions.md).
//
// Input: RAYSWEEP_BENCH_DATASET, or out/van3twin-ring/dataset.h5 under the
// source tree (`raysweep run datasets/van3twin-ring/city.toml --until sweep`),
// or out/demo/dataset.h5; skipped when none exists. At most RAYSWEEP_BENCH_MB
// (default 100) MiB of raw column bytes are used, the same share of each column.
// Counters: MB_per_s (raw bytes in, one thread), ratio (stored / raw).
#include <benchmark/benchmark.h>
#include <hdf5.h>
#include <libdeflate.h>
#include <zlib.h>

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "generators/hdf5/column_file.hpp"

namespace fs = std::filesystem;

namespace {

struct Chunks {
  std::vector<std::vector<unsigned char>> shuffled;  // one per chunk, in file order
  std::size_t raw = 0;
  std::string source;
};

fs::path input_file() {
  if (const char* e = std::getenv("RAYSWEEP_BENCH_DATASET")) return e;
  for (const char* p : {"out/van3twin-ring/dataset.h5", "out/demo/dataset.h5"}) {
    const fs::path f = fs::path(RAYSWEEP_SOURCE_DIR) / p;
    if (fs::exists(f)) return f;
  }
  return {};
}

// The chunked datasets of the file, each cut into its chunks and
// byte-shuffled by its element size. Past RAYSWEEP_BENCH_MB of raw bytes,
// every dataset contributes the same leading fraction of its rows (whole
// chunks, at least one), so the sample keeps the file's mix of columns.
const Chunks& chunks() {
  static const Chunks c = [] {
    Chunks out;
    const fs::path file = input_file();
    if (file.empty() || !fs::exists(file)) return out;
    out.source = file.string();
    const char* mb = std::getenv("RAYSWEEP_BENCH_MB");
    const double limit = (mb ? std::atof(mb) : 100.0) * 1048576.0;
    const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) return out;
    struct Column {
      std::string name;
      std::size_t element = 0, rows = 0, width = 1, chunk_rows = 0;
    };
    std::vector<Column> columns;
    H5Ovisit(
        f, H5_INDEX_NAME, H5_ITER_NATIVE,
        [](hid_t root, const char* name, const H5O_info_t* info, void* data) -> herr_t {
          if (info->type != H5O_TYPE_DATASET) return 0;
          const hid_t d = H5Dopen2(root, name, H5P_DEFAULT);
          const hid_t dcpl = H5Dget_create_plist(d), type = H5Dget_type(d), space = H5Dget_space(d);
          hsize_t dims[2] = {0, 1}, chunk[2] = {0, 1};
          const int rank = H5Sget_simple_extent_dims(space, dims, nullptr);
          if (H5Pget_layout(dcpl) == H5D_CHUNKED && H5Tget_class(type) != H5T_STRING && dims[0] > 0 &&
              H5Pget_chunk(dcpl, 2, chunk) == rank)
            static_cast<std::vector<Column>*>(data)->push_back(
                {name, H5Tget_size(type), dims[0], rank == 2 ? dims[1] : 1, chunk[0]});
          H5Sclose(space);
          H5Tclose(type);
          H5Pclose(dcpl);
          H5Dclose(d);
          return 0;
        },
        &columns);
    double total = 0;
    for (const Column& col : columns) total += static_cast<double>(col.rows * col.width * col.element);
    const double fraction = total > limit ? limit / total : 1.0;
    for (const Column& col : columns) {
      std::size_t rows = static_cast<std::size_t>(fraction * static_cast<double>(col.rows));
      rows = std::min(col.rows, std::max(col.chunk_rows, (rows + col.chunk_rows - 1) / col.chunk_rows * col.chunk_rows));
      const hid_t d = H5Dopen2(f, col.name.c_str(), H5P_DEFAULT);
      const hid_t type = H5Dget_type(d), fspace = H5Dget_space(d);
      const hsize_t start[2] = {0, 0}, count[2] = {rows, col.width};
      H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, nullptr, count, nullptr);
      const hid_t mspace = H5Screate_simple(2, count, nullptr);
      std::vector<unsigned char> all(rows * col.width * col.element);
      if (H5Dread(d, type, mspace, fspace, H5P_DEFAULT, all.data()) >= 0) {
        const std::size_t chunk_bytes = col.chunk_rows * col.width * col.element;
        for (std::size_t s = 0; s < all.size(); s += chunk_bytes) {
          const std::size_t bytes = std::min(chunk_bytes, all.size() - s);
          out.shuffled.push_back(raysweep::generators::hdf5::shuffle_bytes(all.data() + s, bytes, col.element));
          out.raw += bytes;
        }
      }
      H5Sclose(mspace);
      H5Sclose(fspace);
      H5Tclose(type);
      H5Dclose(d);
    }
    H5Fclose(f);
    return out;
  }();
  return c;
}

template <class Compress>
void run(benchmark::State& state, Compress compress) {
  const Chunks& c = chunks();
  if (c.shuffled.empty()) {
    state.SkipWithError("no dataset (run raysweep run datasets/van3twin-ring/city.toml --until sweep first)");
    return;
  }
  std::size_t stored = 0;
  for (auto _ : state) {
    stored = 0;
    for (const auto& chunk : c.shuffled) stored += compress(chunk);
  }
  state.counters["MB_per_s"] = benchmark::Counter(static_cast<double>(c.raw) / 1e6 * static_cast<double>(state.iterations()),
                                                  benchmark::Counter::kIsRate);
  state.counters["ratio"] = static_cast<double>(stored) / static_cast<double>(c.raw);
  state.counters["raw_MB"] = static_cast<double>(c.raw) / 1e6;
  state.SetLabel(c.source);
}

void BM_Zlib(benchmark::State& state) {
  const int level = static_cast<int>(state.range(0));
  std::vector<unsigned char> z;
  run(state, [&](const std::vector<unsigned char>& in) {
    uLongf size = compressBound(static_cast<uLong>(in.size()));
    z.resize(size);
    if (compress2(z.data(), &size, in.data(), static_cast<uLong>(in.size()), level) != Z_OK)
      throw std::runtime_error("zlib: cannot deflate a chunk");
    return static_cast<std::size_t>(size);
  });
}

void BM_Libdeflate(benchmark::State& state) {
  libdeflate_compressor* comp = libdeflate_alloc_compressor(static_cast<int>(state.range(0)));
  if (!comp) throw std::runtime_error("libdeflate: cannot allocate a compressor");
  std::vector<unsigned char> z;
  run(state, [&](const std::vector<unsigned char>& in) {
    z.resize(libdeflate_zlib_compress_bound(comp, in.size()));
    const std::size_t size = libdeflate_zlib_compress(comp, in.data(), in.size(), z.data(), z.size());
    if (size == 0) throw std::runtime_error("libdeflate: cannot deflate a chunk");
    return size;
  });
  libdeflate_free_compressor(comp);
}

}  // namespace

BENCHMARK(BM_Zlib)->Arg(1)->Arg(4)->Arg(6)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Libdeflate)->Arg(1)->Arg(2)->Arg(4)->Arg(6)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
