#include "pipeline/trace_h5.hpp"

#include "generators/sweep/frame_record.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/version.hpp"

namespace raysweep::pipeline {

namespace {

using generators::NodeInfo;
using generators::NodeKind;

std::vector<NodeInfo> node_infos(const SnapshotNodes& in) {
  std::vector<NodeInfo> out;
  for (std::size_t k = 0; k < in.poses->size(); ++k) {
    const auto& p = (*in.poses)[k];
    const auto& d = in.dims[k];
    out.push_back({p.id, NodeKind::vehicle, p.vclass, "", static_cast<float>(d.length), static_cast<float>(d.width),
                   static_cast<float>(d.height)});
  }
  for (const auto& r : *in.antennas) out.push_back({r.id, NodeKind::rsu, "", "", 0, 0, 0});
  return out;
}

// Vehicles at their SUMO pose (front-bumper centre), antennas where they are.
std::vector<generators::NodeState> node_states(const SnapshotNodes& in) {
  std::vector<generators::NodeState> out;
  const auto& nodes = *in.nodes;
  for (std::uint32_t i = 0; i < nodes.size(); ++i) {
    generators::NodeState s;
    s.node = i;
    const auto& v = nodes[i].velocity;
    s.vx = static_cast<float>(v[0]);
    s.vy = static_cast<float>(v[1]);
    s.vz = static_cast<float>(v[2]);
    if (i < in.poses->size()) {
      const auto& p = (*in.poses)[i];
      s.x = p.x, s.y = p.y, s.z = p.z;
      s.heading_deg = static_cast<float>(p.heading_deg);
    } else {
      const auto& r = (*in.antennas)[i - in.poses->size()];
      s.x = r.x, s.y = r.y, s.z = r.z;
    }
    out.push_back(s);
  }
  return out;
}

generators::FrameRecord frame_record(const tracer::Snapshot& snap, const SnapshotNodes& in,
                                     const tracer::OfdmGrid* grid) {
  generators::FrameRecord f;
  f.nodes = node_states(in);
  // Vehicle slot k is node k, so a scene object is its dataset object (static
  // objects first, then one per node, as the sweep numbers them).
  for (const auto& p : snap.pairs) {
    f.links.push_back(generators::link_record(p, p.tx, p.rx));
    if (!in.enclosed.empty() && (in.enclosed[p.tx] || in.enclosed[p.rx]))
      f.links.back().flags |= generators::kLinkEnclosed;
    for (const auto& path : p.paths) {
      f.paths.push_back(generators::path_record(path));
      for (const auto& i : path.interactions) f.interactions.push_back(generators::interaction_record(i, i.object));
    }
    if (grid) {
      const auto h = generators::cfr_record(p.paths, *grid);
      f.cfr.insert(f.cfr.end(), h.begin(), h.end());
    }
  }
  return f;
}

}  // namespace

generators::DatasetHeader channel_dataset_header(const nlohmann::json& config, const nlohmann::json& provenance,
                                                 const tracer::RadioConfig& radio, const tracer::OfdmGrid* grid) {
  generators::DatasetHeader header;
  header.raysweep_version = kVersion;
  header.git_hash = kGitHash;
  header.config = config;
  header.inputs = provenance["inputs"];
  header.provenance = provenance;
  header.carrier_hz = radio.frequency_hz;
  header.bandwidth_hz = radio.bandwidth_hz;
  if (grid) {
    header.cfr_subcarriers = static_cast<std::uint32_t>(grid->n_subcarriers);
    header.cfr_subcarrier_spacing_hz = grid->subcarrier_spacing_hz;
  }
  return header;
}

void write_trace_dataset(const std::string& path, const generators::DatasetHeader& header,
                         const tracer::Snapshot& snap, const SnapshotNodes& in, const tracer::OfdmGrid* grid) {
  std::vector<std::string> objects = in.static_objects;
  for (const auto& n : *in.nodes) objects.push_back(n.id);
  StagedFile staged(path, path + ".tmp.h5");
  {
    const generators::FrameRecord frame = frame_record(snap, in, grid);
    generators::DatasetHeader sized = header;
    sized.expected_rows = {{"F", 1},
                           {"S", frame.nodes.size()},
                           {"L", frame.links.size()},
                           {"P", frame.paths.size()},
                           {"I", frame.interactions.size()}};
    generators::DatasetWriter writer(staged.path(), sized);
    writer.append(frame);
    writer.finish(node_infos(in), objects);
  }
  staged.commit();
}

}  // namespace raysweep::pipeline
