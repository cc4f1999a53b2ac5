// First-order UTD diffraction: on the static scene's edges (also with a
// specular reflection before or after the edge) and, opt-in, on the
// vehicles' edges. Per snapshot each source's view of the edges; per pair
// the edges both ends see, each solved by compute_diffraction_path.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>

#include "diffraction_path.hpp"
#include "mechanisms/mechanism.hpp"
#include "reflected_edges.hpp"
#include "search/visibility.hpp"

namespace raysweep::tracer {

namespace {

// Edges each node can see the outside of, within `range` of it, and that
// no single convex face hides whole from it (hidden_by_convex_face: then
// every leg between the node and the edge is blocked): the cheap half of
// the diffraction test (a pair needs an edge both its ends see). With
// `slabs`, each node's walls are tried by their planes first.
std::vector<std::vector<std::uint32_t>> edges_seen(const TraceScene& scene, const ImageFaces& faces,
                                                   const std::vector<Node>& nodes,
                                                   const std::vector<unsigned char>& wanted, double range,
                                                   const SlabBounds* slabs) {
  const auto& edges = scene.edges();
  std::vector<std::vector<std::uint32_t>> seen(nodes.size());
  tbb::parallel_for(std::size_t{0}, nodes.size(), [&](std::size_t i) {
    if (!wanted[i]) return;
    const Vec3 p = nodes[i].position;
    RecentBlockers blockers;
    for (std::uint32_t k = 0; k < edges.size(); ++k) {
      const Edge& e = edges[k];
      const Vec3 w = p - e.a;
      const double z = std::clamp(dot(w, e.e), 0.0, norm(e.b - e.a));
      const Vec3 v = w - dot(w, e.e) * e.e;
      if (norm(p - (e.a + z * e.e)) > range) continue;
      if (edge_angle(e, v) > e.n * kPi) continue;
      const Vec3 ends[2] = {e.a, e.b};
      if (blockers.hidden(scene, faces, p, ends, 2, nullptr, 0, slabs ? &slabs->walls[i] : nullptr)) continue;
      seen[i].push_back(k);
    }
  });
  return seen;
}

// A seen vehicle edge with the node's coordinate along it and distance from
// its line: with the other end's, Keller's point without the path (most
// candidates fail there).
struct SeenEdge {
  std::uint32_t k;
  double z, r;
};

class Diffraction final : public Mechanism {
 public:
  void prepare(SnapshotPlan& plan, SnapshotStats& stats) override {
    const auto t0 = std::chrono::steady_clock::now();
    const auto& cfg = plan.cfg;
    if (cfg.diffraction && !plan.scene.edges().empty()) {
      seen_ = edges_seen(plan.scene, plan.faces(), plan.nodes, plan.is_source, plan.range,
                         plan.image_search ? &plan.slab_bounds() : nullptr);
      if (cfg.diffraction_reflection) prepare_reflected(plan);
    }
    if (cfg.vehicle_edge_diffraction && plan.n > 1) prepare_vehicle_edges(plan);
    stats.time.edges = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  void add_paths(const SnapshotPlan& plan, const PairTrace& pair, PairResult& res) const override {
    if (!seen_.empty()) add_static(plan, pair, res);
    if (!reflected_.empty()) add_reflected(plan, pair, res);
    if (!vehicle_edges_seen_.empty()) add_vehicle_edges(plan, pair, res);
  }

  double SnapshotStats::Timing::*pair_time() const override { return &SnapshotStats::Timing::diffraction; }

 private:
  // Reflection-diffraction: per node the (static face, edge) combinations
  // its reflections reach; with the edges the other end sees, a pair's
  // reflection-diffraction from its lower end and diffraction-reflection
  // from its higher end.
  void prepare_reflected(const SnapshotPlan& plan) {
    const auto n = plan.n;
    reflected_.resize(n);
    seen_bits_.resize(n);
    edge_z_.resize(n);
    edge_r_.resize(n);
    const auto& edges = plan.scene.edges();
    const auto& faces = plan.faces();
    const SlabBounds& slabs = plan.slab_bounds();
    const std::size_t words = (edges.size() + 63) / 64;
    tbb::parallel_for(std::uint32_t{0}, n, [&](std::uint32_t i) {
      if (!plan.is_source[i]) return;
      seen_bits_[i].assign(words, 0);
      for (auto k : seen_[i]) seen_bits_[i][k >> 6] |= std::uint64_t{1} << (k & 63);
      edge_z_[i].resize(edges.size());
      edge_r_[i].resize(edges.size());
      for (std::size_t k = 0; k < edges.size(); ++k) {
        const Vec3 w = plan.nodes[i].position - edges[k].a;
        edge_z_[i][k] = dot(w, edges[k].e);
        edge_r_[i][k] = norm(w - edge_z_[i][k] * edges[k].e);
      }
    });
    // A source's combinations serve its pairs only on the edges their other
    // ends see (add_reflected): the rest of the city's edges are not walked.
    tbb::parallel_for(std::uint32_t{0}, n, [&](std::uint32_t i) {
      if (!plan.is_source[i]) return;
      std::vector<std::uint64_t> wanted(words, 0);
      for (const auto j : plan.partners[i])  // partners are sources: their bits are set above
        for (std::size_t w = 0; w < words; ++w) wanted[w] |= seen_bits_[j][w];
      std::vector<std::uint32_t> only;
      for (std::size_t w = 0; w < words; ++w)
        for (std::uint64_t bits = wanted[w]; bits; bits &= bits - 1)
          only.push_back(static_cast<std::uint32_t>(64 * w + std::countr_zero(bits)));
      reflected_edges(plan.scene, faces, plan.nodes[i].position, plan.range, reflected_[i], &only, &slabs, i);
    });
  }

  // This frame's vehicle edges, placed (those long enough); per node, those
  // of the other vehicles it sees from outside their wedge within range (a
  // pair needs both ends to).
  void prepare_vehicle_edges(const SnapshotPlan& plan) {
    const auto& scene = plan.scene;
    std::vector<Edge> placed;
    for (std::size_t v = 0; v < scene.vehicles().size(); ++v) {
      placed.clear();
      scene.vehicle_edges(v, placed);
      for (const Edge& e : placed) {
        const double len = norm(e.b - e.a);
        if (len >= kVehicleEdgeMinWavelengths * plan.em.wavelength()) {
          vehicle_edges_.push_back(e);
          vehicle_edge_owner_.push_back(static_cast<int>(v));
          vehicle_edge_length_.push_back(len);
        }
      }
    }
    vehicle_edges_seen_.resize(plan.n);
    tbb::parallel_for(std::uint32_t{0}, plan.n, [&](std::uint32_t i) {
      if (!plan.is_source[i]) return;
      const Vec3 p = plan.nodes[i].position;
      for (std::uint32_t k = 0; k < vehicle_edges_.size(); ++k) {
        if (vehicle_edge_owner_[k] == plan.nodes[i].vehicle) continue;
        const Edge& e = vehicle_edges_[k];
        const Vec3 w = p - e.a;
        const double zk = dot(w, e.e);
        const double z = std::clamp(zk, 0.0, vehicle_edge_length_[k]);
        if (norm(p - (e.a + z * e.e)) > plan.range) continue;
        const Vec3 v = w - zk * e.e;
        if (edge_angle(e, v) > e.n * kPi) continue;
        vehicle_edges_seen_[i].push_back({k, zk, norm(v)});
      }
    });
  }

  // The static edges both ends see.
  void add_static(const SnapshotPlan& plan, const PairTrace& pair, PairResult& res) const {
    const auto &ei = seen_[pair.tx], &ej = seen_[pair.rx];
    std::size_t x = 0, y = 0;
    while (x < ei.size() && y < ej.size()) {
      if (ei[x] < ej[y]) ++x;
      else if (ej[y] < ei[x]) ++y;
      else {
        ++res.candidates;
        if (auto path = compute_diffraction_path(plan.scene, plan.em, plan.nodes[pair.tx], plan.nodes[pair.rx],
                                                 plan.scene.edges()[ei[x]], pair.rays)) {
          path->origin.kind = PathOrigin::Kind::diffraction;
          path->origin.edge = ei[x];
          res.paths.push_back(std::move(*path));
        }
        ++x;
        ++y;
      }
    }
  }

  // One end's reflected edges that the other end sees.
  void add_reflected(const SnapshotPlan& plan, const PairTrace& pair, PairResult& res) const {
    const auto i = pair.tx, j = pair.rx;
    const auto sees = [&](std::uint32_t node, std::uint32_t k) { return (seen_bits_[node][k >> 6] >> (k & 63)) & 1; };
    for (int end = 0; end < 2; ++end) {
      const auto from = end == 0 ? i : j, other = end == 0 ? j : i;
      const auto& z_other = edge_z_[other];
      const auto& r_other = edge_r_[other];
      for (const ReflectedEdge& re : reflected_[from]) {
        if (!sees(other, re.edge)) continue;
        if (!re.keller_on_part(z_other[re.edge], r_other[re.edge])) continue;
        ++res.candidates;
        const FaceRef face{0, re.face};
        if (auto path = compute_diffraction_path(plan.scene, plan.em, plan.nodes[i], plan.nodes[j],
                                                 plan.scene.edges()[re.edge], pair.rays, end == 0 ? &face : nullptr,
                                                 end == 0 ? nullptr : &face)) {
          path->origin.kind = PathOrigin::Kind::diffraction;
          path->origin.edge = re.edge;
          path->origin.faces = {face};
          path->origin.reflected = end == 0 ? -1 : 1;
          res.paths.push_back(std::move(*path));
        }
      }
    }
  }

  // The vehicle edges both ends see. Where the direct path's knife edge can
  // take a vehicle (it does inside 0.55 r1), its UTD paths fade out from
  // 1.0 r1 on: the two model one field and must not add.
  void add_vehicle_edges(const SnapshotPlan& plan, const PairTrace& pair, PairResult& res) const {
    const auto& cfg = plan.cfg;
    const auto &ni = plan.nodes[pair.tx], &nj = plan.nodes[pair.rx];
    const double lambda = plan.lambda;
    const bool knife = cfg.vehicle_diffraction && res.los_class != LosClass::NLOS;
    const double onset = -kKnifeEdgeOnset / std::sqrt(2.0);
    int owner = -1;
    double weight = 1;
    // The floor: vehicle_edge_floor_db below the direct path's free-space power.
    const double d = norm(nj.position - ni.position);
    const double floor = std::pow(lambda / (4 * kPi * d), 2) * std::pow(10.0, -cfg.vehicle_edge_floor_db / 10);
    const auto &ei = vehicle_edges_seen_[pair.tx], &ej = vehicle_edges_seen_[pair.rx];
    std::size_t x = 0, y = 0;
    while (x < ei.size() && y < ej.size()) {
      if (ei[x].k < ej[y].k) ++x;
      else if (ej[y].k < ei[x].k) ++y;
      else {
        const std::uint32_t k = ei[x].k;
        const SeenEdge &si = ei[x], &sj = ej[y];
        ++x;
        ++y;
        // Keller's point (as compute_diffraction_path finds it) off the edge.
        const double zq = (si.z * sj.r + sj.z * si.r) / (si.r + sj.r);
        if (!(zq >= 0 && zq <= vehicle_edge_length_[k])) continue;
        if (vehicle_edge_owner_[k] != owner) {
          owner = vehicle_edge_owner_[k];
          weight = 1;
          if (knife) {
            const double c = plan.obstacles.vehicle_clearance(ni.position, nj.position, lambda, owner);
            weight = std::clamp((c - onset) / (1 - onset), 0.0, 1.0);
          }
        }
        if (!(weight > 0)) continue;
        ++res.candidates;
        if (auto path = compute_diffraction_path(plan.scene, plan.em, ni, nj, vehicle_edges_[k], pair.rays, nullptr,
                                                 nullptr, floor / (weight * weight))) {
          path->a *= weight;
          path->origin.kind = PathOrigin::Kind::vehicle_edge;
          res.paths.push_back(std::move(*path));
        }
      }
    }
  }

  std::vector<std::vector<std::uint32_t>> seen_;  // per node: static edges it sees
  std::vector<std::vector<ReflectedEdge>> reflected_;
  std::vector<std::vector<std::uint64_t>> seen_bits_;
  std::vector<std::vector<double>> edge_z_, edge_r_;  // each node's coordinate along each edge, distance from its line
  std::vector<Edge> vehicle_edges_;
  std::vector<int> vehicle_edge_owner_;
  std::vector<double> vehicle_edge_length_;
  std::vector<std::vector<SeenEdge>> vehicle_edges_seen_;
};

}  // namespace

std::unique_ptr<Mechanism> make_diffraction(const TracerConfig& cfg) {
  return cfg.diffraction || cfg.vehicle_edge_diffraction ? std::make_unique<Diffraction>() : nullptr;
}

}  // namespace raysweep::tracer
