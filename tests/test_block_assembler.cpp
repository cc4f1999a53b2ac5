// The sweep's block assembler: blocks appended in order on its own thread, their
// statistics summed, the shard record written last; a failure on its thread
// surfaces in the caller and leaves no file behind.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "generators/dataset_reader.hpp"
#include "generators/frame_block.hpp"
#include "meshkit/errors.hpp"
#include "pipeline/block_assembler.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace raysweep;
using nlohmann::json;

namespace {

fs::path tmp_dir(const std::string& name) {
  return test::scratch_dir(name + "-" + std::to_string(::getpid()));
}

generators::FrameRecord frame(double t, float gain) {
  generators::FrameRecord f;
  f.time_s = t;
  f.nodes.resize(2);
  f.nodes[0].node = 0;
  f.nodes[1].node = 1;
  f.nodes[1].x = 10 * t;
  generators::LinkRecord l;
  l.tx = 0;
  l.rx = 1;
  l.path_count = 1;
  l.gain_coherent_db = l.gain_incoherent_db = gain;
  f.links = {l};
  generators::PathRecord p;
  p.a = {1e-4f * gain, 0};
  p.tau_s = 1e-7 * t;
  p.interaction_count = 1;
  f.paths = {p};
  generators::InteractionRecord in;
  in.type = 1;
  in.object = 0;
  f.interactions = {in};
  return f;
}

// Block b of `frames` frames (times 10 b + k) and its statistics file.
void write_block(const fs::path& parts, std::uint64_t b, int frames, std::uint64_t rays) {
  generators::FrameBlockWriter w(parts / (pipeline::block_name(b) + ".bin"));
  for (int k = 0; k < frames; ++k) w.append(frame(10.0 * b + k, -60.f - k));
  w.commit();
  std::ofstream(parts / (pipeline::block_name(b) + ".json")) << json{{"frames", frames}, {"rays", rays}}.dump();
}

std::vector<generators::NodeInfo> nodes() {
  std::vector<generators::NodeInfo> n(2);
  n[0].id = "a";
  n[1].id = "b";
  return n;
}

const json kTotals = {{"frames", 0}, {"rays", 0}};

}  // namespace

TEST(BlockAssembler, AppendsBlocksInOrderSumsTheirStatisticsAndWritesTheShardLast) {
  const fs::path dir = tmp_dir("assembler");
  write_block(dir, 0, 3, 100);
  write_block(dir, 1, 2, 40);
  write_block(dir, 3, 1, 7);  // a block of another shard's between them is simply not added
  const fs::path tmp = dir / "d.h5.tmp";
  json totals;
  {
    pipeline::BlockAssembler a(tmp, generators::DatasetHeader{}, dir, kTotals);
    a.add(0);
    a.add(1);
    a.add(3);
    totals = a.finish(nodes(), {"ground"}, R"({"index": 0, "count": 2})");
  }
  EXPECT_EQ(totals, (json{{"frames", 6}, {"rays", 147}}));
  generators::DatasetReader r(tmp);
  EXPECT_TRUE(r.complete());
  ASSERT_EQ(r.frame_count(), 6u);
  const auto frames = r.frames(0, 6);
  const std::vector<double> times = {0, 1, 2, 10, 11, 30};
  const std::vector<float> gains = {-60, -61, -62, -60, -61, -60};
  for (std::size_t k = 0; k < 6; ++k) {
    EXPECT_EQ(frames[k].time_s, times[k]) << k;
    ASSERT_EQ(frames[k].links.size(), 1u);
    EXPECT_EQ(frames[k].links[0].gain_coherent_db, gains[k]) << k;
    EXPECT_EQ(frames[k].nodes[1].x, 10 * times[k]) << k;
  }
  EXPECT_EQ(json::parse(r.header().shard), (json{{"index", 0}, {"count", 2}}));
}

TEST(BlockAssembler, AFailureOnItsThreadSurfacesAndLeavesNoFile) {
  const fs::path dir = tmp_dir("assembler-bad");
  write_block(dir, 0, 2, 1);
  std::ofstream(dir / (pipeline::block_name(1) + ".bin")) << "not a frame block";
  std::ofstream(dir / (pipeline::block_name(1) + ".json")) << R"({"frames": 1, "rays": 1})";
  const fs::path tmp = dir / "d.h5.tmp";
  {
    pipeline::BlockAssembler a(tmp, generators::DatasetHeader{}, dir, kTotals);
    a.add(0);
    a.add(1);
    EXPECT_TRUE(fs::exists(tmp));
    try {
      a.finish(nodes(), {"ground"}, "");
      ADD_FAILURE() << "finish() accepted a corrupt block";
    } catch (const meshkit::InputError& e) {
      EXPECT_NE(std::string(e.what()).find("block_000001.bin"), std::string::npos) << e.what();
    }
  }
  EXPECT_FALSE(fs::exists(tmp));
  // Abandoned before finish(): the same.
  {
    pipeline::BlockAssembler a(tmp, generators::DatasetHeader{}, dir, kTotals);
    a.add(0);
  }
  EXPECT_FALSE(fs::exists(tmp));
}
