// Message generation (generators/sinr/messages.cpp): the ETSI CAM trigger
// (EN 302 637-2 6.1.3) on synthetic kinematics, CAMs and CPMs from a trace,
// the hash-driven uniforms.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <map>
#include <vector>

#include "generators/sinr/channel_trace.hpp"
#include "generators/sinr/messages.hpp"
#include "generators/sinr/sinr_config.hpp"
#include "sinr_fixtures.hpp"

using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using namespace raysweep::generators::sinr::fixtures;

// ===========================================================================
// CAM generation rules (EN 302 637-2 6.1.3).

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
