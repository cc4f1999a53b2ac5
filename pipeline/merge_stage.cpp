#include "pipeline/merge_stage.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>

#include "generators/dataset/dataset_reader.hpp"
#include "generators/dataset/dataset_virtual.hpp"
#include "generators/dataset/dataset_writer.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/shard.hpp"
#include "pipeline/staged_output.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

struct Shard {
  std::string file;
  std::unique_ptr<generators::DatasetReader> reader;
  ShardRecord rec;
};

// A `raysweep sweep --shard` command names its own --out; the merged file
// records the command with the merged file's name there, which is the command
// of the single-process run writing it.
json provenance_for(const json& prov, const std::string& shard_out, const std::string& merged_out) {
  json p = prov;
  if (!p.contains("command") || !p["command"].is_array()) return p;
  auto& cmd = p["command"];
  for (std::size_t i = 0; i < cmd.size(); ++i) {
    if (!cmd[i].is_string()) continue;
    const std::string a = cmd[i];
    if (a == "--out" && i + 1 < cmd.size() && cmd[i + 1] == shard_out) cmd[i + 1] = merged_out;
    else if (a == "--out=" + shard_out) cmd[i] = "--out=" + merged_out;
  }
  return p;
}

// The first difference between two inputs records, in words.
std::string inputs_difference(const json& a, const json& b) {
  if (!a.is_array() || !b.is_array() || a.size() != b.size()) return "the input files differ";
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i] != b[i])
      return "input '" + a[i].value("role", std::string("?")) + "' differs (" + a[i].value("path", std::string()) +
             " sha256 " + a[i].value("sha256", std::string()).substr(0, 12) + " vs " + b[i].value("path", std::string()) +
             " sha256 " + b[i].value("sha256", std::string()).substr(0, 12) + ")";
  return "the input files differ";
}

void check_same_run(const Shard& ref, const Shard& s) {
  const auto& a = ref.reader->header();
  const auto& b = s.reader->header();
  auto differs = [&](const std::string& what) {
    throw std::invalid_argument(s.file + " is not a shard of the same sweep as " + ref.file + ": " + what +
                                " (shards must come from the same inputs, settings and raysweep build)");
  };
  if (a.inputs != b.inputs) differs(inputs_difference(a.inputs, b.inputs));
  if (a.config != b.config) differs("the config differs");
  if (a.raysweep_version != b.raysweep_version || a.git_hash != b.git_hash ||
      ref.reader->schema_version() != s.reader->schema_version())
    differs("raysweep version " + b.raysweep_version + " (" + b.git_hash + ") vs " + a.raysweep_version + " (" +
            a.git_hash + ")");
  if (ref.rec.run_key != s.rec.run_key) differs("the run key differs");
  if (ref.rec.spec.count != s.rec.spec.count)
    differs("it is one of " + std::to_string(s.rec.spec.count) + " shards, not of " + std::to_string(ref.rec.spec.count));
  if (ref.rec.block_frames != s.rec.block_frames || ref.rec.frames_total != s.rec.frames_total)
    differs("its sweep has " + std::to_string(s.rec.frames_total) + " frames in blocks of " +
            std::to_string(s.rec.block_frames) + ", not " + std::to_string(ref.rec.frames_total) + " in blocks of " +
            std::to_string(ref.rec.block_frames));
  if (provenance_for(a.provenance, ref.rec.out, "") != provenance_for(b.provenance, s.rec.out, ""))
    differs("the provenance differs");
  if (a.seed != b.seed || a.carrier_hz != b.carrier_hz || a.bandwidth_hz != b.bandwidth_hz ||
      a.cfr_subcarriers != b.cfr_subcarriers || a.cfr_subcarrier_spacing_hz != b.cfr_subcarrier_spacing_hz)
    differs("the radio attributes differ");
  if (a.store != b.store || a.paths_top_k != b.paths_top_k) differs("the store levels differ");
  const auto& na = ref.reader->nodes();
  const auto& nb = s.reader->nodes();
  bool same_nodes = na.size() == nb.size();
  for (std::size_t i = 0; same_nodes && i < na.size(); ++i)
    same_nodes = na[i].id == nb[i].id && na[i].kind == nb[i].kind && na[i].vclass == nb[i].vclass &&
                 na[i].vtype == nb[i].vtype && na[i].length_m == nb[i].length_m && na[i].width_m == nb[i].width_m &&
                 na[i].height_m == nb[i].height_m;
  if (!same_nodes) differs("the node tables differ");
  if (ref.reader->objects() != s.reader->objects()) differs("the object tables differ");
}

std::vector<Shard> open_shards(const MergeArgs& args) {
  std::vector<Shard> shards;
  for (const auto& f : args.shards) {
    if (!fs::exists(f)) throw std::invalid_argument(f + ": shard file not found");
    if (fs::exists(args.out) && fs::equivalent(f, args.out))
      throw std::invalid_argument(args.out + ": the output is one of the shards");
    Shard s;
    s.file = f;
    s.reader = std::make_unique<generators::DatasetReader>(f);
    if (!s.reader->complete())
      throw std::invalid_argument(f + ": the shard file is not complete (its sweep stopped early; rerun it with --resume)");
    if (s.reader->header().shard.empty())
      throw std::invalid_argument(f + ": not a shard file (no root attribute shard): a whole dataset needs no merge");
    s.rec = ShardRecord::from_json(json::parse(s.reader->header().shard), f);
    shards.push_back(std::move(s));
  }
  return shards;
}

// The shards by index, checked for coverage: every shard index of 0..N-1
// exactly once, so every block once, each with the frames of its blocks.
std::map<std::uint32_t, const Shard*> check_coverage(const std::vector<Shard>& shards) {
  std::map<std::uint32_t, const Shard*> by_index;
  const Shard& first = shards.front();
  for (const auto& s : shards) {
    check_same_run(first, s);
    auto [it, added] = by_index.emplace(s.rec.spec.index, &s);
    if (!added)
      throw std::invalid_argument("shard " + s.rec.spec.name() + " given twice: " + it->second->file + " and " + s.file +
                                  " (each block must be merged exactly once)");
  }
  const std::uint32_t n = first.rec.spec.count;
  std::string missing;
  for (std::uint32_t i = 0; i < n; ++i) {
    if (by_index.count(i)) continue;
    ShardSpec spec{i, n};
    std::string blocks;
    for (std::uint64_t b = i; b < first.rec.blocks_total; b += n) blocks += (blocks.empty() ? "" : ",") + std::to_string(b);
    if (blocks.empty()) blocks = "none";
    missing += (missing.empty() ? "" : "; ") + spec.name() + " (" + shard_file_name(spec) + ", blocks " + blocks + ")";
  }
  if (!missing.empty())
    throw std::invalid_argument("merge: missing shard(s) " + missing + " of the " + std::to_string(n) +
                                " shards of this sweep; run them (--shard I/" + std::to_string(n) + ") and merge again");
  for (const auto& [i, s] : by_index) {
    std::uint64_t frames = 0;
    for (auto b : s->rec.blocks) frames += s->rec.frames_of(b);
    if (frames != s->reader->frame_count())
      throw std::invalid_argument(s->file + ": holds " + std::to_string(s->reader->frame_count()) +
                                  " frames, its blocks have " + std::to_string(frames));
  }
  return by_index;
}

// Where each block's frames are: its shard, the first frame in that shard.
struct Where {
  const Shard* shard;
  std::uint64_t first;
};

std::vector<Where> block_locations(const Shard& first, const std::map<std::uint32_t, const Shard*>& by_index) {
  std::vector<Where> blocks(first.rec.blocks_total);
  for (const auto& [i, s] : by_index) {
    std::uint64_t f = 0;
    for (auto b : s->rec.blocks) {
      blocks[b] = {s, f};
      f += s->rec.frames_of(b);
    }
  }
  return blocks;
}

// The merged file at `path`: a copy of the frames, or an HDF5 virtual
// dataset mapping them from the shards. Returns the frame count.
std::uint64_t write_merged(const fs::path& path, const MergeArgs& args, const generators::DatasetHeader& header,
                           const Shard& first, const std::vector<Where>& blocks) {
  std::uint64_t frames = 0;
  if (args.virtual_dataset) {
    // Mappings name the shards relative to the merged file's folder, so the
    // folder with its shards can move as a whole.
    const fs::path base = fs::absolute(fs::path(args.out)).parent_path();
    std::vector<generators::VirtualPiece> pieces;
    for (std::uint64_t b = 0; b < blocks.size(); ++b) {
      const auto& w = blocks[b];
      const std::uint64_t nf = first.rec.frames_of(b);
      pieces.push_back({w.shard->file, fs::relative(fs::absolute(w.shard->file), base).string(), w.first, nf});
      frames += nf;
    }
    generators::write_virtual_dataset(path, header, first.reader->nodes(), first.reader->objects(), pieces);
  } else {
    generators::DatasetWriter writer(path, header);
    for (std::uint64_t b = 0; b < blocks.size(); ++b) {
      const std::uint64_t nf = first.rec.frames_of(b);
      for (const auto& f : blocks[b].shard->reader->frames(blocks[b].first, nf)) writer.append(f);
      frames += nf;
    }
    writer.finish(first.reader->nodes(), first.reader->objects());
  }
  return frames;
}

// <out>.merge.json: the shards merged (with their hashes) and the result's hash.
void write_merge_record(const MergeArgs& args, const std::map<std::uint32_t, const Shard*>& by_index) {
  json record = {{"merged", args.out}, {"virtual", args.virtual_dataset}, {"shards", json::array()}};
  for (const auto& [i, s] : by_index)
    record["shards"].push_back({{"file", s->file},
                                {"sha256", sha256_file(s->file)},
                                {"index", s->rec.spec.index},
                                {"count", s->rec.spec.count},
                                {"blocks", s->rec.blocks}});
  record["sha256"] = sha256_file(args.out);
  write_file_atomic(args.out + ".merge.json", record.dump(1) + "\n");
}

}  // namespace

json run_merge_stage(const MergeArgs& args) {
  const auto t0 = std::chrono::steady_clock::now();
  if (fs::path(args.out).extension() != ".h5") throw std::invalid_argument(args.out + ": output must end in .h5");
  if (args.shards.empty()) throw std::invalid_argument("merge: no shard files given");
  const std::vector<Shard> shards = open_shards(args);
  const auto by_index = check_coverage(shards);
  const Shard& first = shards.front();
  const std::vector<Where> blocks = block_locations(first, by_index);

  generators::DatasetHeader header = first.reader->header();
  header.shard.clear();
  header.provenance = provenance_for(header.provenance, first.rec.out, args.out);
  const fs::path out(args.out);
  StagedFile staged(out);
  const std::uint64_t frames = write_merged(staged.path(), args, header, first, blocks);
  staged.commit();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  write_merge_record(args, by_index);

  spdlog::info("merged {} shards ({} blocks, {} frames) into {}{} in {:.2f} s", shards.size(), blocks.size(), frames,
               args.out, args.virtual_dataset ? " (virtual dataset)" : "", wall);
  return {{"out", args.out},
          {"shards", shards.size()},
          {"blocks", blocks.size()},
          {"frames", frames},
          {"virtual", args.virtual_dataset},
          {"bytes", fs::file_size(out)},
          {"wall_seconds", wall}};
}

}  // namespace raysweep::pipeline
