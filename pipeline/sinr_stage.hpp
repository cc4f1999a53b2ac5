// Stages `raysweep sinr` and `raysweep report`: SINR outcomes of 802.11p and
// NR-V2X sharing one channel, computed on a traced channel dataset or on a 3GPP
// stochastic baseline (generators/sinr/), and the report that compares them.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/settings/settings.hpp"

namespace raysweep::pipeline {

struct SinrArgs {
  std::string channels;  // channel dataset .h5
  std::string out;       // SINR outcome .h5
  std::string channel_model = "ray";
  bool los_from_ray = false;
  std::string schedule_from;  // reuse the transmissions of this SINR file
  std::string rats_enabled;   // override [sinr] rats_enabled ("both", "80211p-only", "nrv2x-only")
  std::optional<std::uint64_t> seed;
};

// [sinr] from `settings`, with the arguments' overrides.
nlohmann::json run_sinr_stage(const SinrArgs& args, const Settings& settings, const std::vector<std::string>& argv);

struct ReportArgs {
  std::vector<std::string> sinr;  // the first is the reference of the disagreement ratios
  std::string out;                // folder
  std::string labels;             // comma-separated, optional
};

// Runs python/sinr_report.py; returns {out, pngs, table (Markdown)}. Throws
// std::runtime_error when the report cannot be made.
nlohmann::json run_report_stage(const ReportArgs& args);

}  // namespace raysweep::pipeline
