// Transmission scheduling (generators/sinr/schedule.cpp): NR-V2X Mode 2 SPS
// structure and statistics (grants, reselection, retransmissions, sensing) and
// IEEE 802.11p EDCA/CSMA invariants (carrier sense, hidden stations, access
// categories, energy detection of NR).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "generators/sinr/channel_models.hpp"
#include "generators/sinr/channel_trace.hpp"
#include "generators/sinr/messages.hpp"
#include "generators/sinr/phy.hpp"
#include "generators/sinr/schedule.hpp"
#include "generators/sinr/sinr_config.hpp"
#include "sinr_fixtures.hpp"

using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using namespace raysweep::generators::sinr::fixtures;

namespace {

// One frame at t = 0 with every node present (sample and hold: it is in force forever).
ChannelTrace static_trace(const std::vector<std::pair<double, double>>& xy) {
  FrameRecord f;
  f.time_s = 0;
  for (std::uint32_t i = 0; i < xy.size(); ++i) f.nodes.push_back(at(i, xy[i].first, xy[i].second));
  return ChannelTrace::from_records(vehicles(xy.size()), {f}, kFc, 10e6);
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

}  // namespace

// ===========================================================================
// NR-V2X Mode 2 SPS.

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
// IEEE 802.11p EDCA / CSMA.

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
