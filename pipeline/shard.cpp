#include "pipeline/shard.hpp"

#include <algorithm>
#include <stdexcept>

namespace raysweep::pipeline {

std::string ShardSpec::name() const { return std::to_string(index) + "-of-" + std::to_string(count); }

ShardSpec parse_shard(const std::string& text, const std::string& option) {
  const auto slash = text.find('/');
  auto number = [&](const std::string& s) -> long long {
    if (s.empty() || s.size() > 9 || !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; }))
      return -1;
    return std::stoll(s);
  };
  const long long i = slash == std::string::npos ? -1 : number(text.substr(0, slash));
  const long long n = slash == std::string::npos ? -1 : number(text.substr(slash + 1));
  if (i < 0 || n < 1 || i >= n)
    throw std::invalid_argument(option + " " + text + ": expected I/N with 0 <= I < N (e.g. 0/4; Slurm: " +
                                "$SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT with --array=0-(N-1))");
  return {static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(n)};
}

nlohmann::json ShardRecord::to_json() const {
  return {{"index", spec.index},           {"count", spec.count},   {"assignment", "interleaved"},
          {"block_frames", block_frames}, {"blocks_total", blocks_total}, {"frames_total", frames_total},
          {"blocks", blocks},             {"run_key", run_key},    {"out", out}};
}

ShardRecord ShardRecord::from_json(const nlohmann::json& j, const std::string& file) {
  ShardRecord r;
  try {
    r.spec.index = j.at("index").get<std::uint32_t>();
    r.spec.count = j.at("count").get<std::uint32_t>();
    if (j.at("assignment").get<std::string>() != "interleaved")
      throw std::invalid_argument("assignment " + j.at("assignment").dump() + " unknown");
    r.block_frames = j.at("block_frames").get<std::uint64_t>();
    r.blocks_total = j.at("blocks_total").get<std::uint64_t>();
    r.frames_total = j.at("frames_total").get<std::uint64_t>();
    r.blocks = j.at("blocks").get<std::vector<std::uint64_t>>();
    r.run_key = j.at("run_key").get<std::string>();
    r.out = j.at("out").get<std::string>();
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(file + ": attribute shard: " + e.what());
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(file + ": attribute shard: " + e.what());
  }
  if (r.spec.count == 0 || r.spec.index >= r.spec.count || r.block_frames == 0 ||
      r.blocks_total != (r.frames_total + r.block_frames - 1) / r.block_frames)
    throw std::invalid_argument(file + ": attribute shard: inconsistent index, count or block counts");
  std::vector<std::uint64_t> expect;
  for (std::uint64_t b = r.spec.index; b < r.blocks_total; b += r.spec.count) expect.push_back(b);
  if (r.blocks != expect)
    throw std::invalid_argument(file + ": attribute shard: its blocks are not those of shard " + r.spec.name());
  return r;
}

std::uint64_t ShardRecord::frames_of(std::uint64_t block) const {
  const std::uint64_t first = block * block_frames;
  return first >= frames_total ? 0 : std::min(block_frames, frames_total - first);
}

std::string shard_file_name(const ShardSpec& s) { return "dataset." + s.name() + ".h5"; }

}  // namespace raysweep::pipeline
