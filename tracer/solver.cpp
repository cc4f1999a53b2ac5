#include "tracer/solver.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <map>
#include <unordered_map>
#include <unordered_set>

#include "tracer/diffuse.hpp"
#include "tracer/fresnel.hpp"
#include "tracer/image_search.hpp"

namespace raysweep::tracer {

namespace {

using CVec3 = std::array<cdouble, 3>;

cdouble cdot(const CVec3& e, const Vec3& v) { return e[0] * v[0] + e[1] * v[1] + e[2] * v[2]; }
CVec3 cvec(const Vec3& v) { return {cdouble(v[0]), cdouble(v[1]), cdouble(v[2])}; }
CVec3 combine(cdouble a, const Vec3& u, cdouble b, const Vec3& w) {
  return {a * u[0] + b * w[0], a * u[1] + b * w[1], a * u[2] + b * w[2]};
}

// Field e, travelling along k_in, reflected by a face of plane normal n
// with reflection coefficients r (TE/TM in the face's basis), keeping `keep` of
// it (a rough surface's specular share).
CVec3 reflect_field(const CVec3& e, const Vec3& k_in, const Vec3& n, const TeTm& r, double keep) {
  const Vec3 es = te_basis(k_in, n);
  const Vec3 k_out = k_in - (2 * dot(k_in, n)) * n;
  return combine(keep * r.te * cdot(e, es), es, keep * r.tm * cdot(e, cross(es, k_in)), cross(es, k_out));
}
double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

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
  if (!(t.diffuse_tile_m > 0) || !std::isfinite(t.diffuse_tile_m)) bad("tracer.diffuse_tile_m must be positive");
  if (!(t.diffuse_tile_ratio > 0) || !std::isfinite(t.diffuse_tile_ratio))
    bad("tracer.diffuse_tile_ratio must be positive");
  if (!(t.diffuse_shadow_ratio >= 0) || !std::isfinite(t.diffuse_shadow_ratio))
    bad("tracer.diffuse_shadow_ratio must be >= 0");
  if (!(t.diffuse_roulette_db >= 0)) bad("tracer.diffuse_roulette_db must be >= 0 (300 or more: off)");
  if (!std::isfinite(t.path_threshold_db)) bad("tracer.path_threshold_db must be finite (<= 0 keeps every path)");
  if (std::isnan(t.range_margin_db)) bad("tracer.range_margin_db must be a number");
  if (!std::isfinite(t.vehicle_edge_floor_db)) bad("tracer.vehicle_edge_floor_db must be finite");
  if (!std::isfinite(r.sensitivity_dbm)) bad("radio.sensitivity_dbm must be finite");
}

namespace {
double peak_gain(AntennaPattern p) {
  switch (p) {
    case AntennaPattern::isotropic: return 1.0;
    case AntennaPattern::short_dipole: return 1.5;
    case AntennaPattern::halfwave_dipole: return 1.641;
  }
  return 1.0;
}
}  // namespace

double max_range_m(const TracerConfig& t, const RadioConfig& r) {
  // Free space: P_rx = P_tx G^2 (lambda / (4 pi d))^2.
  const double budget_db = r.tx_power_dbm - r.sensitivity_dbm + 20 * std::log10(peak_gain(r.antenna.pattern)) +
                           t.range_margin_db;
  const double lambda = kSpeedOfLight / r.frequency_hz;
  return lambda / (4 * kPi) * std::pow(10.0, budget_db / 20);
}

Electromagnetics::Electromagnetics(const std::vector<std::string>& names, const RadioConfig& radio,
                                   const std::map<std::string, MaterialOverride>& overrides, bool rough)
    : radio_(radio) {
  for (const auto& name : names) {
    auto it = overrides.find(name);
    materials_.push_back(radio_material(name, radio.frequency_hz, it == overrides.end() ? MaterialOverride{} : it->second));
    const auto c = slab_coefficients(materials_.back(), 1.0);
    const double t = std::max(std::abs(c.t.te), std::abs(c.t.tm));
    opaque_.push_back(t < 1e-12);
    normal_loss_db_.push_back(t > 0 ? -20 * std::log10(t) : 1e300);
    const double S = materials_.back().scattering.s;
    keep_.push_back(rough ? std::sqrt(1 - S * S) : 1.0);
  }
}

SlabCoefficients Electromagnetics::coefficients(std::uint16_t i, double cos_theta) const {
  return slab_coefficients(materials_.at(i), std::clamp(cos_theta, 0.0, 1.0));
}

TeTm Electromagnetics::reflection(std::uint16_t i, double cos_theta) const {
  return slab_reflection(materials_.at(i), std::clamp(cos_theta, 0.0, 1.0));
}

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

// The sine below which a grazing segment's reach onto its face stops growing.
constexpr double kGrazingSineFloor = 0.01;

// compute_path; `through_vehicles`: vehicle faces on the way are ignored
// (the direct path that the knife-edge model attenuates instead).
std::optional<Path> exact_path(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& config,
                               const Node& from, const Node& to, const std::vector<FaceRef>& faces, bool* over_cap,
                               std::uint64_t* rays, bool through_vehicles) {
  if (over_cap) *over_cap = false;
  const std::size_t k = faces.size();
  // Image method: mirror the source in each plane, then walk back from the
  // receiver, intersecting each plane on the way.
  // Fixed-size scratch (every candidate of the search passes here, most
  // failing in the first few lines: heap vectors were a tenth of its time).
  if (k > static_cast<std::size_t>(kMaxDepth)) return std::nullopt;
  std::array<Plane, kMaxDepth> planes;
  std::array<Vec3, kMaxDepth + 1> images;
  images[0] = from.position;
  for (std::size_t m = 0; m < k; ++m) {
    planes[m] = scene.plane(faces[m]);
    if (norm(planes[m].normal) < 0.5) return std::nullopt;
    const double dist = dot(planes[m].normal, images[m]) - planes[m].offset;
    images[m + 1] = images[m] - (2.0 * dist) * planes[m].normal;
  }
  std::array<Vec3, kMaxDepth + 2> points;
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
  thread_local std::vector<Event> events;
  events.clear();
  std::array<Vec3, kMaxDepth + 1> dirs;
  double length = 0;
  thread_local std::vector<Hit> hits;
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
    // Where the segment meets its face: Embree's float error lies across the
    // face, so along a grazing ray it grows as 1 / sin(grazing angle) (a car's
    // side seen at 1 degree: 2 mm off at 500 m from the frame's centre, twice
    // the slack). The ray meets the face's plane once, so a hit on the face
    // itself within that reach is the reflection point, whatever the angle
    // (down to 0.57 degrees; beyond, the reach stops growing).
    const double reach_tol =
        ends_on_face ? end_tol / std::max(std::fabs(dot(dir, planes[m].normal)), kGrazingSineFloor) : end_tol;
    const double t0 = m > 0 ? 0 : scene.slack(a, 0) * 0.1;
    const double tfar = ends_on_face ? len + reach_tol : len - end_tol;
    if (tfar <= t0) return std::nullopt;
    // Most candidates of the exact image search run through buildings:
    // stop at the first opaque face, or once the slab cap is exceeded,
    // instead of listing every wall to the end of a long segment.
    const int remaining = config.refraction ? std::max(0, config.max_transmissions - transmissions) : 0;
    // Through vehicles: a vehicle on the way is passed (its knife-edge loss
    // is the caller's), but not one that carries this leg's reflections
    // (a leg cannot reach its face through the body the face belongs to),
    // nor, on a reflected path, the antennas' own vehicles (the knife edges
    // leave them out: they carry the antennas, so a ray through them would
    // cost nothing; the direct path keeps its rule, docs/tracer.md).
    const std::uint32_t host_a = m > 0 ? faces[m - 1].instance : 0, host_b = ends_on_face ? faces[m].instance : 0;
    auto own = [k](const Node& n) { return k > 0 && n.vehicle >= 0 ? static_cast<std::uint32_t>(n.vehicle) + 1 : 0u; };
    const std::uint32_t own_a = own(from), own_b = own(to);
    auto passed = [&](const FaceRef& f) {
      return through_vehicles && scene.is_vehicle(f) && f.instance != host_a && f.instance != host_b &&
             f.instance != own_a && f.instance != own_b;
    };
    const std::size_t first_hits = static_cast<std::size_t>(remaining) + (through_vehicles ? 8 : 3);
    if (!scene.all_hits(a, dir, t0, tfar, hits, first_hits, skip)) {
      int before_end = 0;
      bool opaque = false;
      for (const auto& h : hits)
        if (h.t < len - end_tol && !passed(h.face)) {
          ++before_end;
          opaque = opaque || (through_vehicles && (!config.refraction || em.opaque(scene.material(h.face))));
        }
      if (rays) *rays += hits.size() + 1;
      if (before_end > remaining) {
        if (over_cap && config.refraction) *over_cap = true;
        return std::nullopt;
      }
      // Blocked on the way (the loop below would say so after listing all).
      if (opaque) return std::nullopt;
      // Several faces meet at the end point: list them all.
      if (!scene.all_hits(a, dir, t0, tfar, hits, 4096, skip)) return std::nullopt;
    }
    if (rays) *rays += hits.size() + 1;
    bool reached = !ends_on_face;
    for (const auto& h : hits) {
      if (ends_on_face && h.face == faces[m] && std::fabs(h.t - len) <= reach_tol) {
        reached = true;
        break;
      }
      if (h.t >= len - end_tol) continue;  // at the end point, not on the way
      if (passed(h.face)) continue;
      if (!config.refraction || em.opaque(scene.material(h.face))) return std::nullopt;
      events.push_back(Event{false, h.face, a + h.t * dir, dir});
      ++transmissions;
    }
    // A passed vehicle's face coincident with the reflection point (a car
    // standing on the ground over it) is listed as that crossing instead
    // of the face: the point must then lie on the face itself.
    if (!reached && ends_on_face)
      for (const auto& h : hits)
        if (std::fabs(h.t - len) <= end_tol && passed(h.face)) {
          reached = scene.face_contains(faces[m], b, end_tol);
          break;
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
  path.interactions.reserve(events.size());
  for (const auto& ev : events) {
    const Plane p = scene.plane(ev.face);
    const Vec3& k_in = ev.dir_in;
    const double cos_theta = std::fabs(dot(k_in, p.normal));
    const auto mat = scene.material(ev.face);
    if (ev.reflection) {
      // Rough surfaces keep sqrt(1 - S^2) of the specular field when the
      // scattered part is traced (effective roughness energy partition).
      e = reflect_field(e, k_in, p.normal, em.reflection(mat, cos_theta), em.specular_keep(mat));
    } else {
      const auto c = em.coefficients(mat, cos_theta);
      if (std::abs(c.t.te) < 1e-12 && std::abs(c.t.tm) < 1e-12) return std::nullopt;  // opaque
      const Vec3 es = te_basis(k_in, p.normal);
      const Vec3 ep_in = cross(es, k_in);
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

}  // namespace

std::optional<Path> compute_path(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& config,
                                 const Node& from, const Node& to, const std::vector<FaceRef>& faces, bool* over_cap,
                                 std::uint64_t* rays) {
  return exact_path(scene, em, config, from, to, faces, over_cap, rays, false);
}

namespace {

// Vehicle edges shorter than this many wavelengths do not diffract (wheels'
// facets, mirrors): Keller's stationary point needs room along the edge.
constexpr double kVehicleEdgeMinWavelengths = 5;

// Angle of `v` around an edge, from t0 towards n0, in [0, 2 pi).
double edge_angle(const Edge& e, const Vec3& v) {
  double a = std::atan2(dot(v, e.n0), dot(v, e.t0));
  return a < 0 ? a + 2 * kPi : a;
}

// The leg a -> b (length len along unit dir) is free of everything but the
// two faces of the edge it starts or ends on. Both ends are trimmed by the
// float slack: at the edge point other faces meeting the edge (a third
// face at a corner) touch the leg without blocking it.
bool leg_clear(const TraceScene& scene, const Edge& edge, const Vec3& a, const Vec3& dir, double len,
               std::uint64_t* rays) {
  const double t0 = scene.slack(a, 0) * 0.1;
  const double t1 = len - scene.slack(a, len) * 0.1;
  if (t1 <= t0) return false;
  if (rays) ++*rays;
  return !scene.occluded(a, dir, t0, t1, &edge.face0, &edge.face_n);
}

}  // namespace

std::optional<Path> compute_diffraction_path(const TraceScene& scene, const Electromagnetics& em, const Node& from,
                                             const Node& to, const Edge& edge, std::uint64_t* rays,
                                             const FaceRef* before, const FaceRef* after, double min_power) {
  // A reflection on a plane before (after) the edge is unfolded: the edge
  // sees the source's (receiver's) image, along straight legs of the same
  // length, so Keller's point, the UTD angles and the spreading are those of
  // the image; the field takes the face's coefficients at its point.
  auto image = [&](const Vec3& x, const FaceRef* f, Plane& pl) {
    if (!f) return x;
    pl = scene.plane(*f);
    return x - (2 * (dot(pl.normal, x) - pl.offset)) * pl.normal;
  };
  Plane pa, pb;
  const Vec3 tx = image(from.position, before, pa), rx = image(to.position, after, pb);
  const double len = norm(edge.b - edge.a);
  const Vec3 wt = tx - edge.a, wr = rx - edge.a;
  const double zt = dot(wt, edge.e), zr = dot(wr, edge.e);
  const Vec3 vt = wt - zt * edge.e, vr = wr - zr * edge.e;
  const double rt = norm(vt), rr = norm(vr);
  if (rt < 1e-6 || rr < 1e-6) return std::nullopt;  // an antenna (image) on the edge line
  // Keller: equal angles with the edge, i.e. the point where the unfolded
  // straight line crosses the edge.
  const double zq = (zt * rr + zr * rt) / (rt + rr);
  if (zq < 0 || zq > len) return std::nullopt;
  const Vec3 q = edge.a + zq * edge.e;
  // The reflection point on the unfolded line from image `img` to `x` (the
  // real end's side of the plane), on its face (the sphere first: most
  // combinations fail there).
  auto reflection_point = [&](const FaceRef& f, const Plane& pl, const Vec3& img, const Vec3& x, Vec3& point) {
    const double di = dot(pl.normal, img) - pl.offset, dx = dot(pl.normal, x) - pl.offset;
    if (!(di * dx < 0)) return false;
    point = img + (di / (di - dx)) * (x - img);
    const auto sphere = scene.face_sphere(f);
    const double tol = 2 * scene.slack(point, 0) + 2 * scene.flatness(f);
    const Vec3 w = point - sphere.centre;
    return dot(w, w) <= (sphere.radius + tol) * (sphere.radius + tol) && scene.face_contains(f, point, tol);
  };
  Vec3 p_before{0, 0, 0}, p_after{0, 0, 0};
  if (before && !reflection_point(*before, pa, tx, q, p_before)) return std::nullopt;
  if (after && !reflection_point(*after, pb, rx, q, p_after)) return std::nullopt;
  const double sp = norm(q - tx), sd = norm(rx - q);
  const Vec3 s_in = (1.0 / sp) * (q - tx), s_out = (1.0 / sd) * (rx - q);
  const double sin_b = norm(cross(edge.e, s_in));
  if (sin_b < 1e-6) return std::nullopt;  // grazing along the edge
  // A leg from or to a reflection point, clear of all but its face and,
  // at the edge point, the edge's faces (occlusion ignores two faces, so
  // with two edge faces each is ignored in turn: a real blocker shows in
  // both queries).
  auto reflected_leg_clear = [&](const FaceRef& f, const Vec3& a, const Vec3& b, bool at_edge) {
    const double l = norm(b - a);
    const Vec3 dir = (1.0 / l) * (b - a);
    const double t0 = scene.slack(a, 0) * 0.1, t1 = l - scene.slack(a, l) * 0.1;
    if (t1 <= t0) return false;
    if (rays) ++*rays;
    if (!scene.occluded(a, dir, t0, t1, &f, at_edge ? &edge.face0 : nullptr)) return true;
    if (!at_edge || edge.face_n == edge.face0) return false;
    if (rays) ++*rays;
    return !scene.occluded(a, dir, t0, t1, &f, &edge.face_n);
  };
  auto legs_clear = [&] {
    if (before && (!reflected_leg_clear(*before, from.position, p_before, false) ||
                   !reflected_leg_clear(*before, q, p_before, true)))
      return false;
    if (after &&
        (!reflected_leg_clear(*after, p_after, to.position, false) || !reflected_leg_clear(*after, q, p_after, true)))
      return false;
    if (!before && !leg_clear(scene, edge, from.position, s_in, sp, rays)) return false;
    if (!after && !leg_clear(scene, edge, q, s_out, sd, rays)) return false;
    return true;
  };
  // With a power floor, a bound on the field comes first (below): it does
  // not depend on the legs, and most weak candidates then need no ray.
  if (!(min_power > 0) && !legs_clear()) return std::nullopt;
  // Both ends (images) outside the wedge (the callers' edge lists hold
  // that already; here the angles are needed for the coefficients).
  const double phi_i = edge_angle(edge, vt), phi_d = edge_angle(edge, vr);
  const double ext = edge.n * kPi;
  if (phi_i > ext || phi_d > ext) return std::nullopt;

  const double lambda = em.wavelength();
  const double k = 2 * kPi / lambda;
  const double beta0 = std::acos(std::clamp(dot(edge.e, s_in), -1.0, 1.0));
  const double L = sd * sp * sin_b * sin_b / (sd + sp);
  const double length = sp + sd;
  // The real first and last legs' directions.
  const Vec3 d_first = before ? normalize(p_before - from.position) : s_in;
  const Vec3 d_last = after ? normalize(to.position - p_after) : s_out;
  const Vec3 e_tx = antenna_field(em.radio().antenna, d_first, from.forward);
  const Vec3 f_rx = antenna_field(em.radio().antenna, -1.0 * d_last, to.forward);
  // Under a floor, a bound first (|field| <= max |D| |e_tx| |f_rx|: the
  // edge-fixed bases are orthonormal and every reflection coefficient is
  // at most 1): on the ring road's 60 cars it stops 55 % of the vehicle
  // edges' candidates, before their rays and coefficients. Of the rest most
  // are blocked: the legs before the field.
  if (min_power > 0) {
    const double bound = (lambda / (4 * kPi)) * utd_wedge_bound(edge.n, phi_i, phi_d, beta0, L, k) * norm(e_tx) *
                         norm(f_rx) / std::sqrt(sp * sd * length);
    if (bound * bound < min_power || !legs_clear()) return std::nullopt;
  }
  // Rough faces reflect sqrt(1 - S^2) of the smooth field, in the UTD terms
  // too, so the total stays continuous across reflection boundaries.
  const auto D = utd_wedge(edge.n, phi_i, phi_d, beta0, L, k, &em.material(edge.material0),
                           &em.material(edge.material_n), em.specular_keep(edge.material0),
                           em.specular_keep(edge.material_n));
  // Edge-fixed polarisation bases (Kouyoumjian and Pathak).
  const Vec3 phi_in = -1.0 * normalize(cross(edge.e, s_in));
  const Vec3 beta_in = cross(s_in, phi_in);
  const Vec3 phi_out = normalize(cross(edge.e, s_out));
  const Vec3 beta_out = cross(s_out, phi_out);
  // A reflection of field e travelling along k_in on face f (plane pl).
  auto reflect = [&](const CVec3& e, const Vec3& k_in, const FaceRef& f, const Plane& pl) {
    const auto mat = scene.material(f);
    return reflect_field(e, k_in, pl.normal, em.reflection(mat, std::fabs(dot(k_in, pl.normal))),
                         em.specular_keep(mat));
  };
  cdouble field;
  if (!before && !after) {
    field = -(D.soft * dot(e_tx, beta_in) * dot(f_rx, beta_out) + D.hard * dot(e_tx, phi_in) * dot(f_rx, phi_out));
  } else {
    CVec3 e_in = cvec(e_tx);
    if (before) e_in = reflect(e_in, d_first, *before, pa);
    // The diffracted field leaving the edge along s_out.
    CVec3 e_out = combine(-D.soft * cdot(e_in, beta_in), beta_out, -D.hard * cdot(e_in, phi_in), phi_out);
    if (after) e_out = reflect(e_out, s_out, *after, pb);
    field = cdot(e_out, f_rx);
  }
  Path path;
  path.tau_s = length / kSpeedOfLight;
  const double phase = -2 * kPi * std::fmod(length / lambda, 1.0);
  path.a = (lambda / (4 * kPi)) / std::sqrt(sp * sd * length) * field * std::polar(1.0, phase);
  if (min_power > 0 && std::norm(path.a) < min_power) return std::nullopt;
  path.theta_t = zenith(d_first);
  path.phi_t = azimuth(d_first);
  path.theta_r = zenith(-1.0 * d_last);
  path.phi_r = azimuth(-1.0 * d_last);
  double rate = dot(d_first, -1.0 * from.velocity) + dot(d_last, to.velocity);
  if (edge.face0.instance > 0) rate += dot(s_in - s_out, scene.velocity(edge.face0));  // a vehicle's edge moves
  path.doppler_hz = -rate / lambda;
  if (before)
    path.interactions.push_back(
        Interaction{InteractionType::specular, scene.object(*before), scene.material(*before), p_before});
  path.interactions.push_back(Interaction{InteractionType::diffraction, edge.object, edge.material0, q});
  if (after)
    path.interactions.push_back(
        Interaction{InteractionType::specular, scene.object(*after), scene.material(*after), p_after});
  return path;
}

namespace {

// Diffuse contributions of one source's rays, binned per receiver,
// scattering object (a building, the ground, a vehicle) and delay bin of
// 1 / bandwidth: contributions the system cannot resolve in delay, from one
// object (so from one direction, roughly), become one path. Sums run in a
// fixed order (rays within a chunk, chunks in index order), so the result
// does not depend on the thread count.
struct DiffuseKey {
  std::uint32_t rx = 0;
  std::uint32_t object = 0;
  std::int64_t bin = 0;
  // A contribution to the pair (rx, source) gathered by the higher end's
  // rays (first order, both ends' estimator): rx is the pair's lower end.
  bool reverse = false;
  auto operator<=>(const DiffuseKey&) const = default;
};
struct DiffuseKeyHash {
  std::size_t operator()(const DiffuseKey& k) const {
    return (k.rx * 0x9E3779B97F4A7C15ull) ^ (std::size_t(k.object) * 0xC2B2AE3D27D4EB4Full) ^
           static_cast<std::size_t>(k.bin) * 0x100000001B3ull ^ static_cast<std::size_t>(k.reverse);
  }
};
struct DiffuseAcc {
  double power = 0;          // sum of |a|^2
  double tau = 0;            // power-weighted sums from here on
  Vec3 point{0, 0, 0};       // scattering point
  Vec3 departure{0, 0, 0};   // ray direction at the source
  Vec3 arrival{0, 0, 0};     // from rx towards the scattering point
  double doppler = 0;
  // The strongest single contribution's chain (earlier reflections, then
  // the scattering face) names the path's interactions.
  double peak = 0;
  int n = 0;
  std::array<FaceRef, kMaxDepth + 1> faces{};
  std::array<Vec3, kMaxDepth> prefix{};
  // The chain runs the other way (the scattering first, then the
  // reflections in reverse order): gathered by the pair's higher end.
  bool scatter_first = false;
  void add(const DiffuseAcc& o) {
    power += o.power;
    tau += o.tau;
    point = point + o.point;
    departure = departure + o.departure;
    arrival = arrival + o.arrival;
    doppler += o.doppler;
    if (o.peak > peak) {
      peak = o.peak;
      n = o.n;
      faces = o.faces;
      prefix = o.prefix;
      scatter_first = o.scatter_first;
    }
  }
};
using DiffuseBins = std::vector<std::pair<DiffuseKey, DiffuseAcc>>;

// What a source needs to scatter towards its receivers.
struct DiffuseTargets {
  std::vector<std::uint32_t> rx;  // receivers j > src of requested, in-range pairs
  // Both ends' estimator (TracerConfig::diffuse_both_ends): the lower ends
  // j < src of requested pairs. src's rays sample their first-order
  // scattering too (the two ends' samples combined by weights), and alone
  // the scattering that comes before reflections or slabs (j -> x -> ...
  // -> src: the reverse of what src's rays reach after bouncing).
  std::vector<std::uint32_t> rev;
  bool both_ends = false;
  // Whether the rays gather first-order scattering too (hybrid: the tiles
  // integrate it, the rays only what follows or precedes reflections and
  // slabs).
  bool first_order = true;
  double bin_s = 1e-7;  // delay bin width
  // Samples below this power (|a|^2) play Russian roulette (0: none).
  double roulette = 0;
  // Per node, the static faces one convex face hides whole from it
  // (hidden_by_convex_face; a bitset over the static faces, empty: none
  // known): no shadow ray from such a face to that node can be clear.
  const std::vector<std::vector<std::uint64_t>>* hidden = nullptr;
  bool hides(std::uint32_t node, const FaceRef& face) const {
    if (!hidden || face.instance != 0) return false;
    const auto& bits = (*hidden)[node];
    return !bits.empty() && ((bits[face.face >> 6] >> (face.face & 63)) & 1);
  }
};

// The roulette's threshold for `cfg` (TracerConfig::diffuse_roulette_db).
double roulette_power(const TracerConfig& cfg, const RadioConfig& radio) {
  if (cfg.diffuse_roulette_db >= 300) return 0;
  return std::pow(10.0, (radio.sensitivity_dbm - radio.tx_power_dbm - cfg.diffuse_roulette_db) / 10);
}

// A uniform number in [0, 1) from a sample's identity (splitmix64's
// finaliser over the mixed fields): the roulette gives the same answer
// whatever the thread count or the order the samples run in.
inline double sample_uniform(std::uint64_t a, std::uint64_t b, std::uint64_t c) {
  std::uint64_t z = a * 0x9E3779B97F4A7C15ull ^ (b + 0x632BE59BD9B4E019ull) * 0xBF58476D1CE4E5B9ull ^
                    (c + 0x8CB92BA72F3D8DD7ull) * 0x94D049BB133111EBull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

// Russian roulette for a sample whose power is at most `bound`: the weight
// to multiply its power by when it is kept (1 above the threshold), or 0
// when it is dropped (then its shadow ray is never traced).
inline double roulette_weight(double bound, double threshold, double u) {
  if (!(bound < threshold)) return 1.0;
  const double q = bound / threshold;
  return u < q ? 1.0 / q : 0.0;
}

// Balance-heuristic weight of the samples of end a for first-order
// scattering at a point seen from a and b: each end's rays hit the surface
// with area density (rays / 4 pi) cos / distance^2, so the weight is
// q_a / (q_a + q_b), q = cos / distance^2. Both ends' weighted sums add up
// to one unbiased estimate whose samples come mostly from the nearer end.
inline double balance_weight(double cos_a, double dist_a, double cos_b, double dist_b) {
  const double qa = cos_a / (dist_a * dist_a), qb = cos_b / (dist_b * dist_b);
  return qa + qb > 0 ? qa / (qa + qb) : 0.0;
}

// Lattice rays per shooting task: sums over a source's rays run chunk by
// chunk in index order (trace_pairs and diffuse_power alike), so they do not
// depend on the thread count and both give the same numbers.
constexpr std::size_t kShootChunk = 256;

// Shoot-and-bounce from node `src`: face sequences that pass near other nodes
// and, with diffuse scattering on, the scattered power at each hit.
void shoot_from(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& cfg,
                const std::vector<Node>& nodes, std::uint32_t src, const std::vector<Vec3>& lattice,
                std::size_t begin, std::size_t end, std::vector<CandidateKey>& out, std::uint64_t& rays,
                const DiffuseTargets* diffuse, DiffuseBins* diffuse_out, const ImageFaces* beam_faces = nullptr,
                std::vector<BeamVehicle>* beams = nullptr, std::vector<BeamPair>* beam_pairs = nullptr) {
  const double spacing = std::sqrt(4 * kPi / static_cast<double>(lattice.size())) * cfg.reception_radius_factor;
  const bool scatter = diffuse && (!diffuse->rx.empty() || !diffuse->rev.empty());
  const double d_omega = 4 * kPi / static_cast<double>(lattice.size());
  const double lambda = em.wavelength();
  const double rx_peak_gain = peak_gain(em.radio().antenna.pattern);
  // A ray's reflections so far, as links into the ray's chain (the states
  // of one ray share their prefixes): copying whole face and point arrays
  // of kMaxDepth entries per state cost more than the rest of the loop.
  struct Link {
    FaceRef face;
    Vec3 point;
    std::int32_t parent;
  };
  std::vector<Link> chain;
  struct State {
    Vec3 o, d;
    double len;
    int transmissions;
    double loss_db;
    bool has_leaving;
    FaceRef leaving;
    int n;               // reflections so far
    std::int32_t last;   // the last one's link (-1: none)
    // Diffuse bookkeeping: the ray tube's field (transmit pattern times
    // every coefficient so far), dL/dt of the legs so far, the velocity of
    // the last interaction point.
    CVec3 field;
    double dl_dt;
    Vec3 v_prev;
  };
  // The faces of st's reflections in order into out[0, st.n), their points
  // into points (when given).
  auto unwind = [&](const State& st, FaceRef* out, Vec3* points) {
    std::int32_t l = st.last;
    for (int k = st.n - 1; k >= 0; --k, l = chain[l].parent) {
      out[k] = chain[l].face;
      if (points) points[k] = chain[l].point;
    }
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
  std::unordered_map<DiffuseKey, std::size_t, DiffuseKeyHash> bin_index;
  for (std::size_t r = begin; r < end; ++r) {
    chain.clear();
    std::uint64_t hit_no = 0;  // the ray's hits so far: the roulette's sample identity
    State first{nodes[src].position, lattice[r], 0, 0, 0, false, {}, 0, -1, {}, 0, nodes[src].velocity};
    if (scatter) first.field = cvec(antenna_field(em.radio().antenna, lattice[r], nodes[src].forward));
    stack.push_back(first);
    while (!stack.empty()) {
      State st = stack.back();
      stack.pop_back();
      Hit hit;
      const bool got = scene.closest_hit(st.o, st.d, st.has_leaving ? 0 : 1e-4, std::numeric_limits<double>::infinity(),
                                         hit, st.has_leaving ? &st.leaving : nullptr);
      ++rays;
      const double tseg = got ? hit.t : std::numeric_limits<double>::infinity();
      if (st.n > 0) {
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
          key.faces.resize(st.n);
          unwind(st, key.faces.data(), nullptr);
          if (seen.insert(key).second) out.push_back(key);
        }
      }
      // Whether this segment passes within `radius` of `centre`, widened by
      // twice the ray spacing at that distance (what it may miss between
      // rays: a vehicle, a small face).
      const double seg_end = std::min(tseg, 1e30);
      auto passes = [&](const Vec3& centre, double radius) {
        const Vec3 c = centre - st.o;
        const double t = std::clamp(dot(c, st.d), 0.0, seg_end);
        const Vec3 q = c - t * st.d;
        const double reach = radius + 2 * spacing * (st.len + t);
        return dot(q, q) <= reach * reach;
      };
      // After one reflection on a static face: the vehicles this ray passes
      // are in that face's beam (BeamVehicle).
      if (beams && st.n == 1 && chain[st.last].face.instance == 0 &&
          !std::binary_search(beam_faces->ground.begin(), beam_faces->ground.end(), chain[st.last].face.face)) {
        const auto& spheres = beam_faces->vehicle_spheres;
        for (std::uint32_t v = 0; v < spheres.size(); ++v)
          if (passes(spheres[v].centre, spheres[v].radius)) beams->push_back({chain[st.last].face.face, v});
      }
      // After two reflections, the first on a static face: their pair's beam
      // is lit (BeamPair); after one, so is the pair with a small static face
      // the ray passes.
      if (beam_pairs && st.n == 2 && chain[chain[st.last].parent].face.instance == 0) {
        // The second face may be a vehicle's (a wall's echo off a car onto a
        // wall): its index among ImageFaces' faces.
        const FaceRef& f2 = chain[st.last].face;
        beam_pairs->push_back({chain[chain[st.last].parent].face.face,
                               f2.instance == 0 ? f2.face : beam_faces->vehicle_begin[f2.instance - 1] + f2.face});
      }
      if (beam_pairs && st.n == 1 && chain[st.last].face.instance == 0) {
        const std::uint32_t f1 = chain[st.last].face.face;
        for (const std::uint32_t f2 : beam_faces->small)
          if (f2 != f1 && passes(beam_faces->spheres[f2].centre, beam_faces->spheres[f2].radius + beam_faces->tol[f2]))
            beam_pairs->push_back({f1, f2});
      }
      if (!got) continue;
      ++hit_no;
      const Vec3 p = st.o + hit.t * st.d;
      const auto mat = scene.material(hit.face);
      const RadioMaterial& material = em.material(mat);
      const double s_coef = scatter ? material.scattering.s : 0.0;  // scatter implies em's rough surfaces
      const bool can_scatter =
          s_coef > 0 && st.n < cfg.max_depth && (diffuse->first_order || st.n > 0 || st.transmissions > 0);
      const bool can_reflect = cfg.specular && st.n < cfg.max_depth;
      const bool can_transmit = cfg.refraction && st.transmissions < cfg.max_transmissions && !em.opaque(mat);
      Plane plane;
      if (scatter || can_reflect) plane = scene.plane(hit.face);
      const Vec3 k_out = st.d - (2 * dot(st.d, plane.normal)) * plane.normal;
      // With diffuse on, the ray tube carries its field: the slab
      // coefficients here, the field a smooth surface would reflect, and
      // dL/dt up to this hit.
      SlabCoefficients coef{};
      Vec3 es{0, 0, 0}, ep_in{0, 0, 0}, v_surf{0, 0, 0};
      CVec3 e_ref{};
      double dl_in = 0;
      // Not where nothing downstream can scatter any more (the last bounce
      // off a smooth, opaque face): the slab coefficients are the costly part.
      const bool field_needed = can_scatter || can_transmit || (can_reflect && st.n + 1 < cfg.max_depth);
      if (scatter && field_needed) {
        const double cos_in = std::fabs(dot(st.d, plane.normal));
        // (The transmission only where the ray goes on through the slab.)
        coef = can_transmit ? em.coefficients(mat, cos_in) : SlabCoefficients{em.reflection(mat, cos_in), {}};
        es = te_basis(st.d, plane.normal);
        ep_in = cross(es, st.d);
        e_ref = combine(coef.r.te * cdot(st.field, es), es, coef.r.tm * cdot(st.field, ep_in), cross(es, k_out));
        v_surf = scene.velocity(hit.face);
        dl_in = st.dl_dt + dot(st.d, v_surf - st.v_prev);
      }
      if (can_scatter) {
        // S^2 of the smooth reflection's power is scattered, (1 - K_x) in
        // its polarisation and K_x across it.
        const double len_in = st.len + hit.t;
        const Scattering& sc = material.scattering;
        const ScatteringLobeAt lobe(sc, st.d, plane.normal);
        // First order, nothing crossed: the other end's rays sample these
        // points too (both ends' estimator).
        const bool mis = diffuse->both_ends && st.n == 0 && st.transmissions == 0;
        const double cos_in = std::fabs(dot(st.d, plane.normal));
        // The side the ray arrives from (the lobe's front, ScatteringLobeAt):
        // a node clearly behind the surface gets nothing, and costs no
        // square root or lobe (a third of the evaluations on the bench
        // scenes). Within rounding of the plane it takes the full test.
        const Vec3 front = dot(st.d, plane.normal) < 0 ? plane.normal : -1.0 * plane.normal;
        auto behind = [&](const Vec3& w) {
          return dot(w, front) < -1e-9 * (std::fabs(w[0]) + std::fabs(w[1]) + std::fabs(w[2]));
        };
        const std::uint32_t hit_object = scene.object(hit.face);
        const auto record = [&](std::uint32_t j, bool reverse, double power, double tau, const Vec3& departure,
                                const Vec3& arrival, double dl, bool scatter_first = false) {
          DiffuseKey dk;
          dk.rx = j;
          dk.object = hit_object;
          dk.bin = static_cast<std::int64_t>(std::floor(tau / diffuse->bin_s));
          dk.reverse = reverse;
          auto [it, fresh] = bin_index.try_emplace(dk, diffuse_out->size());
          if (fresh) diffuse_out->emplace_back(dk, DiffuseAcc{});
          // Summed in place (DiffuseAcc::add's terms and order); the chain
          // is copied only when this sample is the bin's new peak.
          DiffuseAcc& acc = (*diffuse_out)[it->second].second;
          acc.power += power;
          acc.tau += power * tau;
          acc.point = acc.point + power * p;
          acc.departure = acc.departure + power * departure;
          acc.arrival = acc.arrival + power * arrival;
          acc.doppler += power * (-dl / lambda);
          if (power > acc.peak) {
            acc.peak = power;
            acc.n = st.n + 1;
            acc.faces.fill(FaceRef{});
            acc.prefix.fill(Vec3{0, 0, 0});
            unwind(st, acc.faces.data(), acc.prefix.data());
            acc.faces[st.n] = hit.face;
            acc.scatter_first = scatter_first;
          }
        };
        // Received power from the reflected field e_in (the field a smooth
        // surface would reflect) scattered towards ks, at distance rs, by a
        // tube of d_omega, into the receive pattern looking along -ks.
        const auto scattered = [&](const CVec3& e_in, const Vec3& ks, double f, double rs, const Vec3& rx_forward) {
          const cdouble along = cdot(e_in, ks);
          const CVec3 et{e_in[0] - along * ks[0], e_in[1] - along * ks[1], e_in[2] - along * ks[2]};
          const double et2 = std::norm(et[0]) + std::norm(et[1]) + std::norm(et[2]);
          const double er2 = std::norm(e_in[0]) + std::norm(e_in[1]) + std::norm(e_in[2]);
          if (!(et2 > 1e-30)) return 0.0;
          const Vec3 fr = antenna_field(em.radio().antenna, -1.0 * ks, rx_forward);
          const CVec3 ex{ks[1] * et[2] - ks[2] * et[1], ks[2] * et[0] - ks[0] * et[2], ks[0] * et[1] - ks[1] * et[0]};
          const double co = std::norm(cdot(et, fr)), cross_pol = std::norm(cdot(ex, fr));
          const double g_eff = ((1 - sc.xpd) * co + sc.xpd * cross_pol) * er2 / et2;
          return s_coef * s_coef * f * g_eff * lambda * lambda * d_omega / (16 * kPi * kPi * rs * rs);
        };
        // The roulette's bound on a sample's power, per lobe value, incident
        // |E|^2 and 1 / distance^2: scattered()'s factors with the received
        // part of the field at most its whole and the receive pattern at its
        // peak gain (|R| <= 1 on a passive surface bounds the incident field
        // of the samples lit from the other end).
        const double bound_per_gain =
            s_coef * s_coef * rx_peak_gain * lambda * lambda * d_omega / (16 * kPi * kPi);
        const double e_ref2 = diffuse->roulette > 0
                                  ? std::norm(e_ref[0]) + std::norm(e_ref[1]) + std::norm(e_ref[2])
                                  : 0.0;
        // Towards node j along ks: this ray's chain, then the scattering.
        const auto gather = [&](std::uint32_t j, bool reverse) {
          const Vec3 w = nodes[j].position - p;
          if (behind(w)) return;
          const double rs = norm(w);
          if (rs < 1e-6) return;
          const Vec3 ks = (1.0 / rs) * w;
          const double f = lobe(ks);
          if (!(f > 0)) return;
          const double balance = mis ? balance_weight(cos_in, len_in, std::fabs(dot(ks, plane.normal)), rs) : 1.0;
          double weight = 1;
          if (diffuse->roulette > 0) {
            weight = roulette_weight(bound_per_gain * f * e_ref2 / (rs * rs) * balance, diffuse->roulette,
                                     sample_uniform(std::uint64_t{src} << 32 | r, hit_no, std::uint64_t{j} << 1 | reverse));
            if (weight == 0) return;
          }
          if (diffuse->hides(j, hit.face)) return;  // its shadow ray would be blocked
          ++rays;
          if (scene.occluded(p, ks, 0, rs - scene.slack(nodes[j].position, 0) * 0.1, &hit.face)) return;
          const double power = scattered(e_ref, ks, f, rs, nodes[j].forward) * balance * weight;
          if (!(power > 0)) return;
          const double dl = dl_in + dot(ks, nodes[j].velocity - v_surf), tau = (len_in + rs) / kSpeedOfLight;
          if (!reverse) {
            record(j, false, power, tau, lattice[r], -1.0 * ks, dl);
          } else {
            // The pair (j, src) read from j: scattered first, then this
            // ray's reflections back to src (evaluated along this ray's
            // direction; equal for a reciprocal lobe).
            record(j, true, power, tau, -1.0 * ks, lattice[r], dl, true);
          }
        };
        for (std::uint32_t j : diffuse->rx) gather(j, false);
        if (diffuse->both_ends && !mis)
          for (std::uint32_t j : diffuse->rev) gather(j, true);
        // The same first-order scattering for the pairs (j, src), j < src,
        // evaluated as from j to src (each pair's field runs from its lower
        // end): the point is lit by j, and seen by src along this ray.
        for (std::size_t q = 0; mis && q < diffuse->rev.size(); ++q) {
          const std::uint32_t j = diffuse->rev[q];
          const Vec3 w = p - nodes[j].position;
          // Lit from j's side, seen back along this ray: j must be in front too.
          if (behind(-1.0 * w)) continue;
          const double la = norm(w);
          if (la < 1e-6) continue;
          const Vec3 ki = (1.0 / la) * w;
          const Vec3 ks = -1.0 * st.d;
          const double f = ScatteringLobeAt(sc, ki, plane.normal)(ks);
          if (!(f > 0)) continue;
          const double cos_a = std::fabs(dot(ki, plane.normal));
          const double balance = balance_weight(cos_a, la, cos_in, hit.t);
          const CVec3 e_a = cvec(antenna_field(em.radio().antenna, ki, nodes[j].forward));
          // The roulette's bound before the slab coefficients (the costly
          // part): |R| <= 1 on a passive surface, and the received part of
          // the scattered field is at most its whole (scattered()'s terms).
          double weight = 1;
          if (diffuse->roulette > 0) {
            const double e2 = std::norm(e_a[0]) + std::norm(e_a[1]) + std::norm(e_a[2]);
            weight = roulette_weight(bound_per_gain * f * e2 / (hit.t * hit.t) * balance, diffuse->roulette,
                                     sample_uniform(std::uint64_t{src} << 32 | r, hit_no, std::uint64_t{j} << 1 | 1));
            if (weight == 0) continue;
          }
          if (diffuse->hides(j, hit.face)) continue;
          ++rays;
          if (scene.occluded(p, -1.0 * ki, 0, la - scene.slack(nodes[j].position, 0) * 0.1, &hit.face)) continue;
          const TeTm ra = em.reflection(mat, cos_a);
          const Vec3 es_a = te_basis(ki, plane.normal);
          const Vec3 ko_a = ki - (2 * dot(ki, plane.normal)) * plane.normal;
          const CVec3 e_ref_a =
              combine(ra.te * cdot(e_a, es_a), es_a, ra.tm * cdot(e_a, cross(es_a, ki)), cross(es_a, ko_a));
          double power = scattered(e_ref_a, ks, f, hit.t, nodes[src].forward);
          power *= balance * weight;
          if (!(power > 0)) continue;
          record(j, true, power, (la + hit.t) / kSpeedOfLight, ki, st.d,
                 dot(ki, v_surf - nodes[j].velocity) + dot(ks, nodes[src].velocity - v_surf));
        }
      }
      if (can_transmit) {
        const double loss = st.loss_db + em.normal_transmission_loss_db(mat);
        if (loss <= cfg.sbr_transmission_loss_db) {
          State next = st;
          next.o = p;
          next.len = st.len + hit.t;
          next.transmissions = st.transmissions + 1;
          next.loss_db = loss;
          next.has_leaving = true;
          next.leaving = hit.face;
          if (scatter) {
            next.field = combine(coef.t.te * cdot(st.field, es), es, coef.t.tm * cdot(st.field, ep_in), ep_in);
            next.dl_dt = dl_in;
            next.v_prev = v_surf;
          }
          stack.push_back(next);
        }
      }
      if (can_reflect) {
        State next = st;
        next.o = p;
        next.d = k_out;
        next.len = st.len + hit.t;
        next.has_leaving = true;
        next.leaving = hit.face;
        chain.push_back(Link{hit.face, p, st.last});
        next.last = static_cast<std::int32_t>(chain.size() - 1);
        ++next.n;
        if (scatter) {
          const double keep = em.specular_keep(mat);
          next.field = {keep * e_ref[0], keep * e_ref[1], keep * e_ref[2]};
          next.dl_dt = dl_in;
          next.v_prev = v_surf;
        }
        stack.push_back(next);
      }
    }
  }
  if (beams) {
    std::sort(beams->begin(), beams->end());
    beams->erase(std::unique(beams->begin(), beams->end()), beams->end());
  }
  if (beam_pairs) {
    std::sort(beam_pairs->begin(), beam_pairs->end());
    beam_pairs->erase(std::unique(beam_pairs->begin(), beam_pairs->end()), beam_pairs->end());
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

std::vector<double> diffuse_power(const TraceScene& scene, const std::vector<Node>& nodes, std::uint32_t src,
                                  const std::vector<std::uint32_t>& receivers, const TracerConfig& cfg,
                                  const RadioConfig& radio) {
  validate(cfg, radio);
  std::vector<double> out(receivers.size(), 0.0);
  if (!cfg.diffuse || cfg.max_depth <= 0 || cfg.diffuse_integration == DiffuseIntegration::tiles) return out;
  if (src >= nodes.size()) throw std::invalid_argument("diffuse_power: source index out of range");
  const Electromagnetics em(scene.material_names(), radio, cfg.materials, cfg.diffuse);
  const double range = max_range_m(cfg, radio);
  DiffuseTargets targets;
  targets.bin_s = 1.0 / radio.bandwidth_hz;
  targets.roulette = roulette_power(cfg, radio);
  std::unordered_map<std::uint32_t, std::size_t> slot;
  for (std::size_t k = 0; k < receivers.size(); ++k) {
    const auto r = receivers[k];
    if (r >= nodes.size()) throw std::invalid_argument("diffuse_power: receiver index out of range");
    if (r == src || norm(nodes[r].position - nodes[src].position) > range) continue;
    if (slot.emplace(r, k).second) targets.rx.push_back(r);
  }
  std::sort(targets.rx.begin(), targets.rx.end());
  if (targets.rx.empty()) return out;
  // The same rays, chunks and merge order as trace_pairs' shoot stage.
  TracerConfig local = cfg;
  local.specular = cfg.specular && cfg.candidates != CandidateSearch::exhaustive;
  const auto lattice = fibonacci_sphere(cfg.rays_per_source);
  const std::size_t chunk = kShootChunk, chunks = (lattice.size() + chunk - 1) / chunk;
  std::vector<DiffuseBins> bins(chunks);
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    std::vector<CandidateKey> found;
    std::uint64_t rays = 0;
    shoot_from(scene, em, local, nodes, src, lattice, c * chunk, std::min(lattice.size(), (c + 1) * chunk), found, rays,
               &targets, &bins[c]);
  });
  for (const auto& b : bins)
    for (const auto& [dk, acc] : b) out[slot.at(dk.rx)] += acc.power;
  return out;
}

Snapshot trace_snapshot(const TraceScene& scene, const std::vector<Node>& nodes, const TracerConfig& cfg,
                        const RadioConfig& radio) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  const auto n = static_cast<std::uint32_t>(nodes.size());
  for (std::uint32_t i = 0; i < n; ++i)
    for (std::uint32_t j = i + 1; j < n; ++j) pairs.emplace_back(i, j);
  return trace_pairs(scene, nodes, pairs, cfg, radio);
}

namespace {

// Edges each node can see the outside of, within `range` of it, and that
// no single convex face hides whole from it (hidden_by_convex_face: then
// every leg between the node and the edge is blocked): the cheap half of
// the diffraction test (a pair needs an edge both its ends see).
std::vector<std::vector<std::uint32_t>> edges_seen(const TraceScene& scene, const ImageFaces& faces,
                                                   const std::vector<Node>& nodes,
                                                   const std::vector<unsigned char>& wanted, double range) {
  const auto& edges = scene.edges();
  std::vector<std::vector<std::uint32_t>> seen(nodes.size());
  tbb::parallel_for(std::size_t{0}, nodes.size(), [&](std::size_t i) {
    if (!wanted[i]) return;
    const Vec3 p = nodes[i].position;
    for (std::uint32_t k = 0; k < edges.size(); ++k) {
      const Edge& e = edges[k];
      const Vec3 w = p - e.a;
      const double z = std::clamp(dot(w, e.e), 0.0, norm(e.b - e.a));
      const Vec3 v = w - dot(w, e.e) * e.e;
      if (norm(p - (e.a + z * e.e)) > range) continue;
      if (edge_angle(e, v) > e.n * kPi) continue;
      const Vec3 ends[2] = {e.a, e.b};
      if (hidden_by_convex_face(scene, faces, p, ends, 2, nullptr, 0)) continue;
      seen[i].push_back(k);
    }
  });
  return seen;
}

}  // namespace

Snapshot trace_pairs(const TraceScene& scene, const std::vector<Node>& nodes,
                     const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs, const TracerConfig& cfg,
                     const RadioConfig& radio) {
  validate(cfg, radio);
  for (const auto& n : nodes) {
    for (double c : n.position)
      if (!std::isfinite(c)) throw std::invalid_argument("node " + n.id + ": position is not finite");
    for (double c : n.velocity)
      if (!std::isfinite(c)) throw std::invalid_argument("node " + n.id + ": velocity is not finite");
    for (double c : n.forward)
      if (!std::isfinite(c)) throw std::invalid_argument("node " + n.id + ": orientation is not finite");
  }
  const Electromagnetics em(scene.material_names(), radio, cfg.materials, cfg.diffuse);
  const auto n = static_cast<std::uint32_t>(nodes.size());
  const double range = max_range_m(cfg, radio);
  Snapshot snap;
  // Which pair slot each (i, j) feeds; sources shoot only when they have a
  // pair to serve. A pair's candidates come from its own two ends, so a pair
  // traced alone gets exactly the paths it gets in a full snapshot.
  std::unordered_map<std::uint64_t, std::size_t> slot;
  slot.reserve(pairs.size());
  std::vector<std::uint32_t> sources;
  std::vector<unsigned char> is_source(n, 0);
  std::vector<unsigned char> in_range(pairs.size(), 1);
  // Diffuse scattering: gathered from the shoot-and-bounce rays' hits
  // (default), or integrated over surface tiles.
  const bool ray_diffuse =
      cfg.diffuse && cfg.max_depth > 0 && cfg.diffuse_integration != DiffuseIntegration::tiles;
  const bool tile_diffuse =
      cfg.diffuse && cfg.max_depth > 0 && cfg.diffuse_integration != DiffuseIntegration::rays;
  std::vector<DiffuseTargets> targets(ray_diffuse ? n : 0);
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    auto [i, j] = pairs[p];
    if (i >= j || j >= n) throw std::invalid_argument("trace_pairs: pair (" + std::to_string(i) + ", " +
                                                      std::to_string(j) + ") is not i < j < node count");
    if (!slot.emplace(static_cast<std::uint64_t>(i) << 32 | j, p).second)
      throw std::invalid_argument("trace_pairs: pair (" + std::to_string(i) + ", " + std::to_string(j) + ") twice");
    if (norm(nodes[j].position - nodes[i].position) > range) {
      in_range[p] = 0;  // labelled, never traced
      continue;
    }
    // Diffuse power: the lower end's rays gather towards the higher end,
    // and with both ends on, the higher end's rays towards the lower.
    if (ray_diffuse) {
      targets[i].rx.push_back(j);
      if (cfg.diffuse_both_ends) targets[j].rev.push_back(i);
    }
    for (auto e : {i, j}) {
      if (is_source[e]) continue;
      is_source[e] = 1;
      sources.push_back(e);
    }
  }
  for (auto& t : targets) {
    std::sort(t.rx.begin(), t.rx.end());
    std::sort(t.rev.begin(), t.rev.end());
    t.both_ends = cfg.diffuse_both_ends;
    t.first_order = !tile_diffuse;
    t.bin_s = 1.0 / radio.bandwidth_hz;
    t.roulette = roulette_power(cfg, radio);
  }
  std::sort(sources.begin(), sources.end());
  std::vector<std::vector<std::vector<FaceRef>>> candidates(pairs.size());
  std::vector<std::map<DiffuseKey, DiffuseAcc>> diffuse(ray_diffuse ? pairs.size() : 0);

  std::uint64_t search_rays = 0;
  const bool image = cfg.specular && cfg.max_depth > 0 && n > 1 && cfg.candidates == CandidateSearch::image;
  const bool sbr_specular = cfg.specular && cfg.max_depth > 0 && cfg.candidates != CandidateSearch::exhaustive;
  ImageFaces faces;
  // Every in-range partner of each node (sorted).
  std::vector<std::vector<std::uint32_t>> partners(image ? n : 0);
  if (image) {
    for (std::size_t p = 0; p < pairs.size(); ++p)
      if (in_range[p]) {
        partners[pairs[p].first].push_back(pairs[p].second);
        partners[pairs[p].second].push_back(pairs[p].first);
      }
    for (auto& v : partners) std::sort(v.begin(), v.end());
    const auto t_image = std::chrono::steady_clock::now();
    std::vector<std::vector<ImageCandidate>> found(n);
    std::vector<ImageSearchStats> istats(n);
    faces = image_faces(scene);
    tbb::parallel_for(std::uint32_t{0}, n, [&](std::uint32_t i) {
      if (partners[i].empty()) return;
      image_candidates(scene, faces, nodes, i, partners[i], std::min(cfg.max_depth, 3), found[i], &istats[i],
                       cfg.vehicle_multi_bounce, cfg.ground_order3);
    });
    for (const auto& st : istats) {
      snap.stats.image_sources += st.image_sources;
      snap.stats.image_tests += st.tests;
    }
    for (std::uint32_t i = 0; i < n; ++i)
      for (auto& c : found[i]) {
        if (c.rx < i) std::reverse(c.faces.begin(), c.faces.end());
        const std::uint64_t key = static_cast<std::uint64_t>(std::min(i, c.rx)) << 32 | std::max(i, c.rx);
        candidates[slot.at(key)].push_back(std::move(c.faces));
      }
    snap.stats.time.image_search = seconds_since(t_image);
  }
  if (cfg.specular && cfg.max_depth > 0 && n > 1 && cfg.candidates == CandidateSearch::exhaustive) {
    std::vector<std::vector<FaceRef>> all;
    std::vector<FaceRef> current;
    enumerate_all(scene, cfg.max_depth, current, all);
    for (std::size_t p = 0; p < pairs.size(); ++p)
      if (in_range[p]) candidates[p] = all;
  }
  std::vector<std::vector<std::uint64_t>> hidden_faces;
  if ((sbr_specular || ray_diffuse) && n > 1) {
    const auto t_shoot = std::chrono::steady_clock::now();
    // The rough static faces one convex face hides whole from each node: the
    // diffuse gathering's shadow rays from them to it are blocked, so not cast.
    if (ray_diffuse && n > 1) {
      if (faces.refs.empty()) faces = image_faces(scene);
      hidden_faces.resize(n);
      tbb::parallel_for(std::uint32_t{0}, n, [&](std::uint32_t j) {
        if (!is_source[j]) return;
        auto& bits = hidden_faces[j];
        bits.assign((faces.static_count + 63) / 64, 0);
        for (std::uint32_t f = 0; f < faces.static_count; ++f) {
          if (!(em.material(scene.material(faces.refs[f])).scattering.s > 0)) continue;
          const FaceRef self{0, f};
          if (hidden_by_convex_face(scene, faces, nodes[j].position, &faces.outline[faces.outline_begin[f]],
                                    faces.outline_begin[f + 1] - faces.outline_begin[f], &self, faces.tol[f]))
            bits[f >> 6] |= std::uint64_t{1} << (f & 63);
        }
      });
      for (auto& t : targets) t.hidden = &hidden_faces;
    }
    const auto lattice = fibonacci_sphere(cfg.rays_per_source);
    const std::size_t chunk = kShootChunk, chunks = (lattice.size() + chunk - 1) / chunk;
    struct TaskOut {
      std::vector<CandidateKey> found;
      DiffuseBins bins;
      std::vector<BeamVehicle> beams;
      std::vector<BeamPair> beam_pairs;
      std::uint64_t rays = 0;
    };
    std::vector<TaskOut> tasks(sources.size() * chunks);
    // A static face then any vehicle: the rays say which combinations can
    // exist, the image method enumerates their faces exactly.
    const bool beam_search = image && cfg.max_depth >= 2;
    std::vector<std::vector<BeamVehicle>> beams(beam_search ? n : 0);
    // A static face, then a static or vehicle face, then the third (order 3).
    const bool triple_search = beam_search && cfg.max_depth >= 3 && cfg.beam_order3;
    std::vector<std::vector<BeamPair>> beam_pairs(triple_search ? n : 0);
    tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t task) {
      const auto src = sources[task / chunks];
      const std::size_t c = task % chunks;
      TaskOut& out = tasks[task];
      TracerConfig local = cfg;
      local.specular = sbr_specular;
      shoot_from(scene, em, local, nodes, src, lattice, c * chunk, std::min(lattice.size(), (c + 1) * chunk),
                 out.found, out.rays, ray_diffuse ? &targets[src] : nullptr, &out.bins, beam_search ? &faces : nullptr,
                 beam_search ? &out.beams : nullptr, triple_search ? &out.beam_pairs : nullptr);
      if (!sbr_specular) out.found.clear();
    });
    // Merged in task order, so the sums are the same for any thread count;
    // the slot lookups run per task and the merging per pair, both in
    // parallel (a serial merge held one core idle for 20-30 ms).
    constexpr std::size_t kNoSlot = ~std::size_t{0};
    std::vector<std::vector<std::size_t>> found_slot(tasks.size()), bin_slot(tasks.size());
    tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t task) {
      const auto src = sources[task / chunks];
      auto& out = tasks[task];
      found_slot[task].assign(out.found.size(), kNoSlot);
      for (std::size_t q = 0; q < out.found.size(); ++q) {
        auto& k = out.found[q];
        // The image search already enumerated these completely.
        if (image && image_complete(scene, faces, k.faces, cfg.ground_order3 && cfg.max_depth >= 3)) continue;
        const std::uint32_t a = std::min(src, k.other), b = std::max(src, k.other);
        const auto it = slot.find(static_cast<std::uint64_t>(a) << 32 | b);
        if (it == slot.end() || !in_range[it->second]) continue;
        if (src > k.other) std::reverse(k.faces.begin(), k.faces.end());
        found_slot[task][q] = it->second;
      }
      bin_slot[task].assign(out.bins.size(), kNoSlot);
      for (std::size_t q = 0; q < out.bins.size(); ++q) {
        auto& dk = out.bins[q].first;
        // Both ends' samples of a pair's bin merge into one record.
        const std::uint32_t a = dk.reverse ? dk.rx : src, b = dk.reverse ? src : dk.rx;
        const auto it = slot.find(static_cast<std::uint64_t>(a) << 32 | b);
        if (it == slot.end()) continue;
        dk.rx = b;
        dk.reverse = false;
        bin_slot[task][q] = it->second;
      }
    });
    // Per pair, its entries in task order: (task, index) lists by counting.
    struct Entry {
      std::uint32_t task, index;
    };
    struct Grouped {
      std::vector<std::size_t> begin;  // pair p's entries: [begin[p], begin[p + 1])
      std::vector<Entry> entries;
    };
    auto group = [&](const std::vector<std::vector<std::size_t>>& slots) {
      std::vector<std::size_t> begin(pairs.size() + 1, 0);
      for (const auto& v : slots)
        for (auto sl : v)
          if (sl != kNoSlot) ++begin[sl + 1];
      for (std::size_t p = 0; p < pairs.size(); ++p) begin[p + 1] += begin[p];
      std::vector<Entry> entries(begin.back());
      std::vector<std::size_t> at(begin.begin(), begin.end() - 1);
      for (std::size_t t = 0; t < slots.size(); ++t)
        for (std::size_t q = 0; q < slots[t].size(); ++q)
          if (slots[t][q] != kNoSlot)
            entries[at[slots[t][q]]++] = Entry{static_cast<std::uint32_t>(t), static_cast<std::uint32_t>(q)};
      return Grouped{std::move(begin), std::move(entries)};
    };
    // (Named members, not structured bindings: clang before 16 cannot
    // capture those in the lambda below.)
    const Grouped found_by_pair = group(found_slot), bins_by_pair = group(bin_slot);
    tbb::parallel_for(std::size_t{0}, pairs.size(), [&](std::size_t p) {
      for (std::size_t e = found_by_pair.begin[p]; e < found_by_pair.begin[p + 1]; ++e) {
        const Entry& en = found_by_pair.entries[e];
        candidates[p].push_back(std::move(tasks[en.task].found[en.index].faces));
      }
      for (std::size_t e = bins_by_pair.begin[p]; e < bins_by_pair.begin[p + 1]; ++e) {
        const Entry& en = bins_by_pair.entries[e];
        const auto& bin = tasks[en.task].bins[en.index];
        diffuse[p][bin.first].add(bin.second);
      }
    });
    for (std::size_t task = 0; task < tasks.size(); ++task) {
      search_rays += tasks[task].rays;
      if (beam_search) {
        auto& b = beams[sources[task / chunks]];
        b.insert(b.end(), tasks[task].beams.begin(), tasks[task].beams.end());
      }
      if (triple_search) {
        auto& b = beam_pairs[sources[task / chunks]];
        b.insert(b.end(), tasks[task].beam_pairs.begin(), tasks[task].beam_pairs.end());
      }
    }
    tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t t) { tasks[t] = TaskOut{}; });
    if (beam_search) {
      const auto t_beams = std::chrono::steady_clock::now();
      std::vector<std::vector<ImageCandidate>> found(n);
      std::vector<ImageSearchStats> bstats(n);
      tbb::parallel_for(std::uint32_t{0}, n, [&](std::uint32_t i) {
        auto& b = beams[i];
        if (partners[i].empty()) return;
        small_face_beams(faces, nodes[i].position, b);
        std::sort(b.begin(), b.end());
        b.erase(std::unique(b.begin(), b.end()), b.end());
        beam_vehicle_candidates(scene, faces, nodes, i, partners[i], b, found[i], &bstats[i],
                                cfg.ground_order3 && cfg.max_depth >= 3);
        if (!triple_search) return;
        auto& bp = beam_pairs[i];
        small_face_pairs(scene, faces, nodes[i].position, bp);
        std::sort(bp.begin(), bp.end());
        bp.erase(std::unique(bp.begin(), bp.end()), bp.end());
        beam_pair_candidates(scene, faces, nodes, i, bp, partners[i], found[i], &bstats[i], cfg.ground_order3);
      });
      for (std::uint32_t i = 0; i < n; ++i) {
        snap.stats.image_sources += bstats[i].image_sources;
        snap.stats.image_tests += bstats[i].tests;
        for (auto& c : found[i]) {
          if (c.rx < i) std::reverse(c.faces.begin(), c.faces.end());
          const std::uint64_t key = static_cast<std::uint64_t>(std::min(i, c.rx)) << 32 | std::max(i, c.rx);
          candidates[slot.at(key)].push_back(std::move(c.faces));
        }
      }
      snap.stats.time.beams = seconds_since(t_beams);
      snap.stats.time.image_search += snap.stats.time.beams;
    }
    // Thread-local order varies; the sorted set does not.
    tbb::parallel_for(std::size_t{0}, candidates.size(), [&](std::size_t p) {
      auto& c = candidates[p];
      std::sort(c.begin(), c.end());
      c.erase(std::unique(c.begin(), c.end()), c.end());
    });
    snap.stats.time.shoot = seconds_since(t_shoot);
  }

  // Diffraction: per node the edges it sees, per pair their intersection.
  std::vector<std::vector<std::uint32_t>> seen;
  std::optional<DiffuseTiles> tiles;
  if (tile_diffuse && n > 1) {
    const auto t_tiles = std::chrono::steady_clock::now();
    tiles.emplace(scene, em, nodes, is_source, cfg, range);
    search_rays += tiles->rays();
    snap.stats.diffuse_tiles = tiles->tile_count();
    snap.stats.diffuse_views = tiles->views();
    snap.stats.time.diffuse_views = seconds_since(t_tiles);
  }
  const auto t_edges = std::chrono::steady_clock::now();
  if (cfg.diffraction && !scene.edges().empty()) {
    if (faces.refs.empty()) faces = image_faces(scene);
    seen = edges_seen(scene, faces, nodes, is_source, range);
  }
  // Reflection-diffraction: per node the (static face, edge) combinations
  // its reflections reach; with the edges the other end sees, a pair's
  // reflection-diffraction from its lower end and diffraction-reflection
  // from its higher end.
  std::vector<std::vector<ReflectedEdge>> reflected;
  std::vector<std::vector<std::uint64_t>> seen_bits;
  std::vector<std::vector<double>> edge_z, edge_r;  // each node's coordinate along each edge, distance from its line
  if (!seen.empty() && cfg.diffraction_reflection) {
    reflected.resize(n);
    seen_bits.resize(n);
    edge_z.resize(n);
    edge_r.resize(n);
    const auto& edges = scene.edges();
    tbb::parallel_for(std::uint32_t{0}, n, [&](std::uint32_t i) {
      if (!is_source[i]) return;
      reflected_edges(scene, faces, nodes[i].position, range, reflected[i]);
      seen_bits[i].assign((edges.size() + 63) / 64, 0);
      for (auto k : seen[i]) seen_bits[i][k >> 6] |= std::uint64_t{1} << (k & 63);
      edge_z[i].resize(edges.size());
      edge_r[i].resize(edges.size());
      for (std::size_t k = 0; k < edges.size(); ++k) {
        const Vec3 w = nodes[i].position - edges[k].a;
        edge_z[i][k] = dot(w, edges[k].e);
        edge_r[i][k] = norm(w - edge_z[i][k] * edges[k].e);
      }
    });
  }
  // Vehicle edges: this frame's, placed (those long enough); per node, those of the other
  // vehicles it sees from outside their wedge within range (a pair needs
  // both ends to).
  std::vector<Edge> vehicle_edges;
  std::vector<int> vehicle_edge_owner;
  std::vector<double> vehicle_edge_length;
  // A seen edge with the node's coordinate along it and distance from its
  // line: with the other end's, Keller's point without the path (most
  // candidates fail there).
  struct SeenEdge {
    std::uint32_t k;
    double z, r;
  };
  std::vector<std::vector<SeenEdge>> vehicle_edges_seen;
  if (cfg.vehicle_edge_diffraction && n > 1) {
    std::vector<Edge> placed;
    for (std::size_t v = 0; v < scene.vehicles().size(); ++v) {
      placed.clear();
      scene.vehicle_edges(v, placed);
      for (const Edge& e : placed) {
        const double len = norm(e.b - e.a);
        if (len >= kVehicleEdgeMinWavelengths * em.wavelength()) {
          vehicle_edges.push_back(e);
          vehicle_edge_owner.push_back(static_cast<int>(v));
          vehicle_edge_length.push_back(len);
        }
      }
    }
    vehicle_edges_seen.resize(n);
    tbb::parallel_for(std::uint32_t{0}, n, [&](std::uint32_t i) {
      if (!is_source[i]) return;
      const Vec3 p = nodes[i].position;
      for (std::uint32_t k = 0; k < vehicle_edges.size(); ++k) {
        if (vehicle_edge_owner[k] == nodes[i].vehicle) continue;
        const Edge& e = vehicle_edges[k];
        const Vec3 w = p - e.a;
        const double zk = dot(w, e.e);
        const double z = std::clamp(zk, 0.0, vehicle_edge_length[k]);
        if (norm(p - (e.a + z * e.e)) > range) continue;
        const Vec3 v = w - zk * e.e;
        if (edge_angle(e, v) > e.n * kPi) continue;
        vehicle_edges_seen[i].push_back({k, zk, norm(v)});
      }
    });
  }
  snap.stats.time.edges = seconds_since(t_edges);

  const double lambda = em.wavelength();
  const FresnelObstacles obstacles(scene);
  const bool knife_reflected = cfg.vehicle_diffraction && cfg.vehicle_diffraction_reflected;
  snap.pairs.resize(pairs.size());
  tbb::enumerable_thread_specific<std::uint64_t> pair_rays(0);
  tbb::enumerable_thread_specific<SnapshotStats::Timing> pair_time;
  const auto t_pairs = std::chrono::steady_clock::now();
  tbb::parallel_for(std::size_t{0}, pairs.size(), [&](std::size_t p) {
    // Not a structured binding: the lambda below uses i and j, which clang < 16
    // (the fuzz build's clang 14) cannot capture.
    const auto i = pairs[p].first, j = pairs[p].second;
    PairResult& res = snap.pairs[p];
    res.tx = i;
    res.rx = j;
    auto& rays = pair_rays.local();
    auto& tm = pair_time.local();
    auto t_step = std::chrono::steady_clock::now();
    auto lap = [&t_step](double& into) {
      const auto now = std::chrono::steady_clock::now();
      into += std::chrono::duration<double>(now - t_step).count();
      t_step = now;
    };
    res.los_class = classify_los(scene, nodes[i].position, nodes[j].position, res.blockers, &rays);
    const auto zone = obstacles.between(nodes[i].position, nodes[j].position, lambda, nodes[i].vehicle,
                                        nodes[j].vehicle);
    res.fresnel_class = fresnel_class(res.los_class, zone);
    res.fresnel_clearance = zone.clearance;
    lap(tm.los);
    if (!in_range[p]) {
      res.out_of_range = true;
      res.stats = path_stats(res.paths);
      return;
    }
    auto add = [&](const std::vector<FaceRef>& faces) {
      bool over = false;
      if (!knife_reflected || faces.empty()) {
        if (auto path = compute_path(scene, em, cfg, nodes[i], nodes[j], faces, &over, &rays))
          res.paths.push_back(std::move(*path));
        else if (over)
          ++res.dropped_transmission_cap;
        return;
      }
      // Vehicles as knife edges on a reflected path too: traced through the
      // vehicles on its way, attenuated by the legs' multiple knife edge in
      // the unfolded path's first zone (continuous as a car enters a leg).
      auto path = exact_path(scene, em, cfg, nodes[i], nodes[j], faces, &over, &rays, true);
      if (!path) {
        if (over) ++res.dropped_transmission_cap;
        return;
      }
      std::vector<Vec3> points{nodes[i].position};
      std::vector<int> host{-1};
      std::size_t q = 0;
      for (const auto& in : path->interactions)
        if (in.type == InteractionType::specular) {
          points.push_back(in.point);
          host.push_back(faces[q].instance == 0 ? -1 : static_cast<int>(faces[q].instance) - 1);
          ++q;
        }
      points.push_back(nodes[j].position);
      host.push_back(-1);
      const auto ke = obstacles.path_knife_edges(points, host, lambda, nodes[i].vehicle, nodes[j].vehicle);
      if (ke.loss_db > 0) {
        path->a *= std::pow(10.0, -ke.loss_db / 20);
        // A leg that crosses a vehicle may also pass through its windows:
        // the stronger of the two, as for the direct path.
        if (ke.v_main > 0)
          if (auto glass = exact_path(scene, em, cfg, nodes[i], nodes[j], faces, nullptr, &rays, false))
            if (std::norm(glass->a) > std::norm(path->a)) path = std::move(glass);
      }
      res.paths.push_back(std::move(*path));
    };
    if (cfg.los) {
      add({});
      // Vehicles in the first Fresnel zone: P.526 knife-edge loss on the
      // direct path (tracer/fresnel.hpp). A direct ray that only vehicles
      // block is traced through them and attenuated; when it also crosses
      // their windows, the stronger of the two is kept.
      if (cfg.vehicle_diffraction && res.los_class != LosClass::NLOS &&
          -std::sqrt(2.0) * zone.vehicle_clearance > kKnifeEdgeOnset) {
        const auto ke = obstacles.vehicle_knife_edges(nodes[i].position, nodes[j].position, lambda,
                                                      nodes[i].vehicle, nodes[j].vehicle);
        if (ke.loss_db > 0) {
          res.vehicle_loss_db = ke.loss_db;
          const double scale = std::pow(10.0, -ke.loss_db / 20);
          const bool have = !res.paths.empty() && res.paths.front().interactions.empty();
          if (res.los_class == LosClass::LOS && have) {
            res.paths.front().a *= scale;
          } else if (auto direct = exact_path(scene, em, cfg, nodes[i], nodes[j], {}, nullptr, &rays, true)) {
            direct->a *= scale;
            if (!have) res.paths.insert(res.paths.begin(), std::move(*direct));
            else if (std::norm(direct->a) > std::norm(res.paths.front().a)) res.paths.front() = std::move(*direct);
          }
        }
      }
    }
    for (const auto& faces : candidates[p]) add(faces);
    res.candidates = static_cast<std::uint32_t>(candidates[p].size() + (cfg.los ? 1 : 0));
    lap(tm.exact);
    if (!seen.empty()) {
      const auto &ei = seen[i], &ej = seen[j];
      std::size_t x = 0, y = 0;
      while (x < ei.size() && y < ej.size()) {
        if (ei[x] < ej[y]) ++x;
        else if (ej[y] < ei[x]) ++y;
        else {
          ++res.candidates;
          if (auto path = compute_diffraction_path(scene, em, nodes[i], nodes[j], scene.edges()[ei[x]], &rays))
            res.paths.push_back(std::move(*path));
          ++x;
          ++y;
        }
      }
    }
    if (!reflected.empty()) {
      const auto sees = [&](std::uint32_t node, std::uint32_t k) { return (seen_bits[node][k >> 6] >> (k & 63)) & 1; };
      for (int end = 0; end < 2; ++end) {
        const auto from = end == 0 ? i : j, other = end == 0 ? j : i;
        const auto& z_other = edge_z[other];
        const auto& r_other = edge_r[other];
        for (const ReflectedEdge& re : reflected[from]) {
          if (!sees(other, re.edge)) continue;
          if (!re.keller_on_part(z_other[re.edge], r_other[re.edge])) continue;
          ++res.candidates;
          const FaceRef face{0, re.face};
          if (auto path = compute_diffraction_path(scene, em, nodes[i], nodes[j], scene.edges()[re.edge], &rays,
                                                   end == 0 ? &face : nullptr, end == 0 ? nullptr : &face))
            res.paths.push_back(std::move(*path));
        }
      }
    }
    if (!vehicle_edges_seen.empty()) {
      // Where the direct path's knife edge can take a vehicle (it does
      // inside 0.55 r1), its UTD paths fade out from 1.0 r1 on: the two
      // model one field and must not add.
      const bool knife = cfg.vehicle_diffraction && res.los_class != LosClass::NLOS;
      const double onset = -kKnifeEdgeOnset / std::sqrt(2.0);
      int owner = -1;
      double weight = 1;
      // The floor: vehicle_edge_floor_db below the direct path's free-space power.
      const double d = norm(nodes[j].position - nodes[i].position);
      const double floor = std::pow(lambda / (4 * kPi * d), 2) * std::pow(10.0, -cfg.vehicle_edge_floor_db / 10);
      const auto &ei = vehicle_edges_seen[i], &ej = vehicle_edges_seen[j];
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
          if (!(zq >= 0 && zq <= vehicle_edge_length[k])) continue;
          if (vehicle_edge_owner[k] != owner) {
            owner = vehicle_edge_owner[k];
            weight = 1;
            if (knife) {
              const double c =
                  obstacles.vehicle_clearance(nodes[i].position, nodes[j].position, lambda, owner);
              weight = std::clamp((c - onset) / (1 - onset), 0.0, 1.0);
            }
          }
          if (!(weight > 0)) continue;
          ++res.candidates;
          if (auto path = compute_diffraction_path(scene, em, nodes[i], nodes[j], vehicle_edges[k], &rays, nullptr,
                                                   nullptr, floor / (weight * weight))) {
            path->a *= weight;
            res.paths.push_back(std::move(*path));
          }
        }
      }
    }
    lap(tm.diffraction);
    if (tiles) {
      tiles->pair_paths(i, j, 1.0 / radio.bandwidth_hz, res.paths);
      lap(tm.diffuse);
    }
    if (ray_diffuse) {
      for (const auto& entry : diffuse[p]) {
        const DiffuseAcc& acc = entry.second;  // not a structured binding: the lambda below uses it (clang 14)
        if (!(acc.power > 0)) continue;
        Path path = diffuse_record(acc.power, acc.tau, acc.departure, acc.arrival, acc.doppler, lambda);
        const double w = 1.0 / acc.power;
        const FaceRef last = acc.faces[acc.n - 1];
        const Interaction scatter{InteractionType::diffuse, scene.object(last), scene.material(last), w * acc.point};
        const auto reflection = [&](int q) {
          return Interaction{InteractionType::specular, scene.object(acc.faces[q]), scene.material(acc.faces[q]),
                             acc.prefix[q]};
        };
        if (acc.scatter_first) {  // scattered first, then the reflections in reverse order
          path.interactions.push_back(scatter);
          for (int q = acc.n - 2; q >= 0; --q) path.interactions.push_back(reflection(q));
        } else {
          for (int q = 0; q + 1 < acc.n; ++q) path.interactions.push_back(reflection(q));
          path.interactions.push_back(scatter);
        }
        res.paths.push_back(std::move(path));
      }
    }
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
    // Model no more than matters: paths far below the pair's strongest.
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
    lap(tm.assemble);
  });
  snap.stats.time.pairs = seconds_since(t_pairs);
  for (const auto& tm : pair_time) {
    snap.stats.time.los += tm.los;
    snap.stats.time.exact += tm.exact;
    snap.stats.time.diffraction += tm.diffraction;
    snap.stats.time.diffuse += tm.diffuse;
    snap.stats.time.assemble += tm.assemble;
  }
  snap.stats.rays = search_rays;
  for (auto r : pair_rays) snap.stats.rays += r;
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
  return snap;
}

}  // namespace raysweep::tracer
