// SINR generator PHY arithmetic (generators/sinr/phy.cpp) against IEEE 802.11
// and 3GPP hand computations: frame durations, rates, bands, NR numerologies
// and resource blocks, noise and overlap.
#include <gtest/gtest.h>

#include <cmath>
#include <utility>

#include "generators/sinr/phy.hpp"
#include "generators/sinr/sinr_config.hpp"
#include "sinr_fixtures.hpp"

using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using namespace raysweep::generators::sinr::fixtures;

namespace {

constexpr double kUs = 1e-6;

}  // namespace

// ===========================================================================
// PHY arithmetic.

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
