// A propagation mechanism: what one snapshot's pairs share is prepared once
// (candidate searches, visibility pre-passes), then each pair adds its
// paths. trace_pairs runs the enabled mechanisms in a fixed order, so a
// pair's paths come out in the same order for any thread count.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "snapshot_plan.hpp"

namespace raysweep::tracer {

// One pair at work: its ends, its slot in the plan and the direct line's
// labels, which the direct and diffraction mechanisms read.
struct PairTrace {
  std::size_t slot = 0;          // in SnapshotPlan::pairs
  std::uint32_t tx = 0, rx = 0;  // node indices, tx < rx (PairResult's)
  FresnelObstruction zone;     // the direct line's first Fresnel zone
  std::uint64_t* rays = nullptr;  // the thread's ray counter
};

class Mechanism {
 public:
  virtual ~Mechanism() = default;
  // Once per snapshot, before any pair, in registry order; may run
  // parallel loops itself. Records its wall time and counters in `stats`.
  virtual void prepare(SnapshotPlan& plan, SnapshotStats& stats) = 0;
  // Appends the pair's paths to res.paths and counts its candidates and
  // drops in `res`. Runs concurrently for different pairs.
  virtual void add_paths(const SnapshotPlan& plan, const PairTrace& pair, PairResult& res) const = 0;
  // The per-pair thread-time field add_paths is charged to.
  virtual double SnapshotStats::Timing::*pair_time() const = 0;
};

using Mechanisms = std::vector<std::unique_ptr<Mechanism>>;

// The mechanisms `cfg` enables, in the order their paths are appended:
// direct (with vehicles as knife edges), specular / refracted, diffracted,
// diffuse. Each factory returns nullptr when its mechanism is off.
Mechanisms make_mechanisms(const TracerConfig& cfg);

// The per-pair steps of trace_pairs. label_pair: the direct line's LoS class,
// its Fresnel zone and label (into pair.zone and res). sequence_path: the
// exact path through `faces` (with the vehicles as knife edges on its legs
// when configured) appended to res.paths; false when it does not exist
// (`blocked`: why, when it exists geometrically: a static face or a vehicle
// blocks it (exact_path.hpp), or it crosses too many slabs; else 0).
// assemble_paths: sorted by delay, duplicates and paths below the threshold
// dropped, statistics.
void label_pair(const SnapshotPlan& plan, PairTrace& pair, PairResult& res);
enum : int { kStaticBlocked = 1, kVehicleBlocked = 2, kOverCap = 3 };
bool sequence_path(const SnapshotPlan& plan, const PairTrace& pair, const std::vector<FaceRef>& faces,
                   PairResult& res, int* blocked = nullptr);
void assemble_paths(const TracerConfig& cfg, PairResult& res);
// The snapshot's totals (SnapshotStats' counts) from its pairs.
void count_paths(Snapshot& snap);

std::unique_ptr<Mechanism> make_direct(const TracerConfig& cfg);
std::unique_ptr<Mechanism> make_specular(const TracerConfig& cfg);
std::unique_ptr<Mechanism> make_diffraction(const TracerConfig& cfg);
std::unique_ptr<Mechanism> make_diffuse(const TracerConfig& cfg);

}  // namespace raysweep::tracer
