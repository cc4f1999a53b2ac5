// The JSON document of `raysweep trace` (docs/cli.md), streamed: pairs and
// paths go to the stream as they are formatted, never into a DOM, so a
// 60-vehicle trace's tens of megabytes cost one pass over the snapshot. The
// text is what nlohmann::json's dump(1) of the same document gives.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tracer/channel.hpp"
#include "tracer/solver.hpp"

namespace raysweep::pipeline {

struct TraceDocument {
  const tracer::Snapshot* snapshot = nullptr;
  const std::vector<tracer::Node>* nodes = nullptr;
  const std::vector<std::string>* objects = nullptr;    // object names by index
  const std::vector<std::string>* materials = nullptr;  // material names by index
  const tracer::OfdmGrid* grid = nullptr;  // each pair's frequency response when set
  std::string cfr_spec;                    // the grid as given (--cfr)
  nlohmann::json radio, provenance;
};

void write_trace_json(std::ostream& out, const TraceDocument& doc);

}  // namespace raysweep::pipeline
