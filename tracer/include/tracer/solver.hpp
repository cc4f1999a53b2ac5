// Path solver: for every requested pair of antenna nodes, the propagation
// paths with full polarisation (complex gain, delay, angles, Doppler,
// interactions) and the pair's LoS / NLoSv / NLoS labels.
//
// trace_pairs plans the pairs (which are in range, which nodes serve as
// sources), lets each enabled mechanism (tracer/src/mechanisms/) prepare what
// its pairs share, then per pair labels the direct line and collects the
// mechanisms' paths in a fixed order: direct (vehicles as knife edges),
// specular and refracted (candidates from the exact image search, the beams
// and the shoot-and-bounce rays, each solved exactly by the image method),
// UTD diffraction (static edges, with a reflection before or after, and
// vehicle edges), diffuse scattering (rays or surface tiles). Duplicates and
// paths far below the strongest are dropped. Each unordered pair is traced
// once from both ends' candidates, so a_ij = a_ji.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "tracer/config.hpp"
#include "tracer/em/coefficients.hpp"
#include "tracer/path.hpp"
#include "tracer/trace_scene.hpp"

namespace raysweep::tracer {

// An antenna: on a vehicle (vehicle >= 0: index into the scene's vehicles) or
// a bare node (road-side unit, test probe).
struct Node {
  std::string id;
  Vec3 position{0, 0, 0};
  Vec3 velocity{0, 0, 0};
  Vec3 forward{1, 0, 0};  // orientation of the antenna pattern (horizontal unit vector)
  int vehicle = -1;
};

// Nodes of the scene's current vehicles (antenna mounts, velocities, headings).
std::vector<Node> vehicle_nodes(const TraceScene& scene);

struct PairResult {
  std::uint32_t tx = 0, rx = 0;  // node indices, tx < rx
  LosClass los_class = LosClass::LOS;   // geometric: what the direct segment crosses
  std::vector<std::uint32_t> blockers;  // objects on the direct segment (sorted, unique)
  // The label by the first Fresnel zone (tracer/src/fresnel_zone.hpp): an obstacle
  // within 0.6 F1 of the direct line counts; the worst obstacle's clearance
  // h / r1 (negative: the line crosses it), capped at 1.
  LosClass fresnel_class = LosClass::LOS;
  double fresnel_clearance = 1;
  // Knife-edge loss of the vehicles in the first Fresnel zone (dB), applied
  // to the direct path (TracerConfig::vehicle_diffraction); 0 when none.
  double vehicle_loss_db = 0;
  std::vector<Path> paths;              // sorted by delay
  // Candidate face sequences that only a vehicle blocks (carried, they let a
  // coherent sweep see the path return: generators/sweep).
  std::vector<std::vector<FaceRef>> near_misses;
  // The face sequences this trace's rays and beams proposed (the search's
  // sample, not its exhaustive image orders), from the lower end, sorted;
  // filled only when the trace was given carried sequences (trace_pairs).
  std::vector<std::vector<FaceRef>> proposed;
  PathStats stats;
  std::uint32_t candidates = 0;         // face sequences refined
  // Candidates dropped for crossing > max_transmissions slabs (the image
  // search's slab bounds skip most such sequences before proposing them).
  std::uint32_t dropped_transmission_cap = 0;
  std::uint32_t dropped_threshold = 0;  // paths dropped for being path_threshold_db below the strongest
  bool out_of_range = false;  // beyond max_range_m: not traced, no paths (LoS class still classified)
};

struct SnapshotStats {
  std::uint64_t rays = 0;            // Embree queries (shoot-and-bounce + refinement + LoS)
  std::uint64_t candidates = 0;
  std::uint64_t paths = 0;
  std::uint64_t dropped_transmission_cap = 0;
  std::uint64_t dropped_threshold = 0;
  std::uint64_t out_of_range_pairs = 0;
  std::uint64_t diffraction_paths = 0, diffuse_paths = 0;  // kept paths ending in those interactions
  std::uint64_t image_sources = 0, image_tests = 0;         // exact image search (tracer/src/search/)
  std::uint64_t diffuse_tiles = 0, diffuse_views = 0;       // surface tiles; (node, tile) pairs in sight
  // Where the time went (seconds). Stages that run one after the other are
  // wall-clock; the per-pair steps run on every thread at once and are
  // thread-seconds summed over threads (their shares, not their wall time).
  struct Timing {
    double image_search = 0;  // wall: exact image candidates (all sources)
    double shoot = 0;         // wall: shoot-and-bounce (candidates and diffuse gathering)
    double beams = 0;         // wall: the candidates of the rays' beams (in image_search and shoot both)
    double diffuse_views = 0; // wall: surface tiles and each node's visibility of them (diffuse)
    double edges = 0;         // wall: per-node edge visibility pre-pass (diffraction)
    double pairs = 0;         // wall: the per-pair loop below, in total
    double los = 0;           // thread-s: geometric LoS class and the Fresnel-zone label
    double exact = 0;         // thread-s: exact paths of every candidate sequence, the vehicles' knife edges
    double diffraction = 0;   // thread-s: diffracted paths
    double diffuse = 0;       // thread-s: diffuse paths integrated over the tiles both ends see
    double assemble = 0;      // thread-s: diffuse records, de-duplication, threshold
  } time;
};

struct Snapshot {
  std::vector<PairResult> pairs;  // (0,1), (0,2), ..., (1,2), ...
  SnapshotStats stats;
};

// Traces all pairs of `nodes` in the scene's current frame. Deterministic for
// any number of threads.
Snapshot trace_snapshot(const TraceScene& scene, const std::vector<Node>& nodes, const TracerConfig& config,
                        const RadioConfig& radio);

// Traces only the listed pairs (i < j, each once), in that order. A pair's
// result equals its result in trace_snapshot: candidates come from its two
// ends only. Sweeps use it to retrace the pairs a moving vehicle touched.
Snapshot trace_pairs(const TraceScene& scene, const std::vector<Node>& nodes,
                     const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs, const TracerConfig& config,
                     const RadioConfig& radio);

// The same, with face sequences carried from earlier searches solved
// besides this search's candidates: carried[p] for pairs[p], each from the
// pair's lower end. Each is solved exactly (image method, exact visibility),
// so a carried sequence that no longer holds adds nothing; and each pair's
// PairResult::proposed is filled, for the caller to carry on. A sweep that
// carries a few frames' proposals on turned lattices samples as many
// lattices as frames (generators/sweep/sweep.hpp).
using FaceSequences = std::vector<std::vector<FaceRef>>;
Snapshot trace_pairs(const TraceScene& scene, const std::vector<Node>& nodes,
                     const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs, const TracerConfig& config,
                     const RadioConfig& radio, const std::vector<FaceSequences>& carried);

// Diffuse power (the sum of |a|^2 of the diffuse records trace_pairs gives
// the pairs (src, r)) at each of `receivers` from node `src`'s shoot-and-
// bounce rays (diffuse_integration = "rays"; 0 otherwise, and beyond range):
// one source to many points (radio maps) without the pairs' other work.
// The points do not shoot, so this is the one-sided estimator: it equals
// trace_pairs' diffuse with diffuse_both_ends = false (src the lower index
// of each pair); the path threshold is not applied.
std::vector<double> diffuse_power(const TraceScene& scene, const std::vector<Node>& nodes, std::uint32_t src,
                                  const std::vector<std::uint32_t>& receivers, const TracerConfig& config,
                                  const RadioConfig& radio);

// The exact path from `from` to `to` reflecting on `faces` in order, or
// nullopt when it does not exist (off a face, blocked, or over the slab cap:
// `over_cap` says which). Exposed for tests (reciprocity, closed forms).
// Reflections keep em.specular_keep() of their field (rough surfaces).
std::optional<Path> compute_path(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& config,
                                 const Node& from, const Node& to, const std::vector<FaceRef>& faces,
                                 bool* over_cap = nullptr, std::uint64_t* rays = nullptr);

// The diffracted path from `from` to `to` over edge `edge` (a static or a
// vehicle's: Keller's law, both sides visible), or nullopt. With `before`
// (`after`), a specular reflection on that static face before (after) the
// edge: reflection-diffraction and diffraction-reflection, unfolded through
// the face's plane; every leg clear, the reflection point on its face. A
// path of power |a|^2 below `min_power` (> 0) is not traced: nullopt, its
// legs' rays not cast. `blocked` (optional): set when a leg is blocked, the
// path otherwise being there.
std::optional<Path> compute_diffraction_path(const TraceScene& scene, const Electromagnetics& em, const Node& from,
                                             const Node& to, const Edge& edge, std::uint64_t* rays = nullptr,
                                             const FaceRef* before = nullptr, const FaceRef* after = nullptr,
                                             double min_power = 0, bool* blocked = nullptr);

// The LoS class of the direct segment and the objects blocking it.
LosClass classify_los(const TraceScene& scene, const Vec3& a, const Vec3& b, std::vector<std::uint32_t>& blockers,
                      std::uint64_t* rays = nullptr);


}  // namespace raysweep::tracer
