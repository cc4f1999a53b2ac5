// Frame blocks (generators/sweep/frame_block.cpp): the exact round trip, the streamed
// layout read back in chunks, truncated and corrupt blocks.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "dataset_fixtures.hpp"
#include "generators/sweep/frame_block.hpp"
#include "hdf5_test_util.hpp"
#include "meshkit/errors.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace raysweep::generators;
using namespace raysweep::generators::fixtures;
using raysweep::meshkit::InputError;
using raysweep::test::read_bytes;

// ---------------------------------------------------------------------------
// Frame blocks.

namespace {

void expect_same(const std::vector<FrameRecord>& a, const std::vector<FrameRecord>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t f = 0; f < a.size(); ++f) {
    const auto &x = a[f], &y = b[f];
    EXPECT_EQ(bits(x.time_s), bits(y.time_s));
    ASSERT_EQ(x.nodes.size(), y.nodes.size());
    for (std::size_t i = 0; i < x.nodes.size(); ++i) {
      const auto &p = x.nodes[i], &q = y.nodes[i];
      EXPECT_EQ(p.node, q.node);
      EXPECT_EQ(bits(p.x), bits(q.x));
      EXPECT_EQ(bits(p.y), bits(q.y));
      EXPECT_EQ(bits(p.z), bits(q.z));
      EXPECT_EQ(bits(p.vx), bits(q.vx));
      EXPECT_EQ(bits(p.vy), bits(q.vy));
      EXPECT_EQ(bits(p.vz), bits(q.vz));
      EXPECT_EQ(bits(p.heading_deg), bits(q.heading_deg));
    }
    ASSERT_EQ(x.links.size(), y.links.size());
    for (std::size_t i = 0; i < x.links.size(); ++i) {
      expect_same_link_columns(x.links[i], y.links[i]);
      EXPECT_EQ(x.links[i].path_count, y.links[i].path_count);
      EXPECT_EQ(x.links[i].paths_beyond_top_k, y.links[i].paths_beyond_top_k);
    }
    ASSERT_EQ(x.paths.size(), y.paths.size());
    for (std::size_t i = 0; i < x.paths.size(); ++i) {
      const auto &p = x.paths[i], &q = y.paths[i];
      EXPECT_EQ(bits(p.a.real()), bits(q.a.real()));
      EXPECT_EQ(bits(p.a.imag()), bits(q.a.imag()));
      EXPECT_EQ(bits(p.tau_s), bits(q.tau_s));
      EXPECT_EQ(bits(p.theta_t), bits(q.theta_t));
      EXPECT_EQ(bits(p.phi_t), bits(q.phi_t));
      EXPECT_EQ(bits(p.theta_r), bits(q.theta_r));
      EXPECT_EQ(bits(p.phi_r), bits(q.phi_r));
      EXPECT_EQ(bits(p.doppler_hz), bits(q.doppler_hz));
      EXPECT_EQ(p.interaction_count, q.interaction_count);
    }
    ASSERT_EQ(x.interactions.size(), y.interactions.size());
    for (std::size_t i = 0; i < x.interactions.size(); ++i) {
      const auto &p = x.interactions[i], &q = y.interactions[i];
      EXPECT_EQ(p.type, q.type);
      EXPECT_EQ(p.object, q.object);
      EXPECT_EQ(bits(p.x), bits(q.x));
      EXPECT_EQ(bits(p.y), bits(q.y));
      EXPECT_EQ(bits(p.z), bits(q.z));
    }
    ASSERT_EQ(x.cfr.size(), y.cfr.size());
    for (std::size_t i = 0; i < x.cfr.size(); ++i) {
      EXPECT_EQ(bits(x.cfr[i].real()), bits(y.cfr[i].real()));
      EXPECT_EQ(bits(x.cfr[i].imag()), bits(y.cfr[i].imag()));
    }
  }
}

}  // namespace

TEST(FrameBlock, RoundTripIsExact) {
  const fs::path dir = tmp_dir("block");
  Builder b;
  auto frames = b.frames();
  frames.push_back(FrameRecord{});  // an empty frame
  frames.back().time_s = 0.3;
  frames[0].nodes[1].x = 389123.456789012345;  // full double precision
  frames[0].paths[0].doppler_hz = -0.0f;
  frames[1].links[0].rms_delay_spread_s = std::numeric_limits<float>::quiet_NaN();
  frames[1].links[1].blocker_count = 65535;
  frames[1].interactions[0].object = 0xfffffffeu;
  const fs::path p = dir / "frames-000001.blk";
  write_frame_block(p, frames);
  EXPECT_FALSE(fs::exists(p.string() + ".tmp"));
  const std::string bytes = read_bytes(p);
  EXPECT_EQ(bytes.substr(0, 8), std::string("RSWBLK5\n"));
  const auto back = read_frame_block(p);
  expect_same(frames, back);
  EXPECT_TRUE(std::isnan(back[1].links[0].rms_delay_spread_s));
  EXPECT_TRUE(std::signbit(back[0].paths[0].doppler_hz));

  // An empty block round-trips too, and rewriting replaces the old block.
  write_frame_block(p, {});
  EXPECT_TRUE(read_frame_block(p).empty());
}

// The streaming writer (one frame in memory) writes the documented layout:
// magic, the frame count it only knows at commit, and an FNV-1a 64 trailer
// over every byte before it, checked here with an independent hash. Frames
// larger than the reader's 1 MiB chunk come back exactly, frame by frame.
TEST(FrameBlock, StreamedBlockMatchesLayoutAndReadsBackInChunks) {
  const fs::path dir = tmp_dir("blockstream");
  Builder b;
  auto frames = b.frames();
  // A frame of 60,000 paths (2.2 MB encoded) spans several read chunks.
  FrameRecord big = frames.back();
  big.time_s += 1;
  big.links.resize(1);
  big.links[0].path_count = 60000;
  big.paths.assign(60000, frames[0].paths[0]);
  for (std::size_t i = 0; i < big.paths.size(); ++i) big.paths[i].tau_s = 1e-9 * static_cast<double>(i);
  big.interactions.clear();
  for (auto& p : big.paths) p.interaction_count = 0;
  frames.push_back(big);
  frames.push_back(frames[0]);
  frames.back().time_s = big.time_s + 1;

  const fs::path p = dir / "stream.blk";
  {
    FrameBlockWriter w(p);
    for (const auto& f : frames) w.append(f);
    EXPECT_FALSE(fs::exists(p)) << "nothing at the final path before commit";
    EXPECT_TRUE(fs::exists(p.string() + ".tmp"));
    EXPECT_EQ(w.frames(), frames.size());
    w.commit();
  }
  EXPECT_FALSE(fs::exists(p.string() + ".tmp"));
  const std::string bytes = read_bytes(p);
  ASSERT_GT(bytes.size(), 2u << 20);
  EXPECT_EQ(bytes.substr(0, 8), std::string("RSWBLK5\n"));
  auto le64 = [&](std::size_t at) {
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= std::uint64_t(static_cast<unsigned char>(bytes[at + i])) << (8 * i);
    return v;
  };
  EXPECT_EQ(le64(8), frames.size());
  std::uint64_t h = 14695981039346656037ull;
  for (std::size_t i = 0; i + 8 < bytes.size(); ++i) h = (h ^ static_cast<unsigned char>(bytes[i])) * 1099511628211ull;
  EXPECT_EQ(le64(bytes.size() - 8), h);

  FrameBlockReader r(p);
  EXPECT_EQ(r.frames(), frames.size());
  std::vector<FrameRecord> back;
  for (FrameRecord f; r.next(f);) back.push_back(f);
  expect_same(frames, back);
  EXPECT_NO_THROW(verify_frame_block(p));

  // A writer dropped before commit (a failed frame) leaves the old block as it was.
  {
    FrameBlockWriter w(p);
    w.append(frames[0]);
  }
  EXPECT_FALSE(fs::exists(p.string() + ".tmp"));
  EXPECT_EQ(read_bytes(p), bytes);
}

TEST(FrameBlock, TruncatedOrCorruptBlocksAreRejected) {
  const fs::path dir = tmp_dir("blockbad");
  Builder b;
  const auto frames = b.frames();
  const fs::path good = dir / "good.blk";
  write_frame_block(good, frames);
  const std::string bytes = read_bytes(good);
  auto expect_rejected = [&](const fs::path& p, const char* what) {
    try {
      read_frame_block(p);
      ADD_FAILURE() << what << ": block accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), p.string()) << what;
      EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << what;
    }
  };
  for (std::size_t cut : {bytes.size() / 2, bytes.size() - 1, std::size_t{12}, std::size_t{0}}) {
    const fs::path p = dir / ("cut" + std::to_string(cut) + ".blk");
    write_bytes(p, bytes.substr(0, cut));
    expect_rejected(p, "truncated");
  }
  for (std::size_t at : {std::size_t{3}, std::size_t{9}, bytes.size() / 3, bytes.size() - 2}) {
    std::string flipped = bytes;
    flipped[at] = static_cast<char>(flipped[at] ^ 0x10);
    const fs::path p = dir / ("flip" + std::to_string(at) + ".blk");
    write_bytes(p, flipped);
    expect_rejected(p, "flipped byte");
  }
  expect_rejected(dir / "missing.blk", "missing");
}
