// Scene stage benchmark: the whole `raysweep scene` stage (read OSM + network,
// repair, extrude, write glb + Mitsuba + manifest) on the demo city and, when
// ../shared is present, on the whole Bad Hersfeld extract (~11k buildings).
// Peak resident memory is reported as a counter (process high-water mark, so
// run one benchmark per process with --benchmark_filter for exact figures).
#include <benchmark/benchmark.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <filesystem>

#include "pipeline/scene_stage.hpp"

namespace fs = std::filesystem;

namespace {

double peak_rss_mib() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss / 1024.0;
}

void run_stage(benchmark::State& state, const fs::path& osm, const fs::path& net, double clip) {
  if (!fs::exists(osm)) {
    state.SkipWithError("input absent (../shared/data not present)");
    return;
  }
  spdlog::set_level(spdlog::level::err);
  const fs::path out = fs::temp_directory_path() / "raysweep-bench-scene";
  const fs::path cfg = fs::temp_directory_path() / "raysweep-bench-scene.toml";
  {
    std::FILE* f = std::fopen(cfg.c_str(), "w");
    std::fprintf(f, "[scene]\nclip_distance_m = %g\n", clip);
    std::fclose(f);
  }
  raysweep::pipeline::SceneArgs args;
  args.osm = osm.string();
  args.net = net.string();
  args.out = out.string();
  args.preview = false;  // time the stage, not matplotlib
  const auto settings = raysweep::pipeline::load_settings(cfg.string());
  nlohmann::json manifest;
  for (auto _ : state) manifest = raysweep::pipeline::run_scene_stage(args, settings, {"bench"});
  state.counters["buildings"] = manifest["buildings"]["kept"].get<double>();
  state.counters["triangles"] = manifest["triangle_count"].get<double>();
  state.counters["peak_rss_MiB"] = peak_rss_mib();
  fs::remove_all(out);
}

void BM_SceneDemo(benchmark::State& state) {
  const fs::path d = fs::path(RAYSWEEP_SOURCE_DIR) / "datasets/demo";
  run_stage(state, d / "kirchberg.osm", d / "kirchberg.net.xml", 150);
}

void BM_SceneBadHersfeldWhole(benchmark::State& state) {
  const fs::path d = fs::path(RAYSWEEP_SHARED_DATA) / "dlr-sumo-scenarios-badhersfeld";
  run_stage(state, d / "osm_bbox.osm.xml.gz", d / "osm_edited.net.xml.gz", 0);  // no clipping: every building
}

}  // namespace

BENCHMARK(BM_SceneDemo)->Unit(benchmark::kMillisecond)->MinTime(0.5);
BENCHMARK(BM_SceneBadHersfeldWhole)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK_MAIN();
