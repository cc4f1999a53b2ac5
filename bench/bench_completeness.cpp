// Completeness of the candidate searches against the exhaustive reference
// (every face sequence up to max_depth, each decided exactly), per path
// order, with the time each search takes.
//
// Scenes (random, seeds 1..3, built outside the timed loop):
//   street  - ground, two building rows (concrete, brick), 5 metal boxes of
//             vehicle size, 6 antennas at 1.2-2 m; depth 3 (static faces only).
//   cars    - ground, one building row, 5 instanced passenger cars (~110
//             planar faces each) with their roof antennas; depth 2.
// Benchmarks: BM_Search/<scene>/<seed>/<search> with search = image (the
// default), sbr (shoot-and-bounce alone) at 4096 rays per source, and the
// exhaustive reference itself. Counters: paths_o<k> (paths with k
// reflections found), ref_o<k> (the reference's), power_o<k> (found power
// of order k over the reference's: 1 = nothing missed).
//
// Run: ./build/bench/bench_completeness --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "meshkit/vehicle_model.hpp"
#include "meshkit/vehicle_library.hpp"
#include "tracer/tracer.hpp"

using namespace raysweep;

namespace {

using tracer::Vec3;

void add_quad(meshkit::Scene& s, const std::string& material, const std::string& object, Vec3 a, Vec3 b, Vec3 c,
              Vec3 d, std::uint32_t& face) {
  auto& m = s.mesh_for(material, "bench");
  const auto obj = s.add_object("mesh", object);
  const auto base = static_cast<std::uint32_t>(m.vertices.size());
  m.vertices.insert(m.vertices.end(), {a, b, c, d});
  m.triangles.push_back({base, base + 1, base + 2});
  m.triangles.push_back({base, base + 2, base + 3});
  m.triangle_object.insert(m.triangle_object.end(), 2, obj);
  m.triangle_face.insert(m.triangle_face.end(), 2, face++);
}

void add_box(meshkit::Scene& s, Vec3 lo, Vec3 hi, const std::string& material, const std::string& name,
             std::uint32_t& face) {
  auto& m = s.mesh_for(material, "bench");
  const auto obj = s.add_object("building", name);
  const Vec3 c[8] = {{lo[0], lo[1], lo[2]}, {hi[0], lo[1], lo[2]}, {hi[0], hi[1], lo[2]}, {lo[0], hi[1], lo[2]},
                     {lo[0], lo[1], hi[2]}, {hi[0], lo[1], hi[2]}, {hi[0], hi[1], hi[2]}, {lo[0], hi[1], hi[2]}};
  const int quads[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {1, 2, 6, 5}, {3, 0, 4, 7}};
  for (const auto& q : quads) {
    const auto base = static_cast<std::uint32_t>(m.vertices.size());
    for (int k : q) m.vertices.push_back(c[k]);
    m.triangles.push_back({base, base + 1, base + 2});
    m.triangles.push_back({base, base + 2, base + 3});
    m.triangle_object.insert(m.triangle_object.end(), 2, obj);
    m.triangle_face.insert(m.triangle_face.end(), 2, face++);
  }
}

struct Case {
  std::unique_ptr<tracer::TraceScene> scene;
  std::vector<tracer::Node> nodes;
  int depth = 2;
  tracer::Snapshot reference;
  bool has_reference = false;
};

tracer::TracerConfig config(int depth, tracer::CandidateSearch search) {
  tracer::TracerConfig c;
  c.max_depth = depth;
  c.candidates = search;
  c.diffuse = false;
  c.diffraction = false;
  c.path_threshold_db = 0;
  return c;
}

Case& get_case(const std::string& kind, int seed) {
  static std::map<std::pair<std::string, int>, Case> cache;
  auto it = cache.find({kind, seed});
  if (it != cache.end()) return it->second;
  Case c;
  std::mt19937 rng(static_cast<unsigned>(seed));
  auto u = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  meshkit::Scene s;
  std::uint32_t face = 0;
  add_quad(s, "medium_dry_ground", "ground", {-200, -200, 0}, {200, -200, 0}, {200, 200, 0}, {-200, 200, 0}, face);
  if (kind == "street") {
    add_box(s, {-80, 9, 0}, {80, 20, 12}, "concrete", "north", face);
    add_box(s, {-80, -20, 0}, {80, -9, 15}, "brick", "south", face);
    for (int b = 0; b < 5; ++b) {
      const double x = u(-50, 50), y = u(-6, 6);
      add_box(s, {x - 2.25, y - 0.9, 0}, {x + 2.25, y + 0.9, 1.5}, "metal", "box" + std::to_string(b), face);
    }
    for (int a = 0; a < 6; ++a)
      c.nodes.push_back(tracer::Node{"n" + std::to_string(a), {u(-50, 50), u(-8, 8), u(1.2, 2.0)}, {0, 0, 0},
                                     {1, 0, 0}, -1});
    c.scene = std::make_unique<tracer::TraceScene>(s);
    c.depth = 3;
  } else {
    add_box(s, {-150, 12, 0}, {150, 24, 15}, "concrete", "north", face);
    c.scene = std::make_unique<tracer::TraceScene>(s);
    meshkit::VehicleLibrary lib;
    const auto& m = lib.model("passenger");
    const auto car = c.scene->add_vehicle_model("passenger", meshkit::to_scene(m), m.antenna);
    std::vector<tracer::VehiclePose> poses;
    for (int v = 0; v < 5; ++v)
      poses.push_back({"v" + std::to_string(v), car, {u(-60, 60), u(-8, 8), 0}, u(0, 1) < 0.5 ? 0.0 : tracer::kPi,
                       {0, 0, 0}});
    c.scene->set_vehicles(poses);
    c.nodes = tracer::vehicle_nodes(*c.scene);
    c.depth = 2;
  }
  return cache.emplace(std::make_pair(kind, seed), std::move(c)).first->second;
}

void by_order(const tracer::Snapshot& s, std::vector<double>& power, std::vector<double>& count) {
  power.assign(8, 0);
  count.assign(8, 0);
  for (const auto& p : s.pairs)
    for (const auto& path : p.paths) {
      std::size_t o = 0;
      for (const auto& it : path.interactions) o += it.type == tracer::InteractionType::specular;
      power[std::min<std::size_t>(o, 7)] += std::norm(path.a);
      count[std::min<std::size_t>(o, 7)] += 1;
    }
}

void BM_Search(benchmark::State& state, const std::string& kind, int seed, tracer::CandidateSearch search) {
  Case& c = get_case(kind, seed);
  if (!c.has_reference) {
    c.reference = tracer::trace_snapshot(*c.scene, c.nodes, config(c.depth, tracer::CandidateSearch::exhaustive), {});
    c.has_reference = true;
  }
  const auto cfg = config(c.depth, search);
  tracer::Snapshot snap;
  for (auto _ : state) {
    snap = tracer::trace_snapshot(*c.scene, c.nodes, cfg, {});
    benchmark::DoNotOptimize(snap.pairs.data());
  }
  std::vector<double> pf, cf, pr, cr;
  by_order(snap, pf, cf);
  by_order(c.reference, pr, cr);
  for (int o = 0; o <= c.depth; ++o) {
    state.counters["paths_o" + std::to_string(o)] = cf[o];
    state.counters["ref_o" + std::to_string(o)] = cr[o];
    state.counters["power_o" + std::to_string(o)] = pr[o] > 0 ? pf[o] / pr[o] : 1.0;
  }
  state.counters["faces"] = static_cast<double>(c.scene->face_count(0));
}

}  // namespace

int main(int argc, char** argv) {
  const std::pair<const char*, tracer::CandidateSearch> searches[] = {{"image", tracer::CandidateSearch::image},
                                                                      {"sbr", tracer::CandidateSearch::sbr},
                                                                      {"exhaustive", tracer::CandidateSearch::exhaustive}};
  for (const std::string kind : {"street", "cars"})
    for (int seed = 1; seed <= 3; ++seed)
      for (const auto& [name, search] : searches)
        benchmark::RegisterBenchmark(("BM_Search/" + kind + "/" + std::to_string(seed) + "/" + name).c_str(),
                                     BM_Search, kind, seed, search)
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
