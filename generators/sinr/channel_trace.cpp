// Loads the part of a channel dataset the SINR generator needs. Columns are read
// in blocks straight into the final arrays, so the peak memory is the loaded
// trace plus one block per column.
#include "generators/sinr/channel_trace.hpp"

#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "generators/dataset_writer.hpp"
#include "generators/hdf5_util.hpp"
#include "generators/ns3_table.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators::sinr {

namespace {

using hdf5::Handle;

constexpr hsize_t kBlockRows = hsize_t{1} << 20;

// Raised by finalize(): from_records() callers see an invalid_argument, load()
// turns it into an InputError naming `element`.
struct OrderError : std::invalid_argument {
  OrderError(std::string el, const std::string& what) : std::invalid_argument(what), element(std::move(el)) {}
  std::string element;
};

class Reader {
 public:
  explicit Reader(std::string path) : path_(std::move(path)) {}

  [[noreturn]] void fail(const std::string& element, const std::string& what) const {
    const std::string h5 = hdf5::hdf5_error_text();
    throw meshkit::InputError(path_, element, what + (h5.empty() ? "" : " (" + h5 + ")"));
  }

  void open() {
    if (H5Fis_hdf5(path_.c_str()) <= 0) fail("", "not an HDF5 file (or unreadable)");
    fid_ = Handle(H5Fopen(path_.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    if (!fid_.valid()) fail("", "cannot open as HDF5 (truncated or corrupt?)");
  }

  bool has_attr(const char* name) const {
    const htri_t r = H5Aexists(fid_.get(), name);
    H5Eclear2(H5E_DEFAULT);
    return r > 0;
  }

  std::string str_attr(const char* name) const {
    const std::string el = std::string("attribute ") + name;
    if (!has_attr(name)) fail(el, "missing");
    Handle a(H5Aopen(fid_.get(), name, H5P_DEFAULT), H5Aclose);
    Handle t(a.valid() ? H5Aget_type(a.get()) : H5I_INVALID_HID, H5Tclose);
    if (!t.valid() || H5Tget_class(t.get()) != H5T_STRING) fail(el, "not a string");
    // One string: H5Aread writes every element of an array attribute.
    Handle sp(H5Aget_space(a.get()), H5Sclose);
    if (!sp.valid() || H5Sget_simple_extent_npoints(sp.get()) != 1) fail(el, "not a single value");
    if (H5Tis_variable_str(t.get()) > 0) {
      char* p = nullptr;
      if (H5Aread(a.get(), t.get(), &p) < 0) fail(el, "cannot read");
      std::string s = p ? p : "";
      if (p) H5free_memory(p);
      return s;
    }
    std::string s(H5Tget_size(t.get()), '\0');
    if (H5Aread(a.get(), t.get(), s.data()) < 0) fail(el, "cannot read");
    return s.substr(0, s.find('\0'));
  }

  template <class T>
  T num_attr(const char* name, hid_t mtype) const {
    const std::string el = std::string("attribute ") + name;
    if (!has_attr(name)) fail(el, "missing");
    Handle a(H5Aopen(fid_.get(), name, H5P_DEFAULT), H5Aclose);
    Handle sp(a.valid() ? H5Aget_space(a.get()) : H5I_INVALID_HID, H5Sclose);
    if (!sp.valid() || H5Sget_simple_extent_npoints(sp.get()) != 1) fail(el, "not a single value");
    T v{};
    if (H5Aread(a.get(), mtype, &v) < 0) fail(el, "cannot read as a number");
    return v;
  }

  Handle dataset(const std::string& p) const {
    // H5Lexists fails rather than answers when an intermediate group is missing.
    for (std::size_t slash = p.find('/', 1);; slash = p.find('/', slash + 1)) {
      const htri_t r = H5Lexists(fid_.get(), p.substr(0, slash).c_str(), H5P_DEFAULT);
      H5Eclear2(H5E_DEFAULT);
      if (r <= 0) fail(p, "missing dataset");
      if (slash == std::string::npos) break;
    }
    Handle d(H5Dopen2(fid_.get(), p.c_str(), H5P_DEFAULT), H5Dclose);
    if (!d.valid()) fail(p, "cannot open dataset");
    return d;
  }

  hsize_t rows(const std::string& p) const {
    Handle d = dataset(p);
    Handle sp(H5Dget_space(d.get()), H5Sclose);
    hsize_t dims[H5S_MAX_RANK] = {};
    if (!sp.valid() || H5Sget_simple_extent_ndims(sp.get()) < 1 || H5Sget_simple_extent_dims(sp.get(), dims, nullptr) < 0)
      fail(p, "not an array");
    return dims[0];
  }

  // Calls fn(first_row, block) for consecutive blocks of a [rows] (width 1) or
  // [rows, width] dataset converted to mtype. T = char* reads variable-length strings.
  template <class T, class Fn>
  void scan(const std::string& p, hid_t mtype, hsize_t rows, hsize_t width, Fn&& fn) const {
    Handle d = dataset(p);
    Handle fs(H5Dget_space(d.get()), H5Sclose);
    const int rank = width == 1 ? 1 : 2;
    hsize_t dims[2] = {0, 0};
    if (!fs.valid() || H5Sget_simple_extent_ndims(fs.get()) != rank || H5Sget_simple_extent_dims(fs.get(), dims, nullptr) < 0 ||
        dims[0] != rows || (rank == 2 && dims[1] != width))
      fail(p, "shape is not [" + std::to_string(rows) + (rank == 2 ? ", " + std::to_string(width) : "") +
                  "] (inconsistent lengths)");
    std::vector<T> buf;
    for (hsize_t start = 0; start < rows; start += kBlockRows) {
      const hsize_t n = std::min(kBlockRows, rows - start);
      buf.assign(static_cast<std::size_t>(n * width), T{});
      const hsize_t s[2] = {start, 0}, c[2] = {n, width};
      Handle ms(H5Screate_simple(rank, c, nullptr), H5Sclose);
      if (!ms.valid() || H5Sselect_hyperslab(fs.get(), H5S_SELECT_SET, s, nullptr, c, nullptr) < 0 ||
          H5Dread(d.get(), mtype, ms.get(), fs.get(), H5P_DEFAULT, buf.data()) < 0)
        fail(p, "cannot read rows " + std::to_string(start) + ".." + std::to_string(start + n - 1));
      fn(static_cast<std::size_t>(start), buf);
      if constexpr (std::is_same_v<T, char*>) H5Dvlen_reclaim(mtype, ms.get(), H5P_DEFAULT, buf.data());
    }
  }

 private:
  std::string path_;
  Handle fid_;
};

}  // namespace

ChannelTrace ChannelTrace::load(const std::string& path) {
  hdf5::QuietHdf5 quiet;
  Reader r(path);
  r.open();
  if (const std::string f = r.str_attr("format"); f != kDatasetFormat)
    r.fail("attribute format", "is \"" + f + "\": not a " + kDatasetFormat + " dataset");
  const std::string version = r.str_attr("schema_version");
  int major = -1, supported = -1;
  std::sscanf(kDatasetSchemaVersion, "%d", &supported);
  if (std::sscanf(version.c_str(), "%d.", &major) != 1 || major != supported)
    r.fail("attribute schema_version", "version \"" + version + "\" is not supported (this program reads " +
                                           std::to_string(supported) + ".x)");
  if (!r.has_attr("complete") || r.num_attr<std::uint64_t>("complete", H5T_NATIVE_UINT64) != 1)
    r.fail("attribute complete", "incomplete file: its writer stopped before finishing it");

  ChannelTrace t;
  t.path_ = path;
  t.carrier_hz_ = r.num_attr<double>("carrier_hz", H5T_NATIVE_DOUBLE);
  t.bandwidth_hz_ = r.num_attr<double>("bandwidth_hz", H5T_NATIVE_DOUBLE);
  // Noise power and the ns-3 table's header come from these: a bad value must
  // be named here, not where a later computation or writer trips on it
  // (tests/fuzz/fuzz_dataset_h5).
  for (const auto& [name, v] : {std::pair{"carrier_hz", t.carrier_hz_}, std::pair{"bandwidth_hz", t.bandwidth_hz_}})
    if (!(std::isfinite(v) && v > 0)) r.fail(std::string("attribute ") + name, "is not a positive number");
  t.seed_ = r.num_attr<std::uint64_t>("seed", H5T_NATIVE_UINT64);

  const hsize_t frames = r.rows("/frames/time_s");
  t.time_.reserve(frames);
  r.scan<double>("/frames/time_s", H5T_NATIVE_DOUBLE, frames, 1,
                 [&](std::size_t, const auto& b) { t.time_.insert(t.time_.end(), b.begin(), b.end()); });
  // offsets[f] must be the running sum of the counts; the sum closes the table.
  auto read_csr = [&](const std::string& offset, const std::string& count, std::vector<std::uint64_t>& out) {
    out.reserve(frames + 1);
    r.scan<std::uint64_t>(offset, H5T_NATIVE_UINT64, frames, 1,
                          [&](std::size_t, const auto& b) { out.insert(out.end(), b.begin(), b.end()); });
    std::uint64_t sum = 0;
    r.scan<std::uint64_t>(count, H5T_NATIVE_UINT64, frames, 1, [&](std::size_t start, const auto& b) {
      for (std::size_t i = 0; i < b.size(); sum += b[i++])
        if (out[start + i] != sum)
          r.fail(offset, "row " + std::to_string(start + i) + " is " + std::to_string(out[start + i]) +
                             ", expected the running sum of " + count + " " + std::to_string(sum));
    });
    out.push_back(sum);
  };
  read_csr("/frames/node_offset", "/frames/node_count", t.state_offset_);
  read_csr("/frames/link_offset", "/frames/link_count", t.link_offset_);

  const hsize_t states = r.rows("/node_states/node");
  if (states != t.state_offset_.back())
    r.fail("/node_states/node", std::to_string(states) + " rows but /frames/node_count sums to " +
                                    std::to_string(t.state_offset_.back()));
  t.states_.resize(states);
  r.scan<std::uint32_t>("/node_states/node", H5T_NATIVE_UINT32, states, 1, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size(); ++i) t.states_[s + i].node = b[i];
  });
  r.scan<double>("/node_states/position", H5T_NATIVE_DOUBLE, states, 3, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size() / 3; ++i) {
      NodeState& n = t.states_[s + i];
      n.x = b[3 * i], n.y = b[3 * i + 1], n.z = b[3 * i + 2];
    }
  });
  r.scan<float>("/node_states/velocity", H5T_NATIVE_FLOAT, states, 3, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size() / 3; ++i) {
      NodeState& n = t.states_[s + i];
      n.vx = b[3 * i], n.vy = b[3 * i + 1], n.vz = b[3 * i + 2];
    }
  });
  r.scan<float>("/node_states/heading_deg", H5T_NATIVE_FLOAT, states, 1, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size(); ++i) t.states_[s + i].heading_deg = b[i];
  });

  const hsize_t nodes = r.rows("/nodes/id");
  t.nodes_.resize(nodes);
  Handle str(H5Tcopy(H5T_C_S1), H5Tclose);
  if (!str.valid() || H5Tset_size(str.get(), H5T_VARIABLE) < 0 || H5Tset_cset(str.get(), H5T_CSET_UTF8) < 0)
    r.fail("/nodes", "cannot create the string type");
  for (auto [p, field] : {std::pair{"/nodes/id", &NodeInfo::id}, std::pair{"/nodes/vclass", &NodeInfo::vclass},
                          std::pair{"/nodes/vtype", &NodeInfo::vtype}})
    r.scan<char*>(p, str.get(), nodes, 1, [&, field = field](std::size_t s, const auto& b) {
      for (std::size_t i = 0; i < b.size(); ++i) t.nodes_[s + i].*field = b[i] ? b[i] : "";
    });
  r.scan<std::uint8_t>("/nodes/kind", H5T_NATIVE_UINT8, nodes, 1, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size(); ++i) {
      if (b[i] > 1) r.fail("/nodes/kind", "row " + std::to_string(s + i) + ": unknown node kind " + std::to_string(b[i]));
      t.nodes_[s + i].kind = static_cast<NodeKind>(b[i]);
    }
  });
  r.scan<float>("/nodes/dimensions", H5T_NATIVE_FLOAT, nodes, 3, [&](std::size_t s, const auto& b) {
    for (std::size_t i = 0; i < b.size() / 3; ++i) {
      NodeInfo& n = t.nodes_[s + i];
      n.length_m = b[3 * i], n.width_m = b[3 * i + 1], n.height_m = b[3 * i + 2];
    }
  });

  const hsize_t links = r.rows("/links/tx");
  if (links != t.link_offset_.back())
    r.fail("/links/tx", std::to_string(links) + " rows but /frames/link_count sums to " +
                            std::to_string(t.link_offset_.back()));
  t.links_.resize(links);
  auto link_column = [&](const char* p, hid_t mtype, auto member) {
    using T = std::remove_reference_t<decltype(Link{}.*member)>;
    r.scan<T>(p, mtype, links, 1, [&](std::size_t s, const auto& b) {
      for (std::size_t i = 0; i < b.size(); ++i) t.links_[s + i].*member = b[i];
    });
  };
  link_column("/links/tx", H5T_NATIVE_UINT32, &Link::tx);
  link_column("/links/rx", H5T_NATIVE_UINT32, &Link::rx);
  link_column("/links/gain_incoherent_db", H5T_NATIVE_FLOAT, &Link::gain_db);
  link_column("/links/los_class", H5T_NATIVE_UINT8, &Link::los_class);
  link_column("/links/flags", H5T_NATIVE_UINT8, &Link::flags);
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
