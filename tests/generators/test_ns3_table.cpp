// The ns-3 lookup table (generators/ns3_table.hpp): build from a channel
// dataset whose CFRs are known in closed form, read back, validate, summarise,
// and refuse corrupt files with messages naming the file and element.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <fstream>
#include <limits>

#include "generators/dataset_schema.hpp"
#include "generators/dataset_writer.hpp"
#include "generators/ns3_table.hpp"
#include "meshkit/errors.hpp"
#include "test_util.hpp"

namespace rg = raysweep::generators;
namespace fs = std::filesystem;
using namespace raysweep::test;

namespace {

constexpr std::uint32_t kK = 8;  // subcarriers
constexpr double kSpacing = 156250, kCarrier = 5.9e9;

// |H_k| = amp(a, b, f) * (1 + k / 8): mean |H|^2 and band means in closed form.
double amp(std::uint32_t a, std::uint32_t b, std::size_t f) { return 1e-3 * (1 + a + 2 * b + 0.1 * f); }
double hk(std::uint32_t a, std::uint32_t b, std::size_t f, std::uint32_t k) { return amp(a, b, f) * (1 + k / 8.0); }

// 3 nodes, 4 frames; node 2 only in frames 2 and 3; link (0, 1) of frame 1 has no path.
fs::path write_dataset(const fs::path& dir, bool with_cfr) {
  rg::DatasetHeader h;
  h.raysweep_version = "test";
  h.git_hash = "test";
  h.config = nlohmann::json::object();
  h.inputs = nlohmann::json::array();
  h.provenance = nlohmann::json::object();
  h.carrier_hz = kCarrier;
  h.bandwidth_hz = 10e6;
  h.cfr_subcarriers = with_cfr ? kK : 0;
  h.cfr_subcarrier_spacing_hz = with_cfr ? kSpacing : 0;
  const fs::path file = dir / (with_cfr ? "cfr.h5" : "plain.h5");
  rg::DatasetWriter w(file, h);
  for (std::size_t f = 0; f < 4; ++f) {
    rg::FrameRecord fr;
    fr.time_s = 5.0 + 0.1 * f;
    const std::uint32_t n = f >= 2 ? 3 : 2;
    for (std::uint32_t i = 0; i < n; ++i) {
      rg::NodeState s;
      s.node = i;
      s.x = 10.0 * i + f;
      s.y = -2.0 * i;
      s.z = 0.3;
      s.vx = 10;
      s.vy = static_cast<float>(i);
      fr.nodes.push_back(s);
    }
    for (std::uint32_t a = 0; a < n; ++a)
      for (std::uint32_t b = a + 1; b < n; ++b) {
        rg::LinkRecord l;
        l.tx = a;
        l.rx = b;
        l.los_class = static_cast<std::uint8_t>((a + b + f) % 3);
        const bool no_path = f == 1 && a == 0 && b == 1;
        const double g = no_path ? -std::numeric_limits<double>::infinity() : 20 * std::log10(amp(a, b, f)) - 3;
        l.gain_coherent_db = l.gain_incoherent_db = static_cast<float>(g);
        l.path_count = 0;
        fr.links.push_back(l);
        if (with_cfr)
          for (std::uint32_t k = 0; k < kK; ++k)
            fr.cfr.emplace_back(no_path ? 0.0f : static_cast<float>(hk(a, b, f, k)), 0.0f);
      }
    w.append(fr);
  }
  std::vector<rg::NodeInfo> nodes(3);
  for (std::uint32_t i = 0; i < 3; ++i) nodes[i].id = "veh" + std::to_string(i);
  w.finish(nodes, {});
  return file;
}

rg::Ns3TableHeader header() {
  rg::Ns3TableHeader h;
  h.raysweep_version = "test";
  h.git_hash = "test";
  h.config = nlohmann::json::object();
  h.inputs = nlohmann::json::array();
  h.provenance = {{"stage", "test"}};
  return h;
}

}  // namespace

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

TEST(Ns3Table, CorruptFilesNameFileAndElement) {
  const fs::path dir = scratch_dir("ns3_table_corrupt");
  const fs::path good = dir / "good.h5";
  rg::build_ns3_table(write_dataset(dir, true).string(), good, header(), 4);
  auto load_error = [](const fs::path& p) {
    try {
      rg::Ns3Table::load(p.string());
    } catch (const raysweep::meshkit::InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  // Missing, not HDF5, truncated.
  EXPECT_NE(load_error(dir / "missing.h5").find((dir / "missing.h5").string()), std::string::npos);
  write_text(dir / "text.h5", "not hdf5");
  EXPECT_NE(load_error(dir / "text.h5").find("not an HDF5 file"), std::string::npos);
  {
    const std::string bytes = read_text(good);
    write_text(dir / "half.h5", bytes.substr(0, bytes.size() / 2));
  }
  EXPECT_NE(load_error(dir / "half.h5").find((dir / "half.h5").string()), std::string::npos);
  EXPECT_FALSE(rg::validate_dataset((dir / "half.h5").string()).empty());
  // A channel dataset is not a table.
  const std::string e = load_error(dir / "cfr.h5");
  EXPECT_NE(e.find("attribute format"), std::string::npos) << e;
  // Through the CLI: validate says INVALID (exit 1), info fails naming the file (exit 2).
  const auto v = run_raysweep("validate " + (dir / "half.h5").string());
  EXPECT_EQ(v.exit_code, 1) << v.output;
  const auto i = run_raysweep("info " + (dir / "text.h5").string());
  EXPECT_EQ(i.exit_code, 2) << i.output;
  EXPECT_NE(i.output.find("text.h5"), std::string::npos);
}

TEST(Ns3Table, CliWritesThroughATemporaryFileAndRecordsProvenance) {
  const fs::path dir = scratch_dir("ns3_table_cli");
  const fs::path ds = write_dataset(dir, true);
  write_text(dir / "c.toml", "[ns3]\nsubcarriers_per_band = 2\n");
  const auto r = run_raysweep("-q ns3-table --channels " + ds.string() + " --out " + (dir / "t.h5").string() +
                              " --config " + (dir / "c.toml").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_FALSE(fs::exists(dir / "t.h5.tmp"));
  const rg::Ns3Table t = rg::Ns3Table::load((dir / "t.h5").string());
  EXPECT_EQ(t.bands().count(), 4u);
  EXPECT_EQ(t.provenance().value("stage", std::string()), "ns3-table");
  const auto v = run_raysweep("validate " + (dir / "t.h5").string());
  EXPECT_EQ(v.exit_code, 0) << v.output;
  // Usage and config errors: exit 2, naming the key.
  write_text(dir / "bad.toml", "[ns3]\nbands = 2\n");
  const auto b = run_raysweep("ns3-table --channels " + ds.string() + " --out " + (dir / "u.h5").string() +
                              " --config " + (dir / "bad.toml").string());
  EXPECT_EQ(b.exit_code, 2);
  EXPECT_NE(b.output.find("ns3.bands"), std::string::npos) << b.output;
  EXPECT_FALSE(fs::exists(dir / "u.h5"));
  EXPECT_EQ(run_raysweep("ns3-table --out x.h5").exit_code, 2);
}

TEST(Ns3Table, EmbeddedSchemaMatchesSourceFile) {
  EXPECT_EQ(rg::ns3_table_schema_json(), read_text(source_dir() / "schemas" / "raysweep_ns3_table.schema.json"));
}
