#include "pipeline/sweep_stage.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <map>
#include <set>

#include "generators/dataset/dataset_writer.hpp"
#include "generators/dataset/store_level.hpp"
#include "generators/sweep/frame_block.hpp"
#include "meshkit/errors.hpp"
#include "meshkit/gltf_io.hpp"
#include "meshkit/vehicle_classes.hpp"
#include "pipeline/fcd.hpp"
#include "pipeline/precompute_store.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/scene_cache.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/trace_h5.hpp"
#include "pipeline/trace_inputs.hpp"
#include "pipeline/trace_stage.hpp"
#include "pipeline/version.hpp"
#include "pipeline/vtypes.hpp"
#include "tracer/tracer.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

std::string block_name(std::uint64_t b) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "block_%06llu", static_cast<unsigned long long>(b));
  return buf;
}

}  // namespace

FcdFilter sweep_fcd_filter(const SweepSettings& cfg) {
  FcdFilter filter;
  filter.begin_s = cfg.begin_s;
  filter.end_s = cfg.end_s;
  filter.step_s = cfg.step_s;
  filter.ids.insert(cfg.ids.begin(), cfg.ids.end());
  filter.types.insert(cfg.types.begin(), cfg.types.end());
  if (!cfg.area.empty()) filter.area = FcdArea{cfg.area[0], cfg.area[1], cfg.area[2], cfg.area[3]};
  return filter;
}

FcdTypeModels::FcdTypeModels(const VTypeMap& vtypes, VehicleLibrary& library, bool use_type_entries,
                             std::string fcd_path)
    : vtypes_(vtypes), library_(library), use_type_entries_(use_type_entries), fcd_(std::move(fcd_path)) {}

const FcdTypeModel* FcdTypeModels::resolve(const FcdVehicle& v) {
  auto it = cache_.find(v.type);
  if (it != cache_.end()) return it->second ? &*it->second : nullptr;
  const auto resolved = vtypes_.resolve(v.type);
  std::optional<FcdTypeModel> tm;
  if (!resolved) {
    spdlog::warn("{}: line {}: vehicle type '{}' is a class raysweep does not model; its vehicles are skipped", fcd_,
                 v.line, v.type);
  } else {
    if (!resolved->known)
      spdlog::warn("{}: line {}: vehicle type '{}' is not defined in the vType files; traced as '{}'", fcd_, v.line,
                   v.type, resolved->vclass);
    const meshkit::VehicleModel* m = nullptr;
    std::string key = v.type;
    if (use_type_entries_) {
      try {
        m = &library_.model(v.type);
      } catch (const std::exception&) {
      }
    }
    if (!m) {
      key = resolved->vclass;
      m = &library_.model(resolved->vclass);
    }
    const auto dims = m->dims();
    tm = FcdTypeModel{key, resolved->vclass, m, std::max(dims.length, resolved->length_m),
                      std::max(dims.width, resolved->width_m), std::max(dims.height, resolved->height_m)};
  }
  it = cache_.emplace(v.type, tm).first;
  return it->second ? &*it->second : nullptr;
}

SweepSelection::SweepSelection(const SweepSettings& cfg, const meshkit::Bounds& scene_bounds, std::string fcd_path)
    : max_vehicles_(cfg.max_vehicles), drop_outside_(cfg.outside == "drop"), bounds_(scene_bounds),
      fcd_(std::move(fcd_path)) {}

std::vector<const FcdVehicle*> SweepSelection::select(const FcdFrame& frame,
                                                      const std::function<bool(const FcdVehicle&)>& traceable) {
  if (max_vehicles_ > 0) {
    std::set<std::string> present;
    for (const auto& v : frame.vehicles) present.insert(v.id);
    for (auto it = selected_.begin(); it != selected_.end();) it = present.count(*it) ? std::next(it) : selected_.erase(it);
  }
  std::vector<const FcdVehicle*> out;
  for (const auto& v : frame.vehicles) {
    if (!traceable(v)) continue;
    if (max_vehicles_ > 0 && !selected_.count(v.id)) {
      if (selected_.size() >= max_vehicles_) continue;
      selected_.insert(v.id);
    }
    const auto& b = bounds_;
    if (v.x < b.min[0] || v.x > b.max[0] || v.y < b.min[1] || v.y > b.max[1]) {
      if (!drop_outside_)
        throw meshkit::InputError(fcd_, "line " + std::to_string(v.line) + " vehicle " + v.id,
                                  "outside the scene (x " + std::to_string(b.min[0]) + ".." + std::to_string(b.max[0]) +
                                      ", y " + std::to_string(b.min[1]) + ".." + std::to_string(b.max[1]) +
                                      "); set [sweep] outside = \"drop\" to skip such vehicles");
      ++dropped_outside_;
      continue;
    }
    out.push_back(&v);
  }
  return out;
}

generators::SweepVehicle sweep_vehicle(const FcdVehicle& v, const FcdTypeModel& tm, std::uint32_t node,
                                       std::uint32_t model) {
  generators::SweepVehicle sv;
  sv.node = node;
  sv.model = model;
  sv.position = {v.x, v.y, v.has_z ? v.z : 0.0};  // finite: FcdReader rejects NaN/Inf
  sv.heading_deg = v.angle_deg;
  const double yaw = yaw_from_heading(v.angle_deg);
  sv.velocity = {v.speed_mps * std::cos(yaw), v.speed_mps * std::sin(yaw), 0};
  sv.length_m = tm.length_m;
  sv.width_m = tm.width_m;
  sv.height_m = tm.height_m;
  return sv;
}

namespace {

// The recorded settings and inputs of a sweep, and its run key: a resumed run
// must continue the same run.
struct SweepRunId {
  json config, prov;
  std::string run_key;
};

SweepRunId identify_run(const SweepArgs& args, const Settings& all, const fs::path& scene_file,
                        const std::vector<std::string>& argv) {
  std::vector<InputFile> inputs;
  inputs.push_back({"scene", scene_file.string()});
  inputs.push_back({"fcd", args.fcd});
  for (const auto& v : args.vtypes) inputs.push_back({"vtypes", v});
  if (!args.rsus.empty()) inputs.push_back({"rsus", args.rsus});
  if (!all.file.empty()) inputs.push_back({"config", all.file});
  if (!args.vehicles.empty()) inputs.push_back({"vehicle_manifest", (fs::path(args.vehicles) / "manifest.json").string()});
  SweepRunId id;
  id.config = all.trace.to_json();
  id.config["sweep"] = all.sweep.to_json();
  id.config["vehicles"] = args.vehicles.empty() ? "built-in parametric" : "library";
  id.prov = provenance("sweep", inputs, id.config, recorded_command(argv));
  all.record_sets(id.prov);
  id.prov["embree"] = tracer::embree_version();
  id.run_key = json{{"config", id.config}, {"inputs", id.prov["inputs"]}, {"version", kVersion}}.dump();
  return id;
}

// The parts folder holds the committed blocks of a run: kept with --resume
// (when it is the same run), discarded otherwise.
void prepare_parts(const SweepArgs& args, const fs::path& parts, const std::string& run_key) {
  const fs::path out(args.out);
  if (fs::exists(parts)) {
    std::ifstream in(parts / "run.json");
    json run;
    try {
      run = json::parse(in);
    } catch (...) {
    }
    if (!args.resume) {
      spdlog::info("{}: discarding the blocks of an earlier run (use --resume to continue it)", parts.string());
      fs::remove_all(parts);
    } else if (run.value("key", "") != run_key) {
      throw std::invalid_argument(parts.string() + ": the interrupted run used other inputs or settings; "
                                  "rerun without --resume to start over");
    }
  } else if (args.resume) {
    spdlog::info("{}: nothing to resume, starting from the first frame", args.out);
  }
  if (!out.parent_path().empty()) fs::create_directories(out.parent_path());
  fs::create_directories(parts);
  write_file_atomic(parts / "run.json", json{{"key", run_key}}.dump() + "\n");
}

// The dataset's nodes: the road-side units first, then each vehicle when it
// first appears.
struct NodeTable {
  std::vector<generators::NodeInfo> nodes;
  std::map<std::string, std::uint32_t> index;
  std::vector<generators::SweepRsu> rsus;

  explicit NodeTable(const std::string& rsus_file) {
    if (rsus_file.empty()) return;
    for (const auto& r : read_nodes_csv(rsus_file)) {
      const auto idx = static_cast<std::uint32_t>(nodes.size());
      nodes.push_back({r.id, generators::NodeKind::rsu, "", "", 0, 0, 0});
      index[r.id] = idx;
      rsus.push_back({idx, {r.x, r.y, r.z}});
    }
  }

  std::uint32_t vehicle(const FcdVehicle& v, const FcdTypeModel& tm, const SweepArgs& args) {
    auto [it, added] = index.emplace(v.id, static_cast<std::uint32_t>(nodes.size()));
    if (added) {
      nodes.push_back({v.id, generators::NodeKind::vehicle, tm.vclass, v.type, static_cast<float>(tm.length_m),
                       static_cast<float>(tm.width_m), static_cast<float>(tm.height_m)});
    } else if (nodes[it->second].kind == generators::NodeKind::rsu) {
      throw meshkit::InputError(args.fcd, "line " + std::to_string(v.line) + " vehicle " + v.id,
                                "has the id of a road-side unit in " + args.rsus);
    }
    return it->second;
  }
};

// Scene model of each FCD vehicle type (registered when the type first appears).
class SceneModels {
 public:
  SceneModels(tracer::TraceScene& scene, FcdTypeModels& types) : scene_(scene), types_(types) {}

  const FcdTypeModel* resolve(const FcdVehicle& v) {
    const FcdTypeModel* tm = types_.resolve(v);
    if (tm && !models_.count(v.type))
      models_[v.type] = scene_.add_vehicle_model(tm->model->name, meshkit::to_scene(*tm->model), tm->model->antenna);
    return tm;
  }
  std::uint32_t at(const std::string& type) const { return models_.at(type); }

 private:
  tracer::TraceScene& scene_;
  FcdTypeModels& types_;
  std::map<std::string, std::uint32_t> models_;
};

// The nodes of `now` not in `before` (both sorted).
std::vector<std::uint32_t> new_nodes(const std::vector<std::uint32_t>& before, const std::vector<std::uint32_t>& now) {
  std::vector<std::uint32_t> out;
  std::set_difference(now.begin(), now.end(), before.begin(), before.end(), std::back_inserter(out));
  return out;
}

// The frames' records, one file per block in the parts folder, each
// committed with its share of the sweep's statistics.
class BlockStore {
 public:
  BlockStore(fs::path parts, const generators::Sweep& sweep, const SweepSettings& cfg)
      : parts_(std::move(parts)), sweep_(sweep), store_(cfg.store), top_k_(cfg.paths_top_k) {}

  fs::path bin(std::uint64_t b) const { return parts_ / (block_name(b) + ".bin"); }
  fs::path stats(std::uint64_t b) const { return parts_ / (block_name(b) + ".json"); }

  // A committed block of an earlier run that is intact.
  bool resumable(std::uint64_t b) const {
    if (!fs::exists(bin(b)) || !fs::exists(stats(b))) return false;
    try {
      generators::verify_frame_block(bin(b));
      return true;
    } catch (const meshkit::InputError& e) {
      spdlog::warn("{}; tracing that block again", e.what());
      return false;
    }
  }

  // A frame reduced to the store level (nothing the dataset drops reaches
  // the disk); `step_seconds`: the sweep's time on it, tracing included.
  void append(std::uint64_t b, generators::FrameRecord frame, double step_seconds, double trace_seconds) {
    const auto t0 = std::chrono::steady_clock::now();
    generators::reduce_frame(frame, store_, top_k_);
    if (!block_) block_.emplace(bin(b));  // streamed to disk: one frame in memory
    block_->append(frame);
    block_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    record_seconds_ += std::max(0.0, step_seconds - trace_seconds);
  }

  void commit(std::uint64_t b) {
    if (!block_) return;
    const auto& s = sweep_.stats();
    const json st = {{"frames", s.frames - before_.frames},
                     {"links", s.links - before_.links},
                     {"traced_links", s.traced_links - before_.traced_links},
                     {"carried_sequences", s.carried_solved - before_.carried_solved},
                     {"carried_paths", s.carried - before_.carried},
                     {"vehicle_updates", s.vehicle_updates - before_.vehicle_updates},
                     {"updates_deferred", s.updates_deferred - before_.updates_deferred},
                     {"rays", s.rays - before_.rays},
                     {"trace_seconds", s.trace_seconds - before_.trace_seconds},
                     {"record_seconds", record_seconds_},
                     {"block_seconds", block_seconds_},
                     {"enclosed_antenna_frames", s.enclosed - before_.enclosed},
                     {"enclosed_nodes", new_nodes(before_.enclosed_nodes, s.enclosed_nodes)}};
    before_ = s;
    record_seconds_ = block_seconds_ = 0;
    write_file_atomic(stats(b), st.dump() + "\n");
    block_->commit();
    block_.reset();
    // Test hook: die like `kill -9` right after a given number of commits.
    static const char* kill_after = std::getenv("RAYSWEEP_KILL_AFTER_BLOCKS");
    static int committed = 0;
    if (kill_after && ++committed == std::atoi(kill_after)) std::raise(SIGKILL);
  }

 private:
  fs::path parts_;
  const generators::Sweep& sweep_;
  std::optional<generators::FrameBlockWriter> block_;
  generators::SweepStats before_;  // sweep statistics at the start of the block
  generators::StoreLevel store_;
  std::uint32_t top_k_;
  // Time outside tracing in the current block: turning results into records
  // (the sweep's step less its tracing), and reducing and serialising them.
  double record_seconds_ = 0, block_seconds_ = 0;
};

// How far the frame loop got.
struct SweepProgress {
  std::chrono::steady_clock::time_point start, logged_at;
  std::uint64_t frames = 0, last_block = 0, blocks_resumed = 0;
  double first_time = 0, last_time = 0;
};

void log_progress(const SweepProgress& p, const generators::Sweep& sweep, const SweepArgs& args,
                  const SweepSettings& cfg, double time_s) {
  const double wall = std::chrono::duration<double>(p.logged_at - p.start).count();
  const auto& s = sweep.stats();
  const double fps = static_cast<double>(s.frames) / wall;
  std::string eta;
  const double end = std::min(cfg.end_s, args.eta_end_s >= 0 ? args.eta_end_s : 1e300);
  if (end < 1e299 && p.frames > 1 && p.last_time > p.first_time) {
    const double dt = (p.last_time - p.first_time) / static_cast<double>(p.frames - 1);
    const double left = std::max(0.0, (end - p.last_time) / dt) / (args.shard ? args.shard->count : 1);
    eta = fmt::format(", ETA {:.0f} s", left / std::max(fps, 1e-9));
  }
  spdlog::info("frame {} (t = {:.1f} s): {:.1f} frames/s, {:.0f} pair-channels/s, cache hit {:.0f}%{}", p.frames,
               time_s, fps, s.links / wall, 100 * s.hit_ratio(), eta);
}

bool owns_block(const SweepArgs& args, std::uint64_t block) { return !args.shard || args.shard->owns(block); }

// Every frame of the FCD: its vehicles through the selection (also in the
// blocks skipped, so the selection and node table match a full run), traced
// into the blocks this run owns and has not committed before.
SweepProgress trace_frames(const SweepArgs& args, const SweepSettings& cfg, std::uint64_t block_frames,
                           FcdReader& reader, SweepSelection& selection, SceneModels& models, NodeTable& nodes,
                           generators::Sweep& sweep, BlockStore& store, std::chrono::steady_clock::time_point start) {
  SweepProgress p;
  p.start = start;
  p.logged_at = std::chrono::steady_clock::now();
  bool skipping_block = false;
  std::uint64_t& block = p.last_block;
  auto traceable = [&](const FcdVehicle& v) { return models.resolve(v) != nullptr; };
  for (FcdFrame frame; reader.next(frame);) {
    if (p.frames % block_frames == 0) {
      if (p.frames > 0) {
        if (!skipping_block) store.commit(block);
        ++block;
      }
      skipping_block = !owns_block(args, block);
      if (!skipping_block && args.resume && store.resumable(block)) {
        skipping_block = true;
        ++p.blocks_resumed;
      }
    }
    if (p.frames == 0) p.first_time = frame.time_s;
    p.last_time = frame.time_s;

    std::vector<generators::SweepVehicle> vehicles;
    for (const FcdVehicle* vp : selection.select(frame, traceable)) {
      const FcdTypeModel* tm = models.resolve(*vp);
      vehicles.push_back(sweep_vehicle(*vp, *tm, nodes.vehicle(*vp, *tm, args), models.at(vp->type)));
    }
    if (!skipping_block) {
      const double traced_before = sweep.stats().trace_seconds;
      const auto t0 = std::chrono::steady_clock::now();
      generators::FrameRecord record = sweep.step(p.frames, frame.time_s, std::move(vehicles));
      const double step = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      store.append(block, std::move(record), step, sweep.stats().trace_seconds - traced_before);
    }
    ++p.frames;

    const auto now = std::chrono::steady_clock::now();
    if (now - p.logged_at > std::chrono::seconds(2)) {
      p.logged_at = now;
      log_progress(p, sweep, args, cfg, frame.time_s);
    }
  }
  if (!skipping_block) store.commit(block);
  if (p.frames == 0) throw meshkit::InputError(args.fcd, "", "no frame left after the time/step filters");
  return p;
}

ShardRecord shard_record(const SweepArgs& args, std::uint64_t block_frames, const SweepProgress& p,
                         const std::string& run_key) {
  ShardRecord shard;
  shard.spec = *args.shard;
  shard.block_frames = block_frames;
  shard.blocks_total = p.last_block + 1;
  shard.frames_total = p.frames;
  for (std::uint64_t b = 0; b <= p.last_block; ++b)
    if (owns_block(args, b)) shard.blocks.push_back(b);
  shard.run_key = sha256_text(run_key + kGitHash);
  shard.out = args.out;
  if (shard.blocks.empty())
    spdlog::warn("{}: shard {} has no block to trace (the sweep has {} blocks of {} frames)", args.out,
                 args.shard->name(), shard.blocks_total, shard.block_frames);
  return shard;
}

generators::DatasetHeader dataset_header(const SweepRunId& id, const TraceSettings& settings, const SweepSettings& cfg,
                                         const generators::SweepOptions& options, const std::string& shard) {
  const tracer::OfdmGrid* grid = options.cfr ? &*options.cfr : nullptr;
  generators::DatasetHeader header = channel_dataset_header(id.config, id.prov, settings.radio, grid);
  header.shard = shard;
  header.store = cfg.store;
  header.paths_top_k = cfg.paths_top_k;
  return header;
}

// The dataset (or the shard) from the committed blocks; the blocks' summed statistics.
json assemble_dataset(const SweepArgs& args, const generators::DatasetHeader& header, std::uint64_t last_block,
                      const BlockStore& store, const NodeTable& nodes, const generators::Sweep& sweep) {
  StagedFile staged{fs::path(args.out)};
  json totals = {{"frames", 0},           {"links", 0},          {"traced_links", 0},
                 {"carried_sequences", 0}, {"carried_paths", 0},  {"vehicle_updates", 0},
                 {"updates_deferred", 0},  {"rays", 0},           {"trace_seconds", 0.0},
                 {"record_seconds", 0.0},  {"block_seconds", 0.0}, {"enclosed_antenna_frames", 0}};
  std::set<std::uint32_t> enclosed;
  const auto t0 = std::chrono::steady_clock::now();
  {
    generators::DatasetWriter writer(staged.path(), header);
    for (std::uint64_t b = 0; b <= last_block; ++b) {
      if (!owns_block(args, b)) continue;
      generators::FrameBlockReader blocks(store.bin(b));
      for (generators::FrameRecord f; blocks.next(f);) writer.append(f);
      std::ifstream in(store.stats(b));
      const json st = json::parse(in);
      for (auto& [k, v] : totals.items()) {
        if (v.is_number_float()) v = v.get<double>() + st.value(k, 0.0);
        else v = v.get<std::uint64_t>() + st.value(k, std::uint64_t{0});
      }
      for (const auto& n : st.value("enclosed_nodes", json::array())) enclosed.insert(n.get<std::uint32_t>());
    }
    totals["enclosed_nodes"] = json::array();
    for (const auto n : enclosed) totals["enclosed_nodes"].push_back(nodes.nodes.at(n).id);
    std::vector<std::string> ids;
    for (const auto& n : nodes.nodes) ids.push_back((n.kind == generators::NodeKind::rsu ? "rsu/" : "vehicle/") + n.id);
    writer.finish(nodes.nodes, sweep.object_names(ids));
  }
  staged.commit();
  // Reading the blocks back, compressing and writing the file.
  totals["write_seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return totals;
}

// Antennas inside buildings make channels through walls: said, with the
// first nodes named (the summary lists them all).
void warn_enclosed(const json& totals) {
  const auto frames = totals["enclosed_antenna_frames"].get<std::uint64_t>();
  if (frames == 0) return;
  const auto& ids = totals["enclosed_nodes"];
  std::string named;
  for (std::size_t k = 0; k < ids.size() && k < 8; ++k) named += (k ? ", " : "") + ids[k].get<std::string>();
  if (ids.size() > 8) named += fmt::format(" and {} more", ids.size() - 8);
  spdlog::warn("{} antenna-frames of {} nodes stand inside a building's closed volume ({}): their channels pass "
               "through its walls; the SUMO lanes there run through OSM footprints (passages, misaligned outlines)",
               frames, ids.size(), named);
}

json sweep_summary(const SweepArgs& args, const json& totals, const SweepProgress& p, const ShardRecord& shard,
                   std::size_t nodes, const SweepSettings& cfg, const generators::SweepOptions& options) {
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - p.start).count();
  const auto links = totals["links"].get<std::uint64_t>();
  const auto traced = totals["traced_links"].get<std::uint64_t>();
  const auto bytes = fs::file_size(args.out);
  json summary = totals;
  summary["out"] = args.out;
  summary["blocks"] = args.shard ? shard.blocks.size() : p.last_block + 1;
  if (args.shard) summary["shard"] = shard.to_json();
  summary["blocks_resumed"] = p.blocks_resumed;
  summary["nodes"] = nodes;
  summary["cache"] = generators::cache_mode_name(options.cache);
  summary["cache_hit_ratio"] = links ? 1.0 - static_cast<double>(traced) / links : 0.0;
  summary["wall_seconds"] = wall;
  summary["bytes"] = bytes;
  summary["bytes_per_link"] = links ? static_cast<double>(bytes) / links : 0.0;
  summary["coherence"] = options.coherence;
  summary["lattice_frames"] = options.lattice_frames;
  summary["diffuse_frames"] = options.diffuse_frames;
  summary["store"] = generators::store_level_name(cfg.store);
  summary["paths_top_k"] = cfg.paths_top_k;
  spdlog::info("swept {} frames ({} resumed blocks), {} pair-channels ({} traced, cache hit {:.1f}%) in {:.1f} s "
               "({:.1f} s tracing; outside tracing {:.1f} s records, {:.1f} s blocks, {:.1f} s writing); {} at level "
               "{} ({:.0f} bytes per pair-frame)",
               totals["frames"].get<std::uint64_t>(), p.blocks_resumed, links, traced,
               100 * summary["cache_hit_ratio"].get<double>(), wall, totals["trace_seconds"].get<double>(),
               totals["record_seconds"].get<double>(), totals["block_seconds"].get<double>(),
               totals["write_seconds"].get<double>(), args.out, summary["store"].get<std::string>(),
               summary["bytes_per_link"].get<double>());
  warn_enclosed(totals);
  if (options.coherence && options.lattice_frames > 1) {
    const auto frames = std::max<std::uint64_t>(1, totals["frames"].get<std::uint64_t>());
    const auto pairs = std::max<std::uint64_t>(1, traced);
    const auto solved = totals["carried_sequences"].get<std::uint64_t>();
    const auto fresh = totals["carried_paths"].get<std::uint64_t>();
    spdlog::info("coherence over {} frames: {:.0f} sequences a frame kept from the frames before and re-solved "
                 "({:.1f} a traced pair), {:.1f} a frame of them new paths or near misses that the frame's own rays "
                 "had not proposed ({:.2f} a traced pair)",
                 options.lattice_frames, static_cast<double>(solved) / frames, static_cast<double>(solved) / pairs,
                 static_cast<double>(fresh) / frames, static_cast<double>(fresh) / pairs);
  }
  return summary;
}

}  // namespace

json run_sweep_stage(const SweepArgs& args, const Settings& all, const std::vector<std::string>& argv) {
  const auto t_start = std::chrono::steady_clock::now();
  if (fs::path(args.out).extension() != ".h5") throw std::invalid_argument(args.out + ": output must end in .h5");
  const TraceSettings& settings = all.trace;
  const SweepSettings& cfg = all.sweep;
  generators::SweepOptions options = cfg.options;
  // A links-level dataset stores no frequency responses: none computed.
  if (cfg.cfr && cfg.store >= generators::StoreLevel::cfr)
    options.cfr = tracer::ofdm_grid(*cfg.cfr, settings.radio.frequency_hz);
  if (!fs::exists(args.fcd)) throw std::invalid_argument(args.fcd + ": FCD file not found");
  const fs::path scene_file = fs::path(args.scene) / "scene.glb";
  if (!fs::exists(scene_file)) throw std::invalid_argument(args.scene + ": no scene.glb (run `raysweep scene` first)");
  const SweepRunId id = identify_run(args, all, scene_file, argv);
  const fs::path parts = args.out + ".parts";
  prepare_parts(args, parts, id.run_key);

  // Scene, library, types, road-side units.
  tracer::TraceScene scene(exclude_objects(read_scene_glb(scene_file.parent_path()), cfg.exclude_objects));
  scene.set_precompute_store(scene_precompute_store(scene_file.parent_path()));
  const auto bounds = scene.static_bounds();
  VehicleLibrary library(args.vehicles, cfg.lod);
  const VTypeMap vtypes = read_vtype_files(args.vtypes);
  NodeTable nodes(args.rsus);
  FcdTypeModels type_models(vtypes, library, !args.vehicles.empty(), args.fcd);
  SceneModels models(scene, type_models);
  FcdReader reader(args.fcd, sweep_fcd_filter(cfg));
  SweepSelection selection(cfg, bounds, args.fcd);
  generators::Sweep sweep(scene, settings.tracer, settings.radio, options, nodes.rsus);
  BlockStore store(parts, sweep, cfg);
  const SweepProgress p =
      trace_frames(args, cfg, options.block_frames, reader, selection, models, nodes, sweep, store, t_start);
  const std::uint64_t dropped_outside = selection.dropped_outside();
  if (dropped_outside) spdlog::warn("{}: {} vehicle-frames outside the scene dropped", args.fcd, dropped_outside);

  const ShardRecord shard = args.shard ? shard_record(args, options.block_frames, p, id.run_key) : ShardRecord{};
  const generators::DatasetHeader header =
      dataset_header(id, settings, cfg, options, args.shard ? shard.to_json().dump() : std::string());
  const json totals = assemble_dataset(args, header, p.last_block, store, nodes, sweep);
  fs::remove_all(parts);
  // A merge record next to the file describes an earlier, merged version of it.
  if (!args.shard) fs::remove(args.out + ".merge.json");

  json summary = sweep_summary(args, totals, p, shard, nodes.nodes.size(), cfg, options);
  summary["dropped_outside"] = dropped_outside;
  return summary;
}

}  // namespace raysweep::pipeline
