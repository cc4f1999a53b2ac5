// SINR settings checks (generators/sinr/sinr_config.cpp): the defaults pass,
// every bad setting throws.
#include <gtest/gtest.h>

#include <stdexcept>

#include "generators/sinr/sinr_config.hpp"
#include "sinr_fixtures.hpp"

using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using namespace raysweep::generators::sinr::fixtures;

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
