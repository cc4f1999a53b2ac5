#include "pipeline/tradeoff/stage.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cstdint>

#include "pipeline/precompute_store.hpp"
#include "pipeline/scene_cache.hpp"
#include "pipeline/sweep_stage.hpp"
#include "pipeline/trace_inputs.hpp"
#include "pipeline/tradeoff/coherence.hpp"
#include "pipeline/tradeoff/grid.hpp"
#include "pipeline/tradeoff/inputs.hpp"
#include "pipeline/tradeoff/measure.hpp"
#include "pipeline/tradeoff/metrics.hpp"
#include "pipeline/tradeoff/report.hpp"
#include "pipeline/tradeoff/scenes.hpp"
#include "pipeline/tradeoff/snapshots.hpp"
#include "pipeline/vtypes.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::pipeline {

using json = nlohmann::json;

namespace {

// The coherence toggle over `window` consecutive frames, in the scene as built.
void run_coherence_toggle(const TradeoffInputs& in, const Settings& settings, const GridAxes& axes,
                          const GridBase& base, const std::vector<NodeRow>& rsus, TradeoffScenes& scenes,
                          FcdTypeModels& type_models, TradeoffRun& run) {
  const SweepSettings& cfg = settings.sweep;
  const auto window = window_frames(in.fcd, cfg, scenes, type_models, axes.coherence_window, rsus.size(), base.lod);
  std::vector<generators::SweepRsu> sweep_rsus;
  for (std::size_t k = 0; k < rsus.size(); ++k)
    sweep_rsus.push_back({static_cast<std::uint32_t>(k), {rsus[k].x, rsus[k].y, rsus[k].z}});
  spdlog::info("tradeoff: coherence off, on with lattice_frames {}, and the reference ({} rays) over {} frames",
               fmt::join(axes.lattice_frames, ","), axes.ref_rays, window.size());
  run.coherence = compare_coherence(*scenes.scene_for(0).scene, settings.trace.tracer, settings.trace.radio,
                                    cfg.options, sweep_rsus, window, axes.lattice_frames, axes.ref_rays);
  run.coherence_t0 = window.empty() ? 0.0 : window.front().time_s;
}

}  // namespace

json run_tradeoff_stage(const TradeoffArgs& args, const Settings& all, const std::vector<std::string>& argv) {
  const auto t_start = std::chrono::steady_clock::now();
  const TradeoffInputs in = resolve_inputs(args, all);
  const GridAxes axes = parse_axes(args);
  const TraceSettings& settings = all.trace;
  const SweepSettings& cfg = all.sweep;
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
  if (axes.coherence_window > 0) run_coherence_toggle(in, all, axes, base, rsus, scenes, type_models, run);

  const json prov = tradeoff_provenance(args, in, all, axes, base, argv);
  json summary = write_outputs(args, in, run, prov, base, scenes);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  spdlog::info("tradeoff: {} settings in {:.1f} s -> {}", run.grid.size(), wall, in.out);
  summary["wall_seconds"] = wall;
  return summary;
}

}  // namespace raysweep::pipeline
