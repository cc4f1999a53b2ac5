#include "pipeline/tradeoff/coherence.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "pipeline/quantile.hpp"

namespace raysweep::pipeline {

namespace {

struct WindowRun {
  std::vector<generators::FrameRecord> frames;
  generators::SweepStats stats;
};

WindowRun sweep_window(tracer::TraceScene& scene, const tracer::TracerConfig& tracer, const tracer::RadioConfig& radio,
                       const generators::SweepOptions& options, const std::vector<generators::SweepRsu>& rsus,
                       const std::vector<CoherenceFrame>& frames) {
  generators::Sweep sweep(scene, tracer, radio, options, rsus);
  WindowRun run;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    generators::FrameRecord rec = sweep.step(k, frames[k].time_s, frames[k].vehicles);
    rec.paths.clear();  // only the links are compared
    rec.interactions.clear();
    rec.cfr.clear();
    run.frames.push_back(std::move(rec));
  }
  run.stats = sweep.stats();
  return run;
}

double floored(float gain_db, double floor_db) {
  return std::isfinite(gain_db) ? std::max(static_cast<double>(gain_db), floor_db) : floor_db;
}

// `run` against `ref`, frame by frame.
CoherenceSweepResult against(const WindowRun& ref, const WindowRun& run, double floor_db) {
  CoherenceSweepResult r;
  r.trace_s = run.stats.trace_seconds;
  r.carried = run.stats.carried_solved;
  std::vector<double> err;
  std::size_t los = 0, fresnel = 0;
  for (std::size_t k = 0; k < ref.frames.size(); ++k) {
    const auto& a = ref.frames[k].links;
    const auto& b = run.frames[k].links;
    if (a.size() != b.size()) r.same_links = false;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
      if (a[i].tx != b[i].tx || a[i].rx != b[i].rx) {
        r.same_links = false;
        continue;
      }
      los += a[i].los_class == b[i].los_class;
      fresnel += a[i].los_class_fresnel == b[i].los_class_fresnel;
      err.push_back(std::abs(floored(b[i].gain_incoherent_db, floor_db) - floored(a[i].gain_incoherent_db, floor_db)));
    }
  }
  const double n = static_cast<double>(err.size());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  r.los_agreement = err.empty() ? nan : static_cast<double>(los) / n;
  r.fresnel_agreement = err.empty() ? nan : static_cast<double>(fresnel) / n;
  r.err_p50_db = quantile(err, 0.5);
  r.err_p95_db = quantile(err, 0.95);
  r.err_p99_db = quantile(err, 0.99);
  r.err_max_db = err.empty() ? nan : *std::max_element(err.begin(), err.end());
  return r;
}

}  // namespace

CoherenceWindowResult compare_coherence(tracer::TraceScene& scene, const tracer::TracerConfig& tracer,
                                        const tracer::RadioConfig& radio, generators::SweepOptions options,
                                        const std::vector<generators::SweepRsu>& rsus,
                                        const std::vector<CoherenceFrame>& frames,
                                        const std::vector<int>& lattice_frames, int reference_rays) {
  const double floor_db = radio.sensitivity_dbm - radio.tx_power_dbm;
  tracer::TracerConfig reference = tracer;
  reference.rays_per_source = reference_rays;
  generators::SweepOptions ref_options = options;
  ref_options.coherence = true;
  ref_options.lattice_frames = 4;
  const WindowRun ref = sweep_window(scene, reference, radio, ref_options, rsus, frames);
  CoherenceWindowResult r;
  r.frames = frames.size();
  r.reference_rays = reference_rays;
  r.reference_trace_s = ref.stats.trace_seconds;
  for (const auto& f : ref.frames) r.pair_frames += f.links.size();
  options.coherence = false;
  r.sweeps.push_back(against(ref, sweep_window(scene, tracer, radio, options, rsus, frames), floor_db));
  r.sweeps.back().label = "off";
  r.sweeps.back().lattice_frames = 0;
  options.coherence = true;
  for (const int k : lattice_frames) {
    options.lattice_frames = static_cast<std::uint32_t>(k);
    r.sweeps.push_back(against(ref, sweep_window(scene, tracer, radio, options, rsus, frames), floor_db));
    r.sweeps.back().label = "K=" + std::to_string(k);
    r.sweeps.back().lattice_frames = options.lattice_frames;
  }
  return r;
}

nlohmann::json coherence_json(const CoherenceWindowResult& r) {
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  nlohmann::json sweeps = nlohmann::json::array();
  for (const auto& s : r.sweeps)
    sweeps.push_back({{"label", s.label},
                      {"lattice_frames", s.lattice_frames},
                      {"trace_s", s.trace_s},
                      {"carried_sequences", s.carried},
                      {"los_agreement", num(s.los_agreement)},
                      {"fresnel_agreement", num(s.fresnel_agreement)},
                      {"gain_diff_p50_db", num(s.err_p50_db)},
                      {"gain_diff_p95_db", num(s.err_p95_db)},
                      {"gain_diff_p99_db", num(s.err_p99_db)},
                      {"gain_diff_max_db", num(s.err_max_db)},
                      {"same_links", s.same_links}});
  return {{"frames", r.frames},
          {"pair_frames", r.pair_frames},
          {"reference_rays", r.reference_rays},
          {"reference_trace_s", r.reference_trace_s},
          {"sweeps", sweeps}};
}

}  // namespace raysweep::pipeline
