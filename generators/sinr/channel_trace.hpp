// A channel dataset (schemas/raysweep_dataset.schema.json) loaded for the SINR
// generator: the frames, the node states of each frame and, per link, the
// wideband gain and LoS class. Paths, interactions and CFRs are not loaded.
// Memory is about 16 bytes per link row plus 40 per node state.
#pragma once

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "generators/dataset/dataset.hpp"

namespace raysweep::generators::sinr {

class ChannelTrace {
 public:
  struct Link {
    std::uint32_t tx = 0, rx = 0;  // tx < rx
    float gain_db = 0;             // gain_incoherent_db: wideband power gain; -inf without paths
    std::uint8_t los_class = 0;
    std::uint8_t flags = 0;        // LinkFlags
  };

  // Reads the file. Throws meshkit::InputError naming the file and the dataset or
  // attribute when the file is not a complete raysweep-channels dataset of a
  // supported major version, or is unreadable.
  static ChannelTrace load(const std::string& path);

  // An in-memory trace (tests): frames in time order, each frame's states sorted by
  // node, its links sorted by (tx, rx) between nodes present in the frame.
  static ChannelTrace from_records(std::vector<NodeInfo> nodes, const std::vector<FrameRecord>& frames,
                                   double carrier_hz, double bandwidth_hz);

  const std::string& path() const { return path_; }  // "" for from_records
  const std::vector<NodeInfo>& nodes() const { return nodes_; }
  double carrier_hz() const { return carrier_hz_; }
  double bandwidth_hz() const { return bandwidth_hz_; }
  std::uint64_t seed() const { return seed_; }

  std::size_t frames() const { return time_.size(); }
  double time(std::size_t frame) const { return time_[frame]; }
  // Frame time step (median spacing of the frame times; 0.1 when fewer than two frames).
  double frame_step() const { return step_; }
  // The frame in force at time t: the last frame with time <= t (0 when t precedes
  // every frame). Requires frames() > 0.
  std::size_t frame_at(double t) const;

  // States of the nodes present in a frame, sorted by node.
  const NodeState* states_begin(std::size_t frame) const;
  const NodeState* states_end(std::size_t frame) const;
  // A node's state in a frame; nullptr when the node is absent from it.
  const NodeState* state(std::size_t frame, std::uint32_t node) const;

  // The link between a and b (either order) in a frame; nullptr when not stored.
  const Link* link(std::size_t frame, std::uint32_t a, std::uint32_t b) const;
  // A frame's links, sorted by (tx, rx); the first one is row link_row(frame) of the file's /links.
  const Link* links_begin(std::size_t frame) const { return links_.data() + link_offset_[frame]; }
  const Link* links_end(std::size_t frame) const { return links_.data() + link_offset_[frame + 1]; }
  std::uint64_t link_row(std::size_t frame) const { return link_offset_[frame]; }

 private:
  std::string path_;
  std::vector<NodeInfo> nodes_;
  double carrier_hz_ = 0, bandwidth_hz_ = 0, step_ = 0.1;
  std::uint64_t seed_ = 0;
  std::vector<double> time_;
  std::vector<std::uint64_t> state_offset_;  // frames + 1 entries
  std::vector<NodeState> states_;
  std::vector<std::uint64_t> link_offset_;   // frames + 1 entries
  std::vector<Link> links_;
  void finalize();  // computes step_, checks ordering
};

}  // namespace raysweep::generators::sinr
