// The coexistence SINR (generators/sinr/coexistence.cpp, VaN3Twin Algorithm 1)
// by hand: a three-node 802.11p reception, NR per resource block, and the
// decoding rule.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "generators/sinr/coexistence.hpp"
#include "generators/sinr/phy.hpp"
#include "generators/sinr/schedule.hpp"
#include "generators/sinr/sinr_config.hpp"
#include "sinr_fixtures.hpp"

using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using namespace raysweep::generators::sinr::fixtures;

namespace {

double mw(double dbm) { return std::pow(10.0, dbm / 10.0); }
double to_dbm(double mw_) { return 10.0 * std::log10(mw_); }

}  // namespace

// ===========================================================================
// Coexistence SINR by hand.

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
