// [ns3]: the lookup table ns-3's raysweep models read.
#pragma once

#include <cstdint>

#include <nlohmann/json.hpp>

namespace raysweep::pipeline {

struct Ns3Settings {
  bool present = false;  // the file has an [ns3] table (`raysweep run` then writes <out>/ns3/table.h5)
  bool enabled = true;
  std::uint32_t subcarriers_per_band = 4;  // per-band gains from the CFR; 0: none
  nlohmann::json to_json() const;
};

}  // namespace raysweep::pipeline
