// `raysweep tradeoff`'s coherence toggle: a short window of consecutive
// frames swept through generators::Sweep with [sweep] coherence off (every
// frame from scratch on one lattice), on with each `lattice_frames` K of the
// axis (turned lattices, the sequences of the K frames before carried), and
// once more as the reference: coherent (K = 4) with the grid's reference
// rays, a better sample of the same model. Each sweep's tracing time and
// its difference from the reference: LoS and Fresnel class agreement and
// the per-pair-frame wideband gain difference (gain_incoherent_db, both
// floored at the sensitivity floor radio.sensitivity_dbm - radio.tx_power_dbm).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generators/sweep/sweep.hpp"

namespace raysweep::pipeline {

struct CoherenceFrame {
  double time_s = 0;
  std::vector<generators::SweepVehicle> vehicles;
};

// One sweep of the window against the reference.
struct CoherenceSweepResult {
  std::string label;           // "off", or "K=k"
  std::uint32_t lattice_frames = 1;  // 0: coherence off
  double trace_s = 0;
  std::size_t carried = 0;     // sequences carried into the frames' traces
  double los_agreement = 0, fresnel_agreement = 0;
  double err_p50_db = 0, err_p95_db = 0, err_p99_db = 0, err_max_db = 0;
  bool same_links = true;      // the same pairs as the reference in every frame
};

struct CoherenceWindowResult {
  std::size_t frames = 0, pair_frames = 0;
  int reference_rays = 0;
  double reference_trace_s = 0;
  std::vector<CoherenceSweepResult> sweeps;  // off first, then each K
};

// The sweeps over `frames` (frame indices from 0: a window shorter than
// options.block_frames is one block), each with its own Sweep on `scene`.
CoherenceWindowResult compare_coherence(tracer::TraceScene& scene, const tracer::TracerConfig& tracer,
                                        const tracer::RadioConfig& radio, generators::SweepOptions options,
                                        const std::vector<generators::SweepRsu>& rsus,
                                        const std::vector<CoherenceFrame>& frames,
                                        const std::vector<int>& lattice_frames, int reference_rays);

nlohmann::json coherence_json(const CoherenceWindowResult& r);

}  // namespace raysweep::pipeline
