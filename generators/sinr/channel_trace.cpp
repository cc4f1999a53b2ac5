// Loads the part of a channel dataset the SINR generator needs. Columns are read
// in blocks straight into the final arrays, so the peak memory is the loaded
// trace plus one block per column.
#include "generators/sinr/channel_trace.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "generators/dataset/dataset_writer.hpp"
#include "generators/dataset/frame_step.hpp"
#include "generators/hdf5/checked_file.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators::sinr {

namespace {

// Raised by finalize(): from_records() callers see an invalid_argument, load()
// turns it into an InputError naming `element`.
struct OrderError : std::invalid_argument {
  OrderError(std::string el, const std::string& what) : std::invalid_argument(what), element(std::move(el)) {}
  std::string element;
};

}  // namespace

ChannelTrace ChannelTrace::load(const std::string& path) {
  hdf5::QuietHdf5 quiet;
  hdf5::CheckedFile r(path);
  r.open();
  if (const std::string f = r.attr<std::string>("/", "format"); f != kDatasetFormat)
    r.fail("attribute format", "is \"" + f + "\": not a " + kDatasetFormat + " dataset");
  const std::string version = r.attr<std::string>("/", "schema_version");
  int major = -1, supported = -1;
  std::sscanf(kDatasetSchemaVersion, "%d", &supported);
  if (std::sscanf(version.c_str(), "%d.", &major) != 1 || major != supported)
    r.fail("attribute schema_version", "version \"" + version + "\" is not supported (this program reads " +
                                           std::to_string(supported) + ".x)");
  if (r.attr_if<std::uint64_t>("/", "complete") != std::uint64_t{1})
    r.fail("attribute complete", "incomplete file: its writer stopped before finishing it");

  ChannelTrace t;
  t.path_ = path;
  t.carrier_hz_ = r.attr<double>("/", "carrier_hz");
  t.bandwidth_hz_ = r.attr<double>("/", "bandwidth_hz");
  // Noise power and the ns-3 table's header come from these: a bad value must
  // be named here, not where a later computation or writer trips on it
  // (tests/fuzz/fuzz_dataset_h5).
  for (const auto& [name, v] : {std::pair{"carrier_hz", t.carrier_hz_}, std::pair{"bandwidth_hz", t.bandwidth_hz_}})
    if (!(std::isfinite(v) && v > 0)) r.fail(std::string("attribute ") + name, "is not a positive number");
  t.seed_ = r.attr<std::uint64_t>("/", "seed");

  const hsize_t frames = r.dataset("/frames/time_s").rows();
  t.time_.reserve(frames);
  r.dataset("/frames/time_s").scan<double>(frames, 1,
                 [&](std::size_t, const auto& b) { t.time_.insert(t.time_.end(), b.begin(), b.end()); });
  // offsets[f] must be the running sum of the counts; the sum closes the table.
  auto read_csr = [&](const std::string& offset, const std::string& count, std::vector<std::uint64_t>& out) {
    out.reserve(frames + 1);
    r.dataset(offset).scan<std::uint64_t>(frames, 1,
                          [&](std::size_t, const auto& b) { out.insert(out.end(), b.begin(), b.end()); });
    std::uint64_t sum = 0;
    r.dataset(count).scan<std::uint64_t>(frames, 1, [&](std::size_t start, const auto& b) {
      for (std::size_t i = 0; i < b.size(); sum += b[i++])
        if (out[start + i] != sum)
          r.fail(offset, "row " + std::to_string(start + i) + " is " + std::to_string(out[start + i]) +
                             ", expected the running sum of " + count + " " + std::to_string(sum));
    });
    out.push_back(sum);
  };
  read_csr("/frames/node_offset", "/frames/node_count", t.state_offset_);
  read_csr("/frames/link_offset", "/frames/link_count", t.link_offset_);

  const hsize_t states = r.dataset("/node_states/node").rows();
  if (states != t.state_offset_.back())
    r.fail("/node_states/node", std::to_string(states) + " rows but /frames/node_count sums to " +
                                    std::to_string(t.state_offset_.back()));
  t.states_.resize(states);
  r.dataset("/node_states/node").scan<std::uint32_t>(states, 1, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size(); ++i) t.states_[s + i].node = b[i];
  });
  r.dataset("/node_states/position").scan<double>(states, 3, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size() / 3; ++i) {
      NodeState& n = t.states_[s + i];
      n.x = b[3 * i], n.y = b[3 * i + 1], n.z = b[3 * i + 2];
    }
  });
  r.dataset("/node_states/velocity").scan<float>(states, 3, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size() / 3; ++i) {
      NodeState& n = t.states_[s + i];
      n.vx = b[3 * i], n.vy = b[3 * i + 1], n.vz = b[3 * i + 2];
    }
  });
  r.dataset("/node_states/heading_deg").scan<float>(states, 1, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size(); ++i) t.states_[s + i].heading_deg = b[i];
  });

  const hsize_t nodes = r.dataset("/nodes/id").rows();
  t.nodes_.resize(nodes);
  for (auto [p, field] : {std::pair{"/nodes/id", &NodeInfo::id}, std::pair{"/nodes/vclass", &NodeInfo::vclass},
                          std::pair{"/nodes/vtype", &NodeInfo::vtype}})
    r.dataset(p).scan<char*>(nodes, 1, [&, field = field](std::size_t s, const auto& b) {
      for (std::size_t i = 0; i < b.size(); ++i) t.nodes_[s + i].*field = b[i] ? b[i] : "";
    });
  r.dataset("/nodes/kind").scan<std::uint8_t>(nodes, 1, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size(); ++i) {
      if (b[i] > 1) r.fail("/nodes/kind", "row " + std::to_string(s + i) + ": unknown node kind " + std::to_string(b[i]));
      t.nodes_[s + i].kind = static_cast<NodeKind>(b[i]);
    }
  });
  r.dataset("/nodes/dimensions").scan<float>(nodes, 3, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size() / 3; ++i) {
      NodeInfo& n = t.nodes_[s + i];
      n.length_m = b[3 * i], n.width_m = b[3 * i + 1], n.height_m = b[3 * i + 2];
    }
  });

  const hsize_t links = r.dataset("/links/tx").rows();
  if (links != t.link_offset_.back())
    r.fail("/links/tx", std::to_string(links) + " rows but /frames/link_count sums to " +
                            std::to_string(t.link_offset_.back()));
  t.links_.resize(links);
  auto link_column = [&](const char* p, auto member) {
    using T = std::remove_reference_t<decltype(Link{}.*member)>;
    r.dataset(p).scan<T>(links, 1, [&](std::size_t s, const auto& b) {
      for (std::size_t i = 0; i < b.size(); ++i) t.links_[s + i].*member = b[i];
    });
  };
  link_column("/links/tx", &Link::tx);
  link_column("/links/rx", &Link::rx);
  link_column("/links/gain_incoherent_db", &Link::gain_db);
  link_column("/links/los_class", &Link::los_class);
  link_column("/links/flags", &Link::flags);
  // The channel models and the ns-3 table take the LoS class as a code of three
  // (a 88 reached the table writer, whose error named its own output:
  // tests/fuzz/fuzz_dataset_h5).
  for (std::size_t i = 0; i < t.links_.size(); ++i)
    if (t.links_[i].los_class > 2)
      r.fail("/links/los_class",
             "row " + std::to_string(i) + ": unknown LoS class " + std::to_string(t.links_[i].los_class));

  try {
    t.finalize();
  } catch (const OrderError& e) {
    r.fail(e.element, e.what());
  }
  return t;
}

ChannelTrace ChannelTrace::from_records(std::vector<NodeInfo> nodes, const std::vector<FrameRecord>& frames,
                                        double carrier_hz, double bandwidth_hz) {
  ChannelTrace t;
  t.nodes_ = std::move(nodes);
  t.carrier_hz_ = carrier_hz;
  t.bandwidth_hz_ = bandwidth_hz;
  t.state_offset_.push_back(0);
  t.link_offset_.push_back(0);
  for (const FrameRecord& f : frames) {
    t.time_.push_back(f.time_s);
    t.states_.insert(t.states_.end(), f.nodes.begin(), f.nodes.end());
    for (const LinkRecord& l : f.links) t.links_.push_back({l.tx, l.rx, l.gain_incoherent_db, l.los_class, l.flags});
    t.state_offset_.push_back(t.states_.size());
    t.link_offset_.push_back(t.links_.size());
  }
  t.finalize();
  return t;
}

void ChannelTrace::finalize() {
  const std::size_t n_nodes = nodes_.size();
  for (std::size_t f = 0; f < time_.size(); ++f) {
    const std::string where = "frame " + std::to_string(f) + ": ";
    if (!std::isfinite(time_[f]) || (f > 0 && time_[f] < time_[f - 1]))
      throw OrderError("/frames/time_s", where + "time is not finite or before the previous frame's");
    for (std::uint64_t i = state_offset_[f]; i < state_offset_[f + 1]; ++i) {
      if (states_[i].node >= n_nodes)
        throw OrderError("/node_states/node", where + "node " + std::to_string(states_[i].node) + " is not below the node count " +
                                                  std::to_string(n_nodes));
      if (i > state_offset_[f] && states_[i].node <= states_[i - 1].node)
        throw OrderError("/node_states/node", where + "node states are not strictly sorted by node");
    }
    for (std::uint64_t i = link_offset_[f]; i < link_offset_[f + 1]; ++i) {
      const Link& l = links_[i];
      const std::string pair = "link (" + std::to_string(l.tx) + ", " + std::to_string(l.rx) + ")";
      if (l.tx >= l.rx) throw OrderError("/links", where + pair + " does not have tx < rx");
      if (i > link_offset_[f] && std::pair(l.tx, l.rx) <= std::pair(links_[i - 1].tx, links_[i - 1].rx))
        throw OrderError("/links", where + "links are not strictly sorted by (tx, rx) at " + pair);
      if (!state(f, l.tx) || !state(f, l.rx)) throw OrderError("/links", where + pair + " names a node absent from the frame");
    }
  }
  step_ = median_step(time_);
}

std::size_t ChannelTrace::frame_at(double t) const {
  const auto it = std::upper_bound(time_.begin(), time_.end(), t);
  return it == time_.begin() ? 0 : static_cast<std::size_t>(it - time_.begin() - 1);
}

const NodeState* ChannelTrace::states_begin(std::size_t frame) const { return states_.data() + state_offset_[frame]; }
const NodeState* ChannelTrace::states_end(std::size_t frame) const { return states_.data() + state_offset_[frame + 1]; }

const NodeState* ChannelTrace::state(std::size_t frame, std::uint32_t node) const {
  const NodeState* end = states_end(frame);
  const NodeState* it =
      std::lower_bound(states_begin(frame), end, node, [](const NodeState& s, std::uint32_t n) { return s.node < n; });
  return it != end && it->node == node ? it : nullptr;
}

const ChannelTrace::Link* ChannelTrace::link(std::size_t frame, std::uint32_t a, std::uint32_t b) const {
  if (a > b) std::swap(a, b);
  const Link* begin = links_.data() + link_offset_[frame];
  const Link* end = links_.data() + link_offset_[frame + 1];
  const Link* it = std::lower_bound(begin, end, std::pair(a, b),
                                    [](const Link& l, const std::pair<std::uint32_t, std::uint32_t>& k) {
                                      return std::pair(l.tx, l.rx) < k;
                                    });
  return it != end && it->tx == a && it->rx == b ? it : nullptr;
}

}  // namespace raysweep::generators::sinr
