// Radio and tracer settings ([radio], [tracer] and [materials.<name>] in the
// TOML config; the pipeline parses them, the tracer only consumes them).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "tracer/em/antenna.hpp"
#include "tracer/em/materials.hpp"

namespace raysweep::tracer {

struct RadioConfig {
  double frequency_hz = 5.9e9;
  double bandwidth_hz = 10e6;
  double tx_power_dbm = 30;  // recorded for the generators; path gains do not depend on it
  // Weakest power a receiver can use: with tx_power_dbm and the antennas'
  // peak gains it sets the free-space reach beyond which pairs are labelled
  // out of range and not traced (TracerConfig::range_margin_db).
  double sensitivity_dbm = -93;
  AntennaSpec antenna;       // the same pattern at every node (vertical isotropic by default)
};

enum class CandidateSearch {
  // Exact image search (every face at order 1, every pair of static faces
  // at order 2: tracer/src/search/) plus shoot-and-bounce for the rest
  // (order-2 sequences touching a vehicle, orders >= 3). Default.
  image,
  sbr,        // shoot-and-bounce only, from every node over a Fibonacci lattice
  exhaustive  // every face sequence up to max_depth: small scenes and tests only
};

// How the diffuse field is integrated over the rough surfaces.
enum class DiffuseIntegration {
  // Monte Carlo over the shoot-and-bounce rays' hits, also after earlier
  // reflections and through slabs; reciprocal in expectation only. Default.
  rays,
  // Deterministic: static surfaces cut into a tree of tiles
  // (tracer/src/diffuse_tiles.hpp), visibility per node, midpoint rule per pair;
  // converged and bitwise reciprocal, first-order scattering only.
  tiles,
  // Both: the tiles for first-order scattering (source -> surface ->
  // receiver, nothing crossed), the rays for the rest (scattering before or
  // after reflections, through slabs), which the tiles do not model.
  hybrid
};

// How a reflection on a vehicle face is weighted. Vehicle bodies are meshes
// of facets a few tens of centimetres wide, smaller than the first Fresnel
// zone at their reflection point (0.5-1 m across at 10-50 m).
enum class FacetReflection {
  // Physical optics: the Kirchhoff integral over the face, in the Fresnel
  // approximation about the specular point (tracer/src/em/physical_optics.hpp),
  // as a factor on the GO reflection.
  po,
  // Geometrical optics: every face an infinite mirror (what Sionna RT does).
  // Default: po on the faces GO finds alone leaves curved bodies' return
  // short (docs/decisions.md).
  go
};

struct TracerConfig {
  int max_depth = 3;  // specular reflections per path (0..kMaxDepth)
  bool los = true;
  bool specular = true;
  bool refraction = true;  // transmission through slabs (without bending)
  // 6144: the least (of 4096, 6144, 8192) whose pairs' gains are within
  // 1 dB p95 of a 65,536-ray reference at the sensitivity floor on both
  // bundled cities (`raysweep tradeoff`, docs/performance.md); 4096 is 19-23 % faster
  // and 1.02 dB off on the demo city (the diffuse estimator's variance).
  int rays_per_source = 6144;
  // The lattice's turn (fibonacci_sphere(n, turn); 0: not turned). Sweeps
  // with [sweep] lattice_frames > 1 set it per frame (generators/sweep).
  std::uint64_t lattice_turn = 0;
  // More lattices for the diffuse gathering alone (their turns; none by
  // default): their rays gather diffuse power as the frame's own do, and
  // every lattice's samples count 1 / (1 + diffuse_turns.size()), so the
  // diffuse records are the mean of that many lattices' estimates. Sweeps
  // with [sweep] diffuse_frames > 1 set them to the frames' before
  // (generators/sweep): consecutive frames share most of their samples.
  // Not a TOML setting of its own.
  std::vector<std::uint64_t> diffuse_turns;
  // Reception sphere radius = factor * angular ray spacing * unfolded length.
  // Candidates are refined exactly, so a generous sphere only costs time.
  double reception_radius_factor = 1.0;
  // Vehicle bundles (tracer/src/shoot/vehicle_bundles.cpp, docs/tracer.md):
  // per source, rays aimed at each other vehicle that the lattice covers
  // with fewer than vehicle_bundle_rays, and through each static face whose
  // beam the lattice showed reaching one. Chains of two vehicles, or
  // through one's cabin onto another, need a far vehicle hit densely, which
  // 6144 rays over the sphere do not give.
  bool vehicle_bundles = true;
  int vehicle_bundle_rays = 16;
  bool vehicle_bundles_via_faces = true;
  CandidateSearch candidates = CandidateSearch::image;
  // Slabs a path may cross (a vehicle's two windows, a building's two
  // walls); an exact path crossing more is dropped and counted in its pair
  // record (never silently).
  int max_transmissions = 2;
  // Shoot-and-bounce rays continue through slabs (up to max_transmissions)
  // while their summed normal-incidence transmission loss stays within this
  // budget, so reflections behind windows and brick walls are found while
  // rays do not fan out through every concrete wall (0.3 m concrete costs
  // about 40 dB at 5.9 GHz; such paths stay below the ones found in front).
  // A huge value makes the search space equal the exhaustive one.
  double sbr_transmission_loss_db = 20;
  // Diffuse scattering (effective roughness model) from the hits of the
  // shoot-and-bounce rays, on materials with a scattering coefficient > 0.
  // When on, specular reflections on those materials keep sqrt(1 - S^2) of
  // their field (the R^2 + S^2 = 1 energy partition).
  bool diffuse = true;
  DiffuseIntegration diffuse_integration = DiffuseIntegration::rays;
  // Rays: first-order scattering (a -> surface -> b, nothing crossed before
  // the surface) is gathered from both ends' rays and combined by multiple
  // importance sampling (balance heuristic on the two ends' hit densities),
  // so points near either end are sampled densely; scattering before
  // reflections (a -> surface -> reflections -> b) from the higher end's
  // rays, which reach it. Off: the lower end's rays alone (scattering after
  // reflections only: the one-sided estimator radio maps use; tests).
  bool diffuse_both_ends = true;
  // Rays: Russian roulette on the gathering's shadow rays. A sample whose
  // power (|a|^2, bounded before its shadow ray) lies below the weakest
  // usable one (radio.sensitivity_dbm - radio.tx_power_dbm) by more than
  // this many dB is kept with probability power / threshold and then
  // counts the threshold: unbiased, and a pair whose total reaches the
  // sensitivity gets a relative standard deviation of at most
  // 10^(-diffuse_roulette_db / 20) from it. Most samples are that weak
  // (at 10 dB, two thirds of a 60-vehicle demo snapshot's, holding 1.5 % of
  // their power), and a shadow ray costs more than the sample's arithmetic.
  // >= 300: off (every sample traced; the tradeoff's reference).
  double diffuse_roulette_db = 10;
  // Image search: two and three reflections on one vehicle (its concave
  // corners, its cabin through the windows) from the per-model table of
  // multi-bounce sequences (TraceScene::vehicle_bounce_sequences). Off:
  // those come from shoot and bounce alone.
  bool vehicle_multi_bounce = true;
  // Image search: three reflections with one on the ground, exactly: among
  // static faces (wall, ground, wall; the ground first or last), and a wall,
  // a vehicle and the ground in any order (the vehicles from the rays' wall-
  // vehicle combinations). Off: those come from shoot and bounce alone.
  bool ground_order3 = true;
  // Image search: three reflections that begin on a static face (wall,
  // wall or car, then a wall or a car; BeamPair). The first two faces come
  // from the shoot-and-bounce rays that reflect on both (the beam is lit;
  // a small static face also when a ray passes it), the third from the
  // pair's beam, exactly. Off: those come from shoot and bounce alone.
  bool beam_order3 = true;
  // Tiles: the finest tile's longest edge (m: where shadow edges are
  // resolved), and the largest tile used relative to its distance from the
  // node that looks (visibility) or from the nearer end (integration;
  // bigger ones are bisected): the midpoint rule's error stays O(ratio^2).
  double diffuse_tile_m = 1.0;
  double diffuse_tile_ratio = 0.25;
  // Tiles: where a shadow edge crosses a tile, it is refined down to tiles
  // of this ratio to their distance, or to diffuse_tile_m (0, the default:
  // to the leaves everywhere; far shadows then cost most of the rays).
  double diffuse_shadow_ratio = 0;
  // First-order UTD edge diffraction on the static scene's wedges
  // (TraceScene::edges()), finite conductivity by Luebbers' coefficients.
  bool diffraction = true;
  // With diffraction: a specular reflection on a static face before or
  // after the edge (reflection-diffraction, diffraction-reflection: the
  // ground bounce over a roof edge, a wall's echo round a corner).
  bool diffraction_reflection = true;
  // Vehicles in the first Fresnel zone of the direct path attenuate it by
  // ITU-R P.526's knife-edge loss (Deygout for several: tracer/src/fresnel_zone.hpp);
  // a direct ray only vehicles block survives, attenuated.
  bool vehicle_diffraction = true;
  // With vehicle_diffraction, the same on every specular path: each leg's
  // vehicles against the unfolded path's first zone (Deygout along the
  // path); a path only vehicles block is traced through them, attenuated.
  // Off by default: +30-70 % per 60-vehicle snapshot (docs/tracer.md).
  bool vehicle_diffraction_reflected = false;
  // First-order UTD diffraction on the vehicles' edges (roofs, hoods,
  // pillars: TraceScene::vehicle_edges), with the static edges' wedge
  // coefficients. A vehicle the knife edge covers (inside 0.55 r1 of the
  // direct line) diffracts by its knife edge alone; between 1.0 and 0.55 r1
  // its UTD paths fade out linearly in clearance, so the two never add.
  bool vehicle_edge_diffraction = false;
  // Reflections on vehicle faces as infinite mirrors (go, what Sionna RT
  // does) or by physical optics over the face (po: fewer one-frame glints,
  // but its near misses are sampled, not searched: docs/decisions.md).
  FacetReflection facet_reflection = FacetReflection::go;
  // Vehicle-edge paths weaker than this (dB) below the pair's direct
  // free-space power are not traced (their field is computed first, the
  // legs' rays only for those above): away from its shadow and reflection
  // boundaries an edge's field is 25-40 dB below that.
  double vehicle_edge_floor_db = 40;
  // A pair's paths weaker than its strongest by more than this (dB) are
  // dropped and counted in PairResult::dropped_threshold. <= 0: keep all.
  double path_threshold_db = 60;
  // Pairs farther apart than the free-space reach of the sensitivity plus
  // this margin (dB: constructive ground reflection adds up to 6 dB) are
  // labelled out of range and not traced. A huge value traces every pair.
  double range_margin_db = 6;
  std::map<std::string, MaterialOverride> materials;
};

// Distance beyond which free space (with both antennas' peak gains and the
// margin) cannot reach radio.sensitivity_dbm.
double max_range_m(const TracerConfig& tracer, const RadioConfig& radio);

constexpr int kMaxDepth = 16;

// Throws std::invalid_argument naming the offending setting.
void validate(const TracerConfig& tracer, const RadioConfig& radio);

}  // namespace raysweep::tracer
