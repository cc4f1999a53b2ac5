// ns-3 lookup tables (HDF5, format raysweep-ns3-table), structure-aware (see
// h5_mutate.hpp): generators::Ns3Table::load, what ns-3's Raysweep models
// read, with lookups of every frame and pair, and dataset_info (`raysweep info`).
#include "generators/formats.hpp"
#include "h5_bases.hpp"
#include "h5_mutate.hpp"

using namespace raysweep;

namespace {
std::vector<std::uint8_t> g_base;
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  fuzz::quiet_hdf5();
  g_base = fuzz::base_bytes("base.h5", fuzz::write_ns3_base);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::mutated_file("table.h5", g_base, data, size);
  fuzz::expect_clear_errors("Ns3Table::load", path, [&] {
    const auto t = generators::Ns3Table::load(path);
    for (std::size_t f = 0; f < t.frames(); ++f) {
      t.frame_at(t.time(f));
      for (std::uint32_t a = 0; a < t.node_count(); ++a) {
        t.state(f, a);
        for (std::uint32_t b = a + 1; b < t.node_count(); ++b)
          if (auto row = t.pair_row(f, a, b)) {
            t.gain_db(*row);
            t.los_class(*row);
            t.band_gain_db(*row);
          }
      }
    }
  });
  fuzz::expect_clear_errors("dataset_info", path, [&] { generators::dataset_info(path); });
  return 0;
}
