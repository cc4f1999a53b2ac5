#include "tracer/radiomap_solver.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <optional>

#include "diffraction_path.hpp"
#include "fresnel_zone.hpp"
#include "reflected_edges.hpp"
#include "search/image_search.hpp"
#include "search/visibility.hpp"
#include "tracer/em/antenna.hpp"

namespace raysweep::tracer {

namespace {

// Points per batch: one image-source pass per batch (the sources are built
// once per batch and tested against all of its points at once).
constexpr std::size_t kBatch = 2048;

// |a|^2 of the free-space direct path from `from` to `to` (antenna patterns
// and polarisation included): what compute_path gives for an unobstructed
// direct segment.
double free_space_gain(const RadioConfig& radio, const Node& from, const Node& to) {
  const Vec3 d = to.position - from.position;
  const double len = norm(d);
  if (!(len > 0)) return 0;
  const Vec3 u = (1.0 / len) * d;
  const Vec3 e_t = antenna_field(radio.antenna, u, from.forward);
  const Vec3 f_r = antenna_field(radio.antenna, -u, to.forward);
  const double lambda = kSpeedOfLight / radio.frequency_hz;
  const double amp = lambda / (4 * kPi * len) * dot(f_r, e_t);
  return amp * amp;
}

// One transmitter's solve: what its points share, built once (the image
// faces, the edges it sees, its reflected edges, the vehicles as
// obstacles), then each batch of points.
class TxSolver {
 public:
  TxSolver(const TraceScene& scene, const Node& tx, const TracerConfig& cfg, const RadioConfig& radio)
      : scene_(scene),
        tx_(tx),
        cfg_(cfg),
        radio_(radio),
        // With diffuse scattering by rays (diffuse_power adds it), rough
        // surfaces keep sqrt(1 - S^2) of the specular field as in `trace`;
        // else they reflect their whole |Gamma|^2 (energy kept, no lobe).
        em_(scene.material_names(), radio, cfg.materials,
            cfg.diffuse && cfg.diffuse_integration != DiffuseIntegration::tiles),
        range_(max_range_m(cfg, radio)),
        lambda_(em_.wavelength()),
        order_(cfg.specular ? std::min(cfg.max_depth, 2) : 0),
        faces_(image_faces(scene)) {
    if (cfg.diffraction) find_tx_edges();
    // Reflection-diffraction (a static face, then the edge), as `trace`
    // lists it from a pair's ends; the transmitter's list once.
    if (cfg.diffraction && cfg.diffraction_reflection)
      reflected_edges(scene, faces_, tx.position, range_, tx_reflected_);
    const bool vehicles = !scene.vehicles().empty();
    if (vehicles && cfg.vehicle_diffraction) obstacles_.emplace(scene);
  }

  // Points [begin, end) into out[begin, end).
  void batch(const std::vector<Vec3>& points, std::size_t begin, std::size_t end,
             std::vector<RadioMapPointResult>& out, RadioMapSolveStats& st) const {
    std::vector<Node> nodes{tx_};
    nodes.front().id = "tx";
    std::vector<std::uint32_t> receivers;
    for (std::size_t i = begin; i < end; ++i) {
      Node n;
      n.id = "p";
      n.position = points[i];
      if (norm(points[i] - tx_.position) <= range_) receivers.push_back(static_cast<std::uint32_t>(nodes.size()));
      nodes.push_back(n);
    }
    // Candidate face sequences of every point in range, by receiver index.
    std::vector<ImageCandidate> found;
    if (order_ > 0) image_candidates(scene_, faces_, nodes, 0, receivers, order_, found);
    std::vector<std::vector<std::vector<FaceRef>>> cand(nodes.size());
    for (auto& c : found) cand[c.rx].push_back(std::move(c.faces));

    std::vector<std::uint32_t> blockers;
    for (std::uint32_t r = 1; r < nodes.size(); ++r) {
      RadioMapPointResult& res = out[begin + r - 1];
      const Node& rx = nodes[r];
      ++st.points;
      res.los = classify_los(scene_, tx_.position, rx.position, blockers, &st.rays);
      if (norm(rx.position - tx_.position) > range_) {
        ++st.out_of_range;
        continue;
      }
      auto& seqs = cand[r];
      std::sort(seqs.begin(), seqs.end());
      seqs.erase(std::unique(seqs.begin(), seqs.end()), seqs.end());
      point(rx, seqs, res, st);
    }
  }

 private:
  // Edges whose outside the transmitter sees within range (the cheap half
  // of the diffraction test, done once).
  void find_tx_edges() {
    const auto& edges = scene_.edges();
    for (std::uint32_t k = 0; k < edges.size(); ++k) {
      const Edge& e = edges[k];
      const Vec3 w = tx_.position - e.a;
      const double z = std::clamp(dot(w, e.e), 0.0, norm(e.b - e.a));
      if (norm(tx_.position - (e.a + z * e.e)) > range_) continue;
      if (edge_angle(e, w - dot(w, e.e) * e.e) > e.n * kPi) continue;
      // Hidden whole from the transmitter by one convex face: no leg reaches it.
      const Vec3 ends[2] = {e.a, e.b};
      if (!hidden_by_convex_face(scene_, faces_, tx_.position, ends, 2, nullptr, 0)) tx_edges_.push_back(k);
    }
  }

  // One point's paths, their gains summed in path order: the direct path,
  // the candidate sequences `seqs`, the edges, the reflected edges.
  void point(const Node& rx, const std::vector<std::vector<FaceRef>>& seqs, RadioMapPointResult& res,
             RadioMapSolveStats& st) const {
    double gain = 0;
    std::uint32_t n_paths = 0;
    auto add = [&](double g) {
      gain += g;
      ++n_paths;
    };
    if (cfg_.los) direct(rx, res.los, st, add);
    st.candidates += seqs.size() + tx_edges_.size();
    for (const auto& s : seqs)
      if (auto p = compute_path(scene_, em_, cfg_, tx_, rx, s, nullptr, &st.rays)) add(std::norm(p->a));
    for (auto k : tx_edges_)
      if (auto p = compute_diffraction_path(scene_, em_, tx_, rx, scene_.edges()[k], &st.rays))
        add(std::norm(p->a));
    // The reflection before the edge: Keller's point from the
    // transmitter's image and the point on the part of the edge in the
    // face's beam (the filter `trace` applies), then the exact path.
    for (const auto& re : tx_reflected_) {
      const Edge& e = scene_.edges()[re.edge];
      const Vec3 w = rx.position - e.a;
      const double zr = dot(w, e.e), rr = norm(w - zr * e.e);
      if (!re.keller_on_part(zr, rr)) continue;
      if (edge_angle(e, w - zr * e.e) > e.n * kPi) continue;  // the point inside the wedge
      ++st.candidates;
      const FaceRef face{0, re.face};
      if (auto p = compute_diffraction_path(scene_, em_, tx_, rx, e, &st.rays, &face, nullptr))
        add(std::norm(p->a));
    }
    res.gain = gain;
    res.paths = n_paths;
    st.paths += n_paths;
  }

  // The direct path by the point's LoS class `los`: free space times the
  // vehicles' knife-edge loss, or through slabs.
  template <class Add>
  void direct(const Node& rx, LosClass los, RadioMapSolveStats& st, Add&& add) const {
    if (los == LosClass::LOS) {
      if (auto p = compute_path(scene_, em_, cfg_, tx_, rx, {}, nullptr, &st.rays)) {
        double g = std::norm(p->a);
        if (obstacles_) {
          const auto ke = obstacles_->vehicle_knife_edges(tx_.position, rx.position, lambda_, tx_.vehicle, -1);
          g *= std::pow(10.0, -ke.loss_db / 10);
        }
        add(g);
      }
    } else if (los == LosClass::NLOSV && obstacles_) {
      const auto ke = obstacles_->vehicle_knife_edges(tx_.position, rx.position, lambda_, tx_.vehicle, -1);
      if (ke.loss_db > 0) add(free_space_gain(radio_, tx_, rx) * std::pow(10.0, -ke.loss_db / 10));
    } else if (auto p = compute_path(scene_, em_, cfg_, tx_, rx, {}, nullptr, &st.rays)) {
      add(std::norm(p->a));  // through slabs
    }
  }

  const TraceScene& scene_;
  const Node& tx_;
  const TracerConfig& cfg_;
  const RadioConfig& radio_;
  const Electromagnetics em_;
  const double range_, lambda_;
  const int order_;
  const ImageFaces faces_;
  std::vector<std::uint32_t> tx_edges_;
  std::vector<ReflectedEdge> tx_reflected_;
  std::optional<FresnelObstacles> obstacles_;
};

}  // namespace

bool inside_static(const TraceScene& scene, const Vec3& p) {
  std::vector<Hit> hits;
  scene.all_hits(p, Vec3{0, 0, 1}, 0, 1e7, hits, 64);
  for (const auto& h : hits) {
    if (scene.is_vehicle(h.face)) continue;
    // The first static face above: its back (normal pointing up, away from
    // the point) faces the point when the point is inside the closed object.
    return scene.plane(h.face).normal[2] > 0;
  }
  return false;
}

std::vector<RadioMapPointResult> solve_points(const TraceScene& scene, const Node& tx,
                                              const std::vector<Vec3>& points, const TracerConfig& cfg,
                                              const RadioConfig& radio, RadioMapSolveStats* stats) {
  validate(cfg, radio);
  const TxSolver solver(scene, tx, cfg, radio);
  std::vector<RadioMapPointResult> out(points.size());
  const std::size_t batches = (points.size() + kBatch - 1) / kBatch;
  tbb::enumerable_thread_specific<RadioMapSolveStats> local;
  tbb::parallel_for(std::size_t{0}, batches, [&](std::size_t b) {
    const std::size_t begin = b * kBatch, end = std::min(points.size(), begin + kBatch);
    solver.batch(points, begin, end, out, local.local());
  });
  if (stats) {
    *stats = RadioMapSolveStats{};
    for (const auto& s : local) {
      stats->points += s.points;
      stats->paths += s.paths;
      stats->candidates += s.candidates;
      stats->out_of_range += s.out_of_range;
      stats->rays += s.rays;
    }
  }
  return out;
}

}  // namespace raysweep::tracer
