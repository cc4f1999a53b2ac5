// Vehicle library benchmark: load + segment (+ normalise) and LOD generation
// (decimation + Hausdorff error) per model: the parametric passenger car and
// bus, and the BMW OpenMATERIAL car and truck when ../shared is present.
#include <benchmark/benchmark.h>
#include <spdlog/spdlog.h>

#include <filesystem>

#include "meshkit/vehicle_lod.hpp"
#include "pipeline/vehicles_stage.hpp"

namespace fs = std::filesystem;
using namespace raysweep;

namespace {

fs::path bmw(const char* file) {
  return fs::path(RAYSWEEP_SHARED_DATA) / "openmaterial-validation-vehicles/objects" / file;
}

void BM_LoadSegment(benchmark::State& state, const std::string& vclass, const fs::path& file) {
  if (!file.empty() && !fs::exists(file)) {
    state.SkipWithError("input absent (../shared/data not present)");
    return;
  }
  spdlog::set_level(spdlog::level::err);
  pipeline::VehiclesSettings cfg;
  std::size_t tris = 0;
  for (auto _ : state) tris = pipeline::build_vehicle(vclass, vclass, file.string(), cfg).model.triangle_count();
  state.counters["triangles"] = static_cast<double>(tris);
}

void BM_Lods(benchmark::State& state, const std::string& vclass, const fs::path& file) {
  if (!file.empty() && !fs::exists(file)) {
    state.SkipWithError("input absent (../shared/data not present)");
    return;
  }
  spdlog::set_level(spdlog::level::err);
  pipeline::VehiclesSettings cfg;
  const auto model = pipeline::build_vehicle(vclass, vclass, file.string(), cfg).model;
  double h_last = 0;
  std::size_t t_last = 0;
  for (auto _ : state)
    for (double r : cfg.lod_ratios) {
      if (r >= 1) continue;
      auto lod = meshkit::simplify_vehicle(model, r, cfg.lod_max_error_m);
      h_last = meshkit::hausdorff_distance(model, lod);
      t_last = lod.triangle_count();
    }
  state.counters["triangles_lod0"] = static_cast<double>(model.triangle_count());
  state.counters["triangles_last"] = static_cast<double>(t_last);
  state.counters["hausdorff_last_m"] = h_last;
}

}  // namespace

BENCHMARK_CAPTURE(BM_LoadSegment, parametric_passenger, "passenger", fs::path())->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_LoadSegment, parametric_bus, "bus", fs::path())->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_LoadSegment, bmw_car, "passenger", bmw("vehicle_example.gltf"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_LoadSegment, bmw_truck, "truck", bmw("truck_example.gltf"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Lods, parametric_passenger, "passenger", fs::path())->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Lods, bmw_car, "passenger", bmw("vehicle_example.gltf"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Lods, bmw_truck, "truck", bmw("truck_example.gltf"))->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
