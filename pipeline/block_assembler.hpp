// The sweep's dataset, assembled from its committed frame blocks on a thread of
// its own while the next blocks are traced (internal to the sweep stage).
//
//   BlockAssembler a(tmp, header, parts);   // creates tmp (a DatasetWriter)
//   a.add(b);                               // block b is on disk, in block order
//   json totals = a.finish(nodes, objects, shard);   // waits, writes the tables
//
// Reading a block back, filling the columns and deflating them took 42 s after the
// 475 s of tracing of the ring road's 600 frames; done as the blocks commit, only
// the last block's share is left at the end. An exception on the thread is
// rethrown by the next add() or by finish(); an assembler destroyed before
// finish() stops its thread and removes the temporary file.
#pragma once

#include <nlohmann/json.hpp>

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "generators/dataset.hpp"
#include "generators/dataset_writer.hpp"

namespace raysweep::pipeline {

class BlockAssembler {
 public:
  // `parts` holds block_NNNNNN.bin (frames) and block_NNNNNN.json (the block's
  // sweep statistics, summed into the totals `finish` returns, starting from
  // `totals`' keys at zero).
  BlockAssembler(std::filesystem::path tmp, const generators::DatasetHeader& header, std::filesystem::path parts,
                 nlohmann::json totals);
  ~BlockAssembler();
  BlockAssembler(const BlockAssembler&) = delete;
  BlockAssembler& operator=(const BlockAssembler&) = delete;

  void add(std::uint64_t block);
  nlohmann::json finish(const std::vector<generators::NodeInfo>& nodes, const std::vector<std::string>& objects,
                        const std::string& shard);

 private:
  void run();
  void append(std::uint64_t block);
  void stop_thread();

  std::filesystem::path tmp_, parts_;
  std::unique_ptr<generators::DatasetWriter> writer_;
  nlohmann::json totals_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::uint64_t> queue_;
  bool closed_ = false, stop_ = false, finished_ = false;
  std::exception_ptr error_;
  std::thread thread_;
};

// "block_000042": the file stem of block 42 in a sweep's parts folder.
std::string block_name(std::uint64_t block);

}  // namespace raysweep::pipeline
