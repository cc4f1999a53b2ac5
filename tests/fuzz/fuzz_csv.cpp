// Pose and node CSV files (`raysweep trace --poses/--nodes`, the sweep's RSUs,
// radiomap, render) through pipeline::read_poses_csv and read_nodes_csv.
#include "fuzz_common.hpp"
#include "pipeline/trace_inputs.hpp"

using namespace raysweep;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("input.csv", data, size);
  fuzz::expect_clear_errors("read_poses_csv", path, [&] { pipeline::read_poses_csv(path); });
  fuzz::expect_clear_errors("read_nodes_csv", path, [&] { pipeline::read_nodes_csv(path); });
  return 0;
}
