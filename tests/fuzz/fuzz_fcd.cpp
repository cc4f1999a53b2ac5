// SUMO FCD traces through pipeline::FcdReader (every frame pulled), what the
// sweep reads; once unfiltered and once with a time step, window and area
// filter (the paths that skip timesteps and drop vehicles).
#include "fuzz_common.hpp"
#include "pipeline/fcd.hpp"

using namespace raysweep;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("input.fcd.xml", data, size);
  auto pull = [&](const pipeline::FcdFilter& filter) {
    pipeline::FcdReader reader(path, filter);
    pipeline::FcdFrame frame;
    while (reader.next(frame)) {
    }
  };
  fuzz::expect_clear_errors("FcdReader", path, [&] { pull({}); });
  pipeline::FcdFilter f;
  f.begin_s = 0.5;
  f.end_s = 100;
  f.step_s = 0.2;
  f.types = {"DEFAULT_VEHTYPE", "bus"};
  f.area = pipeline::FcdArea{-100, -100, 500, 500};
  fuzz::expect_clear_errors("FcdReader (filtered)", path, [&] { pull(f); });
  return 0;
}
