// city.toml / --config files through every stage's config entry point, each
// called by the file's path (so the harness does not depend on how the tables
// are parsed inside): [city] and the inputs it names, [scene], [radio],
// [tracer], [materials.*], [vehicles] (classes, rules), [sweep], [sinr],
// [ns3], [radiomap]. ([traffic] is read by load_city_config for its inputs;
// its other keys only inside `raysweep run`.)
#include "fuzz_common.hpp"
#include "pipeline/city_run.hpp"
#include "pipeline/config.hpp"
#include "pipeline/ns3_stage.hpp"
#include "pipeline/radiomap_stage.hpp"
#include "pipeline/sinr_stage.hpp"
#include "pipeline/sweep_stage.hpp"
#include "pipeline/trace_config.hpp"
#include "pipeline/vehicles_stage.hpp"

using namespace raysweep;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("city.toml", data, size);
  fuzz::expect_clear_errors("load_scene_config", path, [&] { pipeline::load_scene_config(path).to_json(); });
  fuzz::expect_clear_errors("load_trace_config", path, [&] { pipeline::load_trace_config(path).to_json(); });
  fuzz::expect_clear_errors("load_vehicles_config", path, [&] { pipeline::load_vehicles_config(path); });
  fuzz::expect_clear_errors("load_sweep_config", path, [&] { pipeline::load_sweep_config(path); });
  fuzz::expect_clear_errors("load_sinr_settings", path, [&] { pipeline::load_sinr_settings(path); });
  fuzz::expect_clear_errors("load_ns3_settings", path, [&] { pipeline::load_ns3_settings(path).to_json(); });
  fuzz::expect_clear_errors("load_radiomap_settings", path, [&] { pipeline::load_radiomap_settings(path); });
  fuzz::expect_clear_errors("load_city_config", path, [&] { pipeline::load_city_config(path); });
  return 0;
}
