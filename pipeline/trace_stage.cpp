#include "pipeline/trace_stage.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>
#include <optional>
#include <filesystem>

#include "meshkit/gltf_io.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/trace_inputs.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// JSON has no infinities: a pair without paths reports null gains.
json db_or_null(double linear) {
  if (!(linear > 0)) return nullptr;
  return tracer::to_db(linear);
}

}  // namespace

json snapshot_json(const tracer::Snapshot& snap, const std::vector<tracer::Node>& nodes,
                   const std::vector<std::string>& objects, const std::vector<std::string>& materials) {
  json pairs = json::array();
  for (const auto& p : snap.pairs) {
    json paths = json::array();
    for (const auto& path : p.paths) {
      json inter = json::array();
      for (const auto& i : path.interactions)
        inter.push_back({{"type", tracer::interaction_name(i.type)},
                         {"object", objects.at(i.object)},
                         {"material", materials.at(i.material)},
                         {"point", i.point}});
      paths.push_back({{"a_re", path.a.real()},
                       {"a_im", path.a.imag()},
                       {"tau_s", path.tau_s},
                       {"theta_t", path.theta_t},
                       {"phi_t", path.phi_t},
                       {"theta_r", path.theta_r},
                       {"phi_r", path.phi_r},
                       {"doppler_hz", path.doppler_hz},
                       {"interactions", inter}});
    }
    json blockers = json::array();
    for (auto b : p.blockers) blockers.push_back(objects.at(b));
    pairs.push_back({{"tx", nodes[p.tx].id},
                     {"rx", nodes[p.rx].id},
                     {"los_class", tracer::los_class_name(p.los_class)},
                     {"los_class_fresnel", tracer::los_class_name(p.fresnel_class)},
                     {"fresnel_clearance", p.fresnel_clearance},
                     {"vehicle_loss_db", p.vehicle_loss_db},
                     {"blockers", blockers},
                     {"path_gain_db", db_or_null(p.stats.gain_coherent)},
                     {"path_gain_incoherent_db", db_or_null(p.stats.gain_incoherent)},
                     {"delay_s", p.stats.first_delay_s},
                     {"rms_delay_spread_s", p.stats.rms_delay_spread_s},
                     {"n_paths", p.paths.size()},
                     {"candidates", p.candidates},
                     {"dropped_transmission_cap", p.dropped_transmission_cap},
                     {"paths_below_threshold", p.dropped_threshold},
                     {"out_of_range", p.out_of_range},
                     {"paths", paths}});
  }
  json node_list = json::array();
  for (const auto& n : nodes)
    node_list.push_back({{"id", n.id}, {"position", n.position}, {"velocity", n.velocity}, {"vehicle", n.vehicle}});
  return {{"nodes", node_list},
          {"pairs", pairs},
          {"stats",
           {{"rays", snap.stats.rays},
            {"candidates", snap.stats.candidates},
            {"paths", snap.stats.paths},
            {"dropped_transmission_cap", snap.stats.dropped_transmission_cap},
            {"paths_below_threshold", snap.stats.dropped_threshold},
            {"out_of_range_pairs", snap.stats.out_of_range_pairs},
            {"diffraction_paths", snap.stats.diffraction_paths},
            {"diffuse_paths", snap.stats.diffuse_paths}}}};
}

json run_trace_stage(const TraceArgs& args, const Settings& all, const std::vector<std::string>& argv) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto ext = fs::path(args.out).extension().string();
  if (ext == ".h5")
    throw std::invalid_argument(args.out + ": HDF5 output comes with the dataset schema (raysweep sweep); "
                                "write .json for a single snapshot");
  if (ext != ".json") throw std::invalid_argument(args.out + ": output must end in .json");
  const TraceSettings& settings = all.trace;
  std::optional<tracer::OfdmGrid> grid;
  if (!args.cfr.empty()) grid = tracer::ofdm_grid(tracer::parse_ofdm_grid_spec(args.cfr, "--cfr"), settings.radio.frequency_hz);

  const fs::path scene_file = fs::path(args.scene) / "scene.glb";
  if (!fs::exists(scene_file))
    throw std::invalid_argument(args.scene + ": no scene.glb (run `raysweep scene` first)");
  tracer::TraceScene scene(exclude_objects(meshkit::read_glb(scene_file.string()), args.exclude_objects));

  std::vector<InputFile> inputs{{"scene", scene_file.string()}};
  if (!all.file.empty()) inputs.push_back({"config", all.file});
  VehicleLibrary library(args.vehicles, args.lod);
  std::vector<PoseRow> poses;
  if (!args.poses.empty()) {
    poses = read_poses_csv(args.poses);
    inputs.push_back({"poses", args.poses});
    try {
      place_vehicles(scene, library, poses);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(args.poses + ": " + e.what());
    }
    for (const auto& f : library.files()) inputs.push_back({"vehicle_model", f});
  }
  auto nodes = tracer::vehicle_nodes(scene);
  if (!args.nodes.empty()) {
    inputs.push_back({"nodes", args.nodes});
    for (const auto& r : read_nodes_csv(args.nodes)) {
      for (const auto& n : nodes)
        if (n.id == r.id) throw std::invalid_argument(args.nodes + ": node id '" + r.id + "' is also a vehicle id");
      nodes.push_back(tracer::Node{r.id, {r.x, r.y, r.z}, {0, 0, 0}, {1, 0, 0}, -1});
    }
  }
  if (nodes.size() < 2) throw std::invalid_argument("trace: need at least two antennas (--poses and/or --nodes)");

  const auto t1 = std::chrono::steady_clock::now();
  const auto snap = tracer::trace_snapshot(scene, nodes, settings.tracer, settings.radio);
  const double trace_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();

  json out = snapshot_json(snap, nodes, scene.object_names(), scene.material_names());
  if (grid) {
    out["cfr_grid"] = {{"spec", args.cfr},
                       {"carrier_hz", grid->carrier_hz},
                       {"subcarrier_spacing_hz", grid->subcarrier_spacing_hz},
                       {"n_subcarriers", grid->n_subcarriers},
                       {"first_offset_hz", grid->offset_hz(0)}};
    for (std::size_t i = 0; i < snap.pairs.size(); ++i) {
      const auto h = tracer::frequency_response(snap.pairs[i].paths, *grid);
      json re = json::array(), im = json::array();
      for (const auto& v : h) {
        re.push_back(v.real());
        im.push_back(v.imag());
      }
      out["pairs"][i]["cfr_re"] = re;
      out["pairs"][i]["cfr_im"] = im;
    }
  }
  json config = settings.to_json();
  config["vehicles"] = args.vehicles.empty() ? "built-in parametric" : args.vehicles;
  config["lod"] = args.lod;
  config["exclude_objects"] = args.exclude_objects;
  config["cfr"] = args.cfr;
  out["radio"] = config["radio"];
  out["provenance"] = provenance("trace", inputs, config, argv);
  all.record_sets(out["provenance"]);
  out["provenance"]["embree"] = tracer::embree_version();
  if (!fs::path(args.out).parent_path().empty()) fs::create_directories(fs::path(args.out).parent_path());
  write_file_atomic(args.out, out.dump(1) + "\n");
  std::size_t los = 0, nlosv = 0, nlos = 0;
  for (const auto& p : snap.pairs)
    (p.los_class == tracer::LosClass::LOS ? los : p.los_class == tracer::LosClass::NLOSV ? nlosv : nlos)++;
  spdlog::info("traced {} antennas, {} pairs ({} LOS / {} NLOSV / {} NLOS), {} paths in {:.1f} ms; total {:.2f} s",
               nodes.size(), snap.pairs.size(), los, nlosv, nlos, snap.stats.paths, trace_s * 1e3,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return {{"pairs", snap.pairs.size()}, {"paths", snap.stats.paths}, {"los", los}, {"nlosv", nlosv},
          {"nlos", nlos}, {"trace_ms", trace_s * 1e3}};
}

}  // namespace raysweep::pipeline
