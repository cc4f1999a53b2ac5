// Shoot-and-bounce: rays from every source over a Fibonacci lattice. One
// pass serves three consumers: face sequences passing near the other nodes
// (specular candidates, refined exactly by the image method), the beams of
// wall-vehicle and wall-wall combinations the image search enumerates, and
// the diffuse power gathered at each hit (diffuse_integration rays/hybrid).
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include "search/beam_search.hpp"
#include "search/face_index.hpp"
#include "shoot/diffuse_bins.hpp"
#include "tracer/solver.hpp"

namespace raysweep::tracer {

struct SnapshotPlan;

// A face sequence a ray of one source proposed for the pair (source, other).
struct CandidateKey {
  std::uint32_t other;
  std::vector<FaceRef> faces;
  bool operator==(const CandidateKey&) const = default;
};
struct CandidateHash {
  std::size_t operator()(const CandidateKey& k) const {
    std::size_t h = k.other * 0x9E3779B97F4A7C15ull;
    for (const auto& f : k.faces) h = (h ^ (std::size_t(f.instance) << 32 ^ f.face)) * 0x100000001B3ull;
    return h;
  }
};

// A bundle ray's aim (shoot_vehicle_bundles): straight at a vehicle, or at
// one through `face` (a static face, or another vehicle's). `spacing` is the
// bundle's angular spacing at the source.
struct BundleTarget {
  FaceRef face{};
  bool via_face = false;
  double spacing = 0;
};

// What every ray of a snapshot sees: the scene, its materials, the
// settings and the nodes.
struct ShootContext {
  const TraceScene& scene;
  const Electromagnetics& em;
  const TracerConfig& cfg;
  const std::vector<Node>& nodes;
};

// What a shooting task's rays feed besides the specular candidates they
// propose (each off unless set).
struct ShootFeeds {
  // The diffuse gathering: the power scattered towards these targets
  // (ShootFinds::bins).
  const DiffuseTargets* diffuse = nullptr;
  // The faces the marks below index, and the beams to mark: (static face,
  // vehicle) combinations (ShootFinds::beams) and lit pairs
  // (ShootFinds::beam_pairs).
  const ImageFaces* faces = nullptr;
  bool beams = false, beam_pairs = false;
  // Bundle rays (shoot/vehicle_bundles.cpp): ray r is aimed at bundle[r];
  // with bundle_marks, the (vehicle face, vehicle) beams they show
  // (ShootFinds::beams; a bundle marks no other beams).
  const std::vector<BundleTarget>* bundle = nullptr;
  bool bundle_marks = false;
  // The ray count whose spacing sizes the reception spheres (0: the rays'
  // own).
  std::size_t spacing_rays = 0;
  // Whether the rays propose face sequences near the other nodes (off: a
  // lattice that only gathers diffuse power).
  bool propose = true;
  // Mixed into the diffuse roulette's sample identity: lattices of other
  // turns draw other numbers for their rays of the same index (0: none).
  std::uint64_t sample_salt = 0;
};

// One shooting task's finds: a source's chunk of the lattice.
struct ShootFinds {
  std::vector<CandidateKey> found;
  DiffuseBins bins;
  std::vector<BeamVehicle> beams;
  std::vector<BeamPair> beam_pairs;
  std::uint64_t rays = 0;
};

// Lattice rays per shooting task: sums over a source's rays run chunk by
// chunk in index order (trace_pairs and diffuse_power alike), so they do not
// depend on the thread count and both give the same numbers.
constexpr std::size_t kShootChunk = 256;

// Shoot-and-bounce from node `src`, rays [begin, end) of `lattice`: face
// sequences that pass near other nodes and what `feeds` asks for.
void shoot_from(const ShootContext& world, std::uint32_t src, const std::vector<Vec3>& lattice, std::size_t begin,
                std::size_t end, const ShootFeeds& feeds, ShootFinds& finds);

// What the shoot-and-bounce pass of one snapshot found, merged per pair in
// task order (the same sums for any thread count).
struct ShootPass {
  // Per pair: face sequences the rays proposed (not those the image search
  // enumerates completely), reversed to run from the pair's lower end.
  std::vector<std::vector<std::vector<FaceRef>>> candidates;
  // Per pair: the diffuse records gathered by both ends' rays.
  std::vector<std::map<DiffuseKey, DiffuseAcc>> diffuse;
  // Per node: the beams its rays lit (for the image search's beam stages).
  std::vector<std::vector<BeamVehicle>> beams;
  std::vector<std::vector<BeamPair>> beam_pairs;
  std::uint64_t rays = 0;
  double seconds = 0;  // wall
};

// Runs the pass for the plan's sources (SnapshotPlan::shoot() runs it once).
ShootPass run_shoot_pass(const SnapshotPlan& plan);

// Merges the tasks' finds into the pass in task order (the same sums for
// any thread count) and clears them: task t shot from task_src[t].
void merge_tasks(const SnapshotPlan& plan, std::vector<ShootFinds>& tasks, const std::vector<std::uint32_t>& task_src,
                 ShootPass& pass);

}  // namespace raysweep::tracer
