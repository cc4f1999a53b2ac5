#include "pipeline/tradeoff/grid.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "pipeline/settings/tables.hpp"
#include "pipeline/tradeoff/stage.hpp"

namespace raysweep::pipeline {

namespace {

constexpr int kMaxGridRays = 1 << 22;
constexpr int kMaxReferenceDepth = 5;

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

}  // namespace

std::string setting_label(int rays, int depth) { return fmt::format("r{} d{}", rays, depth); }

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
  a.lattice_frames = args.lattice_frames.empty()
                         ? (args.quick ? std::vector<int>{1, 4} : std::vector<int>{1, 2, 4, 8})
                         : parse_int_list("--lattice-frames", args.lattice_frames, 1, 64);
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

TradeoffSetting GridBase::variant(const std::string& what) const {
  TradeoffSetting s;
  s.label = setting_label(rays, depth) + " " + what;
  s.tracer = tracer;
  s.tracer.rays_per_source = rays;
  s.tracer.max_depth = depth;
  s.lod = lod;
  return s;
}

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

namespace {

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

}  // namespace

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

}  // namespace raysweep::pipeline
