// SINR outcome files (HDF5, format raysweep-sinr), structure-aware (see
// h5_mutate.hpp): sinr::read_sinr_schedule (`raysweep sinr --schedule-from`)
// and dataset_info (`raysweep info`).
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
  g_base = fuzz::base_bytes("base.h5", fuzz::write_sinr_base);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::mutated_file("sinr.h5", g_base, data, size);
  fuzz::expect_clear_errors("read_sinr_schedule", path, [&] { generators::sinr::read_sinr_schedule(path); });
  fuzz::expect_clear_errors("dataset_info", path, [&] { generators::dataset_info(path); });
  return 0;
}
