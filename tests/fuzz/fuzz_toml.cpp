// city.toml / --config files through both config entry points, each called
// by the file's path (so the harness does not depend on how the tables are
// parsed inside): load_settings reads [scene], [radio], [tracer],
// [materials.*], [vehicles] (classes, rules), [traffic], [sweep], [sinr],
// [ns3] and [radiomap]; load_city_settings also [city] and the inputs it names.
#include "fuzz_common.hpp"
#include "pipeline/settings/settings.hpp"

using namespace raysweep;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("city.toml", data, size);
  fuzz::expect_clear_errors("load_settings", path, [&] {
    const auto s = pipeline::load_settings(path);
    s.scene.to_json();
    s.trace.to_json();
    s.ns3.to_json();
  });
  fuzz::expect_clear_errors("load_city_settings", path, [&] { pipeline::load_city_settings(path); });
  return 0;
}
