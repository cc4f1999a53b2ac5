#include "pipeline/tradeoff/report.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "pipeline/preview.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/staged_output.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

std::string fmt_num(double v) { return std::isfinite(v) ? fmt::format("{:.6g}", v) : std::string("nan"); }
json json_num(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json tail_json(const TradeoffResult& r) {
  json j = json::object();
  for (std::size_t m = 0; m < kMechanismCount && m < r.tail_by_mechanism.size(); ++m)
    j[kMechanisms[m]] = r.tail_by_mechanism[m];
  return j;
}

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

std::string coherence_text(const CoherenceWindowResult& c, double t0) {
  std::ostringstream text;
  text << fmt::format(
      "\ncoherence over {} frames from t = {:.1f} s ({} pair-frames), against the reference ({} rays, K = 4; "
      "tracing {:.2f} s):\n{:>8} {:>10} {:>9} {:>8} {:>8} {:>22}\n",
      c.frames, t0, c.pair_frames, c.reference_rays, c.reference_trace_s, "sweep", "tracing s", "carried", "LoS %",
      "Fresnel %", "gain diff p50/p99/max");
  for (const auto& s : c.sweeps)
    text << fmt::format("{:>8} {:>10.2f} {:>9} {:>8.2f} {:>8.2f} {:>8.2f} /{:>5.2f} /{:>6.2f}{}\n", s.label, s.trace_s,
                        s.carried, 100 * s.los_agreement, 100 * s.fresnel_agreement, s.err_p50_db, s.err_p99_db,
                        s.err_max_db, s.same_links ? "" : " (other pairs than the reference's)");
  return text.str();
}

}  // namespace

json tradeoff_provenance(const TradeoffArgs& args, const TradeoffInputs& in, const Settings& settings,
                         const GridAxes& axes, const GridBase& b, const std::vector<std::string>& argv) {
  std::vector<InputFile> inputs{{"scene", in.scene_file.string()}, {"fcd", in.fcd}};
  for (const auto& v : in.vtype_files) inputs.push_back({"vtypes", v});
  if (!in.rsus_file.empty()) inputs.push_back({"rsus", in.rsus_file});
  if (!in.config.empty()) inputs.push_back({args.city.empty() ? "config" : "city", in.config});
  if (in.library_mode()) inputs.push_back({"vehicle_manifest", (fs::path(in.vehicles_dir) / "manifest.json").string()});
  json cfg_json = settings.trace.to_json();
  cfg_json["sweep"] = settings.sweep.to_json();
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
                          {"coherence_window", axes.coherence_window},
                          {"lattice_frames", axes.lattice_frames}};
  json prov = provenance("tradeoff", inputs, cfg_json, recorded_command(argv));
  settings.record_sets(prov);
  prov["embree"] = tracer::embree_version();
  return prov;
}

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
  const fs::path coherence_png = dir / "tradeoff.coherence.png";
  if (args.chart) {
    std::vector<std::string> chart_args{(dir / "tradeoff.csv").string(), png.string(), "--title",
                                        "raysweep tradeoff: " + in.title};
    if (run.coherence)
      chart_args.insert(chart_args.end(), {"--coherence", (dir / "tradeoff.json").string(), coherence_png.string()});
    chart = run_python_script("tradeoff_chart.py", chart_args);
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
  if (chart && run.coherence) summary["coherence_png"] = coherence_png.string();
  return summary;
}

}  // namespace raysweep::pipeline
