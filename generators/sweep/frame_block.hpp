// Crash-safe intermediate storage of committed frames, so a sweep killed (even
// with kill -9) can resume from the last block on disk instead of starting over.
//
// File layout (all integers and floats little-endian, IEEE 754 floats):
//   magic        8 bytes  "RSWBLK5\n" (2: links carry paths_below_threshold,
//                                     3: and los_class_fresnel, fresnel_clearance,
//                                     4: and vehicle_loss_db, 5: and the summaries)
//   frame_count  u64
//   per frame:
//     time_s f64; node_count, link_count, path_count, interaction_count, cfr_count: u64 each
//     nodes        node u32, x y z f64, vx vy vz f32, heading_deg f32            (44 bytes each)
//     links        tx u32, rx u32, los_class u8, flags u8, blocker_count u16,
//                  gain_coherent_db f32, gain_incoherent_db f32, first_delay_s f64,
//                  rms_delay_spread_s f32, path_count u32,
//                  paths_below_threshold u32, los_class_fresnel u8,
//                  fresnel_clearance f32, vehicle_loss_db f32,
//                  paths_beyond_top_k u32, diffuse_gain_db f32, k_factor_db f32,
//                  rms_doppler_spread_hz f32, aod_spread aoa_spread 2 x f32 each,
//                  strongest_excess_delay_s f32, strongest_aod strongest_aoa 2 x f32 each
//                                                                                (101 bytes each)
//     paths        a.re f32, a.im f32, tau_s f64, theta_t phi_t theta_r phi_r f32,
//                  doppler_hz f32, interaction_count u8                          (37 bytes each)
//     interactions type u8, object u32, x y z f32                                (17 bytes each)
//     cfr          re f32, im f32                                                 (8 bytes each)
//   checksum     u64 FNV-1a 64 of every byte before it
// Values are stored bit-exactly (NaN payloads, -inf and -0 survive the round trip).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "generators/dataset/dataset.hpp"

namespace raysweep::generators {

inline constexpr char kFrameBlockMagic[9] = "RSWBLK5\n";

// Streams frames into a block with one frame in memory at a time: append()
// serialises a frame to path + ".tmp"; commit() writes the frame count and the
// checksum (hashing the file back in 1 MiB chunks), fsyncs it, renames it to
// path and fsyncs the folder. A writer destroyed before commit() removes the
// .tmp, leaving path as it was. Throws std::runtime_error naming the file on
// I/O errors. Same bytes as write_frame_block for the same frames.
class FrameBlockWriter {
 public:
  explicit FrameBlockWriter(const std::filesystem::path& path);
  ~FrameBlockWriter();
  FrameBlockWriter(const FrameBlockWriter&) = delete;
  FrameBlockWriter& operator=(const FrameBlockWriter&) = delete;
  void append(const FrameRecord& frame);
  void commit();
  std::uint64_t frames() const { return frames_; }

 private:
  std::filesystem::path path_;
  std::string tmp_;
  int fd_ = -1;
  std::uint64_t size_ = 0, frames_ = 0;
};

// Reads a block frame by frame: the constructor checks the magic and the
// checksum in one chunked pass; next() decodes one frame at a time (false after
// the last, once it has checked that nothing follows). Memory: one frame plus
// a 1 MiB buffer, whatever the block's size. Throws meshkit::InputError naming
// the file, as read_frame_block does.
class FrameBlockReader {
 public:
  explicit FrameBlockReader(const std::filesystem::path& path);
  ~FrameBlockReader();
  std::uint64_t frames() const;
  bool next(FrameRecord& frame);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Checks a whole block (checksum and every frame's layout) without keeping it.
void verify_frame_block(const std::filesystem::path& path);

// Writes path + ".tmp", fsyncs it, renames it to path and fsyncs the folder, so
// path is either absent, the previous block, or the complete new block. Throws
// std::runtime_error naming the file on I/O errors.
void write_frame_block(const std::filesystem::path& path, const std::vector<FrameRecord>& frames);

// Reads a block written by write_frame_block. Throws meshkit::InputError naming the
// file for a missing, truncated or corrupt block (bad magic, short read, checksum
// mismatch, counts that do not fit the file).
std::vector<FrameRecord> read_frame_block(const std::filesystem::path& path);

}  // namespace raysweep::generators
