// Specular reflections and refractions: candidate face sequences from the
// exact image search, the beams the rays lit and the shoot-and-bounce rays
// (or every sequence, exhaustive), each refined by the image method into
// the exact path (tracer/src/exact_path.hpp).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "exact_path.hpp"
#include "mechanisms/mechanism.hpp"
#include "search/beam_search.hpp"
#include "search/image_search.hpp"
#include "search/visibility.hpp"

namespace raysweep::tracer {

namespace {

using Sequences = std::vector<std::vector<FaceRef>>;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Every sequence of faces up to max_depth, no face twice in a row.
void enumerate_all(const TraceScene& scene, int depth, std::vector<FaceRef>& current,
                   std::vector<std::vector<FaceRef>>& out) {
  if (!current.empty()) out.push_back(current);
  if (static_cast<int>(current.size()) == depth) return;
  const std::uint32_t instances = static_cast<std::uint32_t>(scene.vehicles().size() + 1);
  for (std::uint32_t i = 0; i < instances; ++i)
    for (std::uint32_t f = 0; f < scene.face_count(i); ++f) {
      const FaceRef ref{i, f};
      if (!current.empty() && current.back() == ref) continue;
      current.push_back(ref);
      enumerate_all(scene, depth, current, out);
      current.pop_back();
    }
}

// The exhaustive reference holds every sequence for every pair: a city's
// thousands of faces at depth 2 already ask for more memory than a machine
// has (the demo's: killed at 24 GB). Refused, with the numbers, above this
// many sequences over all pairs (about 50 bytes each).
constexpr double kMaxExhaustiveSequences = 2e8;

void check_exhaustive_size(const TraceScene& scene, int depth, std::size_t pairs) {
  double faces = 0;
  for (std::uint32_t i = 0; i <= scene.vehicles().size(); ++i) faces += static_cast<double>(scene.face_count(i));
  double sequences = 0, level = faces;
  for (int d = 1; d <= depth; ++d, level *= std::max(faces - 1, 0.0)) sequences += level;
  if (sequences * static_cast<double>(pairs) <= kMaxExhaustiveSequences) return;
  std::ostringstream msg;
  msg << std::setprecision(3) << "tracer.candidates = \"exhaustive\": " << faces << " faces to depth " << depth
      << " make " << sequences << " sequences for each of " << pairs << " pairs, more than the "
      << kMaxExhaustiveSequences << " this reference holds in memory; it is meant for small scenes (clip the scene, "
      << "lower max_depth or trace fewer nodes)";
  throw std::invalid_argument(msg.str());
}

// Each source's candidates into its pairs' lists, turned to run from the
// pair's lower end.
void file_by_pair(const SnapshotPlan& plan, std::vector<std::vector<ImageCandidate>>& found,
                  std::vector<Sequences>& candidates) {
  for (std::uint32_t i = 0; i < plan.n; ++i)
    for (auto& c : found[i]) {
      if (c.rx < i) std::reverse(c.faces.begin(), c.faces.end());
      candidates[plan.slot.at(SnapshotPlan::key(std::min(i, c.rx), std::max(i, c.rx)))].push_back(
          std::move(c.faces));
    }
}

void add_search_stats(const std::vector<ImageSearchStats>& st, SnapshotStats& stats) {
  for (const auto& s : st) {
    stats.image_sources += s.image_sources;
    stats.image_tests += s.tests;
  }
}

// Order 1 on every face, order 2 on static pairs, the vehicles' own
// multi-bounce tables and the ground's order 3: tracer/src/search/image_search.hpp.
void image_search(const SnapshotPlan& plan, std::vector<Sequences>& candidates, SnapshotStats& stats) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto& cfg = plan.cfg;
  const ImageFaces& faces = plan.faces();
  std::vector<std::vector<ImageCandidate>> found(plan.n);
  std::vector<ImageSearchStats> st(plan.n);
  const SlabBounds& slabs = plan.slab_bounds();
  tbb::parallel_for(std::uint32_t{0}, plan.n, [&](std::uint32_t i) {
    if (plan.partners[i].empty()) return;
    image_candidates(plan.scene, faces, plan.nodes, i, plan.partners[i], std::min(cfg.max_depth, 3), found[i],
                     {.multi_bounce = cfg.vehicle_multi_bounce, .ground_order3 = cfg.ground_order3, .slabs = &slabs},
                     &st[i]);
  });
  add_search_stats(st, stats);
  file_by_pair(plan, found, candidates);
  stats.time.image_search = seconds_since(t0);
}

// The wall-vehicle (order 2, and with the ground order 3) and three-face
// combinations whose beams the rays lit, enumerated exactly.
void beam_search(const SnapshotPlan& plan, ShootPass& pass, std::vector<Sequences>& candidates,
                 SnapshotStats& stats) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto& cfg = plan.cfg;
  const ImageFaces& faces = plan.faces();
  const bool triple_search = !pass.beam_pairs.empty();
  const SlabBounds* slabs = triple_search && plan.image_search ? &plan.slab_bounds() : nullptr;
  std::vector<std::vector<ImageCandidate>> found(plan.n);
  std::vector<ImageSearchStats> st(plan.n);
  tbb::parallel_for(std::uint32_t{0}, plan.n, [&](std::uint32_t i) {
    auto& b = pass.beams[i];
    if (plan.partners[i].empty()) return;
    small_face_beams(faces, plan.nodes[i].position, b);
    std::sort(b.begin(), b.end());
    b.erase(std::unique(b.begin(), b.end()), b.end());
    beam_vehicle_candidates(plan.scene, faces, plan.nodes, i, plan.partners[i], b, found[i],
                            {.with_ground = cfg.ground_order3 && cfg.max_depth >= 3}, &st[i]);
    if (!triple_search) return;
    auto& bp = pass.beam_pairs[i];
    small_face_pairs(plan.scene, faces, plan.nodes[i].position, bp);
    std::sort(bp.begin(), bp.end());
    bp.erase(std::unique(bp.begin(), bp.end()), bp.end());
    beam_pair_candidates(plan.scene, faces, plan.nodes, i, bp, plan.partners[i], found[i], &st[i],
                         cfg.ground_order3, slabs);
  });
  add_search_stats(st, stats);
  file_by_pair(plan, found, candidates);
  stats.time.beams = seconds_since(t0);
  stats.time.image_search += stats.time.beams;
}

// Vehicles as knife edges on a reflected path too: traced through the
// vehicles on its way, attenuated by the legs' multiple knife edge in the
// unfolded path's first zone (continuous as a car enters a leg).
void add_knife_edges(const SnapshotPlan& plan, const PairTrace& pair, const std::vector<FaceRef>& faces,
                     Path& path) {
  const Node &a = plan.nodes[pair.tx], &b = plan.nodes[pair.rx];
  std::vector<Vec3> points{a.position};
  std::vector<int> host{-1};
  std::size_t q = 0;
  for (const auto& in : path.interactions)
    if (in.type == InteractionType::specular) {
      points.push_back(in.point);
      host.push_back(faces[q].instance == 0 ? -1 : static_cast<int>(faces[q].instance) - 1);
      ++q;
    }
  points.push_back(b.position);
  host.push_back(-1);
  const auto ke = plan.obstacles.path_knife_edges(points, host, plan.lambda, a.vehicle, b.vehicle);
  if (!(ke.loss_db > 0)) return;
  path.a *= std::pow(10.0, -ke.loss_db / 20);
  // A leg that crosses a vehicle may also pass through its windows: the
  // stronger of the two, as for the direct path.
  if (ke.v_main > 0)
    if (auto glass = exact_path(plan.scene, plan.em, plan.cfg, a, b, faces, nullptr, pair.rays, false))
      if (std::norm(glass->a) > std::norm(path.a)) path = std::move(*glass);
}

}  // namespace

bool sequence_path(const SnapshotPlan& plan, const PairTrace& pair, const std::vector<FaceRef>& faces,
                   PairResult& res, int* blocked) {
  const auto& cfg = plan.cfg;
  const Node &a = plan.nodes[pair.tx], &b = plan.nodes[pair.rx];
  bool over = false;
  std::optional<Path> path;
  if (!(cfg.vehicle_diffraction && cfg.vehicle_diffraction_reflected) || faces.empty()) {
    path = exact_path(plan.scene, plan.em, cfg, a, b, faces, &over, pair.rays, false, blocked);
  } else {
    path = exact_path(plan.scene, plan.em, cfg, a, b, faces, &over, pair.rays, true, blocked);
    if (path) add_knife_edges(plan, pair, faces, *path);
  }
  if (!path) {
    if (over) ++res.dropped_transmission_cap;
    if (over && blocked) *blocked = kOverCap;
    return false;
  }
  path->origin.kind = PathOrigin::Kind::sequence;
  path->origin.faces = faces;
  res.paths.push_back(std::move(*path));
  return true;
}

namespace {

class Specular final : public Mechanism {
 public:
  void prepare(SnapshotPlan& plan, SnapshotStats& stats) override {
    const auto& cfg = plan.cfg;
    candidates_.assign(plan.pairs.size(), {});
    if (plan.n < 2) return;
    if (plan.image_search) image_search(plan, candidates_, stats);
    if (cfg.candidates == CandidateSearch::exhaustive) {
      check_exhaustive_size(plan.scene, cfg.max_depth, plan.pairs.size());
      Sequences all;
      std::vector<FaceRef> current;
      enumerate_all(plan.scene, cfg.max_depth, current, all);
      for (std::size_t p = 0; p < plan.pairs.size(); ++p)
        if (plan.in_range[p]) candidates_[p] = all;
    }
    ShootPass& pass = plan.shoot();
    // What the rays and their beams proposed: this search's sample, which a
    // caller carrying sequences keeps (PairResult::proposed).
    std::vector<Sequences>& sampled = plan.carried ? proposed_ : candidates_;
    if (plan.carried) proposed_.assign(plan.pairs.size(), {});
    for (std::size_t p = 0; p < pass.candidates.size(); ++p)
      for (auto& faces : pass.candidates[p]) sampled[p].push_back(std::move(faces));
    pass.candidates.clear();
    if (!pass.beams.empty()) beam_search(plan, pass, sampled, stats);
    // Thread-local order varies; the sorted set does not.
    tbb::parallel_for(std::size_t{0}, candidates_.size(), [&](std::size_t p) {
      auto& c = candidates_[p];
      if (plan.carried) {
        sort_unique(proposed_[p]);
        c.insert(c.end(), proposed_[p].begin(), proposed_[p].end());
        c.insert(c.end(), (*plan.carried)[p].begin(), (*plan.carried)[p].end());
      }
      sort_unique(c);
    });
  }

  void add_paths(const SnapshotPlan& plan, const PairTrace& pair, PairResult& res) const override {
    const auto& candidates = candidates_[pair.slot];
    int blocked = 0;
    for (const auto& faces : candidates)
      if (!sequence_path(plan, pair, faces, res, &blocked) && blocked == kVehicleBlocked)
        res.near_misses.push_back(faces);
    res.candidates += static_cast<std::uint32_t>(candidates.size());
    if (!proposed_.empty()) res.proposed = proposed_[pair.slot];
  }

  double SnapshotStats::Timing::*pair_time() const override { return &SnapshotStats::Timing::exact; }

 private:
  static void sort_unique(Sequences& c) {
    std::sort(c.begin(), c.end());
    c.erase(std::unique(c.begin(), c.end()), c.end());
  }

  std::vector<Sequences> candidates_;  // per pair, sorted
  std::vector<Sequences> proposed_;    // per pair, sorted: the rays' and beams' (with carried sequences only)
};

}  // namespace

std::unique_ptr<Mechanism> make_specular(const TracerConfig& cfg) {
  return cfg.specular && cfg.max_depth > 0 ? std::make_unique<Specular>() : nullptr;
}

}  // namespace raysweep::tracer
