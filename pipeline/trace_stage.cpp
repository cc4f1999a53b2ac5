#include "pipeline/trace_stage.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>
#include <optional>
#include <filesystem>
#include <fstream>

#include "meshkit/gltf_io.hpp"
#include "pipeline/peer_export.hpp"
#include "pipeline/precompute_store.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/scene_cache.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/trace_h5.hpp"
#include "pipeline/trace_inputs.hpp"
#include "pipeline/trace_json.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Through a temporary sibling, as every output.
void write_trace_file(const std::string& path, const TraceDocument& doc) {
  StagedFile staged(path);
  {
    std::ofstream out(staged.path(), std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error(path + ": cannot create");
    write_trace_json(out, doc);
    out.close();
    if (!out) throw std::runtime_error(path + ": write failed");
  }
  staged.commit();
}

}  // namespace

namespace {

// The snapshot's scene, vehicles and antennas, and the files they came from.
struct SnapshotInputs {
  std::optional<tracer::TraceScene> scene;
  std::vector<PoseRow> poses;
  std::vector<NodeRow> antennas;
  std::vector<tracer::Node> nodes;
  std::vector<meshkit::VehicleDims> dims;
  std::vector<InputFile> files;
};

void add_poses(const TraceArgs& args, SnapshotInputs& in) {
  VehicleLibrary library(args.vehicles, args.lod);
  in.poses = read_poses_csv(args.poses);
  in.files.push_back({"poses", args.poses});
  try {
    place_vehicles(*in.scene, library, in.poses);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(args.poses + ": " + e.what());
  }
  for (const auto& p : in.poses) in.dims.push_back(library.model(p.vclass).dims());
  for (const auto& f : library.files()) in.files.push_back({"vehicle_model", f});
}

void add_antennas(const TraceArgs& args, SnapshotInputs& in) {
  in.files.push_back({"nodes", args.nodes});
  in.antennas = read_nodes_csv(args.nodes);
  for (const auto& r : in.antennas) {
    for (const auto& n : in.nodes)
      if (n.id == r.id) throw std::invalid_argument(args.nodes + ": node id '" + r.id + "' is also a vehicle id");
    in.nodes.push_back(tracer::Node{r.id, {r.x, r.y, r.z}, {0, 0, 0}, {1, 0, 0}, -1});
  }
}

// Fills `in` (its scene cannot move).
void load_snapshot(const TraceArgs& args, const std::string& config_file, SnapshotInputs& in) {
  const fs::path scene_file = fs::path(args.scene) / "scene.glb";
  if (!fs::exists(scene_file))
    throw std::invalid_argument(args.scene + ": no scene.glb (run `raysweep scene` first)");
  in.scene.emplace(exclude_objects(read_scene_glb(scene_file.parent_path()), args.exclude_objects));
  in.scene->set_precompute_store(scene_precompute_store(args.scene));
  in.files.push_back({"scene", scene_file.string()});
  if (!config_file.empty()) in.files.push_back({"config", config_file});
  if (!args.poses.empty()) add_poses(args, in);
  in.nodes = tracer::vehicle_nodes(*in.scene);
  if (!args.nodes.empty()) add_antennas(args, in);
  if (in.nodes.size() < 2) throw std::invalid_argument("trace: need at least two antennas (--poses and/or --nodes)");
}

void write_json_output(const TraceArgs& args, const SnapshotInputs& in, const tracer::Snapshot& snap,
                       const tracer::OfdmGrid* grid, const json& config, const json& prov) {
  const std::vector<std::string> objects = in.scene->object_names();
  TraceDocument doc;
  doc.snapshot = &snap;
  doc.nodes = &in.nodes;
  doc.objects = &objects;
  doc.materials = &in.scene->material_names();
  doc.grid = grid;
  doc.cfr_spec = args.cfr;
  doc.radio = config["radio"];
  doc.provenance = prov;
  write_trace_file(args.out, doc);
}

void write_h5_output(const TraceArgs& args, const SnapshotInputs& in, const tracer::Snapshot& snap,
                     const tracer::OfdmGrid* grid, const TraceSettings& settings, const json& config,
                     const json& prov, const std::vector<char>& inside) {
  const auto header = channel_dataset_header(config, prov, settings.radio, grid);
  SnapshotNodes nodes;
  nodes.nodes = &in.nodes;
  nodes.poses = &in.poses;
  nodes.antennas = &in.antennas;
  nodes.dims = in.dims;
  nodes.static_objects = in.scene->object_names();
  nodes.static_objects.resize(in.scene->static_object_count());
  nodes.enclosed = inside;
  write_trace_dataset(args.out, header, snap, nodes, grid);
}

json trace_summary(const tracer::Snapshot& snap, std::size_t antennas, double load_s, double trace_s, double total_s) {
  std::size_t los = 0, nlosv = 0, nlos = 0;
  for (const auto& p : snap.pairs)
    (p.los_class == tracer::LosClass::LOS ? los : p.los_class == tracer::LosClass::NLOSV ? nlosv : nlos)++;
  spdlog::info(
      "traced {} antennas, {} pairs ({} LOS / {} NLOSV / {} NLOS), {} paths in {:.1f} ms; total {:.2f} s "
      "(inputs {:.0f} ms, writing {:.0f} ms)",
      antennas, snap.pairs.size(), los, nlosv, nlos, snap.stats.paths, trace_s * 1e3, total_s, load_s * 1e3,
      (total_s - load_s - trace_s) * 1e3);
  return {{"pairs", snap.pairs.size()}, {"paths", snap.stats.paths}, {"los", los}, {"nlosv", nlosv},
          {"nlos", nlos}, {"trace_ms", trace_s * 1e3}};
}

// The antennas standing inside a building's closed volume, warned about
// by name (their channels pass through its walls): [{id, object}].
// `inside`: per node.
json enclosed_antennas(const tracer::TraceScene& scene, const std::vector<tracer::Node>& nodes,
                       std::vector<char>& inside) {
  json out = json::array();
  const auto objects = scene.object_names();
  inside.assign(nodes.size(), 0);
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    const auto& n = nodes[k];
    const std::int64_t o = scene.enclosing_object(n.position);
    if (o < 0) continue;
    inside[k] = 1;
    out.push_back({{"id", n.id}, {"object", objects.at(static_cast<std::size_t>(o))}});
    spdlog::warn("antenna {} at ({:.2f}, {:.2f}, {:.2f}) stands inside {}'s closed volume: its channels pass "
                 "through the walls (a lane through the building's footprint?)",
                 n.id, n.position[0], n.position[1], n.position[2], objects.at(static_cast<std::size_t>(o)));
  }
  return out;
}

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

json run_trace_stage(const TraceArgs& args, const Settings& all, const std::vector<std::string>& argv) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto ext = fs::path(args.out).extension().string();
  if (args.out.empty() && args.mitsuba.empty())
    throw std::invalid_argument("trace: nothing to write (--out and/or --mitsuba)");
  if (!args.out.empty() && ext != ".json" && ext != ".h5")
    throw std::invalid_argument(args.out + ": output must end in .json (trace document) or .h5 (channel dataset)");
  const TraceSettings& settings = all.trace;
  std::optional<tracer::OfdmGrid> grid;
  if (!args.cfr.empty())
    grid = tracer::ofdm_grid(tracer::parse_ofdm_grid_spec(args.cfr, "--cfr"), settings.radio.frequency_hz);
  SnapshotInputs in;
  load_snapshot(args, all.file, in);
  std::vector<char> inside;
  const json enclosed = enclosed_antennas(*in.scene, in.nodes, inside);

  json config = settings.to_json();
  config["vehicles"] = args.vehicles.empty() ? "built-in parametric" : args.vehicles;
  config["lod"] = args.lod;
  config["exclude_objects"] = args.exclude_objects;
  config["cfr"] = args.cfr;
  json prov = provenance("trace", in.files, config, argv);
  all.record_sets(prov);
  prov["embree"] = tracer::embree_version();
  if (!args.mitsuba.empty()) {
    write_peer_scene(*in.scene, in.nodes, settings, prov, args.mitsuba);
    spdlog::info("{}: the snapshot for a peer tracer ({} antennas)", args.mitsuba, in.nodes.size());
  }
  if (args.out.empty()) return {{"nodes", in.nodes.size()}, {"mitsuba", args.mitsuba}};

  const auto t1 = std::chrono::steady_clock::now();
  const double load_s = seconds_since(t0);
  const auto snap = tracer::trace_snapshot(*in.scene, in.nodes, settings.tracer, settings.radio);
  const double trace_s = seconds_since(t1);

  if (!fs::path(args.out).parent_path().empty()) fs::create_directories(fs::path(args.out).parent_path());
  const tracer::OfdmGrid* g = grid ? &*grid : nullptr;
  if (ext == ".h5") write_h5_output(args, in, snap, g, settings, config, prov, inside);
  else write_json_output(args, in, snap, g, config, prov);
  json summary = trace_summary(snap, in.nodes.size(), load_s, trace_s, seconds_since(t0));
  if (!enclosed.empty()) summary["enclosed"] = enclosed;
  return summary;
}

}  // namespace raysweep::pipeline
