// [sinr]: 802.11p and NR-V2X sharing the channel (`raysweep sinr`, `run`).
#pragma once

#include <vector>

#include <nlohmann/json.hpp>

#include "generators/sinr/channel_models.hpp"
#include "generators/sinr/sinr_config.hpp"

namespace raysweep::pipeline {

struct SinrSettings {
  bool present = false;  // the file has a [sinr] table (`raysweep run` then computes outcomes)
  bool enabled = true;
  generators::sinr::SinrConfig config;
  generators::sinr::StochasticOptions stochastic;
  std::vector<generators::sinr::SinrModel> models{generators::sinr::SinrModel{}};  // `run`: the first is the reference
  bool shared_schedule = true;  // `run`: the other models reuse the reference's transmissions
  bool isolated_runs = false;   // `run`: also the reference with each RAT alone (no coexistence)
  nlohmann::json to_json() const;
};

}  // namespace raysweep::pipeline
