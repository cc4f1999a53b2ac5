#include "pipeline/sweep_stage.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <map>
#include <set>

#include "generators/dataset_writer.hpp"
#include "generators/frame_block.hpp"
#include "meshkit/errors.hpp"
#include "meshkit/gltf_io.hpp"
#include "meshkit/vehicle_classes.hpp"
#include "pipeline/config.hpp"
#include "pipeline/config_tables.hpp"
#include "pipeline/fcd.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/trace_config.hpp"
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

json SweepConfig::to_json() const { return sweep_table().write(*this); }

SweepConfig load_sweep_config(const std::string& path) {
  SweepConfig c;
  if (path.empty()) return c;
  const ConfigFile file(path);
  file.read(sweep_table(), c);
  if (!(c.begin_s <= c.end_s)) file.fail("sweep", "end_s", "must not be before sweep.begin_s");
  return c;
}

FcdFilter sweep_fcd_filter(const SweepConfig& cfg) {
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

SweepSelection::SweepSelection(const SweepConfig& cfg, const meshkit::Bounds& scene_bounds, std::string fcd_path)
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

json run_sweep_stage(const SweepArgs& args, const std::vector<std::string>& argv) {
  const auto t_start = std::chrono::steady_clock::now();
  if (fs::path(args.out).extension() != ".h5") throw std::invalid_argument(args.out + ": output must end in .h5");
  const TraceSettings settings = load_trace_config(args.config);
  const SweepConfig cfg = load_sweep_config(args.config);
  generators::SweepOptions options = cfg.options;
  if (!cfg.cfr.empty()) options.cfr = parse_ofdm_grid(cfg.cfr, settings.radio.frequency_hz);
  if (!fs::exists(args.fcd)) throw std::invalid_argument(args.fcd + ": FCD file not found");

  // Inputs and the run key: a resumed run must continue the same run.
  std::vector<InputFile> inputs;
  const fs::path scene_file = fs::path(args.scene) / "scene.glb";
  if (!fs::exists(scene_file)) throw std::invalid_argument(args.scene + ": no scene.glb (run `raysweep scene` first)");
  inputs.push_back({"scene", scene_file.string()});
  inputs.push_back({"fcd", args.fcd});
  for (const auto& v : args.vtypes) inputs.push_back({"vtypes", v});
  if (!args.rsus.empty()) inputs.push_back({"rsus", args.rsus});
  if (!args.config.empty()) inputs.push_back({"config", args.config});
  if (!args.vehicles.empty()) inputs.push_back({"vehicle_manifest", (fs::path(args.vehicles) / "manifest.json").string()});
  json config = settings.to_json();
  config["sweep"] = cfg.to_json();
  config["vehicles"] = args.vehicles.empty() ? "built-in parametric" : "library";
  json prov = provenance("sweep", inputs, config, recorded_command(argv));
  prov["embree"] = tracer::embree_version();
  const std::string run_key = json{{"config", config}, {"inputs", prov["inputs"]}, {"version", kVersion}}.dump();
  auto mine = [&](std::uint64_t block) { return !args.shard || args.shard->owns(block); };

  const fs::path out(args.out);
  const fs::path parts = out.string() + ".parts";
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

  // Scene, library, types, road-side units.
  tracer::TraceScene scene(exclude_objects(meshkit::read_glb(scene_file.string()), cfg.exclude_objects));
  const auto bounds = scene.static_bounds();
  VehicleLibrary library(args.vehicles, cfg.lod);
  VTypeMap vtypes;
  for (const auto& f : args.vtypes) {
    if (fs::path(f).extension() == ".sumocfg") vtypes.add_sumocfg(f);
    else vtypes.add_file(f);
  }
  std::vector<generators::NodeInfo> node_table;
  std::map<std::string, std::uint32_t> node_index;
  std::vector<generators::SweepRsu> rsus;
  if (!args.rsus.empty()) {
    for (const auto& r : read_nodes_csv(args.rsus)) {
      const auto idx = static_cast<std::uint32_t>(node_table.size());
      node_table.push_back({r.id, generators::NodeKind::rsu, "", "", 0, 0, 0});
      node_index[r.id] = idx;
      rsus.push_back({idx, {r.x, r.y, r.z}});
    }
  }
  // Scene model of each FCD vehicle type (registered when the type first appears).
  FcdTypeModels type_models(vtypes, library, !args.vehicles.empty(), args.fcd);
  std::map<std::string, std::uint32_t> scene_models;
  auto model_for = [&](const FcdVehicle& v) -> const FcdTypeModel* {
    const FcdTypeModel* tm = type_models.resolve(v);
    if (tm && !scene_models.count(v.type))
      scene_models[v.type] = scene.add_vehicle_model(tm->model->name, meshkit::to_scene(*tm->model), tm->model->antenna);
    return tm;
  };

  FcdReader reader(args.fcd, sweep_fcd_filter(cfg));
  SweepSelection selection(cfg, bounds, args.fcd);

  generators::Sweep sweep(scene, settings.tracer, settings.radio, options, rsus);
  std::optional<generators::FrameBlockWriter> block;  // streamed to disk: one frame in memory
  std::uint64_t frame_index = 0, block_index = 0, blocks_resumed = 0;
  bool skipping_block = false;
  json block_stats = json::array();
  auto progress_at = std::chrono::steady_clock::now();
  double first_time = 0, last_time = 0;
  FcdFrame frame;

  generators::SweepStats before;  // sweep statistics at the start of the block
  auto commit_block = [&]() {
    if (!block) return;
    const auto& s = sweep.stats();
    const json st = {{"frames", s.frames - before.frames},
                     {"links", s.links - before.links},
                     {"traced_links", s.traced_links - before.traced_links},
                     {"vehicle_updates", s.vehicle_updates - before.vehicle_updates},
                     {"updates_deferred", s.updates_deferred - before.updates_deferred},
                     {"rays", s.rays - before.rays},
                     {"trace_seconds", s.trace_seconds - before.trace_seconds}};
    before = s;
    write_file_atomic(parts / (block_name(block_index) + ".json"), st.dump() + "\n");
    block->commit();
    block.reset();
    // Test hook: die like `kill -9` right after a given number of commits.
    static const char* kill_after = std::getenv("RAYSWEEP_KILL_AFTER_BLOCKS");
    static int committed = 0;
    if (kill_after && ++committed == std::atoi(kill_after)) std::raise(SIGKILL);
  };

  while (reader.next(frame)) {
    if (frame_index % options.block_frames == 0) {
      if (frame_index > 0) {
        if (!skipping_block) commit_block();
        ++block_index;
      }
      skipping_block = !mine(block_index);
      if (!skipping_block && args.resume && fs::exists(parts / (block_name(block_index) + ".bin")) &&
          fs::exists(parts / (block_name(block_index) + ".json"))) {
        try {
          generators::verify_frame_block(parts / (block_name(block_index) + ".bin"));
          skipping_block = true;
          ++blocks_resumed;
        } catch (const meshkit::InputError& e) {
          spdlog::warn("{}; tracing that block again", e.what());
        }
      }
    }
    if (frame_index == 0) first_time = frame.time_s;
    last_time = frame.time_s;

    // Vehicles of this frame: types, selection, scene bounds, node ids.
    std::vector<generators::SweepVehicle> vehicles;
    for (const FcdVehicle* vp : selection.select(frame, [&](const FcdVehicle& v) { return model_for(v) != nullptr; })) {
      const FcdVehicle& v = *vp;
      const FcdTypeModel* tm = model_for(v);
      auto [it, added] = node_index.emplace(v.id, static_cast<std::uint32_t>(node_table.size()));
      if (added) {
        node_table.push_back({v.id, generators::NodeKind::vehicle, tm->vclass, v.type, static_cast<float>(tm->length_m),
                              static_cast<float>(tm->width_m), static_cast<float>(tm->height_m)});
      } else if (node_table[it->second].kind == generators::NodeKind::rsu) {
        throw meshkit::InputError(args.fcd, "line " + std::to_string(v.line) + " vehicle " + v.id,
                                  "has the id of a road-side unit in " + args.rsus);
      }
      generators::SweepVehicle sv;
      sv.node = it->second;
      sv.model = scene_models.at(v.type);
      sv.position = {v.x, v.y, v.has_z ? v.z : 0.0};  // finite: FcdReader rejects NaN/Inf
      sv.heading_deg = v.angle_deg;
      const double yaw = yaw_from_heading(v.angle_deg);
      sv.velocity = {v.speed_mps * std::cos(yaw), v.speed_mps * std::sin(yaw), 0};
      sv.length_m = tm->length_m;
      sv.width_m = tm->width_m;
      sv.height_m = tm->height_m;
      vehicles.push_back(sv);
    }
    if (!skipping_block) {
      if (!block) block.emplace(parts / (block_name(block_index) + ".bin"));
      block->append(sweep.step(frame_index, frame.time_s, std::move(vehicles)));
    }
    ++frame_index;

    const auto now = std::chrono::steady_clock::now();
    if (now - progress_at > std::chrono::seconds(2)) {
      progress_at = now;
      const double wall = std::chrono::duration<double>(now - t_start).count();
      const auto& s = sweep.stats();
      const double fps = static_cast<double>(s.frames) / wall;
      std::string eta;
      const double end = std::min(cfg.end_s, args.eta_end_s >= 0 ? args.eta_end_s : 1e300);
      if (end < 1e299 && frame_index > 1 && last_time > first_time) {
        const double dt = (last_time - first_time) / static_cast<double>(frame_index - 1);
        const double left = std::max(0.0, (end - last_time) / dt) / (args.shard ? args.shard->count : 1);
        eta = fmt::format(", ETA {:.0f} s", left / std::max(fps, 1e-9));
      }
      spdlog::info("frame {} (t = {:.1f} s): {:.1f} frames/s, {:.0f} pair-channels/s, cache hit {:.0f}%{}",
                   frame_index, frame.time_s, fps, s.links / wall, 100 * s.hit_ratio(), eta);
    }
  }
  if (!skipping_block) commit_block();
  if (frame_index == 0) throw meshkit::InputError(args.fcd, "", "no frame left after the time/step filters");
  const std::uint64_t dropped_outside = selection.dropped_outside();
  if (dropped_outside) spdlog::warn("{}: {} vehicle-frames outside the scene dropped", args.fcd, dropped_outside);

  ShardRecord shard;
  if (args.shard) {
    shard.spec = *args.shard;
    shard.block_frames = options.block_frames;
    shard.blocks_total = block_index + 1;
    shard.frames_total = frame_index;
    for (std::uint64_t b = 0; b <= block_index; ++b)
      if (mine(b)) shard.blocks.push_back(b);
    shard.run_key = sha256_text(run_key + kGitHash);
    shard.out = args.out;
    if (shard.blocks.empty())
      spdlog::warn("{}: shard {} has no block to trace (the sweep has {} blocks of {} frames)", args.out,
                   args.shard->name(), shard.blocks_total, shard.block_frames);
  }

  // Assemble the dataset (or the shard) from the committed blocks.
  generators::DatasetHeader header;
  header.raysweep_version = kVersion;
  header.git_hash = kGitHash;
  header.config = config;
  header.inputs = prov["inputs"];
  header.provenance = prov;
  header.seed = 0;
  if (args.shard) header.shard = shard.to_json().dump();
  header.carrier_hz = settings.radio.frequency_hz;
  header.bandwidth_hz = settings.radio.bandwidth_hz;
  if (options.cfr) {
    header.cfr_subcarriers = static_cast<std::uint32_t>(options.cfr->n_subcarriers);
    header.cfr_subcarrier_spacing_hz = options.cfr->subcarrier_spacing_hz;
  }
  StagedFile staged(out);
  json totals = {{"frames", 0},       {"links", 0},           {"traced_links", 0}, {"vehicle_updates", 0},
                 {"updates_deferred", 0}, {"rays", 0}, {"trace_seconds", 0.0}};
  {
    generators::DatasetWriter writer(staged.path(), header);
    for (std::uint64_t b = 0; b <= block_index; ++b) {
      if (!mine(b)) continue;
      generators::FrameBlockReader blocks(parts / (block_name(b) + ".bin"));
      for (generators::FrameRecord f; blocks.next(f);) writer.append(f);
      std::ifstream in(parts / (block_name(b) + ".json"));
      const json st = json::parse(in);
      for (auto& [k, v] : totals.items()) {
        if (v.is_number_float()) v = v.get<double>() + st.at(k).get<double>();
        else v = v.get<std::uint64_t>() + st.at(k).get<std::uint64_t>();
      }
    }
    std::vector<std::string> ids;
    for (const auto& n : node_table) ids.push_back((n.kind == generators::NodeKind::rsu ? "rsu/" : "vehicle/") + n.id);
    writer.finish(node_table, sweep.object_names(ids));
  }
  staged.commit();
  fs::remove_all(parts);
  // A merge record next to the file describes an earlier, merged version of it.
  if (!args.shard) fs::remove(out.string() + ".merge.json");

  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  const auto links = totals["links"].get<std::uint64_t>();
  const auto traced = totals["traced_links"].get<std::uint64_t>();
  json summary = totals;
  summary["out"] = args.out;
  summary["blocks"] = args.shard ? shard.blocks.size() : block_index + 1;
  if (args.shard) summary["shard"] = shard.to_json();
  summary["blocks_resumed"] = blocks_resumed;
  summary["nodes"] = node_table.size();
  summary["cache"] = generators::cache_mode_name(options.cache);
  summary["cache_hit_ratio"] = links ? 1.0 - static_cast<double>(traced) / links : 0.0;
  summary["wall_seconds"] = wall;
  summary["bytes"] = fs::file_size(out);
  summary["bytes_per_link"] = links ? static_cast<double>(fs::file_size(out)) / links : 0.0;
  summary["dropped_outside"] = dropped_outside;
  spdlog::info("swept {} frames ({} resumed blocks), {} pair-channels ({} traced, cache hit {:.1f}%) in {:.1f} s "
               "({:.1f} s tracing); {} ({:.0f} bytes per pair-frame)",
               totals["frames"].get<std::uint64_t>(), blocks_resumed, links, traced,
               100 * summary["cache_hit_ratio"].get<double>(), wall, totals["trace_seconds"].get<double>(), args.out,
               summary["bytes_per_link"].get<double>());
  return summary;
}

}  // namespace raysweep::pipeline
