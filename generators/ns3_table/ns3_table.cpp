// The ns-3 lookup table (raysweep-ns3-table): streaming writer and in-memory
// reader. Datasets, file types, shapes, chunk shapes, units and descriptions come
// from the embedded schema (schemas/raysweep_ns3_table.schema.json) through the
// shared column machinery (generators/hdf5/column_file.hpp).
#include "generators/ns3_table/ns3_table.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "generators/dataset/frame_step.hpp"
#include "generators/hdf5/checked_file.hpp"
#include "generators/hdf5/column_file.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators {

using hdf5::Column;
using hdf5::ColumnFile;
using hdf5::Dtype;
using hdf5::Handle;
using hdf5::QuietHdf5;

const char* gain_source_name(GainSource s) { return s == GainSource::cfr ? "cfr" : "incoherent"; }

// ---------------------------------------------------------------------------
// Writer.

struct Ns3TableWriter::Impl {
  std::string file;
  Ns3TableHeader header;
  Ns3TableBands bands;
  ColumnFile out;
  bool finished = false;
  Column *f_time, *f_state_offset, *f_state_count, *f_pair_offset, *f_pair_count;
  Column *s_node, *s_position, *s_velocity;
  Column *p_a, *p_b, *p_gain, *p_los;
  Column* band_gain = nullptr;
  std::vector<double> times;
  std::uint64_t states = 0, pair_rows = 0;
  std::int64_t max_node = -1;

  Impl(const std::filesystem::path& path, const Ns3TableHeader& h, const Ns3TableBands& b)
      : file(path.string()), header(h), bands(b), out(file, ns3_table_schema(), {{"B", b.count()}}) {}

  void create() {
    const auto bad = [&](const std::string& what) { throw std::invalid_argument(file + ": ns-3 table header: " + what); };
    if (!(std::isfinite(header.carrier_hz) && header.carrier_hz > 0)) bad("carrier_hz is not a positive number");
    if (!(std::isfinite(header.bandwidth_hz) && header.bandwidth_hz > 0)) bad("bandwidth_hz is not a positive number");
    for (std::size_t i = 1; i < bands.count(); ++i)
      if (!(bands.center_hz[i] > bands.center_hz[i - 1])) bad("band centres are not increasing");
    out.create();
    out.identity_attrs(kNs3TableFormat, kNs3TableSchemaVersion, header.raysweep_version, header.git_hash, header.config,
                       header.inputs, header.provenance, header.seed);
    out.attr("", "carrier_hz", header.carrier_hz);
    out.attr("", "bandwidth_hz", header.bandwidth_hz);
    out.attr("", "gain_source", static_cast<std::uint8_t>(header.gain_source));
    f_time = out.column("frames", "time_s", Dtype::f64);
    f_state_offset = out.column("frames", "state_offset", Dtype::u64);
    f_state_count = out.column("frames", "state_count", Dtype::u64);
    f_pair_offset = out.column("frames", "pair_offset", Dtype::u64);
    f_pair_count = out.column("frames", "pair_count", Dtype::u64);
    s_node = out.column("node_states", "node", Dtype::u32);
    s_position = out.column("node_states", "position", Dtype::f64);
    s_velocity = out.column("node_states", "velocity", Dtype::f32);
    p_a = out.column("pairs", "a", Dtype::u32);
    p_b = out.column("pairs", "b", Dtype::u32);
    p_gain = out.column("pairs", "gain_db", Dtype::f32);
    p_los = out.column("pairs", "los_class", Dtype::u8);
    if (bands.count()) {
      out.attr("spectrum", "band_count", static_cast<std::uint32_t>(bands.count()));
      out.attr("spectrum", "subcarriers_per_band", bands.subcarriers_per_band);
      out.attr("spectrum", "band_width_hz", bands.band_width_hz);
      out.table("spectrum", "center_hz", Dtype::f64, bands.count(), bands.center_hz.data());
      band_gain = out.column("spectrum", "gain_db", Dtype::f32);
    }
  }

  void add_frame(double t, const std::vector<NodeState>& st, const std::vector<Ns3Pair>& pairs,
                 const std::vector<float>& band_gains) {
    if (finished) throw std::runtime_error(file + ": add_frame() after finish()");
    const std::string where = file + ": frame " + std::to_string(times.size()) + ": ";
    const auto bad = [&](const std::string& what) { throw std::invalid_argument(where + what); };
    if (!std::isfinite(t) || (!times.empty() && t <= times.back())) bad("time " + std::to_string(t) + " s is not after the previous frame's");
    for (std::size_t i = 1; i < st.size(); ++i)
      if (st[i].node <= st[i - 1].node) bad("node states are not strictly sorted by node");
    const auto present = [&](std::uint32_t n) {
      return std::binary_search(st.begin(), st.end(), n, [](const auto& x, const auto& y) {
        if constexpr (std::is_same_v<std::decay_t<decltype(x)>, NodeState>) return x.node < y;
        else return x < y.node;
      });
    };
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      const Ns3Pair& p = pairs[i];
      const std::string name = "pair (" + std::to_string(p.a) + ", " + std::to_string(p.b) + ")";
      if (p.a >= p.b) bad(name + " does not have a < b");
      if (i > 0 && std::pair(p.a, p.b) <= std::pair(pairs[i - 1].a, pairs[i - 1].b)) bad("pairs are not strictly sorted at " + name);
      if (!present(p.a) || !present(p.b)) bad(name + " names a node absent from the frame's states");
      if (p.los_class > 2) bad(name + ": LoS class " + std::to_string(p.los_class) + " is not 0, 1 or 2");
      if (std::isnan(p.gain_db) || p.gain_db == std::numeric_limits<float>::infinity()) bad(name + ": gain is NaN or +inf");
    }
    if (band_gains.size() != pairs.size() * bands.count())
      bad(std::to_string(band_gains.size()) + " band gains for " + std::to_string(pairs.size()) + " pairs x " +
          std::to_string(bands.count()) + " bands");
    times.push_back(t);
    f_time->put(t);
    f_state_offset->put(states);
    f_state_count->put(std::uint64_t{st.size()});
    f_pair_offset->put(pair_rows);
    f_pair_count->put(std::uint64_t{pairs.size()});
    for (const NodeState& s : st) {
      s_node->put(s.node);
      for (double v : {s.x, s.y, s.z}) s_position->put(v);
      for (float v : {s.vx, s.vy, s.vz}) s_velocity->put(v);
      max_node = std::max<std::int64_t>(max_node, s.node);
    }
    for (const Ns3Pair& p : pairs) {
      p_a->put(p.a);
      p_b->put(p.b);
      p_gain->put(p.gain_db);
      p_los->put(p.los_class);
    }
    for (float g : band_gains) band_gain->put(g);
    states += st.size();
    pair_rows += pairs.size();
    out.maybe_flush();
  }

  void finish(const std::vector<NodeInfo>& nodes) {
    if (finished) throw std::runtime_error(file + ": finish() called twice");
    const std::uint64_t n = nodes.size();
    if (max_node >= static_cast<std::int64_t>(n))
      throw std::invalid_argument(file + ": records name node " + std::to_string(max_node) + " but the node table has " +
                                  std::to_string(n) + " nodes");
    out.flush_all();
    std::vector<const char*> ids;
    std::vector<std::uint8_t> kinds;
    for (const auto& node : nodes) {
      ids.push_back(node.id.c_str());
      kinds.push_back(static_cast<std::uint8_t>(node.kind));
    }
    out.table("nodes", "id", Dtype::str, n, ids.data());
    out.table("nodes", "kind", Dtype::u8, n, kinds.data());
    out.attr("", "time_start_s", times.empty() ? 0.0 : times.front());
    out.attr("", "time_end_s", times.empty() ? 0.0 : times.back());
    out.attr("", "frame_step_s", median_step(times));
    out.attr("", "node_count", n);
    out.attr("", "frame_count", std::uint64_t{times.size()});
    out.attr("", "pair_count", pair_rows);
    out.close_all(true);
    finished = true;
  }
};

Ns3TableWriter::Ns3TableWriter(const std::filesystem::path& path, const Ns3TableHeader& header,
                               const Ns3TableBands& bands) {
  QuietHdf5 quiet;
  impl_ = std::make_unique<Impl>(path, header, bands);
  impl_->create();
}

Ns3TableWriter::~Ns3TableWriter() {
  if (impl_ && !impl_->finished) impl_->out.abandon();
}

void Ns3TableWriter::add_frame(double time_s, const std::vector<NodeState>& states, const std::vector<Ns3Pair>& pairs,
                               const std::vector<float>& band_gain_db) {
  QuietHdf5 quiet;
  impl_->add_frame(time_s, states, pairs, band_gain_db);
}

void Ns3TableWriter::finish(const std::vector<NodeInfo>& nodes) {
  QuietHdf5 quiet;
  impl_->finish(nodes);
}

std::uint64_t Ns3TableWriter::frames() const { return impl_->times.size(); }
std::uint64_t Ns3TableWriter::pairs() const { return impl_->pair_rows; }

// ---------------------------------------------------------------------------
// Reader.

Ns3Table Ns3Table::load(const std::string& path) {
  QuietHdf5 quiet;
  hdf5::CheckedFile r(path);
  r.open();
  if (const std::string f = r.attr<std::string>("/", "format"); f != kNs3TableFormat)
    r.fail("attribute format", "is \"" + f + "\": not a " + kNs3TableFormat + " file");
  const std::string version = r.attr<std::string>("/", "schema_version");
  const auto major = hdf5::major_version(version);
  if (!major || major != hdf5::major_version(kNs3TableSchemaVersion))
    r.fail("attribute schema_version", "version \"" + version + "\" is not supported (this program reads " +
                                           kNs3TableSchemaVersion + ")");
  if (r.attr_if<std::uint64_t>("/", "complete") != std::uint64_t{1})
    r.fail("attribute complete", "incomplete file: its writer stopped before finishing it");

  Ns3Table t;
  t.path_ = path;
  t.carrier_hz_ = r.attr<double>("/", "carrier_hz");
  t.bandwidth_hz_ = r.attr<double>("/", "bandwidth_hz");
  const auto source = r.attr<std::uint64_t>("/", "gain_source");
  if (source > 1) r.fail("attribute gain_source", "unknown code " + std::to_string(source));
  t.gain_source_ = static_cast<GainSource>(source);
  t.provenance_ = nlohmann::json::parse(r.attr<std::string>("/", "provenance"), nullptr, false);

  t.ids_ = r.dataset("/nodes/id").strings();
  const std::uint64_t n = t.ids_.size();
  if (n > 65535) r.fail("/nodes/id", std::to_string(n) + " nodes: more than the 65535 this reader supports");
  for (auto k : r.dataset("/nodes/kind").read_all<std::uint8_t>(n)) {
    if (k > 1) r.fail("/nodes/kind", "unknown node kind " + std::to_string(k));
    t.kinds_.push_back(static_cast<NodeKind>(k));
  }

  const hdf5::Dataset time = r.dataset("/frames/time_s");
  const hsize_t frames = time.rows();
  t.time_ = time.read_all<double>(frames);
  for (std::size_t f = 0; f < frames; ++f)
    if (!std::isfinite(t.time_[f]) || (f > 0 && t.time_[f] <= t.time_[f - 1]))
      r.fail("/frames/time_s", "row " + std::to_string(f) + ": not finite or not after the previous frame's time");
  t.step_ = median_step(t.time_);
  // offsets[f] must be the running sum of the counts; the sum closes the table.
  auto csr = [&](const std::string& offset, const std::string& count, std::vector<std::uint64_t>& out) {
    out = r.dataset(offset).read_all<std::uint64_t>(frames);
    const auto counts = r.dataset(count).read_all<std::uint64_t>(frames);
    std::uint64_t sum = 0;
    for (std::size_t f = 0; f < frames; sum += counts[f++])
      if (out[f] != sum)
        r.fail(offset, "row " + std::to_string(f) + " is " + std::to_string(out[f]) + ", expected the running sum of " +
                           count + " " + std::to_string(sum));
    out.push_back(sum);
  };
  csr("/frames/state_offset", "/frames/state_count", t.state_offset_);
  csr("/frames/pair_offset", "/frames/pair_count", t.pair_offset_);

  const std::uint64_t s = t.state_offset_.back();
  const auto node = r.dataset("/node_states/node").read_all<std::uint32_t>(s);
  const auto pos = r.dataset("/node_states/position").read_all<double>(s, 3);
  const auto vel = r.dataset("/node_states/velocity").read_all<float>(s, 3);
  t.states_.resize(s);
  for (std::size_t i = 0; i < s; ++i) {
    NodeState& st = t.states_[i];
    st.node = node[i];
    st.x = pos[3 * i], st.y = pos[3 * i + 1], st.z = pos[3 * i + 2];
    st.vx = vel[3 * i], st.vy = vel[3 * i + 1], st.vz = vel[3 * i + 2];
  }
  for (std::size_t f = 0; f < frames; ++f)
    for (std::uint64_t i = t.state_offset_[f]; i < t.state_offset_[f + 1]; ++i) {
      if (t.states_[i].node >= n)
        r.fail("/node_states/node", "row " + std::to_string(i) + ": node " + std::to_string(t.states_[i].node) +
                                        " is not below the node count " + std::to_string(n));
      if (i > t.state_offset_[f] && t.states_[i].node <= t.states_[i - 1].node)
        r.fail("/node_states/node", "row " + std::to_string(i) + ": frame " + std::to_string(f) +
                                        "'s node states are not strictly sorted by node");
    }

  const std::uint64_t p = t.pair_offset_.back();
  const auto a = r.dataset("/pairs/a").read_all<std::uint32_t>(p);
  const auto b = r.dataset("/pairs/b").read_all<std::uint32_t>(p);
  t.gain_ = r.dataset("/pairs/gain_db").read_all<float>(p);
  t.los_ = r.dataset("/pairs/los_class").read_all<std::uint8_t>(p);
  t.key_.resize(p);
  for (std::size_t f = 0; f < frames; ++f)
    for (std::uint64_t i = t.pair_offset_[f]; i < t.pair_offset_[f + 1]; ++i) {
      const std::string row = "row " + std::to_string(i) + " (frame " + std::to_string(f) + "): ";
      if (a[i] >= b[i] || b[i] >= n)
        r.fail("/pairs/a", row + "pair (" + std::to_string(a[i]) + ", " + std::to_string(b[i]) +
                               ") is not a < b < node count " + std::to_string(n));
      t.key_[i] = static_cast<std::uint32_t>(a[i] * n + b[i]);
      if (i > t.pair_offset_[f] && t.key_[i] <= t.key_[i - 1])
        r.fail("/pairs/a", row + "pairs are not strictly sorted by (a, b) within the frame");
      if (t.los_[i] > 2) r.fail("/pairs/los_class", row + "unknown LoS class " + std::to_string(t.los_[i]));
      if (std::isnan(t.gain_[i])) r.fail("/pairs/gain_db", row + "NaN");
    }

  if (r.exists("/spectrum")) {
    r.group("/spectrum");
    const auto count = r.attr<std::uint64_t>("/spectrum", "band_count");
    t.bands_.subcarriers_per_band = static_cast<std::uint32_t>(r.attr<std::uint64_t>("/spectrum", "subcarriers_per_band"));
    t.bands_.band_width_hz = r.attr<double>("/spectrum", "band_width_hz");
    t.bands_.center_hz = r.dataset("/spectrum/center_hz").read_all<double>(count);
    if (count) t.band_gain_ = r.dataset("/spectrum/gain_db").read_all<float>(p, count);
  }
  return t;
}

std::optional<std::size_t> Ns3Table::frame_at(double t) const {
  if (time_.empty() || !(t >= time_.front()) || t > time_.back() + step_) return std::nullopt;
  const auto it = std::upper_bound(time_.begin(), time_.end(), t);
  return static_cast<std::size_t>(it - time_.begin() - 1);
}

const NodeState* Ns3Table::state(std::size_t frame, std::uint32_t node) const {
  const NodeState* begin = states_.data() + state_offset_[frame];
  const NodeState* end = states_.data() + state_offset_[frame + 1];
  const NodeState* it = std::lower_bound(begin, end, node, [](const NodeState& s, std::uint32_t v) { return s.node < v; });
  return it != end && it->node == node ? it : nullptr;
}

std::optional<std::size_t> Ns3Table::pair_row(std::size_t frame, std::uint32_t a, std::uint32_t b) const {
  if (a > b) std::swap(a, b);
  if (a == b || b >= ids_.size()) return std::nullopt;
  const std::uint32_t key = static_cast<std::uint32_t>(a * ids_.size() + b);
  const auto begin = key_.begin() + static_cast<std::ptrdiff_t>(pair_offset_[frame]);
  const auto end = key_.begin() + static_cast<std::ptrdiff_t>(pair_offset_[frame + 1]);
  const auto it = std::lower_bound(begin, end, key);
  if (it == end || *it != key) return std::nullopt;
  return static_cast<std::size_t>(it - key_.begin());
}

std::size_t Ns3Table::memory_bytes() const {
  std::size_t bytes = 0;
  for (const auto& s : ids_) bytes += sizeof(std::string) + s.capacity();
  bytes += kinds_.capacity() + time_.capacity() * sizeof(double) +
           (state_offset_.capacity() + pair_offset_.capacity()) * sizeof(std::uint64_t) +
           states_.capacity() * sizeof(NodeState) + key_.capacity() * sizeof(std::uint32_t) +
           gain_.capacity() * sizeof(float) + los_.capacity() + band_gain_.capacity() * sizeof(float) +
           bands_.center_hz.capacity() * sizeof(double);
  return bytes;
}

}  // namespace raysweep::generators
