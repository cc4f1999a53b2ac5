#include "pipeline/tradeoff/scenes.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <stdexcept>

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

std::string metres_label(double m) { return fmt::format("{:g}m", m); }

}  // namespace

TradeoffScenes::TradeoffScenes(meshkit::Scene static_scene, std::string vehicles_dir,
                               std::shared_ptr<const tracer::PrecomputeStore> store)
    : static_(std::move(static_scene)), vehicles_dir_(std::move(vehicles_dir)), store_(std::move(store)) {
  scenes_[0.0].scene = std::make_unique<tracer::TraceScene>(static_);
  scenes_[0.0].scene->set_precompute_store(store_);
  scenes_[0.0].stats.triangles_before = scenes_[0.0].stats.triangles_after = static_.triangle_count();
}

VehicleLibrary& TradeoffScenes::library(int lod) {
  const int key = library_mode() ? lod : 0;
  auto& l = libraries_[key];
  if (!l) l = std::make_unique<VehicleLibrary>(vehicles_dir_, library_mode() ? lod : -1);
  return *l;
}

SceneVariant& TradeoffScenes::scene_for(double simplify_m) {
  auto& v = scenes_[simplify_m];
  if (!v.scene) {
    const auto t = std::chrono::steady_clock::now();
    const meshkit::Scene simplified = meshkit::simplify_scene(static_, simplify_m, &v.stats);
    v.scene = std::make_unique<tracer::TraceScene>(simplified);
    v.scene->set_precompute_store(store_);
    spdlog::info("tradeoff: static geometry simplified within {} m: {} -> {} triangles ({} objects changed, {:.2f} s)",
                 simplify_m, v.stats.triangles_before, v.stats.triangles_after, v.stats.objects_simplified,
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count());
  }
  return v;
}

std::uint32_t TradeoffScenes::model(SceneVariant& sv, int lod, const std::string& key) {
  const int lib_lod = library_mode() ? lod : 0;
  auto it = sv.models.find({lib_lod, key});
  if (it == sv.models.end()) {
    const auto& m = library(lib_lod).model(key);
    it = sv.models.emplace(std::make_pair(lib_lod, key),
                           sv.scene->add_vehicle_model(m.name, meshkit::to_scene(m), m.antenna))
             .first;
  }
  return it->second;
}

std::vector<tracer::Node> TradeoffScenes::place(SceneVariant& sv, int lod, const SnapshotPoses& snap,
                                                const std::vector<NodeRow>& rsus) {
  std::vector<tracer::VehiclePose> poses;
  for (const auto& v : snap.vehicles) {
    const double yaw = yaw_from_heading(v.heading_deg);
    poses.push_back(tracer::VehiclePose{v.id, model(sv, lod, v.key), {v.x, v.y, v.z}, yaw,
                                        {v.speed_mps * std::cos(yaw), v.speed_mps * std::sin(yaw), 0}});
  }
  sv.scene->set_vehicles(poses);
  auto nodes = tracer::vehicle_nodes(*sv.scene);
  for (const auto& r : rsus) nodes.push_back(tracer::Node{"rsu/" + r.id, {r.x, r.y, r.z}, {0, 0, 0}, {1, 0, 0}, -1});
  return nodes;
}

int coarsest_lod(TradeoffScenes& scenes, const std::string& vehicles_dir, const std::vector<SnapshotPoses>& snapshots) {
  if (!scenes.library_mode()) return -1;
  std::set<std::string> used_keys;
  for (const auto& s : snapshots)
    for (const auto& v : s.vehicles) used_keys.insert(v.key);
  std::ifstream in(fs::path(vehicles_dir) / "manifest.json");
  const json manifest = json::parse(in);
  int top = 0;
  for (const auto& e : manifest.at("vehicles"))
    for (const auto& l : e.at("lods")) top = std::max(top, l.at("lod").get<int>());
  for (int lod = top; lod > 0; --lod) {
    try {
      VehicleLibrary& lib = scenes.library(lod);
      for (const auto& k : used_keys) lib.model(k);
      return lod;
    } catch (const std::invalid_argument&) {
      // an entry without this level: try a finer one
    }
  }
  return -1;
}

void add_scene_variants(const GridBase& b, const GridAxes& axes, int coarsest, TradeoffScenes& scenes,
                        std::vector<TradeoffSetting>& grid) {
  if (coarsest > 0 && coarsest != b.lod) {
    auto s = b.variant("lod" + std::to_string(coarsest));
    s.lod = coarsest;
    grid.push_back(s);
  } else {
    spdlog::info("tradeoff: no coarser vehicle LOD to compare ({})",
                 scenes.library_mode() ? "the library has no coarser level" : "built-in models: give --vehicles for LODs");
  }
  for (double m : axes.simplify) {
    if (m <= 0) continue;
    // A tolerance that changes no object traces the default's scene: its
    // row would only chart the timer's noise (on the ring road's box
    // buildings it "dominated" the default by 1 % of time).
    if (scenes.scene_for(m).stats.objects_simplified == 0) {
      spdlog::info("tradeoff: static {} leaves every object as it is: the default's scene, not charted",
                   metres_label(m));
      continue;
    }
    auto s = b.variant("static " + metres_label(m));
    s.simplify_m = m;
    grid.push_back(s);
  }
}

}  // namespace raysweep::pipeline
