// SINR channel models (generators/sinr/channel_models.cpp): 3GPP formulas
// against hand-computed values, LoS / shadowing statistics, spatial
// consistency, determinism across query orders and threads, the traced (ray)
// model. Loading traces: test_channel_trace.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "channel_fixtures.hpp"
#include "generators/sinr/channel_models.hpp"
#include "generators/sinr/channel_trace.hpp"

using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using namespace raysweep::generators::sinr::channel_fixtures;
using Scen = formulas::Tr37885Scenario;

namespace {

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
