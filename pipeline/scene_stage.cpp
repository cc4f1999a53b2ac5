#include "pipeline/scene_stage.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <filesystem>

#include "meshkit/city.hpp"
#include "meshkit/errors.hpp"
#include "meshkit/gltf_io.hpp"
#include "meshkit/mitsuba_io.hpp"
#include "meshkit/osm_buildings.hpp"
#include "meshkit/sumo_net.hpp"
#include "pipeline/preview.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/staged_output.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json bounds_json(const meshkit::Bounds& b) {
  if (b.empty()) return nullptr;
  return {{"min", b.min}, {"max", b.max}};
}

// Topology self-check of everything written: buildings must be closed.
json topology_json(const meshkit::Scene& scene) {
  std::size_t boundary = 0, nonmanifold = 0, inconsistent = 0;
  for (const auto& m : scene.meshes) {
    if (m.name.rfind("buildings-", 0) != 0) continue;
    const auto r = meshkit::edge_report(m);
    boundary += r.boundary_edges;
    nonmanifold += r.nonmanifold_edges;
    inconsistent += r.inconsistent_edges;
  }
  return {{"buildings_watertight", boundary == 0 && nonmanifold == 0 && inconsistent == 0},
          {"boundary_edges", boundary},
          {"nonmanifold_edges", nonmanifold},
          {"inconsistent_edges", inconsistent}};
}

// The scene and the manifest's record of where it came from.
struct BuiltScene {
  meshkit::Scene scene;
  json manifest;
};

BuiltScene import_mitsuba(const SceneArgs& args, std::vector<InputFile>& inputs) {
  if (!args.osm.empty() || !args.net.empty())
    throw std::invalid_argument("--from-mitsuba cannot be combined with --osm/--net");
  spdlog::info("importing Mitsuba scene {}", args.from_mitsuba);
  BuiltScene b;
  b.scene = meshkit::read_mitsuba(args.from_mitsuba);
  inputs.push_back({"mitsuba", args.from_mitsuba});
  json shapes = json::array();
  for (const auto& m : b.scene.meshes)
    shapes.push_back({{"name", m.name}, {"material", m.material}, {"triangles", m.triangles.size()}});
  b.manifest["source"] = "mitsuba";
  b.manifest["meshes"] = shapes;
  return b;
}

// An extract that misses the network would silently give an empty city.
void check_overlap(const SceneArgs& args, const SceneSettings& cfg, const meshkit::SumoNetwork& net,
                   const meshkit::OsmBuildings& osm, const meshkit::Projection& projection) {
  if (net.lane_shapes.empty() || osm.nodes == 0) return;
  const auto a = projection.forward(osm.min_lon, osm.min_lat);
  const auto b = projection.forward(osm.max_lon, osm.max_lat);
  double nx0 = INFINITY, ny0 = INFINITY, nx1 = -INFINITY, ny1 = -INFINITY;
  for (const auto& lane : net.lane_shapes)
    for (const auto& v : lane) {
      nx0 = std::min(nx0, v[0]), ny0 = std::min(ny0, v[1]);
      nx1 = std::max(nx1, v[0]), ny1 = std::max(ny1, v[1]);
    }
  const double m = std::max(cfg.city.clip_distance_m, 0.0);
  if (std::max(a[0], b[0]) < nx0 - m || std::min(a[0], b[0]) > nx1 + m || std::max(a[1], b[1]) < ny0 - m ||
      std::min(a[1], b[1]) > ny1 + m)
    throw meshkit::InputError(args.osm, "",
                              "the OSM extract does not overlap the network " + args.net + " (extract x " +
                                  std::to_string(std::min(a[0], b[0])) + ".." + std::to_string(std::max(a[0], b[0])) +
                                  ", network x " + std::to_string(nx0) + ".." + std::to_string(nx1) +
                                  "); wrong network or projection?");
}

BuiltScene build_from_osm(const SceneArgs& args, const SceneSettings& cfg, std::vector<InputFile>& inputs) {
  if (args.osm.empty()) throw std::invalid_argument("--osm (or --from-mitsuba) is required");
  if (args.net.empty() == args.proj.empty()) throw std::invalid_argument("give exactly one of --net or --proj");
  meshkit::SumoNetwork net;
  std::string proj_string;
  meshkit::Vec2 offset{0, 0};
  if (!args.net.empty()) {
    spdlog::info("reading network {}", args.net);
    net = meshkit::read_sumo_network(args.net);
    proj_string = net.proj_parameter;
    offset = net.net_offset;
    inputs.push_back({"net", args.net});
  } else {
    proj_string = args.proj;
    offset = args.net_offset.value_or(meshkit::Vec2{0, 0});
  }
  inputs.push_back({"osm", args.osm});
  meshkit::Projection projection(proj_string, offset);
  spdlog::info("reading OSM {}", args.osm);
  const auto osm =
      meshkit::read_osm_buildings(args.osm, [&](double lon, double lat) { return projection.forward(lon, lat); });
  spdlog::info("{} nodes, {} ways, {} relations; {} building candidates", osm.nodes, osm.ways, osm.relations,
               osm.buildings.size() + osm.skipped.size());
  check_overlap(args, cfg, net, osm, projection);

  auto city = meshkit::build_city(osm, net.lane_shapes, cfg.city, [](std::size_t done, std::size_t total) {
    spdlog::info("footprints {}/{}", done, total);
  });
  for (const auto& w : city.report.warnings) spdlog::warn("{}", w);
  if (city.report.kept.empty()) spdlog::warn("{}: no building kept (see skipped_by_reason in the manifest)", args.osm);
  BuiltScene b;
  b.scene = std::move(city.scene);
  b.manifest = meshkit::to_json(city.report);
  b.manifest["source"] = "osm";
  b.manifest["projection"] = {{"proj", proj_string}, {"net_offset", offset}};
  if (!args.net.empty()) b.manifest["network"] = {{"edges", net.edge_count}, {"lanes", net.lane_shapes.size()}};
  b.manifest["osm"] = {{"nodes", osm.nodes}, {"ways", osm.ways}, {"relations", osm.relations}};
  return b;
}

// What the manifest says of the scene itself: bounds, materials, counts, topology, files.
void describe_scene(const meshkit::Scene& scene, json& manifest) {
  manifest["bounds"] = bounds_json(scene.bounds());
  std::map<std::string, std::size_t> tri_by_mat;
  for (const auto& m : scene.meshes) tri_by_mat[m.material] += m.triangles.size();
  std::vector<std::string> materials;
  for (const auto& [m, n] : tri_by_mat) materials.push_back(m);
  manifest["materials"] = materials;
  manifest["triangle_count"] = scene.triangle_count();
  manifest["object_count"] = scene.objects.size();
  manifest["topology"] = topology_json(scene);
  manifest["files"] = {{"gltf", "scene.glb"}, {"mitsuba", "mitsuba/scene.xml"}};
}

}  // namespace

json run_scene_stage(const SceneArgs& args, const Settings& settings, const std::vector<std::string>& argv) {
  const auto t0 = std::chrono::steady_clock::now();
  if (args.out.empty()) throw std::invalid_argument("--out is required");
  SceneSettings cfg = settings.scene;
  if (args.draco) cfg.draco = *args.draco;

  std::vector<InputFile> inputs;
  if (!settings.file.empty()) inputs.push_back({"config", settings.file});
  BuiltScene built = args.from_mitsuba.empty() ? build_from_osm(args, cfg, inputs) : import_mitsuba(args, inputs);
  const meshkit::Scene& scene = built.scene;
  json& manifest = built.manifest;
  describe_scene(scene, manifest);
  manifest["provenance"] = provenance("scene", inputs, cfg.to_json(), argv);
  settings.record_sets(manifest["provenance"]);

  StagedDirectory out(args.out);
  meshkit::GltfOptions gopt;
  gopt.draco = cfg.draco;
  gopt.draco_position_bits = cfg.draco_position_bits;
  if (gopt.draco) spdlog::warn("scene.glb {}", meshkit::kDracoReadersNote);
  meshkit::write_glb(scene, (out.path() / "scene.glb").string(), gopt);
  meshkit::write_mitsuba(scene, (out.path() / "mitsuba").string());
  const auto t1 = std::chrono::steady_clock::now();
  write_file_atomic(out.path() / "manifest.json", manifest.dump(2) + "\n");
  if (args.preview && run_python_script("scene_preview.py", {out.path().string()})) {
    manifest["files"]["preview"] = "preview.png";
    write_file_atomic(out.path() / "manifest.json", manifest.dump(2) + "\n");
  }
  out.commit();
  spdlog::info("scene written to {} ({} triangles, {} objects, {:.2f} s)", args.out, scene.triangle_count(),
               scene.objects.size(), std::chrono::duration<double>(t1 - t0).count());
  return manifest;
}

}  // namespace raysweep::pipeline
