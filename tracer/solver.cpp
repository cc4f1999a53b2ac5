#include "tracer/solver.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

namespace raysweep::tracer {

namespace {

using CVec3 = std::array<cdouble, 3>;

cdouble cdot(const CVec3& e, const Vec3& v) { return e[0] * v[0] + e[1] * v[1] + e[2] * v[2]; }
CVec3 cvec(const Vec3& v) { return {cdouble(v[0]), cdouble(v[1]), cdouble(v[2])}; }
CVec3 combine(cdouble a, const Vec3& u, cdouble b, const Vec3& w) {
  return {a * u[0] + b * w[0], a * u[1] + b * w[1], a * u[2] + b * w[2]};
}

// TE basis vector for direction k on a surface with normal n.
Vec3 te_basis(const Vec3& k, const Vec3& n) {
  const Vec3 s = cross(k, n);
  const double l = norm(s);
  return l > 1e-12 ? (1.0 / l) * s : any_perpendicular(k);
}

// Face sequence of one shoot-and-bounce ray, without heap allocation.
struct Sequence {
  std::array<FaceRef, kMaxDepth> faces{};
  int n = 0;
};

struct CandidateKey {
  std::uint32_t other;
  std::vector<FaceRef> faces;
  bool operator==(const CandidateKey&) const = default;
};
struct CandidateHash {
  std::size_t operator()(const CandidateKey& k) const {
    std::size_t h = k.other * 0x9E3779B97F4A7C15ull;
    for (const auto& f : k.faces) h = (h ^ (std::size_t(f.instance) << 32 ^ f.face)) * 0x100000001B3ull;
    return h;
  }
};

}  // namespace

void validate(const TracerConfig& t, const RadioConfig& r) {
  auto bad = [](const std::string& what) { throw std::invalid_argument(what); };
  if (!(r.frequency_hz > 0) || !std::isfinite(r.frequency_hz)) bad("radio.frequency_hz must be positive");
  if (!(r.bandwidth_hz > 0) || !std::isfinite(r.bandwidth_hz)) bad("radio.bandwidth_hz must be positive");
  if (!std::isfinite(r.tx_power_dbm)) bad("radio.tx_power_dbm must be finite");
  if (t.max_depth < 0 || t.max_depth > kMaxDepth)
    bad("tracer.max_depth must be within 0.." + std::to_string(kMaxDepth));
  if (t.rays_per_source < 1) bad("tracer.rays_per_source must be at least 1");
  if (!(t.reception_radius_factor > 0)) bad("tracer.reception_radius_factor must be positive");
  if (t.max_transmissions < 0) bad("tracer.max_transmissions must be >= 0");
  if (!(t.sbr_transmission_loss_db >= 0)) bad("tracer.sbr_transmission_loss_db must be >= 0");
}

Electromagnetics::Electromagnetics(const std::vector<std::string>& names, const RadioConfig& radio,
                                   const std::map<std::string, MaterialOverride>& overrides)
    : radio_(radio) {
  for (const auto& name : names) {
    auto it = overrides.find(name);
    materials_.push_back(radio_material(name, radio.frequency_hz, it == overrides.end() ? MaterialOverride{} : it->second));
    const auto c = slab_coefficients(materials_.back(), 1.0);
    const double t = std::max(std::abs(c.t.te), std::abs(c.t.tm));
    opaque_.push_back(t < 1e-12);
    normal_loss_db_.push_back(t > 0 ? -20 * std::log10(t) : 1e300);
  }
}

SlabCoefficients Electromagnetics::coefficients(std::uint16_t i, double cos_theta) const {
  return slab_coefficients(materials_.at(i), std::clamp(cos_theta, 0.0, 1.0));
}

std::vector<Node> vehicle_nodes(const TraceScene& scene) {
  std::vector<Node> nodes;
  const auto& vs = scene.vehicles();
  for (std::size_t v = 0; v < vs.size(); ++v)
    nodes.push_back(Node{vs[v].id, scene.vehicle_antenna(v), vs[v].velocity, scene.vehicle_forward(v),
                         static_cast<int>(v)});
  return nodes;
}

std::vector<Vec3> fibonacci_sphere(int n) {
  std::vector<Vec3> dirs(static_cast<std::size_t>(n));
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double phi = golden * i;
    dirs[i] = Vec3{r * std::cos(phi), r * std::sin(phi), z};
  }
  return dirs;
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

std::optional<Path> compute_path(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& config,
                                 const Node& from, const Node& to, const std::vector<FaceRef>& faces, bool* over_cap,
                                 std::uint64_t* rays) {
  if (over_cap) *over_cap = false;
  const std::size_t k = faces.size();
  // Image method: mirror the source in each plane, then walk back from the
  // receiver, intersecting each plane on the way.
  std::vector<Plane> planes(k);
  std::vector<Vec3> images(k + 1);
  images[0] = from.position;
  for (std::size_t m = 0; m < k; ++m) {
    planes[m] = scene.plane(faces[m]);
    if (norm(planes[m].normal) < 0.5) return std::nullopt;
    const double dist = dot(planes[m].normal, images[m]) - planes[m].offset;
    images[m + 1] = images[m] - (2.0 * dist) * planes[m].normal;
  }
  std::vector<Vec3> points(k + 2);
  points[0] = from.position;
  points[k + 1] = to.position;
  Vec3 target = to.position;
  for (std::size_t m = k; m-- > 0;) {
    const Plane& p = planes[m];
    const double di = dot(p.normal, images[m + 1]) - p.offset;
    const double dt = dot(p.normal, target) - p.offset;
    // The image and the point it is seen from lie strictly on opposite sides.
    if (!(di * dt < 0)) return std::nullopt;
    const double s = di / (di - dt);
    points[m + 1] = images[m + 1] + s * (target - images[m + 1]);
    target = points[m + 1];
  }

  // Trace every segment: it must end on its face, and what it crosses on the
  // way are slabs (or opaque blockers).
  struct Event {
    bool reflection;
    FaceRef face;
    Vec3 point;
    Vec3 dir_in;
  };
  std::vector<Event> events;
  std::vector<Vec3> dirs(k + 1);
  double length = 0;
  std::vector<Hit> hits;
  int transmissions = 0;
  for (std::size_t m = 0; m <= k; ++m) {
    const Vec3 a = points[m], b = points[m + 1];
    const double len = norm(b - a);
    if (len < 1e-9) return std::nullopt;
    const Vec3 dir = (1.0 / len) * (b - a);
    dirs[m] = dir;
    length += len;
    const FaceRef* skip = m > 0 ? &faces[m - 1] : nullptr;
    const bool ends_on_face = m < k;
    const double end_tol = ends_on_face ? std::max(scene.slack(b, 0), 2 * scene.flatness(faces[m]) + 1e-6 * len)
                                        : scene.slack(b, 0) * 0.1;
    const double t0 = m > 0 ? 0 : scene.slack(a, 0) * 0.1;
    const double tfar = ends_on_face ? len + end_tol : len - end_tol;
    if (tfar <= t0) return std::nullopt;
    if (!scene.all_hits(a, dir, t0, tfar, hits, 4096, skip)) return std::nullopt;
    if (rays) *rays += hits.size() + 1;
    bool reached = !ends_on_face;
    for (const auto& h : hits) {
      if (ends_on_face && h.face == faces[m] && std::fabs(h.t - len) <= end_tol) {
        reached = true;
        break;
      }
      if (h.t >= len - end_tol) continue;  // at the end point, not on the way
      if (!config.refraction) return std::nullopt;
      events.push_back(Event{false, h.face, a + h.t * dir, dir});
      ++transmissions;
    }
    if (!reached) return std::nullopt;
    if (ends_on_face) events.push_back(Event{true, faces[m], b, dir});
  }
  if (transmissions > config.max_transmissions) {
    if (over_cap) *over_cap = true;
    return std::nullopt;
  }

  // Field along the path: the transmit pattern's vector, then each
  // interaction in its own TE/TM basis.
  CVec3 e = cvec(antenna_field(em.radio().antenna, dirs[0], from.forward));
  Path path;
  for (const auto& ev : events) {
    const Plane p = scene.plane(ev.face);
    const Vec3& k_in = ev.dir_in;
    const double cos_theta = std::fabs(dot(k_in, p.normal));
    const auto mat = scene.material(ev.face);
    const auto c = em.coefficients(mat, cos_theta);
    const Vec3 es = te_basis(k_in, p.normal);
    const Vec3 ep_in = cross(es, k_in);
    if (ev.reflection) {
      const Vec3 k_out = k_in - (2 * dot(k_in, p.normal)) * p.normal;
      e = combine(c.r.te * cdot(e, es), es, c.r.tm * cdot(e, ep_in), cross(es, k_out));
    } else {
      if (std::abs(c.t.te) < 1e-12 && std::abs(c.t.tm) < 1e-12) return std::nullopt;  // opaque
      e = combine(c.t.te * cdot(e, es), es, c.t.tm * cdot(e, ep_in), ep_in);
    }
    path.interactions.push_back(Interaction{ev.reflection ? InteractionType::specular : InteractionType::refraction,
                                            scene.object(ev.face), mat, ev.point});
  }
  const Vec3 arrival = -dirs[k];
  const Vec3 f_rx = antenna_field(em.radio().antenna, arrival, to.forward);
  const double lambda = em.wavelength();
  path.tau_s = length / kSpeedOfLight;
  const double phase = -2 * kPi * std::fmod(length / lambda, 1.0);
  path.a = (lambda / (4 * kPi * length)) * cdot(e, f_rx) * std::polar(1.0, phase);
  path.theta_t = zenith(dirs[0]);
  path.phi_t = azimuth(dirs[0]);
  path.theta_r = zenith(arrival);
  path.phi_r = azimuth(arrival);
  // Doppler: -(1/lambda) dL/dt, each segment shortening with the closing
  // speed of its end points (a moving reflector moves its reflection point
  // with it; sliding along the face does not change L to first order).
  double dl_dt = 0;
  Vec3 v_prev = from.velocity;
  for (std::size_t m = 0; m <= k; ++m) {
    const Vec3 v_next = m < k ? scene.velocity(faces[m]) : to.velocity;
    dl_dt += dot(dirs[m], v_next - v_prev);
    v_prev = v_next;
  }
  path.doppler_hz = -dl_dt / lambda;
  return path;
}

namespace {

// Shoot-and-bounce from node `src`: face sequences that pass near other nodes.
void shoot_from(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& cfg,
                const std::vector<Node>& nodes, std::uint32_t src, const std::vector<Vec3>& lattice,
                std::size_t begin, std::size_t end, std::vector<CandidateKey>& out, std::uint64_t& rays) {
  const double spacing = std::sqrt(4 * kPi / static_cast<double>(lattice.size())) * cfg.reception_radius_factor;
  struct State {
    Vec3 o, d;
    double len;
    int transmissions;
    double loss_db;
    bool has_leaving;
    FaceRef leaving;
    Sequence seq;
  };
  std::vector<State> stack;
  const Vec3 ref = nodes[src].position;
  std::vector<float> nx(nodes.size()), ny(nodes.size()), nz(nodes.size());
  for (std::size_t j = 0; j < nodes.size(); ++j) {
    nx[j] = static_cast<float>(nodes[j].position[0] - ref[0]);
    ny[j] = static_cast<float>(nodes[j].position[1] - ref[1]);
    nz[j] = static_cast<float>(nodes[j].position[2] - ref[2]);
  }
  std::vector<unsigned char> inside(nodes.size());
  std::unordered_set<CandidateKey, CandidateHash> seen;
  CandidateKey key;
  for (std::size_t r = begin; r < end; ++r) {
    stack.push_back(State{nodes[src].position, lattice[r], 0, 0, 0, false, {}, {}});
    while (!stack.empty()) {
      State st = stack.back();
      stack.pop_back();
      Hit hit;
      const bool got = scene.closest_hit(st.o, st.d, st.has_leaving ? 0 : 1e-4, std::numeric_limits<double>::infinity(),
                                         hit, st.has_leaving ? &st.leaving : nullptr);
      ++rays;
      const double tseg = got ? hit.t : std::numeric_limits<double>::infinity();
      if (st.seq.n > 0) {
        // Branch-free pass over all nodes first (vectorises), keys only for hits.
        const std::size_t nn = nodes.size();
        // Single precision relative to the source (city-sized offsets keep
        // millimetres): a candidate test only, the exact path is recomputed
        // in double; float doubles the SIMD width of this hot loop.
        const float ox = static_cast<float>(st.o[0] - ref[0]), oy = static_cast<float>(st.o[1] - ref[1]),
                    oz = static_cast<float>(st.o[2] - ref[2]);
        const float dx = static_cast<float>(st.d[0]), dy = static_cast<float>(st.d[1]), dz = static_cast<float>(st.d[2]);
        const float len = static_cast<float>(st.len), sp = static_cast<float>(spacing);
        const float tmax = static_cast<float>(std::min(tseg, 1e30));
        unsigned any = 0;
        for (std::size_t j = 0; j < nn; ++j) {
          const float wx = nx[j] - ox, wy = ny[j] - oy, wz = nz[j] - oz;
          const float s = wx * dx + wy * dy + wz * dz;
          const float r = sp * (len + s);
          const unsigned in = (s > 0) & (s <= tmax) & (wx * wx + wy * wy + wz * wz - s * s <= r * r);
          inside[j] = static_cast<unsigned char>(in);
          any |= in;
        }
        for (std::uint32_t j = 0; any && j < nn; ++j) {
          if (!inside[j] || j == src) continue;
          key.other = j;
          key.faces.assign(st.seq.faces.begin(), st.seq.faces.begin() + st.seq.n);
          if (seen.insert(key).second) out.push_back(key);
        }
      }
      if (!got) continue;
      const Vec3 p = st.o + hit.t * st.d;
      const auto mat = scene.material(hit.face);
      if (cfg.refraction && st.transmissions < cfg.max_transmissions && !em.opaque(mat)) {
        const double loss = st.loss_db + em.normal_transmission_loss_db(mat);
        if (loss <= cfg.sbr_transmission_loss_db)
          stack.push_back(State{p, st.d, st.len + hit.t, st.transmissions + 1, loss, true, hit.face, st.seq});
      }
      if (cfg.specular && st.seq.n < cfg.max_depth) {
        const Vec3 n = scene.plane(hit.face).normal;
        State next{p, st.d - (2 * dot(st.d, n)) * n, st.len + hit.t, st.transmissions, st.loss_db, true, hit.face,
                   st.seq};
        next.seq.faces[next.seq.n++] = hit.face;
        stack.push_back(next);
      }
    }
  }
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

}  // namespace

Snapshot trace_snapshot(const TraceScene& scene, const std::vector<Node>& nodes, const TracerConfig& cfg,
                        const RadioConfig& radio) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  const auto n = static_cast<std::uint32_t>(nodes.size());
  for (std::uint32_t i = 0; i < n; ++i)
    for (std::uint32_t j = i + 1; j < n; ++j) pairs.emplace_back(i, j);
  return trace_pairs(scene, nodes, pairs, cfg, radio);
}

Snapshot trace_pairs(const TraceScene& scene, const std::vector<Node>& nodes,
                     const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs, const TracerConfig& cfg,
                     const RadioConfig& radio) {
  validate(cfg, radio);
  for (const auto& n : nodes)
    for (double c : n.position)
      if (!std::isfinite(c)) throw std::invalid_argument("node " + n.id + ": position is not finite");
  const Electromagnetics em(scene.material_names(), radio, cfg.materials);
  const auto n = static_cast<std::uint32_t>(nodes.size());
  Snapshot snap;
  // Which pair slot each (i, j) feeds; sources shoot only when they have a
  // pair to serve. A pair's candidates come from its own two ends, so a pair
  // traced alone gets exactly the paths it gets in a full snapshot.
  std::unordered_map<std::uint64_t, std::size_t> slot;
  slot.reserve(pairs.size());
  std::vector<std::uint32_t> sources;
  std::vector<unsigned char> is_source(n, 0);
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    auto [i, j] = pairs[p];
    if (i >= j || j >= n) throw std::invalid_argument("trace_pairs: pair (" + std::to_string(i) + ", " +
                                                      std::to_string(j) + ") is not i < j < node count");
    if (!slot.emplace(static_cast<std::uint64_t>(i) << 32 | j, p).second)
      throw std::invalid_argument("trace_pairs: pair (" + std::to_string(i) + ", " + std::to_string(j) + ") twice");
    for (auto e : {i, j}) {
      if (is_source[e]) continue;
      is_source[e] = 1;
      sources.push_back(e);
    }
  }
  std::sort(sources.begin(), sources.end());
  std::vector<std::vector<std::vector<FaceRef>>> candidates(pairs.size());

  std::uint64_t search_rays = 0;
  if (cfg.specular && cfg.max_depth > 0 && n > 1) {
    if (cfg.candidates == CandidateSearch::exhaustive) {
      std::vector<std::vector<FaceRef>> all;
      std::vector<FaceRef> current;
      enumerate_all(scene, cfg.max_depth, current, all);
      for (auto& c : candidates) c = all;
    } else {
      const auto lattice = fibonacci_sphere(cfg.rays_per_source);
      const std::size_t chunk = 256;
      const std::size_t chunks = (lattice.size() + chunk - 1) / chunk;
      struct Local {
        std::vector<std::pair<std::uint32_t, CandidateKey>> found;
        std::uint64_t rays = 0;
      };
      tbb::enumerable_thread_specific<Local> locals;
      tbb::parallel_for(std::size_t{0}, sources.size() * chunks, [&](std::size_t task) {
        const auto src = sources[task / chunks];
        const std::size_t c = task % chunks;
        auto& local = locals.local();
        std::vector<CandidateKey> out;
        shoot_from(scene, em, cfg, nodes, src, lattice, c * chunk, std::min(lattice.size(), (c + 1) * chunk), out,
                   local.rays);
        for (auto& k : out) local.found.emplace_back(src, std::move(k));
      });
      for (auto& local : locals) {
        search_rays += local.rays;
        for (auto& [src, k] : local.found) {
          const std::uint32_t a = std::min(src, k.other), b = std::max(src, k.other);
          const auto it = slot.find(static_cast<std::uint64_t>(a) << 32 | b);
          if (it == slot.end()) continue;
          if (src > k.other) std::reverse(k.faces.begin(), k.faces.end());
          candidates[it->second].push_back(std::move(k.faces));
        }
      }
      // Thread-local order varies; the sorted set does not.
      tbb::parallel_for(std::size_t{0}, candidates.size(), [&](std::size_t p) {
        auto& c = candidates[p];
        std::sort(c.begin(), c.end());
        c.erase(std::unique(c.begin(), c.end()), c.end());
      });
    }
  }

  snap.pairs.resize(pairs.size());
  tbb::enumerable_thread_specific<std::uint64_t> pair_rays(0);
  tbb::parallel_for(std::size_t{0}, pairs.size(), [&](std::size_t p) {
    auto [i, j] = pairs[p];
    PairResult& res = snap.pairs[p];
    res.tx = i;
    res.rx = j;
    auto& rays = pair_rays.local();
    res.los_class = classify_los(scene, nodes[i].position, nodes[j].position, res.blockers, &rays);
    auto add = [&](const std::vector<FaceRef>& faces) {
      bool over = false;
      if (auto path = compute_path(scene, em, cfg, nodes[i], nodes[j], faces, &over, &rays))
        res.paths.push_back(std::move(*path));
      else if (over)
        ++res.dropped_transmission_cap;
    };
    if (cfg.los) add({});
    for (const auto& faces : candidates[p]) add(faces);
    res.candidates = static_cast<std::uint32_t>(candidates[p].size() + (cfg.los ? 1 : 0));
    // Distinct face sequences can still describe one physical path (a point
    // on the seam of two faces that are coplanar in fact): keep the first.
    std::stable_sort(res.paths.begin(), res.paths.end(),
                     [](const Path& a, const Path& b) { return a.tau_s < b.tau_s; });
    std::vector<Path> unique;
    for (auto& path : res.paths) {
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
    res.paths = std::move(unique);
    res.stats = path_stats(res.paths);
  });
  snap.stats.rays = search_rays;
  for (auto r : pair_rays) snap.stats.rays += r;
  for (const auto& r : snap.pairs) {
    snap.stats.candidates += r.candidates;
    snap.stats.paths += r.paths.size();
    snap.stats.dropped_transmission_cap += r.dropped_transmission_cap;
  }
  return snap;
}

}  // namespace raysweep::tracer
