// `raysweep trace --out X.h5`: the snapshot as a one-frame channel dataset
// (schemas/README.md), the layout `raysweep sweep` writes, so the readers,
// `raysweep info` / `validate` and the SINR stage take a one-shot trace as
// they take a sweep.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "generators/dataset/dataset_writer.hpp"
#include "pipeline/trace_inputs.hpp"
#include "tracer/channel.hpp"
#include "tracer/solver.hpp"

namespace raysweep::pipeline {

// What the snapshot was traced from: vehicles first (node k is pose k), then
// the bare antennas (node rows), in the order of `nodes`.
struct SnapshotNodes {
  const std::vector<tracer::Node>* nodes = nullptr;
  const std::vector<PoseRow>* poses = nullptr;
  const std::vector<NodeRow>* antennas = nullptr;
  std::vector<meshkit::VehicleDims> dims;  // per pose
  std::vector<std::string> static_objects;
  // Per node: its antenna stands inside a building (TraceScene::enclosing_object);
  // empty: none does.
  std::vector<char> enclosed;
};

// The header every writer of a channel dataset gives it: version, commit,
// config and provenance (its inputs too), the radio's carrier and bandwidth,
// and the frequency-response grid when there is one.
generators::DatasetHeader channel_dataset_header(const nlohmann::json& config, const nlohmann::json& provenance,
                                                 const tracer::RadioConfig& radio, const tracer::OfdmGrid* grid);

// Writes the dataset through a temporary sibling; header.cfr_* must match `grid`.
void write_trace_dataset(const std::string& path, const generators::DatasetHeader& header,
                         const tracer::Snapshot& snap, const SnapshotNodes& in, const tracer::OfdmGrid* grid);

}  // namespace raysweep::pipeline
