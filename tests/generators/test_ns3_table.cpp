// The ns-3 lookup table (generators/ns3_table/ns3_table.hpp): build from a channel
// dataset whose CFRs are known in closed form, read back, validate and
// summarise. Corrupt files and the ns3-table command:
// tests/cli/test_cli_ns3_table.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <fstream>
#include <limits>

#include "generators/dataset/dataset_writer.hpp"
#include "generators/formats.hpp"
#include "generators/ns3_table/ns3_table.hpp"
#include "meshkit/errors.hpp"
#include "ns3_table_fixtures.hpp"
#include "test_util.hpp"

namespace rg = raysweep::generators;
namespace fs = std::filesystem;
using namespace raysweep::test;
using namespace raysweep::test::ns3;

TEST(Ns3Table, BuildFromCfrRoundTrip) {
  const fs::path dir = scratch_dir("ns3_table_cfr");
  const fs::path table = dir / "table.h5";
  const auto stats = rg::build_ns3_table(write_dataset(dir, true).string(), table, header(), 4);
  EXPECT_EQ(stats.frames, 4u);
  EXPECT_EQ(stats.pairs, 1u + 1u + 3u + 3u);
  EXPECT_EQ(stats.bands, 2u);
  EXPECT_EQ(stats.gain_source, rg::GainSource::cfr);
  EXPECT_TRUE(rg::validate_dataset(table.string()).empty());

  const rg::Ns3Table t = rg::Ns3Table::load(table.string());
  EXPECT_EQ(t.gain_source(), rg::GainSource::cfr);
  EXPECT_EQ(t.node_ids(), (std::vector<std::string>{"veh0", "veh1", "veh2"}));
  EXPECT_DOUBLE_EQ(t.carrier_hz(), kCarrier);
  ASSERT_EQ(t.frames(), 4u);
  EXPECT_NEAR(t.frame_step(), 0.1, 1e-12);
  // Bands: subcarriers 0..3 and 4..7 around the carrier (k - K/2) * spacing.
  ASSERT_EQ(t.bands().count(), 2u);
  EXPECT_NEAR(t.bands().center_hz[0], kCarrier + (1.5 - 4) * kSpacing, 1e-3);
  EXPECT_NEAR(t.bands().center_hz[1], kCarrier + (5.5 - 4) * kSpacing, 1e-3);
  EXPECT_DOUBLE_EQ(t.bands().band_width_hz, 4 * kSpacing);
  for (std::size_t f = 0; f < 4; ++f) {
    const std::uint32_t n = f >= 2 ? 3 : 2;
    for (std::uint32_t a = 0; a < n; ++a)
      for (std::uint32_t b = a + 1; b < n; ++b) {
        const auto row = t.pair_row(f, b, a);  // either order
        ASSERT_TRUE(row) << f << " " << a << " " << b;
        EXPECT_EQ(t.los_class(*row), (a + b + f) % 3);
        if (f == 1 && a == 0 && b == 1) {
          EXPECT_TRUE(std::isinf(t.gain_db(*row)) && t.gain_db(*row) < 0);
          continue;
        }
        double mean = 0, band[2] = {0, 0};
        for (std::uint32_t k = 0; k < kK; ++k) {
          mean += hk(a, b, f, k) * hk(a, b, f, k) / kK;
          band[k / 4] += hk(a, b, f, k) * hk(a, b, f, k) / 4;
        }
        EXPECT_NEAR(t.gain_db(*row), 10 * std::log10(mean), 1e-4);
        EXPECT_NEAR(t.band_gain_db(*row)[0], 10 * std::log10(band[0]), 1e-4);
        EXPECT_NEAR(t.band_gain_db(*row)[1], 10 * std::log10(band[1]), 1e-4);
      }
    for (std::uint32_t i = 0; i < n; ++i) {
      const auto* s = t.state(f, i);
      ASSERT_NE(s, nullptr);
      EXPECT_DOUBLE_EQ(s->x, 10.0 * i + f);
      EXPECT_FLOAT_EQ(s->vy, static_cast<float>(i));
    }
  }
  EXPECT_FALSE(t.pair_row(0, 0, 2));  // node 2 absent in frame 0
  EXPECT_EQ(t.state(0, 2), nullptr);
  // Sample and hold, and the window: first frame .. last frame + one step.
  EXPECT_EQ(t.frame_at(5.0), 0u);
  EXPECT_EQ(t.frame_at(5.1999), 1u);
  EXPECT_EQ(t.frame_at(5.35), 3u);
  EXPECT_FALSE(t.frame_at(4.999));
  EXPECT_FALSE(t.frame_at(5.41));

  const auto info = rg::dataset_info(table.string());
  EXPECT_EQ(info["format"], rg::kNs3TableFormat);
  EXPECT_EQ(info["pairs"], 8);
  EXPECT_EQ(info["bands"], 2);
  EXPECT_EQ(info["gain_source"], "cfr");
  EXPECT_NE(rg::format_dataset_info(info).find("bytes per pair-frame"), std::string::npos);
}

TEST(Ns3Table, WithoutCfrTheIncoherentGain) {
  const fs::path dir = scratch_dir("ns3_table_plain");
  const fs::path table = dir / "table.h5";
  const auto stats = rg::build_ns3_table(write_dataset(dir, false).string(), table, header(), 4);
  EXPECT_EQ(stats.gain_source, rg::GainSource::incoherent);
  EXPECT_EQ(stats.bands, 0u);
  EXPECT_TRUE(rg::validate_dataset(table.string()).empty());
  const rg::Ns3Table t = rg::Ns3Table::load(table.string());
  const auto row = t.pair_row(2, 1, 2);
  ASSERT_TRUE(row);
  EXPECT_NEAR(t.gain_db(*row), 20 * std::log10(amp(1, 2, 2)) - 3, 1e-4);
  EXPECT_EQ(t.band_gain_db(*row), nullptr);
}

TEST(Ns3Table, BandsMustDivideTheSubcarriers) {
  const fs::path dir = scratch_dir("ns3_table_bands");
  EXPECT_THROW(rg::build_ns3_table(write_dataset(dir, true).string(), dir / "t.h5", header(), 3), std::invalid_argument);
}

TEST(Ns3Table, WriterRejectsInconsistentFrames) {
  const fs::path dir = scratch_dir("ns3_table_writer");
  rg::Ns3TableHeader h = header();
  h.carrier_hz = kCarrier;
  h.bandwidth_hz = 10e6;
  rg::Ns3TableWriter w(dir / "t.h5", h, {});
  std::vector<rg::NodeState> st(2);
  st[1].node = 1;
  EXPECT_THROW(w.add_frame(1.0, st, {{1, 0, -60, 0}}, {}), std::invalid_argument);   // a > b
  EXPECT_THROW(w.add_frame(1.0, st, {{0, 2, -60, 0}}, {}), std::invalid_argument);   // node 2 absent
  EXPECT_THROW(w.add_frame(1.0, st, {{0, 1, NAN, 0}}, {}), std::invalid_argument);   // NaN gain
  EXPECT_THROW(w.add_frame(1.0, st, {{0, 1, -60, 3}}, {}), std::invalid_argument);   // LoS class
  w.add_frame(1.0, st, {{0, 1, -60, 0}}, {});
  EXPECT_THROW(w.add_frame(1.0, st, {{0, 1, -60, 0}}, {}), std::invalid_argument);   // time not after
  EXPECT_THROW(w.finish({rg::NodeInfo{}}), std::invalid_argument);                    // node 1 beyond the table
}

TEST(Ns3Table, EmbeddedSchemaMatchesSourceFile) {
  EXPECT_EQ(rg::ns3_table_schema_json(), read_text(source_dir() / "schemas" / "raysweep_ns3_table.schema.json"));
}
