// `raysweep sinr` and `raysweep report` end to end on a synthetic channel
// dataset: a valid SINR file with provenance, baselines evaluated on the very
// transmissions of the ray run, the report's PNGs and table, determinism
// across thread counts, bad input that names the file and writes nothing, and
// `raysweep run` including the SINR stage (skipped when up to date).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <limits>

#include "generators/dataset/dataset_writer.hpp"
#include "generators/sinr/sinr_file.hpp"
#include "test_util.hpp"

using namespace raysweep::test;
using nlohmann::json;
namespace gen = raysweep::generators;

namespace {

// Twelve vehicles on two parallel streets 30 m apart, driving at different
// speeds for 4 s at 10 Hz. Links across the streets are NLOS (a building row),
// links along a street LOS, with a free-space-like gain.
fs::path synthetic_channels(const fs::path& dir) {
  const fs::path path = dir / "channels.h5";
  gen::DatasetHeader h;
  h.raysweep_version = "test";
  h.git_hash = "test";
  h.config = json::object();
  h.inputs = json::array();
  h.provenance = json::object();
  h.carrier_hz = 5.9e9;
  h.bandwidth_hz = 10e6;
  gen::DatasetWriter w(path, h);
  std::vector<gen::NodeInfo> nodes;
  for (int i = 0; i < 12; ++i) nodes.push_back({"veh" + std::to_string(i), gen::NodeKind::vehicle, "passenger", "car", 4.5f, 1.8f, 1.5f});
  for (int f = 0; f < 40; ++f) {
    gen::FrameRecord fr;
    fr.time_s = 0.1 * f;
    for (std::uint32_t i = 0; i < 12; ++i) {
      gen::NodeState s;
      s.node = i;
      const double v = 8.0 + i;
      s.x = 40.0 * (i % 6) + v * fr.time_s;
      s.y = i < 6 ? 0.0 : 30.0;
      s.vx = static_cast<float>(v);
      s.heading_deg = 90;
      fr.nodes.push_back(s);
    }
    for (std::uint32_t a = 0; a < 12; ++a)
      for (std::uint32_t b = a + 1; b < 12; ++b) {
        const auto& p = fr.nodes[a];
        const auto& q = fr.nodes[b];
        const double d = std::hypot(p.x - q.x, p.y - q.y);
        gen::LinkRecord l;
        l.tx = a;
        l.rx = b;
        const bool same_street = (a < 6) == (b < 6);
        l.los_class = same_street ? 0 : 2;
        l.gain_incoherent_db = static_cast<float>(-47.85 - 20 * std::log10(d) - (same_street ? 0 : 35));
        l.gain_coherent_db = l.gain_incoherent_db;
        fr.links.push_back(l);
      }
    w.append(fr);
  }
  std::vector<std::string> objects;
  for (const auto& n : nodes) objects.push_back(n.id);
  w.finish(nodes, objects);
  return path;
}

std::string sinr_args(const fs::path& channels, const fs::path& out, const fs::path& config) {
  return "sinr --channels " + channels.string() + " --out " + out.string() + " --config " + config.string();
}

void write_sinr_config(const fs::path& p, const std::string& extra = "") {
  write_text(p, "[sinr]\nseed = 7\nnr_fraction = 0.5\n" + extra);
}

}  // namespace

TEST(CliSinr, OutcomesValidateAndBaselinesReuseTheRaySchedule) {
  auto dir = scratch_dir("cli_sinr");
  const auto channels = synthetic_channels(dir);
  write_sinr_config(dir / "s.toml");
  auto r = run_raysweep(sinr_args(channels, dir / "ray.h5", dir / "s.toml"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("PRR 80211p"), std::string::npos) << r.output;
  EXPECT_EQ(run_raysweep("validate " + (dir / "ray.h5").string()).exit_code, 0);
  r = run_raysweep("info --json " + (dir / "ray.h5").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json info = json::parse(r.output);
  EXPECT_EQ(info["format"], "raysweep-sinr");
  EXPECT_EQ(info["channel_model"], "ray");
  EXPECT_GT(info["transmissions"].get<int>(), 100);  // 12 vehicles x 4 s of CAMs
  EXPECT_GT(info["receptions"].get<int>(), info["transmissions"].get<int>());

  // Provenance: the channel file's hash, the config and the seed are in the file.
  const auto sched = gen::sinr::read_sinr_schedule((dir / "ray.h5").string());
  EXPECT_EQ(sched.config["seed"], 7);
  EXPECT_EQ(sched.config["channel_model"], "ray");
  r = run_command("h5dump -a /inputs " + (dir / "ray.h5").string());
  if (r.exit_code == 0) {
    EXPECT_NE(r.output.find("sha256"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("channels.h5"), std::string::npos) << r.output;
  }

  // A baseline on the same transmissions: identical schedule, other outcomes.
  r = run_raysweep(sinr_args(channels, dir / "urban.h5", dir / "s.toml") +
                   " --channel-model tr37885-urban --los-from-ray --schedule-from " + (dir / "ray.h5").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto base = gen::sinr::read_sinr_schedule((dir / "urban.h5").string());
  ASSERT_EQ(base.transmissions.size(), sched.transmissions.size());
  for (std::size_t i = 0; i < base.transmissions.size(); ++i) {
    EXPECT_EQ(base.transmissions[i].node, sched.transmissions[i].node);
    EXPECT_EQ(base.transmissions[i].start_s, sched.transmissions[i].start_s);
    EXPECT_EQ(base.transmissions[i].packet, sched.transmissions[i].packet);
  }
  for (std::size_t n = 0; n < base.nodes.size(); ++n) EXPECT_EQ(base.nodes[n].rat, sched.nodes[n].rat);

  // The report: PNGs and a table with the disagreement ratios.
  r = run_raysweep("report --sinr " + (dir / "ray.h5").string() + " " + (dir / "urban.h5").string() + " --out " +
                   (dir / "report").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("DR decodability"), std::string::npos) << r.output;
  for (const char* f : {"sinr_pdf.png", "prr_distance.png", "report.md", "report.json"}) {
    ASSERT_TRUE(fs::exists(dir / "report" / f)) << f;
    EXPECT_GT(fs::file_size(dir / "report" / f), 500u) << f;
  }
}

TEST(CliSinr, SameSeedSameBytesWhateverTheThreadCount) {
  auto dir = scratch_dir("cli_sinr_det");
  const auto channels = synthetic_channels(dir);
  write_sinr_config(dir / "s.toml", "nr_retransmissions = 1\nnr_selection = \"sensing\"\n");
  for (const char* m : {"ray", "tr37885-urban"}) {
    const std::string model = std::string(" --channel-model ") + m;
    // The same output name: the command line is part of the provenance (-j is not).
    ASSERT_EQ(run_raysweep("-j 1 " + sinr_args(channels, dir / "o.h5", dir / "s.toml") + model).exit_code, 0);
    const std::string one = read_text(dir / "o.h5");
    ASSERT_EQ(run_raysweep("-j 2 " + sinr_args(channels, dir / "o.h5", dir / "s.toml") + model).exit_code, 0);
    EXPECT_EQ(one, read_text(dir / "o.h5")) << m;
    ASSERT_EQ(run_raysweep(sinr_args(channels, dir / "c.h5", dir / "s.toml") + model + " --seed 8").exit_code, 0);
    const auto a = gen::sinr::read_sinr_schedule((dir / "o.h5").string());
    const auto c = gen::sinr::read_sinr_schedule((dir / "c.h5").string());
    bool differ = a.transmissions.size() != c.transmissions.size();
    for (std::size_t i = 0; !differ && i < a.transmissions.size(); ++i)
      differ = a.transmissions[i].start_s != c.transmissions[i].start_s;
    EXPECT_TRUE(differ) << m << ": another seed gives other CAM phases";
  }
}

TEST(CliSinr, BadInputNamesTheFileAndWritesNothing) {
  auto dir = scratch_dir("cli_sinr_bad");
  const auto channels = synthetic_channels(dir);
  write_sinr_config(dir / "s.toml");
  const fs::path out = dir / "out.h5";
  auto expect_fails = [&](const std::string& args, const std::string& needle) {
    auto r = run_raysweep(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(needle), std::string::npos) << args << "\n" << r.output;
    EXPECT_FALSE(fs::exists(out)) << args;
    EXPECT_FALSE(fs::exists(out.string() + ".tmp")) << args;
  };
  write_text(dir / "notes.h5", "not HDF5\n");
  expect_fails(sinr_args(dir / "notes.h5", out, dir / "s.toml"), "notes.h5");
  write_text(dir / "typo.toml", "[sinr]\nseed = 1\nnr_fractoin = 0.5\n");
  expect_fails(sinr_args(channels, out, dir / "typo.toml"), "typo.toml:3: sinr.nr_fractoin: unknown key (did you mean 'nr_fraction'?)");
  write_text(dir / "range.toml", "[sinr]\nnr_fraction = 1.5\n");
  expect_fails(sinr_args(channels, out, dir / "range.toml"), "nr_fraction");
  write_text(dir / "big.toml", "[sinr]\ncam_bytes = 2000\n");
  expect_fails(sinr_args(channels, out, dir / "big.toml"), "subchannels");
  expect_fails(sinr_args(channels, out, dir / "s.toml") + " --channel-model winner", "unknown channel model");
  write_text(dir / "ids.toml", "[sinr]\nnr_ids = [\"veh99\"]\n");
  expect_fails(sinr_args(channels, out, dir / "ids.toml"), "veh99");
  // A schedule from a file that is not a SINR file.
  expect_fails(sinr_args(channels, out, dir / "s.toml") + " --schedule-from " + channels.string(), "channels.h5");
  // The report refuses a channel dataset.
  auto r = run_raysweep("report --sinr " + channels.string() + " --out " + (dir / "rep").string());
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("channels.h5"), std::string::npos) << r.output;
}

TEST(CliSinr, ReportNumbersMatchHandComputedSets) {
  // The report script's own test: DR, PRR and bimodality against hand-built files.
  if (!fs::exists("/usr/bin/python3") || run_command("/usr/bin/python3 -c 'import h5py, matplotlib'").exit_code != 0)
    GTEST_SKIP() << "python3 with h5py and matplotlib needed";
  auto r = run_command("/usr/bin/python3 " + (source_dir() / "tests/python/test_sinr_report.py").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
}
