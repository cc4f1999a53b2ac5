// The snapshot's orchestration: plan the pairs, let each enabled mechanism
// prepare what its pairs share, then per pair (in parallel) label the
// direct line, collect every mechanism's paths and assemble them.
#include "tracer/solver.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "mechanisms/mechanism.hpp"

namespace raysweep::tracer {

std::vector<Node> vehicle_nodes(const TraceScene& scene) {
  std::vector<Node> nodes;
  const auto& vs = scene.vehicles();
  for (std::size_t v = 0; v < vs.size(); ++v)
    nodes.push_back(Node{vs[v].id, scene.vehicle_antenna(v), vs[v].velocity, scene.vehicle_forward(v),
                         static_cast<int>(v)});
  return nodes;
}

LosClass classify_los(const TraceScene& scene, const Vec3& a, const Vec3& b, std::vector<std::uint32_t>& blockers,
                      std::uint64_t* rays) {
  blockers.clear();
  const double len = norm(b - a);
  if (len <= 0) return LosClass::LOS;
  const Vec3 dir = (1.0 / len) * (b - a);
  std::vector<Hit> hits;
  scene.all_hits(a, dir, scene.slack(a, 0) * 0.1, len - scene.slack(a, len) * 0.1, hits, 1u << 20);
  if (rays) *rays += hits.size() + 1;
  bool static_hit = false;
  for (const auto& h : hits) {
    if (!scene.is_vehicle(h.face)) static_hit = true;
    blockers.push_back(scene.object(h.face));
  }
  std::sort(blockers.begin(), blockers.end());
  blockers.erase(std::unique(blockers.begin(), blockers.end()), blockers.end());
  if (static_hit) return LosClass::NLOS;
  return blockers.empty() ? LosClass::LOS : LosClass::NLOSV;
}

namespace {

using Clock = std::chrono::steady_clock;

void check_nodes(const std::vector<Node>& nodes) {
  for (const auto& n : nodes) {
    for (double c : n.position)
      if (!std::isfinite(c)) throw std::invalid_argument("node " + n.id + ": position is not finite");
    for (double c : n.velocity)
      if (!std::isfinite(c)) throw std::invalid_argument("node " + n.id + ": velocity is not finite");
    for (double c : n.forward)
      if (!std::isfinite(c)) throw std::invalid_argument("node " + n.id + ": orientation is not finite");
  }
}

// Distinct face sequences can still describe one physical path (a point on
// the seam of two faces that are coplanar in fact): keep the first.
std::vector<Path> without_duplicates(std::vector<Path>& paths) {
  std::stable_sort(paths.begin(), paths.end(), [](const Path& a, const Path& b) { return a.tau_s < b.tau_s; });
  std::vector<Path> unique;
  for (auto& path : paths) {
    bool dup = false;
    for (auto it = unique.rbegin(); it != unique.rend() && path.tau_s - it->tau_s < 1e-15; ++it) {
      if (it->interactions.size() != path.interactions.size()) continue;
      bool same = true;
      for (std::size_t q = 0; q < path.interactions.size() && same; ++q)
        same = it->interactions[q].type == path.interactions[q].type &&
               norm(it->interactions[q].point - path.interactions[q].point) < 1e-6;
      dup = same;
      if (dup) break;
    }
    if (!dup) unique.push_back(std::move(path));
  }
  return unique;
}

}  // namespace

// The pair's paths sorted by delay, duplicates dropped, and (model no more
// than matters) those far below its strongest.
void assemble_paths(const TracerConfig& cfg, PairResult& res) {
  std::vector<Path> unique = without_duplicates(res.paths);
  if (cfg.path_threshold_db > 0 && !unique.empty()) {
    double peak = 0;
    for (const auto& path : unique) peak = std::max(peak, std::norm(path.a));
    const double floor = peak * std::pow(10.0, -cfg.path_threshold_db / 10);
    const auto keep = std::stable_partition(unique.begin(), unique.end(),
                                            [&](const Path& path) { return std::norm(path.a) >= floor; });
    res.dropped_threshold = static_cast<std::uint32_t>(unique.end() - keep);
    unique.erase(keep, unique.end());
  }
  res.paths = std::move(unique);
  res.stats = path_stats(res.paths);
}

void label_pair(const SnapshotPlan& plan, PairTrace& pair, PairResult& res) {
  const auto& nodes = plan.nodes;
  res.tx = pair.tx;
  res.rx = pair.rx;
  const Vec3 a = nodes[pair.tx].position, b = nodes[pair.rx].position;
  res.los_class = classify_los(plan.scene, a, b, res.blockers, pair.rays);
  pair.zone = plan.obstacles.between(a, b, plan.lambda, nodes[pair.tx].vehicle, nodes[pair.rx].vehicle);
  res.fresnel_class = fresnel_class(res.los_class, pair.zone);
  res.fresnel_clearance = pair.zone.clearance;
}

namespace {

// One pair: its labels, then every mechanism's paths, assembled. `tm`
// collects the thread's time per step.
void trace_pair(const SnapshotPlan& plan, const Mechanisms& mechanisms, std::size_t p, PairResult& res,
                std::uint64_t& rays, SnapshotStats::Timing& tm) {
  PairTrace pair{p, plan.pairs[p].first, plan.pairs[p].second, {}, &rays};
  auto t_step = Clock::now();
  auto lap = [&t_step](double& into) {
    const auto now = Clock::now();
    into += std::chrono::duration<double>(now - t_step).count();
    t_step = now;
  };
  label_pair(plan, pair, res);
  lap(tm.los);
  if (!plan.in_range[p]) {
    res.out_of_range = true;
    res.stats = path_stats(res.paths);
    return;
  }
  for (const auto& m : mechanisms) {
    m->add_paths(plan, pair, res);
    lap(tm.*(m->pair_time()));
  }
  assemble_paths(plan.cfg, res);
  lap(tm.assemble);
}

}  // namespace

void count_paths(Snapshot& snap) {
  for (const auto& r : snap.pairs) {
    snap.stats.candidates += r.candidates;
    snap.stats.paths += r.paths.size();
    snap.stats.dropped_transmission_cap += r.dropped_transmission_cap;
    snap.stats.dropped_threshold += r.dropped_threshold;
    snap.stats.out_of_range_pairs += r.out_of_range;
    for (const auto& path : r.paths) {
      // A diffuse record scatters once, last or (gathered by the pair's
      // higher end) first; a diffracted path ends at its edge.
      bool diffracted = false, diffuse = false;
      for (const auto& in : path.interactions) {
        diffracted |= in.type == InteractionType::diffraction;
        diffuse |= in.type == InteractionType::diffuse;
      }
      snap.stats.diffraction_paths += diffracted;
      snap.stats.diffuse_paths += diffuse;
    }
  }
}

namespace {

Snapshot trace_planned(const TraceScene& scene, const std::vector<Node>& nodes, const PairList& pairs,
                       const TracerConfig& cfg, const RadioConfig& radio, const std::vector<FaceSequences>* carried) {
  validate(cfg, radio);
  check_nodes(nodes);
  if (carried && carried->size() != pairs.size())
    throw std::invalid_argument("trace_pairs: carried sequences for " + std::to_string(carried->size()) +
                                " pairs, " + std::to_string(pairs.size()) + " pairs given");
  const Electromagnetics em(scene.material_names(), radio, cfg.materials, cfg.diffuse);
  SnapshotPlan plan(scene, nodes, pairs, cfg, radio, em);
  plan.carried = carried;
  Snapshot snap;
  const Mechanisms mechanisms = make_mechanisms(cfg);
  for (const auto& m : mechanisms) m->prepare(plan, snap.stats);
  snap.stats.time.shoot = plan.shoot_seconds();

  snap.pairs.resize(pairs.size());
  tbb::enumerable_thread_specific<std::uint64_t> pair_rays(0);
  tbb::enumerable_thread_specific<SnapshotStats::Timing> pair_time;
  const auto t_pairs = Clock::now();
  tbb::parallel_for(std::size_t{0}, pairs.size(), [&](std::size_t p) {
    trace_pair(plan, mechanisms, p, snap.pairs[p], pair_rays.local(), pair_time.local());
  });
  snap.stats.time.pairs = std::chrono::duration<double>(Clock::now() - t_pairs).count();
  for (const auto& tm : pair_time) {
    snap.stats.time.los += tm.los;
    snap.stats.time.exact += tm.exact;
    snap.stats.time.diffraction += tm.diffraction;
    snap.stats.time.diffuse += tm.diffuse;
    snap.stats.time.assemble += tm.assemble;
  }
  snap.stats.rays = plan.search_rays;
  for (auto r : pair_rays) snap.stats.rays += r;
  count_paths(snap);
  return snap;
}

}  // namespace

Snapshot trace_pairs(const TraceScene& scene, const std::vector<Node>& nodes, const PairList& pairs,
                     const TracerConfig& cfg, const RadioConfig& radio) {
  return trace_planned(scene, nodes, pairs, cfg, radio, nullptr);
}

Snapshot trace_pairs(const TraceScene& scene, const std::vector<Node>& nodes, const PairList& pairs,
                     const TracerConfig& cfg, const RadioConfig& radio, const std::vector<FaceSequences>& carried) {
  return trace_planned(scene, nodes, pairs, cfg, radio, &carried);
}

Snapshot trace_snapshot(const TraceScene& scene, const std::vector<Node>& nodes, const TracerConfig& cfg,
                        const RadioConfig& radio) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  const auto n = static_cast<std::uint32_t>(nodes.size());
  for (std::uint32_t i = 0; i < n; ++i)
    for (std::uint32_t j = i + 1; j < n; ++j) pairs.emplace_back(i, j);
  return trace_pairs(scene, nodes, pairs, cfg, radio);
}

}  // namespace raysweep::tracer
