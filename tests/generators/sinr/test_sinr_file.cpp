// SINR outcome file (raysweep-sinr): writer round trip (schedule reader and the
// HDF5 C API), validation, dataset_info, rejected input, corrupt and unfinished
// files, determinism, embedded schema.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "generators/formats.hpp"
#include "generators/sinr/sinr_file.hpp"
#include "hdf5_test_util.hpp"
#include "meshkit/errors.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using raysweep::meshkit::InputError;
using raysweep::test::H5;
using raysweep::test::has_attr;
using raysweep::test::num_attr;
using raysweep::test::poke_f64;
using raysweep::test::poke_u64;
using raysweep::test::read_bytes;
using raysweep::test::read_ds;
using raysweep::test::scratch_dir;
using raysweep::test::set_str_attr;
using raysweep::test::str_attr;
using raysweep::test::source_dir;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

fs::path tmp_dir(const std::string& name) { return scratch_dir(name + "-" + std::to_string(::getpid())); }

// ---------------------------------------------------------------------------
// Test records: an RSU and a vehicle with 802.11p (nodes 0, 1), two NR-V2X
// vehicles (2, 3), a vehicle without radio (4); four transmissions (one a blind
// retransmission), four receptions with overlaps of both RATs, counted or not.

SinrHeader test_header() {
  SinrHeader h;
  h.raysweep_version = "0.1.0-test";
  h.git_hash = "0123456789ab";
  h.config = {{"sinr", {{"rats", {"80211p", "nrv2x"}}, {"prr_range_m", 300}}}};
  h.inputs = {{"channels", {{"path", "channels.h5"}, {"sha256", "ab"}}}};
  h.provenance = {{"command", "raysweep sinr"}};
  h.seed = 7;
  h.channel_model = "tr37885-urban";
  h.los_from_ray = true;
  h.carrier_hz = 5.9e9;
  h.sinr_threshold_db = 2.5;
  h.sensitivity_dbm = -92;
  h.gain_threshold_db = -110;
  h.time_start_s = 0;
  h.time_end_s = 1;
  return h;
}

std::vector<SinrNode> test_nodes() {
  return {{"rsu0", NodeKind::rsu, Rat::wifi80211p},
          {"veh.a", NodeKind::vehicle, Rat::wifi80211p},
          {"veh.b", NodeKind::vehicle, Rat::nr_v2x},
          {"veh.c", NodeKind::vehicle, Rat::nr_v2x},
          {"veh.d", NodeKind::vehicle, Rat::none}};
}

Transmission tx(std::uint32_t node, Rat rat, Message m, std::uint64_t packet, std::uint8_t attempt, double start,
                double duration, double f_lo, double f_hi, double power) {
  Transmission t;
  t.node = node;
  t.rat = rat;
  t.message = m;
  t.packet = packet;
  t.attempt = attempt;
  t.size_bytes = static_cast<std::uint32_t>(200 + 100 * packet % 7);
  t.start_s = start;
  t.duration_s = duration;
  t.f_lo_hz = f_lo;
  t.f_hi_hz = f_hi;
  t.power_dbm = power;
  return t;
}

std::vector<Transmission> test_transmissions() {
  return {tx(0, Rat::wifi80211p, Message::cam, 100, 0, 0.0, 4.2e-4, 5.885e9, 5.895e9, 23),
          tx(2, Rat::nr_v2x, Message::cpm, 200, 0, 1e-4, 1e-3, 5.890e9, 5.900e9, 22.5),
          tx(2, Rat::nr_v2x, Message::cpm, 200, 1, 2.1e-3, 1e-3, 5.890e9, 5.900e9, 22.5),
          tx(1, Rat::wifi80211p, Message::cam, 101, 0, 2.1e-3, 4.2e-4, 5.885e9, 5.895e9, 20)};
}

struct Rx {
  Reception r;
  std::vector<Interferer> overlaps;
};

Reception rec(std::uint32_t t, std::uint32_t rx, float d, float prx, float intra, float inter, float sinr,
              std::uint8_t los, std::uint16_t interferers, bool decoded) {
  Reception r;
  r.transmission = t;
  r.rx = rx;
  r.distance_m = d;
  r.prx_dbm = prx;
  r.intra_dbm = intra;
  r.inter_dbm = inter;
  r.noise_dbm = -95.5f;
  r.sinr_db = sinr;
  r.los_class = los;
  r.interferers = interferers;
  r.decoded = decoded;
  return r;
}

Interferer ovl(std::uint32_t t, float gain, float power, bool inter_rat, bool counted) {
  return {t, gain, power, inter_rat, counted};
}

std::vector<Rx> test_receptions() {
  return {
      {rec(0, 1, 50.f, -70.f, -kInf, -90.f, 19.5f, 0, 1, true), {ovl(1, -80.f, -90.f, true, true)}},
      {rec(1, 3, 30.f, -65.f, -kInf, -kInf, 30.5f, 1, 0, true), {ovl(0, -130.f, -kInf, true, false)}},
      {rec(2, 3, 30.5f, -kInf, -kInf, -kInf, -kInf, 2, 0, false), {}},
      {rec(3, 0, 51.f, -72.f, -kInf, -100.f, 20.f, 0, 1, true),
       {ovl(2, -95.f, -100.f, true, true), ovl(1, -kInf, -kInf, true, false)}},
  };
}

PrrEntry prr(std::uint32_t t, std::uint32_t r, Rat rat, std::uint64_t packets, std::uint64_t received, float d) {
  PrrEntry e;
  e.tx = t;
  e.rx = r;
  e.rat = rat;
  e.packets = packets;
  e.received = received;
  e.mean_distance_m = d;
  return e;
}

std::vector<PrrEntry> test_prr_links() {
  return {prr(0, 1, Rat::wifi80211p, 1, 1, 50.f), prr(1, 0, Rat::wifi80211p, 1, 1, 51.f),
          prr(2, 3, Rat::nr_v2x, 1, 1, 30.f), prr(3, 2, Rat::nr_v2x, 0, 0, 0.f)};
}

std::vector<PrrEntry> test_prr_rats() {
  return {prr(0, 0, Rat::wifi80211p, 4, 3, 50.5f), prr(0, 0, Rat::nr_v2x, 1, 1, 30.f)};
}

void write_test_file(const fs::path& file, bool finish = true) {
  SinrWriter w(file, test_header());
  for (const auto& t : test_transmissions()) w.add_transmission(t);
  for (const auto& r : test_receptions()) w.add_reception(r.r, r.overlaps);
  if (finish) w.finish(test_nodes(), test_prr_links(), test_prr_rats());
}

bool mentions(const std::vector<std::string>& problems, const std::string& what) {
  return std::any_of(problems.begin(), problems.end(),
                     [&](const std::string& p) { return p.find(what) != std::string::npos; });
}

std::string joined(const std::vector<std::string>& problems) {
  std::string s;
  for (const auto& p : problems) s += "  " + p + "\n";
  return s;
}

// Bitwise float equality (so -inf and NaN compare as stored).
bool same(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

}  // namespace

// ---------------------------------------------------------------------------

TEST(SinrFile, WriteValidateReadBack) {
  const fs::path file = tmp_dir("roundtrip") / "sinr.h5";
  write_test_file(file);
  const auto problems = validate_dataset(file.string());
  EXPECT_TRUE(problems.empty()) << joined(problems);

  // Root attributes.
  EXPECT_EQ(str_attr(file, "format"), "raysweep-sinr");
  EXPECT_EQ(str_attr(file, "schema_version"), "1.0.0");
  EXPECT_EQ(str_attr(file, "channel_model"), "tr37885-urban");
  EXPECT_EQ(nlohmann::json::parse(str_attr(file, "inputs")), test_header().inputs);
  EXPECT_EQ(num_attr<std::uint64_t>(file, "seed", H5T_NATIVE_UINT64), 7u);
  EXPECT_EQ(num_attr<std::uint8_t>(file, "los_from_ray", H5T_NATIVE_UINT8), 1u);
  EXPECT_EQ(num_attr<double>(file, "gain_threshold_db", H5T_NATIVE_DOUBLE), -110.0);
  EXPECT_EQ(num_attr<std::uint64_t>(file, "node_count", H5T_NATIVE_UINT64), 5u);
  EXPECT_EQ(num_attr<std::uint64_t>(file, "transmission_count", H5T_NATIVE_UINT64), 4u);
  EXPECT_EQ(num_attr<std::uint64_t>(file, "reception_count", H5T_NATIVE_UINT64), 4u);
  EXPECT_EQ(num_attr<std::uint64_t>(file, "interferer_count", H5T_NATIVE_UINT64), 4u);
  EXPECT_EQ(num_attr<std::uint8_t>(file, "complete", H5T_NATIVE_UINT8), 1u);

  // Schedule reader: every transmission field, the node table, the config.
  const auto sched = read_sinr_schedule(file.string());
  const auto ts = test_transmissions();
  ASSERT_EQ(sched.transmissions.size(), ts.size());
  for (std::size_t i = 0; i < ts.size(); ++i) {
    const auto &a = sched.transmissions[i], &b = ts[i];
    EXPECT_EQ(a.node, b.node) << i;
    EXPECT_EQ(a.rat, b.rat) << i;
    EXPECT_EQ(a.message, b.message) << i;
    EXPECT_EQ(a.packet, b.packet) << i;
    EXPECT_EQ(a.attempt, b.attempt) << i;
    EXPECT_EQ(a.size_bytes, b.size_bytes) << i;
    EXPECT_EQ(a.start_s, b.start_s) << i;
    EXPECT_EQ(a.duration_s, b.duration_s) << i;
    EXPECT_EQ(a.f_lo_hz, b.f_lo_hz) << i;
    EXPECT_EQ(a.f_hi_hz, b.f_hi_hz) << i;
    EXPECT_EQ(a.power_dbm, static_cast<double>(static_cast<float>(b.power_dbm))) << i;  // stored as f32
  }
  const auto nodes = test_nodes();
  ASSERT_EQ(sched.nodes.size(), nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    EXPECT_EQ(sched.nodes[i].id, nodes[i].id);
    EXPECT_EQ(sched.nodes[i].kind, nodes[i].kind);
    EXPECT_EQ(sched.nodes[i].rat, nodes[i].rat);
  }
  EXPECT_EQ(sched.config, test_header().config);

  // Receptions: fields copied from their transmission, overlap ranges, -inf kept.
  const auto rs = test_receptions();
  const auto r_tx = read_ds<std::uint32_t>(file, "/receptions/tx", H5T_NATIVE_UINT32);
  const auto r_rat = read_ds<std::uint8_t>(file, "/receptions/rat", H5T_NATIVE_UINT8);
  const auto r_packet = read_ds<std::uint64_t>(file, "/receptions/packet", H5T_NATIVE_UINT64);
  const auto r_attempt = read_ds<std::uint8_t>(file, "/receptions/attempt", H5T_NATIVE_UINT8);
  const auto r_time = read_ds<double>(file, "/receptions/time_s", H5T_NATIVE_DOUBLE);
  const auto r_rx = read_ds<std::uint32_t>(file, "/receptions/rx", H5T_NATIVE_UINT32);
  const auto r_sinr = read_ds<float>(file, "/receptions/sinr_db", H5T_NATIVE_FLOAT);
  const auto r_prx = read_ds<float>(file, "/receptions/prx_dbm", H5T_NATIVE_FLOAT);
  const auto r_intra = read_ds<float>(file, "/receptions/intra_dbm", H5T_NATIVE_FLOAT);
  const auto r_inter = read_ds<float>(file, "/receptions/inter_dbm", H5T_NATIVE_FLOAT);
  const auto r_noise = read_ds<float>(file, "/receptions/noise_dbm", H5T_NATIVE_FLOAT);
  const auto r_dist = read_ds<float>(file, "/receptions/distance_m", H5T_NATIVE_FLOAT);
  const auto r_los = read_ds<std::uint8_t>(file, "/receptions/los_class", H5T_NATIVE_UINT8);
  const auto r_decoded = read_ds<std::uint8_t>(file, "/receptions/decoded", H5T_NATIVE_UINT8);
  const auto r_interf = read_ds<std::uint16_t>(file, "/receptions/interferers", H5T_NATIVE_UINT16);
  const auto r_ocount = read_ds<std::uint16_t>(file, "/receptions/overlap_count", H5T_NATIVE_UINT16);
  const auto r_ooffset = read_ds<std::uint64_t>(file, "/receptions/overlap_offset", H5T_NATIVE_UINT64);
  ASSERT_EQ(r_tx.size(), rs.size());
  std::uint64_t offset = 0;
  for (std::size_t i = 0; i < rs.size(); ++i) {
    const auto& r = rs[i].r;
    const auto& t = ts[r.transmission];
    EXPECT_EQ(r_tx[i], t.node) << i;
    EXPECT_EQ(r_rat[i], static_cast<std::uint8_t>(t.rat)) << i;
    EXPECT_EQ(r_packet[i], t.packet) << i;
    EXPECT_EQ(r_attempt[i], t.attempt) << i;
    EXPECT_EQ(r_time[i], t.start_s) << i;
    EXPECT_EQ(r_rx[i], r.rx) << i;
    EXPECT_TRUE(same(r_sinr[i], r.sinr_db)) << i;
    EXPECT_TRUE(same(r_prx[i], r.prx_dbm)) << i;
    EXPECT_TRUE(same(r_intra[i], r.intra_dbm)) << i;
    EXPECT_TRUE(same(r_inter[i], r.inter_dbm)) << i;
    EXPECT_TRUE(same(r_noise[i], r.noise_dbm)) << i;
    EXPECT_TRUE(same(r_dist[i], r.distance_m)) << i;
    EXPECT_EQ(r_los[i], r.los_class) << i;
    EXPECT_EQ(r_decoded[i], r.decoded ? 1 : 0) << i;
    EXPECT_EQ(r_interf[i], r.interferers) << i;
    EXPECT_EQ(r_ocount[i], rs[i].overlaps.size()) << i;
    EXPECT_EQ(r_ooffset[i], offset) << i;
    offset += rs[i].overlaps.size();
  }
  const auto x_t = read_ds<std::uint32_t>(file, "/interferers/transmission", H5T_NATIVE_UINT32);
  const auto x_gain = read_ds<float>(file, "/interferers/gain_db", H5T_NATIVE_FLOAT);
  const auto x_power = read_ds<float>(file, "/interferers/power_dbm", H5T_NATIVE_FLOAT);
  const auto x_inter = read_ds<std::uint8_t>(file, "/interferers/inter_rat", H5T_NATIVE_UINT8);
  const auto x_counted = read_ds<std::uint8_t>(file, "/interferers/counted", H5T_NATIVE_UINT8);
  ASSERT_EQ(x_t.size(), offset);
  std::size_t k = 0;
  for (const auto& r : rs)
    for (const auto& o : r.overlaps) {
      EXPECT_EQ(x_t[k], o.transmission) << k;
      EXPECT_TRUE(same(x_gain[k], o.gain_db)) << k;
      EXPECT_TRUE(same(x_power[k], o.power_dbm)) << k;
      EXPECT_EQ(x_inter[k], o.inter_rat ? 1 : 0) << k;
      EXPECT_EQ(x_counted[k], o.counted ? 1 : 0) << k;
      ++k;
    }

  // PRR tables: prr = received / packets, NaN without packets.
  const auto l_prr = read_ds<float>(file, "/prr_links/prr", H5T_NATIVE_FLOAT);
  const auto l_tx = read_ds<std::uint32_t>(file, "/prr_links/tx", H5T_NATIVE_UINT32);
  const auto l_dist = read_ds<float>(file, "/prr_links/mean_distance_m", H5T_NATIVE_FLOAT);
  ASSERT_EQ(l_prr.size(), 4u);
  EXPECT_EQ(l_tx, (std::vector<std::uint32_t>{0, 1, 2, 3}));
  EXPECT_EQ(l_prr[0], 1.f);
  EXPECT_TRUE(std::isnan(l_prr[3]));
  EXPECT_EQ(l_dist[2], 30.f);
  EXPECT_EQ(read_ds<float>(file, "/prr_rats/prr", H5T_NATIVE_FLOAT), (std::vector<float>{0.75f, 1.f}));
  EXPECT_EQ(read_ds<std::uint8_t>(file, "/prr_rats/rat", H5T_NATIVE_UINT8), (std::vector<std::uint8_t>{1, 2}));

  // Summary.
  const auto info = dataset_info(file.string());
  EXPECT_EQ(info["format"], "raysweep-sinr");
  EXPECT_EQ(info["schema_version"], "1.0.0");
  EXPECT_EQ(info["raysweep_version"], "0.1.0-test");
  EXPECT_EQ(info["git_hash"], "0123456789ab");
  EXPECT_EQ(info["complete"], true);
  EXPECT_EQ(info["channel_model"], "tr37885-urban");
  EXPECT_EQ(info["los_from_ray"], true);
  EXPECT_EQ(info["nodes"], 5);
  EXPECT_EQ(info["transmissions"], 4);
  EXPECT_EQ(info["receptions"], 4);
  EXPECT_EQ(info["interferers"], 4);
  EXPECT_EQ(info["decoded"], 3);
  EXPECT_EQ(info["prr"]["80211p"]["packets"], 4);
  EXPECT_EQ(info["prr"]["80211p"]["received"], 3);
  EXPECT_DOUBLE_EQ(info["prr"]["80211p"]["prr"].get<double>(), 0.75);
  EXPECT_DOUBLE_EQ(info["prr"]["nrv2x"]["prr"].get<double>(), 1.0);
  EXPECT_EQ(info["file"], file.string());
  EXPECT_EQ(info["file_bytes"].get<std::uint64_t>(), fs::file_size(file));
  const std::string text = format_dataset_info(info);
  EXPECT_NE(text.find("raysweep-sinr 1.0.0"), std::string::npos) << text;
  EXPECT_NE(text.find("receptions    4 (3 decoded, 75.0 %)"), std::string::npos) << text;
  EXPECT_NE(text.find("80211p  0.7500 (3 of 4 packets)"), std::string::npos) << text;
  EXPECT_EQ(text.find("INCOMPLETE"), std::string::npos) << text;
}

TEST(SinrFile, EmptyRunIsValid) {
  const fs::path file = tmp_dir("empty") / "sinr.h5";
  {
    SinrWriter w(file, test_header());
    w.finish({}, {}, {prr(0, 0, Rat::wifi80211p, 0, 0, 0.f)});
  }
  EXPECT_TRUE(validate_dataset(file.string()).empty()) << joined(validate_dataset(file.string()));
  const auto info = dataset_info(file.string());
  EXPECT_EQ(info["transmissions"], 0);
  EXPECT_TRUE(info["prr"]["80211p"]["prr"].is_null());
  EXPECT_TRUE(read_sinr_schedule(file.string()).transmissions.empty());
}

TEST(SinrFile, WriterRejectsInconsistentInput) {
  const fs::path dir = tmp_dir("reject");
  const auto ts = test_transmissions();
  const auto rs = test_receptions();
  SinrWriter w(dir / "x.h5", test_header());
  auto reject_tx = [&](Transmission t, const char* what) {
    EXPECT_THROW(w.add_transmission(t), std::invalid_argument) << what;
  };
  w.add_transmission(ts[0]);
  w.add_transmission(ts[1]);
  {
    auto t = ts[2];
    t.start_s = 0.5e-4;  // before transmission 1's start
    reject_tx(t, "unsorted start");
  }
  {
    auto t = ts[2];
    t.duration_s = 0;
    reject_tx(t, "zero duration");
  }
  {
    auto t = ts[2];
    t.f_hi_hz = t.f_lo_hz;
    reject_tx(t, "empty band");
  }
  {
    auto t = ts[2];
    t.rat = Rat::none;
    reject_tx(t, "RAT none");
  }
  try {
    auto t = ts[2];
    t.start_s = -1;
    w.add_transmission(t);
    ADD_FAILURE() << "unsorted transmission accepted";
  } catch (const std::invalid_argument& e) {
    // The message names the file and the row.
    EXPECT_NE(std::string(e.what()).find((dir / "x.h5").string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("transmission 2"), std::string::npos) << e.what();
  }
  EXPECT_EQ(w.transmissions(), 2u);
  w.add_transmission(ts[2]);
  w.add_transmission(ts[3]);

  auto reject_rx = [&](Reception r, std::vector<Interferer> o, const char* what) {
    EXPECT_THROW(w.add_reception(r, o), std::invalid_argument) << what;
  };
  {
    auto r = rs[0];
    r.r.transmission = 9;
    reject_rx(r.r, {}, "unknown transmission");
  }
  {
    auto r = rs[0];
    r.r.rx = 0;  // transmission 0 is sent by node 0
    reject_rx(r.r, r.overlaps, "rx == tx");
  }
  {
    auto r = rs[0];
    r.r.interferers = 2;  // one counted overlap
    reject_rx(r.r, r.overlaps, "interferers mismatch");
  }
  {
    auto r = rs[0];
    r.overlaps.push_back(ovl(0, -50.f, -60.f, false, true));
    r.r.interferers = 2;
    reject_rx(r.r, r.overlaps, "overlap is the own transmission");
  }
  {
    auto r = rs[0];
    r.overlaps.push_back(ovl(7, -50.f, -60.f, true, false));
    reject_rx(r.r, r.overlaps, "overlap names an unknown transmission");
  }
  {
    auto r = rs[0];
    r.overlaps[0].inter_rat = false;  // transmission 1 is NR-V2X, the reception 802.11p
    reject_rx(r.r, r.overlaps, "inter_rat disagrees");
  }
  EXPECT_EQ(w.receptions(), 0u);
  w.add_reception(rs[1].r, rs[1].overlaps);
  reject_rx(rs[0].r, rs[0].overlaps, "(transmission, rx) before the previous reception's");
  reject_rx(rs[1].r, rs[1].overlaps, "the same (transmission, rx) twice");
  reject_tx(ts[3], "transmission after a reception");
  for (std::size_t i = 2; i < rs.size(); ++i) w.add_reception(rs[i].r, rs[i].overlaps);
  EXPECT_EQ(w.receptions(), 3u);

  // finish() checks the tables against the records.
  auto nodes = test_nodes();
  nodes.pop_back();
  nodes.pop_back();  // node 3 receives
  EXPECT_THROW(w.finish(nodes, test_prr_links(), test_prr_rats()), std::invalid_argument);
  auto links = test_prr_links();
  links[0].received = 2;
  EXPECT_THROW(w.finish(test_nodes(), links, test_prr_rats()), std::invalid_argument);
  links = test_prr_links();
  links[1].rx = 5;
  EXPECT_THROW(w.finish(test_nodes(), links, test_prr_rats()), std::invalid_argument);
  w.finish(test_nodes(), test_prr_links(), test_prr_rats());
  EXPECT_THROW(w.add_transmission(ts[3]), std::runtime_error);
  EXPECT_TRUE(validate_dataset((dir / "x.h5").string()).empty()) << joined(validate_dataset((dir / "x.h5").string()));

  // A header the schema does not allow: nothing is created.
  auto h = test_header();
  h.channel_model = "free-space";
  EXPECT_THROW({ SinrWriter bad(dir / "bad.h5", h); }, std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir / "bad.h5"));
}

TEST(SinrFile, CorruptFilesAreRejected) {
  const fs::path dir = tmp_dir("corrupt");
  const fs::path good = dir / "good.h5";
  write_test_file(good);
  ASSERT_TRUE(validate_dataset(good.string()).empty()) << joined(validate_dataset(good.string()));
  auto copy = [&](const std::string& name) {
    const fs::path p = dir / name;
    fs::copy_file(good, p, fs::copy_options::overwrite_existing);
    return p;
  };

  {  // decoded outside {0, 1}
    const fs::path p = copy("decoded2.h5");
    poke_u64(p, "/receptions/decoded", 1, 2);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/receptions/decoded")) << joined(problems);
  }
  {  // a reception whose tx is not its transmission's sender
    const fs::path p = copy("tx.h5");
    poke_u64(p, "/receptions/tx", 0, 3);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/receptions/tx")) << joined(problems);
  }
  {  // a reception from itself
    const fs::path p = copy("self.h5");
    poke_u64(p, "/receptions/rx", 0, 0);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/receptions/rx")) << joined(problems);
  }
  {  // interferers not the number of counted overlaps
    const fs::path p = copy("interferers.h5");
    poke_u64(p, "/receptions/interferers", 3, 2);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/receptions/interferers")) << joined(problems);
  }
  {  // an overlap naming the reception's own transmission
    const fs::path p = copy("own.h5");
    poke_u64(p, "/interferers/transmission", 0, 0);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "own transmission")) << joined(problems);
  }
  {  // receptions out of order
    const fs::path p = copy("order.h5");
    poke_u64(p, "/receptions/transmission", 1, 3);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "not strictly sorted")) << joined(problems);
  }
  {  // transmissions out of schedule order, a zero duration
    const fs::path p = copy("schedule.h5");
    poke_f64(p, "/transmissions/start_s", 1, 5.0);
    poke_f64(p, "/transmissions/duration_s", 0, 0.0);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/transmissions/start_s")) << joined(problems);
    EXPECT_TRUE(mentions(problems, "/transmissions/duration_s")) << joined(problems);
    EXPECT_TRUE(mentions(problems, "/receptions/time_s")) << joined(problems);
  }
  {  // PRR not received / packets, more received than sent
    const fs::path p = copy("prr.h5");
    poke_u64(p, "/prr_links/received", 2, 5);
    poke_f64(p, "/prr_rats/prr", 0, 0.5);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/prr_links/received")) << joined(problems);
    EXPECT_TRUE(mentions(problems, "/prr_rats/prr")) << joined(problems);
  }
  {  // a transmission reference out of range
    const fs::path p = copy("ref.h5");
    poke_u64(p, "/interferers/transmission", 2, 99);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/interferers/transmission")) << joined(problems);
  }
  {  // an unknown format: one problem naming the file and the format
    const fs::path p = copy("format.h5");
    set_str_attr(p, "format", "raysweep-frobs");
    const auto problems = validate_dataset(p.string());
    ASSERT_EQ(problems.size(), 1u) << joined(problems);
    EXPECT_TRUE(mentions(problems, p.string())) << joined(problems);
    EXPECT_TRUE(mentions(problems, "raysweep-frobs")) << joined(problems);
    EXPECT_THROW(dataset_info(p.string()), InputError);
    try {
      read_sinr_schedule(p.string());
      ADD_FAILURE() << "read_sinr_schedule accepted another format";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), p.string());
      EXPECT_EQ(e.element(), "attribute format");
    }
  }
  {  // an unsupported major version
    const fs::path p = copy("v2.h5");
    set_str_attr(p, "schema_version", "2.0.0");
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "major version 2")) << joined(problems);
    EXPECT_THROW(read_sinr_schedule(p.string()), InputError);
  }
  {  // the schedule reader checks what it returns
    const fs::path p = copy("schedrat.h5");
    poke_u64(p, "/transmissions/rat", 2, 0);
    try {
      read_sinr_schedule(p.string());
      ADD_FAILURE() << "read_sinr_schedule accepted RAT none";
    } catch (const InputError& e) {
      EXPECT_EQ(e.element(), "/transmissions/rat");
    }
    EXPECT_TRUE(mentions(validate_dataset(p.string()), "/transmissions/rat"));
  }
}

TEST(SinrFile, UnfinishedFileIsIncomplete) {
  const fs::path file = tmp_dir("unfinished") / "sinr.h5";
  write_test_file(file, /*finish=*/false);
  EXPECT_FALSE(has_attr(file, "complete"));
  const auto problems = validate_dataset(file.string());
  EXPECT_TRUE(mentions(problems, "complete")) << joined(problems);
  // What was written is there and readable.
  EXPECT_EQ(read_ds<double>(file, "/transmissions/start_s", H5T_NATIVE_DOUBLE).size(), 4u);
  EXPECT_EQ(read_ds<std::uint32_t>(file, "/receptions/rx", H5T_NATIVE_UINT32).size(), 4u);
  const auto info = dataset_info(file.string());
  EXPECT_EQ(info["complete"], false);
  EXPECT_EQ(info["nodes"], 0);
  EXPECT_EQ(info["receptions"], 4);
  EXPECT_TRUE(info["prr"].empty());
  EXPECT_NE(format_dataset_info(info).find("INCOMPLETE"), std::string::npos);
  try {
    read_sinr_schedule(file.string());
    ADD_FAILURE() << "read_sinr_schedule accepted an unfinished file";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), file.string());
    EXPECT_EQ(e.element(), "attribute complete");
  }
  EXPECT_THROW(read_sinr_schedule((file.parent_path() / "absent.h5").string()), InputError);
}

// Same records, same header -> byte-identical files.
TEST(SinrFile, DeterministicBytes) {
  const fs::path dir = tmp_dir("determinism");
  write_test_file(dir / "a.h5");
  write_test_file(dir / "b.h5");
  const std::string a = read_bytes(dir / "a.h5"), b = read_bytes(dir / "b.h5");
  ASSERT_FALSE(a.empty());
  EXPECT_EQ(a.size(), b.size());
  EXPECT_TRUE(a == b) << "files differ";
}

TEST(SinrFile, EmbeddedSchemaMatchesSourceFile) {
  const std::string on_disk = read_bytes(source_dir() / "schemas" / "raysweep_sinr.schema.json");
  EXPECT_EQ(sinr_schema_json(), on_disk);
  EXPECT_EQ(sinr_schema().at("schema_version"), kSinrSchemaVersion);
  EXPECT_EQ(sinr_schema().at("format"), kSinrFormat);
  // The code tables are the enums' values.
  const auto& rat = sinr_schema().at("codes").at("rat").at("values");
  EXPECT_EQ(rat.at("1"), "80211p");
  EXPECT_EQ(rat.at("2"), "nrv2x");
  EXPECT_EQ(sinr_schema().at("codes").at("message").at("values").at("1"), "cpm");
}
