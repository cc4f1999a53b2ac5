// The SINR generator's vocabulary (generators/sinr/types.cpp): RAT and message
// names.
#include <gtest/gtest.h>

#include <stdexcept>

#include "generators/sinr/types.hpp"
#include "sinr_fixtures.hpp"

using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using namespace raysweep::generators::sinr::fixtures;

TEST(SinrPhy, RatNames) {
  EXPECT_STREQ(rat_name(Rat::none), "none");
  EXPECT_STREQ(rat_name(Rat::wifi80211p), "80211p");
  EXPECT_STREQ(rat_name(Rat::nr_v2x), "nrv2x");
  for (Rat r : {Rat::none, Rat::wifi80211p, Rat::nr_v2x}) EXPECT_EQ(parse_rat(rat_name(r)), r);
  EXPECT_THROW(parse_rat("lte"), std::invalid_argument);
  EXPECT_STREQ(message_name(Message::cam), "cam");
  EXPECT_STREQ(message_name(Message::cpm), "cpm");
}
