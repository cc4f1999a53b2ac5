// Shoot-and-bounce: rays from every source over a Fibonacci lattice. One
// pass serves three consumers: face sequences passing near the other nodes
// (specular candidates, refined exactly by the image method), the beams of
// wall-vehicle and wall-wall combinations the image search enumerates, and
// the diffuse power gathered at each hit (diffuse_integration rays/hybrid).
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include "search/beam_search.hpp"
#include "search/face_index.hpp"
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

// Diffuse contributions of one source's rays, binned per receiver,
// scattering object (a building, the ground, a vehicle) and delay bin of
// 1 / bandwidth: contributions the system cannot resolve in delay, from one
// object (so from one direction, roughly), become one path. Sums run in a
// fixed order (rays within a chunk, chunks in index order), so the result
// does not depend on the thread count.
struct DiffuseKey {
  std::uint32_t rx = 0;
  std::uint32_t object = 0;
  std::int64_t bin = 0;
  // A contribution to the pair (rx, source) gathered by the higher end's
  // rays (first order, both ends' estimator): rx is the pair's lower end.
  bool reverse = false;
  auto operator<=>(const DiffuseKey&) const = default;
};
struct DiffuseKeyHash {
  std::size_t operator()(const DiffuseKey& k) const {
    return (k.rx * 0x9E3779B97F4A7C15ull) ^ (std::size_t(k.object) * 0xC2B2AE3D27D4EB4Full) ^
           static_cast<std::size_t>(k.bin) * 0x100000001B3ull ^ static_cast<std::size_t>(k.reverse);
  }
};
struct DiffuseAcc {
  double power = 0;          // sum of |a|^2
  double tau = 0;            // power-weighted sums from here on
  Vec3 point{0, 0, 0};       // scattering point
  Vec3 departure{0, 0, 0};   // ray direction at the source
  Vec3 arrival{0, 0, 0};     // from rx towards the scattering point
  double doppler = 0;
  // The strongest single contribution's chain (earlier reflections, then
  // the scattering face) names the path's interactions.
  double peak = 0;
  int n = 0;
  std::array<FaceRef, kMaxDepth + 1> faces{};
  std::array<Vec3, kMaxDepth> prefix{};
  // The chain runs the other way (the scattering first, then the
  // reflections in reverse order): gathered by the pair's higher end.
  bool scatter_first = false;
  void add(const DiffuseAcc& o) {
    power += o.power;
    tau += o.tau;
    point = point + o.point;
    departure = departure + o.departure;
    arrival = arrival + o.arrival;
    doppler += o.doppler;
    if (o.peak > peak) {
      peak = o.peak;
      n = o.n;
      faces = o.faces;
      prefix = o.prefix;
      scatter_first = o.scatter_first;
    }
  }
};
using DiffuseBins = std::vector<std::pair<DiffuseKey, DiffuseAcc>>;

// What a source needs to scatter towards its receivers.
struct DiffuseTargets {
  std::vector<std::uint32_t> rx;  // receivers j > src of requested, in-range pairs
  // Both ends' estimator (TracerConfig::diffuse_both_ends): the lower ends
  // j < src of requested pairs. src's rays sample their first-order
  // scattering too (the two ends' samples combined by weights), and alone
  // the scattering that comes before reflections or slabs (j -> x -> ...
  // -> src: the reverse of what src's rays reach after bouncing).
  std::vector<std::uint32_t> rev;
  bool both_ends = false;
  // Whether the rays gather first-order scattering too (hybrid: the tiles
  // integrate it, the rays only what follows or precedes reflections and
  // slabs).
  bool first_order = true;
  double bin_s = 1e-7;  // delay bin width
  // Samples below this power (|a|^2) play Russian roulette (0: none).
  double roulette = 0;
  // Per node, the static faces one convex face hides whole from it
  // (hidden_by_convex_face; a bitset over the static faces, empty: none
  // known): no shadow ray from such a face to that node can be clear.
  const std::vector<std::vector<std::uint64_t>>* hidden = nullptr;
  bool hides(std::uint32_t node, const FaceRef& face) const {
    if (!hidden || face.instance != 0) return false;
    const auto& bits = (*hidden)[node];
    return !bits.empty() && ((bits[face.face >> 6] >> (face.face & 63)) & 1);
  }
};

// The roulette's threshold for `cfg` (TracerConfig::diffuse_roulette_db).
double roulette_power(const TracerConfig& cfg, const RadioConfig& radio);

// Lattice rays per shooting task: sums over a source's rays run chunk by
// chunk in index order (trace_pairs and diffuse_power alike), so they do not
// depend on the thread count and both give the same numbers.
constexpr std::size_t kShootChunk = 256;

// Shoot-and-bounce from node `src`: face sequences that pass near other nodes
// and, with diffuse scattering on, the scattered power at each hit.
void shoot_from(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& cfg,
                const std::vector<Node>& nodes, std::uint32_t src, const std::vector<Vec3>& lattice,
                std::size_t begin, std::size_t end, std::vector<CandidateKey>& out, std::uint64_t& rays,
                const DiffuseTargets* diffuse, DiffuseBins* diffuse_out, const ImageFaces* beam_faces = nullptr,
                std::vector<BeamVehicle>* beams = nullptr, std::vector<BeamPair>* beam_pairs = nullptr);

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

}  // namespace raysweep::tracer
