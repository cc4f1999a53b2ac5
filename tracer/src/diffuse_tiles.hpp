// Diffuse scattering by surface tiles (effective roughness, Degli-Esposti
// 2007), integrated deterministically over the static surfaces that scatter.
//
// Every static face whose material has S > 0 is cut into a tree of
// triangles by longest-edge bisection (long thin wall triangles give compact
// tiles, and every level partitions the face's area exactly), down to
// leaves whose longest edge is at most `diffuse_tile_m`. Per snapshot, each
// antenna decides the visibility of the tiles no larger than
// `diffuse_tile_ratio` times their distance (coarse far away, fine nearby:
// one ray to each such tile's centre; vehicles and buildings block), and a
// pair integrates the bistatic radar-equation term over the tiles both ends
// see:
//
//   dP = S^2 f(k_i, k_s) g_pol lambda^2 A cos(theta_i) / (16 pi^2 r_i^2 r_s^2)
//
// with the midpoint rule on tiles no larger than `diffuse_tile_ratio` times
// the nearer end's distance (below the leaves, tiles are bisected on the
// fly; children inherit their parent's visibility), so the rule's error,
// O((size / distance)^2) per tile, stays bounded everywhere. The
// term is evaluated from both ends and averaged, so a_ij = a_ji bitwise.
// Energy: specular reflections on these faces keep sqrt(1 - S^2) of their
// field (Electromagnetics::specular_keep), the R^2 + S^2 = 1 partition.
//
// Only the first interaction scatters (source -> tile -> receiver): diffuse
// scattering after earlier reflections, and through slabs, is not modelled
// (docs/tracer.md measures what that leaves out against the ray-based
// estimator, `diffuse_integration = "rays"`).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "em/scattering.hpp"
#include "tracer/solver.hpp"

namespace raysweep::tracer {

class DiffuseTiles {
 public:
  // The tile tree of the scattering static faces (built once per scene and
  // tile size, kept with the TraceScene), and each wanted node's view of it
  // (visibility rays: counted in rays()). `range`: tiles farther from a
  // node than this are not seen by it.
  DiffuseTiles(const TraceScene& scene, const Electromagnetics& em, const std::vector<Node>& nodes,
               const std::vector<unsigned char>& wanted, const TracerConfig& cfg, double range);
  ~DiffuseTiles();

  // Diffuse paths of pair (a, b), a < b: one per scattering object and delay
  // bin of `bin_s` (power-weighted delay, directions, point and Doppler;
  // phase of the bin delay's carrier phase), appended to `out`.
  void pair_paths(std::uint32_t a, std::uint32_t b, double bin_s, std::vector<Path>& out) const;

  std::size_t tile_count() const;  // finest tiles (longest edge <= diffuse_tile_m)
  std::uint64_t rays() const { return rays_; }
  std::uint64_t views() const;  // (node, tile) visibility decisions

  struct Tree;   // the tile tree
  struct View;   // a tile as one node sees it
  struct Sight;  // one node's visibility cut through the tile tree

 private:
  class PairWalk;  // pair_paths' walk through both ends' cuts

  // The part of the view that decides whether the node faces the tile.
  bool faces(std::uint32_t node, const Vec3& centre, std::uint32_t face, View& out) const;
  // The rest: the incident field and the lobe (after faces() held).
  void complete(std::uint32_t node, std::uint32_t face, View& out) const;
  bool view(std::uint32_t node, const Vec3& centre, std::uint32_t face, View& out) const {
    if (!faces(node, centre, face, out)) return false;
    complete(node, face, out);
    return true;
  }

  const TraceScene& scene_;
  const Electromagnetics& em_;
  const std::vector<Node>& nodes_;
  double ratio_ = 0.25;
  double shadow_ratio_ = 0;
  std::shared_ptr<const Tree> tree_;
  std::vector<Sight> sight_;  // per node
  std::uint64_t rays_ = 0;
};

}  // namespace raysweep::tracer
