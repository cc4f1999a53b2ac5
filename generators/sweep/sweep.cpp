#include "generators/sweep/sweep.hpp"

#include "generators/sweep/frame_record.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace raysweep::generators {

using tracer::Vec3;
using tracer::operator+;
using tracer::operator-;
using tracer::operator*;
using tracer::norm;

const char* cache_mode_name(CacheMode m) {
  switch (m) {
    case CacheMode::none: return "none";
    case CacheMode::per_pair: return "per_pair";
    case CacheMode::global: return "global";
  }
  return "?";
}

CacheMode parse_cache_mode(const std::string& s) {
  if (s == "none") return CacheMode::none;
  if (s == "per_pair") return CacheMode::per_pair;
  if (s == "global") return CacheMode::global;
  throw std::invalid_argument("cache mode '" + s + "': expected none, per_pair or global");
}

namespace {

constexpr double kDeg = tracer::kPi / 180.0;

double yaw_of(double heading_deg) { return (90.0 - heading_deg) * kDeg; }

struct Sphere {
  Vec3 c;
  double r;
};

Sphere bounding_sphere(const SweepVehicle& v) {
  const double yaw = yaw_of(v.heading_deg);
  const Vec3 fwd{std::cos(yaw), std::sin(yaw), 0};
  const Vec3 c = v.position - (0.5 * v.length_m) * fwd + Vec3{0, 0, 0.5 * v.height_m};
  return {c, 0.5 * std::sqrt(v.length_m * v.length_m + v.width_m * v.width_m + v.height_m * v.height_m)};
}

bool same_pose(const SweepVehicle& a, const SweepVehicle& b) {
  return a.model == b.model && a.position == b.position && a.heading_deg == b.heading_deg && a.velocity == b.velocity;
}

// Distance from p to the segment ab.
double segment_distance(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = tracer::dot(ab, ab);
  const double t = len2 > 0 ? std::clamp(tracer::dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
  return norm(p - (a + t * ab));
}

std::uint64_t pair_key(std::uint32_t a, std::uint32_t b) { return static_cast<std::uint64_t>(a) << 32 | b; }

}  // namespace

Sweep::Sweep(tracer::TraceScene& scene, const tracer::TracerConfig& tracer, const tracer::RadioConfig& radio,
             const SweepOptions& options, std::vector<SweepRsu> rsus)
    : scene_(scene), tracer_(tracer), radio_(radio), options_(options), rsus_(std::move(rsus)) {
  if (options_.block_frames == 0) throw std::invalid_argument("sweep: block_frames must be at least 1");
  if (!(options_.d0_m >= 0) || !(options_.coherence_time_s >= 0) || !(options_.cache_margin_m >= 0))
    throw std::invalid_argument("sweep: d0, coherence time and cache margin must be >= 0");
  if (options_.lattice_frames == 0) throw std::invalid_argument("sweep: lattice_frames must be at least 1");
  if (options_.diffuse_frames == 0) throw std::invalid_argument("sweep: diffuse_frames must be at least 1");
  std::sort(rsus_.begin(), rsus_.end(), [](const SweepRsu& a, const SweepRsu& b) { return a.node < b.node; });
}

std::vector<std::string> Sweep::object_names(const std::vector<std::string>& node_ids) const {
  auto names = scene_.object_names();
  names.resize(scene_.static_object_count());
  names.insert(names.end(), node_ids.begin(), node_ids.end());
  return names;
}

namespace {

// Sorts the frame's vehicles by node; a node twice, or an RSU's node among
// them, is an error.
void sort_and_check(std::vector<SweepVehicle>& vehicles, const std::vector<SweepRsu>& rsus) {
  std::sort(vehicles.begin(), vehicles.end(),
            [](const SweepVehicle& a, const SweepVehicle& b) { return a.node < b.node; });
  for (std::size_t i = 1; i < vehicles.size(); ++i)
    if (vehicles[i].node == vehicles[i - 1].node)
      throw std::invalid_argument("sweep: node " + std::to_string(vehicles[i].node) + " twice in one frame");
  for (const auto& v : vehicles)
    for (const auto& r : rsus)
      if (r.node == v.node) throw std::invalid_argument("sweep: node " + std::to_string(v.node) + " is an RSU");
}

}  // namespace

// What changed since the last frame.
struct Sweep::Motion {
  std::vector<Sphere> moved;           // every moved vehicle's old and new sphere, every departed one's last
  std::vector<std::uint32_t> updated;  // sorted node ids
  bool scene_changed = false, departed = false;
};

// The frame's antennas in node order, so local pair (i < j) is node pair (i < j).
struct Sweep::Antennas {
  std::vector<tracer::Node> nodes;
  std::vector<std::uint32_t> node_of;    // local index -> dataset node
  std::vector<std::uint32_t> slot_node;  // vehicle slot in the scene -> dataset node
};

// The update rule: which meshes move; spheres of everything that moved.
Sweep::Motion Sweep::place_vehicles(const std::vector<SweepVehicle>& vehicles) {
  Motion motion;
  std::map<std::uint32_t, Placed> next;
  for (const auto& v : vehicles) {
    auto it = placed_.find(v.node);
    bool update = it == placed_.end();
    if (!update) {
      const double threshold = std::max(options_.d0_m, norm(v.velocity) * options_.coherence_time_s);
      if (threshold == 0)
        update = !same_pose(v, it->second.v);
      else
        update = norm(v.position - it->second.v.position) > threshold || v.model != it->second.v.model;
      if (!update && !same_pose(v, it->second.v)) ++stats_.updates_deferred;
    }
    if (update) {
      if (it != placed_.end()) motion.moved.push_back(bounding_sphere(it->second.v));
      motion.moved.push_back(bounding_sphere(v));
      motion.updated.push_back(v.node);
      next[v.node] = Placed{v};
      ++stats_.vehicle_updates;
      motion.scene_changed = true;
    } else {
      next[v.node] = it->second;
    }
  }
  for (const auto& [node, p] : placed_)
    if (!next.count(node)) {
      motion.moved.push_back(bounding_sphere(p.v));
      motion.scene_changed = motion.departed = true;
    }
  placed_ = std::move(next);
  return motion;
}

// The scene's vehicles where they were last placed, in node order.
void Sweep::pose_vehicles() {
  std::vector<tracer::VehiclePose> poses;
  for (const auto& [node, p] : placed_) {
    const double yaw = yaw_of(p.v.heading_deg);
    poses.push_back(tracer::VehiclePose{std::to_string(node), p.v.model, p.v.position, yaw, p.v.velocity});
  }
  scene_.set_vehicles(poses);
}

Sweep::Antennas Sweep::antennas() const {
  Antennas a;
  a.slot_node.resize(placed_.size());
  std::size_t r = 0, slot = 0;
  auto it = placed_.begin();
  while (r < rsus_.size() || it != placed_.end()) {
    if (it == placed_.end() || (r < rsus_.size() && rsus_[r].node < it->first)) {
      a.nodes.push_back(tracer::Node{std::to_string(rsus_[r].node), rsus_[r].position, {0, 0, 0}, {1, 0, 0}, -1});
      a.node_of.push_back(rsus_[r].node);
      ++r;
    } else {
      a.nodes.push_back(tracer::Node{std::to_string(it->first), scene_.vehicle_antenna(slot), it->second.v.velocity,
                                     scene_.vehicle_forward(slot), static_cast<int>(slot)});
      a.node_of.push_back(it->first);
      a.slot_node[slot] = it->first;
      ++slot;
      ++it;
    }
  }
  return a;
}

// Whether the pair of dataset nodes (a, b) must be traced again: not cached,
// or its cached paths may have changed by `motion` (the cache mode's rule).
bool Sweep::needs_trace(std::uint32_t node_a, std::uint32_t node_b, const Motion& motion) const {
  auto it = cache_.find(pair_key(node_a, node_b));
  bool trace = it == cache_.end() || options_.cache == CacheMode::none;
  if (!trace && options_.cache == CacheMode::global) trace = !motion.moved.empty();
  if (trace || options_.cache != CacheMode::per_pair) return trace;
  const auto& updated = motion.updated;
  trace = std::binary_search(updated.begin(), updated.end(), node_a) ||
          std::binary_search(updated.begin(), updated.end(), node_b);
  const auto& c = it->second;
  // A pair without paths has no ellipsoid to speak of, and any new path
  // is its strongest: retrace it on any move (its sources shoot anyway).
  if (c.link.path_count == 0 && !motion.moved.empty()) trace = true;
  return trace || near_cached_paths(c, motion);
}

// Whether a moved sphere of `motion` comes near cached link c's paths.
bool Sweep::near_cached_paths(const CachedLink& c, const Motion& motion) const {
  bool trace = false;
  for (std::size_t s = 0; !trace && s < motion.moved.size(); ++s) {
    const Sphere& m = motion.moved[s];
    const double r = m.r + options_.cache_margin_m;
    // A path near the vehicle may be blocked, moved or gone; a vehicle
    // inside the strong ellipsoid may add a path as strong as the best.
    if (norm(m.c - c.a) + norm(m.c - c.b) - 2 * m.r <= c.reach) {
      trace = true;
      break;
    }
    bool outside = false;
    for (int k = 0; k < 3; ++k) outside |= m.c[k] < c.lo[k] - r || m.c[k] > c.hi[k] + r;
    if (outside) continue;
    std::size_t q = 0;
    for (const auto n : c.path_points) {
      for (std::size_t e = q; !trace && e + 1 < q + n; ++e)
        trace = segment_distance(m.c, c.points[e], c.points[e + 1]) <= r;
      q += n;
    }
  }
  return trace;
}

// A traced pair as the cache keeps it: its records and what decides when it
// must be traced again.
Sweep::CachedLink Sweep::cache_link(const tracer::PairResult& res, const Antennas& antennas, NodePair pair) const {
  const auto [i, j] = pair;
  const std::uint32_t statics = scene_.static_object_count();
  const double c0 = tracer::kSpeedOfLight;
  CachedLink c;
  c.a = antennas.nodes[i].position;
  c.b = antennas.nodes[j].position;
  // The direct segment is a "path" for invalidation: a vehicle crossing it
  // changes the LoS class.
  double strongest_len = norm(c.a - c.b), strongest = -1;
  c.points = {c.a, c.b};
  c.path_points = {2};
  c.link = link_record(res, antennas.node_of[i], antennas.node_of[j]);
  for (const auto& path : res.paths) {
    if (std::norm(path.a) > strongest) {
      strongest = std::norm(path.a);
      strongest_len = path.tau_s * c0;
    }
    c.points.push_back(c.a);
    for (const auto& in : path.interactions) c.points.push_back(in.point);
    c.points.push_back(c.b);
    c.path_points.push_back(static_cast<std::uint32_t>(path.interactions.size() + 2));
    c.paths.push_back(path_record(path));
    for (const auto& in : path.interactions)
      c.interactions.push_back(interaction_record(
          in, in.object < statics ? in.object : statics + antennas.slot_node.at(in.object - statics)));
  }
  // The first Fresnel zone (the LoS label) lies within d + lambda / 2.
  c.reach = std::max(strongest_len, norm(c.a - c.b) + 0.5 * tracer::kSpeedOfLight / radio_.frequency_hz) +
            options_.cache_margin_m;
  c.lo = c.hi = c.a;
  for (const auto& p : c.points)
    for (int k = 0; k < 3; ++k) {
      c.lo[k] = std::min(c.lo[k], p[k]);
      c.hi[k] = std::max(c.hi[k], p[k]);
    }
  if (options_.cfr) c.cfr = cfr_record(res.paths, *options_.cfr);
  return c;
}

// The pairs of `todo` traced, in pair order: with coherence, each frame's
// rays on the frame's turned lattice and every pair also solving the
// sequences carried from its last lattice_frames frames; with diffuse_frames,
// the frames before's lattices gathering diffuse power too.
tracer::Snapshot Sweep::trace_todo(std::uint64_t frame, const Antennas& ant, const std::vector<NodePair>& todo) {
  const std::uint64_t base = tracer_.lattice_turn;
  tracer::TracerConfig turned = tracer_;
  if (carries()) turned.lattice_turn = frame_lattice_turn(base, frame);
  // The diffuse gathering also shoots the lattices of the frames before
  // (their turns depend on the frame index alone: no state to carry). An
  // unturned sweep's own lattice is the base turn, which one of them can
  // meet in the first frames: that one is drawn from another stream.
  for (std::uint32_t k = 1; k < options_.diffuse_frames; ++k) {
    std::uint64_t t = frame_lattice_turn(base, frame - k);
    if (t == turned.lattice_turn) t = frame_lattice_turn(~base, frame - k);
    turned.diffuse_turns.push_back(t);
  }
  if (!carries()) return tracer::trace_pairs(scene_, ant.nodes, todo, turned, radio_);
  const auto carried = carried_sequences(frame, ant, todo);
  tracer::Snapshot traced = tracer::trace_pairs(scene_, ant.nodes, todo, turned, radio_, carried);
  for (std::size_t p = 0; p < todo.size(); ++p) keep_found(frame, ant, todo[p], traced.pairs[p], carried[p]);
  return traced;
}

// Per pair of `search` (the frame's traced pairs), its kept sequences (keep_found) stamped within the
// last lattice_frames frames whose vehicles are all still here, as this
// frame's FaceRefs (older ones forgotten).
std::vector<tracer::FaceSequences> Sweep::carried_sequences(std::uint64_t frame, const Antennas& ant,
                                                            const std::vector<NodePair>& search) {
  std::map<std::uint32_t, std::uint32_t> slot_of;  // dataset node -> vehicle slot
  for (std::uint32_t s = 0; s < ant.slot_node.size(); ++s) slot_of[ant.slot_node[s]] = s;
  std::vector<tracer::FaceSequences> carried(search.size());
  for (std::size_t p = 0; p < search.size(); ++p) {
    auto it = kept_.find(pair_key(ant.node_of[search[p].first], ant.node_of[search[p].second]));
    if (it == kept_.end()) continue;
    auto& kept = it->second;
    std::erase_if(kept, [&](const KeptSequence& k) { return frame - k.second >= options_.lattice_frames; });
    for (const auto& [faces, last] : kept) {
      std::vector<tracer::FaceRef> now;
      for (const auto& f : faces) {
        if (f.instance == 0) {
          now.push_back(f);
          continue;
        }
        auto at = slot_of.find(f.instance - 1);
        if (at == slot_of.end()) break;
        now.push_back({at->second + 1, f.face});
      }
      if (now.size() == faces.size()) carried[p].push_back(std::move(now));
    }
    stats_.carried_solved += carried[p].size();
  }
  return carried;
}

// A searched pair's sequences proposed by this frame's rays, and those
// carried that gave a path or a near miss, into its kept set stamped
// `frame`: a proposal is kept K frames, a path while it holds and K after.
void Sweep::keep_found(std::uint64_t frame, const Antennas& ant, NodePair pair, const tracer::PairResult& res,
                       const tracer::FaceSequences& carried) {
  using Seq = std::vector<tracer::FaceRef>;
  std::vector<Seq> found = res.near_misses;
  for (const auto& path : res.paths)
    if (path.origin.kind == tracer::PathOrigin::Kind::sequence) found.push_back(path.origin.faces);
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  auto in = [](const std::vector<Seq>& sorted, const Seq& x) {
    return std::binary_search(sorted.begin(), sorted.end(), x);
  };
  std::vector<Seq> sorted_carried = carried;
  std::sort(sorted_carried.begin(), sorted_carried.end());
  std::vector<KeptSequence> fresh;
  auto keep = [&](Seq named) {
    for (auto& f : named)
      if (f.instance > 0) f.instance = ant.slot_node.at(f.instance - 1) + 1;
    fresh.emplace_back(std::move(named), frame);
  };
  for (const auto& faces : res.proposed) keep(faces);
  for (const auto& faces : found)
    if (!in(res.proposed, faces) && in(sorted_carried, faces)) {  // not an exact enumeration's (found every frame)
      ++stats_.carried;
      keep(faces);
    }
  std::sort(fresh.begin(), fresh.end());
  if (fresh.empty()) return;
  // Merge: a sequence found again takes this frame's stamp.
  auto& kept = kept_[pair_key(ant.node_of[pair.first], ant.node_of[pair.second])];
  std::vector<KeptSequence> merged;
  merged.reserve(kept.size() + fresh.size());
  std::size_t a = 0, b = 0;
  while (a < kept.size() || b < fresh.size()) {
    if (b == fresh.size() || (a < kept.size() && kept[a].first < fresh[b].first)) {
      merged.push_back(std::move(kept[a++]));
    } else {
      if (a < kept.size() && kept[a].first == fresh[b].first) ++a;
      merged.push_back(std::move(fresh[b++]));
    }
  }
  kept = std::move(merged);
}

// Every node's state (RSUs and `vehicles`, sorted), in node order.
void Sweep::append_nodes(const std::vector<SweepVehicle>& vehicles, FrameRecord& frame) const {
  std::size_t r = 0;
  auto v = vehicles.begin();
  while (r < rsus_.size() || v != vehicles.end()) {
    NodeState s;
    if (v == vehicles.end() || (r < rsus_.size() && rsus_[r].node < v->node)) {
      s.node = rsus_[r].node;
      s.x = rsus_[r].position[0];
      s.y = rsus_[r].position[1];
      s.z = rsus_[r].position[2];
      ++r;
    } else {
      s.node = v->node;
      s.x = v->position[0];
      s.y = v->position[1];
      s.z = v->position[2];
      s.vx = static_cast<float>(v->velocity[0]);
      s.vy = static_cast<float>(v->velocity[1]);
      s.vz = static_cast<float>(v->velocity[2]);
      s.heading_deg = static_cast<float>(v->heading_deg);
      ++v;
    }
    frame.nodes.push_back(s);
  }
}

// Every pair's records from the cache, in pair order; those not in `traced`
// (a subsequence of `all`) flagged as cached.
void Sweep::append_links(const std::vector<NodePair>& all, const std::vector<NodePair>& traced,
                         const std::vector<std::uint32_t>& node_of, const std::vector<char>& inside,
                         FrameRecord& frame) {
  std::size_t next_traced = 0;
  for (const auto& [i, j] : all) {
    const bool is_traced = next_traced < traced.size() && traced[next_traced] == std::make_pair(i, j);
    if (is_traced) ++next_traced;
    const auto& c = cache_.at(pair_key(node_of[i], node_of[j]));
    LinkRecord link = c.link;
    if (!is_traced) link.flags |= kLinkCached;
    if (inside[i] || inside[j]) link.flags |= kLinkEnclosed;
    frame.links.push_back(link);
    frame.paths.insert(frame.paths.end(), c.paths.begin(), c.paths.end());
    frame.interactions.insert(frame.interactions.end(), c.interactions.begin(), c.interactions.end());
    frame.cfr.insert(frame.cfr.end(), c.cfr.begin(), c.cfr.end());
    stats_.paths += c.paths.size();
  }
}

// Pairs whose nodes left are of no further use.
void Sweep::forget_departed() {
  for (auto it = cache_.begin(); it != cache_.end();) {
    const auto a = static_cast<std::uint32_t>(it->first >> 32), b = static_cast<std::uint32_t>(it->first);
    auto present = [&](std::uint32_t x) {
      return placed_.count(x) ||
             std::any_of(rsus_.begin(), rsus_.end(), [x](const SweepRsu& r) { return r.node == x; });
    };
    it = present(a) && present(b) ? std::next(it) : cache_.erase(it);
  }
  std::erase_if(kept_, [this](const auto& k) { return !cache_.count(k.first); });
}

// The antennas inside a building this frame (their channels pass through
// walls): counted, their nodes kept for the summary; true per antenna.
std::vector<char> Sweep::note_enclosed(const Antennas& ant) {
  std::vector<char> inside(ant.nodes.size(), 0);
  for (std::size_t k = 0; k < ant.nodes.size(); ++k) {
    if (scene_.enclosing_object(ant.nodes[k].position) < 0) continue;
    inside[k] = 1;
    ++stats_.enclosed;
    auto& seen = stats_.enclosed_nodes;
    const auto at = std::lower_bound(seen.begin(), seen.end(), ant.node_of[k]);
    if (at == seen.end() || *at != ant.node_of[k]) seen.insert(at, ant.node_of[k]);
  }
  return inside;
}

FrameRecord Sweep::step(std::uint64_t frame_index, double time_s, std::vector<SweepVehicle> vehicles) {
  sort_and_check(vehicles, rsus_);
  const bool block_start = frame_index % options_.block_frames == 0;
  if (block_start) {
    placed_.clear();
    cache_.clear();
    kept_.clear();
  }
  const Motion motion = place_vehicles(vehicles);
  if (motion.scene_changed || block_start) pose_vehicles();
  const Antennas ant = antennas();
  const std::vector<char> inside = note_enclosed(ant);

  // Which pairs to trace.
  const auto n = static_cast<std::uint32_t>(ant.nodes.size());
  std::vector<NodePair> all, todo;
  for (std::uint32_t i = 0; i < n; ++i)
    for (std::uint32_t j = i + 1; j < n; ++j) all.emplace_back(i, j);
  for (const auto& [i, j] : all)
    if (needs_trace(ant.node_of[i], ant.node_of[j], motion)) todo.emplace_back(i, j);

  const auto t0 = std::chrono::steady_clock::now();
  const tracer::Snapshot snap = trace_todo(frame_index, ant, todo);
  stats_.trace_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  stats_.rays += snap.stats.rays;
  for (std::size_t p = 0; p < todo.size(); ++p) {
    CachedLink c = cache_link(snap.pairs[p], ant, todo[p]);
    cache_[pair_key(c.link.tx, c.link.rx)] = std::move(c);
  }

  FrameRecord frame;
  frame.time_s = time_s;
  append_nodes(vehicles, frame);
  append_links(all, todo, ant.node_of, inside, frame);
  if (motion.departed) forget_departed();
  ++stats_.frames;
  stats_.links += all.size();
  stats_.traced_links += todo.size();
  return frame;
}

}  // namespace raysweep::generators
