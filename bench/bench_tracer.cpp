// Tracer benchmark: what one traced snapshot costs, and what it is made of.
//
// Two scenes, each loaded once per process:
//   demo     - the demo city (datasets/demo/kirchberg.osm + kirchberg.net.xml)
//              through the whole `raysweep scene` stage (default config, into
//              a temp dir), read back from scene.glb; lanes from kirchberg.net.xml.
//   van3twin - VaN3Twin's Sionna ring road (SionnaCircleScenario/scene.xml via
//              read_mitsuba) without Sionna's placeholder car boxes (objects
//              whose id matches `car_`, as `raysweep trace --exclude-objects`
//              would drop them); lanes from sumo_files_v2v_map/map.net.xml.
//              Skipped (SkipWithError) when ../shared/data is absent.
//
// Benchmarks:
//   BM_SceneBuild/<scene>        TraceScene construction (static Embree BVH,
//                                planar faces): paid once per scene, not per frame.
//   BM_VehicleUpdate/<scene>/N   TraceScene::set_vehicles alone for N vehicles
//                                whose positions move a little every iteration
//                                (instance transforms + top-level re-commit).
//   BM_EmbreeRaw/<scene>         Embree's raw closest-hit throughput
//                                (TraceScene::shoot_raw, 2^20 Fibonacci
//                                directions, tfar 1e4 m) from 1.5 m above the
//                                first of 60 placed vehicles: an upper bound on
//                                the ray rate the solver can reach.
//   BM_Snapshot/<scene>/N        trace_snapshot for N vehicles (N = 5 ... 120)
//                                with the default TracerConfig (depth 3, LoS +
//                                specular + refraction, 6144 rays per source)
//                                and default RadioConfig (5.9 GHz); the second
//                                argument's bits add diffraction (1) and
//                                diffuse scattering (2), swap the exact image
//                                search for shoot-and-bounce alone (4),
//                                integrate diffuse by tiles (8), and leave out
//                                ground_order3 (16), vehicle_multi_bounce (32)
//                                or the diffuse gathering's second end (64), or
//                                integrate first-order diffuse by tiles and the
//                                rest by rays (128, "hybrid"), with tiles of 2 m
//                                at ratio 0.5 (256), or add UTD on the vehicles'
//                                edges (512). Counters
//                                ms_* / tms_* say where the time went
//                                (SnapshotStats::Timing). Poses come
//                                from place_on_lanes(net, N, seed 1,
//                                passenger:truck:bus = 8:1:1); when that mix does
//                                not fit, passenger cars only (counter
//                                passenger_only = 1 and the label say which).
//                                Scene, models, poses, the vehicles' bounce
//                                tables and the diffuse tile tree are set up
//                                outside the timed loop (a sweep builds them once). Counters: pairs, rays (Embree
//                                queries per snapshot), paths, candidates, the
//                                LOS / NLOSV / NLOS pair counts, pairs without
//                                any path, and pairs_per_s / rays_per_s over
//                                wall-clock time.
// Everything runs on TBB's threads, so all timings are wall-clock (UseRealTime,
// which appends "/real_time" to the names); the CPU column counts the calling
// thread only and the rates are per wall-clock second.
//
// Run (medians of 5 repetitions; about 80 s on 2 cores):
//   ./build/bench/bench_tracer --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
// One group only, e.g.: --benchmark_filter='BM_Snapshot/demo/'
#include <benchmark/benchmark.h>
// The pipeline logs through the shared libspdlog (its CMake target's usage
// requirements, which reach this target only as a link dependency); without
// these, spdlog::set_level here would set a header-only copy's level and the
// scene stage would still log at info.
#ifndef SPDLOG_COMPILED_LIB
#define SPDLOG_SHARED_LIB
#define SPDLOG_COMPILED_LIB
#define SPDLOG_FMT_EXTERNAL
#endif
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "meshkit/gltf_io.hpp"
#include "meshkit/lane_placement.hpp"
#include "meshkit/mitsuba_io.hpp"
#include "meshkit/sumo_net.hpp"
#include "meshkit/vehicle_library.hpp"
#include "pipeline/scene_stage.hpp"
#include "pipeline/trace_inputs.hpp"
#include "tracer/tracer.hpp"

namespace fs = std::filesystem;
using namespace raysweep;

namespace {

// tracer's Vec3 operators (Vec3 is std::array, so ADL does not find them).
using tracer::operator+;
using tracer::operator*;

const fs::path kVan3twin = fs::path(RAYSWEEP_SHARED_DATA) / "van3twin/DriveX-devs_VaN3Twin/src";

struct Placement {
  std::vector<meshkit::PoseRow> poses;
  bool passenger_only = false;
  std::string error;  // non-empty: neither mix could be placed
};

// One scene with everything derived from it, built on first use.
struct SceneCase {
  std::string error;  // non-empty: benchmarks on this scene skip with it
  meshkit::Scene static_scene;
  meshkit::SumoNetwork net;
  std::size_t excluded_objects = 0;
  std::unique_ptr<tracer::TraceScene> trace;  // shared by the benchmarks; each places its own vehicles
  meshkit::VehicleLibrary library;           // built-in parametric models
  std::map<int, Placement> placements;
};

std::unique_ptr<SceneCase> load_demo() {
  auto c = std::make_unique<SceneCase>();
  const fs::path d = fs::path(RAYSWEEP_SOURCE_DIR) / "datasets/demo";
  const fs::path out = fs::temp_directory_path() / "raysweep-bench-tracer-demo";
  try {
    fs::remove_all(out);
    pipeline::SceneArgs args;
    args.osm = (d / "kirchberg.osm").string();
    args.net = (d / "kirchberg.net.xml").string();
    args.out = out.string();
    args.preview = false;
    pipeline::run_scene_stage(args, pipeline::Settings{}, {"bench_tracer"});
    c->static_scene = meshkit::read_glb((out / "scene.glb").string());
    c->net = meshkit::read_sumo_network(args.net);
  } catch (const std::exception& e) {
    c->error = std::string("demo scene: ") + e.what();
  }
  std::error_code ec;
  fs::remove_all(out, ec);
  return c;
}

std::unique_ptr<SceneCase> load_van3twin() {
  auto c = std::make_unique<SceneCase>();
  const fs::path xml = kVan3twin / "sionna/scenarios/SionnaCircleScenario/scene.xml";
  const fs::path net = kVan3twin / "automotive/examples/sumo_files_v2v_map/map.net.xml";
  if (!fs::exists(xml) || !fs::exists(net)) {
    c->error = "input absent (../shared/data not present)";
    return c;
  }
  try {
    c->static_scene = pipeline::exclude_objects(meshkit::read_mitsuba(xml.string()), "car_", &c->excluded_objects);
    c->net = meshkit::read_sumo_network(net.string());
  } catch (const std::exception& e) {
    c->error = std::string("van3twin scene: ") + e.what();
  }
  return c;
}

SceneCase& scene_case(const std::string& name) {
  static std::map<std::string, std::unique_ptr<SceneCase>> cache;
  auto it = cache.find(name);
  if (it == cache.end()) it = cache.emplace(name, name == "demo" ? load_demo() : load_van3twin()).first;
  return *it->second;
}

// The scene's TraceScene (built once) or nullptr after SkipWithError.
tracer::TraceScene* trace_scene(benchmark::State& state, SceneCase& c) {
  if (!c.error.empty()) {
    state.SkipWithError(c.error.c_str());
    return nullptr;
  }
  if (!c.trace) {
    try {
      c.trace = std::make_unique<tracer::TraceScene>(c.static_scene);
    } catch (const std::exception& e) {
      c.error = std::string("TraceScene: ") + e.what();
      state.SkipWithError(c.error.c_str());
      return nullptr;
    }
  }
  return c.trace.get();
}

const Placement& placement(SceneCase& c, int n) {
  auto it = c.placements.find(n);
  if (it != c.placements.end()) return it->second;
  Placement p;
  try {
    p.poses = meshkit::place_on_lanes(c.net, n, 1, {{"passenger", 8}, {"truck", 1}, {"bus", 1}});
  } catch (const std::invalid_argument&) {
    try {
      p.poses = meshkit::place_on_lanes(c.net, n, 1, {{"passenger", 1}});
      p.passenger_only = true;
    } catch (const std::invalid_argument& e) {
      p.error = e.what();
    }
  }
  return c.placements.emplace(n, std::move(p)).first->second;
}

// Scene with `n` vehicles placed, or nullptr after SkipWithError.
tracer::TraceScene* scene_with_vehicles(benchmark::State& state, const std::string& name, int n,
                                        const Placement** used = nullptr) {
  SceneCase& c = scene_case(name);
  tracer::TraceScene* scene = trace_scene(state, c);
  if (!scene) return nullptr;
  const Placement& p = placement(c, n);
  if (!p.error.empty()) {
    state.SkipWithError(p.error.c_str());
    return nullptr;
  }
  try {
    pipeline::place_vehicles(*scene, c.library, p.poses);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return nullptr;
  }
  if (used) *used = &p;
  return scene;
}

void BM_SceneBuild(benchmark::State& state, const std::string& name) {
  SceneCase& c = scene_case(name);
  if (!c.error.empty()) {
    state.SkipWithError(c.error.c_str());
    return;
  }
  std::unique_ptr<tracer::TraceScene> built;
  for (auto _ : state) {
    state.PauseTiming();
    built.reset();  // releasing the previous one is not part of the build
    state.ResumeTiming();
    built = std::make_unique<tracer::TraceScene>(c.static_scene);
  }
  state.counters["triangles"] = static_cast<double>(built ? built->static_triangle_count() : 0);
  state.counters["objects"] = static_cast<double>(c.static_scene.objects.size());
  state.counters["excluded_objects"] = static_cast<double>(c.excluded_objects);
}

void BM_VehicleUpdate(benchmark::State& state, const std::string& name) {
  const int n = static_cast<int>(state.range(0));
  tracer::TraceScene* scene = scene_with_vehicles(state, name, n);
  if (!scene) return;
  // Frames 10 ms apart: every vehicle moves by velocity * dt each frame.
  constexpr int kFrames = 16;
  std::vector<std::vector<tracer::VehiclePose>> frames(kFrames, scene->vehicles());
  for (int f = 0; f < kFrames; ++f)
    for (auto& v : frames[f]) v.position = v.position + (0.01 * f) * v.velocity;
  std::size_t f = 0;
  for (auto _ : state) {
    scene->set_vehicles(frames[f]);
    f = (f + 1) % kFrames;
  }
  state.counters["vehicles"] = n;
}

void BM_EmbreeRaw(benchmark::State& state, const std::string& name) {
  tracer::TraceScene* scene = scene_with_vehicles(state, name, 60);
  if (!scene) return;
  static const std::vector<tracer::Vec3> dirs = tracer::fibonacci_sphere(1 << 20);
  const tracer::Vec3 origin = scene->vehicles().front().position + tracer::Vec3{0, 0, 1.5};
  std::size_t hits = 0;
  for (auto _ : state) {
    hits = scene->shoot_raw(origin, dirs, 1e4);
    benchmark::DoNotOptimize(hits);
  }
  state.counters["rays"] = static_cast<double>(dirs.size());
  state.counters["rays_per_s"] =
      benchmark::Counter(static_cast<double>(dirs.size()), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["hit_fraction"] = static_cast<double>(hits) / static_cast<double>(dirs.size());
}

// Mechanism sets of the snapshot benchmark: each adds its cost on top of
// the specular/refraction core (the tracer's defaults otherwise).
// kSbr: the same with shoot-and-bounce alone as the candidate search (what
// the exact image search costs and buys).
// kTiles: diffuse scattering integrated by surface tiles instead of rays.
// kNoGround3, kNoMultiBounce, kOneEnd: without one of the completeness
// classes (tracer.ground_order3, vehicle_multi_bounce, diffuse_both_ends),
// so what each costs is measured on its own.
enum Mechanisms {
  kSpecular = 0,
  kDiffraction = 1,
  kDiffuse = 2,
  kAll = 3,
  kSbr = 4,
  kTiles = 8,
  kNoGround3 = 16,
  kNoMultiBounce = 32,
  kOneEnd = 64,
  kHybrid = 128,
  kCoarseTiles = 256,
  kVehicleEdges = 512
};
std::string mechanisms_name(int m) {
  static const char* names[] = {"specular", "+diffraction", "+diffuse", "+diffraction+diffuse"};
  return std::string(names[m & 3]) + (m & kTiles ? " (tiles)" : "") + (m & kSbr ? ", sbr search" : ", image search") +
         (m & kNoGround3 ? ", no ground_order3" : "") + (m & kNoMultiBounce ? ", no vehicle_multi_bounce" : "") +
         (m & kOneEnd ? ", diffuse from one end" : "") + (m & kHybrid ? ", diffuse hybrid" : "") +
         (m & kCoarseTiles ? ", tiles 2 m / ratio 0.5" : "") + (m & kVehicleEdges ? ", vehicle edges" : "");
}

// The per-model multi-bounce tables are built on first use and kept with the
// scene (a sweep builds them once, in its first frame): built here, untimed,
// so a case's few iterations do not carry them.
void warm_bounce_tables(const tracer::TraceScene& scene, const tracer::TracerConfig& cfg) {
  for (std::size_t v = 0; cfg.vehicle_multi_bounce && v < scene.vehicles().size(); ++v)
    scene.vehicle_bounce_sequences(v, {1, 0, 0}, 0);
}

void BM_Snapshot(benchmark::State& state, const std::string& name) {
  const int n = static_cast<int>(state.range(0));
  const int mech = state.range(1);
  const Placement* used = nullptr;
  tracer::TraceScene* scene = scene_with_vehicles(state, name, n, &used);
  if (!scene) return;
  const auto nodes = tracer::vehicle_nodes(*scene);
  tracer::TracerConfig cfg;
  cfg.diffraction = mech & kDiffraction;
  cfg.diffuse = mech & kDiffuse;
  if (mech & kSbr) cfg.candidates = tracer::CandidateSearch::sbr;
  if (mech & kTiles) cfg.diffuse_integration = tracer::DiffuseIntegration::tiles;
  if (mech & kHybrid) cfg.diffuse_integration = tracer::DiffuseIntegration::hybrid;
  if (mech & kCoarseTiles) {
    cfg.diffuse_tile_m = 2;
    cfg.diffuse_tile_ratio = 0.5;
  }
  if (mech & kVehicleEdges) cfg.vehicle_edge_diffraction = true;
  if (mech & kNoGround3) cfg.ground_order3 = false;
  if (mech & kNoMultiBounce) cfg.vehicle_multi_bounce = false;
  if (mech & kOneEnd) cfg.diffuse_both_ends = false;
  const tracer::RadioConfig radio;
  tracer::Snapshot snap;
  warm_bounce_tables(*scene, cfg);
  // Likewise the diffuse tile tree (built once per scene): two nodes build it.
  if (cfg.diffuse && cfg.diffuse_integration != tracer::DiffuseIntegration::rays && nodes.size() >= 2)
    tracer::trace_snapshot(*scene, {nodes[0], nodes[1]}, cfg, radio);
  for (auto _ : state) {
    snap = tracer::trace_snapshot(*scene, nodes, cfg, radio);
    benchmark::DoNotOptimize(snap.pairs.data());
  }
  std::size_t los = 0, nlosv = 0, nlos = 0, no_path = 0, knife = 0;
  double knife_db = 0;
  for (const auto& p : snap.pairs) {
    if (p.vehicle_loss_db > 0) {
      ++knife;
      knife_db += p.vehicle_loss_db;
    }
    (p.los_class == tracer::LosClass::LOS ? los : p.los_class == tracer::LosClass::NLOSV ? nlosv : nlos)++;
    no_path += p.paths.empty();
  }
  std::size_t trucks = 0, buses = 0;
  for (const auto& p : used->poses) {
    trucks += p.vclass == "truck";
    buses += p.vclass == "bus";
  }
  const auto pairs = static_cast<double>(snap.pairs.size());
  const auto rays = static_cast<double>(snap.stats.rays);
  state.counters["pairs"] = pairs;
  state.counters["pairs_per_s"] = benchmark::Counter(pairs, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["rays"] = rays;
  state.counters["rays_per_s"] = benchmark::Counter(rays, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["paths"] = static_cast<double>(snap.stats.paths);
  state.counters["candidates"] = static_cast<double>(snap.stats.candidates);
  state.counters["dropped_cap"] = static_cast<double>(snap.stats.dropped_transmission_cap);
  state.counters["below_threshold"] = static_cast<double>(snap.stats.dropped_threshold);
  state.counters["diffraction_paths"] = static_cast<double>(snap.stats.diffraction_paths);
  state.counters["diffuse_paths"] = static_cast<double>(snap.stats.diffuse_paths);
  state.counters["edges"] = static_cast<double>(scene->edges().size());
  std::size_t vehicle_faces = 0;
  for (std::uint32_t v = 1; v <= scene->vehicles().size(); ++v) vehicle_faces += scene->face_count(v);
  state.counters["image_sources"] = static_cast<double>(snap.stats.image_sources);
  state.counters["image_tests"] = static_cast<double>(snap.stats.image_tests);
  // Where the time went (last iteration; ms; per-pair steps in thread-ms).
  const auto& tm = snap.stats.time;
  state.counters["ms_image"] = 1e3 * tm.image_search;
  state.counters["ms_shoot"] = 1e3 * tm.shoot;
  state.counters["ms_beams"] = 1e3 * tm.beams;
  state.counters["ms_edges"] = 1e3 * tm.edges;
  state.counters["ms_diffuse_views"] = 1e3 * tm.diffuse_views;
  state.counters["diffuse_tiles"] = static_cast<double>(snap.stats.diffuse_tiles);
  state.counters["diffuse_views"] = static_cast<double>(snap.stats.diffuse_views);
  state.counters["tms_diffuse"] = 1e3 * tm.diffuse;
  state.counters["ms_pairs"] = 1e3 * tm.pairs;
  state.counters["tms_los"] = 1e3 * tm.los;
  state.counters["tms_exact"] = 1e3 * tm.exact;
  state.counters["tms_diffraction"] = 1e3 * tm.diffraction;
  state.counters["tms_assemble"] = 1e3 * tm.assemble;
  state.counters["static_faces"] = static_cast<double>(scene->face_count(0));
  state.counters["vehicle_faces"] = static_cast<double>(vehicle_faces);
  state.counters["LOS"] = static_cast<double>(los);
  state.counters["NLOSV"] = static_cast<double>(nlosv);
  state.counters["NLOS"] = static_cast<double>(nlos);
  state.counters["no_path_pairs"] = static_cast<double>(no_path);
  // Pairs whose direct path vehicles attenuate (knife edges), mean loss.
  state.counters["knife_pairs"] = static_cast<double>(knife);
  state.counters["knife_loss_db_mean"] = knife ? knife_db / static_cast<double>(knife) : 0.0;
  state.counters["passenger_only"] = used->passenger_only ? 1 : 0;
  state.counters["trucks"] = static_cast<double>(trucks);
  state.counters["buses"] = static_cast<double>(buses);
  state.SetLabel(mechanisms_name(mech) +
                 (used->passenger_only ? ", mix passenger" : ", mix passenger:truck:bus 8:1:1"));
}

// Per-pair diffuse power (sum of |a|^2 over paths with a diffuse
// interaction).
std::vector<double> diffuse_power(const tracer::Snapshot& snap) {
  std::vector<double> p;
  for (const auto& pair : snap.pairs) {
    double sum = 0;
    for (const auto& path : pair.paths)
      if (std::any_of(path.interactions.begin(), path.interactions.end(),
                      [](const auto& in) { return in.type == tracer::InteractionType::diffuse; }))
        sum += std::norm(path.a);
    p.push_back(sum);
  }
  return p;
}

// |10 log10(got / ref)| over the listed pairs (200 dB where got has none):
// median and 95th percentile, and the ratio of the summed powers.
void report_error(benchmark::State& state, const std::string& name, const std::vector<double>& got,
                  const std::vector<double>& ref, const std::vector<unsigned char>& use) {
  std::vector<double> err;
  double sg = 0, sr = 0;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    if (!use[i] || !(ref[i] > 0)) continue;
    sg += got[i];
    sr += ref[i];
    err.push_back(got[i] > 0 ? std::fabs(10 * std::log10(got[i] / ref[i])) : 200.0);
  }
  std::sort(err.begin(), err.end());
  auto q = [&](double f) { return err.empty() ? 0.0 : err[static_cast<std::size_t>(f * (err.size() - 1))]; };
  state.counters[name + "_db_median"] = q(0.5);
  state.counters[name + "_db_p95"] = q(0.95);
  state.counters[name + "_power_ratio"] = sr > 0 ? sg / sr : 0;
}

std::vector<double> total_power(const tracer::Snapshot& snap) {
  std::vector<double> p;
  for (const auto& pair : snap.pairs) p.push_back(pair.stats.gain_incoherent);
  return p;
}

// BM_DiffuseAccuracy/<scene>/N: every mechanism at the defaults (timed),
// against the same with a fine tile integration (tiles of 0.25 m, ratio
// 0.05) and with the ray estimator (diffuse_integration = "rays", 4096 and
// 65536 rays per source, scattering after up to two reflections). Per pair:
// the total incoherent gain ("total_*"), and the diffuse power where the
// reference's diffuse part is at least 1 % of its total ("diffuse_*").
void BM_DiffuseAccuracy(benchmark::State& state, const std::string& name) {
  const int n = static_cast<int>(state.range(0));
  tracer::TraceScene* scene = scene_with_vehicles(state, name, n);
  if (!scene) return;
  const auto nodes = tracer::vehicle_nodes(*scene);
  tracer::TracerConfig cfg;
  cfg.diffuse_integration = tracer::DiffuseIntegration::tiles;
  cfg.diffuse_shadow_ratio = static_cast<double>(state.range(1)) / 1000;
  cfg.diffuse_tile_ratio = static_cast<double>(state.range(2)) / 1000;
  cfg.diffuse_tile_m = static_cast<double>(state.range(3)) / 1000;
  const tracer::RadioConfig radio;
  tracer::Snapshot snap;
  warm_bounce_tables(*scene, cfg);
  for (auto _ : state) {
    snap = tracer::trace_snapshot(*scene, nodes, cfg, radio);
    benchmark::DoNotOptimize(snap.pairs.data());
  }
  tracer::TracerConfig fine = cfg;
  fine.diffuse_tile_m = 0.25;
  fine.diffuse_tile_ratio = 0.05;
  fine.diffuse_shadow_ratio = 0;
  const auto ref = tracer::trace_snapshot(*scene, nodes, fine, radio);
  const auto ref_total = total_power(ref), ref_diffuse = diffuse_power(ref);
  std::vector<unsigned char> all(ref_total.size(), 1), relevant(ref_total.size(), 0);
  for (std::size_t i = 0; i < ref_total.size(); ++i) relevant[i] = ref_diffuse[i] >= 0.01 * ref_total[i];
  auto compare = [&](const std::string& name, const tracer::Snapshot& s) {
    report_error(state, name + "total", total_power(s), ref_total, all);
    report_error(state, name + "diffuse", diffuse_power(s), ref_diffuse, relevant);
  };
  compare("", snap);
  tracer::TracerConfig rays = cfg;
  rays.diffuse_integration = tracer::DiffuseIntegration::rays;
  for (int k : {4096, 65536}) {
    if (state.range(1) != 0 || state.range(2) != 250) break;  // the rays once per scene and size (defaults)
    rays.rays_per_source = k;
    compare("rays" + std::to_string(k) + "_", tracer::trace_snapshot(*scene, nodes, rays, radio));
  }
  state.counters["relevant_pairs"] = static_cast<double>(std::count(relevant.begin(), relevant.end(), 1));
  state.counters["tiles"] = static_cast<double>(snap.stats.diffuse_tiles);
  state.counters["views"] = static_cast<double>(snap.stats.diffuse_views);
  state.counters["ms_views"] = 1e3 * snap.stats.time.diffuse_views;
  state.counters["tile_rays"] = static_cast<double>(snap.stats.rays);
  state.counters["tms_pairs"] = 1e3 * snap.stats.time.diffuse;
}

void register_all() {
  for (const std::string scene : {"demo", "van3twin"}) {
    benchmark::RegisterBenchmark(("BM_SceneBuild/" + scene).c_str(), BM_SceneBuild, scene)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("BM_VehicleUpdate/" + scene).c_str(), BM_VehicleUpdate, scene)
        ->Arg(60)
        ->Arg(120)
        ->Unit(benchmark::kMicrosecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("BM_EmbreeRaw/" + scene).c_str(), BM_EmbreeRaw, scene)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    auto* snap = benchmark::RegisterBenchmark(("BM_Snapshot/" + scene).c_str(), BM_Snapshot, scene);
    for (int n : {5, 10, 20, 40, 60, 120}) snap->Args({n, kSpecular});
    // Every mechanism, how it grows with vehicles.
    for (int n : {5, 10, 20, 40, 120}) snap->Args({n, kAll});
    // The cost of each mechanism, at two traffic densities.
    for (int n : {20, 60})
      for (int m : {int(kDiffraction), int(kDiffuse), int(kAll), kSbr | kSpecular, kSbr | kAll, kTiles | kAll,
                    kHybrid | kAll})
        snap->Args({n, m});
    // What each completeness class costs, at 60 vehicles.
    for (int m : {kSpecular | kNoGround3, kSpecular | kNoMultiBounce, kAll | kOneEnd}) snap->Args({60, m});
    // The hybrid diffuse integration with coarser tiles (a default candidate).
    snap->Args({60, kAll | kHybrid | kCoarseTiles});
    // UTD on the vehicles' edges too (item 3).
    for (int n : {20, 60}) snap->Args({n, kAll | kVehicleEdges});
    snap->Unit(benchmark::kMillisecond)->UseRealTime();
    // Further arguments x 1000: diffuse_shadow_ratio, diffuse_tile_ratio,
    // diffuse_tile_m.
    benchmark::RegisterBenchmark(("BM_DiffuseAccuracy/" + scene).c_str(), BM_DiffuseAccuracy, scene)
        ->Args({20, 0, 250, 1000})
        ->Args({20, 0, 500, 1000})
        ->Args({60, 0, 250, 1000})
        ->Args({60, 30, 250, 1000})
        ->Args({60, 60, 250, 1000})
        ->Args({60, 0, 500, 1000})
        ->Args({60, 0, 500, 2000})
        ->Args({60, 0, 500, 4000})
        ->Args({60, 125, 500, 2000})
        ->Iterations(1)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  }
}

}  // namespace

int main(int argc, char** argv) {
  spdlog::set_level(spdlog::level::err);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  register_all();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
