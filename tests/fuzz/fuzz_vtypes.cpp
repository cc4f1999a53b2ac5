// SUMO route/additional files with <vType>s: pipeline::VTypeMap (what the
// sweep resolves FCD types with) and meshkit::read_sumo_vtypes (`raysweep
// vehicles --vtypes`); the same bytes as a .sumocfg through sumocfg_inputs.
#include "fuzz_common.hpp"
#include "meshkit/sumo_net.hpp"
#include "pipeline/vtypes.hpp"

using namespace raysweep;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("input.rou.xml", data, size);
  fuzz::expect_clear_errors("VTypeMap", path, [&] {
    pipeline::VTypeMap map;
    map.add_file(path);
    for (const auto& t : meshkit::read_sumo_vtypes(path)) map.resolve(t.id);
    map.resolve("DEFAULT_VEHTYPE");
    map.resolve("not-there");
  });
  const std::string cfg = fuzz::write_input("input.sumocfg", data, size);
  fuzz::expect_clear_errors("sumocfg_inputs", cfg, [&] { pipeline::sumocfg_inputs(cfg); });
  return 0;
}
