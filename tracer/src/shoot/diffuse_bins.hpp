// What the rays' diffuse gathering fills and the diffuse mechanism reads:
// the contributions binned per receiver, object and delay (DiffuseKey,
// DiffuseAcc), and what a source scatters towards (DiffuseTargets).
#pragma once

#include <array>
#include <compare>
#include <cstdint>
#include <utility>
#include <vector>

#include "tracer/solver.hpp"

namespace raysweep::tracer {

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
  // The share of the estimate one lattice's samples carry: 1 / the lattices
  // that gather (TracerConfig::diffuse_turns); each sample's solid angle is
  // 4 pi / rays times this (and `roulette` is scaled by it).
  double share = 1.0;
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

}  // namespace raysweep::tracer
