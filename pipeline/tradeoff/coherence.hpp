// `raysweep tradeoff`'s coherence toggle: a short window of consecutive
// frames swept twice through generators::Sweep, with [sweep] coherence off
// (every frame from scratch on one lattice) and on (turned lattices, the
// sequences of the frames before carried), and what carrying costs and
// changes: LoS and Fresnel class agreement and the per-pair-frame wideband
// gain difference (gain_incoherent_db, both floored at the sensitivity
// floor radio.sensitivity_dbm - radio.tx_power_dbm).
#pragma once

#include <cstddef>
#include <vector>

#include <nlohmann/json.hpp>

#include "generators/sweep/sweep.hpp"

namespace raysweep::pipeline {

struct CoherenceFrame {
  double time_s = 0;
  std::vector<generators::SweepVehicle> vehicles;
};

struct CoherenceWindowResult {
  std::size_t frames = 0, pair_frames = 0;
  std::size_t carried_on = 0;  // sequences the coherent sweep carried into its frames' traces
  double trace_off_s = 0, trace_on_s = 0;
  double los_agreement = 0, fresnel_agreement = 0;
  double err_p50_db = 0, err_p99_db = 0, err_max_db = 0;
  bool same_links = true;  // both sweeps wrote the same pairs in every frame
  double speedup() const;  // trace_off_s / trace_on_s
};

// Both sweeps over `frames` (frame indices from 0: a window shorter than
// options.block_frames is one block), each with its own Sweep on `scene`.
CoherenceWindowResult compare_coherence(tracer::TraceScene& scene, const tracer::TracerConfig& tracer,
                                        const tracer::RadioConfig& radio, generators::SweepOptions options,
                                        const std::vector<generators::SweepRsu>& rsus,
                                        const std::vector<CoherenceFrame>& frames);

nlohmann::json coherence_json(const CoherenceWindowResult& r);

}  // namespace raysweep::pipeline
