#include "pipeline/block_assembler.hpp"

#include <cstdio>
#include <fstream>

#include "generators/frame_block.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;

std::string block_name(std::uint64_t block) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "block_%06llu", static_cast<unsigned long long>(block));
  return buf;
}

BlockAssembler::BlockAssembler(fs::path tmp, const generators::DatasetHeader& header, fs::path parts, json totals)
    : tmp_(std::move(tmp)), parts_(std::move(parts)), totals_(std::move(totals)) {
  writer_ = std::make_unique<generators::DatasetWriter>(tmp_, header);
  thread_ = std::thread([this] { run(); });
}

BlockAssembler::~BlockAssembler() {
  stop_thread();
  if (finished_) return;
  writer_.reset();  // closed without `complete`
  std::error_code ec;
  fs::remove(tmp_, ec);
}

void BlockAssembler::stop_thread() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void BlockAssembler::add(std::uint64_t block) {
  {
    std::lock_guard lock(mutex_);
    if (error_) std::rethrow_exception(error_);
    queue_.push_back(block);
  }
  wake_.notify_all();
}

json BlockAssembler::finish(const std::vector<generators::NodeInfo>& nodes, const std::vector<std::string>& objects,
                            const std::string& shard) {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  if (error_) std::rethrow_exception(error_);
  if (!shard.empty()) writer_->set_shard(shard);
  writer_->finish(nodes, objects);
  writer_.reset();
  finished_ = true;
  return totals_;
}

void BlockAssembler::run() {
  try {
    for (;;) {
      std::uint64_t block;
      {
        std::unique_lock lock(mutex_);
        wake_.wait(lock, [&] { return stop_ || closed_ || !queue_.empty(); });
        if (stop_ || queue_.empty()) return;  // stopped, or closed with nothing left
        block = queue_.front();
        queue_.pop_front();
      }
      append(block);
    }
  } catch (...) {
    std::lock_guard lock(mutex_);
    error_ = std::current_exception();
  }
}

void BlockAssembler::append(std::uint64_t block) {
  generators::FrameBlockReader frames(parts_ / (block_name(block) + ".bin"));
  for (generators::FrameRecord f; frames.next(f);) writer_->append(f);
  std::ifstream in(parts_ / (block_name(block) + ".json"));
  const json st = json::parse(in);
  for (auto& [k, v] : totals_.items()) {
    if (v.is_number_float()) v = v.get<double>() + st.at(k).get<double>();
    else v = v.get<std::uint64_t>() + st.at(k).get<std::uint64_t>();
  }
}

}  // namespace raysweep::pipeline
