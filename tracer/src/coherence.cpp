// The coherent re-solve: each pair's recalled paths at the new positions,
// in parallel over pairs, with the labels and the direct path afresh.
#include "tracer/coherence.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <tuple>
#include <unordered_map>

#include "mechanisms/mechanism.hpp"
#include "search/image_search.hpp"

namespace raysweep::tracer {

namespace {

// A vehicle's frame: its pose's position and yaw about +z.
Vec3 to_local(const VehiclePose& pose, const Vec3& p) {
  const Vec3 d = p - pose.position;
  const double c = std::cos(pose.yaw_rad), s = std::sin(pose.yaw_rad);
  return {c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]};
}

Vec3 to_world(const VehiclePose& pose, const Vec3& q) {
  const double c = std::cos(pose.yaw_rad), s = std::sin(pose.yaw_rad);
  return pose.position + Vec3{c * q[0] - s * q[1], s * q[0] + c * q[1], q[2]};
}

// Recall-side names of the current frame's vehicles.
class RecallNames {
 public:
  RecallNames(const TraceScene& scene, PairRecall& rc) : scene_(scene), rc_(rc) {}
  std::int32_t vehicle(std::uint32_t slot) {
    const std::string& id = scene_.vehicles().at(slot).id;
    for (std::size_t k = 0; k < rc_.vehicles.size(); ++k)
      if (rc_.vehicles[k] == id) return static_cast<std::int32_t>(k);
    rc_.vehicles.push_back(id);
    rc_.poses.push_back(scene_.vehicles()[slot]);
    return static_cast<std::int32_t>(rc_.vehicles.size() - 1);
  }
  RecallFace face(const FaceRef& f) {
    return RecallFace{f.instance == 0 ? -1 : vehicle(f.instance - 1), f.face};
  }
  std::vector<RecallFace> faces(const std::vector<FaceRef>& fs) {
    std::vector<RecallFace> out;
    for (const auto& f : fs) out.push_back(face(f));
    return out;
  }

 private:
  const TraceScene& scene_;
  PairRecall& rc_;
};

RecallScatter recall_scatter(const TraceScene& scene, RecallNames& names, const Path& path) {
  RecallScatter s;
  s.record = path;
  s.record.origin = {};
  const std::uint32_t statics = scene.static_object_count();
  for (const auto& in : path.interactions) {
    if (in.object < statics) {
      s.host.push_back(-1);
      s.local.push_back(in.point);
    } else {
      const std::uint32_t slot = in.object - statics;
      s.host.push_back(names.vehicle(slot));
      s.local.push_back(to_local(scene.vehicles().at(slot), in.point));
    }
  }
  return s;
}

}  // namespace

PairRecall make_recall(const TraceScene& scene, const std::vector<Node>& nodes, const PairResult& res) {
  PairRecall rc;
  rc.a = nodes.at(res.tx);
  rc.b = nodes.at(res.rx);
  rc.los_class = res.los_class;
  rc.fresnel_class = res.fresnel_class;
  rc.out_of_range = res.out_of_range;
  RecallNames names(scene, rc);
  double total = 0;
  for (const auto& path : res.paths) total += std::norm(path.a);
  const auto share = [total](const Path& path) { return total > 0 ? std::norm(path.a) / total : 0.0; };
  for (const auto& path : res.paths) {
    const auto& o = path.origin;
    const bool on_vehicle =
        std::any_of(o.faces.begin(), o.faces.end(), [](const FaceRef& f) { return f.instance > 0; });
    // The paths that traffic makes and unmakes between searches.
    if (o.kind == PathOrigin::Kind::diffuse || o.kind == PathOrigin::Kind::vehicle_edge || on_vehicle)
      rc.volatile_share += share(path);
    switch (o.kind) {
      case PathOrigin::Kind::direct: rc.direct_share += share(path); break;  // always traced afresh
      case PathOrigin::Kind::sequence: rc.sequences.push_back({names.faces(o.faces), share(path)}); break;
      case PathOrigin::Kind::diffraction:
        rc.diffracted.push_back({o.edge, names.faces(o.faces), o.reflected, share(path)});
        break;
      case PathOrigin::Kind::diffuse:
        rc.diffuse.push_back(recall_scatter(scene, names, path));
        rc.diffuse.back().share = share(path);
        break;
      case PathOrigin::Kind::vehicle_edge:
      case PathOrigin::Kind::unknown: rc.complete = false; break;
    }
  }
  for (const auto& faces : res.near_misses) rc.near_misses.push_back(names.faces(faces));
  // The diffraction mechanism's order: plain edges by index, then the
  // reflections before the edge, then after, by face and edge.
  std::stable_sort(rc.diffracted.begin(), rc.diffracted.end(), [](const auto& x, const auto& y) {
    const auto key = [](const PairRecall::Diffracted& d) {
      return std::make_tuple(d.reflected == 0 ? 0 : d.reflected < 0 ? 1 : 2, d.face.empty() ? 0u : d.face[0].face,
                             d.edge);
    };
    return key(x) < key(y);
  });
  return rc;
}

namespace {

// Where the recall's names are in the current frame.
struct Slots {
  std::unordered_map<std::string, std::uint32_t> of;  // vehicle id -> slot
  explicit Slots(const TraceScene& scene) {
    for (std::size_t v = 0; v < scene.vehicles().size(); ++v)
      of.emplace(scene.vehicles()[v].id, static_cast<std::uint32_t>(v));
  }
  // The recall's faces as this frame's; false when a vehicle has left.
  bool faces(const PairRecall& rc, const std::vector<RecallFace>& in, std::vector<FaceRef>& out) const {
    out.clear();
    for (const auto& f : in) {
      if (f.vehicle < 0) {
        out.push_back(FaceRef{0, f.face});
        continue;
      }
      auto it = of.find(rc.vehicles[f.vehicle]);
      if (it == of.end()) return false;
      out.push_back(FaceRef{it->second + 1, f.face});
    }
    return true;
  }
};

// The polyline a, points..., b: its length.
double polyline(const Vec3& a, const std::vector<Vec3>& points, const Vec3& b) {
  double len = 0;
  Vec3 prev = a;
  for (const auto& p : points) {
    len += norm(p - prev);
    prev = p;
  }
  return len + norm(b - prev);
}

// A diffuse record at the new positions: its points where their hosts are
// now; its delay, carrier phase, angles and Doppler follow its legs. Its
// power stays: a record sums the scattering of a whole region of a surface
// (one object, one delay bin), which a single point's spreading does not
// represent (a ground patch around a car moves with the car); recalls of
// pairs where such records matter do not hold (the sweep's volatile share).
// False when its vehicle has left.
bool rescatter(const TraceScene& scene, const Slots& slots, const PairRecall& rc, const RecallScatter& s,
               const Node& a, const Node& b, double lambda, Path& out) {
  const Path& old = s.record;
  const std::size_t n = old.interactions.size();
  if (n == 0) return false;
  std::vector<Vec3> now(n), was(n), vel(n, Vec3{0, 0, 0});
  std::vector<std::int64_t> slot(n, -1);
  for (std::size_t q = 0; q < n; ++q) {
    was[q] = old.interactions[q].point;
    if (s.host[q] < 0) {
      now[q] = s.local[q];
      continue;
    }
    auto it = slots.of.find(rc.vehicles[s.host[q]]);
    if (it == slots.of.end()) return false;
    const VehiclePose &pose = scene.vehicles()[it->second], &then = rc.poses[s.host[q]];
    const bool still = pose.position == then.position && pose.yaw_rad == then.yaw_rad;
    now[q] = still ? was[q] : to_world(pose, s.local[q]);
    vel[q] = pose.velocity;
    slot[q] = it->second;
  }
  const Vec3 dep0 = normalize(was.front() - rc.a.position), dep1 = normalize(now.front() - a.position);
  const Vec3 arr0 = normalize(was.back() - rc.b.position), arr1 = normalize(now.back() - b.position);
  // Changes applied to the record's own values (its angles are power-
  // weighted means, not its point's directions): nothing moved, nothing
  // changes, to the bit.
  out = old;
  const double stretch = polyline(a.position, now, b.position) - polyline(rc.a.position, was, rc.b.position);
  out.tau_s = old.tau_s + stretch / kSpeedOfLight;
  out.a = old.a * std::polar(1.0, -2 * kPi * std::fmod(stretch / lambda, 1.0));
  out.theta_t = old.theta_t + (zenith(dep1) - zenith(dep0));
  out.phi_t = old.phi_t + std::remainder(azimuth(dep1) - azimuth(dep0), 2 * kPi);
  out.theta_r = old.theta_r + (zenith(arr1) - zenith(arr0));
  out.phi_r = old.phi_r + std::remainder(azimuth(arr1) - azimuth(arr0), 2 * kPi);
  // The end legs' closing speeds, then and now (the inner legs' are kept).
  const auto rate = [&](const Vec3& dep, const Vec3& va, const Vec3& arr, const Vec3& vb) {
    return dot(dep, vel.front() - va) + dot(arr, vel.back() - vb);
  };
  out.doppler_hz = old.doppler_hz - (rate(dep1, a.velocity, arr1, b.velocity) -
                                     rate(dep0, rc.a.velocity, arr0, rc.b.velocity)) / lambda;
  for (std::size_t q = 0; q < n; ++q) {
    out.interactions[q].point = now[q];
    if (slot[q] >= 0) out.interactions[q].object = scene.vehicle_object(static_cast<std::size_t>(slot[q]));
  }
  out.origin.kind = PathOrigin::Kind::diffuse;
  return true;
}

struct Resolver {
  const SnapshotPlan& plan;
  const Mechanism* direct;
  const Slots& slots;
  double vanish_limit;
  const std::vector<std::vector<std::vector<FaceRef>>>& fresh;  // per pair: this frame's image candidates

  // One pair: labels, direct path, recalled paths, assembled. False when
  // the recall no longer holds.
  bool pair(std::size_t p, PairRecall& rc, PairResult& res, std::uint64_t& rays) const {
    PairTrace pt{p, plan.pairs[p].first, plan.pairs[p].second, {}, &rays};
    label_pair(plan, pt, res);
    const bool held = rc.complete && res.los_class == rc.los_class && res.fresnel_class == rc.fresnel_class &&
                      rc.out_of_range == !plan.in_range[p];
    rc.los_class = res.los_class;
    rc.fresnel_class = res.fresnel_class;
    rc.out_of_range = !plan.in_range[p];
    if (!plan.in_range[p]) {
      res.out_of_range = true;
      res.stats = path_stats(res.paths);
      return held;
    }
    if (direct) direct->add_paths(plan, pt, res);
    const double vanished = sequences(pt, rc, res) + diffracted(pt, rc, res) + scattered(pt, rc, res);
    assemble_paths(plan.cfg, res);
    return held && vanished <= vanish_limit;
  }

  // The recalled sequences and near misses in the order the search tries
  // them (sorted), so that paths of equal delay come out as it gives them.
  // Returns the power share (at the search) of recalled paths gone other
  // than by a blocked leg: a path off its face, or on a vehicle that left.
  double sequences(const PairTrace& pt, const PairRecall& rc, PairResult& res) const {
    std::map<std::vector<FaceRef>, double> tries;  // faces -> recalled share (-1: not a recalled path)
    double vanished = 0;
    std::vector<FaceRef> faces;
    for (const auto& seq : rc.sequences) {
      if (slots.faces(rc, seq.faces, faces)) tries.emplace(faces, seq.share);
      else vanished += seq.share;
    }
    for (const auto& seq : rc.near_misses)
      if (slots.faces(rc, seq, faces)) tries.emplace(faces, -1.0);
    for (const auto& seq : fresh[pt.slot]) tries.emplace(seq, -1.0);
    int blocked = 0;
    for (const auto& [seq, share] : tries) {
      ++res.candidates;
      if (!sequence_path(plan, pt, seq, res, &blocked) && share > 0 && blocked == 0) vanished += share;
    }
    return vanished;
  }

  double diffracted(const PairTrace& pt, const PairRecall& rc, PairResult& res) const {
    double vanished = 0;
    std::vector<FaceRef> face;
    for (const auto& d : rc.diffracted) {
      ++res.candidates;
      if (d.edge >= plan.scene.edges().size() || !slots.faces(rc, d.face, face)) {
        vanished += d.share;
        continue;
      }
      const FaceRef* f = face.empty() ? nullptr : &face[0];
      bool blocked = false;
      auto path = compute_diffraction_path(plan.scene, plan.em, plan.nodes[pt.tx], plan.nodes[pt.rx],
                                           plan.scene.edges()[d.edge], pt.rays, d.reflected < 0 ? f : nullptr,
                                           d.reflected > 0 ? f : nullptr, 0, &blocked);
      if (!path) {
        if (!blocked) vanished += d.share;  // off its edge; a blocked leg comes back when cleared
        continue;
      }
      path->origin = {PathOrigin::Kind::diffraction, face, d.edge, d.reflected};
      res.paths.push_back(std::move(*path));
    }
    return vanished;
  }

  double scattered(const PairTrace& pt, const PairRecall& rc, PairResult& res) const {
    double vanished = 0;
    const Node &a = plan.nodes[pt.tx], &b = plan.nodes[pt.rx];
    for (const auto& s : rc.diffuse) {
      Path path;
      if (rescatter(plan.scene, slots, rc, s, a, b, plan.lambda, path)) res.paths.push_back(std::move(path));
      else vanished += s.share;
    }
    return vanished;
  }
};

// Every sequence of this frame that the exact image search enumerates but
// those of two or more static faces (each face at order 1, the ground with
// a vehicle, a vehicle's own multi-bounce sequences: cheap), per pair: a
// wall's or a car's reflection that appears between two searches is found
// in the frame it appears.
std::vector<std::vector<std::vector<FaceRef>>> frame_candidates(const SnapshotPlan& plan) {
  std::vector<std::vector<std::vector<FaceRef>>> out(plan.pairs.size());
  const auto& cfg = plan.cfg;
  if (!cfg.specular || cfg.max_depth < 1 || plan.n < 2 || cfg.candidates == CandidateSearch::sbr) return out;
  const ImageFaces& faces = plan.faces();
  std::vector<std::vector<ImageCandidate>> found(plan.n);
  tbb::parallel_for(std::uint32_t{0}, plan.n, [&](std::uint32_t i) {
    if (!plan.partners[i].empty())
      image_candidates(plan.scene, faces, plan.nodes, i, plan.partners[i], std::min(cfg.max_depth, 3), found[i],
                       {.multi_bounce = cfg.vehicle_multi_bounce, .ground_order3 = false, .static_pairs = false});
  });
  for (std::uint32_t i = 0; i < plan.n; ++i)
    for (auto& c : found[i]) {
      if (c.rx < i) std::reverse(c.faces.begin(), c.faces.end());
      out[plan.slot.at(SnapshotPlan::key(std::min(i, c.rx), std::max(i, c.rx)))].push_back(std::move(c.faces));
    }
  return out;
}

}  // namespace

Snapshot resolve_pairs(const TraceScene& scene, const std::vector<Node>& nodes,
                       const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs,
                       const std::vector<PairRecall*>& recalls, const TracerConfig& config, const RadioConfig& radio,
                       double vanish_limit, std::vector<unsigned char>& intact) {
  if (recalls.size() != pairs.size()) throw std::invalid_argument("resolve_pairs: one recall per pair");
  validate(config, radio);
  const Electromagnetics em(scene.material_names(), radio, config.materials, config.diffuse);
  SnapshotPlan plan(scene, nodes, pairs, config, radio, em);
  const auto direct = make_direct(config);
  const Slots slots(scene);
  const auto fresh = frame_candidates(plan);
  const Resolver resolver{plan, direct.get(), slots, vanish_limit, fresh};
  Snapshot snap;
  snap.pairs.resize(pairs.size());
  intact.assign(pairs.size(), 0);
  tbb::enumerable_thread_specific<std::uint64_t> rays(0);
  tbb::parallel_for(std::size_t{0}, pairs.size(), [&](std::size_t p) {
    intact[p] = resolver.pair(p, *recalls[p], snap.pairs[p], rays.local());
  });
  for (auto r : rays) snap.stats.rays += r;
  count_paths(snap);
  return snap;
}

}  // namespace raysweep::tracer
