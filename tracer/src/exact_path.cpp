// The exact specular / refracted path through a given face sequence: image
// method in double precision, every segment traced, slabs on the way
// added, the field carried through each interaction's TE/TM basis.
#include "exact_path.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "em/field.hpp"
#include "em/physical_optics.hpp"

namespace raysweep::tracer {

namespace {

// The sine below which a grazing segment's reach onto its face stops growing.
constexpr double kGrazingSineFloor = 0.01;

// A reflection on a sequence face, or a slab crossed on the way.
struct Event {
  bool reflection;
  FaceRef face;
  Vec3 point;
  Vec3 dir_in;
  int leg = 0;            // the segment that ends here
  double travelled = 0;   // the unfolded length from the source to here
};

// Image method: mirror the source in each plane, then walk back from the
// receiver, intersecting each plane on the way: the reflection points into
// points[1..k], the planes into planes[0..k). False when the sequence has no
// path (a degenerate plane, an image on the wrong side).
bool unfold(const TraceScene& scene, const Node& from, const Node& to, const std::vector<FaceRef>& faces,
            std::array<Plane, kMaxDepth>& planes, std::array<Vec3, kMaxDepth + 2>& points) {
  const std::size_t k = faces.size();
  // Fixed-size scratch (every candidate of the search passes here, most
  // failing in the first few lines: heap vectors were a tenth of its time).
  std::array<Vec3, kMaxDepth + 1> images;
  images[0] = from.position;
  for (std::size_t m = 0; m < k; ++m) {
    planes[m] = scene.plane(faces[m]);
    if (norm(planes[m].normal) < 0.5) return false;
    const double dist = dot(planes[m].normal, images[m]) - planes[m].offset;
    images[m + 1] = images[m] - (2.0 * dist) * planes[m].normal;
  }
  points[0] = from.position;
  points[k + 1] = to.position;
  Vec3 target = to.position;
  for (std::size_t m = k; m-- > 0;) {
    const Plane& p = planes[m];
    const double di = dot(p.normal, images[m + 1]) - p.offset;
    const double dt = dot(p.normal, target) - p.offset;
    // The image and the point it is seen from lie strictly on opposite sides.
    if (!(di * dt < 0)) return false;
    const double s = di / (di - dt);
    points[m + 1] = images[m + 1] + s * (target - images[m + 1]);
    target = points[m + 1];
  }
  return true;
}

// Twice the reach the ray test grants a segment ending on face m (the end
// point's slack, the face's flatness, the grazing angle: exact_path), plus
// a millimetre: a point farther off the face cannot be reached.
double off_face_tolerance(const TraceScene& scene, const FaceRef& face, const std::array<Vec3, kMaxDepth + 2>& points,
                          const Plane& plane, std::size_t m) {
  const Vec3 a = points[m], b = points[m + 1];
  const double len = norm(b - a);
  if (!(len > 0)) return 0;
  const double end_tol = std::max(scene.slack(b, 0), 2 * scene.flatness(face) + 1e-6 * len);
  const double sine = std::fabs(dot((1.0 / len) * (b - a), plane.normal));
  return 2 * end_tol / std::max(sine, kGrazingSineFloor) + 1e-3;
}

// A reflection on a vehicle face by physical optics: the face's Kirchhoff
// integral over an infinite mirror's, with the wave at the face taken as the
// image source's (the unfolded length before it) seen from the receiver's
// image (the unfolded length after). A chain of such faces multiplies their
// factors (docs/tracer.md states what this leaves out).
cdouble facet_po(const TraceScene& scene, const Event& ev, const Vec3& normal, const Vec3& dir_out, double length,
                 double k) {
  thread_local std::vector<std::array<Vec3, 3>> triangles;
  triangles.clear();
  scene.face_triangles(ev.face, triangles);
  const Vec3 source = ev.point - ev.travelled * ev.dir_in;
  const Vec3 receiver = ev.point + (length - ev.travelled) * dir_out;
  return facet_factor(triangles, normal, source, receiver, k);
}

// The path's field along its events (the transmit pattern's vector, then
// each interaction in its own TE/TM basis), its delay, angles and Doppler;
// nullopt when a crossed slab is opaque.
std::optional<Path> path_field(const TraceScene& scene, const Electromagnetics& em, const Node& from, const Node& to,
                               const std::vector<FaceRef>& faces, const std::vector<Event>& events,
                               const std::array<Vec3, kMaxDepth + 1>& dirs, double length, bool facet_po_on) {
  const std::size_t k = faces.size();
  CVec3 e = cvec(antenna_field(em.radio().antenna, dirs[0], from.forward));
  cdouble facets = 1.0;
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
      if (facet_po_on && scene.is_vehicle(ev.face))
        facets *= facet_po(scene, ev, p.normal, dirs[ev.leg + 1], length, 2 * kPi / em.wavelength());
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
  if (facets != 1.0) path.a *= facets;
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

std::optional<Path> exact_path(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& config,
                               const Node& from, const Node& to, const std::vector<FaceRef>& faces, bool* over_cap,
                               std::uint64_t* rays, bool through_vehicles, int* blocked) {
  if (over_cap) *over_cap = false;
  if (blocked) *blocked = 0;
  const std::size_t k = faces.size();
  if (k > static_cast<std::size_t>(kMaxDepth)) return std::nullopt;
  std::array<Plane, kMaxDepth> planes;
  std::array<Vec3, kMaxDepth + 2> points;
  if (!unfold(scene, from, to, faces, planes, points)) return std::nullopt;
  // A reflection point off its face (beyond every tolerance the ray test
  // below grants) makes no path: no ray is cast for it, and it is no near
  // miss, whatever a leg crosses. With physical optics a vehicle facet's
  // point may lie off it within kNearMissFresnelRadii (off_facet): its leg
  // then ends in the air beside the facet.
  const bool po = config.facet_reflection == FacetReflection::po;
  std::array<bool, kMaxDepth> off_facet{};
  for (std::size_t m = 0; m < k; ++m) {
    const double tol = off_face_tolerance(scene, faces[m], points, planes[m], m);
    if (scene.face_contains(faces[m], points[m + 1], tol)) continue;
    if (!po || !scene.is_vehicle(faces[m])) return std::nullopt;
    double before = 0, total = 0;  // unfolded lengths to the point and in all
    for (std::size_t q = 0; q <= k; ++q) (q <= m ? before : total) += norm(points[q + 1] - points[q]);
    total += before;
    const double zone = fresnel_radius(em.wavelength(), before, total - before);
    if (!scene.face_contains(faces[m], points[m + 1], tol + kNearMissFresnelRadii * zone)) return std::nullopt;
    off_facet[m] = true;
  }

  // Trace every segment: it must end on its face, and what it crosses on the
  // way are slabs (or opaque blockers).
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
    const bool ends_on_face = m < k && !off_facet[m];
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
    const std::uint32_t host_a = m > 0 ? faces[m - 1].instance : 0, host_b = m < k ? faces[m].instance : 0;
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
      if (!config.refraction || em.opaque(scene.material(h.face))) {
        if (blocked) *blocked = scene.is_vehicle(h.face) ? 2 : 1;
        return std::nullopt;
      }
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
    if (m < k) events.push_back(Event{true, faces[m], b, dir, static_cast<int>(m), length});
  }
  if (transmissions > config.max_transmissions) {
    if (over_cap) *over_cap = true;
    return std::nullopt;
  }

  return path_field(scene, em, from, to, faces, events, dirs, length,
                    config.facet_reflection == FacetReflection::po);
}

std::optional<Path> compute_path(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& config,
                                 const Node& from, const Node& to, const std::vector<FaceRef>& faces, bool* over_cap,
                                 std::uint64_t* rays) {
  return exact_path(scene, em, config, from, to, faces, over_cap, rays, false);
}

}  // namespace raysweep::tracer
