// SUMO networks (net.xml, plain or gzip: detected by content) through
// meshkit::read_sumo_network, what `raysweep scene --net`, `poses` and the
// sweep read; the same bytes as a polygon file through read_sumo_polygons.
#include "fuzz_common.hpp"
#include "meshkit/sumo_net.hpp"

using namespace raysweep;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("input.net.xml", data, size);
  fuzz::expect_clear_errors("read_sumo_network", path, [&] { meshkit::read_sumo_network(path); });
  fuzz::expect_clear_errors("read_sumo_polygons", path, [&] { meshkit::read_sumo_polygons(path); });
  return 0;
}
