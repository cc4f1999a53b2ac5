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

}  // namespace

double CoherenceWindowResult::speedup() const {
  return trace_on_s > 0 ? trace_off_s / trace_on_s : std::numeric_limits<double>::quiet_NaN();
}

CoherenceWindowResult compare_coherence(tracer::TraceScene& scene, const tracer::TracerConfig& tracer,
                                        const tracer::RadioConfig& radio, generators::SweepOptions options,
                                        const std::vector<generators::SweepRsu>& rsus,
                                        const std::vector<CoherenceFrame>& frames) {
  options.coherence = false;
  const WindowRun off = sweep_window(scene, tracer, radio, options, rsus, frames);
  options.coherence = true;
  const WindowRun on = sweep_window(scene, tracer, radio, options, rsus, frames);
  const double floor_db = radio.sensitivity_dbm - radio.tx_power_dbm;
  CoherenceWindowResult r;
  r.frames = frames.size();
  r.trace_off_s = off.stats.trace_seconds;
  r.trace_on_s = on.stats.trace_seconds;
  r.carried_on = on.stats.carried_solved;
  std::vector<double> err;
  std::size_t los = 0, fresnel = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const auto& a = off.frames[k].links;
    const auto& b = on.frames[k].links;
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
  r.pair_frames = err.size();
  const double n = static_cast<double>(err.size());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  r.los_agreement = err.empty() ? nan : static_cast<double>(los) / n;
  r.fresnel_agreement = err.empty() ? nan : static_cast<double>(fresnel) / n;
  r.err_p50_db = quantile(err, 0.5);
  r.err_p99_db = quantile(err, 0.99);
  r.err_max_db = err.empty() ? nan : *std::max_element(err.begin(), err.end());
  return r;
}

nlohmann::json coherence_json(const CoherenceWindowResult& r) {
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  return {{"frames", r.frames},
          {"pair_frames", r.pair_frames},
          {"carried_sequences_on", r.carried_on},
          {"trace_s_off", r.trace_off_s},
          {"trace_s_on", r.trace_on_s},
          {"speedup", num(r.speedup())},
          {"los_agreement", num(r.los_agreement)},
          {"fresnel_agreement", num(r.fresnel_agreement)},
          {"gain_diff_p50_db", num(r.err_p50_db)},
          {"gain_diff_p99_db", num(r.err_p99_db)},
          {"gain_diff_max_db", num(r.err_max_db)},
          {"same_links", r.same_links}};
}

}  // namespace raysweep::pipeline
