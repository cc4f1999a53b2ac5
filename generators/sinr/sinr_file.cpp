// SINR outcome file (raysweep-sinr): streaming writer and schedule reader. The
// datasets, their file types, shapes, chunk shapes, units and descriptions come
// from the embedded schema (schemas/raysweep_sinr.schema.json) through the shared
// column machinery (generators/hdf5/column_file.hpp); this file knows which record
// field goes where and refuses records that would make an invalid file.
#include "generators/sinr/sinr_file.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "generators/hdf5/checked_file.hpp"
#include "generators/hdf5/column_file.hpp"
#include "meshkit/errors.hpp"

namespace raysweep::generators::sinr {

using hdf5::Column;
using hdf5::ColumnFile;
using hdf5::Dtype;
using hdf5::Handle;
using hdf5::QuietHdf5;

namespace {

constexpr std::uint8_t kMaxRat = static_cast<std::uint8_t>(Rat::nr_v2x);
constexpr std::uint8_t kMaxMessage = static_cast<std::uint8_t>(Message::cpm);
constexpr std::uint8_t kMaxNodeKind = static_cast<std::uint8_t>(NodeKind::rsu);

std::string num(double v) { return std::to_string(v); }

std::uint8_t flag(bool b) { return b ? 1 : 0; }

}  // namespace

// ---------------------------------------------------------------------------
// Writer.

struct SinrWriter::Impl {
  std::string file;  // for messages
  SinrHeader header;
  ColumnFile out;
  bool finished = false;

  Column *t_node, *t_rat, *t_message, *t_packet, *t_attempt, *t_size, *t_start, *t_duration, *t_band, *t_power;
  Column *r_transmission, *r_tx, *r_rx, *r_rat, *r_packet, *r_attempt, *r_time, *r_distance, *r_prx, *r_intra,
      *r_inter, *r_noise, *r_sinr, *r_los, *r_interferers, *r_decoded, *r_overlap_count, *r_overlap_offset;
  Column *x_transmission, *x_gain, *x_power, *x_inter_rat, *x_counted;

  // What a reception row copies from its transmission, and what checks need.
  struct Sent {
    std::uint64_t packet;
    double start_s;
    std::uint32_t node;
    Rat rat;
    std::uint8_t attempt;
  };
  std::vector<Sent> sent;
  std::uint64_t reception_count = 0, overlap_count = 0;
  std::pair<std::uint32_t, std::uint32_t> last_reception{0, 0};
  std::int64_t max_node = -1;

  Impl(const std::filesystem::path& path, const SinrHeader& h)
      : file(path.string()), header(h), out(file, sinr_schema()) {}

  // The header is checked before the file is created, so a bad one truncates nothing.
  void check_header() const {
    const auto bad = [&](const std::string& what) { throw std::invalid_argument(file + ": SINR header: " + what); };
    for (const auto& a : sinr_schema().at("attributes")) {
      if (a.at("name") != "channel_model") continue;
      const auto& allowed = a.at("one_of");
      if (std::find(allowed.begin(), allowed.end(), header.channel_model) == allowed.end())
        bad("channel model \"" + header.channel_model + "\" is not one of " + allowed.dump());
    }
    const std::pair<const char*, double> reals[] = {{"carrier_hz", header.carrier_hz},
                                                    {"sinr_threshold_db", header.sinr_threshold_db},
                                                    {"sensitivity_dbm", header.sensitivity_dbm},
                                                    {"gain_threshold_db", header.gain_threshold_db},
                                                    {"time_start_s", header.time_start_s},
                                                    {"time_end_s", header.time_end_s}};
    for (const auto& [name, v] : reals)
      if (!std::isfinite(v)) bad(std::string(name) + " is not finite");
  }

  void create() {
    check_header();
    out.create();
    out.identity_attrs(kSinrFormat, kSinrSchemaVersion, header.raysweep_version, header.git_hash, header.config, header.inputs,
                       header.provenance, header.seed);
    out.attr("", "channel_model", header.channel_model);
    out.attr("", "los_from_ray", flag(header.los_from_ray));
    out.attr("", "carrier_hz", header.carrier_hz);
    out.attr("", "sinr_threshold_db", header.sinr_threshold_db);
    out.attr("", "sensitivity_dbm", header.sensitivity_dbm);
    out.attr("", "gain_threshold_db", header.gain_threshold_db);
    out.attr("", "time_start_s", header.time_start_s);
    out.attr("", "time_end_s", header.time_end_s);

    t_node = out.column("transmissions", "node", Dtype::u32);
    t_rat = out.column("transmissions", "rat", Dtype::u8);
    t_message = out.column("transmissions", "message", Dtype::u8);
    t_packet = out.column("transmissions", "packet", Dtype::u64);
    t_attempt = out.column("transmissions", "attempt", Dtype::u8);
    t_size = out.column("transmissions", "size_bytes", Dtype::u32);
    t_start = out.column("transmissions", "start_s", Dtype::f64);
    t_duration = out.column("transmissions", "duration_s", Dtype::f64);
    t_band = out.column("transmissions", "band_hz", Dtype::f64);
    t_power = out.column("transmissions", "power_dbm", Dtype::f32);

    r_transmission = out.column("receptions", "transmission", Dtype::u32);
    r_tx = out.column("receptions", "tx", Dtype::u32);
    r_rx = out.column("receptions", "rx", Dtype::u32);
    r_rat = out.column("receptions", "rat", Dtype::u8);
    r_packet = out.column("receptions", "packet", Dtype::u64);
    r_attempt = out.column("receptions", "attempt", Dtype::u8);
    r_time = out.column("receptions", "time_s", Dtype::f64);
    r_distance = out.column("receptions", "distance_m", Dtype::f32);
    r_prx = out.column("receptions", "prx_dbm", Dtype::f32);
    r_intra = out.column("receptions", "intra_dbm", Dtype::f32);
    r_inter = out.column("receptions", "inter_dbm", Dtype::f32);
    r_noise = out.column("receptions", "noise_dbm", Dtype::f32);
    r_sinr = out.column("receptions", "sinr_db", Dtype::f32);
    r_los = out.column("receptions", "los_class", Dtype::u8);
    r_interferers = out.column("receptions", "interferers", Dtype::u16);
    r_decoded = out.column("receptions", "decoded", Dtype::u8);
    r_overlap_count = out.column("receptions", "overlap_count", Dtype::u16);
    r_overlap_offset = out.column("receptions", "overlap_offset", Dtype::u64);

    x_transmission = out.column("interferers", "transmission", Dtype::u32);
    x_gain = out.column("interferers", "gain_db", Dtype::f32);
    x_power = out.column("interferers", "power_dbm", Dtype::f32);
    x_inter_rat = out.column("interferers", "inter_rat", Dtype::u8);
    x_counted = out.column("interferers", "counted", Dtype::u8);
  }

  void add_transmission(const Transmission& t) {
    if (finished) throw std::runtime_error(file + ": add_transmission() after finish()");
    const auto bad = [&](const std::string& what) {
      throw std::invalid_argument(file + ": transmission " + std::to_string(sent.size()) + " (node " +
                                  std::to_string(t.node) + ", packet " + std::to_string(t.packet) + ", attempt " +
                                  std::to_string(t.attempt) + "): " + what);
    };
    // Receptions name transmissions by row and are sorted by it: all rows come first.
    if (reception_count > 0) bad("added after a reception");
    if (sent.size() >= std::numeric_limits<std::uint32_t>::max()) bad("too many transmissions");
    if (!std::isfinite(t.start_s)) bad("start time is not finite");
    if (!sent.empty() && t.start_s < sent.back().start_s)
      bad("starts at " + num(t.start_s) + " s, before the previous transmission's start " + num(sent.back().start_s) +
          " s");
    if (!(std::isfinite(t.duration_s) && t.duration_s > 0)) bad("duration " + num(t.duration_s) + " s is not > 0");
    if (!(std::isfinite(t.f_lo_hz) && std::isfinite(t.f_hi_hz) && t.f_hi_hz > t.f_lo_hz))
      bad("band [" + num(t.f_lo_hz) + ", " + num(t.f_hi_hz) + "] Hz does not have f_lo < f_hi");
    if (t.rat == Rat::none) bad("RAT none");
    if (static_cast<std::uint8_t>(t.rat) > kMaxRat) bad("unknown RAT code " + std::to_string(static_cast<int>(t.rat)));
    if (static_cast<std::uint8_t>(t.message) > kMaxMessage)
      bad("unknown message code " + std::to_string(static_cast<int>(t.message)));

    t_node->put(t.node);
    t_rat->put(static_cast<std::uint8_t>(t.rat));
    t_message->put(static_cast<std::uint8_t>(t.message));
    t_packet->put(t.packet);
    t_attempt->put(t.attempt);
    t_size->put(t.size_bytes);
    t_start->put(t.start_s);
    t_duration->put(t.duration_s);
    t_band->put(t.f_lo_hz), t_band->put(t.f_hi_hz);
    t_power->put(static_cast<float>(t.power_dbm));
    sent.push_back({t.packet, t.start_s, t.node, t.rat, t.attempt});
    max_node = std::max<std::int64_t>(max_node, t.node);
    out.maybe_flush();
  }

  void add_reception(const Reception& r, const std::vector<Interferer>& overlaps) {
    if (finished) throw std::runtime_error(file + ": add_reception() after finish()");
    const auto bad = [&](const std::string& what) {
      throw std::invalid_argument(file + ": reception " + std::to_string(reception_count) + " (transmission " +
                                  std::to_string(r.transmission) + ", rx " + std::to_string(r.rx) + "): " + what);
    };
    if (r.transmission >= sent.size())
      bad("unknown transmission (" + std::to_string(sent.size()) + " transmissions added)");
    const std::pair<std::uint32_t, std::uint32_t> key{r.transmission, r.rx};
    if (reception_count > 0 && !(last_reception < key))
      bad("not after the previous reception (transmission " + std::to_string(last_reception.first) + ", rx " +
          std::to_string(last_reception.second) + ") in (transmission, rx) order");
    const Sent& s = sent[r.transmission];
    if (r.rx == s.node) bad("the receiver is the sender");
    if (r.los_class > 2) bad("los_class " + std::to_string(r.los_class) + " not in 0..2");
    if (overlaps.size() > std::numeric_limits<std::uint16_t>::max())
      bad(std::to_string(overlaps.size()) + " overlaps, at most 65535 per reception");
    std::size_t counted = 0;
    for (std::size_t i = 0; i < overlaps.size(); ++i) {
      const auto& o = overlaps[i];
      const std::string at = "overlap " + std::to_string(i) + " (transmission " + std::to_string(o.transmission) + ")";
      if (o.transmission >= sent.size()) bad(at + ": unknown transmission");
      if (o.transmission == r.transmission) bad(at + ": the reception's own transmission");
      if (o.inter_rat != (sent[o.transmission].rat != s.rat))
        bad(at + ": inter_rat " + std::to_string(o.inter_rat) + " disagrees with the transmissions' RATs");
      if (o.counted) ++counted;
    }
    if (counted != r.interferers)
      bad("interferers is " + std::to_string(r.interferers) + " but " + std::to_string(counted) +
          " overlaps are counted");

    r_transmission->put(r.transmission);
    r_tx->put(s.node);
    r_rx->put(r.rx);
    r_rat->put(static_cast<std::uint8_t>(s.rat));
    r_packet->put(s.packet);
    r_attempt->put(s.attempt);
    r_time->put(s.start_s);
    r_distance->put(r.distance_m);
    r_prx->put(r.prx_dbm);
    r_intra->put(r.intra_dbm);
    r_inter->put(r.inter_dbm);
    r_noise->put(r.noise_dbm);
    r_sinr->put(r.sinr_db);
    r_los->put(r.los_class);
    r_interferers->put(r.interferers);
    r_decoded->put(flag(r.decoded));
    r_overlap_count->put(static_cast<std::uint16_t>(overlaps.size()));
    r_overlap_offset->put(std::uint64_t{overlap_count});
    for (const auto& o : overlaps) {
      x_transmission->put(o.transmission);
      x_gain->put(o.gain_db);
      x_power->put(o.power_dbm);
      x_inter_rat->put(flag(o.inter_rat));
      x_counted->put(flag(o.counted));
    }
    overlap_count += overlaps.size();
    ++reception_count;
    last_reception = key;
    max_node = std::max<std::int64_t>(max_node, r.rx);
    out.maybe_flush();
  }

  static float prr_of(const PrrEntry& e) {
    if (e.packets == 0) return std::numeric_limits<float>::quiet_NaN();
    return static_cast<float>(static_cast<double>(e.received) / static_cast<double>(e.packets));
  }

  void finish(const std::vector<SinrNode>& nodes, const std::vector<PrrEntry>& links, const std::vector<PrrEntry>& rats) {
    if (finished) throw std::runtime_error(file + ": finish() called twice");
    const std::uint64_t n = nodes.size();
    if (max_node >= static_cast<std::int64_t>(n))
      throw std::invalid_argument(file + ": records name node " + std::to_string(max_node) + " but the node table has " +
                                  std::to_string(n) + " nodes");
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      const auto bad = [&](const std::string& what) {
        throw std::invalid_argument(file + ": node " + std::to_string(i) + " (" + nodes[i].id + "): " + what);
      };
      if (static_cast<std::uint8_t>(nodes[i].kind) > kMaxNodeKind) bad("unknown node kind");
      if (static_cast<std::uint8_t>(nodes[i].rat) > kMaxRat) bad("unknown RAT code");
    }
    const auto check_prr = [&](const std::vector<PrrEntry>& entries, const char* table, bool link) {
      for (std::size_t i = 0; i < entries.size(); ++i) {
        const auto& e = entries[i];
        const auto bad = [&](const std::string& what) {
          throw std::invalid_argument(file + ": " + table + " entry " + std::to_string(i) +
                                      (link ? " (" + std::to_string(e.tx) + " -> " + std::to_string(e.rx) + ")" : "") +
                                      ": " + what);
        };
        if (link && (e.tx >= n || e.rx >= n))
          bad("names a node >= the node table's " + std::to_string(n) + " nodes");
        if (link && e.tx == e.rx) bad("tx == rx");
        if (static_cast<std::uint8_t>(e.rat) > kMaxRat) bad("unknown RAT code");
        if (e.received > e.packets)
          bad(std::to_string(e.received) + " received of " + std::to_string(e.packets) + " packets");
      }
    };
    check_prr(links, "PRR link", true);
    check_prr(rats, "PRR RAT", false);
    out.flush_all();

    std::vector<const char*> ids;
    std::vector<std::uint8_t> kinds, node_rats;
    for (const auto& node : nodes) {
      ids.push_back(node.id.c_str());
      kinds.push_back(static_cast<std::uint8_t>(node.kind));
      node_rats.push_back(static_cast<std::uint8_t>(node.rat));
    }
    out.table("nodes", "id", Dtype::str, n, ids.data());
    out.table("nodes", "kind", Dtype::u8, n, kinds.data());
    out.table("nodes", "rat", Dtype::u8, n, node_rats.data());

    // Links can be many (up to N^2): chunked and compressed like the streams.
    Column* l_tx = out.column("prr_links", "tx", Dtype::u32);
    Column* l_rx = out.column("prr_links", "rx", Dtype::u32);
    Column* l_rat = out.column("prr_links", "rat", Dtype::u8);
    Column* l_packets = out.column("prr_links", "packets", Dtype::u64);
    Column* l_received = out.column("prr_links", "received", Dtype::u64);
    Column* l_prr = out.column("prr_links", "prr", Dtype::f32);
    Column* l_distance = out.column("prr_links", "mean_distance_m", Dtype::f32);
    for (const auto& e : links) {
      l_tx->put(e.tx);
      l_rx->put(e.rx);
      l_rat->put(static_cast<std::uint8_t>(e.rat));
      l_packets->put(e.packets);
      l_received->put(e.received);
      l_prr->put(prr_of(e));
      l_distance->put(e.mean_distance_m);
      out.maybe_flush();
    }
    out.flush_all();

    std::vector<std::uint8_t> rat_codes;
    std::vector<std::uint64_t> packets, received;
    std::vector<float> prr;
    for (const auto& e : rats) {
      rat_codes.push_back(static_cast<std::uint8_t>(e.rat));
      packets.push_back(e.packets);
      received.push_back(e.received);
      prr.push_back(prr_of(e));
    }
    out.table("prr_rats", "rat", Dtype::u8, rats.size(), rat_codes.data());
    out.table("prr_rats", "packets", Dtype::u64, rats.size(), packets.data());
    out.table("prr_rats", "received", Dtype::u64, rats.size(), received.data());
    out.table("prr_rats", "prr", Dtype::f32, rats.size(), prr.data());

    out.attr("", "node_count", std::uint64_t{n});
    out.attr("", "transmission_count", std::uint64_t{sent.size()});
    out.attr("", "reception_count", std::uint64_t{reception_count});
    out.attr("", "interferer_count", std::uint64_t{overlap_count});
    out.close_all(true);
    finished = true;
  }
};

SinrWriter::SinrWriter(const std::filesystem::path& path, const SinrHeader& header) {
  QuietHdf5 quiet;
  impl_ = std::make_unique<Impl>(path, header);
  impl_->create();
}

SinrWriter::~SinrWriter() {
  if (impl_ && !impl_->finished) impl_->out.abandon();
}

void SinrWriter::add_transmission(const Transmission& t) {
  QuietHdf5 quiet;
  impl_->add_transmission(t);
}

void SinrWriter::add_reception(const Reception& r, const std::vector<Interferer>& overlaps) {
  QuietHdf5 quiet;
  impl_->add_reception(r, overlaps);
}

void SinrWriter::finish(const std::vector<SinrNode>& nodes, const std::vector<PrrEntry>& prr_links,
                        const std::vector<PrrEntry>& prr_rats) {
  QuietHdf5 quiet;
  impl_->finish(nodes, prr_links, prr_rats);
}

std::uint64_t SinrWriter::transmissions() const { return impl_->sent.size(); }
std::uint64_t SinrWriter::receptions() const { return impl_->reception_count; }

// ---------------------------------------------------------------------------
// Schedule reader.

namespace {

// A whole dataset of the schema's dtype and shape converted to T; rows in *rows.
template <class T>
std::vector<T> schema_column(const hdf5::CheckedFile& f, const std::string& group, const std::string& name,
                             hsize_t* rows) {
  const auto& spec = hdf5::schema_dataset(sinr_schema(), group, name);
  const auto& shape = spec.at("shape");
  const hsize_t width = shape.size() == 2 ? shape[1].get<hsize_t>() : 1;
  const hdf5::Dataset d = f.dataset("/" + group + "/" + name);
  d.expect_dtype(spec.at("dtype"));
  d.expect(shape.size() == 2 ? hdf5::Extents{std::nullopt, width} : hdf5::Extents{std::nullopt});
  *rows = d.rows();
  return d.read<T>(0, *rows, width);
}

}  // namespace

SinrSchedule read_sinr_schedule(const std::string& path) {
  QuietHdf5 quiet;
  hdf5::CheckedFile r(path);
  r.open();
  const auto str_attr = [&](const std::string& name) { return r.attr<std::string>("/", name); };
  const std::string format = str_attr("format");
  if (format != kSinrFormat)
    r.fail("attribute format", "not a raysweep-sinr file (format \"" + format + "\")");
  const std::string version = str_attr("schema_version");
  const auto major = hdf5::major_version(version);
  if (!major || major != hdf5::major_version(kSinrSchemaVersion))
    r.fail("attribute schema_version", "version " + version + " is not supported (this program reads " +
                                           std::to_string(*hdf5::major_version(kSinrSchemaVersion)) + ".x)");
  if (r.attr_if<std::uint64_t>("/", "complete") != std::uint64_t{1})
    r.fail("attribute complete", "missing or not 1: the file was not finished (its writer stopped before finish())");

  SinrSchedule out;
  const std::string config = str_attr("config");
  try {
    out.config = nlohmann::json::parse(config);
  } catch (const nlohmann::json::exception& e) {
    r.fail("attribute config", std::string("not valid JSON text: ") + e.what());
  }

  // Nodes.
  hsize_t n = 0, rows = 0;
  const std::vector<std::string> ids = r.dataset("/nodes/id").strings();
  n = ids.size();
  const auto kind = schema_column<std::uint8_t>(r, "nodes", "kind", &rows);
  if (rows != n) r.fail("/nodes/kind", "has " + std::to_string(rows) + " rows, /nodes/id " + std::to_string(n));
  const auto node_rat = schema_column<std::uint8_t>(r, "nodes", "rat", &rows);
  if (rows != n) r.fail("/nodes/rat", "has " + std::to_string(rows) + " rows, /nodes/id " + std::to_string(n));
  out.nodes.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (kind[i] > kMaxNodeKind) r.fail("/nodes/kind", "row " + std::to_string(i) + ": unknown node kind " + std::to_string(kind[i]));
    if (node_rat[i] > kMaxRat) r.fail("/nodes/rat", "row " + std::to_string(i) + ": unknown RAT " + std::to_string(node_rat[i]));
    out.nodes[i] = {ids[i], static_cast<NodeKind>(kind[i]), static_cast<Rat>(node_rat[i])};
  }

  // Transmissions.
  hsize_t t = 0;
  const auto node = schema_column<std::uint32_t>(r, "transmissions", "node", &t);
  const auto same_rows = [&](const char* name, hsize_t got) {
    if (got != t)
      r.fail(std::string("/transmissions/") + name,
             "has " + std::to_string(got) + " rows, /transmissions/node " + std::to_string(t));
  };
  const auto rat = schema_column<std::uint8_t>(r, "transmissions", "rat", &rows);
  same_rows("rat", rows);
  const auto message = schema_column<std::uint8_t>(r, "transmissions", "message", &rows);
  same_rows("message", rows);
  const auto packet = schema_column<std::uint64_t>(r, "transmissions", "packet", &rows);
  same_rows("packet", rows);
  const auto attempt = schema_column<std::uint8_t>(r, "transmissions", "attempt", &rows);
  same_rows("attempt", rows);
  const auto size = schema_column<std::uint32_t>(r, "transmissions", "size_bytes", &rows);
  same_rows("size_bytes", rows);
  const auto start = schema_column<double>(r, "transmissions", "start_s", &rows);
  same_rows("start_s", rows);
  const auto duration = schema_column<double>(r, "transmissions", "duration_s", &rows);
  same_rows("duration_s", rows);
  const auto band = schema_column<double>(r, "transmissions", "band_hz", &rows);
  same_rows("band_hz", rows);
  const auto power = schema_column<float>(r, "transmissions", "power_dbm", &rows);
  same_rows("power_dbm", rows);

  out.transmissions.resize(t);
  for (std::size_t i = 0; i < t; ++i) {
    const auto bad = [&](const char* name, const std::string& what) {
      r.fail(std::string("/transmissions/") + name, "row " + std::to_string(i) + ": " + what);
    };
    if (node[i] >= n) bad("node", "node " + std::to_string(node[i]) + " not below N = " + std::to_string(n));
    if (rat[i] == 0 || rat[i] > kMaxRat) bad("rat", "RAT " + std::to_string(rat[i]) + " not 1 or 2");
    if (message[i] > kMaxMessage) bad("message", "unknown message code " + std::to_string(message[i]));
    if (!std::isfinite(start[i]) || (i > 0 && start[i] < start[i - 1]))
      bad("start_s", "start " + num(start[i]) + " s not finite or before the previous transmission's");
    if (!(std::isfinite(duration[i]) && duration[i] > 0)) bad("duration_s", "duration " + num(duration[i]) + " s not > 0");
    if (!(std::isfinite(band[2 * i]) && std::isfinite(band[2 * i + 1]) && band[2 * i] < band[2 * i + 1]))
      bad("band_hz", "band does not have f_lo < f_hi");
    auto& x = out.transmissions[i];
    x.node = node[i];
    x.rat = static_cast<Rat>(rat[i]);
    x.message = static_cast<Message>(message[i]);
    x.packet = packet[i];
    x.attempt = attempt[i];
    x.size_bytes = size[i];
    x.start_s = start[i];
    x.duration_s = duration[i];
    x.f_lo_hz = band[2 * i];
    x.f_hi_hz = band[2 * i + 1];
    x.power_dbm = power[i];
  }
  return out;
}

}  // namespace raysweep::generators::sinr
