// Stages `raysweep sinr` and `raysweep report`: SINR outcomes of 802.11p and
// NR-V2X sharing one channel, computed on a traced channel dataset or on a 3GPP
// stochastic baseline (generators/sinr/), and the report that compares them.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generators/sinr/channel_models.hpp"
#include "generators/sinr/sinr_config.hpp"

namespace raysweep::pipeline {

// One channel model of a comparison: "ray", "tr36885", "tr37885-urban",
// "tr37885-highway", each optionally with "+los-from-ray".
struct SinrModel {
  generators::sinr::ChannelModelKind kind = generators::sinr::ChannelModelKind::ray;
  bool los_from_ray = false;
  std::string label() const;  // e.g. "tr37885-urban+los-from-ray"
};
SinrModel parse_sinr_model(const std::string& s);  // throws std::invalid_argument

// The [sinr] table. Unknown keys and bad values are ConfigErrors naming file, key and line.
struct SinrSettings {
  bool present = false;  // the file has a [sinr] table (`raysweep run` then computes outcomes)
  bool enabled = true;
  generators::sinr::SinrConfig config;
  generators::sinr::StochasticOptions stochastic;
  std::vector<SinrModel> models{SinrModel{}};  // `run`: the first is the reference
  bool shared_schedule = true;  // `run`: the other models reuse the reference's transmissions
  bool isolated_runs = false;   // `run`: also the reference with each RAT alone (no coexistence)
  nlohmann::json to_json() const;
};
SinrSettings load_sinr_settings(const std::string& path);

struct SinrArgs {
  std::string channels;  // channel dataset .h5
  std::string out;       // SINR outcome .h5
  std::string config;    // TOML with a [sinr] table (optional)
  std::string channel_model = "ray";
  bool los_from_ray = false;
  std::string schedule_from;  // reuse the transmissions of this SINR file
  std::string rats_enabled;   // override [sinr] rats_enabled ("both", "80211p-only", "nrv2x-only")
  std::optional<std::uint64_t> seed;
};

nlohmann::json run_sinr_stage(const SinrArgs& args, const std::vector<std::string>& argv);

struct ReportArgs {
  std::vector<std::string> sinr;  // the first is the reference of the disagreement ratios
  std::string out;                // folder
  std::string labels;             // comma-separated, optional
};

// Runs python/sinr_report.py; returns {out, pngs, table (Markdown)}. Throws
// std::runtime_error when the report cannot be made.
nlohmann::json run_report_stage(const ReportArgs& args);

}  // namespace raysweep::pipeline
