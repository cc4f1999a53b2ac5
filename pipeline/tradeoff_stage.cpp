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
#include "pipeline/precompute_store.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/quantile.hpp"
#include "pipeline/scene_cache.hpp"
#include "pipeline/settings/tables.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/sweep_stage.hpp"
#include "pipeline/tradeoff_coherence.hpp"
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

std::string metres_label(double m) { return fmt::format("{:g}m", m); }

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

namespace {

// ---- Inputs (everything is checked before anything is traced or written).

// What a run reads and where it writes: a city's outputs or explicit inputs.
struct TradeoffInputs {
  std::string scene_dir, vehicles_dir, fcd, config, rsus_file, out, title;
  std::vector<std::string> vtype_files;
  fs::path scene_file;
  Settings settings;  // the city file's, or --config's (read once, after the inputs are checked)
  bool library_mode() const { return !vehicles_dir.empty(); }
};

TradeoffInputs resolve_inputs(const TradeoffArgs& args) {
  TradeoffInputs in{args.scene, args.vehicles, args.fcd, args.config, args.rsus, args.out, "", args.vtypes, {}};
  if (!args.city.empty()) {
    if (!args.scene.empty() || !args.fcd.empty() || !args.vehicles.empty() || !args.config.empty() ||
        !args.rsus.empty() || !args.vtypes.empty())
      throw std::invalid_argument("tradeoff: give either a city file or --scene/--fcd/--vehicles/--config, not both");
    if (!fs::exists(args.city)) throw std::invalid_argument(args.city + ": city file not found");
    in.settings = load_city_settings(args.city, args.set);
    const CityOutputs o = city_outputs(in.settings, args.city_out);
    in.scene_dir = o.scene;
    in.vehicles_dir = o.vehicles;
    in.fcd = o.fcd;
    in.rsus_file = o.rsus;
    in.vtype_files = o.vtypes;
    in.config = args.city;
    if (in.out.empty()) in.out = (fs::path(o.out) / "tradeoff").string();
    in.title = in.settings.city.name;
  } else {
    if (!args.city_out.empty()) throw std::invalid_argument("tradeoff: --city-out needs a city file");
    if (in.scene_dir.empty() || in.fcd.empty())
      throw std::invalid_argument("tradeoff: give a city file (after `raysweep run CITY.toml`) or --scene and --fcd");
    if (in.out.empty()) throw std::invalid_argument("tradeoff: --out DIR is required with --scene/--fcd");
    in.title = fs::path(in.scene_dir).filename().string();
  }
  in.scene_file = fs::path(in.scene_dir) / "scene.glb";
  if (!fs::exists(in.scene_file))
    throw std::invalid_argument(in.scene_dir + ": no scene.glb (run `raysweep scene` first)");
  if (!fs::exists(in.fcd)) throw std::invalid_argument(in.fcd + ": FCD file not found");
  if (!in.vehicles_dir.empty() && !fs::exists(fs::path(in.vehicles_dir) / "manifest.json"))
    throw std::invalid_argument(in.vehicles_dir +
                                ": not a vehicle library (no manifest.json; run `raysweep vehicles`)");
  if (!in.config.empty() && !fs::exists(in.config)) throw std::invalid_argument(in.config + ": config file not found");
  if (!in.rsus_file.empty() && !fs::exists(in.rsus_file))
    throw std::invalid_argument(in.rsus_file + ": RSU file not found");
  if (fs::exists(in.out) && !fs::is_directory(in.out))
    throw std::invalid_argument(in.out + ": exists and is not a folder");
  return in;
}

// The grid's axes and the reference, from the options (or their defaults).
struct GridAxes {
  int snapshots = 0;
  std::vector<int> rays, depths;
  std::vector<double> simplify;
  int ref_rays = 0, ref_depth = 0;
  int coherence_window = 0;  // frames; 0: no coherence toggle
};

GridAxes parse_axes(const TradeoffArgs& args) {
  GridAxes a;
  a.snapshots = args.snapshots > 0 ? args.snapshots : (args.quick ? 2 : 4);
  if (args.snapshots < 0 || a.snapshots > 1000)
    throw std::invalid_argument("--snapshots: expected 1..1000, got " + std::to_string(args.snapshots));
  a.rays = args.rays.empty() ? (args.quick ? std::vector<int>{256, 1024} : std::vector<int>{1024, 4096, 16384})
                             : parse_int_list("--rays", args.rays, 1, kMaxGridRays);
  a.depths = args.depths.empty() ? (args.quick ? std::vector<int>{1, 2} : std::vector<int>{1, 2, 3})
                                 : parse_int_list("--depths", args.depths, 0, tracer::kMaxDepth);
  a.simplify = args.simplify.empty() ? (args.quick ? std::vector<double>{2.0} : std::vector<double>{0.5, 2.0})
                                     : parse_number_list("--simplify", args.simplify, 0.0);
  a.coherence_window = args.coherence_window >= 0 ? args.coherence_window : (args.quick ? 4 : 20);
  if (a.coherence_window > 1000)
    throw std::invalid_argument("--coherence-window: expected 0..1000, got " + std::to_string(args.coherence_window));
  const int max_rays = a.rays.back(), max_depth = a.depths.back();
  a.ref_rays = args.reference_rays > 0 ? args.reference_rays : 4 * max_rays;
  if (args.reference_rays < 0 || a.ref_rays > 4 * kMaxGridRays)
    throw std::invalid_argument("--reference-rays: expected 1.." + std::to_string(4 * kMaxGridRays));
  a.ref_depth =
      args.reference_depth >= 0 ? args.reference_depth : std::max(max_depth, std::min(max_depth + 1, kMaxReferenceDepth));
  if (a.ref_depth > tracer::kMaxDepth)
    throw std::invalid_argument("--reference-depth: expected 0.." + std::to_string(tracer::kMaxDepth));
  if (a.ref_rays < max_rays || a.ref_depth < max_depth)
    spdlog::warn("tradeoff: the reference ({} rays, depth {}) is below the grid's largest ({} rays, depth {})",
                 a.ref_rays, a.ref_depth, max_rays, max_depth);
  return a;
}

// ---- Grid.

// The config's own setting on the grid; each variant differs from it in one respect.
struct GridBase {
  tracer::TracerConfig tracer;
  int rays = 0, depth = 0, lod = 0;

  TradeoffSetting variant(const std::string& what) const {
    TradeoffSetting s;
    s.label = setting_label(rays, depth) + " " + what;
    s.tracer = tracer;
    s.tracer.rays_per_source = rays;
    s.tracer.max_depth = depth;
    s.lod = lod;
    return s;
  }
};

GridBase grid_base(const tracer::TracerConfig& base, const GridAxes& axes, int lod) {
  const auto& rays = axes.rays;
  const auto& depths = axes.depths;
  GridBase b;
  b.tracer = base;
  b.rays = std::find(rays.begin(), rays.end(), base.rays_per_source) != rays.end() ? base.rays_per_source : rays.back();
  b.depth = std::find(depths.begin(), depths.end(), base.max_depth) != depths.end() ? base.max_depth : depths.back();
  b.lod = lod;
  return b;
}

TradeoffSetting reference_setting(const tracer::TracerConfig& base, const GridAxes& axes) {
  TradeoffSetting ref;
  ref.label = "reference";
  ref.reference = true;
  ref.tracer = base;
  ref.tracer.rays_per_source = axes.ref_rays;
  ref.tracer.max_depth = axes.ref_depth;
  ref.tracer.los = ref.tracer.specular = ref.tracer.refraction = ref.tracer.diffuse = ref.tracer.diffraction = true;
  ref.tracer.vehicle_diffraction = true;
  // Vehicles sampled 4x as densely as the default's bundles (or more).
  ref.tracer.vehicle_bundles = ref.tracer.vehicle_bundles_via_faces = true;
  ref.tracer.vehicle_bundle_rays = std::max(128, 4 * base.vehicle_bundle_rays);
  ref.tracer.path_threshold_db = 0;  // keep every path
  // Diffuse tiles (when the base integrates by tiles): converged.
  ref.tracer.diffuse_tile_m = std::min(base.diffuse_tile_m, 0.25);
  ref.tracer.diffuse_tile_ratio = std::min(base.diffuse_tile_ratio, 0.05);
  ref.tracer.diffuse_shadow_ratio = 0;
  ref.tracer.diffuse_roulette_db = 300;  // every diffuse sample traced
  ref.lod = 0;
  return ref;
}

// Each switch the [tracer] table declares a study for (pipeline/settings/trace_tables.cpp,
// Table::toggle), turned over against the base where it applies: a new
// mechanism's switch joins the grid from its declaration.
void add_declared_toggles(const GridBase& b, const tracer::RadioConfig& radio, std::vector<TradeoffSetting>& grid) {
  TraceSettings base{radio, b.variant("").tracer};
  for (const auto& t : tracer_table().toggles()) {
    if (t.applies && !t.applies(base)) continue;
    TraceSettings flipped = base;
    t.flip(flipped);
    auto s = b.variant(t.get(base) ? t.off_label : t.on_label);
    s.tracer = flipped.tracer;
    grid.push_back(s);
  }
}

// The mechanisms together: all on, or the geometrical-optics core alone.
void add_mechanism_variants(const GridBase& b, std::vector<TradeoffSetting>& grid) {
  const tracer::TracerConfig& base = b.tracer;
  if (!base.diffuse || !base.diffraction || !base.refraction || !base.specular || !base.los) {
    auto s = b.variant("all mechanisms");
    s.tracer.los = s.tracer.specular = s.tracer.refraction = s.tracer.diffuse = s.tracer.diffraction = true;
    grid.push_back(s);
  } else {
    // What diffuse and diffraction add together.
    auto s = b.variant("specular only");
    s.tracer.diffuse = s.tracer.diffraction = false;
    grid.push_back(s);
  }
}

// The diffuse integration: the other methods, coarser tiles, the ray method's roulette.
void add_diffuse_variants(const GridBase& b, std::vector<TradeoffSetting>& grid) {
  const tracer::TracerConfig& base = b.tracer;
  if (!base.diffuse) return;
  using DI = tracer::DiffuseIntegration;
  const std::pair<DI, const char*> methods[] = {
      {DI::rays, "diffuse by rays"}, {DI::tiles, "diffuse by tiles"}, {DI::hybrid, "diffuse hybrid"}};
  for (const auto& [how, label] : methods) {
    if (how == base.diffuse_integration) continue;
    auto s = b.variant(label);
    s.tracer.diffuse_integration = how;
    grid.push_back(s);
  }
  if (base.diffuse_integration != DI::rays) {
    auto s = b.variant("tile ratio x2");
    s.tracer.diffuse_tile_ratio = 2 * base.diffuse_tile_ratio;
    grid.push_back(s);
    s = b.variant("coarse tiles");
    s.tracer.diffuse_tile_m = 4 * base.diffuse_tile_m;
    s.tracer.diffuse_tile_ratio = 2 * base.diffuse_tile_ratio;
    grid.push_back(s);
    return;
  }
  // Diffuse by rays: the roulette on weak samples' shadow rays.
  const bool on = base.diffuse_roulette_db < 300;
  auto s = b.variant(on ? "-diffuse roulette" : "+diffuse roulette");
  s.tracer.diffuse_roulette_db = on ? 300 : 20;
  grid.push_back(s);
}

// The candidate search: image against sampling.
void add_search_variants(const GridBase& b, std::vector<TradeoffSetting>& grid) {
  const tracer::TracerConfig& base = b.tracer;
  const bool image = base.candidates == tracer::CandidateSearch::image;
  // What the exact image search costs and buys over sampling alone.
  if (base.candidates != tracer::CandidateSearch::exhaustive) {
    auto s = b.variant(image ? "sbr search" : "image search");
    s.tracer.candidates = image ? tracer::CandidateSearch::sbr : tracer::CandidateSearch::image;
    grid.push_back(s);
  }
}

// The reference first, then rays x depths, then the variants of the base.
std::vector<TradeoffSetting> build_grid(const GridBase& b, const GridAxes& axes, const tracer::RadioConfig& radio) {
  std::vector<TradeoffSetting> grid{reference_setting(b.tracer, axes)};
  for (int r : axes.rays)
    for (int d : axes.depths) {
      TradeoffSetting s;
      s.label = setting_label(r, d);
      s.tracer = b.tracer;
      s.tracer.rays_per_source = r;
      s.tracer.max_depth = d;
      s.lod = b.lod;
      grid.push_back(s);
    }
  add_declared_toggles(b, radio, grid);
  add_mechanism_variants(b, grid);
  add_diffuse_variants(b, grid);
  add_search_variants(b, grid);
  return grid;
}

// ---- Scene, library, snapshots.

struct SceneVariant {
  std::unique_ptr<tracer::TraceScene> scene;
  std::map<std::pair<int, std::string>, std::uint32_t> models;  // (lod, library key) -> model index
  meshkit::SimplifyStats stats;
};

// The static scene at each simplification and the vehicle library at each
// LOD, built when first asked for.
class TradeoffScenes {
 public:
  // `store`: where the vehicle models' precomputed tables are kept (the scene's cache/).
  TradeoffScenes(meshkit::Scene static_scene, std::string vehicles_dir,
                 std::shared_ptr<const tracer::PrecomputeStore> store)
      : static_(std::move(static_scene)), vehicles_dir_(std::move(vehicles_dir)), store_(std::move(store)) {
    scenes_[0.0].scene = std::make_unique<tracer::TraceScene>(static_);
    scenes_[0.0].scene->set_precompute_store(store_);
    scenes_[0.0].stats.triangles_before = scenes_[0.0].stats.triangles_after = static_.triangle_count();
  }

  meshkit::Bounds static_bounds() const { return scenes_.at(0.0).scene->static_bounds(); }
  bool library_mode() const { return !vehicles_dir_.empty(); }

  VehicleLibrary& library(int lod) {  // by LOD (built-in: one, key 0)
    const int key = library_mode() ? lod : 0;
    auto& l = libraries_[key];
    if (!l) l = std::make_unique<VehicleLibrary>(vehicles_dir_, library_mode() ? lod : -1);
    return *l;
  }

  SceneVariant& scene_for(double simplify_m) {
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

  std::size_t triangles(double simplify_m) const { return scenes_.at(simplify_m).stats.triangles_after; }

  // The scene model of library entry `key` at `lod` (registered on first use).
  std::uint32_t model(SceneVariant& sv, int lod, const std::string& key) {
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

  // The snapshot's vehicles (at `lod`) placed in `sv`; its antennas and the RSUs.
  std::vector<tracer::Node> place(SceneVariant& sv, int lod, const SnapshotPoses& snap, const std::vector<NodeRow>& rsus) {
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

 private:
  const meshkit::Scene static_;
  const std::string vehicles_dir_;
  std::shared_ptr<const tracer::PrecomputeStore> store_;
  std::map<double, SceneVariant> scenes_;
  std::map<int, std::unique_ptr<VehicleLibrary>> libraries_;
};

// `n` of the eligible frame times, spread evenly over their span (indices).
std::set<std::size_t> spread_choice(const std::vector<double>& eligible, int n) {
  std::set<std::size_t> chosen;
  if (eligible.size() <= static_cast<std::size_t>(n)) {
    for (std::size_t i = 0; i < eligible.size(); ++i) chosen.insert(i);
    return chosen;
  }
  const double t0 = eligible.front(), t1 = eligible.back();
  for (int k = 0; k < n; ++k) {
    const double target = n == 1 ? 0.5 * (t0 + t1) : t0 + (t1 - t0) * k / (n - 1);
    std::size_t best = SIZE_MAX;
    for (std::size_t i = 0; i < eligible.size(); ++i)
      if (!chosen.count(i) && (best == SIZE_MAX || std::abs(eligible[i] - target) < std::abs(eligible[best] - target)))
        best = i;
    chosen.insert(best);
  }
  return chosen;
}

SnapshotPoses snapshot_poses(const FcdFrame& frame, const std::vector<const FcdVehicle*>& selected,
                             FcdTypeModels& type_models) {
  SnapshotPoses s;
  s.time_s = frame.time_s;
  s.line = frame.line;
  for (const FcdVehicle* v : selected) {
    s.vehicles.push_back(SnapVehicle{v->id, type_models.resolve(*v)->key, v->x, v->y, v->has_z ? v->z : 0.0,
                                     v->angle_deg, v->speed_mps});
  }
  return s;
}

// Pass 1: the frames with at least two traced vehicles; pass 2 takes the
// chosen ones (the selection depends on every earlier frame).
std::vector<SnapshotPoses> choose_snapshots(const std::string& fcd, const SweepSettings& cfg,
                                            const meshkit::Bounds& bounds, FcdTypeModels& type_models, int n) {
  auto traceable = [&](const FcdVehicle& v) { return type_models.resolve(v) != nullptr; };
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
  const std::set<std::size_t> chosen = spread_choice(eligible, n);
  std::vector<SnapshotPoses> snapshots;
  FcdReader reader(fcd, sweep_fcd_filter(cfg));
  SweepSelection selection(cfg, bounds, fcd);
  FcdFrame frame;
  std::size_t index = 0;
  while (snapshots.size() < chosen.size() && reader.next(frame)) {
    const auto selected = selection.select(frame, traceable);
    if (selected.size() < 2) continue;
    if (!chosen.count(index++)) continue;
    snapshots.push_back(snapshot_poses(frame, selected, type_models));
  }
  return snapshots;
}

// `n` consecutive frames (every one the sweep would trace) from the first
// with at least two traced vehicles, as the sweep steps them (nodes
// numbered RSUs first, then vehicles in order of appearance; models at `lod`
// in the scene as built): the coherence toggle's window.
std::vector<CoherenceFrame> window_frames(const std::string& fcd, const SweepSettings& cfg, TradeoffScenes& scenes,
                                          FcdTypeModels& type_models, int n, std::size_t rsus, int lod) {
  auto traceable = [&](const FcdVehicle& v) { return type_models.resolve(v) != nullptr; };
  SceneVariant& sv = scenes.scene_for(0);
  std::map<std::string, std::uint32_t> node_of;
  std::vector<CoherenceFrame> frames;
  FcdReader reader(fcd, sweep_fcd_filter(cfg));
  SweepSelection selection(cfg, scenes.static_bounds(), fcd);
  for (FcdFrame frame; frames.size() < static_cast<std::size_t>(n) && reader.next(frame);) {
    const auto selected = selection.select(frame, traceable);
    if (frames.empty() && selected.size() < 2) continue;
    CoherenceFrame f{frame.time_s, {}};
    for (const FcdVehicle* v : selected) {
      const FcdTypeModel* tm = type_models.resolve(*v);
      const auto node = node_of.emplace(v->id, static_cast<std::uint32_t>(rsus + node_of.size())).first->second;
      f.vehicles.push_back(sweep_vehicle(*v, *tm, node, scenes.model(sv, lod, tm->key)));
    }
    frames.push_back(std::move(f));
  }
  return frames;
}

// The coarsest LOD every entry the snapshots use has (-1: none, or built-in models).
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

// The variants known only once the snapshots are: the coarsest vehicle LOD,
// and each static simplification that changes the scene.
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

// ---- Tracing.

// Per setting: per-snapshot gains (first round), path and ray totals, and
// per snapshot its fastest time over the rounds.
struct GridTraces {
  std::vector<std::vector<PairGains>> gains;
  std::vector<double> paths, rays_traced;
  std::vector<std::vector<double>> best;
};

PairGains pair_gains(const tracer::Snapshot& traced) {
  PairGains pg;
  for (const auto& p : traced.pairs) {
    pg.power.push_back(p.stats.gain_incoherent);
    pg.los.push_back(static_cast<int>(p.los_class));
    std::array<double, kMechanismCount> m{};
    for (const auto& path : p.paths) m[mechanism_of(path)] += std::norm(path.a);
    pg.by_mechanism.push_back(m);
  }
  return pg;
}

// Snapshot-major, settings interleaved (and every repeat another full
// round), so a burst of load from elsewhere on the machine spreads over all
// settings instead of falsifying one; a snapshot's time is its fastest repeat.
GridTraces trace_grid(const std::vector<TradeoffSetting>& grid, const std::vector<SnapshotPoses>& snapshots,
                      const std::vector<NodeRow>& rsus, const tracer::RadioConfig& radio, int repeats,
                      TradeoffScenes& scenes) {
  for (const auto& s : grid) scenes.scene_for(s.simplify_m);
  GridTraces t{std::vector<std::vector<PairGains>>(grid.size()), std::vector<double>(grid.size(), 0),
               std::vector<double>(grid.size(), 0),
               std::vector<std::vector<double>>(grid.size(), std::vector<double>(snapshots.size(), INFINITY))};
  for (int rep = 0; rep < repeats; ++rep)
    for (std::size_t k = 0; k < snapshots.size(); ++k) {
      const auto t_snap = std::chrono::steady_clock::now();
      for (std::size_t g = 0; g < grid.size(); ++g) {
        const auto& s = grid[g];
        SceneVariant& sv = scenes.scene_for(s.simplify_m);
        const auto nodes = scenes.place(sv, s.lod, snapshots[k], rsus);
        const auto t0 = std::chrono::steady_clock::now();
        const tracer::Snapshot traced = tracer::trace_snapshot(*sv.scene, nodes, s.tracer, radio);
        t.best[g][k] = std::min(t.best[g][k], std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        if (rep > 0) continue;  // deterministic: the first round has the results
        t.gains[g].push_back(pair_gains(traced));
        t.paths[g] += static_cast<double>(traced.stats.paths);
        t.rays_traced[g] += static_cast<double>(traced.stats.rays);
      }
      spdlog::info("snapshot {}/{}{} (t = {:.1f} s, {} vehicles): {} settings in {:.1f} s", k + 1, snapshots.size(),
                   repeats > 1 ? fmt::format(", round {}/{}", rep + 1, repeats) : std::string(), snapshots[k].time_s,
                   snapshots[k].vehicles.size(), grid.size(),
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - t_snap).count());
    }
  return t;
}

// Each setting against the reference (grid[0]), and the Pareto front.
std::vector<TradeoffResult> score(const GridTraces& t, std::size_t n_snapshots, double rx_gain_db) {
  const double n = static_cast<double>(n_snapshots);
  std::vector<TradeoffResult> results(t.gains.size());
  for (std::size_t g = 0; g < results.size(); ++g) {
    auto& r = results[g];
    r.times_s = t.best[g];
    r.paths = t.paths[g] / n;
    r.rays_traced = t.rays_traced[g] / n;
    r.time_per_snapshot_s = quantile(r.times_s, 0.5);
    double sum = 0;
    for (double x : r.times_s) sum += x;
    r.time_mean_s = sum / n;
    compare_to_reference(t.gains[g], t.gains[0], r, rx_gain_db);
  }
  std::vector<std::pair<double, double>> points;
  for (const auto& r : results) points.emplace_back(r.time_per_snapshot_s, r.err_p95_db);
  const auto front = pareto_front(points);
  for (std::size_t g = 0; g < results.size(); ++g) results[g].pareto = front[g];
  return results;
}

// The cheapest setting within the target error that agrees on the LoS class (-1: none).
int suggest(const std::vector<TradeoffSetting>& grid, const std::vector<TradeoffResult>& results, double target_p95_db) {
  int suggested = -1;
  for (std::size_t g = 0; g < grid.size(); ++g) {
    const auto& r = results[g];
    if (grid[g].reference || !(r.err_p95_db <= target_p95_db) || !(r.los_agreement >= 0.99)) continue;
    if (suggested < 0 || r.time_per_snapshot_s < results[suggested].time_per_snapshot_s) suggested = static_cast<int>(g);
  }
  return suggested;
}

// ---- Outputs.

std::string tradeoff_csv(const std::vector<TradeoffSetting>& grid, const std::vector<TradeoffResult>& results,
                         const std::string& base_label) {
  std::ostringstream csv;
  csv << "label,rays,depth,diffuse,diffraction,refraction,lod,static_simplification,time_per_snapshot_s,"
         "err_median_db,err_p95_db,los_agreement,power_fraction,power_fraction_median,paths,pareto,rays_traced,"
         "missed_pairs,err_median_rx_db,err_p95_rx_db,base\n";
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
  }
  return csv.str();
}

json row_json(const TradeoffSetting& s, const TradeoffResult& r, std::size_t static_triangles) {
  return {{"label", s.label},
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
          {"static_triangles", static_triangles},
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
          {"pareto", r.pareto}};
}

// What tradeoff.json's metrics mean.
json metrics_json() {
  return {{"gain", "incoherent sum of |a|^2 per pair, dB, floored at -200 dB"},
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
          {"static_simplification", "static geometry decimated within this error (m); 0: as built"}};
}

json tradeoff_provenance(const TradeoffArgs& args, const TradeoffInputs& in, const TraceSettings& settings,
                         const SweepSettings& cfg, const GridAxes& axes, const GridBase& b,
                         const std::vector<std::string>& argv) {
  std::vector<InputFile> inputs{{"scene", in.scene_file.string()}, {"fcd", in.fcd}};
  for (const auto& v : in.vtype_files) inputs.push_back({"vtypes", v});
  if (!in.rsus_file.empty()) inputs.push_back({"rsus", in.rsus_file});
  if (!in.config.empty()) inputs.push_back({args.city.empty() ? "config" : "city", in.config});
  if (in.library_mode()) inputs.push_back({"vehicle_manifest", (fs::path(in.vehicles_dir) / "manifest.json").string()});
  json cfg_json = settings.to_json();
  cfg_json["sweep"] = cfg.to_json();
  cfg_json["vehicles"] = in.library_mode() ? "library" : "built-in parametric";
  cfg_json["tradeoff"] = {{"snapshots", axes.snapshots},
                          {"rays", axes.rays},
                          {"depths", axes.depths},
                          {"simplify_m", axes.simplify},
                          {"reference_rays", axes.ref_rays},
                          {"reference_depth", axes.ref_depth},
                          {"base_rays", b.rays},
                          {"base_depth", b.depth},
                          {"quick", args.quick},
                          {"repeats", std::max(1, args.repeats)},
                          {"target_p95_db", args.target_p95_db},
                          {"coherence_window", axes.coherence_window}};
  json prov = provenance("tradeoff", inputs, cfg_json, recorded_command(argv));
  in.settings.record_sets(prov);
  prov["embree"] = tracer::embree_version();
  return prov;
}

json snapshots_json(const std::vector<SnapshotPoses>& snapshots, std::size_t rsus) {
  json snaps = json::array();
  for (const auto& s : snapshots) {
    json ids = json::array();
    for (const auto& v : s.vehicles) ids.push_back(v.id);
    const std::size_t nodes = s.vehicles.size() + rsus;
    snaps.push_back({{"time_s", s.time_s}, {"fcd_line", s.line}, {"vehicles", ids}, {"pairs", nodes * (nodes - 1) / 2}});
  }
  return snaps;
}

// A table for the terminal, and where the error of the tail comes from.
std::string terminal_table(const std::vector<TradeoffSetting>& grid, const std::vector<TradeoffResult>& results) {
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
  return table.str();
}

// Everything a run computed, for the outputs.
struct TradeoffRun {
  std::vector<TradeoffSetting> grid;
  std::vector<TradeoffResult> results;
  std::vector<SnapshotPoses> snapshots;
  std::size_t rsus = 0;
  int suggested = -1;
  std::optional<CoherenceWindowResult> coherence;  // the coherence toggle's window
  double coherence_t0 = 0;
};

std::string coherence_text(const CoherenceWindowResult& c, double t0) {
  return fmt::format(
      "\ncoherence over {} frames from t = {:.1f} s ({} pair-frames; [sweep] coherence off = reference): tracing {:.2f} s "
      "off, {:.2f} s on ({:.2f} x; {:.1f} % of the traced pair-frames searched); LoS {:.2f} %, Fresnel {:.2f} %; "
      "gain difference p50 / p99 / max {:.2f} / {:.2f} / {:.2f} dB{}\n",
      c.frames, t0, c.pair_frames, c.trace_off_s, c.trace_on_s, c.speedup(),
      c.traced_on ? 100.0 * static_cast<double>(c.searched_on) / static_cast<double>(c.traced_on) : 0.0,
      100 * c.los_agreement, 100 * c.fresnel_agreement, c.err_p50_db, c.err_p99_db, c.err_max_db,
      c.same_links ? "" : " (the sweeps wrote different pairs)");
}

// tradeoff.csv, tradeoff.json and (args.chart) tradeoff.png under in.out;
// the summary without its wall time.
json write_outputs(const TradeoffArgs& args, const TradeoffInputs& in, const TradeoffRun& run, const json& prov,
                   const GridBase& b, const TradeoffScenes& scenes) {
  json rows = json::array();
  for (std::size_t g = 0; g < run.grid.size(); ++g)
    rows.push_back(row_json(run.grid[g], run.results[g], scenes.triangles(run.grid[g].simplify_m)));
  json doc = {{"format", "raysweep-tradeoff"},
              {"title", in.title},
              {"rows", rows},
              {"snapshots", snapshots_json(run.snapshots, run.rsus)},
              {"threads", tbb::this_task_arena::max_concurrency()},
              {"suggested", run.suggested >= 0 ? json(run.grid[run.suggested].label) : json(nullptr)},
              {"metrics", metrics_json()},
              {"provenance", prov}};
  if (run.coherence) {
    doc["coherence"] = coherence_json(*run.coherence);
    doc["coherence"]["t0_s"] = run.coherence_t0;
  }

  const fs::path dir(in.out);
  fs::create_directories(dir);
  write_file_atomic(dir / "tradeoff.csv", tradeoff_csv(run.grid, run.results, setting_label(b.rays, b.depth)));
  write_file_atomic(dir / "tradeoff.json", doc.dump(1) + "\n");
  const fs::path png = dir / "tradeoff.png";
  bool chart = false;
  if (args.chart) {
    chart = run_python_script("tradeoff_chart.py", {(dir / "tradeoff.csv").string(), png.string(), "--title",
                                                    "raysweep tradeoff: " + in.title});
    if (!chart) spdlog::warn("{}: no chart (python3 with matplotlib needed)", png.string());
  }
  json summary = {{"out", in.out},
                  {"csv", (dir / "tradeoff.csv").string()},
                  {"json", (dir / "tradeoff.json").string()},
                  {"settings", run.grid.size()},
                  {"snapshots", run.snapshots.size()},
                  {"table", terminal_table(run.grid, run.results) +
                                (run.coherence ? coherence_text(*run.coherence, run.coherence_t0) : std::string())},
                  {"suggested", doc["suggested"]},
                  {"target_p95_db", args.target_p95_db}};
  if (chart) summary["png"] = png.string();
  return summary;
}

}  // namespace

json run_tradeoff_stage(const TradeoffArgs& args, const std::vector<std::string>& argv) {
  const auto t_start = std::chrono::steady_clock::now();
  TradeoffInputs in = resolve_inputs(args);
  const GridAxes axes = parse_axes(args);
  if (args.city.empty()) in.settings = load_settings(in.config, args.set);
  const TraceSettings& settings = in.settings.trace;
  const SweepSettings& cfg = in.settings.sweep;
  tracer::validate(settings.tracer, settings.radio);

  // Built-in models are full detail (a library's LOD 0).
  const GridBase base = grid_base(settings.tracer, axes, in.library_mode() ? cfg.lod : 0);
  TradeoffRun run;
  run.grid = build_grid(base, axes, settings.radio);
  for (const auto& s : run.grid) tracer::validate(s.tracer, settings.radio);

  spdlog::info("tradeoff: reading {} and {}", in.scene_file.string(), in.fcd);
  TradeoffScenes scenes(exclude_objects(read_scene_glb(in.scene_file.parent_path()), cfg.exclude_objects), in.vehicles_dir,
                        scene_precompute_store(in.scene_file.parent_path()));
  const VTypeMap vtypes = read_vtype_files(in.vtype_files);
  FcdTypeModels type_models(vtypes, scenes.library(base.lod), in.library_mode(), in.fcd);
  run.snapshots = choose_snapshots(in.fcd, cfg, scenes.static_bounds(), type_models, axes.snapshots);
  std::vector<NodeRow> rsus;
  if (!in.rsus_file.empty()) rsus = read_nodes_csv(in.rsus_file);
  run.rsus = rsus.size();
  add_scene_variants(base, axes, coarsest_lod(scenes, in.vehicles_dir, run.snapshots), scenes, run.grid);

  std::size_t max_vehicles = 0;
  for (const auto& s : run.snapshots) max_vehicles = std::max(max_vehicles, s.vehicles.size());
  spdlog::info("tradeoff: {} settings x {} snapshots (t = {:.1f}..{:.1f} s, up to {} vehicles{}), {} threads",
               run.grid.size(), run.snapshots.size(), run.snapshots.front().time_s, run.snapshots.back().time_s,
               max_vehicles, rsus.empty() ? "" : fmt::format(" + {} RSUs", rsus.size()),
               tbb::this_task_arena::max_concurrency());
  const GridTraces traces =
      trace_grid(run.grid, run.snapshots, rsus, settings.radio, std::max(1, args.repeats), scenes);
  // The weakest channel gain a receiver hears (for the *_rx errors).
  const double rx_gain_db = settings.radio.sensitivity_dbm - settings.radio.tx_power_dbm;
  run.results = score(traces, run.snapshots.size(), rx_gain_db);
  run.suggested = suggest(run.grid, run.results, args.target_p95_db);
  if (axes.coherence_window > 0) {
    const auto window = window_frames(in.fcd, cfg, scenes, type_models, axes.coherence_window, rsus.size(), base.lod);
    std::vector<generators::SweepRsu> sweep_rsus;
    for (std::size_t k = 0; k < rsus.size(); ++k)
      sweep_rsus.push_back({static_cast<std::uint32_t>(k), {rsus[k].x, rsus[k].y, rsus[k].z}});
    spdlog::info("tradeoff: coherence off and on over {} frames", window.size());
    run.coherence = compare_coherence(*scenes.scene_for(0).scene, settings.tracer, settings.radio, cfg.options,
                                      sweep_rsus, window);
    run.coherence_t0 = window.empty() ? 0.0 : window.front().time_s;
  }

  const json prov = tradeoff_provenance(args, in, settings, cfg, axes, base, argv);
  json summary = write_outputs(args, in, run, prov, base, scenes);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  spdlog::info("tradeoff: {} settings in {:.1f} s -> {}", run.grid.size(), wall, in.out);
  summary["wall_seconds"] = wall;
  return summary;
}

}  // namespace raysweep::pipeline
