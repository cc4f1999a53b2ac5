// The traffic sweep: frame after frame, move the vehicle instances, decide
// which pairs must be traced again, trace them and turn the results into
// dataset records (dataset.hpp).
//
// Two ways to avoid work, both optional and both measured (see README):
// - The update rule of the VaN3Twin paper: a vehicle's mesh is moved only
//   when it has moved more than max(d0, v * Tc) since its last update; until
//   then it is traced where it was last placed. d0 = Tc = 0 moves every
//   vehicle that changed at all (exact tracing).
// - The path cache. `global` (the paper): any update clears every pair.
//   `per_pair`: an update invalidates the pairs the vehicle belongs to, the
//   pairs without any path (on any move), the pairs with a stored path
//   segment or the direct segment within the
//   margin of the vehicle's old or new bounding sphere, and the pairs whose
//   "strong" ellipsoid (foci at the two antennas, sum of distances up to the
//   strongest stored path's length plus the margin) meets either sphere. A
//   pair kept from the cache therefore still has exactly its stored paths
//   and LoS class; what it can miss is a new path via a vehicle that moved
//   outside the strong ellipsoid, which is longer, hence weaker in spreading
//   loss, than the strongest path it has (measured by `raysweep` benchmarks).
//
// Coherence across frames (`coherence`, on by default; `lattice_frames` K,
// 4 by default): every frame's search shoots its lattice (and its vehicle
// bundles) turned by a rotation drawn from the frame index
// (tracer.lattice_turn), and every pair traced in a frame also solves the
// sampled sequences (the rays' and beams' proposals) that gave it a path or
// a near miss in its K frames before, by the image method and exact
// visibility: a path one lattice found stays while it holds and K frames
// after, whatever the later lattices sample, and one that no longer holds
// adds nothing. Over static scenery a frame thus has the paths of every
// lattice so far; under traffic, of the last K frames' at least. Off (or
// K = 1): every frame searched from scratch on the one unturned lattice.
// Diffuse records are the frame's own lattice's, and with `diffuse_frames`
// D > 1 the mean over the lattices of the frame and its D - 1 frames
// before, all shot from this frame's positions: the diffuse estimate has D
// times the samples, and consecutive frames share D - 1 lattices of them.
//
// The cache, the update rule and the carried sequences restart at every block of
// `block_frames` frames (every vehicle placed afresh, every pair traced), so
// each block depends only on its own frames: a resumed run or a shard
// commits the same blocks as an uninterrupted one.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "generators/dataset/dataset.hpp"
#include "tracer/channel.hpp"
#include "tracer/solver.hpp"

namespace raysweep::generators {

enum class CacheMode { none, per_pair, global };
const char* cache_mode_name(CacheMode m);
CacheMode parse_cache_mode(const std::string& s);  // "none" | "per_pair" | "global"; std::invalid_argument otherwise

struct SweepOptions {
  double d0_m = 0;
  double coherence_time_s = 0;
  CacheMode cache = CacheMode::per_pair;
  double cache_margin_m = 0.5;
  std::uint32_t block_frames = 50;
  // Samples that add up across frames (turned lattices, carried sequences);
  // false: every frame from scratch on one unturned lattice.
  bool coherence = true;
  // With coherence: a traced pair also solves the sampled sequences that
  // gave it a path in its last lattice_frames frames (1: none, every frame
  // the same lattice).
  std::uint32_t lattice_frames = 4;
  // Diffuse samples shared by consecutive frames: a frame's diffuse
  // gathering shoots its own lattice and those of its diffuse_frames - 1
  // frames before (tracer.diffuse_turns), each weighted alike (1: its own).
  std::uint32_t diffuse_frames = 1;
  std::optional<tracer::OfdmGrid> cfr;  // store each link's frequency response
};

// The lattice turn of frame `frame` (absolute, from the sweep's start) of a
// sweep with turned lattices, from the configured tracer.lattice_turn: the
// two mixed so that no two (turn, frame) meet.
inline std::uint64_t frame_lattice_turn(std::uint64_t base_turn, std::uint64_t frame) {
  return base_turn * 0x9E3779B97F4A7C15ull + frame + 1;
}

// A vehicle in the current frame.
struct SweepVehicle {
  std::uint32_t node = 0;   // dataset node index (stable over the sweep)
  std::uint32_t model = 0;  // TraceScene model index
  tracer::Vec3 position{0, 0, 0};  // front-bumper centre on the road (SUMO)
  double heading_deg = 0;          // clockwise from north (SUMO)
  tracer::Vec3 velocity{0, 0, 0};
  double length_m = 5, width_m = 2, height_m = 1.5;  // for the bounding sphere
};

// A static antenna (road-side unit).
struct SweepRsu {
  std::uint32_t node = 0;
  tracer::Vec3 position{0, 0, 0};  // antenna
};

struct SweepStats {
  std::uint64_t frames = 0;
  std::uint64_t links = 0;           // pair-frames written
  std::uint64_t traced_links = 0;    // pair-frames traced (the rest came from the cache)
  std::uint64_t carried_solved = 0;  // coherence: carried sequences re-solved in the frames' traces
  std::uint64_t carried = 0;         // of them, paths (and near misses) that this frame's rays had not proposed
  std::uint64_t vehicle_updates = 0; // vehicle meshes moved (incl. first placements)
  std::uint64_t updates_deferred = 0;  // vehicle-frames that moved but stayed under the update threshold
  std::uint64_t paths = 0;
  std::uint64_t rays = 0;
  // Antenna-frames standing inside a building's closed volume
  // (TraceScene::enclosing_object: a lane through an OSM footprint), and
  // those antennas' dataset nodes (sorted, distinct).
  std::uint64_t enclosed = 0;
  std::vector<std::uint32_t> enclosed_nodes;
  double trace_seconds = 0;
  double hit_ratio() const { return links ? 1.0 - static_cast<double>(traced_links) / links : 0.0; }
};

class Sweep {
 public:
  // `rsus` are present in every frame. The scene's vehicle models must be
  // registered before step() names them.
  Sweep(tracer::TraceScene& scene, const tracer::TracerConfig& tracer, const tracer::RadioConfig& radio,
        const SweepOptions& options, std::vector<SweepRsu> rsus);

  // One frame. `frame_index` counts frames from the start of the sweep (it
  // places the block boundaries); vehicles in any order, node ids unique.
  FrameRecord step(std::uint64_t frame_index, double time_s, std::vector<SweepVehicle> vehicles);

  const SweepStats& stats() const { return stats_; }
  // Object table of the dataset: the static objects, then one per node
  // (`node_ids` in node order).
  std::vector<std::string> object_names(const std::vector<std::string>& node_ids) const;

 private:
  struct Placed {
    SweepVehicle v;  // pose it was last placed at
  };
  struct CachedLink {
    LinkRecord link;
    std::vector<PathRecord> paths;
    std::vector<InteractionRecord> interactions;
    std::vector<std::complex<float>> cfr;
    tracer::Vec3 a, b;  // antenna positions it was traced with
    double reach = 0;   // strongest stored path's length (or the direct distance + lambda / 2) + margin
    std::vector<tracer::Vec3> points;         // each path's polyline a, interactions..., b
    std::vector<std::uint32_t> path_points;   // polyline sizes
    tracer::Vec3 lo{0, 0, 0}, hi{0, 0, 0};    // box around every point
  };
  // step()'s phases (the two structs are defined in sweep.cpp).
  struct Motion;
  struct Antennas;
  using NodePair = std::pair<std::uint32_t, std::uint32_t>;  // local antenna indices, first < second
  Motion place_vehicles(const std::vector<SweepVehicle>& vehicles);
  void pose_vehicles();
  Antennas antennas() const;
  std::vector<char> note_enclosed(const Antennas& ant);
  bool needs_trace(std::uint32_t node_a, std::uint32_t node_b, const Motion& motion) const;
  bool near_cached_paths(const CachedLink& c, const Motion& motion) const;
  CachedLink cache_link(const tracer::PairResult& res, const Antennas& antennas, NodePair pair) const;
  bool carries() const { return options_.coherence && options_.lattice_frames > 1; }
  tracer::Snapshot trace_todo(std::uint64_t frame, const Antennas& ant, const std::vector<NodePair>& todo);
  void append_nodes(const std::vector<SweepVehicle>& vehicles, FrameRecord& frame) const;
  void append_links(const std::vector<NodePair>& all, const std::vector<NodePair>& traced,
                    const std::vector<std::uint32_t>& node_of, const std::vector<char>& inside, FrameRecord& frame);
  void forget_departed();
  std::vector<tracer::FaceSequences> carried_sequences(std::uint64_t frame, const Antennas& ant,
                                                       const std::vector<NodePair>& search);
  void keep_found(std::uint64_t frame, const Antennas& ant, NodePair pair, const tracer::PairResult& res,
                  const tracer::FaceSequences& carried);

  tracer::TraceScene& scene_;
  tracer::TracerConfig tracer_;
  tracer::RadioConfig radio_;
  SweepOptions options_;
  std::vector<SweepRsu> rsus_;
  std::map<std::uint32_t, Placed> placed_;
  std::map<std::uint64_t, CachedLink> cache_;
  // Turned lattices, per pair of dataset nodes: each sampled sequence that
  // gave a path or a near miss (vehicle faces as FaceRef{dataset node + 1,
  // face}), with the last frame it did; sorted by sequence.
  using KeptSequence = std::pair<std::vector<tracer::FaceRef>, std::uint64_t>;
  std::map<std::uint64_t, std::vector<KeptSequence>> kept_;
  SweepStats stats_;
};

}  // namespace raysweep::generators
