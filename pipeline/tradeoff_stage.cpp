#include "pipeline/tradeoff_stage.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "meshkit/errors.hpp"
#include "meshkit/gltf_io.hpp"
#include "meshkit/scene_simplify.hpp"
#include "pipeline/city_run.hpp"
#include "pipeline/fcd.hpp"
#include "pipeline/preview.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/sweep_stage.hpp"
#include "pipeline/trace_config.hpp"
#include "pipeline/trace_inputs.hpp"
#include "pipeline/version.hpp"
#include "pipeline/vtypes.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr double kFloorDb = -200.0;  // gains are floored here; pairs whose reference is at the floor are not compared
constexpr int kMaxGridRays = 1 << 22;
constexpr int kMaxReferenceDepth = 5;

// Linear-interpolated quantile (numpy's default) of unsorted values.
double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

double gain_db(double p) { return p > 0 ? std::max(kFloorDb, 10.0 * std::log10(p)) : kFloorDb; }

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t") - a + 1);
}

std::vector<std::string> split_list(const std::string& option, const std::string& text) {
  std::vector<std::string> items;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) items.push_back(trim(item));
  if (items.empty() || std::any_of(items.begin(), items.end(), [](const std::string& s) { return s.empty(); }))
    throw std::invalid_argument(option + " '" + text + "': expected a comma-separated list (e.g. 1024,4096)");
  return items;
}

// A vehicle of a snapshot, as the sweep would place it.
struct SnapVehicle {
  std::string id, key;  // key: library entry (FcdTypeModel::key)
  double x = 0, y = 0, z = 0, heading_deg = 0, speed_mps = 0;
};
struct SnapshotPoses {
  double time_s = 0;
  long line = 0;
  std::vector<SnapVehicle> vehicles;
};

std::string fmt_num(double v) { return std::isfinite(v) ? fmt::format("{:.6g}", v) : std::string("nan"); }
json json_num(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

std::string setting_label(int rays, int depth) { return fmt::format("r{} d{}", rays, depth); }

std::string mm(double m) { return fmt::format("{:g}m", m); }

}  // namespace

std::vector<int> parse_int_list(const std::string& option, const std::string& text, int min, int max) {
  std::vector<int> out;
  for (const auto& item : split_list(option, text)) {
    std::size_t used = 0;
    long long v = 0;
    try {
      v = std::stoll(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != item.size() || v < min || v > max)
      throw std::invalid_argument(option + ": '" + item + "' is not an integer in " + std::to_string(min) + ".." +
                                  std::to_string(max));
    if (std::find(out.begin(), out.end(), static_cast<int>(v)) == out.end()) out.push_back(static_cast<int>(v));
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<double> parse_number_list(const std::string& option, const std::string& text, double min) {
  std::vector<double> out;
  for (const auto& item : split_list(option, text)) {
    std::size_t used = 0;
    double v = 0;
    try {
      v = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != item.size() || !std::isfinite(v) || !(v >= min))
      throw std::invalid_argument(option + ": '" + item + "' is not a number >= " + fmt::format("{:g}", min));
    if (std::find(out.begin(), out.end(), v) == out.end()) out.push_back(v);
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<bool> pareto_front(const std::vector<std::pair<double, double>>& pts) {
  std::vector<bool> front(pts.size(), false);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto [ti, ei] = pts[i];
    if (std::isnan(ti) || std::isnan(ei)) continue;
    bool dominated = false;
    for (std::size_t j = 0; j < pts.size() && !dominated; ++j) {
      if (j == i) continue;
      const auto [tj, ej] = pts[j];
      if (std::isnan(tj) || std::isnan(ej)) continue;
      dominated = tj <= ti && ej <= ei && (tj < ti || ej < ei);
    }
    front[i] = !dominated;
  }
  return front;
}

static std::size_t mechanism_of(const tracer::Path& path) {
  std::size_t reflections = 0;
  for (const auto& i : path.interactions) {
    if (i.type == tracer::InteractionType::diffuse) return 5;
    if (i.type == tracer::InteractionType::diffraction) return 4;
    if (i.type == tracer::InteractionType::specular) ++reflections;
  }
  return std::min<std::size_t>(reflections, 3);
}

void compare_to_reference(const std::vector<PairGains>& setting, const std::vector<PairGains>& reference,
                          TradeoffResult& r, double rx_gain_db) {
  if (setting.size() != reference.size()) throw std::logic_error("tradeoff: snapshot counts differ");
  std::vector<double> errors, errors_rx, ratios;
  std::size_t pairs = 0, agree = 0, missed = 0;
  r.tail_pairs = 0;
  r.tail_by_mechanism.assign(kMechanismCount, 0);
  double sum_min = 0, sum_ref = 0;
  for (std::size_t s = 0; s < setting.size(); ++s) {
    const auto& a = setting[s];
    const auto& b = reference[s];
    if (a.power.size() != b.power.size()) throw std::logic_error("tradeoff: pair counts differ");
    for (std::size_t p = 0; p < a.power.size(); ++p) {
      ++pairs;
      if (a.los[p] == b.los[p]) ++agree;
      const double P = a.power[p], R = b.power[p];
      sum_ref += R;
      sum_min += std::min(P, R);
      if (R > 0) ratios.push_back(std::min(1.0, P / R));
      const double gr = gain_db(R);
      if (gr > kFloorDb) {
        const double g = gain_db(P);
        errors.push_back(std::abs(g - gr));
        if (gr >= rx_gain_db) {
          const double e = std::abs(std::max(g, rx_gain_db) - gr);
          errors_rx.push_back(e);
          if (e > kAttributionDb && p < a.by_mechanism.size() && p < b.by_mechanism.size()) {
            std::size_t worst = 0;
            double worst_diff = -1;
            for (std::size_t m = 0; m < kMechanismCount; ++m) {
              const double d = std::abs(a.by_mechanism[p][m] - b.by_mechanism[p][m]);
              if (d > worst_diff) worst_diff = d, worst = m;
            }
            ++r.tail_pairs;
            ++r.tail_by_mechanism[worst];
          }
        }
        if (g <= kFloorDb) ++missed;
      }
    }
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  r.pairs = pairs;
  r.compared_pairs = errors.size();
  r.err_median_db = quantile(errors, 0.5);
  r.err_p95_db = quantile(errors, 0.95);
  r.los_agreement = pairs ? static_cast<double>(agree) / static_cast<double>(pairs) : nan;
  r.power_fraction = sum_ref > 0 ? sum_min / sum_ref : nan;
  r.power_fraction_median = quantile(ratios, 0.5);
  r.missed_pairs = errors.empty() ? nan : static_cast<double>(missed) / static_cast<double>(errors.size());
  r.rx_pairs = errors_rx.size();
  r.err_median_rx_db = quantile(errors_rx, 0.5);
  r.err_p95_rx_db = quantile(errors_rx, 0.95);
}

static json tail_json(const TradeoffResult& r) {
  json j = json::object();
  for (std::size_t m = 0; m < kMechanismCount && m < r.tail_by_mechanism.size(); ++m)
    j[kMechanisms[m]] = r.tail_by_mechanism[m];
  return j;
}

json run_tradeoff_stage(const TradeoffArgs& args, const std::vector<std::string>& argv) {
  const auto t_start = std::chrono::steady_clock::now();

  // ---- Inputs (everything is checked before anything is traced or written).
  std::string scene_dir = args.scene, vehicles_dir = args.vehicles, fcd = args.fcd, config = args.config,
              rsus_file = args.rsus, out = args.out;
  std::vector<std::string> vtype_files = args.vtypes;
  std::string title;
  if (!args.city.empty()) {
    if (!args.scene.empty() || !args.fcd.empty() || !args.vehicles.empty() || !args.config.empty() ||
        !args.rsus.empty() || !args.vtypes.empty())
      throw std::invalid_argument("tradeoff: give either a city file or --scene/--fcd/--vehicles/--config, not both");
    if (!fs::exists(args.city)) throw std::invalid_argument(args.city + ": city file not found");
    const CityOutputs o = city_outputs(args.city, args.city_out);
    scene_dir = o.scene;
    vehicles_dir = o.vehicles;
    fcd = o.fcd;
    rsus_file = o.rsus;
    vtype_files = o.vtypes;
    config = args.city;
    if (out.empty()) out = (fs::path(o.out) / "tradeoff").string();
    title = load_city_config(args.city).name;
  } else {
    if (!args.city_out.empty()) throw std::invalid_argument("tradeoff: --city-out needs a city file");
    if (scene_dir.empty() || fcd.empty())
      throw std::invalid_argument("tradeoff: give a city file (after `raysweep run CITY.toml`) or --scene and --fcd");
    if (out.empty()) throw std::invalid_argument("tradeoff: --out DIR is required with --scene/--fcd");
    title = fs::path(scene_dir).filename().string();
  }
  const fs::path scene_file = fs::path(scene_dir) / "scene.glb";
  if (!fs::exists(scene_file)) throw std::invalid_argument(scene_dir + ": no scene.glb (run `raysweep scene` first)");
  if (!fs::exists(fcd)) throw std::invalid_argument(fcd + ": FCD file not found");
  if (!vehicles_dir.empty() && !fs::exists(fs::path(vehicles_dir) / "manifest.json"))
    throw std::invalid_argument(vehicles_dir + ": not a vehicle library (no manifest.json; run `raysweep vehicles`)");
  if (!config.empty() && !fs::exists(config)) throw std::invalid_argument(config + ": config file not found");
  if (!rsus_file.empty() && !fs::exists(rsus_file)) throw std::invalid_argument(rsus_file + ": RSU file not found");
  if (fs::exists(out) && !fs::is_directory(out)) throw std::invalid_argument(out + ": exists and is not a folder");

  const int n_snapshots = args.snapshots > 0 ? args.snapshots : (args.quick ? 2 : 4);
  if (args.snapshots < 0 || n_snapshots > 1000)
    throw std::invalid_argument("--snapshots: expected 1..1000, got " + std::to_string(args.snapshots));
  const std::vector<int> rays = args.rays.empty()
                                    ? (args.quick ? std::vector<int>{256, 1024} : std::vector<int>{1024, 4096, 16384})
                                    : parse_int_list("--rays", args.rays, 1, kMaxGridRays);
  const std::vector<int> depths = args.depths.empty() ? (args.quick ? std::vector<int>{1, 2} : std::vector<int>{1, 2, 3})
                                                      : parse_int_list("--depths", args.depths, 0, tracer::kMaxDepth);
  const std::vector<double> simplify = args.simplify.empty()
                                           ? (args.quick ? std::vector<double>{2.0} : std::vector<double>{0.5, 2.0})
                                           : parse_number_list("--simplify", args.simplify, 0.0);
  const int max_rays = rays.back(), max_depth = depths.back();
  const int ref_rays = args.reference_rays > 0 ? args.reference_rays : 4 * max_rays;
  if (args.reference_rays < 0 || ref_rays > 4 * kMaxGridRays)
    throw std::invalid_argument("--reference-rays: expected 1.." + std::to_string(4 * kMaxGridRays));
  const int ref_depth =
      args.reference_depth >= 0 ? args.reference_depth : std::max(max_depth, std::min(max_depth + 1, kMaxReferenceDepth));
  if (ref_depth > tracer::kMaxDepth)
    throw std::invalid_argument("--reference-depth: expected 0.." + std::to_string(tracer::kMaxDepth));
  if (ref_rays < max_rays || ref_depth < max_depth)
    spdlog::warn("tradeoff: the reference ({} rays, depth {}) is below the grid's largest ({} rays, depth {})", ref_rays,
                 ref_depth, max_rays, max_depth);

  const TraceSettings settings = load_trace_config(config);
  const SweepConfig cfg = load_sweep_config(config);
  tracer::validate(settings.tracer, settings.radio);

  // ---- Grid.
  const tracer::TracerConfig& base = settings.tracer;
  const bool library_mode = !vehicles_dir.empty();
  const int base_lod = library_mode ? cfg.lod : 0;  // built-in models are full detail (a library's LOD 0)
  const int base_rays =
      std::find(rays.begin(), rays.end(), base.rays_per_source) != rays.end() ? base.rays_per_source : max_rays;
  const int base_depth = std::find(depths.begin(), depths.end(), base.max_depth) != depths.end() ? base.max_depth : max_depth;
  std::vector<TradeoffSetting> grid;
  {
    TradeoffSetting ref;
    ref.label = "reference";
    ref.reference = true;
    ref.tracer = base;
    ref.tracer.rays_per_source = ref_rays;
    ref.tracer.max_depth = ref_depth;
    ref.tracer.los = ref.tracer.specular = ref.tracer.refraction = ref.tracer.diffuse = ref.tracer.diffraction = true;
    ref.tracer.vehicle_diffraction = true;
    ref.tracer.path_threshold_db = 0;  // keep every path
    // Diffuse tiles (when the base integrates by tiles): converged.
    ref.tracer.diffuse_tile_m = std::min(base.diffuse_tile_m, 0.25);
    ref.tracer.diffuse_tile_ratio = std::min(base.diffuse_tile_ratio, 0.05);
    ref.tracer.diffuse_shadow_ratio = 0;
    ref.tracer.diffuse_roulette_db = 300;  // every diffuse sample traced
    ref.lod = 0;
    grid.push_back(ref);
  }
  for (int r : rays)
    for (int d : depths) {
      TradeoffSetting s;
      s.label = setting_label(r, d);
      s.tracer = base;
      s.tracer.rays_per_source = r;
      s.tracer.max_depth = d;
      s.lod = base_lod;
      grid.push_back(s);
    }
  auto variant = [&](const std::string& what) {
    TradeoffSetting s;
    s.label = setting_label(base_rays, base_depth) + " " + what;
    s.tracer = base;
    s.tracer.rays_per_source = base_rays;
    s.tracer.max_depth = base_depth;
    s.lod = base_lod;
    return s;
  };
  {
    auto s = variant(base.diffuse ? "-diffuse" : "+diffuse");
    s.tracer.diffuse = !base.diffuse;
    grid.push_back(s);
    s = variant(base.diffraction ? "-diffraction" : "+diffraction");
    s.tracer.diffraction = !base.diffraction;
    grid.push_back(s);
    s = variant(base.vehicle_diffraction ? "-vehicle knife edges" : "+vehicle knife edges");
    s.tracer.vehicle_diffraction = !base.vehicle_diffraction;
    grid.push_back(s);
    if (base.vehicle_diffraction) {
      s = variant(base.vehicle_diffraction_reflected ? "-reflected knife edges" : "+reflected knife edges");
      s.tracer.vehicle_diffraction_reflected = !base.vehicle_diffraction_reflected;
      grid.push_back(s);
    }
    s = variant(base.vehicle_edge_diffraction ? "-vehicle edges" : "+vehicle edges");
    s.tracer.vehicle_edge_diffraction = !base.vehicle_edge_diffraction;
    grid.push_back(s);
    s = variant(base.refraction ? "-refraction" : "+refraction");
    s.tracer.refraction = !base.refraction;
    grid.push_back(s);
    if (!base.diffuse || !base.diffraction || !base.refraction || !base.specular || !base.los) {
      s = variant("all mechanisms");
      s.tracer.los = s.tracer.specular = s.tracer.refraction = s.tracer.diffuse = s.tracer.diffraction = true;
      grid.push_back(s);
    } else {
      // The geometrical-optics core alone: what diffuse and diffraction add together.
      s = variant("specular only");
      s.tracer.diffuse = s.tracer.diffraction = false;
      grid.push_back(s);
    }
    // The diffuse integration: the other methods, and coarser tiles.
    if (base.diffuse) {
      using DI = tracer::DiffuseIntegration;
      const std::pair<DI, const char*> methods[] = {
          {DI::rays, "diffuse by rays"}, {DI::tiles, "diffuse by tiles"}, {DI::hybrid, "diffuse hybrid"}};
      for (const auto& [how, label] : methods) {
        if (how == base.diffuse_integration) continue;
        s = variant(label);
        s.tracer.diffuse_integration = how;
        grid.push_back(s);
      }
      if (base.diffuse_integration != DI::rays) {
        s = variant("tile ratio x2");
        s.tracer.diffuse_tile_ratio = 2 * base.diffuse_tile_ratio;
        grid.push_back(s);
        s = variant("coarse tiles");
        s.tracer.diffuse_tile_m = 4 * base.diffuse_tile_m;
        s.tracer.diffuse_tile_ratio = 2 * base.diffuse_tile_ratio;
        grid.push_back(s);
      }
    }
    // Diffuse by rays: both ends' samples, or the lower end's alone.
    if (base.diffuse && base.diffuse_integration == tracer::DiffuseIntegration::rays) {
      s = variant(base.diffuse_both_ends ? "diffuse one end" : "diffuse both ends");
      s.tracer.diffuse_both_ends = !base.diffuse_both_ends;
      grid.push_back(s);
    }
    // Diffuse by rays: the roulette on weak samples' shadow rays.
    if (base.diffuse && base.diffuse_integration == tracer::DiffuseIntegration::rays) {
      const bool on = base.diffuse_roulette_db < 300;
      s = variant(on ? "-diffuse roulette" : "+diffuse roulette");
      s.tracer.diffuse_roulette_db = on ? 300 : 20;
      grid.push_back(s);
    }
    // The per-model multi-bounce table of the image search.
    if (base.candidates == tracer::CandidateSearch::image && base_depth >= 2) {
      s = variant(base.vehicle_multi_bounce ? "-vehicle multi-bounce" : "+vehicle multi-bounce");
      s.tracer.vehicle_multi_bounce = !base.vehicle_multi_bounce;
      grid.push_back(s);
    }
    // Its order-3 static paths through the ground.
    if (base.candidates == tracer::CandidateSearch::image && base_depth >= 3) {
      s = variant(base.ground_order3 ? "-ground order 3" : "+ground order 3");
      s.tracer.ground_order3 = !base.ground_order3;
      grid.push_back(s);
    }
    // Its order-3 sequences in the lit beams of static face pairs.
    if (base.candidates == tracer::CandidateSearch::image && base_depth >= 3) {
      s = variant(base.beam_order3 ? "-beam order 3" : "+beam order 3");
      s.tracer.beam_order3 = !base.beam_order3;
      grid.push_back(s);
    }
    // Reflection on a static face before or after a diffracting edge.
    if (base.diffraction) {
      s = variant(base.diffraction_reflection ? "-reflection-diffraction" : "+reflection-diffraction");
      s.tracer.diffraction_reflection = !base.diffraction_reflection;
      grid.push_back(s);
    }
    // What the exact image search costs and buys over sampling alone.
    if (base.candidates != tracer::CandidateSearch::exhaustive) {
      const bool image = base.candidates == tracer::CandidateSearch::image;
      s = variant(image ? "sbr search" : "image search");
      s.tracer.candidates = image ? tracer::CandidateSearch::sbr : tracer::CandidateSearch::image;
      grid.push_back(s);
    }
  }
  for (const auto& s : grid) tracer::validate(s.tracer, settings.radio);

  // ---- Scene, library, snapshots.
  spdlog::info("tradeoff: reading {} and {}", scene_file.string(), fcd);
  const meshkit::Scene static_scene = exclude_objects(meshkit::read_glb(scene_file.string()), cfg.exclude_objects);
  struct SceneVariant {
    std::unique_ptr<tracer::TraceScene> scene;
    std::map<std::pair<int, std::string>, std::uint32_t> models;  // (lod, library key) -> model index
    meshkit::SimplifyStats stats;
  };
  std::map<double, SceneVariant> scenes;
  scenes[0.0].scene = std::make_unique<tracer::TraceScene>(static_scene);
  scenes[0.0].stats.triangles_before = scenes[0.0].stats.triangles_after = static_scene.triangle_count();
  const auto bounds = scenes[0.0].scene->static_bounds();

  std::map<int, std::unique_ptr<VehicleLibrary>> libraries;  // by LOD (built-in: one, key 0)
  auto library = [&](int lod) -> VehicleLibrary& {
    const int key = library_mode ? lod : 0;
    auto& l = libraries[key];
    if (!l) l = std::make_unique<VehicleLibrary>(vehicles_dir, library_mode ? lod : -1);
    return *l;
  };
  VTypeMap vtypes;
  for (const auto& f : vtype_files) {
    if (fs::path(f).extension() == ".sumocfg") vtypes.add_sumocfg(f);
    else vtypes.add_file(f);
  }
  FcdTypeModels type_models(vtypes, library(base_lod), library_mode, fcd);
  auto traceable = [&](const FcdVehicle& v) { return type_models.resolve(v) != nullptr; };

  // Pass 1: the frames with at least two traced vehicles; pass 2 takes the
  // chosen ones (the selection depends on every earlier frame).
  std::vector<double> eligible;
  {
    FcdReader reader(fcd, sweep_fcd_filter(cfg));
    SweepSelection selection(cfg, bounds, fcd);
    FcdFrame frame;
    while (reader.next(frame))
      if (selection.select(frame, traceable).size() >= 2) eligible.push_back(frame.time_s);
    if (selection.dropped_outside())
      spdlog::warn("{}: {} vehicle-frames outside the scene dropped", fcd, selection.dropped_outside());
  }
  if (eligible.empty())
    throw meshkit::InputError(fcd, "", "no frame with at least two vehicles to trace (in the [sweep] time window)");
  std::set<std::size_t> chosen;
  if (eligible.size() <= static_cast<std::size_t>(n_snapshots)) {
    for (std::size_t i = 0; i < eligible.size(); ++i) chosen.insert(i);
  } else {
    const double t0 = eligible.front(), t1 = eligible.back();
    for (int k = 0; k < n_snapshots; ++k) {
      const double target = n_snapshots == 1 ? 0.5 * (t0 + t1) : t0 + (t1 - t0) * k / (n_snapshots - 1);
      std::size_t best = SIZE_MAX;
      for (std::size_t i = 0; i < eligible.size(); ++i)
        if (!chosen.count(i) && (best == SIZE_MAX || std::abs(eligible[i] - target) < std::abs(eligible[best] - target)))
          best = i;
      chosen.insert(best);
    }
  }
  std::vector<SnapshotPoses> snapshots;
  {
    FcdReader reader(fcd, sweep_fcd_filter(cfg));
    SweepSelection selection(cfg, bounds, fcd);
    FcdFrame frame;
    std::size_t index = 0;
    while (snapshots.size() < chosen.size() && reader.next(frame)) {
      const auto selected = selection.select(frame, traceable);
      if (selected.size() < 2) continue;
      if (chosen.count(index++)) {
        SnapshotPoses s;
        s.time_s = frame.time_s;
        s.line = frame.line;
        for (const FcdVehicle* v : selected)
          s.vehicles.push_back(SnapVehicle{v->id, type_models.resolve(*v)->key, v->x, v->y, v->has_z ? v->z : 0.0,
                                           v->angle_deg, v->speed_mps});
        snapshots.push_back(std::move(s));
      }
    }
  }
  std::vector<NodeRow> rsus;
  if (!rsus_file.empty()) rsus = read_nodes_csv(rsus_file);
  std::set<std::string> used_keys;
  for (const auto& s : snapshots)
    for (const auto& v : s.vehicles) used_keys.insert(v.key);

  // The coarsest LOD every entry the snapshots use has.
  int coarsest_lod = -1;
  if (library_mode) {
    std::ifstream in(fs::path(vehicles_dir) / "manifest.json");
    const json manifest = json::parse(in);
    int top = 0;
    for (const auto& e : manifest.at("vehicles"))
      for (const auto& l : e.at("lods")) top = std::max(top, l.at("lod").get<int>());
    for (int lod = top; lod > 0 && coarsest_lod < 0; --lod) {
      try {
        VehicleLibrary& lib = library(lod);
        for (const auto& k : used_keys) lib.model(k);
        coarsest_lod = lod;
      } catch (const std::invalid_argument&) {
        // an entry without this level: try a finer one
      }
    }
  }
  if (coarsest_lod > 0 && coarsest_lod != base_lod) {
    auto s = variant("lod" + std::to_string(coarsest_lod));
    s.lod = coarsest_lod;
    grid.push_back(s);
  } else {
    spdlog::info("tradeoff: no coarser vehicle LOD to compare ({})",
                 library_mode ? "the library has no coarser level" : "built-in models: give --vehicles for LODs");
  }

  // ---- Tracing.
  auto scene_for = [&](double simplify_m) -> SceneVariant& {
    auto& v = scenes[simplify_m];
    if (!v.scene) {
      const auto t = std::chrono::steady_clock::now();
      const meshkit::Scene simplified = meshkit::simplify_scene(static_scene, simplify_m, &v.stats);
      v.scene = std::make_unique<tracer::TraceScene>(simplified);
      spdlog::info("tradeoff: static geometry simplified within {} m: {} -> {} triangles ({} objects changed, {:.2f} s)",
                   simplify_m, v.stats.triangles_before, v.stats.triangles_after, v.stats.objects_simplified,
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count());
    }
    return v;
  };
  for (double m : simplify) {
    if (m <= 0) continue;
    // A tolerance that changes no object traces the default's scene: its
    // row would only chart the timer's noise (on the ring road's box
    // buildings it "dominated" the default by 1 % of time).
    if (scene_for(m).stats.objects_simplified == 0) {
      spdlog::info("tradeoff: static {} leaves every object as it is: the default's scene, not charted", mm(m));
      continue;
    }
    auto s = variant("static " + mm(m));
    s.simplify_m = m;
    grid.push_back(s);
  }
  auto place = [&](SceneVariant& sv, int lod, const SnapshotPoses& snap) {
    std::vector<tracer::VehiclePose> poses;
    for (const auto& v : snap.vehicles) {
      const int lib_lod = library_mode ? lod : 0;
      auto it = sv.models.find({lib_lod, v.key});
      if (it == sv.models.end()) {
        const auto& m = library(lib_lod).model(v.key);
        it = sv.models.emplace(std::make_pair(lib_lod, v.key),
                               sv.scene->add_vehicle_model(m.name, meshkit::to_scene(m), m.antenna))
                 .first;
      }
      const double yaw = yaw_from_heading(v.heading_deg);
      poses.push_back(tracer::VehiclePose{v.id, it->second, {v.x, v.y, v.z}, yaw,
                                          {v.speed_mps * std::cos(yaw), v.speed_mps * std::sin(yaw), 0}});
    }
    sv.scene->set_vehicles(poses);
    auto nodes = tracer::vehicle_nodes(*sv.scene);
    for (const auto& r : rsus) nodes.push_back(tracer::Node{"rsu/" + r.id, {r.x, r.y, r.z}, {0, 0, 0}, {1, 0, 0}, -1});
    return nodes;
  };

  std::size_t max_vehicles = 0;
  for (const auto& s : snapshots) max_vehicles = std::max(max_vehicles, s.vehicles.size());
  spdlog::info("tradeoff: {} settings x {} snapshots (t = {:.1f}..{:.1f} s, up to {} vehicles{}), {} threads", grid.size(),
               snapshots.size(), snapshots.front().time_s, snapshots.back().time_s, max_vehicles,
               rsus.empty() ? "" : fmt::format(" + {} RSUs", rsus.size()), tbb::this_task_arena::max_concurrency());

  // The weakest channel gain a receiver hears (for the *_rx errors).
  const double rx_gain_db = settings.radio.sensitivity_dbm - settings.radio.tx_power_dbm;
  // Snapshot-major, settings interleaved (and every repeat another full
  // round), so a burst of load from elsewhere on the machine spreads over all
  // settings instead of falsifying one; a snapshot's time is its fastest repeat.
  for (const auto& s : grid) scene_for(s.simplify_m);
  const int repeats = std::max(1, args.repeats);
  std::vector<std::vector<PairGains>> gains(grid.size());
  std::vector<TradeoffResult> results(grid.size());
  std::vector<double> paths(grid.size(), 0), rays_traced(grid.size(), 0);
  std::vector<std::vector<double>> best(grid.size(), std::vector<double>(snapshots.size(), INFINITY));
  for (int rep = 0; rep < repeats; ++rep)
    for (std::size_t k = 0; k < snapshots.size(); ++k) {
      const auto t_snap = std::chrono::steady_clock::now();
      for (std::size_t g = 0; g < grid.size(); ++g) {
        const auto& s = grid[g];
        SceneVariant& sv = scene_for(s.simplify_m);
        const auto nodes = place(sv, s.lod, snapshots[k]);
        const auto t0 = std::chrono::steady_clock::now();
        const tracer::Snapshot traced = tracer::trace_snapshot(*sv.scene, nodes, s.tracer, settings.radio);
        best[g][k] = std::min(best[g][k], std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        if (rep > 0) continue;  // deterministic: the first round has the results
        PairGains pg;
        for (const auto& p : traced.pairs) {
          pg.power.push_back(p.stats.gain_incoherent);
          pg.los.push_back(static_cast<int>(p.los_class));
          std::array<double, kMechanismCount> m{};
          for (const auto& path : p.paths) m[mechanism_of(path)] += std::norm(path.a);
          pg.by_mechanism.push_back(m);
        }
        gains[g].push_back(std::move(pg));
        paths[g] += static_cast<double>(traced.stats.paths);
        rays_traced[g] += static_cast<double>(traced.stats.rays);
      }
      spdlog::info("snapshot {}/{}{} (t = {:.1f} s, {} vehicles): {} settings in {:.1f} s", k + 1, snapshots.size(),
                   repeats > 1 ? fmt::format(", round {}/{}", rep + 1, repeats) : std::string(), snapshots[k].time_s,
                   snapshots[k].vehicles.size(), grid.size(),
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - t_snap).count());
    }
  const double n = static_cast<double>(snapshots.size());
  for (std::size_t g = 0; g < grid.size(); ++g) {
    auto& r = results[g];
    r.times_s = best[g];
    r.paths = paths[g] / n;
    r.rays_traced = rays_traced[g] / n;
    r.time_per_snapshot_s = quantile(r.times_s, 0.5);
    double sum = 0;
    for (double t : r.times_s) sum += t;
    r.time_mean_s = sum / n;
    compare_to_reference(gains[g], gains[0], r, rx_gain_db);  // grid[0] is the reference
  }
  std::vector<std::pair<double, double>> points;
  for (const auto& r : results) points.emplace_back(r.time_per_snapshot_s, r.err_p95_db);
  const auto front = pareto_front(points);
  for (std::size_t g = 0; g < grid.size(); ++g) results[g].pareto = front[g];

  // The suggestion: the cheapest setting within the target error that agrees on the LoS class.
  int suggested = -1;
  for (std::size_t g = 0; g < grid.size(); ++g) {
    const auto& r = results[g];
    if (grid[g].reference || !(r.err_p95_db <= args.target_p95_db) || !(r.los_agreement >= 0.99)) continue;
    if (suggested < 0 || r.time_per_snapshot_s < results[suggested].time_per_snapshot_s) suggested = static_cast<int>(g);
  }

  // ---- Outputs.
  std::ostringstream csv;
  csv << "label,rays,depth,diffuse,diffraction,refraction,lod,static_simplification,time_per_snapshot_s,"
         "err_median_db,err_p95_db,los_agreement,power_fraction,power_fraction_median,paths,pareto,rays_traced,"
         "missed_pairs,err_median_rx_db,err_p95_rx_db,base\n";
  const std::string base_label = setting_label(base_rays, base_depth);  // the config's own setting
  json rows = json::array();
  for (std::size_t g = 0; g < grid.size(); ++g) {
    const auto& s = grid[g];
    const auto& r = results[g];
    csv << s.label << "," << s.tracer.rays_per_source << "," << s.tracer.max_depth << "," << int(s.tracer.diffuse) << ","
        << int(s.tracer.diffraction) << "," << int(s.tracer.refraction) << "," << s.lod << "," << fmt_num(s.simplify_m)
        << "," << fmt_num(r.time_per_snapshot_s) << "," << fmt_num(r.err_median_db) << "," << fmt_num(r.err_p95_db)
        << "," << fmt_num(r.los_agreement) << "," << fmt_num(r.power_fraction) << ","
        << fmt_num(r.power_fraction_median) << "," << fmt_num(r.paths) << "," << int(r.pareto) << ","
        << fmt_num(r.rays_traced) << "," << fmt_num(r.missed_pairs) << "," << fmt_num(r.err_median_rx_db) << ","
        << fmt_num(r.err_p95_rx_db) << "," << int(s.label == base_label) << "\n";
    rows.push_back({{"label", s.label},
                    {"reference", s.reference},
                    {"rays", s.tracer.rays_per_source},
                    {"depth", s.tracer.max_depth},
                    {"los", s.tracer.los},
                    {"specular", s.tracer.specular},
                    {"diffuse", s.tracer.diffuse},
                    {"diffraction", s.tracer.diffraction},
                    {"refraction", s.tracer.refraction},
                    {"candidates", s.tracer.candidates == tracer::CandidateSearch::image ? "image"
                                   : s.tracer.candidates == tracer::CandidateSearch::sbr ? "sbr"
                                                                                          : "exhaustive"},
                    {"path_threshold_db", s.tracer.path_threshold_db},
                    {"diffuse_both_ends", s.tracer.diffuse_both_ends},
                    {"diffuse_roulette_db", s.tracer.diffuse_roulette_db},
                    {"vehicle_multi_bounce", s.tracer.vehicle_multi_bounce},
                    {"ground_order3", s.tracer.ground_order3},
                    {"beam_order3", s.tracer.beam_order3},
                    {"diffraction_reflection", s.tracer.diffraction_reflection},
                    {"lod", s.lod},
                    {"static_simplification", s.simplify_m},
                    {"static_triangles", scenes.at(s.simplify_m).stats.triangles_after},
                    {"time_per_snapshot_s", json_num(r.time_per_snapshot_s)},
                    {"time_mean_s", json_num(r.time_mean_s)},
                    {"times_s", r.times_s},
                    {"err_median_db", json_num(r.err_median_db)},
                    {"err_p95_db", json_num(r.err_p95_db)},
                    {"los_agreement", json_num(r.los_agreement)},
                    {"power_fraction", json_num(r.power_fraction)},
                    {"power_fraction_median", json_num(r.power_fraction_median)},
                    {"paths", r.paths},
                    {"rays_traced", r.rays_traced},
                    {"pairs", r.pairs},
                    {"compared_pairs", r.compared_pairs},
                    {"missed_pairs", json_num(r.missed_pairs)},
                    {"err_median_rx_db", json_num(r.err_median_rx_db)},
                    {"err_p95_rx_db", json_num(r.err_p95_rx_db)},
                    {"rx_pairs", r.rx_pairs},
                    {"tail_pairs", r.tail_pairs},
                    {"tail_by_mechanism", tail_json(r)},
                    {"pareto", r.pareto}});
  }

  std::vector<InputFile> inputs{{"scene", scene_file.string()}, {"fcd", fcd}};
  for (const auto& v : vtype_files) inputs.push_back({"vtypes", v});
  if (!rsus_file.empty()) inputs.push_back({"rsus", rsus_file});
  if (!config.empty()) inputs.push_back({args.city.empty() ? "config" : "city", config});
  if (library_mode) inputs.push_back({"vehicle_manifest", (fs::path(vehicles_dir) / "manifest.json").string()});
  json cfg_json = settings.to_json();
  cfg_json["sweep"] = cfg.to_json();
  cfg_json["vehicles"] = library_mode ? "library" : "built-in parametric";
  cfg_json["tradeoff"] = {{"snapshots", n_snapshots},
                          {"rays", rays},
                          {"depths", depths},
                          {"simplify_m", simplify},
                          {"reference_rays", ref_rays},
                          {"reference_depth", ref_depth},
                          {"base_rays", base_rays},
                          {"base_depth", base_depth},
                          {"quick", args.quick},
                          {"repeats", std::max(1, args.repeats)},
                          {"target_p95_db", args.target_p95_db}};
  json prov = provenance("tradeoff", inputs, cfg_json, recorded_command(argv));
  prov["embree"] = tracer::embree_version();
  json snaps = json::array();
  for (const auto& s : snapshots) {
    json ids = json::array();
    for (const auto& v : s.vehicles) ids.push_back(v.id);
    const std::size_t nodes = s.vehicles.size() + rsus.size();
    snaps.push_back({{"time_s", s.time_s}, {"fcd_line", s.line}, {"vehicles", ids}, {"pairs", nodes * (nodes - 1) / 2}});
  }
  json doc = {{"format", "raysweep-tradeoff"},
              {"title", title},
              {"rows", rows},
              {"snapshots", snaps},
              {"threads", tbb::this_task_arena::max_concurrency()},
              {"suggested", suggested >= 0 ? json(grid[suggested].label) : json(nullptr)},
              {"metrics",
               {{"gain", "incoherent sum of |a|^2 per pair, dB, floored at -200 dB"},
                {"err", "|G - G_ref| over the pairs whose reference gain is above -200 dB, pooled over snapshots"},
                {"missed_pairs", "fraction of the compared pairs where the setting finds no path"},
                {"err_rx", "|max(G, G_rx) - G_ref| over the pairs whose reference gain reaches G_rx = "
                           "radio.sensitivity_dbm - radio.tx_power_dbm (the error a receiver sees: a missed pair "
                           "counts as far as the sensitivity, not the -200 dB floor)"},
                {"los_agreement", "fraction of pairs with the reference's LoS class"},
                {"power_fraction", "sum over pairs of min(P, P_ref) / sum of P_ref"},
                {"power_fraction_median", "median over pairs (P_ref > 0) of min(1, P / P_ref)"},
                {"time_per_snapshot_s", "median over snapshots of the wall time of trace_snapshot"},
                {"pareto", "not dominated in (time_per_snapshot_s, err_p95_db)"},
                {"tail_by_mechanism",
                 "of the tail_pairs (err_rx > 1 dB), how many have each mechanism as their largest power difference "
                 "to the reference: direct (no reflection: slabs, vehicles' knife edges), specular order 1, 2, "
                 ">= 3, diffraction, diffuse"},
                {"lod", "vehicle LOD; -1: each library entry's default"},
                {"static_simplification", "static geometry decimated within this error (m); 0: as built"}}},
              {"provenance", prov}};

  const fs::path dir(out);
  fs::create_directories(dir);
  write_file_atomic(dir / "tradeoff.csv", csv.str());
  write_file_atomic(dir / "tradeoff.json", doc.dump(1) + "\n");
  const fs::path png = dir / "tradeoff.png";
  bool chart = false;
  if (args.chart) {
    chart = run_python_script("tradeoff_chart.py", {(dir / "tradeoff.csv").string(), png.string(), "--title",
                                                    "raysweep tradeoff: " + title});
    if (!chart) spdlog::warn("{}: no chart (python3 with matplotlib needed)", png.string());
  }

  // A table for the terminal, and where the error of the tail comes from.
  std::ostringstream table;
  table << fmt::format("{:<28} {:>10} {:>8} {:>8} {:>8} {:>7} {:>7} {:>7} {:>8} {}\n", "setting", "s/snapshot",
                       "err med", "err p95", "p95 rx", "miss %", "LoS %", "power %", "paths", "pareto");
  for (std::size_t g = 0; g < grid.size(); ++g) {
    const auto& r = results[g];
    table << fmt::format("{:<28} {:>10.4f} {:>8.2f} {:>8.2f} {:>8.2f} {:>7.1f} {:>7.1f} {:>7.1f} {:>8.0f} {}\n",
                         grid[g].label, r.time_per_snapshot_s, r.err_median_db, r.err_p95_db, r.err_p95_rx_db,
                         100 * r.missed_pairs, 100 * r.los_agreement, 100 * r.power_fraction, r.paths,
                         r.pareto ? "*" : "");
  }
  table << fmt::format("\npairs with p95-rx error > {:g} dB, by the mechanism of their largest power difference:\n",
                       kAttributionDb);
  table << fmt::format("{:<28} {:>7}", "setting", "pairs");
  for (const char* m : kMechanisms) table << fmt::format(" {:>11}", m);
  table << "\n";
  for (std::size_t g = 1; g < grid.size(); ++g) {
    const auto& r = results[g];
    table << fmt::format("{:<28} {:>7}", grid[g].label, r.tail_pairs);
    for (std::size_t m = 0; m < kMechanismCount; ++m) table << fmt::format(" {:>11}", r.tail_by_mechanism[m]);
    table << "\n";
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  spdlog::info("tradeoff: {} settings in {:.1f} s -> {}", grid.size(), wall, out);
  json summary = {{"out", out},
                  {"csv", (dir / "tradeoff.csv").string()},
                  {"json", (dir / "tradeoff.json").string()},
                  {"settings", grid.size()},
                  {"snapshots", snapshots.size()},
                  {"wall_seconds", wall},
                  {"table", table.str()},
                  {"suggested", doc["suggested"]},
                  {"target_p95_db", args.target_p95_db}};
  if (chart) summary["png"] = png.string();
  return summary;
}

}  // namespace raysweep::pipeline
