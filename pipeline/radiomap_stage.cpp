#include "pipeline/radiomap_stage.hpp"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "generators/dataset/dataset_reader.hpp"
#include "meshkit/gltf_io.hpp"
#include "meshkit/sumo_net.hpp"
#include "pipeline/preview.hpp"
#include "pipeline/precompute_store.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/quantile.hpp"
#include "pipeline/radiomap_vdb.hpp"
#include "pipeline/render_stage.hpp"
#include "pipeline/scene_cache.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/sweep_stage.hpp"
#include "pipeline/trace_stage.hpp"
#include "pipeline/trace_inputs.hpp"
#include "tracer/radiomap_solver.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;
using tracer::Vec3;
using Voxel = std::array<std::int32_t, 3>;

namespace {

// Path gain stored where a voxel has no path (out of range, or nothing
// reaches it); recorded as the grids' `no_path_db` metadata.
constexpr float kNoPathDb = -300.0f;

// The network the scene was built against (its manifest's "net" input).
std::string scene_network(const std::string& scene_dir) {
  std::ifstream in(fs::path(scene_dir) / "manifest.json");
  if (!in) return {};
  try {
    const json m = json::parse(in);
    for (const auto& i : m.at("provenance").at("inputs"))
      if (i.value("role", "") == "net" && fs::exists(i.value("path", ""))) return i["path"].get<std::string>();
  } catch (const json::exception&) {
  }
  return {};
}

// Voxel columns (i, j) whose centre (i v, j v) lies within `margin` of a lane
// centre line, sorted.
std::vector<std::array<std::int32_t, 2>> street_columns(const meshkit::SumoNetwork& net, double v, double margin) {
  std::set<std::array<std::int32_t, 2>> cols;
  for (const auto& lane : net.lane_shapes)
    for (std::size_t s = 0; s + 1 < lane.size(); ++s) {
      const double ax = lane[s][0], ay = lane[s][1], bx = lane[s + 1][0], by = lane[s + 1][1];
      const double dx = bx - ax, dy = by - ay, len2 = dx * dx + dy * dy;
      const auto i0 = static_cast<std::int32_t>(std::floor((std::min(ax, bx) - margin) / v));
      const auto i1 = static_cast<std::int32_t>(std::ceil((std::max(ax, bx) + margin) / v));
      const auto j0 = static_cast<std::int32_t>(std::floor((std::min(ay, by) - margin) / v));
      const auto j1 = static_cast<std::int32_t>(std::ceil((std::max(ay, by) + margin) / v));
      for (auto i = i0; i <= i1; ++i)
        for (auto j = j0; j <= j1; ++j) {
          const double px = i * v, py = j * v;
          const double t = len2 > 0 ? std::clamp(((px - ax) * dx + (py - ay) * dy) / len2, 0.0, 1.0) : 0.0;
          const double ex = ax + t * dx - px, ey = ay + t * dy - py;
          if (ex * ex + ey * ey <= margin * margin) cols.insert({i, j});
        }
    }
  return {cols.begin(), cols.end()};
}

}  // namespace

namespace {

// The settings with the command line's transmitters, checked; each
// transmitter's power defaults to the radio's.
RadioMapSettings checked_settings(const RadioMapArgs& args, const Settings& all, const std::string& cfg_name) {
  RadioMapSettings s = all.radiomap;
  for (const auto& spec : args.tx) s.tx.push_back(parse_radiomap_tx(spec, "--tx"));
  // Each key's own range is the schema's (settings/tables.cpp); this one spans two keys.
  if (s.z_min_m > s.z_max_m)
    throw std::invalid_argument(cfg_name + ": radiomap.z_min_m (" + std::to_string(s.z_min_m) +
                                ") must not exceed radiomap.z_max_m (" + std::to_string(s.z_max_m) + ")");
  if (s.tx.empty()) throw std::invalid_argument("radiomap: no transmitter (--tx ID,X,Y,Z or [radiomap] tx)");
  std::set<std::string> ids;
  for (auto& t : s.tx) {
    if (!ids.insert(t.id).second) throw std::invalid_argument("radiomap: transmitter id '" + t.id + "' twice");
    if (!t.power_given) t.power_dbm = all.trace.radio.tx_power_dbm;
  }
  return s;
}

// The vehicles of --poses placed in the scene (their files recorded as inputs).
void place_poses(const RadioMapArgs& args, tracer::TraceScene& scene, std::vector<InputFile>& inputs) {
  VehicleLibrary library(args.vehicles, args.lod);
  inputs.push_back({"poses", args.poses});
  try {
    place_vehicles(scene, library, read_poses_csv(args.poses));
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(args.poses + ": " + e.what());
  }
  for (const auto& f : library.files()) inputs.push_back({"vehicle_model", f});
}

// The region ("streets" or "all") and its voxel columns.
struct MapRegion {
  std::string name;
  std::vector<std::array<std::int32_t, 2>> columns;
};

MapRegion map_region(const RadioMapArgs& args, const RadioMapSettings& s, const tracer::TraceScene& scene,
                     std::vector<InputFile>& inputs) {
  const std::string net_path = args.net.empty() ? scene_network(args.scene) : args.net;
  MapRegion r;
  r.name = s.region.empty() ? (net_path.empty() ? "all" : "streets") : s.region;
  if (r.name == "streets" && net_path.empty())
    throw std::invalid_argument("radiomap: region \"streets\" needs a SUMO network (--net, or a scene built with one)");
  const double v = s.voxel_m;
  if (r.name == "streets") {
    const auto net = meshkit::read_sumo_network(net_path);
    inputs.push_back({"net", net_path});
    r.columns = street_columns(net, v, s.street_margin_m);
  } else {
    const auto b = scene.static_bounds();
    for (auto i = static_cast<std::int32_t>(std::ceil(b.min[0] / v)); i * v <= b.max[0]; ++i)
      for (auto j = static_cast<std::int32_t>(std::ceil(b.min[1] / v)); j * v <= b.max[1]; ++j)
        r.columns.push_back({i, j});
  }
  return r;
}

// The voxels of the open air and their centres: centres inside a building are never active.
struct OpenVoxels {
  std::vector<Voxel> voxels;
  std::vector<Vec3> points;
};

OpenVoxels open_voxels(const MapRegion& region, long layers, const RadioMapSettings& s,
                       const tracer::TraceScene& scene) {
  const double v = s.voxel_m;
  std::vector<Voxel> candidates;
  for (const auto& c : region.columns)
    for (std::int32_t k = 0; k < layers; ++k) candidates.push_back({c[0], c[1], k});
  auto centre = [&](const Voxel& x) { return Vec3{x[0] * v, x[1] * v, s.z_min_m + x[2] * v}; };
  std::vector<unsigned char> open(candidates.size(), 0);
  tbb::parallel_for(std::size_t{0}, candidates.size(),
                    [&](std::size_t n) { open[n] = !tracer::inside_static(scene, centre(candidates[n])); });
  OpenVoxels o;
  for (std::size_t n = 0; n < candidates.size(); ++n)
    if (open[n]) {
      o.voxels.push_back(candidates[n]);
      o.points.push_back(centre(candidates[n]));
    }
  return o;
}

// Diffuse scattering: the voxels where it is gathered exactly (one per
// block and layer, nearest the block's centre), and each voxel's row among them.
struct DiffuseSamples {
  std::vector<std::uint32_t> at;       // per voxel: row in `samples`
  std::vector<std::uint32_t> samples;  // voxel indices
};

DiffuseSamples diffuse_samples(const std::vector<Voxel>& voxels, const RadioMapSettings& s) {
  const double v = s.voxel_m;
  const double b = s.diffuse_block_m > 0 ? s.diffuse_block_m : v;
  DiffuseSamples d;
  d.at.resize(voxels.size());
  std::map<std::array<long, 3>, std::pair<double, std::uint32_t>> nearest;  // block -> (distance, voxel)
  auto block_of = [&](const Voxel& x) {
    return std::array<long, 3>{static_cast<long>(std::floor(x[0] * v / b)), static_cast<long>(std::floor(x[1] * v / b)),
                               static_cast<long>(x[2])};
  };
  for (std::size_t n = 0; n < voxels.size(); ++n) {
    const auto key = block_of(voxels[n]);
    const double dx = voxels[n][0] * v - (key[0] + 0.5) * b, dy = voxels[n][1] * v - (key[1] + 0.5) * b;
    const double dist = s.diffuse_block_m > 0 ? std::hypot(dx, dy) : 0.0;
    auto [it, fresh] = nearest.try_emplace(key, dist, static_cast<std::uint32_t>(n));
    if (!fresh && dist < it->second.first) it->second = {dist, static_cast<std::uint32_t>(n)};
  }
  std::map<std::uint32_t, std::uint32_t> sample_index;  // voxel -> row in samples
  for (const auto& [key, dn] : nearest) sample_index.emplace(dn.second, 0);
  for (auto& [n, row] : sample_index) {
    row = static_cast<std::uint32_t>(d.samples.size());
    d.samples.push_back(n);
  }
  for (std::size_t n = 0; n < voxels.size(); ++n) d.at[n] = sample_index.at(nearest.at(block_of(voxels[n])).second);
  spdlog::info("radio map: diffuse scattering gathered at {} voxels (blocks of {} m)", d.samples.size(), b);
  return d;
}

// What the transmitters give: two grids each (path gain, LoS class), the
// strongest received power and its transmitter per voxel, and the timings.
struct TxMaps {
  std::vector<VdbGrid> grids;
  std::vector<float> rss;
  std::vector<std::int32_t> best;
  json per_tx = json::array();
  double solve_s = 0;
};

// The path gain at every voxel centre from `tx`, diffuse scattering added
// where `diffuse` has samples.
std::vector<tracer::RadioMapPointResult> solve_tx(const tracer::TraceScene& scene, const tracer::Node& node,
                                                  const OpenVoxels& o, const DiffuseSamples* diffuse,
                                                  const TraceSettings& trace, tracer::RadioMapSolveStats& st) {
  auto res = tracer::solve_points(scene, node, o.points, trace.tracer, trace.radio, &st);
  if (!diffuse) return res;
  std::vector<tracer::Node> nodes{node};
  std::vector<std::uint32_t> receivers;
  for (auto n : diffuse->samples) {
    tracer::Node p;
    p.id = "v" + std::to_string(n);
    p.position = o.points[n];
    receivers.push_back(static_cast<std::uint32_t>(nodes.size()));
    nodes.push_back(p);
  }
  const auto power = tracer::diffuse_power(scene, nodes, 0, receivers, trace.tracer, trace.radio);
  for (std::size_t n = 0; n < o.voxels.size(); ++n) res[n].gain += power[diffuse->at[n]];
  return res;
}

// Per transmitter: path gain and LoS class at every voxel centre.
TxMaps solve_transmitters(const tracer::TraceScene& scene, const RadioMapSettings& s, const OpenVoxels& o,
                          const DiffuseSamples* diffuse, const TraceSettings& trace) {
  const std::size_t nv = o.voxels.size();
  TxMaps m;
  m.rss.assign(nv, kNoPathDb);
  m.best.assign(nv, -1);
  for (std::size_t t = 0; t < s.tx.size(); ++t) {
    const auto& tx = s.tx[t];
    tracer::Node node;
    node.id = tx.id;
    node.position = tx.position;
    const auto t1 = std::chrono::steady_clock::now();
    tracer::RadioMapSolveStats st;
    const auto res = solve_tx(scene, node, o, diffuse, trace, st);
    const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
    m.solve_s += sec;
    VdbGrid pg{"path_gain_db." + tx.id, true, {}, {}, kNoPathDb, 0, json::object()};
    VdbGrid lc{"los_class." + tx.id, false, {}, {}, 0, -1, json::object()};
    pg.f.resize(nv);
    lc.i.resize(nv);
    for (std::size_t n = 0; n < nv; ++n) {
      pg.f[n] = res[n].gain > 0 ? static_cast<float>(tracer::to_db(res[n].gain)) : kNoPathDb;
      lc.i[n] = static_cast<std::int32_t>(res[n].los);
      const float p = pg.f[n] > kNoPathDb ? static_cast<float>(tx.power_dbm) + pg.f[n] : kNoPathDb;
      if (p > m.rss[n]) {
        m.rss[n] = p;
        m.best[n] = static_cast<std::int32_t>(t);
      }
    }
    const json tx_meta = {{"tx_id", tx.id}, {"tx_position_m", tx.position}, {"tx_power_dbm", tx.power_dbm}};
    pg.meta = tx_meta;
    pg.meta["quantity"] = "incoherent path gain sum |a|^2 at the voxel centre (dB)";
    pg.meta["no_path_db"] = kNoPathDb;
    lc.meta = tx_meta;
    lc.meta["quantity"] = "geometric LoS class of the direct segment: 0 LOS, 1 NLOSV, 2 NLOS";
    m.grids.push_back(std::move(pg));
    m.grids.push_back(std::move(lc));
    m.per_tx.push_back({{"id", tx.id}, {"seconds", sec}, {"voxels_per_s", nv / std::max(sec, 1e-9)},
                        {"paths", st.paths}, {"rays", st.rays}, {"out_of_range", st.out_of_range}});
    spdlog::info("radio map: {} in {:.2f} s ({:.0f} voxels/s, {} paths)", tx.id, sec, nv / std::max(sec, 1e-9),
                 st.paths);
  }
  return m;
}

// The strongest received power, its transmitter, and the display grid: that
// power mapped to [0, 1] from the sensitivity to the map's peak.
void add_best_server_grids(TxMaps& m, double floor_dbm) {
  float peak = kNoPathDb;
  for (float p : m.rss) peak = std::max(peak, p);
  VdbGrid density{"density", true, {}, {}, 0, 0, json::object()};
  density.f.resize(m.rss.size());
  for (std::size_t n = 0; n < m.rss.size(); ++n)
    density.f[n] = peak > floor_dbm
                       ? static_cast<float>(std::clamp((m.rss[n] - floor_dbm) / (peak - floor_dbm), 0.0, 1.0))
                       : 0.0f;
  density.meta = {{"quantity", "rss_dbm mapped linearly to [0, 1] from sensitivity_dbm to the map's peak"},
                  {"floor_dbm", floor_dbm}, {"peak_dbm", peak}};
  m.grids.push_back(VdbGrid{"rss_dbm", true, m.rss, {}, kNoPathDb, 0,
                            {{"quantity", "received power of the strongest transmitter: tx_power_dbm + path_gain_db (dBm)"},
                             {"no_path_db", kNoPathDb}}});
  m.grids.push_back(VdbGrid{"best_server", false, {}, m.best, 0, -1,
                            {{"quantity", "index into the file's tx list of the strongest transmitter (-1: none)"}}});
  m.grids.push_back(std::move(density));
}

// Agreement with the per-point tracer (`raysweep trace`) at `count` sampled
// voxels, for the first transmitter (its grids are grids[0] and grids[1]).
json check_vs_trace(int count, const RadioMapTx& tx, const OpenVoxels& o, const std::vector<VdbGrid>& grids,
                    const tracer::TraceScene& scene, const TraceSettings& trace) {
  std::vector<tracer::Node> nodes(1);
  nodes[0].id = tx.id;
  nodes[0].position = tx.position;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  std::vector<std::size_t> which;
  const std::size_t nv = o.voxels.size();
  const std::size_t step = std::max<std::size_t>(1, nv / static_cast<std::size_t>(count));
  for (std::size_t n = step / 2; n < nv && which.size() < static_cast<std::size_t>(count); n += step) {
    tracer::Node p;
    p.id = "v" + std::to_string(n);
    p.position = o.points[n];
    nodes.push_back(p);
    which.push_back(n);
    pairs.emplace_back(0, static_cast<std::uint32_t>(nodes.size() - 1));
  }
  const auto snap = tracer::trace_pairs(scene, nodes, pairs, trace.tracer, trace.radio);
  const double floor_dbm = trace.radio.sensitivity_dbm;
  std::vector<double> diff;
  std::size_t los_agree = 0;
  for (std::size_t q = 0; q < which.size(); ++q) {
    const double g = snap.pairs[q].stats.gain_incoherent;
    if (static_cast<std::int32_t>(snap.pairs[q].los_class) == grids[1].i[which[q]]) ++los_agree;
    if (!(g > 0) || tx.power_dbm + tracer::to_db(g) < floor_dbm) continue;
    diff.push_back(std::fabs(tracer::to_db(g) - grids[0].f[which[q]]));
  }
  json check = {{"tx", tx.id}, {"voxels", which.size()}, {"above_sensitivity", diff.size()},
                {"median_abs_db", quantile(diff, 0.5)}, {"p90_abs_db", quantile(diff, 0.9)},
                {"max_abs_db", diff.empty() ? 0.0 : *std::max_element(diff.begin(), diff.end())},
                {"los_class_agreement", which.empty() ? 0.0 : double(los_agree) / which.size()}};
  spdlog::info("radio map vs trace at {} voxels ({} above sensitivity): |diff| median {:.3f} dB, p90 {:.3f} dB",
               which.size(), diff.size(), check["median_abs_db"].get<double>(), check["p90_abs_db"].get<double>());
  return check;
}

// The file's metadata: grid geometry, transmitters, method, config and provenance.
json vdb_meta(const TraceSettings& trace, const RadioMapSettings& s, const std::string& region, std::size_t voxels,
              const json& config, const json& prov, const json& check) {
  json txs = json::array();
  for (const auto& t : s.tx) txs.push_back({{"id", t.id}, {"position_m", t.position}, {"power_dbm", t.power_dbm}});
  json meta = {{"format", "raysweep radio map"},
               {"format_version", "1.0"},
               {"carrier_hz", trace.radio.frequency_hz},
               {"bandwidth_hz", trace.radio.bandwidth_hz},
               {"sensitivity_dbm", trace.radio.sensitivity_dbm},
               {"voxel_m", s.voxel_m},
               {"z_min_m", s.z_min_m},
               {"z_max_m", s.z_max_m},
               {"region", region},
               {"voxels", voxels},
               {"tx", txs.dump()},
               {"semantics", "voxel (i,j,k) holds the value at transform.indexToWorld(i,j,k) = (i v, j v, z_min + k v), "
                             "its centre (a point value, not a voxel average)"},
               {"method", "per-voxel exact paths through the tracer (tracer/radiomap_solver.hpp): LoS, "
                          "specular/refracted order <= 2 by the image method, first-order UTD diffraction; no "
                          "diffuse scattering and no order >= 3 (docs/radiomap.md)"},
               {"tracer_config", config.dump()},
               {"provenance", prov.dump()}};
  if (!check.is_null()) meta["check_vs_trace"] = check.dump();
  return meta;
}

}  // namespace

json run_radiomap_stage(const RadioMapArgs& args, const Settings& all, const std::vector<std::string>& argv) {
  const auto t0 = std::chrono::steady_clock::now();
  if (fs::path(args.out).extension() != ".vdb") throw std::invalid_argument(args.out + ": output must end in .vdb");
  if (!args.png.empty() && fs::path(args.png).extension() != ".png")
    throw std::invalid_argument(args.png + ": the slice picture must end in .png");
  const TraceSettings& trace = all.trace;
  const std::string cfg_name = all.file.empty() ? std::string("radiomap settings") : all.file;
  const RadioMapSettings s = checked_settings(args, all, cfg_name);
  const long layers = static_cast<long>(std::floor((s.z_max_m - s.z_min_m) / s.voxel_m + 1e-9)) + 1;
  if (layers > 100000) throw std::invalid_argument(cfg_name + ": radiomap: more than 100000 voxel layers");

  const fs::path scene_file = fs::path(args.scene) / "scene.glb";
  if (!fs::exists(scene_file)) throw std::invalid_argument(args.scene + ": no scene.glb (run `raysweep scene` first)");
  tracer::TraceScene scene(read_scene_glb(scene_file.parent_path()));
  scene.set_precompute_store(scene_precompute_store(args.scene));
  std::vector<InputFile> inputs{{"scene", scene_file.string()}};
  if (!all.file.empty()) inputs.push_back({"config", all.file});
  if (!args.poses.empty()) place_poses(args, scene, inputs);
  for (const auto& t : s.tx)
    if (tracer::inside_static(scene, t.position))
      throw std::invalid_argument("radiomap: transmitter " + t.id + " at (" + std::to_string(t.position[0]) + ", " +
                                  std::to_string(t.position[1]) + ", " + std::to_string(t.position[2]) +
                                  ") is inside a building of " + scene_file.string());

  const MapRegion region = map_region(args, s, scene, inputs);
  const OpenVoxels o = open_voxels(region, layers, s, scene);
  if (o.voxels.empty()) throw std::invalid_argument("radiomap: the region holds no voxel in the open air");
  spdlog::info("radio map: {} voxels ({} region, {} m, {} layers from z = {} m), {} transmitter(s)", o.voxels.size(),
               region.name, s.voxel_m, layers, s.z_min_m, s.tx.size());
  // Hybrid gathers by rays here: the transmitter's rays reach first-order scattering only.
  const bool diffuse = trace.tracer.diffuse && trace.tracer.diffuse_integration != tracer::DiffuseIntegration::tiles;
  const std::optional<DiffuseSamples> samples =
      diffuse ? std::optional<DiffuseSamples>(diffuse_samples(o.voxels, s)) : std::nullopt;
  TxMaps maps = solve_transmitters(scene, s, o, samples ? &*samples : nullptr, trace);
  add_best_server_grids(maps, trace.radio.sensitivity_dbm);
  const json check = args.check > 0 ? check_vs_trace(args.check, s.tx.front(), o, maps.grids, scene, trace) : json();

  json config = trace.to_json();
  config["radiomap"] = s.to_json();
  config["radiomap"]["region"] = region.name;
  config["vehicles"] = args.vehicles.empty() ? "built-in parametric" : args.vehicles;
  json prov = provenance("radiomap", inputs, config, argv);
  all.record_sets(prov);
  write_radiomap_vdb(args.out, s.voxel_m, s.z_min_m, o.voxels, maps.grids,
                     vdb_meta(trace, s, region.name, o.voxels.size(), config, prov, check));

  json summary = {{"out", args.out}, {"voxels", o.voxels.size()}, {"region", region.name}, {"tx", maps.per_tx},
                  {"solve_s", maps.solve_s}, {"check", check}};
  if (!args.png.empty()) {
    const fs::path png(args.png);
    // The slice script infers the picture's format from the extension.
    StagedFile staged(png, png.parent_path() / (png.stem().string() + ".tmp.png"));
    if (run_python_script("radiomap_slice.py", {args.out, args.scene, staged.path().string()})) {
      staged.commit();
      summary["png"] = png.string();
    }
  }
  summary["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return summary;
}

namespace {

// One frame of the city's dataset for the picture: the vehicles of its
// middle frame (poses CSV) and that snapshot traced again (`raysweep trace`
// JSON), so the render shows them with their strongest paths. False when
// the dataset has no vehicle there.
bool frame_for_render(const fs::path& dataset, const Settings& city, const std::string& scene_dir,
                      const fs::path& dir, const std::vector<std::string>& argv) {
  generators::DatasetReader reader(dataset);
  if (reader.frame_count() == 0) return false;
  const auto frame = reader.frames(reader.frame_count() / 2, 1).at(0);
  std::vector<PoseRow> poses;
  for (const auto& st : frame.nodes) {
    const auto& info = reader.nodes().at(st.node);
    if (info.kind != generators::NodeKind::vehicle) continue;
    poses.push_back({info.id, info.vclass, st.x, st.y, st.z, st.heading_deg,
                     std::sqrt(double(st.vx) * st.vx + double(st.vy) * st.vy + double(st.vz) * st.vz)});
  }
  if (poses.empty()) return false;
  fs::create_directories(dir);
  write_file_atomic(dir / "poses.csv", poses_csv(poses));
  TraceArgs t;
  t.scene = scene_dir;
  t.vehicles = (dataset.parent_path() / "vehicles").string();
  t.poses = (dir / "poses.csv").string();
  t.exclude_objects = city.sweep.exclude_objects;
  t.out = (dir / "trace.json").string();
  spdlog::info("render: frame at {:.1f} s ({} vehicles) traced for its paths", frame.time_s, poses.size());
  run_trace_stage(t, city, argv);
  return true;
}

}  // namespace

namespace {

// The --set options a city's map was made with (<out>/.stamps/radiomap.json,
// absent without any): changing them redoes the map as editing the file does.
bool sets_changed(const Settings& city, const fs::path& record) {
  json recorded = json::array();
  std::ifstream in(record);
  if (in) {
    try {
      recorded = json::parse(in).value("set", json::array());
    } catch (const json::exception&) {
      return true;
    }
  }
  return recorded != json(city.sets);
}

void record_sets(const Settings& city, const fs::path& record) {
  if (city.sets.empty()) {
    fs::remove(record);
    return;
  }
  fs::create_directories(record.parent_path());
  write_file_atomic(record, json{{"set", city.sets}}.dump() + "\n");
}

}  // namespace

json run_city_radiomap(const Settings& city, const std::string& out, const std::string& scene_dir,
                       const std::string& net, bool force, const std::vector<std::string>& argv) {
  const fs::path vdb = fs::path(out) / "radiomap.vdb", png = fs::path(out) / "radiomap.png";
  const fs::path render = fs::path(out) / "render.png";
  const auto newest_input = std::max(fs::last_write_time(fs::path(scene_dir) / "scene.glb"), fs::last_write_time(city.file));
  json summary = {{"vdb", vdb.string()}};
  const fs::path sets_record = fs::path(out) / ".stamps" / "radiomap.json";
  if (force || !fs::exists(vdb) || fs::last_write_time(vdb) < newest_input || sets_changed(city, sets_record)) {
    RadioMapArgs a;
    a.scene = scene_dir;
    a.net = net;
    a.out = vdb.string();
    if (city.radiomap.png) a.png = png.string();
    spdlog::info("radiomap: {}", vdb.string());
    summary = run_radiomap_stage(a, city, argv);
    record_sets(city, sets_record);
  } else {
    spdlog::info("radiomap: up to date ({})", vdb.string());
  }
  if (fs::exists(png)) summary["png"] = png.string();
  if (find_blender().empty()) {
    spdlog::warn("{}: no picture (Blender not installed: apt-get install blender)", render.string());
  } else if (force || !fs::exists(render) || fs::last_write_time(render) < fs::last_write_time(vdb) ||
             (fs::exists(fs::path(out) / "dataset.h5") &&
              fs::last_write_time(render) < fs::last_write_time(fs::path(out) / "dataset.h5"))) {
    RenderArgs r;
    r.scene = scene_dir;
    r.radiomap = vdb.string();
    r.out = render.string();
    try {
      const fs::path dataset = fs::path(out) / "dataset.h5", frame_dir = fs::path(out) / "render";
      if (fs::exists(dataset) && frame_for_render(dataset, city, scene_dir, frame_dir, argv)) {
        r.vehicles = (fs::path(out) / "vehicles").string();
        r.poses = (frame_dir / "poses.csv").string();
        r.paths = (frame_dir / "trace.json").string();
      }
      run_render_stage(r, argv);
      summary["render"] = render.string();
    } catch (const std::exception& e) {
      spdlog::warn("{}: no picture ({})", render.string(), e.what());
    }
  } else {
    summary["render"] = render.string();
  }
  return summary;
}

}  // namespace raysweep::pipeline
