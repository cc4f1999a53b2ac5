// SINR channel models and the channel trace: 3GPP formulas against hand-computed
// values, LoS / shadowing statistics, spatial consistency, determinism across
// query orders and threads, the traced (ray) model, and loading datasets.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "generators/dataset_writer.hpp"
#include "generators/sinr/channel_models.hpp"
#include "generators/sinr/channel_trace.hpp"
#include "hdf5_test_util.hpp"
#include "meshkit/errors.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using raysweep::meshkit::InputError;
using raysweep::test::H5;
using raysweep::test::scratch_dir;
using Scen = formulas::Tr37885Scenario;

namespace {

constexpr double kFc = 5.9e9;
constexpr float kNoGain = -std::numeric_limits<float>::infinity();

NodeState at(std::uint32_t node, double x, double y, double z = 0) {
  NodeState s;
  s.node = node;
  s.x = x, s.y = y, s.z = z;
  return s;
}

LinkRecord link_rec(std::uint32_t tx, std::uint32_t rx, float gain, std::uint8_t los, std::uint8_t flags = 0) {
  LinkRecord l;
  l.tx = tx, l.rx = rx, l.los_class = los, l.flags = flags;
  l.gain_coherent_db = l.gain_incoherent_db = gain;
  return l;
}

std::vector<NodeInfo> vehicles(std::size_t n) {
  std::vector<NodeInfo> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i].id = "veh" + std::to_string(i);
  return v;
}

// One frame: node 0 at the origin, nodes 1..n on a circle of radius d around it.
ChannelTrace circle_trace(std::uint32_t n, double d) {
  FrameRecord f;
  f.nodes.push_back(at(0, 0, 0));
  for (std::uint32_t i = 1; i <= n; ++i) {
    const double a = 2 * M_PI * i / n;
    f.nodes.push_back(at(i, d * std::cos(a), d * std::sin(a)));
  }
  return ChannelTrace::from_records(vehicles(n + 1), {f}, kFc, 10e6);
}

// Pairs (2i, 2i+1) 50 m apart, far from each other; in frame 1 both nodes of a
// pair have moved by move/2 sideways (dd = move). With `gap`, a third frame
// without the odd nodes and a fourth with all back at the frame-0 positions.
// Every pair has a traced LOS link.
ChannelTrace pair_trace(std::uint32_t pairs, double move, bool gap = false) {
  auto frame = [&](double t, double dy, bool odd) {
    FrameRecord f;
    f.time_s = t;
    for (std::uint32_t i = 0; i < pairs; ++i) {
      f.nodes.push_back(at(2 * i, 5000.0 * i, dy));
      if (odd) f.nodes.push_back(at(2 * i + 1, 5000.0 * i + 50, dy));
      if (odd) f.links.push_back(link_rec(2 * i, 2 * i + 1, -80, 0));
    }
    return f;
  };
  std::vector<FrameRecord> frames = {frame(0, 0, true), frame(0.1, move / 2, true)};
  if (gap) {
    frames.push_back(frame(0.2, move / 2, false));
    frames.push_back(frame(0.3, 0, true));
  }
  return ChannelTrace::from_records(vehicles(2 * pairs), frames, kFc, 10e6);
}

double correlation(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  double mx = 0, my = 0;
  for (std::size_t i = 0; i < x.size(); ++i) mx += x[i] / n, my += y[i] / n;
  double sxy = 0, sxx = 0, syy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  return sxy / std::sqrt(sxx * syy);
}

}  // namespace

// ---------------------------------------------------------------------------
// Closed forms.

TEST(ChannelFormulas, Tr37885PathLoss) {
  const double lf = std::log10(5.9);
  // Hand-computed: 38.77 + 16.7 * 2 + 18.2 * 0.770852 = 86.1995.
  EXPECT_NEAR(formulas::tr37885_pathloss_db(Scen::urban, 0, 100, kFc), 86.20, 0.01);
  EXPECT_NEAR(formulas::tr37885_pathloss_db(Scen::highway, 0, 100, kFc), 87.82, 0.01);
  EXPECT_NEAR(formulas::tr37885_pathloss_db(Scen::urban, 2, 100, kFc), 111.42, 0.01);
  for (double d : {3.0, 37.0, 250.0, 1000.0}) {
    EXPECT_NEAR(formulas::tr37885_pathloss_db(Scen::urban, 0, d, kFc), 38.77 + 16.7 * std::log10(d) + 18.2 * lf, 1e-9);
    EXPECT_NEAR(formulas::tr37885_pathloss_db(Scen::highway, 0, d, kFc), 32.4 + 20 * std::log10(d) + 20 * lf, 1e-9);
    const double nlos = 36.85 + 30 * std::log10(d) + 18.9 * lf;
    EXPECT_NEAR(formulas::tr37885_pathloss_db(Scen::urban, 2, d, kFc), nlos, 1e-9);
    EXPECT_NEAR(formulas::tr37885_pathloss_db(Scen::highway, 2, d, kFc), nlos, 1e-9);  // tracer NLOS on a highway
    // NLOSV: the LOS value; the random blockage is the model's.
    EXPECT_DOUBLE_EQ(formulas::tr37885_pathloss_db(Scen::urban, 1, d, kFc),
                     formulas::tr37885_pathloss_db(Scen::urban, 0, d, kFc));
  }
}

TEST(ChannelFormulas, Tr36885PathLossAndBreakpoint) {
  const double lf = std::log10(5.9);
  // h' = 0.5 m: d'BP = 4 * 0.25 * 5.9e9 / c = 19.68 m.
  const double d_bp = 5.9e9 / 299792458.0;
  EXPECT_NEAR(d_bp, 19.68, 0.01);
  EXPECT_NEAR(formulas::tr36885_pathloss_db(true, 10, kFc, 1.5, 1.5), 65.117, 0.01);   // 22.7 + 27 + 20 lf
  EXPECT_NEAR(formulas::tr36885_pathloss_db(true, 100, kFc, 1.5, 1.5), 100.057, 0.01);  // 80 + 7.56 + 10.416 + 2.081
  EXPECT_NEAR(formulas::tr36885_pathloss_db(false, 100, kFc, 1.5, 1.5), 116.142, 0.01);
  EXPECT_NEAR(formulas::tr36885_pathloss_db(true, 500, kFc, 1.5, 1.5),
              40 * std::log10(500.0) + 7.56 - 2 * 17.3 * std::log10(0.5) + 2.7 * lf, 1e-9);
  // Both branches meet near the breakpoint (71.79 vs 71.82 dB).
  const double below = formulas::tr36885_pathloss_db(true, d_bp * (1 - 1e-9), kFc, 1.5, 1.5);
  const double above = formulas::tr36885_pathloss_db(true, d_bp * (1 + 1e-9), kFc, 1.5, 1.5);
  EXPECT_NEAR(below, 71.79, 0.01);
  EXPECT_NEAR(above, 71.82, 0.01);
  EXPECT_LT(std::abs(above - below), 0.5);
  EXPECT_NEAR(formulas::tr36885_pathloss_db(false, 3, kFc, 1.5, 1.5), 60.25, 0.01);  // 36.7 log10 3 + 22.7 + 26 lf
  // NLOS is never below LOS. At 5.9 GHz the UMi curve only drops below the
  // 40 log10 d LOS branch beyond about 7000 km, where the LOS value must be taken.
  for (double d = 3; d < 2000; d *= 1.3)
    EXPECT_GE(formulas::tr36885_pathloss_db(false, d, kFc, 1.5, 1.5), formulas::tr36885_pathloss_db(true, d, kFc, 1.5, 1.5));
  EXPECT_DOUBLE_EQ(formulas::tr36885_pathloss_db(false, 1e8, kFc, 1.5, 1.5), formulas::tr36885_pathloss_db(true, 1e8, kFc, 1.5, 1.5));
  EXPECT_GT(formulas::tr36885_pathloss_db(false, 1e6, kFc, 1.5, 1.5), formulas::tr36885_pathloss_db(true, 1e6, kFc, 1.5, 1.5));
}

TEST(ChannelFormulas, LosProbabilities) {
  EXPECT_DOUBLE_EQ(formulas::tr36885_p_los(1), 1.0);
  EXPECT_DOUBLE_EQ(formulas::tr36885_p_los(18), 1.0);
  EXPECT_NEAR(formulas::tr36885_p_los(100), 0.18 * (1 - std::exp(-100.0 / 36)) + std::exp(-100.0 / 36), 1e-12);
  EXPECT_NEAR(formulas::tr36885_p_los(100), 0.2310, 1e-4);
  double prev = 1.0;
  for (double d = 1; d <= 3000; d += 0.5) {
    const double p = formulas::tr36885_p_los(d);
    EXPECT_LE(p, prev + 1e-12) << d;
    prev = p;
  }
  EXPECT_LT(prev, 0.01);

  EXPECT_NEAR(formulas::tr37885_p_los(Scen::urban, 100), 0.3358, 1e-4);  // 1.05 e^-1.14
  EXPECT_NEAR(formulas::tr37885_p_nlos(Scen::urban, 100), 0.3002, 1e-4);
  EXPECT_DOUBLE_EQ(formulas::tr37885_p_los(Scen::urban, 1), 1.0);
  EXPECT_NEAR(formulas::tr37885_p_los(Scen::highway, 100), 0.8403, 1e-4);
  EXPECT_NEAR(formulas::tr37885_p_los(Scen::highway, 475), 0.5434, 1e-4);
  EXPECT_NEAR(formulas::tr37885_p_los(Scen::highway, 476), 0.539, 1e-6);
  EXPECT_DOUBLE_EQ(formulas::tr37885_p_los(Scen::highway, 2000), 0.0);
  for (double d = 1; d <= 1000; d += 1) {
    for (Scen s : {Scen::urban, Scen::highway}) {
      const double l = formulas::tr37885_p_los(s, d), n = formulas::tr37885_p_nlos(s, d);
      EXPECT_GE(l, 0) << d;
      EXPECT_LE(l, 1) << d;
      EXPECT_GE(n, 0) << d;
      EXPECT_LE(l + n, 1 + 1e-12) << d;
    }
    EXPECT_EQ(formulas::tr37885_p_nlos(Scen::highway, d), 0.0);
  }
}

TEST(ChannelFormulas, BlockageBranchesAndSigmas) {
  // Both antennas under the blocker (the default 1.5 m vs 1.6 m).
  auto b = formulas::tr37885_nlosv_blockage(100, 1.5, 1.5, 1.6);
  EXPECT_DOUBLE_EQ(b.mean_db, 9.0);
  EXPECT_DOUBLE_EQ(b.sigma_db, 4.5);
  b = formulas::tr37885_nlosv_blockage(1000, 1.5, 1.5, 1.6);  // 15 log10(1000) - 41 = 4
  EXPECT_NEAR(b.mean_db, 13.0, 1e-9);
  // One above, one below.
  b = formulas::tr37885_nlosv_blockage(1000, 2.0, 1.5, 1.6);
  EXPECT_NEAR(b.mean_db, 9.0, 1e-9);
  EXPECT_DOUBLE_EQ(b.sigma_db, 4.0);
  b = formulas::tr37885_nlosv_blockage(100, 1.5, 2.0, 1.6);
  EXPECT_DOUBLE_EQ(b.mean_db, 5.0);
  // Both above: no blockage.
  b = formulas::tr37885_nlosv_blockage(1000, 2.0, 2.5, 1.6);
  EXPECT_EQ(b.mean_db, 0.0);
  EXPECT_EQ(b.sigma_db, 0.0);

  EXPECT_EQ(formulas::shadowing_sigma_db(ChannelModelKind::ray, 0), 0.0);
  EXPECT_EQ(formulas::shadowing_sigma_db(ChannelModelKind::ray, 2), 0.0);
  EXPECT_EQ(formulas::shadowing_sigma_db(ChannelModelKind::tr36885, 0), 3.0);
  EXPECT_EQ(formulas::shadowing_sigma_db(ChannelModelKind::tr36885, 2), 4.0);
  for (auto k : {ChannelModelKind::tr37885_urban, ChannelModelKind::tr37885_highway}) {
    EXPECT_EQ(formulas::shadowing_sigma_db(k, 0), 3.0);
    EXPECT_EQ(formulas::shadowing_sigma_db(k, 1), 4.0);
    EXPECT_EQ(formulas::shadowing_sigma_db(k, 2), 4.0);
  }
}

TEST(ChannelFormulas, ModelNames) {
  for (auto k : {ChannelModelKind::ray, ChannelModelKind::tr36885, ChannelModelKind::tr37885_urban,
                 ChannelModelKind::tr37885_highway})
    EXPECT_EQ(parse_channel_model(channel_model_name(k)), k);
  EXPECT_STREQ(channel_model_name(ChannelModelKind::tr37885_highway), "tr37885-highway");
  try {
    parse_channel_model("winner");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'winner'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("tr37885-urban"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------
// Statistics of the stochastic models.

namespace {

struct Counts {
  std::size_t n = 0, cls[3] = {0, 0, 0};
  std::vector<double> excess[3];  // loss - LOS path loss, per class
};

Counts collect(const ChannelModel& m, std::uint32_t n, double los_pl) {
  Counts c;
  for (std::uint32_t i = 1; i <= n; ++i) {
    const LinkState s = m.link(0, 0, i);
    ++c.n;
    ++c.cls[s.los_class];
    c.excess[s.los_class].push_back(-s.gain_db - los_pl);
  }
  return c;
}

void expect_fraction(std::size_t k, std::size_t n, double p, const char* what) {
  const double sigma = std::sqrt(p * (1 - p) / static_cast<double>(n));
  EXPECT_NEAR(static_cast<double>(k) / static_cast<double>(n), p, 3 * sigma) << what;
}

void mean_std(const std::vector<double>& v, double& mean, double& sd) {
  mean = 0;
  for (double x : v) mean += x / static_cast<double>(v.size());
  double ss = 0;
  for (double x : v) ss += (x - mean) * (x - mean);
  sd = std::sqrt(ss / static_cast<double>(v.size() - 1));
}

}  // namespace

TEST(ChannelModels, LosFractionsMatchProbabilities) {
  const std::uint32_t n = 4000;
  const double d = 100;
  const ChannelTrace t = circle_trace(n, d);
  StochasticOptions o;
  o.seed = 11;
  {
    auto m = make_channel_model(ChannelModelKind::tr37885_urban, t, o);
    const Counts c = collect(*m, n, 0);
    const double p_los = 1.05 * std::exp(-0.0114 * d);
    const double l = std::log(d) - 5.0063;
    const double p_nlos = 1 / (0.0312 * d) * std::exp(-l * l / 2.4544);
    expect_fraction(c.cls[0], n, p_los, "urban LOS");
    expect_fraction(c.cls[2], n, p_nlos, "urban NLOS");
    expect_fraction(c.cls[1], n, 1 - p_los - p_nlos, "urban NLOSV");
    EXPECT_NEAR(m->link(0, 0, 1).distance_m, d, 1e-9);
  }
  {
    auto m = make_channel_model(ChannelModelKind::tr37885_highway, t, o);
    const Counts c = collect(*m, n, 0);
    expect_fraction(c.cls[0], n, 2.1013e-6 * d * d - 0.002 * d + 1.0193, "highway LOS");
    EXPECT_EQ(c.cls[2], 0u);
  }
  {
    auto m = make_channel_model(ChannelModelKind::tr36885, t, o);
    const Counts c = collect(*m, n, 0);
    expect_fraction(c.cls[0], n, 0.18 * (1 - std::exp(-d / 36)) + std::exp(-d / 36), "tr36885 LOS");
    EXPECT_EQ(c.cls[1], 0u);  // two states
  }
}

TEST(ChannelModels, ShadowingAndBlockageStatistics) {
  const std::uint32_t n = 4000;
  const double d = 100;
  const ChannelTrace t = circle_trace(n, d);
  StochasticOptions o;
  o.seed = 5;
  auto m = make_channel_model(ChannelModelKind::tr37885_highway, t, o);
  const double pl_los = 32.4 + 20 * std::log10(d) + 20 * std::log10(5.9);
  const Counts c = collect(*m, n, pl_los);
  double mean = 0, sd = 0;
  ASSERT_GT(c.excess[0].size(), 2000u);
  mean_std(c.excess[0], mean, sd);
  EXPECT_NEAR(sd, 3.0, 0.3);
  EXPECT_NEAR(mean, 0.0, 3 * 3.0 / std::sqrt(static_cast<double>(c.excess[0].size())));
  // NLOSV: blockage N(9, 4.5) (clipped at 0, which barely matters) plus 4 dB shadowing.
  ASSERT_GT(c.excess[1].size(), 300u);
  mean_std(c.excess[1], mean, sd);
  EXPECT_NEAR(mean, 9.0, 3 * 6.0 / std::sqrt(static_cast<double>(c.excess[1].size())));
  EXPECT_NEAR(sd, std::sqrt(4.5 * 4.5 + 16), 0.8);

  // Without shadowing, LOS links sit exactly on the path loss.
  o.shadowing = false;
  auto flat = make_channel_model(ChannelModelKind::tr37885_highway, t, o);
  const Counts f = collect(*flat, n, pl_los);
  for (double x : f.excess[0]) ASSERT_NEAR(x, 0.0, 1e-4);
  for (double x : f.excess[1]) ASSERT_GE(x, -1e-4);  // the blockage loss is never a gain
}

TEST(ChannelModels, SpatialConsistency) {
  const std::uint32_t pairs = 2000;
  StochasticOptions o;
  o.seed = 3;
  o.los_from_ray = true;  // fixed LOS class: the gain follows the shadowing process alone
  auto gains = [&](const ChannelTrace& t, std::size_t f0, std::size_t f1, ChannelModelKind k = ChannelModelKind::tr37885_urban) {
    auto m = make_channel_model(k, t, o);
    std::vector<double> g0, g1;
    for (std::uint32_t i = 0; i < pairs; ++i) {
      g0.push_back(m->link(f0, 2 * i, 2 * i + 1).gain_db);
      g1.push_back(m->link(f1, 2 * i, 2 * i + 1).gain_db);
    }
    return std::pair(g0, g1);
  };
  {  // standing still: identical
    const ChannelTrace t = pair_trace(pairs, 0.0);
    for (bool ray : {true, false}) {
      o.los_from_ray = ray;
      for (auto k : {ChannelModelKind::tr36885, ChannelModelKind::tr37885_urban}) {
        auto m = make_channel_model(k, t, o);
        std::size_t changed = 0;
        for (std::uint32_t i = 0; i < pairs; ++i) {
          const LinkState a = m->link(0, 2 * i, 2 * i + 1), b = m->link(1, 2 * i, 2 * i + 1);
          changed += a.gain_db != b.gain_db || a.los_class != b.los_class;
        }
        EXPECT_EQ(changed, 0u);
      }
    }
    o.los_from_ray = true;
  }
  {  // 1 m with 10 m decorrelation: rho = e^-0.1 = 0.905
    const auto [g0, g1] = gains(pair_trace(pairs, 1.0), 0, 1);
    EXPECT_GT(correlation(g0, g1), 0.8);
    EXPECT_LT(correlation(g0, g1), 0.97);
  }
  {  // 1 km: independent
    const auto [g0, g1] = gains(pair_trace(pairs, 1000.0), 0, 1);
    EXPECT_LT(std::abs(correlation(g0, g1)), 0.2);
  }
  {  // the pair was apart in frame 2: frame 3 restarts although it is back where frame 0 was
    const ChannelTrace t = pair_trace(pairs, 0.0, true);
    const auto [g1, g3] = gains(t, 1, 3);
    EXPECT_LT(std::abs(correlation(g1, g3)), 0.2);
    auto m = make_channel_model(ChannelModelKind::tr37885_urban, t, o);
    EXPECT_EQ(m->link(2, 0, 1).gain_db, -std::numeric_limits<double>::infinity());
  }
  {  // the LoS state itself is correlated for small moves and not for large ones
    o.los_from_ray = false;
    auto agreement = [&](double move) {
      const ChannelTrace t = pair_trace(pairs, move);
      auto m = make_channel_model(ChannelModelKind::tr37885_urban, t, o);
      std::size_t same = 0;
      for (std::uint32_t i = 0; i < pairs; ++i)
        same += m->link(0, 2 * i, 2 * i + 1).los_class == m->link(1, 2 * i, 2 * i + 1).los_class;
      return static_cast<double>(same) / pairs;
    };
    // Independent draws agree with probability sum p_k^2 (about 0.51 at 50 m).
    const double pl = 1.05 * std::exp(-0.0114 * 50), l = std::log(50.0) - 5.0063;
    const double pn = 1 / (0.0312 * 50) * std::exp(-l * l / 2.4544), pv = 1 - pl - pn;
    const double independent = pl * pl + pn * pn + pv * pv;
    EXPECT_GT(agreement(1.0), 0.8);
    EXPECT_NEAR(agreement(1000.0), independent, 0.05);
  }
}

TEST(ChannelModels, ReciprocalDeterministicAndThreadSafe) {
  // 40 vehicles on a 400 m x 60 m patch, moving, some leaving and entering.
  const std::uint32_t n = 40;
  std::vector<FrameRecord> frames(6);
  for (std::size_t f = 0; f < frames.size(); ++f) {
    frames[f].time_s = 0.1 * static_cast<double>(f);
    for (std::uint32_t i = 0; i < n; ++i) {
      if ((i + f) % 7 == 0) continue;
      frames[f].nodes.push_back(at(i, 10.0 * i + 3.0 * static_cast<double>(f) * (i % 3), 60.0 * std::sin(i), 0));
    }
  }
  const ChannelTrace t = ChannelTrace::from_records(vehicles(n), frames, kFc, 10e6);
  for (auto k : {ChannelModelKind::tr36885, ChannelModelKind::tr37885_urban, ChannelModelKind::tr37885_highway}) {
    StochasticOptions o;
    o.seed = 77;
    auto m1 = make_channel_model(k, t, o), m2 = make_channel_model(k, t, o);
    o.seed = 78;
    auto m3 = make_channel_model(k, t, o);
    struct Q {
      std::size_t f;
      std::uint32_t a, b;
    };
    std::vector<Q> queries;
    for (std::size_t f = 0; f < frames.size(); ++f)
      for (std::uint32_t a = 0; a < n; ++a)
        for (std::uint32_t b = a + 1; b < n; ++b) queries.push_back({f, a, b});
    std::vector<LinkState> first;
    for (const Q& q : queries) first.push_back(m1->link(q.f, q.a, q.b));
    // m2: reversed order, swapped ends, four threads.
    std::vector<LinkState> second(queries.size());
    std::vector<std::thread> threads;
    for (std::size_t w = 0; w < 4; ++w)
      threads.emplace_back([&, w] {
        for (std::size_t i = queries.size(); i-- > 0;)
          if (i % 4 == w) second[i] = m2->link(queries[i].f, queries[i].b, queries[i].a);
      });
    for (auto& th : threads) th.join();
    std::size_t present = 0, differ = 0;
    for (std::size_t i = 0; i < queries.size(); ++i) {
      const Q& q = queries[i];
      ASSERT_EQ(first[i].gain_db, second[i].gain_db) << channel_model_name(k) << " " << q.f << " " << q.a << " " << q.b;
      ASSERT_EQ(first[i].los_class, second[i].los_class);
      ASSERT_EQ(first[i].distance_m, second[i].distance_m);
      const LinkState back = m1->link(q.f, q.b, q.a);
      ASSERT_EQ(first[i].gain_db, back.gain_db);
      const bool here = t.state(q.f, q.a) && t.state(q.f, q.b);
      ASSERT_EQ(std::isinf(first[i].gain_db), !here);
      if (!here) continue;
      ++present;
      differ += m3->link(q.f, q.a, q.b).gain_db != first[i].gain_db;
    }
    EXPECT_GT(present, 3000u);
    EXPECT_GT(differ, present * 9 / 10) << "another seed must give another channel";
  }
}

TEST(ChannelModels, LosFromRay) {
  FrameRecord f;
  for (std::uint32_t i = 0; i < 6; ++i) f.nodes.push_back(at(i, 40.0 * i, 0));
  f.links = {link_rec(0, 1, -70, 0), link_rec(0, 2, -90, 1), link_rec(0, 3, -100, 2),
             link_rec(0, 4, kNoGain, 0, kLinkOutOfRange)};  // (0, 5): not stored
  const ChannelTrace t = ChannelTrace::from_records(vehicles(7), {f}, kFc, 10e6);
  StochasticOptions o;
  o.los_from_ray = true;
  o.shadowing = false;
  const double lf = std::log10(5.9);
  auto urban = make_channel_model(ChannelModelKind::tr37885_urban, t, o);
  EXPECT_EQ(urban->link(0, 1, 0).los_class, 0);
  EXPECT_NEAR(urban->link(0, 0, 1).gain_db, -(38.77 + 16.7 * std::log10(40.0) + 18.2 * lf), 1e-4);
  EXPECT_EQ(urban->link(0, 0, 2).los_class, 1);
  EXPECT_LE(urban->link(0, 0, 2).gain_db, -(38.77 + 16.7 * std::log10(80.0) + 18.2 * lf) + 1e-4);
  EXPECT_EQ(urban->link(0, 0, 3).los_class, 2);
  EXPECT_NEAR(urban->link(0, 0, 3).gain_db, -(36.85 + 30 * std::log10(120.0) + 18.9 * lf), 1e-4);
  EXPECT_EQ(urban->link(0, 0, 4).los_class, 2);  // out of range
  EXPECT_EQ(urban->link(0, 5, 0).los_class, 2);  // not stored
  EXPECT_TRUE(std::isfinite(urban->link(0, 5, 0).gain_db));
  EXPECT_EQ(urban->link(0, 0, 6).gain_db, -std::numeric_limits<double>::infinity());  // node 6 absent
  auto v2v = make_channel_model(ChannelModelKind::tr36885, t, o);
  EXPECT_EQ(v2v->link(0, 0, 1).los_class, 0);
  EXPECT_EQ(v2v->link(0, 0, 2).los_class, 2);  // NLOSV is NLOS in the two-state model
  EXPECT_NEAR(v2v->link(0, 0, 2).gain_db, -formulas::tr36885_pathloss_db(false, 80, kFc, 1.5, 1.5), 1e-4);
  EXPECT_EQ(v2v->kind(), ChannelModelKind::tr36885);
}

TEST(ChannelModels, RayModelReturnsTracedChannel) {
  FrameRecord f;
  f.nodes = {at(0, 0, 0, 6), at(1, 30, 40, 6), at(2, 3, 4, 0), at(4, 100, 0, 0)};
  f.links = {link_rec(0, 1, -75.5f, 1), link_rec(0, 2, -60, 0), link_rec(1, 2, kNoGain, 2, kLinkOutOfRange)};
  const ChannelTrace t = ChannelTrace::from_records(vehicles(5), {f}, kFc, 10e6);
  auto m = make_channel_model(ChannelModelKind::ray, t, StochasticOptions{});
  EXPECT_EQ(m->kind(), ChannelModelKind::ray);
  LinkState s = m->link(0, 1, 0);
  EXPECT_FLOAT_EQ(static_cast<float>(s.gain_db), -75.5f);
  EXPECT_EQ(s.los_class, 1);
  EXPECT_NEAR(s.distance_m, 50.0, 1e-9);
  EXPECT_EQ(m->link(0, 0, 1).gain_db, s.gain_db);
  s = m->link(0, 0, 2);
  EXPECT_FLOAT_EQ(static_cast<float>(s.gain_db), -60.f);
  EXPECT_NEAR(s.distance_m, std::sqrt(9.0 + 16.0 + 36.0), 1e-9);
  for (auto [a, b] : {std::pair(1u, 2u), std::pair(0u, 4u), std::pair(0u, 3u)}) {  // out of range, missing, absent
    s = m->link(0, a, b);
    EXPECT_EQ(s.gain_db, -std::numeric_limits<double>::infinity()) << a << "-" << b;
    EXPECT_EQ(s.los_class, 2);
  }
  EXPECT_NEAR(m->link(0, 4, 0).distance_m, std::sqrt(100.0 * 100.0 + 36.0), 1e-9);  // 3D: the RSU is 6 m up
}

// ---------------------------------------------------------------------------
// ChannelTrace.

namespace {

// RSU 0 and vehicles 1, 2 over three frames; vehicle 1 leaves before the last.
std::vector<FrameRecord> trace_records() {
  std::vector<FrameRecord> out(3);
  for (std::size_t f = 0; f < 3; ++f) {
    out[f].time_s = 0.5 + 0.25 * static_cast<double>(f);  // exact in binary
    for (std::uint32_t n = 0; n < 3; ++n) {
      if (f == 2 && n == 1) continue;
      NodeState s = at(n, 10.0 * n + static_cast<double>(f), -2.0 * n, n == 0 ? 6.0 : 0.0);
      s.vx = 10.f * static_cast<float>(n), s.vy = 0.5f, s.vz = 0.f;
      s.heading_deg = 90.f + static_cast<float>(n);
      out[f].nodes.push_back(s);
    }
  }
  auto add = [](FrameRecord& f, LinkRecord l) {
    const bool in_range = !(l.flags & kLinkOutOfRange);
    l.path_count = in_range ? 1 : 0;
    l.first_delay_s = in_range ? 1e-7 : 0;
    f.links.push_back(l);
    if (in_range) {
      PathRecord p;
      p.a = {1e-4f, 0.f};
      p.tau_s = 1e-7;
      f.paths.push_back(p);
    }
  };
  add(out[0], link_rec(0, 1, -61.5f, 0));
  add(out[0], link_rec(0, 2, -83.25f, 2));
  add(out[0], link_rec(1, 2, kNoGain, 2, kLinkOutOfRange));
  add(out[1], link_rec(0, 1, -62.f, 1, kLinkCached));
  add(out[2], link_rec(0, 2, -84.f, 0));
  return out;
}

std::vector<NodeInfo> trace_nodes() {
  std::vector<NodeInfo> n(3);
  n[0].id = "rsu0", n[0].kind = NodeKind::rsu;
  n[1].id = "veh.a", n[1].vclass = "passenger", n[1].vtype = "DEFAULT_VEHTYPE";
  n[1].length_m = 4.5f, n[1].width_m = 1.8f, n[1].height_m = 1.5f;
  n[2].id = "veh.b", n[2].vclass = "truck", n[2].vtype = "lorry";
  n[2].length_m = 12.f, n[2].width_m = 2.5f, n[2].height_m = 3.75f;
  return n;
}

void write_trace(const fs::path& file, bool finish = true) {
  DatasetHeader h;
  h.raysweep_version = "test";
  h.git_hash = "unknown";
  h.seed = 1234;
  h.carrier_hz = kFc;
  h.bandwidth_hz = 20e6;
  DatasetWriter w(file, h);
  for (const auto& f : trace_records()) w.append(f);
  if (finish) w.finish(trace_nodes(), {"ground", "rsu0", "veh.a", "veh.b"});
}

void check_trace(const ChannelTrace& t) {
  ASSERT_EQ(t.frames(), 3u);
  EXPECT_EQ(t.time(1), 0.75);
  EXPECT_EQ(t.frame_step(), 0.25);
  EXPECT_EQ(t.frame_at(0.0), 0u);
  EXPECT_EQ(t.frame_at(0.5), 0u);
  EXPECT_EQ(t.frame_at(0.74), 0u);
  EXPECT_EQ(t.frame_at(0.75), 1u);
  EXPECT_EQ(t.frame_at(0.9), 1u);
  EXPECT_EQ(t.frame_at(1.0), 2u);
  EXPECT_EQ(t.frame_at(99), 2u);
  ASSERT_EQ(t.nodes().size(), 3u);
  EXPECT_EQ(t.nodes()[2].vtype, "lorry");
  EXPECT_EQ(t.nodes()[0].kind, NodeKind::rsu);
  EXPECT_FLOAT_EQ(t.nodes()[2].height_m, 3.75f);
  EXPECT_EQ(t.states_end(0) - t.states_begin(0), 3);
  EXPECT_EQ(t.states_end(2) - t.states_begin(2), 2);
  const NodeState* s = t.state(1, 2);
  ASSERT_NE(s, nullptr);
  EXPECT_DOUBLE_EQ(s->x, 21.0);
  EXPECT_DOUBLE_EQ(s->y, -4.0);
  EXPECT_FLOAT_EQ(s->vx, 20.f);
  EXPECT_FLOAT_EQ(s->heading_deg, 92.f);
  EXPECT_DOUBLE_EQ(t.state(0, 0)->z, 6.0);
  EXPECT_EQ(t.state(2, 1), nullptr);
  const ChannelTrace::Link* l = t.link(0, 2, 0);
  ASSERT_NE(l, nullptr);
  EXPECT_EQ(l, t.link(0, 0, 2));
  EXPECT_FLOAT_EQ(l->gain_db, -83.25f);
  EXPECT_EQ(l->los_class, 2);
  l = t.link(0, 2, 1);
  ASSERT_NE(l, nullptr);
  EXPECT_EQ(l->gain_db, kNoGain);
  EXPECT_EQ(l->flags, kLinkOutOfRange);
  EXPECT_EQ(t.link(1, 1, 0)->flags, kLinkCached);
  EXPECT_EQ(t.link(1, 0, 2), nullptr);
  EXPECT_EQ(t.link(2, 0, 1), nullptr);
  EXPECT_FLOAT_EQ(t.link(2, 0, 2)->gain_db, -84.f);
  EXPECT_EQ(t.carrier_hz(), kFc);
}

}  // namespace

TEST(ChannelTrace, FromRecords) {
  const ChannelTrace t = ChannelTrace::from_records(trace_nodes(), trace_records(), kFc, 20e6);
  check_trace(t);
  EXPECT_EQ(t.path(), "");

  auto bad = trace_records();
  std::swap(bad[0].links[0], bad[0].links[1]);
  EXPECT_THROW(ChannelTrace::from_records(trace_nodes(), bad, kFc, 20e6), std::invalid_argument);
  bad = trace_records();
  bad[2].links.push_back(link_rec(1, 2, -70, 0));  // node 1 is absent from frame 2
  EXPECT_THROW(ChannelTrace::from_records(trace_nodes(), bad, kFc, 20e6), std::invalid_argument);
  bad = trace_records();
  bad[2].time_s = 0.1;
  EXPECT_THROW(ChannelTrace::from_records(trace_nodes(), bad, kFc, 20e6), std::invalid_argument);
  bad = trace_records();
  std::swap(bad[1].nodes[0], bad[1].nodes[1]);
  EXPECT_THROW(ChannelTrace::from_records(trace_nodes(), bad, kFc, 20e6), std::invalid_argument);
  EXPECT_THROW(ChannelTrace::from_records(vehicles(2), trace_records(), kFc, 20e6), std::invalid_argument);
}

TEST(ChannelTrace, LoadRoundTrip) {
  const fs::path dir = scratch_dir(std::to_string(::getpid()));
  const fs::path file = dir / "trace.h5";
  write_trace(file);
  const ChannelTrace t = ChannelTrace::load(file.string());
  check_trace(t);
  EXPECT_EQ(t.path(), file.string());
  EXPECT_EQ(t.seed(), 1234u);
  EXPECT_EQ(t.bandwidth_hz(), 20e6);
  EXPECT_EQ(t.nodes()[1].id, "veh.a");
  EXPECT_EQ(t.nodes()[1].vclass, "passenger");
  // The ray model over the loaded trace.
  auto m = make_channel_model(ChannelModelKind::ray, t, StochasticOptions{});
  EXPECT_FLOAT_EQ(static_cast<float>(m->link(0, 1, 0).gain_db), -61.5f);
  EXPECT_EQ(m->link(0, 1, 2).gain_db, -std::numeric_limits<double>::infinity());
}

namespace {

// The InputError that loading `file` throws ("" when none).
std::string load_error(const fs::path& file) {
  try {
    ChannelTrace::load(file.string());
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), file.string());
    return e.what();
  }
  return "";
}

}  // namespace

TEST(ChannelTrace, LoadErrors) {
  const fs::path dir = scratch_dir(std::to_string(::getpid()));
  const fs::path text = dir / "notes.h5";
  raysweep::test::write_text(text, "not an HDF5 file\n");
  std::string e = load_error(text);
  EXPECT_NE(e.find(text.string()), std::string::npos) << e;
  EXPECT_NE(e.find("HDF5"), std::string::npos) << e;
  EXPECT_NE(load_error(dir / "missing.h5").find("missing.h5"), std::string::npos);

  const fs::path unfinished = dir / "unfinished.h5";
  write_trace(unfinished, false);
  e = load_error(unfinished);
  EXPECT_NE(e.find("incomplete"), std::string::npos) << e;
  EXPECT_NE(e.find(unfinished.string()), std::string::npos) << e;

  auto corrupt = [&](const std::string& name, auto&& edit) {
    const fs::path p = dir / name;
    write_trace(p);
    {
      H5 f{H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
      EXPECT_GE(f.id, 0);
      edit(f.id);
    }
    return load_error(p);
  };
  e = corrupt("version.h5", [](hid_t f) {
    H5Adelete(f, "schema_version");
    H5 t{H5Tcopy(H5T_C_S1), H5Tclose};
    H5Tset_size(t.id, H5T_VARIABLE);
    H5 s{H5Screate(H5S_SCALAR), H5Sclose};
    H5 a{H5Acreate2(f, "schema_version", t.id, s.id, H5P_DEFAULT, H5P_DEFAULT), H5Aclose};
    const char* v = "2.0.0";
    H5Awrite(a.id, t.id, &v);
  });
  EXPECT_NE(e.find("schema_version"), std::string::npos) << e;
  EXPECT_NE(e.find("2.0.0"), std::string::npos) << e;
  e = corrupt("norx.h5", [](hid_t f) { H5Ldelete(f, "/links/rx", H5P_DEFAULT); });
  EXPECT_NE(e.find("/links/rx"), std::string::npos) << e;
  EXPECT_NE(e.find("missing"), std::string::npos) << e;
  e = corrupt("offset.h5", [](hid_t f) {
    H5 d{H5Dopen2(f, "/frames/link_offset", H5P_DEFAULT), H5Dclose};
    H5 fs_{H5Dget_space(d.id), H5Sclose};
    const hsize_t row = 1, count = 1;
    H5Sselect_hyperslab(fs_.id, H5S_SELECT_SET, &row, nullptr, &count, nullptr);
    H5 ms{H5Screate_simple(1, &count, nullptr), H5Sclose};
    const std::uint64_t v = 2;
    H5Dwrite(d.id, H5T_NATIVE_UINT64, ms.id, fs_.id, H5P_DEFAULT, &v);
  });
  EXPECT_NE(e.find("/frames/link_offset"), std::string::npos) << e;
  e = corrupt("unsorted.h5", [](hid_t f) {  // frame 0's links become (0,2), (0,2), (1,2)
    H5 d{H5Dopen2(f, "/links/rx", H5P_DEFAULT), H5Dclose};
    H5 fs_{H5Dget_space(d.id), H5Sclose};
    const hsize_t row = 0, count = 1;
    H5Sselect_hyperslab(fs_.id, H5S_SELECT_SET, &row, nullptr, &count, nullptr);
    H5 ms{H5Screate_simple(1, &count, nullptr), H5Sclose};
    const std::uint32_t v = 2;
    H5Dwrite(d.id, H5T_NATIVE_UINT32, ms.id, fs_.id, H5P_DEFAULT, &v);
  });
  EXPECT_NE(e.find("/links"), std::string::npos) << e;
  EXPECT_NE(e.find("sorted"), std::string::npos) << e;
}
