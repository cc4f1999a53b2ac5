// SINR generator (VaN3Twin coexistence): PHY arithmetic against IEEE 802.11 /
// 3GPP hand computations, the ETSI CAM trigger on synthetic kinematics, NR-V2X
// Mode 2 SPS structure and statistics, 802.11p EDCA/CSMA invariants, a
// hand-computed three-node coexistence SINR, the decoding rule, and run_sinr end
// to end (file validity, RAT assignment, determinism across runs, threads and
// schedule reuse).
#include <gtest/gtest.h>

#if __has_include(<hdf5.h>)
#include <hdf5.h>
#else
#include <hdf5/serial/hdf5.h>  // Debian's serial HDF5 (the test target has no HDF5 include path)
#endif

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "generators/dataset_schema.hpp"
#include "generators/sinr/channel_models.hpp"
#include "generators/sinr/channel_trace.hpp"
#include "generators/sinr/coexistence.hpp"
#include "generators/sinr/messages.hpp"
#include "generators/sinr/outcomes.hpp"
#include "generators/sinr/phy.hpp"
#include "generators/sinr/schedule.hpp"
#include "generators/sinr/sinr_config.hpp"
#include "generators/sinr/sinr_file.hpp"
#include "generators/sinr/types.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using raysweep::test::read_text;
using raysweep::test::scratch_dir;

namespace {

constexpr double kFc = 5.9e9;
constexpr double kInfD = std::numeric_limits<double>::infinity();
constexpr double kUs = 1e-6;

double mw(double dbm) { return std::pow(10.0, dbm / 10.0); }
double to_dbm(double mw_) { return 10.0 * std::log10(mw_); }

NodeState at(std::uint32_t node, double x, double y, float vx = 0, float vy = 0, float heading = 0) {
  NodeState s;
  s.node = node;
  s.x = x, s.y = y, s.z = 0;
  s.vx = vx, s.vy = vy;
  s.heading_deg = heading;
  return s;
}

std::vector<NodeInfo> vehicles(std::size_t n) {
  std::vector<NodeInfo> v(n);
  for (std::size_t i = 0; i < n; ++i) {
    v[i].id = "veh" + std::to_string(i);
    v[i].kind = NodeKind::vehicle;
    v[i].vtype = "car";
  }
  return v;
}

// One frame at t = 0 with every node present (sample and hold: it is in force forever).
ChannelTrace static_trace(const std::vector<std::pair<double, double>>& xy) {
  FrameRecord f;
  f.time_s = 0;
  for (std::uint32_t i = 0; i < xy.size(); ++i) f.nodes.push_back(at(i, xy[i].first, xy[i].second));
  return ChannelTrace::from_records(vehicles(xy.size()), {f}, kFc, 10e6);
}

// Free-space-like gain -(40 + 20 log10 d) (d >= 1 m), no channel beyond `cutoff_m`.
double log_distance_gain(double d) { return -(40.0 + 20.0 * std::log10(std::max(d, 1.0))); }

// A channel model whose gains the test chooses: gain(a, b, d) with a < b.
class FakeChannel : public ChannelModel {
 public:
  using GainFn = std::function<double(std::uint32_t, std::uint32_t, double)>;
  FakeChannel(const ChannelTrace& trace, GainFn gain) : trace_(trace), gain_(std::move(gain)) {}
  LinkState link(std::size_t frame, std::uint32_t a, std::uint32_t b) const override {
    LinkState s;
    s.gain_db = -kInfD;
    s.los_class = 2;
    const NodeState* sa = trace_.state(frame, a);
    const NodeState* sb = trace_.state(frame, b);
    if (!sa || !sb || a == b) return s;
    const double d = std::sqrt((sa->x - sb->x) * (sa->x - sb->x) + (sa->y - sb->y) * (sa->y - sb->y) +
                               (sa->z - sb->z) * (sa->z - sb->z));
    s.distance_m = d;
    s.gain_db = gain_(std::min(a, b), std::max(a, b), d);
    s.los_class = 0;
    return s;
  }
  ChannelModelKind kind() const override { return ChannelModelKind::ray; }

 private:
  const ChannelTrace& trace_;
  GainFn gain_;
};

FakeChannel::GainFn distance_gain(double cutoff_m) {
  return [cutoff_m](std::uint32_t, std::uint32_t, double d) { return d > cutoff_m ? -kInfD : log_distance_gain(d); };
}

FakeChannel::GainFn constant_gain(double g) {
  return [g](std::uint32_t, std::uint32_t, double) { return g; };
}

// Tiny deterministic uniform generator for test inputs (LCG, platform independent).
struct Lcg {
  std::uint64_t s;
  double next() {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(s >> 11) * 0x1.0p-53;
  }
};

// Messages of every node at phase[node] + k * period, k = 0, 1, ... while < end, sorted by (t, node).
std::vector<GeneratedMessage> periodic_messages(const std::vector<double>& phase, double period, double end,
                                                std::uint32_t bytes) {
  std::vector<GeneratedMessage> out;
  for (std::uint32_t n = 0; n < phase.size(); ++n)
    for (std::uint64_t k = 0;; ++k) {
      const double t = phase[n] + static_cast<double>(k) * period;
      if (t >= end) break;
      out.push_back({t, n, Message::cam, bytes});
    }
  std::sort(out.begin(), out.end(), [](const GeneratedMessage& a, const GeneratedMessage& b) {
    return a.t != b.t ? a.t < b.t : a.node < b.node;
  });
  return out;
}

std::int64_t slot_index(double t, double slot) { return std::llround(t / slot); }

bool on_slot_boundary(double t, double slot) { return std::abs(t / slot - std::round(t / slot)) < 1e-6; }

// Attempt-0 transmissions of each node, in time order.
std::vector<std::vector<const Transmission*>> first_attempts_by_node(const Schedule& s, std::uint32_t nodes) {
  std::vector<std::vector<const Transmission*>> by(nodes);
  for (const auto& t : s.transmissions)
    if (t.attempt == 0) by[t.node].push_back(&t);
  for (auto& v : by)
    std::sort(v.begin(), v.end(), [](const Transmission* a, const Transmission* b) { return a->start_s < b->start_s; });
  return by;
}

// ---------------------------------------------------------------------------
// HDF5 column reading (receptions are only in the file).

template <class T>
std::vector<T> read_column(const fs::path& file, const std::string& dataset, hid_t mtype) {
  std::vector<T> v;
  const hid_t f = H5Fopen(file.string().c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) {
    ADD_FAILURE() << "cannot open " << file;
    return v;
  }
  const hid_t d = H5Dopen2(f, dataset.c_str(), H5P_DEFAULT);
  if (d < 0) {
    ADD_FAILURE() << "no dataset " << dataset << " in " << file;
    H5Fclose(f);
    return v;
  }
  const hid_t sp = H5Dget_space(d);
  const hssize_t n = H5Sget_simple_extent_npoints(sp);
  v.resize(static_cast<std::size_t>(n));
  if (n > 0 && H5Dread(d, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0)
    ADD_FAILURE() << "cannot read " << dataset;
  H5Sclose(sp);
  H5Dclose(d);
  H5Fclose(f);
  return v;
}

}  // namespace

// ===========================================================================
// 1. PHY arithmetic.

TEST(SinrPhy, WifiFrameDurationsByHand) {
  // PPDU = 32 us training + 8 us SIGNAL + 8 us x ceil((16 SERVICE + 8 bytes + 6 tail) / N_DBPS).
  struct Case {
    double rate;
    std::uint32_t bytes;
    double expected_us;
  };
  const Case cases[] = {
      {3e6, 300, 40 + 8 * 101},  // 2422 bits / 24 = 100.9 -> 101 symbols = 848 us
      {3e6, 100, 40 + 8 * 35},   // 822 / 24 = 34.25 -> 35
      {3e6, 0, 40 + 8 * 1},      // 22 bits -> 1 symbol
      {3e6, 3, 40 + 8 * 2},      // 46 bits <= 48 -> 2
      {3e6, 4, 40 + 8 * 3},      // 54 bits > 48 -> 3
      {6e6, 300, 40 + 8 * 51},   // 2422 / 48 = 50.46 -> 51 = 448 us
      {6e6, 100, 40 + 8 * 18},   // 822 / 48 = 17.1 -> 18
      {6e6, 9, 40 + 8 * 2},      // 94 bits <= 96 -> 2
      {6e6, 10, 40 + 8 * 3},     // 102 bits > 96 -> 3
      {12e6, 300, 40 + 8 * 26},  // 2422 / 96 = 25.2 -> 26
      {27e6, 1500, 40 + 8 * 56}, // 12022 / 216 = 55.66 -> 56
  };
  for (const auto& c : cases) {
    WifiPhy p;
    p.data_rate_bps = c.rate;
    EXPECT_NEAR(p.frame_duration_s(c.bytes), c.expected_us * kUs, 1e-12) << c.rate << " b/s, " << c.bytes << " B";
  }
  EXPECT_NEAR(WifiPhy{}.frame_duration_s(300), 848e-6, 1e-12);  // default rate is 3 Mb/s
}

TEST(SinrPhy, WifiDataBitsPerSymbolAndInvalidRates) {
  const std::pair<double, int> rates[] = {{3e6, 24},   {4.5e6, 36}, {6e6, 48},   {9e6, 72},
                                          {12e6, 96}, {18e6, 144}, {24e6, 192}, {27e6, 216}};
  for (auto [r, n] : rates) {
    WifiPhy p;
    p.data_rate_bps = r;
    EXPECT_EQ(p.data_bits_per_symbol(), n) << r;
    EXPECT_NO_THROW(p.check());
  }
  for (double bad : {5e6, 54e6, 0.0, 2.9e6, -3e6}) {
    WifiPhy p;
    p.data_rate_bps = bad;
    EXPECT_THROW(p.data_bits_per_symbol(), std::invalid_argument) << bad;
    EXPECT_THROW(p.frame_duration_s(300), std::invalid_argument) << bad;
    EXPECT_THROW(p.check(), std::invalid_argument) << bad;
  }
}

TEST(SinrPhy, WifiBandEdges) {
  WifiPhy p;
  EXPECT_DOUBLE_EQ(p.f_lo_hz(), 5.9e9 - 26 * 156.25e3);
  EXPECT_DOUBLE_EQ(p.f_hi_hz(), 5.9e9 + 26 * 156.25e3);
  EXPECT_NEAR(p.f_hi_hz() - p.f_lo_hz(), 8.125e6, 1e-3);
  EXPECT_EQ(p.resource_units(), 52);
  p.carrier_hz = 5.89e9;
  EXPECT_DOUBLE_EQ(p.f_lo_hz(), 5.89e9 - 4.0625e6);
}

TEST(SinrPhy, NrNumerologyAndResourceBlocks) {
  NrPhy p;  // numerology 2, 10 MHz
  EXPECT_DOUBLE_EQ(p.subcarrier_spacing_hz(), 60e3);
  EXPECT_DOUBLE_EQ(p.slot_s(), 0.25e-3);
  EXPECT_DOUBLE_EQ(p.rb_bandwidth_hz(), 720e3);
  EXPECT_EQ(p.rbs(), 11);
  EXPECT_EQ(p.subchannels(), 1);
  p.bandwidth_hz = 20e6;
  EXPECT_EQ(p.rbs(), 24);
  EXPECT_EQ(p.subchannels(), 2);
  p.bandwidth_hz = 40e6;
  EXPECT_EQ(p.rbs(), 51);
  EXPECT_EQ(p.subchannels(), 5);

  NrPhy p0;
  p0.numerology = 0;
  EXPECT_DOUBLE_EQ(p0.subcarrier_spacing_hz(), 15e3);
  EXPECT_DOUBLE_EQ(p0.slot_s(), 1e-3);
  EXPECT_EQ(p0.rbs(), 52);
  EXPECT_EQ(p0.subchannels(), 5);
  NrPhy p1;
  p1.numerology = 1;
  p1.bandwidth_hz = 20e6;
  EXPECT_DOUBLE_EQ(p1.subcarrier_spacing_hz(), 30e3);
  EXPECT_DOUBLE_EQ(p1.slot_s(), 0.5e-3);
  EXPECT_EQ(p1.rbs(), 51);
}

TEST(SinrPhy, NrBitsPerRbAndSubchannelsForPacket) {
  NrPhy p;  // MCS 14: Qm 4, R 553/1024; 10 data symbols
  EXPECT_DOUBLE_EQ(p.bits_per_rb(), 12.0 * 10 * 4 * 553 / 1024);  // 259.21875
  EXPECT_DOUBLE_EQ(p.bits_per_rb(), 259.21875);
  // 300 B: 2424 bits / 259.21875 = 9.35 -> 10 RBs -> 1 subchannel of 10.
  EXPECT_EQ(p.subchannels_for(300), 1);
  // 321 B: 2592 bits / 259.21875 = 9.9993 -> 10 RBs; 322 B: 2600 -> 10.03 -> 11 RBs -> 2 subchannels.
  EXPECT_EQ(p.subchannels_for(321), 1);
  EXPECT_EQ(p.subchannels_for(322), 2);
  // 800 B: 6424 / 259.21875 = 24.8 -> 25 RBs -> 3 subchannels.
  EXPECT_EQ(p.subchannels_for(800), 3);
  p.mcs = 0;  // Qm 2, R 120/1024
  EXPECT_DOUBLE_EQ(p.bits_per_rb(), 12.0 * 10 * 2 * 120 / 1024);  // 28.125
  EXPECT_EQ(p.subchannels_for(300), 9);  // 2424 / 28.125 = 86.2 -> 87 RBs -> 9 subchannels
  p.mcs = 28;  // Qm 6, R 948/1024
  EXPECT_DOUBLE_EQ(p.bits_per_rb(), 12.0 * 10 * 6 * 948 / 1024);
  p.mcs = 14;
  p.data_symbols = 12;
  EXPECT_DOUBLE_EQ(p.bits_per_rb(), 12.0 * 12 * 4 * 553 / 1024);
}

TEST(SinrPhy, NrSubchannelBands) {
  NrPhy p;
  p.bandwidth_hz = 20e6;  // 24 RBs of 720 kHz centred: grid [fc - 8.64 MHz, fc + 8.64 MHz)
  EXPECT_NEAR(p.f_lo_hz(0), 5.9e9 - 8.64e6, 1e-3);
  EXPECT_NEAR(p.f_hi_hz(0, 1), 5.9e9 - 1.44e6, 1e-3);
  EXPECT_NEAR(p.f_lo_hz(1), 5.9e9 - 1.44e6, 1e-3);
  EXPECT_NEAR(p.f_hi_hz(1, 1), 5.9e9 + 5.76e6, 1e-3);
  EXPECT_NEAR(p.f_hi_hz(0, 2), 5.9e9 + 5.76e6, 1e-3);
  NrPhy q;  // 10 MHz: 11 RBs, grid [fc - 3.96 MHz, fc + 3.96 MHz)
  EXPECT_NEAR(q.f_lo_hz(0), 5.9e9 - 3.96e6, 1e-3);
  EXPECT_NEAR(q.f_hi_hz(0, 1), 5.9e9 + 3.24e6, 1e-3);
}

TEST(SinrPhy, NrCheckRejectsUnsupportedSettings) {
  EXPECT_NO_THROW(NrPhy{}.check());
  auto bad = [](auto mutate) {
    NrPhy p;
    mutate(p);
    return p;
  };
  EXPECT_THROW(bad([](NrPhy& p) { p.subchannel_rbs = 20; }).check(), std::invalid_argument);  // 11 RBs < 20
  EXPECT_THROW(bad([](NrPhy& p) { p.numerology = 3; }).check(), std::invalid_argument);
  EXPECT_THROW(bad([](NrPhy& p) { p.numerology = -1; }).check(), std::invalid_argument);
  EXPECT_THROW(bad([](NrPhy& p) { p.bandwidth_hz = 5e6; }).check(), std::invalid_argument);  // N/A at 60 kHz
  EXPECT_THROW(bad([](NrPhy& p) { p.bandwidth_hz = 12e6; }).check(), std::invalid_argument);
  EXPECT_THROW(bad([](NrPhy& p) { p.mcs = 29; }).check(), std::invalid_argument);
  EXPECT_THROW(bad([](NrPhy& p) { p.mcs = -1; }).check(), std::invalid_argument);
  EXPECT_THROW(bad([](NrPhy& p) { p.data_symbols = 0; }).check(), std::invalid_argument);
  EXPECT_THROW(bad([](NrPhy& p) { p.data_symbols = 13; }).check(), std::invalid_argument);
  EXPECT_THROW(bad([](NrPhy& p) { p.subchannel_rbs = 9; }).check(), std::invalid_argument);
  EXPECT_NO_THROW(bad([](NrPhy& p) {
                    p.bandwidth_hz = 20e6;
                    p.subchannel_rbs = 20;
                  }).check());  // 24 RBs: one subchannel of 20
  EXPECT_NO_THROW(bad([](NrPhy& p) {
                    p.numerology = 0;
                    p.bandwidth_hz = 5e6;
                  }).check());  // 25 RBs at 15 kHz
}

TEST(SinrPhy, NoiseAndOverlap) {
  EXPECT_NEAR(noise_dbm(10e6, 9), -95.0, 1e-9);
  EXPECT_NEAR(noise_dbm(1.0, 0), -174.0, 1e-12);
  EXPECT_NEAR(noise_dbm(8.125e6, 9), -174 + 10 * std::log10(8.125e6) + 9, 1e-9);
  EXPECT_DOUBLE_EQ(overlap(0, 2, 1, 3), 1);
  EXPECT_DOUBLE_EQ(overlap(1, 3, 0, 2), 1);
  EXPECT_DOUBLE_EQ(overlap(0, 1, 1, 2), 0);  // touching
  EXPECT_DOUBLE_EQ(overlap(1, 2, 0, 1), 0);
  EXPECT_DOUBLE_EQ(overlap(0, 1, 2, 3), 0);  // disjoint
  EXPECT_DOUBLE_EQ(overlap(2, 3, 0, 1), 0);
  EXPECT_DOUBLE_EQ(overlap(0, 10, 2, 3), 1);  // contained
  EXPECT_DOUBLE_EQ(overlap(2, 3, 0, 10), 1);
  EXPECT_DOUBLE_EQ(overlap(0, 1, 0, 1), 1);
  EXPECT_DOUBLE_EQ(overlap(-1.5, 0.5, -0.5, 4), 1.0);
}

TEST(SinrPhy, RatNames) {
  EXPECT_STREQ(rat_name(Rat::none), "none");
  EXPECT_STREQ(rat_name(Rat::wifi80211p), "80211p");
  EXPECT_STREQ(rat_name(Rat::nr_v2x), "nrv2x");
  for (Rat r : {Rat::none, Rat::wifi80211p, Rat::nr_v2x}) EXPECT_EQ(parse_rat(rat_name(r)), r);
  EXPECT_THROW(parse_rat("lte"), std::invalid_argument);
  EXPECT_STREQ(message_name(Message::cam), "cam");
  EXPECT_STREQ(message_name(Message::cpm), "cpm");
}

TEST(SinrConfigCheck, DefaultsPassAndBadSettingsThrow) {
  EXPECT_NO_THROW(SinrConfig{}.check());
  auto throws = [](auto mutate) {
    SinrConfig c;
    mutate(c);
    try {
      c.check();
    } catch (const std::invalid_argument&) {
      return true;
    }
    return false;
  };
  EXPECT_TRUE(throws([](SinrConfig& c) { c.rats.nr_fraction = 1.5; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.rats.enabled = "wifi"; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.cam.t_gen_min_s = 0; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.cam.t_gen_max_s = 0.05; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.cam.check_period_s = 0.2; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.cam.n_gen_cam = 0; }));
  // 300 + 100 B = 3224 bits -> 13 RBs -> 2 subchannels, but 10 MHz has one.
  EXPECT_TRUE(throws([](SinrConfig& c) { c.cam.low_frequency_bytes = 100; }));
  EXPECT_FALSE(throws([](SinrConfig& c) {
    c.cam.low_frequency_bytes = 100;
    c.nr.bandwidth_hz = 20e6;
  }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.cpm.enabled = true; }));  // 800 B needs 3 subchannels
  EXPECT_TRUE(throws([](SinrConfig& c) { c.nr_mac.reservation_period_s = 0.0201; }));  // 80.4 slots
  EXPECT_FALSE(throws([](SinrConfig& c) { c.nr_mac.reservation_period_s = 0.0205; }));  // 82 slots
  EXPECT_TRUE(throws([](SinrConfig& c) { c.nr_mac.reservation_period_s = 0; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.nr_mac.retransmissions = 32; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.nr_mac.keep_probability = 1.1; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.nr_mac.min_candidate_ratio = 0; }));
  EXPECT_TRUE(throws([](SinrConfig& c) {
    c.nr_mac.t1_slots = 5;
    c.nr_mac.t2_slots = 5;
  }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.wifi_mac.access_category = "XX"; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.wifi.data_rate_bps = 5e6; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.nr.numerology = 3; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.wifi_bler = {{5, 0.5}, {5, 0.1}}; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.nr_bler = {{0, 1.5}}; }));
  EXPECT_FALSE(throws([](SinrConfig& c) { c.nr_bler = {{0, 1.0}, {10, 0.0}}; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.tx_power_dbm = kInfD; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.prr_range_m = 0; }));
  EXPECT_TRUE(throws([](SinrConfig& c) { c.max_receiver_distance_m = -1; }));
}

// ===========================================================================
// 2. CAM generation rules (EN 302 637-2 6.1.3).

namespace {

struct CamRun {
  std::vector<int> sent;        // check indices that generated a CAM
  std::vector<double> t_gen;    // T_GenCam after each CAM
  std::vector<bool> lf;         // low-frequency container in each CAM
};

// Checks at t = i * period for i = 0 .. checks-1 with kinematics k(i).
CamRun run_cam(const CamConfig& c, int checks, const std::function<Kinematics(int, double)>& k, double period = 0.1) {
  CamTrigger trig(c);
  CamRun r;
  for (int i = 0; i < checks; ++i) {
    const double t = i * period;
    Kinematics kin = k(i, t);
    kin.t = t;
    if (trig.check(kin)) {
      r.sent.push_back(i);
      r.t_gen.push_back(trig.t_gen_cam());
      r.lf.push_back(trig.low_frequency_due());
    }
  }
  return r;
}

std::vector<int> every(int step, int first, int last) {
  std::vector<int> v;
  for (int i = first; i <= last; i += step) v.push_back(i);
  return v;
}

}  // namespace

TEST(CamTrigger, StationaryVehicleSendsEverySecond) {
  const CamRun r = run_cam(CamConfig{}, 50, [](int, double) { return Kinematics{0, 10, 20, 0, 90}; });
  EXPECT_EQ(r.sent, every(10, 0, 49));  // t = 0, 1, 2, 3, 4 s
  for (double g : r.t_gen) EXPECT_DOUBLE_EQ(g, 1.0);
  for (bool lf : r.lf) EXPECT_TRUE(lf);  // 1 s >= 500 ms every time
}

TEST(CamTrigger, PositionChangeRule) {
  // 20 m/s: 2 m per check; 4 m at 0.2 s is not > 4 m, 6 m at 0.3 s is: every 300 ms.
  const CamRun r = run_cam(CamConfig{}, 50, [](int i, double) { return Kinematics{0, 2.0 * i, 0, 20, 90}; });
  EXPECT_EQ(r.sent, every(3, 0, 49));
  for (std::size_t k = 1; k < r.t_gen.size(); ++k) EXPECT_NEAR(r.t_gen[k], 0.3, 1e-9);
  // LF container at 0, then at 0.6 s (0.3 s is < 500 ms since), 1.2 s, ...
  for (std::size_t k = 0; k < r.lf.size(); ++k) EXPECT_EQ(r.lf[k], k % 2 == 0) << "CAM " << k;

  // 10 m/s: 4 m after 4 checks (not > 4 m), 5 m after 5: every 500 ms.
  const CamRun r10 = run_cam(CamConfig{}, 50, [](int i, double) { return Kinematics{0, 1.0 * i, 0, 10, 90}; });
  EXPECT_EQ(r10.sent, every(5, 0, 49));
  for (bool lf : r10.lf) EXPECT_TRUE(lf);  // 500 ms apart: due every time
}

TEST(CamTrigger, HeadingChangeRule) {
  // 5 deg per check at 1 m/s (0.1 m per check): every 100 ms.
  const CamRun r = run_cam(CamConfig{}, 30, [](int i, double) { return Kinematics{0, 0.1 * i, 0, 1, 5.0 * i}; });
  EXPECT_EQ(r.sent, every(1, 0, 29));
  for (std::size_t k = 1; k < r.t_gen.size(); ++k) EXPECT_NEAR(r.t_gen[k], 0.1, 1e-9);
  // LF container every 500 ms: CAMs 0, 5, 10, ...
  for (std::size_t k = 0; k < r.lf.size(); ++k) EXPECT_EQ(r.lf[k], k % 5 == 0) << "CAM " << k;

  // 2 deg per check across north (359, 1, 3, ...): the change wraps, so 2, 4 (not > 4), 6 deg: every 300 ms.
  const CamRun w = run_cam(CamConfig{}, 30, [](int i, double) {
    return Kinematics{0, 0, 0, 0, std::fmod(359.0 + 2.0 * i, 360.0)};
  });
  EXPECT_EQ(w.sent, every(3, 0, 29));
}

TEST(CamTrigger, SpeedChangeRule) {
  const CamRun r = run_cam(CamConfig{}, 30, [](int i, double) { return Kinematics{0, 0, 0, 10 + 0.6 * i, 0}; });
  EXPECT_EQ(r.sent, every(1, 0, 29));
  // 0.25 m/s per check: 0.25, 0.5 (not > 0.5), 0.75: every 300 ms.
  const CamRun s = run_cam(CamConfig{}, 30, [](int i, double) { return Kinematics{0, 0, 0, 10 + 0.25 * i, 0}; });
  EXPECT_EQ(s.sent, every(3, 0, 29));
}

TEST(CamTrigger, DynamicsNeedTGenCamMin) {
  // Checks every 50 ms, heading 5 deg per check: the dynamics rule may fire only
  // once T_GenCamMin = 100 ms has passed, so every other check.
  CamConfig c;
  c.check_period_s = 0.05;
  const CamRun r = run_cam(c, 40, [](int i, double) { return Kinematics{0, 0, 0, 1, 5.0 * i}; }, 0.05);
  EXPECT_EQ(r.sent, every(2, 0, 39));
}

TEST(CamTrigger, TGenCamHoldsForNGenCamThenReturnsToMax) {
  // Heading 5 deg per check until check 10, then constant: CAMs every 100 ms by
  // dynamics up to 10, then N_GenCam = 3 CAMs by time at T_GenCam = 100 ms (11,
  // 12, 13), then T_GenCam = T_GenCamMax: 23, 33, 43.
  const CamRun r = run_cam(CamConfig{}, 50, [](int i, double) {
    return Kinematics{0, 0, 0, 1, 5.0 * std::min(i, 10)};
  });
  std::vector<int> expected = every(1, 0, 13);
  for (int i : {23, 33, 43}) expected.push_back(i);
  EXPECT_EQ(r.sent, expected);
  ASSERT_EQ(r.t_gen.size(), expected.size());
  EXPECT_NEAR(r.t_gen[11], 0.1, 1e-9);  // after CAM at check 11 (1st by time)
  EXPECT_NEAR(r.t_gen[12], 0.1, 1e-9);  // 2nd
  EXPECT_DOUBLE_EQ(r.t_gen[13], 1.0);   // 3rd: back to T_GenCamMax
  EXPECT_DOUBLE_EQ(r.t_gen[14], 1.0);

  // 300 ms intervals (heading 1.5 deg per check) until check 9: CAMs 0, 3, 6, 9;
  // then 3 by time at 300 ms (12, 15, 18), then 1 s (28, 38, 48).
  const CamRun q = run_cam(CamConfig{}, 50, [](int i, double) {
    return Kinematics{0, 0, 0, 0, 1.5 * std::min(i, 9)};
  });
  EXPECT_EQ(q.sent, (std::vector<int>{0, 3, 6, 9, 12, 15, 18, 28, 38, 48}));
  std::vector<int> intervals;
  for (std::size_t k = 1; k < q.sent.size(); ++k) intervals.push_back(q.sent[k] - q.sent[k - 1]);
  EXPECT_EQ(intervals, (std::vector<int>{3, 3, 3, 3, 3, 3, 10, 10, 10}));

  // N_GenCam = 1: one CAM at the held interval, then T_GenCamMax.
  CamConfig one;
  one.n_gen_cam = 1;
  const CamRun o = run_cam(one, 50, [](int i, double) { return Kinematics{0, 0, 0, 0, 1.5 * std::min(i, 9)}; });
  EXPECT_EQ(o.sent, (std::vector<int>{0, 3, 6, 9, 12, 22, 32, 42}));
}

TEST(CamTrigger, LowFrequencyContainer) {
  CamTrigger t(CamConfig{});
  ASSERT_TRUE(t.check({0.0, 0, 0, 0, 5}));
  EXPECT_TRUE(t.low_frequency_due());  // first CAM
  // Heading changes of 10 deg every 100 ms: CAMs at 0.1 .. 0.4 without, 0.5 with.
  for (int i = 1; i <= 6; ++i) {
    ASSERT_TRUE(t.check({i * 0.1, 0, 0, 0, 5.0 + 10.0 * i})) << i;
    EXPECT_EQ(t.low_frequency_due(), i == 5) << i;
  }
}

namespace {

// Four nodes, 20 frames at 10 Hz: node 0 drives east at 20 m/s (2 m per frame),
// nodes 1..3 stand still; node 3 is absent from frames 3..6 (t in [0.3, 0.7)).
ChannelTrace cam_trace() {
  std::vector<FrameRecord> frames;
  for (int f = 0; f < 20; ++f) {
    FrameRecord fr;
    fr.time_s = f * 0.1;
    fr.nodes.push_back(at(0, 2.0 * f, 0, 20, 0, 90));
    fr.nodes.push_back(at(1, 0, 50, 0, 0, 0));
    fr.nodes.push_back(at(2, 0, 60, 0, 0, 0));
    if (f < 3 || f > 6) fr.nodes.push_back(at(3, 0, 70, 0, 0, 0));
    frames.push_back(fr);
  }
  return ChannelTrace::from_records(vehicles(4), frames, kFc, 10e6);
}

std::map<std::uint32_t, std::vector<GeneratedMessage>> by_node(const std::vector<GeneratedMessage>& m, Message kind) {
  std::map<std::uint32_t, std::vector<GeneratedMessage>> out;
  for (const auto& g : m)
    if (g.message == kind) out[g.node].push_back(g);
  return out;
}

}  // namespace

TEST(CamMessages, GenerateFromTrace) {
  const ChannelTrace tr = cam_trace();
  const std::vector<Rat> rats{Rat::nr_v2x, Rat::wifi80211p, Rat::none, Rat::wifi80211p};
  SinrConfig c;
  c.cam.low_frequency_bytes = 50;
  c.seed = 11;
  const auto msgs = generate_messages(tr, rats, c, 0.0, 2.0);
  // Sorted by (t, node), all within the window.
  for (std::size_t i = 1; i < msgs.size(); ++i)
    EXPECT_TRUE(msgs[i - 1].t < msgs[i].t || (msgs[i - 1].t == msgs[i].t && msgs[i - 1].node < msgs[i].node)) << i;
  for (const auto& m : msgs) {
    EXPECT_GE(m.t, 0.0);
    EXPECT_LT(m.t, 2.0);
    EXPECT_EQ(m.message, Message::cam);
  }
  auto per = by_node(msgs, Message::cam);
  EXPECT_EQ(per.count(2), 0u) << "a node with RAT none sends nothing";

  // Relative check indices of each node's CAMs (its phase is its first CAM time, in [0, 100 ms)).
  auto relative = [&](std::uint32_t n) {
    std::vector<int> idx;
    const double t0 = per[n].front().t;
    EXPECT_GE(t0, 0.0);
    EXPECT_LT(t0, 0.1);
    for (const auto& m : per[n]) {
      const double k = (m.t - t0) / 0.1;
      EXPECT_NEAR(k, std::round(k), 1e-6);
      idx.push_back(static_cast<int>(std::lround(k)));
    }
    return idx;
  };
  // Node 0: 2 m per frame -> every 3rd check; LF at 0, 0.6, 1.2, 1.8 s.
  EXPECT_EQ(relative(0), (std::vector<int>{0, 3, 6, 9, 12, 15, 18}));
  std::vector<std::uint32_t> bytes0;
  for (const auto& m : per[0]) bytes0.push_back(m.bytes);
  EXPECT_EQ(bytes0, (std::vector<std::uint32_t>{350, 300, 350, 300, 350, 300, 350}));
  // Node 1: stationary: 0 and 1 s.
  EXPECT_EQ(relative(1), (std::vector<int>{0, 10}));
  // Node 3: CAM at 0; absent at checks 3..6 (nothing sent, trigger restarts);
  // back at check 7 with a fresh trigger (immediate CAM), then 1 s later.
  EXPECT_EQ(relative(3), (std::vector<int>{0, 7, 17}));
  for (const auto& m : per[3]) EXPECT_EQ(m.bytes, 350u);  // first CAM of a trigger, then 1 s later: LF due
  for (const auto& m : per[3]) EXPECT_FALSE(m.t >= 0.3 && m.t < 0.7) << "sent while absent at " << m.t;

  // Phases differ between vehicles.
  const double p0 = per[0].front().t, p1 = per[1].front().t, p3 = per[3].front().t;
  EXPECT_GT(std::abs(p0 - p1), 1e-9);
  EXPECT_GT(std::abs(p0 - p3), 1e-9);
  EXPECT_GT(std::abs(p1 - p3), 1e-9);

  // Deterministic for a seed; another seed moves the phases.
  const auto again = generate_messages(tr, rats, c, 0.0, 2.0);
  ASSERT_EQ(again.size(), msgs.size());
  for (std::size_t i = 0; i < msgs.size(); ++i) {
    EXPECT_EQ(again[i].t, msgs[i].t);
    EXPECT_EQ(again[i].node, msgs[i].node);
    EXPECT_EQ(again[i].bytes, msgs[i].bytes);
  }
  SinrConfig c2 = c;
  c2.seed = 12;
  const auto other = by_node(generate_messages(tr, rats, c2, 0.0, 2.0), Message::cam);
  EXPECT_TRUE(other.at(0).front().t != p0 || other.at(1).front().t != p1 || other.at(3).front().t != p3);

  // A window [0.5, 1.5): node 0's trigger starts at frame 5 (first check -> CAM), then every 3rd.
  const auto win = by_node(generate_messages(tr, rats, c, 0.5, 1.5), Message::cam);
  ASSERT_TRUE(win.count(0));
  EXPECT_EQ(win.at(0).size(), 4u);  // frames 5, 8, 11, 14
  for (const auto& [n, v] : win)
    for (const auto& m : v) {
      EXPECT_GE(m.t, 0.5);
      EXPECT_LT(m.t, 1.5);
    }
}

TEST(CamMessages, PeriodicCpmsSkipAbsence) {
  const ChannelTrace tr = cam_trace();
  const std::vector<Rat> rats{Rat::nr_v2x, Rat::wifi80211p, Rat::none, Rat::wifi80211p};
  SinrConfig c;
  c.cam.enabled = false;
  c.cpm.enabled = true;
  c.cpm.period_s = 0.1;
  c.cpm.bytes = 200;
  const auto msgs = generate_messages(tr, rats, c, 0.0, 2.0);
  auto per = by_node(msgs, Message::cpm);
  EXPECT_EQ(by_node(msgs, Message::cam).size(), 0u);
  EXPECT_EQ(per[0].size(), 20u);
  EXPECT_EQ(per[1].size(), 20u);
  EXPECT_EQ(per.count(2), 0u);
  EXPECT_EQ(per[3].size(), 16u);  // absent for 4 of the 20 periods
  for (const auto& m : per[3]) EXPECT_FALSE(m.t >= 0.3 && m.t < 0.7);
  for (const auto& m : msgs) EXPECT_EQ(m.bytes, 200u);
}

TEST(CamMessages, HashUniformIsDeterministicAndUniform) {
  EXPECT_EQ(hash_uniform(1, 2, 3, 4), hash_uniform(1, 2, 3, 4));
  EXPECT_NE(hash_uniform(1, 2, 3, 4), hash_uniform(2, 2, 3, 4));
  double sum = 0;
  int below_quarter = 0;
  const int n = 100000;
  for (int i = 0; i < n; ++i) {
    const double u = hash_uniform(42, static_cast<std::uint64_t>(i));
    ASSERT_GE(u, 0.0);
    ASSERT_LT(u, 1.0);
    sum += u;
    below_quarter += u < 0.25;
  }
  EXPECT_NEAR(sum / n, 0.5, 0.005);              // sd of the mean 0.0009
  EXPECT_NEAR(below_quarter / double(n), 0.25, 0.006);  // sd 0.0014
}

// ===========================================================================
// 3. NR-V2X Mode 2 SPS.

TEST(NrSps, CounterRange) {
  EXPECT_EQ(sps_counter_range(0.02), (std::pair<int, int>{25, 75}));
  EXPECT_EQ(sps_counter_range(0.01), (std::pair<int, int>{25, 75}));  // max(20 ms, period)
  EXPECT_EQ(sps_counter_range(0.05), (std::pair<int, int>{10, 30}));
  EXPECT_EQ(sps_counter_range(0.1), (std::pair<int, int>{5, 15}));
  EXPECT_EQ(sps_counter_range(0.5), (std::pair<int, int>{5, 15}));
}

namespace {

struct SpsSetup {
  ChannelTrace trace;
  std::vector<Rat> rats;
};

// n NR vehicles 10 m apart on a line (all strongly coupled).
SpsSetup nr_line(std::uint32_t n) {
  std::vector<std::pair<double, double>> xy;
  for (std::uint32_t i = 0; i < n; ++i) xy.push_back({10.0 * i, 0});
  return {static_trace(xy), std::vector<Rat>(n, Rat::nr_v2x)};
}

std::vector<double> random_phases(std::uint32_t n, double period, std::uint64_t seed) {
  Lcg g{seed};
  std::vector<double> p;
  for (std::uint32_t i = 0; i < n; ++i) p.push_back(g.next() * period);
  return p;
}

}  // namespace

TEST(NrSps, TransmissionsOnSlotsWithinTheSelectionWindow) {
  auto [trace, rats] = nr_line(20);
  FakeChannel ch(trace, distance_gain(1e9));
  SinrConfig c;
  c.nr.bandwidth_hz = 20e6;
  const double slot = c.nr.slot_s();
  const auto msgs = periodic_messages(random_phases(20, 0.1, 3), 0.1, 10.0, 300);
  const Schedule s = schedule_transmissions(trace, ch, rats, msgs, c);
  EXPECT_EQ(s.packets, msgs.size());
  EXPECT_EQ(s.nr_dropped, 0u);
  ASSERT_EQ(s.transmissions.size(), msgs.size());  // one transmission per packet, no retransmissions
  ASSERT_EQ(s.gain_db.size(), s.transmissions.size() * 20);
  std::set<std::uint64_t> packets;
  double max_latency = 0;
  for (std::size_t i = 0; i < s.transmissions.size(); ++i) {
    const Transmission& t = s.transmissions[i];
    if (i > 0) {
      EXPECT_GE(t.start_s, s.transmissions[i - 1].start_s);
    }
    EXPECT_EQ(t.rat, Rat::nr_v2x);
    EXPECT_EQ(t.attempt, 0);
    EXPECT_TRUE(on_slot_boundary(t.start_s, slot)) << t.start_s;
    EXPECT_DOUBLE_EQ(t.duration_s, 0.25e-3);
    EXPECT_DOUBLE_EQ(t.power_dbm, 30.0);
    EXPECT_EQ(t.size_bytes, 300u);
    // One subchannel (300 B at MCS 14) of the 20 MHz grid: subchannel 0 or 1.
    const bool sub0 = std::abs(t.f_lo_hz - (kFc - 8.64e6)) < 1 && std::abs(t.f_hi_hz - (kFc - 1.44e6)) < 1;
    const bool sub1 = std::abs(t.f_lo_hz - (kFc - 1.44e6)) < 1 && std::abs(t.f_hi_hz - (kFc + 5.76e6)) < 1;
    EXPECT_TRUE(sub0 || sub1) << t.f_lo_hz << " " << t.f_hi_hz;
    ASSERT_LT(t.packet, msgs.size());
    EXPECT_TRUE(packets.insert(t.packet).second) << "packet " << t.packet << " twice";
    const GeneratedMessage& m = msgs[t.packet];
    EXPECT_EQ(m.node, t.node);
    const double latency = t.start_s - m.t;
    EXPECT_GT(latency, 0.0);
    // Selection window [n + T1, n + T2] with T2 = the 80-slot reservation period and
    // n the slot after the message: at most 81 slots (20.25 ms) after generation.
    EXPECT_LE(latency, 0.02 + slot + 1e-9);
    max_latency = std::max(max_latency, latency);
    // Gains stored per node: -inf to itself, the link's gain elsewhere.
    EXPECT_EQ(s.gain(i, t.node), -std::numeric_limits<float>::infinity());
    const std::uint32_t other = (t.node + 1) % 20;
    EXPECT_NEAR(s.gain(i, other), log_distance_gain(10.0 * std::abs(double(other) - double(t.node))), 1e-4);
  }
  RecordProperty("max_nr_latency_ms", std::to_string(max_latency * 1e3));
}

TEST(NrSps, PersistentGrantUsesEveryReservationOccasion) {
  // keep_probability 1: no reselection ever. With irregular message times (not
  // multiples of 20 ms), every transmission of a node lies on its grant's occasions
  // (a multiple of 80 slots from its first) on the same subchannels, and on the
  // first occasion usable after the message.
  auto [trace, rats] = nr_line(10);
  FakeChannel ch(trace, distance_gain(1e9));
  SinrConfig c;
  c.nr.bandwidth_hz = 20e6;
  c.nr_mac.keep_probability = 1.0;
  const double slot = c.nr.slot_s();
  std::vector<GeneratedMessage> msgs;
  Lcg g{99};
  for (std::uint32_t n = 0; n < 10; ++n)
    for (double t = g.next() * 0.1; t < 20.0; t += 0.05 + 0.1 * g.next()) msgs.push_back({t, n, Message::cam, 300});
  std::sort(msgs.begin(), msgs.end(), [](const GeneratedMessage& a, const GeneratedMessage& b) {
    return a.t != b.t ? a.t < b.t : a.node < b.node;
  });
  const Schedule s = schedule_transmissions(trace, ch, rats, msgs, c);
  ASSERT_EQ(s.transmissions.size(), msgs.size());
  const auto by = first_attempts_by_node(s, 10);
  for (std::uint32_t n = 0; n < 10; ++n) {
    ASSERT_GT(by[n].size(), 100u);
    const Transmission* first = by[n].front();
    for (const Transmission* t : by[n]) {
      const std::int64_t d = slot_index(t->start_s, slot) - slot_index(first->start_s, slot);
      EXPECT_EQ(d % 80, 0) << "node " << n << " at " << t->start_s;
      EXPECT_DOUBLE_EQ(t->f_lo_hz, first->f_lo_hz);
      EXPECT_DOUBLE_EQ(t->f_hi_hz, first->f_hi_hz);
      const double tm = msgs[t->packet].t;
      EXPECT_GT(t->start_s, tm);
      // The previous occasion was not usable: it began before the message (plus at most
      // the processing slots T1 + the slot in progress).
      EXPECT_LT(t->start_s - 0.02, tm + 2 * slot + 1e-9);
    }
  }
}

TEST(NrSps, GrantLifetimeMatchesCounterRange) {
  // keep_probability 0, counter C uniform in [25, 75] decremented at every 20 ms
  // occasion (used or not); one message per node every 100 ms = every 5th occasion.
  // The grant serves message k (occasion 5k) while 5k <= C - 1, i.e.
  // floor((C - 1) / 5) + 1 messages: 5 for C = 25, 6 for C = 26..30, ..., 15 for
  // C = 71..75; mean (5 + 5 (6 + ... + 15)) / 51 = 530 / 51 = 10.39 messages = 1.04 s
  // (the mean counter is 50 occasions = 1 s).
  // A reselection is visible unless it lands on the same slot phase and subchannel
  // (1 of 80 x 2 candidates), which merges two grants: 10.39 / (1 - 1/160).
  const std::uint32_t n = 20;
  auto [trace, rats] = nr_line(n);
  FakeChannel ch(trace, distance_gain(1e9));
  SinrConfig c;
  c.nr.bandwidth_hz = 20e6;
  const double slot = c.nr.slot_s();
  const auto msgs = periodic_messages(random_phases(n, 0.1, 5), 0.1, 60.0, 300);
  const Schedule s = schedule_transmissions(trace, ch, rats, msgs, c);
  ASSERT_EQ(s.transmissions.size(), msgs.size());
  const auto by = first_attempts_by_node(s, n);
  std::vector<int> lengths;  // messages per grant; the last grant of each node is cut by the end: not counted
  for (std::uint32_t v = 0; v < n; ++v) {
    int run = 1;
    for (std::size_t k = 1; k < by[v].size(); ++k) {
      const std::int64_t gap = slot_index(by[v][k]->start_s, slot) - slot_index(by[v][k - 1]->start_s, slot);
      if (gap == 400 && by[v][k]->f_lo_hz == by[v][k - 1]->f_lo_hz) {
        ++run;
        continue;
      }
      // Within a grant transmissions are exactly 5 periods apart; a new grant moves by < 80 slots.
      EXPECT_GT(gap, 400 - 80);
      EXPECT_LT(gap, 400 + 80);
      lengths.push_back(run);
      run = 1;
    }
  }
  ASSERT_GT(lengths.size(), 800u);
  double mean = 0;
  for (int l : lengths) mean += l;
  mean /= static_cast<double>(lengths.size());
  const double expected = (530.0 / 51.0) / (1.0 - 1.0 / 160.0);
  EXPECT_NEAR(mean, expected, 0.06 * expected) << lengths.size() << " grants";
  EXPECT_NEAR(mean * 0.1, 1.0, 0.15) << "mean grant lifetime (s)";
  // A counter of at least 25 occasions serves messages 0..4 at least; at most 75 -> 15
  // messages (longer only when two grants merged).
  for (int l : lengths) EXPECT_GE(l, 5);
  // Mean latency: the first occasion is uniform over slots n+1 .. n+80 after the slot
  // n following the message: E = (1 + 40.5) slots - half a slot = 10.25 ms.
  EXPECT_NEAR(s.nr_mean_latency_s, 41.0 * slot - 0.5 * slot, 1e-3);
}

TEST(NrSps, BlindRetransmissions) {
  const std::uint32_t n = 10;
  auto [trace, rats] = nr_line(n);
  FakeChannel ch(trace, distance_gain(1e9));
  for (int retx : {1, 2}) {
    SinrConfig c;
    c.nr.bandwidth_hz = 20e6;
    c.nr_mac.retransmissions = retx;
    const double slot = c.nr.slot_s();
    const auto msgs = periodic_messages(random_phases(n, 0.1, 8), 0.1, 10.0, 300);
    const Schedule s = schedule_transmissions(trace, ch, rats, msgs, c);
    ASSERT_EQ(s.transmissions.size(), msgs.size() * (retx + 1)) << retx;
    // Sorted by (start, node, packet, attempt).
    for (std::size_t i = 1; i < s.transmissions.size(); ++i) {
      const auto& a = s.transmissions[i - 1];
      const auto& b = s.transmissions[i];
      EXPECT_TRUE(std::tie(a.start_s, a.node, a.packet, a.attempt) < std::tie(b.start_s, b.node, b.packet, b.attempt))
          << i;
    }
    std::map<std::uint64_t, std::vector<const Transmission*>> per_packet;
    for (const auto& t : s.transmissions) per_packet[t.packet].push_back(&t);
    ASSERT_EQ(per_packet.size(), msgs.size());
    for (auto& [p, v] : per_packet) {
      ASSERT_EQ(v.size(), static_cast<std::size_t>(retx + 1));
      std::sort(v.begin(), v.end(), [](auto* a, auto* b) { return a->attempt < b->attempt; });
      const Transmission& first = *v[0];
      EXPECT_EQ(first.attempt, 0);
      std::int64_t prev = slot_index(first.start_s, slot);
      for (int k = 1; k <= retx; ++k) {
        const Transmission& r = *v[k];
        EXPECT_EQ(r.attempt, k);
        EXPECT_EQ(r.node, first.node);
        EXPECT_EQ(r.size_bytes, first.size_bytes);
        EXPECT_DOUBLE_EQ(r.f_lo_hz, first.f_lo_hz);
        EXPECT_DOUBLE_EQ(r.f_hi_hz, first.f_hi_hz);
        EXPECT_TRUE(on_slot_boundary(r.start_s, slot));
        EXPECT_DOUBLE_EQ(r.duration_s, slot);
        const std::int64_t sl = slot_index(r.start_s, slot);
        EXPECT_GT(sl, prev) << "attempts in time order, distinct slots";
        EXPECT_LE(sl - slot_index(first.start_s, slot), 31) << "within 32 slots of the first";
        prev = sl;
      }
    }
  }
}

TEST(NrSps, OversizedPacketsAreDroppedAndLargerPacketsReselect) {
  // 20 MHz: two subchannels. keep_probability 1: the grant would never end by itself.
  // Messages every 100 ms: 300 B (1 subchannel) except a 400 B one (2 subchannels,
  // does not fit the grant: reselection) and an 800 B one (3 > 2: dropped).
  auto [trace, rats] = nr_line(1);
  FakeChannel ch(trace, distance_gain(1e9));
  SinrConfig c;
  c.nr.bandwidth_hz = 20e6;
  c.nr_mac.keep_probability = 1.0;
  const double slot = c.nr.slot_s();
  std::vector<GeneratedMessage> msgs;
  for (int k = 0; k < 10; ++k)
    msgs.push_back({0.0101 + 0.1 * k, 0, Message::cam, k == 3 ? 400u : k == 6 ? 800u : 300u});
  const Schedule s = schedule_transmissions(trace, ch, rats, msgs, c);
  EXPECT_EQ(s.packets, 10u);
  EXPECT_EQ(s.nr_dropped, 1u);
  ASSERT_EQ(s.transmissions.size(), 9u);
  std::map<std::uint64_t, const Transmission*> by_packet;
  for (const auto& t : s.transmissions) by_packet[t.packet] = &t;
  EXPECT_EQ(by_packet.count(6), 0u) << "the 800 B packet needs 3 of 2 subchannels";
  const double sub = 10 * 720e3;
  for (std::uint64_t k : {0, 1, 2}) EXPECT_NEAR(by_packet[k]->f_hi_hz - by_packet[k]->f_lo_hz, sub, 1e-3);
  for (std::uint64_t k : {3, 4, 5, 7, 8, 9}) {
    // The grant selected for the 400 B packet has 2 subchannels (the whole 20 MHz grid)
    // and carries the later, smaller packets too.
    EXPECT_NEAR(by_packet[k]->f_lo_hz, kFc - 8.64e6, 1e-3) << k;
    EXPECT_NEAR(by_packet[k]->f_hi_hz, kFc + 5.76e6, 1e-3) << k;
  }
  auto gap = [&](std::uint64_t a, std::uint64_t b) {
    return slot_index(by_packet[b]->start_s, slot) - slot_index(by_packet[a]->start_s, slot);
  };
  EXPECT_EQ(gap(0, 1), 400);
  EXPECT_EQ(gap(1, 2), 400);
  EXPECT_EQ(gap(3, 4), 400);
  EXPECT_EQ(gap(4, 5), 400);
  EXPECT_EQ(gap(5, 7), 800);  // the dropped packet's occasions pass unused
  EXPECT_EQ(gap(7, 8), 400);
  EXPECT_EQ(gap(8, 9), 400);
}

namespace {

// `pairs` pairs of NR vehicles 10 m apart, pairs 100 km apart (no channel between
// pairs). Node 2p sends at phase a_p + 0.1 k, node 2p + 1 at a_p + offset + 0.1 k.
struct SensingResult {
  int selections = 0;  // visible new grants
  int checked = 0;     // selections with an announced, continuing partner reservation
  int violations = 0;  // ... that took that reservation's slot phase
  int collisions = 0;  // same-slot transmissions of a pair
};

SensingResult sensing_run(bool sensing, double offset_s, std::uint32_t pairs, double seconds) {
  std::vector<std::pair<double, double>> xy;
  std::vector<double> phase;
  for (std::uint32_t p = 0; p < pairs; ++p) {
    xy.push_back({1e5 * p, 0});
    xy.push_back({1e5 * p + 10, 0});
    const double a = 0.00013 + 0.0011 * p;
    phase.push_back(a);
    phase.push_back(a + offset_s);
  }
  const ChannelTrace trace = static_trace(xy);
  FakeChannel ch(trace, distance_gain(1000));
  SinrConfig c;  // 10 MHz: one subchannel, 80 candidate slots per window
  c.nr_mac.sensing = sensing;
  const double slot = c.nr.slot_s();
  const auto msgs = periodic_messages(phase, 0.1, seconds, 300);
  const Schedule s =
      schedule_transmissions(trace, ch, std::vector<Rat>(xy.size(), Rat::nr_v2x), msgs, c);
  EXPECT_EQ(s.transmissions.size(), msgs.size());
  const auto by = first_attempts_by_node(s, static_cast<std::uint32_t>(xy.size()));
  SensingResult r;
  for (std::uint32_t x = 0; x < xy.size(); ++x) {
    const auto& mine = by[x];
    const auto& other = by[x ^ 1u];
    for (std::size_t k = 0; k < mine.size(); ++k) {
      const std::int64_t sx = slot_index(mine[k]->start_s, slot);
      if (k > 0 && sx - slot_index(mine[k - 1]->start_s, slot) == 400) continue;  // grant continues
      ++r.selections;
      const double tx_msg = msgs[mine[k]->packet].t;
      // The partner's last transmission heard before this message (its SCI announces
      // the reservation), within the 1 s sensing window...
      auto it = std::upper_bound(other.begin(), other.end(), tx_msg,
                                 [](double t, const Transmission* o) { return t < o->start_s; });
      if (it == other.begin()) continue;
      const Transmission* heard = *(it - 1);
      if (tx_msg - heard->start_s > 1.0) continue;
      // ... and the partner kept that reservation afterwards.
      if (it == other.end() || slot_index((*it)->start_s, slot) - slot_index(heard->start_s, slot) != 400) continue;
      ++r.checked;
      const std::int64_t d = sx - slot_index(heard->start_s, slot);
      if (((d % 80) + 80) % 80 == 0) ++r.violations;
    }
  }
  for (std::uint32_t p = 0; p < pairs; ++p) {
    std::set<std::int64_t> slots_a;
    for (const auto* t : by[2 * p]) slots_a.insert(slot_index(t->start_s, slot));
    for (const auto* t : by[2 * p + 1]) r.collisions += slots_a.count(slot_index(t->start_s, slot)) ? 1 : 0;
  }
  return r;
}

}  // namespace

TEST(NrSps, SensingExcludesAnnouncedReservations) {
  // Partners 50 ms apart: each one's last transmission precedes the other's message.
  const SensingResult random = sensing_run(false, 0.050, 10, 120.0);
  const SensingResult sensed = sensing_run(true, 0.050, 10, 120.0);
  RecordProperty("random_violations", random.violations);
  RecordProperty("sensing_violations", sensed.violations);
  ASSERT_GT(random.checked, 1000);
  ASSERT_GT(sensed.checked, 1000);
  // Random selection lands on the partner's phase about 1 in 80 times.
  EXPECT_GE(random.violations, 5) << random.checked << " checked";
  EXPECT_EQ(sensed.violations, 0) << sensed.checked << " checked";
}

TEST(NrSps, SensingUsesReservationsAnnouncedBeforeANewerTransmission) {
  // Partners 1 ms apart: when the later one selects, the earlier one usually has
  // already scheduled (but not yet sent) this round's transmission on the same
  // grant. The reservation was announced by its previous transmission 100 ms earlier
  // (inside the 1 s sensing window), so it must still be excluded.
  const SensingResult random = sensing_run(false, 0.001, 10, 120.0);
  const SensingResult sensed = sensing_run(true, 0.001, 10, 120.0);
  RecordProperty("random_violations", random.violations);
  RecordProperty("sensing_violations", sensed.violations);
  RecordProperty("random_collisions", random.collisions);
  RecordProperty("sensing_collisions", sensed.collisions);
  ASSERT_GT(random.checked, 1000);
  ASSERT_GT(sensed.checked, 1000);
  EXPECT_GE(random.violations, 5);
  EXPECT_LT(sensed.collisions, random.collisions) << "sensing should collide less than random selection";
  EXPECT_EQ(sensed.violations, 0) << sensed.checked << " selections checked; random selection had "
                                  << random.violations;
}

// ===========================================================================
// 4. IEEE 802.11p EDCA / CSMA.

TEST(WifiCsma, EdcaParameters) {
  auto eq = [](EdcaParams p, int a, int lo, int hi) { return p.aifsn == a && p.cw_min == lo && p.cw_max == hi; };
  EXPECT_TRUE(eq(edca_params("BK"), 9, 15, 1023));
  EXPECT_TRUE(eq(edca_params("BE"), 6, 15, 1023));
  EXPECT_TRUE(eq(edca_params("VI"), 3, 7, 15));
  EXPECT_TRUE(eq(edca_params("VO"), 2, 3, 7));
  EXPECT_THROW(edca_params("AC_BE"), std::invalid_argument);
  EXPECT_THROW(edca_params(""), std::invalid_argument);
}

namespace {

constexpr double kAifsBe = 32e-6 + 6 * 13e-6;  // SIFS + AIFSN x slot = 110 us

void check_wifi_tx_basics(const Schedule& s, const std::vector<GeneratedMessage>& msgs, const SinrConfig& c) {
  for (const auto& t : s.transmissions) {
    ASSERT_EQ(t.rat, Rat::wifi80211p);
    ASSERT_LT(t.packet, msgs.size());
    const auto& m = msgs[t.packet];
    EXPECT_EQ(m.node, t.node);
    EXPECT_EQ(t.size_bytes, m.bytes);
    EXPECT_EQ(t.attempt, 0);
    EXPECT_GE(t.start_s, m.t);
    EXPECT_DOUBLE_EQ(t.duration_s, c.wifi.frame_duration_s(t.size_bytes));
    EXPECT_DOUBLE_EQ(t.f_lo_hz, kFc - 4.0625e6);
    EXPECT_DOUBLE_EQ(t.f_hi_hz, kFc + 4.0625e6);
    EXPECT_DOUBLE_EQ(t.power_dbm, c.tx_power_dbm);
  }
}

}  // namespace

namespace {

// A FakeChannel that, on every query, allocates (and keeps) one heap block of each
// small size class filled with `fill` bytes (0x00: 0 dB as float; 0xFF: NaN). A
// correct simulator never notices; one that keeps pointers into a buffer it has
// since reallocated reads those bytes as gains (the allocator hands the freed block
// out again), which makes such a use-after-free fail deterministically.
class HeapFillingChannel : public FakeChannel {
 public:
  HeapFillingChannel(const ChannelTrace& trace, GainFn gain, unsigned char fill)
      : FakeChannel(trace, std::move(gain)), fill_(fill) {}
  ~HeapFillingChannel() override {
    for (void* p : pool_) std::free(p);
  }
  LinkState link(std::size_t frame, std::uint32_t a, std::uint32_t b) const override {
    {
      std::lock_guard<std::mutex> lock(m_);
      // The first queries suffice (the scenarios reallocate early); bounds the memory kept.
      for (std::size_t sz = 24; sz <= 1032 && pool_.size() < 64 * 400; sz += 16) {
        void* p = std::malloc(sz);
        std::memset(p, fill_, sz);
        pool_.push_back(p);
      }
    }
    return FakeChannel::link(frame, a, b);
  }

 private:
  unsigned char fill_;
  mutable std::mutex m_;
  mutable std::vector<void*> pool_;
};

}  // namespace

TEST(WifiCsma, StationsThatHearEachOtherDoNotOverlap) {
  // 8 stations within 70 m: every frame is received at >= -77 dBm > -85 dBm CCA.
  const std::uint32_t n = 8;
  std::vector<std::pair<double, double>> xy;
  for (std::uint32_t i = 0; i < n; ++i) xy.push_back({10.0 * i, 0});
  const ChannelTrace trace = static_trace(xy);
  FakeChannel ch(trace, distance_gain(1e9));
  SinrConfig c;
  // Clustered phases (0.3 ms apart, frames 848 us) and a burst at 0.5 s force contention.
  std::vector<double> phase;
  for (std::uint32_t i = 0; i < n; ++i) phase.push_back(0.0003 * i + 0.00001);
  auto msgs = periodic_messages(phase, 0.1, 5.0, 300);
  for (std::uint32_t i = 0; i < n; ++i) msgs.push_back({0.55, i, Message::cam, 100});
  std::sort(msgs.begin(), msgs.end(), [](const GeneratedMessage& a, const GeneratedMessage& b) {
    return a.t != b.t ? a.t < b.t : a.node < b.node;
  });
  const Schedule s = schedule_transmissions(trace, ch, std::vector<Rat>(n, Rat::wifi80211p), msgs, c);
  check_wifi_tx_basics(s, msgs, c);
  // Every message is sent once or replaced in the queue by a newer one.
  EXPECT_EQ(s.transmissions.size() + s.wifi_dropped, msgs.size());
  std::set<std::uint64_t> seen;
  for (const auto& t : s.transmissions) EXPECT_TRUE(seen.insert(t.packet).second);
  int deferred = 0, collisions = 0;
  const auto& tx = s.transmissions;
  for (std::size_t i = 0; i < tx.size(); ++i) {
    deferred += tx[i].start_s > msgs[tx[i].packet].t;
    for (std::size_t j = i + 1; j < tx.size() && tx[j].start_s < tx[i].end_s(); ++j) {
      // Overlap in time: only frames started within the CCA delay (8 us) of each other.
      EXPECT_NE(tx[i].node, tx[j].node) << "a station's own frames overlap";
      EXPECT_LE(tx[j].start_s - tx[i].start_s, 8e-6 + 1e-12)
          << "nodes " << tx[i].node << ", " << tx[j].node << " at " << tx[i].start_s << ", " << tx[j].start_s;
      ++collisions;
    }
  }
  // The medium was idle for at least AIFS before every frame (other stations' frames).
  for (std::size_t i = 0; i < tx.size(); ++i)
    for (std::size_t j = 0; j < tx.size(); ++j) {
      if (tx[j].node == tx[i].node || tx[j].end_s() > tx[i].start_s) continue;
      if (tx[i].start_s - tx[j].end_s() > 0.01) continue;
      EXPECT_GE(tx[i].start_s - tx[j].end_s(), kAifsBe - 1e-12) << "frame " << i << " after frame " << j;
    }
  EXPECT_GT(deferred, 20) << "the scenario should make stations defer";
  RecordProperty("collisions", collisions);
}

TEST(WifiCsma, HiddenStationsSendAtGenerationTime) {
  // Gains -130 dB: frames arrive at -100 dBm (< -85 preamble CCA) and at most 5 of
  // them add up to -93 dBm (< -65 energy CCA): nobody defers. (The channel refills
  // freed heap blocks with zeros, so gains read through a dangling pointer would be
  // 0 dB and make stations defer deterministically.)
  for (double g : {-130.0, -kInfD}) {
    const std::uint32_t n = 6;
    std::vector<std::pair<double, double>> xy;
    for (std::uint32_t i = 0; i < n; ++i) xy.push_back({1000.0 * i, 0});
    const ChannelTrace trace = static_trace(xy);
    HeapFillingChannel ch(trace, constant_gain(g), 0x00);
    SinrConfig c;
    std::vector<double> phase;
    for (std::uint32_t i = 0; i < n; ++i) phase.push_back(0.0002 * i + 0.00003);
    const auto msgs = periodic_messages(phase, 0.1, 3.0, 300);
    const Schedule s = schedule_transmissions(trace, ch, std::vector<Rat>(n, Rat::wifi80211p), msgs, c);
    check_wifi_tx_basics(s, msgs, c);
    ASSERT_EQ(s.transmissions.size(), msgs.size()) << g;
    EXPECT_EQ(s.wifi_dropped, 0u);
    for (const auto& t : s.transmissions) EXPECT_EQ(t.start_s, msgs[t.packet].t) << "node " << t.node << " gain " << g;
    EXPECT_EQ(s.wifi_mean_latency_s, 0.0);
  }
}

TEST(WifiCsma, PreambleDetectionThreshold) {
  // Station 1 gets a message 200 us into station 0's 848 us frame.
  for (double g : {-110.0, -118.0}) {  // received at -80 dBm (>= -85: busy) / -88 dBm (idle)
    const ChannelTrace trace = static_trace({{0, 0}, {100, 0}});
    FakeChannel ch(trace, constant_gain(g));
    SinrConfig c;
    const std::vector<GeneratedMessage> msgs{{0.010, 0, Message::cam, 300}, {0.0102, 1, Message::cam, 300}};
    const Schedule s = schedule_transmissions(trace, ch, {Rat::wifi80211p, Rat::wifi80211p}, msgs, c);
    ASSERT_EQ(s.transmissions.size(), 2u);
    const Transmission& a = s.transmissions[0];
    const Transmission& b = s.transmissions[1];
    EXPECT_EQ(a.start_s, 0.010);
    if (g == -110.0) {
      const double backoff = (b.start_s - a.end_s() - kAifsBe) / 13e-6;
      EXPECT_GE(backoff, -1e-6) << "deferred until the frame ends + AIFS";
      EXPECT_LE(backoff, 15 + 1e-6) << "CWmin 15";
      EXPECT_NEAR(backoff, std::round(backoff), 1e-6) << "whole backoff slots";
    } else {
      EXPECT_EQ(b.start_s, 0.0102);
    }
  }
}

TEST(WifiCsma, AccessCategoryTimingAndQueueReplacement) {
  // Station 0 sends a 1500 B frame (40 + 8 x ceil(12022 / 24) = 4048 us); station 1,
  // 10 m away, gets two messages while it is on air: the newer replaces the older in
  // the queue (dropped), and goes out after the frame + AIFS + backoff of the category.
  struct Ac {
    const char* name;
    double aifs;
    int cw;
  };
  for (const Ac& ac : {Ac{"BE", 32e-6 + 6 * 13e-6, 15}, Ac{"VO", 32e-6 + 2 * 13e-6, 3}, Ac{"BK", 32e-6 + 9 * 13e-6, 15}}) {
    const ChannelTrace trace = static_trace({{0, 0}, {10, 0}});
    FakeChannel ch(trace, distance_gain(1e9));
    SinrConfig c;
    c.wifi_mac.access_category = ac.name;
    const std::vector<GeneratedMessage> msgs{
        {0.010, 0, Message::cam, 1500}, {0.0101, 1, Message::cam, 300}, {0.0102, 1, Message::cpm, 200}};
    const Schedule s = schedule_transmissions(trace, ch, {Rat::wifi80211p, Rat::wifi80211p}, msgs, c);
    EXPECT_EQ(s.wifi_dropped, 1u) << ac.name;
    ASSERT_EQ(s.transmissions.size(), 2u) << ac.name;
    const Transmission& a = s.transmissions[0];
    const Transmission& b = s.transmissions[1];
    EXPECT_EQ(a.node, 0u);
    EXPECT_NEAR(a.duration_s, 4048e-6, 1e-12);
    EXPECT_EQ(b.node, 1u);
    EXPECT_EQ(b.packet, 2u) << "the newer message is sent";
    EXPECT_EQ(b.message, Message::cpm);
    EXPECT_EQ(b.size_bytes, 200u);
    const double backoff = (b.start_s - a.end_s() - ac.aifs) / 13e-6;
    EXPECT_GE(backoff, -1e-6) << ac.name;
    EXPECT_LE(backoff, ac.cw + 1e-6) << ac.name;
    EXPECT_NEAR(backoff, std::round(backoff), 1e-6) << ac.name;
    // Mean latency over the two frames: (0 + (b.start - 10.2 ms)) / 2.
    EXPECT_NEAR(s.wifi_mean_latency_s, (b.start_s - 0.0102) / 2, 1e-12);
  }
}

TEST(WifiCsma, EnergyDetectionOfNrCountsOnlyTheInBandShare) {
  // An NR transmission on one 7.2 MHz subchannel of a 20 MHz carrier overlaps the
  // 8.125 MHz 802.11p band only partly; energy detection (-65 dBm) sees P_rx x share.
  SinrConfig c;
  c.nr.bandwidth_hz = 20e6;
  const ChannelTrace trace = static_trace({{0, 0}, {30, 0}});
  const std::vector<Rat> rats{Rat::nr_v2x, Rat::wifi80211p};
  const GeneratedMessage nr_msg{0.010, 0, Message::cam, 300};
  FakeChannel probe(trace, constant_gain(-90));
  const Schedule alone = schedule_transmissions(trace, probe, rats, {nr_msg}, c);
  ASSERT_EQ(alone.transmissions.size(), 1u);
  const Transmission nr = alone.transmissions[0];
  const double share = overlap(nr.f_lo_hz, nr.f_hi_hz, kFc - 4.0625e6, kFc + 4.0625e6) / (nr.f_hi_hz - nr.f_lo_hz);
  ASSERT_GT(share, 0.3);
  ASSERT_LT(share, 0.8);  // either subchannel overlaps the 802.11p band partly (0.364 or 0.764)
  const double g_edge = -65.0 - 30.0 - 10 * std::log10(share);  // gain that puts the in-band share at -65 dBm
  for (double delta : {+1.0, -1.0}) {
    FakeChannel ch(trace, constant_gain(g_edge + delta));
    const std::vector<GeneratedMessage> msgs{nr_msg, {nr.start_s + 100e-6, 1, Message::cam, 300}};
    const Schedule s = schedule_transmissions(trace, ch, rats, msgs, c);
    ASSERT_EQ(s.transmissions.size(), 2u);
    const Transmission* w = nullptr;
    for (const auto& t : s.transmissions)
      if (t.rat == Rat::wifi80211p) w = &t;
    ASSERT_NE(w, nullptr);
    // The NR schedule does not depend on 802.11p.
    for (const auto& t : s.transmissions) {
      if (t.rat == Rat::nr_v2x) {
        EXPECT_EQ(t.start_s, nr.start_s);
      }
    }
    if (delta > 0) {  // in-band energy 1 dB above -65 dBm: busy until the NR slot ends
      const double backoff = (w->start_s - nr.end_s() - kAifsBe) / 13e-6;
      EXPECT_GE(backoff, -1e-6);
      EXPECT_LE(backoff, 15 + 1e-6);
      EXPECT_NEAR(backoff, std::round(backoff), 1e-6);
    } else {  // 1 dB below: idle (total received power is above -65 dBm, the in-band share is not)
      EXPECT_EQ(w->start_s, nr.start_s + 100e-6);
    }
  }
}

TEST(WifiCsma, MessageArrivingDuringOwnFrameIsSentAfterIt) {
  // A lone station gets a second message 200 us into its own 848 us frame. It must
  // queue it and send it after the frame (+ AIFS + backoff); nothing replaces it.
  const ChannelTrace trace = static_trace({{0, 0}});
  FakeChannel ch(trace, distance_gain(1e9));
  SinrConfig c;
  const std::vector<GeneratedMessage> msgs{{0.010, 0, Message::cam, 300}, {0.0102, 0, Message::cpm, 100}};
  const Schedule s = schedule_transmissions(trace, ch, {Rat::wifi80211p}, msgs, c);
  EXPECT_EQ(s.wifi_dropped, 0u);
  ASSERT_EQ(s.transmissions.size(), 2u) << "the second message was neither sent nor counted as dropped";
  const Transmission& a = s.transmissions[0];
  const Transmission& b = s.transmissions[1];
  EXPECT_EQ(a.start_s, 0.010);
  EXPECT_GE(b.start_s, a.end_s() + kAifsBe - 1e-12);
  EXPECT_LE(b.start_s, a.end_s() + kAifsBe + 15 * 13e-6 + 1e-12);
}


TEST(WifiCsma, StationKeepsDeferringWhileAHiddenStationTransmits) {
  // Station 0 sends a 848 us frame at 0; station 2, 10 m away, hears it at -30 dBm.
  // Station 1 is hidden from both (no channel) and sends short frames at 100 us
  // and 400 us, during station 0's frame. Station 2's message at 500 us must wait
  // for the end of station 0's frame + AIFS + backoff, whatever station 1 does.
  const ChannelTrace trace = static_trace({{0, 0}, {5000, 0}, {10, 0}});
  HeapFillingChannel ch(trace, distance_gain(1000), 0xFF);
  SinrConfig c;
  const std::vector<GeneratedMessage> msgs{{0.0, 0, Message::cam, 300},
                                           {0.0001, 1, Message::cam, 20},
                                           {0.0004, 1, Message::cam, 20},
                                           {0.0005, 2, Message::cam, 300}};
  const Schedule s = schedule_transmissions(trace, ch, std::vector<Rat>(3, Rat::wifi80211p), msgs, c);
  ASSERT_EQ(s.transmissions.size(), 4u);
  const Transmission* a = nullptr;
  const Transmission* cc = nullptr;
  for (const auto& t : s.transmissions) {
    if (t.node == 0) a = &t;
    if (t.node == 2) cc = &t;
  }
  ASSERT_TRUE(a && cc);
  EXPECT_EQ(a->start_s, 0.0);
  EXPECT_GE(cc->start_s, a->end_s() + kAifsBe - 1e-12)
      << "station 2 transmitted at " << cc->start_s * 1e6 << " us, inside station 0's frame [0, "
      << a->end_s() * 1e6 << ") us that it receives at -30 dBm";
  EXPECT_LE(cc->start_s, a->end_s() + kAifsBe + 15 * 13e-6 + 1e-12);
}

// ===========================================================================
// 5. Coexistence SINR by hand.

namespace {

Transmission make_tx(Rat rat, double start, double dur, double f_lo, double f_hi, double power = 30) {
  Transmission t;
  t.rat = rat;
  t.start_s = start;
  t.duration_s = dur;
  t.f_lo_hz = f_lo;
  t.f_hi_hz = f_hi;
  t.power_dbm = power;
  return t;
}

}  // namespace

TEST(Coexistence, ThreeNodeWifiReceptionByHand) {
  SinrConfig c;  // NF 9 dB, gain threshold -120 dB
  const double lo = kFc - 4.0625e6, hi = kFc + 4.0625e6, bw = hi - lo;  // 8.125 MHz, 52 x 156.25 kHz
  const double dur = 848e-6;
  const Transmission sig = make_tx(Rat::wifi80211p, 1.0, dur, lo, hi);
  // 802.11p interferer on the same band, overlapping the second half of the signal.
  const Transmission wifi_i = make_tx(Rat::wifi80211p, 1.0 + dur / 2, dur, lo, hi);
  // NR interferer on subchannel 0 of a 20 MHz carrier: [fc - 8.64 MHz, fc - 1.44 MHz),
  // the whole signal duration.
  NrPhy nr;
  nr.bandwidth_hz = 20e6;
  const Transmission nr_i = make_tx(Rat::nr_v2x, 0.9999, 0.25e-3 * 4, nr.f_lo_hz(0), nr.f_hi_hz(0, 1));
  ASSERT_NEAR(nr_i.f_hi_hz, kFc - 1.44e6, 1e-3);
  EXPECT_EQ(resource_blocks(sig, c), 52);

  // By hand. Signal: 30 dBm - 80 dB = -50 dBm over 52 blocks.
  const double S = mw(-50.0);
  // 802.11p interferer: 30 - 90 = -60 dBm over the same 8.125 MHz, half the time.
  const double I_wifi = mw(-60.0) * 0.5;
  // NR interferer: 30 - 100 = -70 dBm over 7.2 MHz; it covers [fc - 4.0625, fc - 1.44) MHz
  // of the signal: 2.6225 MHz = 16.784 blocks of 156.25 kHz.
  const double nr_psd = mw(-70.0) / 7.2e6;
  const double I_nr = nr_psd * 2.6225e6;
  const double N = mw(-174.0 + 9.0) * bw;
  // Per block: S/52 over noise + interference; blocks 0..15 see the full NR PSD,
  // block 16 a 0.784 share of it, blocks 17..51 none.
  const double w = 156.25e3;
  const double s_b = S / 52, n_b = N / 52, iw_b = I_wifi / 52, inr_b = nr_psd * w;
  const double lin = (16 * s_b / (n_b + iw_b + inr_b) + 1 * s_b / (n_b + iw_b + 0.784 * inr_b) +
                      35 * s_b / (n_b + iw_b)) / 52;
  const double expected_sinr = to_dbm(lin);
  EXPECT_NEAR(expected_sinr, 12.7415, 1e-3);  // the hand computation itself (python cross-check)

  const std::vector<OverlapInput> in{{7, &wifi_i, -90.0}, {9, &nr_i, -100.0}};
  const SinrBreakdown b = coexistence_sinr(sig, -80.0, in, c);
  EXPECT_NEAR(b.prx_dbm, -50.0, 1e-9);
  EXPECT_NEAR(b.intra_dbm, to_dbm(I_wifi), 0.01);  // -63.01 dBm
  EXPECT_NEAR(b.intra_dbm, -63.0103, 1e-3);
  EXPECT_NEAR(b.inter_dbm, to_dbm(I_nr), 0.01);  // -74.39 dBm
  EXPECT_NEAR(b.inter_dbm, -74.3862, 1e-3);
  EXPECT_NEAR(b.noise_dbm, -174.0 + 10 * std::log10(8.125e6) + 9.0, 1e-9);  // -95.90 dBm
  EXPECT_NEAR(b.sinr_db, expected_sinr, 0.01);
  EXPECT_EQ(b.counted, 2);
  ASSERT_EQ(b.overlaps.size(), 2u);
  EXPECT_EQ(b.overlaps[0].transmission, 7u);
  EXPECT_FALSE(b.overlaps[0].inter_rat);
  EXPECT_TRUE(b.overlaps[0].counted);
  EXPECT_NEAR(b.overlaps[0].power_dbm, to_dbm(I_wifi), 1e-3);
  EXPECT_FLOAT_EQ(b.overlaps[0].gain_db, -90.0f);
  EXPECT_EQ(b.overlaps[1].transmission, 9u);
  EXPECT_TRUE(b.overlaps[1].inter_rat);
  EXPECT_TRUE(b.overlaps[1].counted);
  EXPECT_NEAR(b.overlaps[1].power_dbm, to_dbm(I_nr), 1e-3);

  // The gain threshold above the NR interferer's gain: it is not counted.
  SinrConfig c2 = c;
  c2.gain_threshold_db = -95.0;
  const SinrBreakdown b2 = coexistence_sinr(sig, -80.0, in, c2);
  EXPECT_EQ(b2.counted, 1);
  EXPECT_TRUE(b2.overlaps[0].counted);
  EXPECT_FALSE(b2.overlaps[1].counted);
  EXPECT_TRUE(b2.overlaps[1].inter_rat);
  EXPECT_NEAR(b2.overlaps[1].power_dbm, to_dbm(I_nr), 1e-3);  // still reported
  EXPECT_TRUE(std::isinf(b2.inter_dbm) && b2.inter_dbm < 0);
  EXPECT_NEAR(b2.intra_dbm, b.intra_dbm, 1e-9);
  EXPECT_NEAR(b2.sinr_db, to_dbm(S / (N + I_wifi)), 0.01);  // flat over the band: 13.008 dB
  EXPECT_GT(b2.sinr_db, b.sinr_db);
  // A gain exactly at the threshold counts.
  c2.gain_threshold_db = -100.0;
  EXPECT_EQ(coexistence_sinr(sig, -80.0, in, c2).counted, 2);

  // Without interferers: S / N; without a path: -inf.
  const SinrBreakdown clean = coexistence_sinr(sig, -80.0, {}, c);
  EXPECT_NEAR(clean.sinr_db, -50.0 - (-174.0 + 10 * std::log10(bw) + 9.0), 1e-6);
  EXPECT_TRUE(std::isinf(clean.intra_dbm) && std::isinf(clean.inter_dbm));
  const SinrBreakdown nopath = coexistence_sinr(sig, -kInfD, in, c);
  EXPECT_TRUE(std::isinf(nopath.prx_dbm) && nopath.prx_dbm < 0);
  EXPECT_TRUE(std::isinf(nopath.sinr_db) && nopath.sinr_db < 0);
}

TEST(Coexistence, NrReceptionResolvedPerResourceBlock) {
  SinrConfig c;
  c.nr.bandwidth_hz = 20e6;
  NrPhy nr = c.nr;
  // NR signal on subchannel 1: [fc - 1.44, fc + 5.76) MHz = 10 RBs of 720 kHz; -40 dBm.
  const Transmission sig = make_tx(Rat::nr_v2x, 2.0, 0.25e-3, nr.f_lo_hz(1), nr.f_hi_hz(1, 1));
  EXPECT_EQ(resource_blocks(sig, c), 10);
  // 802.11p frame over the whole slot, received at -65 dBm over 8.125 MHz: it covers
  // [fc - 1.44, fc + 4.0625) MHz = 5.5025 MHz = 7.642 RBs of the signal.
  const Transmission w = make_tx(Rat::wifi80211p, 1.9999, 848e-6, kFc - 4.0625e6, kFc + 4.0625e6);
  // NR interferer on the same subchannel for the first 40% of the slot... (starts before)
  const Transmission n2 = make_tx(Rat::nr_v2x, 2.0 - 0.15e-3, 0.25e-3, nr.f_lo_hz(1), nr.f_hi_hz(1, 1));
  const double S = mw(30 - 70), N = mw(-174 + 9) * 7.2e6;
  const double wifi_psd = mw(30 - 95) / 8.125e6, rb = 720e3;
  const double I_nr = mw(30 - 85) * 0.4;  // 0.1 ms of the 0.25 ms slot
  const double s_b = S / 10, n_b = N / 10, i_nr_b = I_nr / 10, i_w_b = wifi_psd * rb;
  const double frac = 5.5025e6 / rb - 7;  // 0.6424
  const double lin = (7 * s_b / (n_b + i_nr_b + i_w_b) + s_b / (n_b + i_nr_b + frac * i_w_b) +
                      2 * s_b / (n_b + i_nr_b)) / 10;
  const SinrBreakdown b = coexistence_sinr(sig, -70.0, {{0, &w, -95.0}, {1, &n2, -85.0}}, c);
  EXPECT_NEAR(b.prx_dbm, -40.0, 1e-9);
  EXPECT_NEAR(b.intra_dbm, to_dbm(I_nr), 0.01);
  EXPECT_NEAR(b.inter_dbm, to_dbm(wifi_psd * 5.5025e6), 0.01);
  EXPECT_NEAR(b.noise_dbm, -174 + 10 * std::log10(7.2e6) + 9, 1e-9);
  EXPECT_NEAR(b.sinr_db, to_dbm(lin), 0.01);
  EXPECT_EQ(b.counted, 2);
  EXPECT_TRUE(b.overlaps[0].inter_rat);
  EXPECT_FALSE(b.overlaps[1].inter_rat);
}

TEST(Decodable, ThresholdSensitivityAndBlerCurves) {
  SinrConfig c;  // threshold 10 dB, sensitivity -93 dBm
  for (Rat r : {Rat::wifi80211p, Rat::nr_v2x}) {
    EXPECT_TRUE(decodable(r, 10.0, -93.0, c, 0.5));
    EXPECT_TRUE(decodable(r, 25.0, -40.0, c, 0.0));
    EXPECT_FALSE(decodable(r, 9.99, -50.0, c, 0.99));
    EXPECT_FALSE(decodable(r, 20.0, -93.01, c, 0.99));
    EXPECT_FALSE(decodable(r, 20.0, -kInfD, c, 0.99));
  }
  // BLER 1 at 0 dB falling linearly to 0 at 10 dB (NR only).
  c.nr_bler = {{0.0, 1.0}, {10.0, 0.0}};
  EXPECT_FALSE(decodable(Rat::nr_v2x, 5.0, -50, c, 0.49));  // BLER(5 dB) = 0.5
  EXPECT_TRUE(decodable(Rat::nr_v2x, 5.0, -50, c, 0.51));
  EXPECT_FALSE(decodable(Rat::nr_v2x, 2.5, -50, c, 0.74));  // 0.75
  EXPECT_TRUE(decodable(Rat::nr_v2x, 2.5, -50, c, 0.76));
  EXPECT_TRUE(decodable(Rat::nr_v2x, 8.0, -50, c, 0.21));   // 0.2: decoded below the 10 dB threshold
  EXPECT_FALSE(decodable(Rat::nr_v2x, -5.0, -50, c, 0.999));  // clamped: BLER 1
  EXPECT_TRUE(decodable(Rat::nr_v2x, 30.0, -50, c, 0.0));     // clamped: BLER 0
  EXPECT_FALSE(decodable(Rat::nr_v2x, 30.0, -95, c, 0.9));    // sensitivity still applies
  // 802.11p keeps the threshold rule.
  EXPECT_TRUE(decodable(Rat::wifi80211p, 10.0, -50, c, 0.0));
  EXPECT_FALSE(decodable(Rat::wifi80211p, 8.0, -50, c, 0.99));
  // Three-point curve.
  c.wifi_bler = {{0.0, 1.0}, {4.0, 0.5}, {8.0, 0.1}};
  EXPECT_FALSE(decodable(Rat::wifi80211p, 6.0, -50, c, 0.29));  // 0.3
  EXPECT_TRUE(decodable(Rat::wifi80211p, 6.0, -50, c, 0.31));
  EXPECT_FALSE(decodable(Rat::wifi80211p, 2.0, -50, c, 0.74));  // 0.75
}

// ===========================================================================
// 6. run_sinr end to end.

namespace {

// Node 0: an RSU; nodes 1..6: vehicles driving east at 10 m/s in two lanes, 20 frames at 10 Hz.
ChannelTrace e2e_trace() {
  std::vector<NodeInfo> nodes(7);
  nodes[0].id = "rsu0";
  nodes[0].kind = NodeKind::rsu;
  for (int i = 1; i <= 6; ++i) {
    nodes[i].id = "veh" + std::to_string(i);
    nodes[i].kind = NodeKind::vehicle;
    nodes[i].vtype = "car";
  }
  std::vector<FrameRecord> frames;
  for (int f = 0; f < 20; ++f) {
    FrameRecord fr;
    fr.time_s = f * 0.1;
    fr.nodes.push_back(at(0, 60, 15));
    for (std::uint32_t i = 1; i <= 6; ++i)
      fr.nodes.push_back(at(i, 20.0 * i + 1.0 * f, (i % 2) * 3.5, 10, 0, 90));
    frames.push_back(fr);
  }
  return ChannelTrace::from_records(nodes, frames, kFc, 10e6);
}

SinrConfig e2e_config(std::uint64_t seed) {
  SinrConfig c;
  c.seed = seed;
  c.nr.bandwidth_hz = 20e6;
  c.cpm.enabled = true;
  c.cpm.bytes = 400;  // 2 subchannels
  c.cpm.period_s = 0.1;
  return c;
}

SinrRunStats run_to_file(const fs::path& p, const ChannelTrace& tr, const ChannelModel& ch, const SinrConfig& c,
                         const std::vector<Rat>& rats, const std::vector<Transmission>* reuse = nullptr) {
  const auto [b, e] = sinr_window(tr, c);
  SinrHeader h;
  h.raysweep_version = "test";
  h.git_hash = "unknown";
  h.config = nlohmann::json{{"test", "e2e"}};
  h.inputs = nlohmann::json::object();
  h.provenance = nlohmann::json::object();
  h.seed = 1;  // the same in every file, so files differ only by their content
  h.channel_model = "ray";
  h.carrier_hz = kFc;
  h.sinr_threshold_db = c.sinr_threshold_db;
  h.sensitivity_dbm = c.sensitivity_dbm;
  h.gain_threshold_db = c.gain_threshold_db;
  h.time_start_s = b;
  h.time_end_s = e;
  SinrWriter w(p, h);
  return run_sinr(tr, ch, c, rats, reuse, w);
}

bool same_transmissions(const std::vector<Transmission>& a, const std::vector<Transmission>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const auto &x = a[i], &y = b[i];
    if (x.node != y.node || x.rat != y.rat || x.message != y.message || x.packet != y.packet ||
        x.attempt != y.attempt || x.size_bytes != y.size_bytes || x.start_s != y.start_s ||
        x.duration_s != y.duration_s || x.f_lo_hz != y.f_lo_hz || x.f_hi_hz != y.f_hi_hz ||
        x.power_dbm != y.power_dbm)
      return false;
  }
  return true;
}

}  // namespace

TEST(RunSinr, AssignRats) {
  const ChannelTrace tr = e2e_trace();
  RatAssignment a;  // nr_fraction 0.5
  const auto rats = assign_rats(tr, a, 3);
  ASSERT_EQ(rats.size(), 7u);
  EXPECT_EQ(rats[0], Rat::none) << "RSUs are silent unless listed";
  int nr = 0, wifi = 0;
  for (int i = 1; i <= 6; ++i) nr += rats[i] == Rat::nr_v2x, wifi += rats[i] == Rat::wifi80211p;
  EXPECT_EQ(nr, 3);
  EXPECT_EQ(wifi, 3);
  EXPECT_EQ(assign_rats(tr, a, 3), rats) << "deterministic for a seed";

  // Some seed gives another split (an exact 3/3 each time).
  bool differs = false;
  for (std::uint64_t seed = 4; seed < 20 && !differs; ++seed) {
    const auto r = assign_rats(tr, a, seed);
    EXPECT_EQ(std::count(r.begin(), r.end(), Rat::nr_v2x), 3);
    differs = r != rats;
  }
  EXPECT_TRUE(differs);

  // nrv2x-only: the same NR vehicles, the 802.11p ones silenced.
  RatAssignment only = a;
  only.enabled = "nrv2x-only";
  const auto r2 = assign_rats(tr, only, 3);
  for (int i = 0; i <= 6; ++i) EXPECT_EQ(r2[i], rats[i] == Rat::nr_v2x ? Rat::nr_v2x : Rat::none) << i;
  only.enabled = "80211p-only";
  const auto r3 = assign_rats(tr, only, 3);
  for (int i = 0; i <= 6; ++i) EXPECT_EQ(r3[i], rats[i] == Rat::wifi80211p ? Rat::wifi80211p : Rat::none) << i;

  // active_vehicles 4: vehicles 1..4 split 2/2, 5 and 6 silent.
  RatAssignment act = a;
  act.active_vehicles = 4;
  const auto r4 = assign_rats(tr, act, 3);
  EXPECT_EQ(r4[5], Rat::none);
  EXPECT_EQ(r4[6], Rat::none);
  EXPECT_EQ(std::count(r4.begin(), r4.end(), Rat::nr_v2x), 2);
  EXPECT_EQ(std::count(r4.begin(), r4.end(), Rat::wifi80211p), 2);

  // Lists take precedence over vTypes, vTypes over the fraction.
  RatAssignment lists;
  lists.by_vtype["car"] = Rat::nr_v2x;
  lists.wifi_ids = {"veh2"};
  lists.nr_ids = {"rsu0"};
  lists.silent_ids = {"veh5"};
  const auto r5 = assign_rats(tr, lists, 3);
  EXPECT_EQ(r5, (std::vector<Rat>{Rat::nr_v2x, Rat::nr_v2x, Rat::wifi80211p, Rat::nr_v2x, Rat::nr_v2x, Rat::none,
                                  Rat::nr_v2x}));
  RatAssignment unknown;
  unknown.nr_ids = {"veh99"};
  EXPECT_THROW(assign_rats(tr, unknown, 3), std::invalid_argument);
}

TEST(RunSinr, EndToEndFileDeterminismAndReuse) {
  const ChannelTrace tr = e2e_trace();
  FakeChannel ch(tr, distance_gain(1e9));
  const SinrConfig c = e2e_config(7);
  const auto rats = assign_rats(tr, c.rats, c.seed);
  const fs::path dir = scratch_dir("sinr");
  const fs::path f1 = dir / "run1.h5", f2 = dir / "run2.h5";

  const SinrRunStats st = run_to_file(f1, tr, ch, c, rats);
  EXPECT_EQ(validate_dataset(f1.string()), std::vector<std::string>{});
  EXPECT_DOUBLE_EQ(st.time_start_s, 0.0);
  EXPECT_NEAR(st.time_end_s, 2.0, 1e-9);
  ASSERT_GT(st.transmissions, 50u);
  // All six vehicles are present in every frame: each transmission has exactly the two
  // other vehicles of its RAT as receivers (the RSU has none).
  EXPECT_EQ(st.receptions, 2 * st.transmissions);

  const auto r_tr = read_column<std::uint32_t>(f1, "/receptions/transmission", H5T_NATIVE_UINT32);
  const auto r_tx = read_column<std::uint32_t>(f1, "/receptions/tx", H5T_NATIVE_UINT32);
  const auto r_rx = read_column<std::uint32_t>(f1, "/receptions/rx", H5T_NATIVE_UINT32);
  const auto r_rat = read_column<std::uint8_t>(f1, "/receptions/rat", H5T_NATIVE_UINT8);
  const auto t_node = read_column<std::uint32_t>(f1, "/transmissions/node", H5T_NATIVE_UINT32);
  const auto t_rat = read_column<std::uint8_t>(f1, "/transmissions/rat", H5T_NATIVE_UINT8);
  const auto n_rat = read_column<std::uint8_t>(f1, "/nodes/rat", H5T_NATIVE_UINT8);
  ASSERT_EQ(r_rx.size(), st.receptions);
  ASSERT_EQ(t_node.size(), st.transmissions);
  ASSERT_EQ(n_rat.size(), 7u);
  for (std::uint32_t n = 0; n < 7; ++n) EXPECT_EQ(n_rat[n], static_cast<std::uint8_t>(rats[n]));
  std::size_t nr_tx = 0, wifi_tx = 0;
  for (std::size_t i = 0; i < t_node.size(); ++i) {
    EXPECT_EQ(t_rat[i], static_cast<std::uint8_t>(rats[t_node[i]])) << "a node sends with its own RAT";
    nr_tx += t_rat[i] == 2;
    wifi_tx += t_rat[i] == 1;
  }
  EXPECT_GT(nr_tx, 0u);
  EXPECT_GT(wifi_tx, 0u);
  for (std::size_t i = 0; i < r_rx.size(); ++i) {
    ASSERT_LT(r_tr[i], t_node.size());
    EXPECT_NE(r_rx[i], t_node[r_tr[i]]) << "the sender is not a receiver";
    EXPECT_EQ(r_tx[i], t_node[r_tr[i]]);
    EXPECT_EQ(r_rat[i], t_rat[r_tr[i]]);
    EXPECT_EQ(static_cast<std::uint8_t>(rats[r_rx[i]]), t_rat[r_tr[i]]) << "receiver of the transmission's RAT";
  }

  // The same seed: a byte-identical file.
  run_to_file(f2, tr, ch, c, rats);
  EXPECT_TRUE(read_text(f1) == read_text(f2)) << "two runs with the same seed differ";

  // One thread vs four threads: byte-identical.
  const fs::path f_one = dir / "one.h5", f_four = dir / "four.h5";
  {
    tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 1);
    run_to_file(f_one, tr, ch, c, rats);
  }
  {
    tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 4);
    run_to_file(f_four, tr, ch, c, rats);
  }
  EXPECT_TRUE(read_text(f_one) == read_text(f_four)) << "results depend on the number of threads";
  EXPECT_TRUE(read_text(f_one) == read_text(f1));

  // Another seed: another schedule.
  const fs::path f_other = dir / "other.h5";
  run_to_file(f_other, tr, ch, e2e_config(8), rats);
  const SinrSchedule s1 = read_sinr_schedule(f1.string());
  const SinrSchedule s_other = read_sinr_schedule(f_other.string());
  EXPECT_FALSE(same_transmissions(s1.transmissions, s_other.transmissions));

  // Schedule reuse: the transmissions of the first run, evaluated again.
  ASSERT_EQ(s1.transmissions.size(), st.transmissions);
  ASSERT_EQ(s1.nodes.size(), 7u);
  for (std::uint32_t n = 0; n < 7; ++n) {
    EXPECT_EQ(s1.nodes[n].id, tr.nodes()[n].id);
    EXPECT_EQ(s1.nodes[n].rat, rats[n]);
  }
  const fs::path f_reuse = dir / "reuse.h5";
  const SinrRunStats st_reuse = run_to_file(f_reuse, tr, ch, c, rats, &s1.transmissions);
  EXPECT_EQ(validate_dataset(f_reuse.string()), std::vector<std::string>{});
  const SinrSchedule s_reuse = read_sinr_schedule(f_reuse.string());
  EXPECT_TRUE(same_transmissions(s1.transmissions, s_reuse.transmissions));
  EXPECT_EQ(st_reuse.receptions, st.receptions);
  EXPECT_EQ(st_reuse.decoded, st.decoded);
  const auto sinr1 = read_column<float>(f1, "/receptions/sinr_db", H5T_NATIVE_FLOAT);
  const auto sinr_r = read_column<float>(f_reuse, "/receptions/sinr_db", H5T_NATIVE_FLOAT);
  EXPECT_TRUE(sinr1 == sinr_r) << "the same transmissions under the same channel give the same SINRs";

  // A reused schedule naming a node the trace does not have is refused.
  std::vector<Transmission> bad = s1.transmissions;
  bad[0].node = 7;
  EXPECT_THROW(run_to_file(dir / "bad.h5", tr, ch, c, rats, &bad), std::invalid_argument);
}

TEST(RunSinr, NrOnlyRunHasNoWifiTraffic) {
  const ChannelTrace tr = e2e_trace();
  FakeChannel ch(tr, distance_gain(1e9));
  SinrConfig c = e2e_config(7);
  c.rats.enabled = "nrv2x-only";
  const auto rats = assign_rats(tr, c.rats, c.seed);
  const fs::path f = scratch_dir("sinr") / "nr.h5";
  const SinrRunStats st = run_to_file(f, tr, ch, c, rats);
  EXPECT_EQ(validate_dataset(f.string()), std::vector<std::string>{});
  const SinrSchedule s = read_sinr_schedule(f.string());
  ASSERT_FALSE(s.transmissions.empty());
  for (const auto& t : s.transmissions) {
    EXPECT_EQ(t.rat, Rat::nr_v2x);
    EXPECT_EQ(rats[t.node], Rat::nr_v2x);
  }
  EXPECT_EQ(st.receptions, 2 * st.transmissions);  // 3 NR vehicles
  for (const auto& e : st.prr_rats) EXPECT_EQ(e.rat, Rat::nr_v2x);
}
