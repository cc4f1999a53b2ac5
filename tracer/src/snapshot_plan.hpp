// What every mechanism of one snapshot shares: the requested pairs and
// which are in range, the nodes that serve as sources, the scene's faces
// as the image search indexes them, the Fresnel-zone obstacles, and the
// shoot-and-bounce pass (run once, for whichever mechanisms need it).
#pragma once

#include <cstdint>
#include <memory>
#include <unordered_map>
#include <utility>
#include <vector>

#include "fresnel_zone.hpp"
#include "search/face_index.hpp"
#include "search/visibility.hpp"
#include "shoot/shoot.hpp"
#include "tracer/solver.hpp"

namespace raysweep::tracer {

using PairList = std::vector<std::pair<std::uint32_t, std::uint32_t>>;

struct SnapshotPlan {
  // Checks the pairs (i < j < node count, each once); throws
  // std::invalid_argument naming the first bad one.
  SnapshotPlan(const TraceScene& scene, const std::vector<Node>& nodes, const PairList& pairs,
               const TracerConfig& cfg, const RadioConfig& radio, const Electromagnetics& em);

  const TraceScene& scene;
  const std::vector<Node>& nodes;
  const PairList& pairs;
  const TracerConfig& cfg;
  const RadioConfig& radio;
  const Electromagnetics& em;
  std::uint32_t n = 0;  // nodes
  double range = 0;     // max_range_m: farther pairs are labelled, not traced
  double lambda = 0;

  // Which pair slot each (i, j) feeds. Sources shoot only when they have a
  // pair to serve; a pair's candidates come from its own two ends, so a
  // pair traced alone gets exactly the paths it gets in a full snapshot.
  std::unordered_map<std::uint64_t, std::size_t> slot;
  std::vector<unsigned char> in_range;        // per pair
  std::vector<std::uint32_t> sources;         // sorted
  std::vector<unsigned char> is_source;       // per node
  std::vector<std::vector<std::uint32_t>> partners;  // per node: its in-range partners, sorted
  FresnelObstacles obstacles;

  // The search stages that more than one mechanism reads, from the config.
  bool image_search = false;  // exact image candidates (CandidateSearch::image)
  bool sbr_specular = false;  // the rays propose specular sequences
  bool ray_diffuse = false;   // the rays gather diffuse power
  bool tile_diffuse = false;  // surface tiles integrate first-order scattering

  static std::uint64_t key(std::uint32_t i, std::uint32_t j) { return static_cast<std::uint64_t>(i) << 32 | j; }
  // The scene's faces as the image search indexes them (built on first use).
  const ImageFaces& faces() const;
  // Every source's lower bounds on the slabs to each static face, with the
  // cap the exact paths keep (built on first use): the image search prunes
  // sequences by them, the reflection-diffraction search the faces they
  // hide whole (a bound of one or more).
  const SlabBounds& slab_bounds() const;
  // The shoot-and-bounce pass (run on first use; empty when no stage needs it).
  ShootPass& shoot();
  double shoot_seconds() const { return shoot_ ? shoot_->seconds : 0; }

  std::uint64_t search_rays = 0;  // rays cast by the per-snapshot stages
  // Sequences carried from earlier searches, per pair (trace_pairs); null
  // when none are: then PairResult::proposed stays empty.
  const std::vector<FaceSequences>* carried = nullptr;

 private:
  mutable std::unique_ptr<ImageFaces> faces_;
  mutable std::unique_ptr<SlabBounds> slabs_;
  std::unique_ptr<ShootPass> shoot_;
};

}  // namespace raysweep::tracer
