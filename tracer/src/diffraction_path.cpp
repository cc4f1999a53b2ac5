// UTD diffraction paths over one edge (Keller's point, Luebbers'
// coefficients), with an optional specular reflection before or after it.
#include "diffraction_path.hpp"

#include <algorithm>
#include <cmath>

#include "em/field.hpp"
#include "em/utd.hpp"

namespace raysweep::tracer {

namespace {

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

// One diffracted path's geometry: the ends, a reflection before (after)
// the edge unfolded into the source's (receiver's) image across its face's
// plane, Keller's point on the edge and the legs to and from it.
struct Unfolded {
  const FaceRef* before = nullptr;
  const FaceRef* after = nullptr;
  Plane pa, pb;                // the reflecting faces' planes
  Vec3 tx{0, 0, 0}, rx{0, 0, 0};  // the ends, or their images
  Vec3 vt{0, 0, 0}, vr{0, 0, 0};  // from the edge's line to tx and rx, perpendicular to it
  Vec3 q{0, 0, 0};             // Keller's point
  Vec3 p_before{0, 0, 0}, p_after{0, 0, 0};  // the reflection points
  double sp = 0, sd = 0;       // tx -> q, q -> rx
  Vec3 s_in{0, 0, 0}, s_out{0, 0, 0};
  double sin_b = 0;
};

// The reflection point on the unfolded line from image `img` to `x` (the
// real end's side of the plane), on its face (the sphere first: most
// combinations fail there).
bool reflection_point(const TraceScene& scene, const FaceRef& f, const Plane& pl, const Vec3& img, const Vec3& x,
                      Vec3& point) {
  const double di = dot(pl.normal, img) - pl.offset, dx = dot(pl.normal, x) - pl.offset;
  if (!(di * dx < 0)) return false;
  point = img + (di / (di - dx)) * (x - img);
  const auto sphere = scene.face_sphere(f);
  const double tol = 2 * scene.slack(point, 0) + 2 * scene.flatness(f);
  const Vec3 w = point - sphere.centre;
  return dot(w, w) <= (sphere.radius + tol) * (sphere.radius + tol) && scene.face_contains(f, point, tol);
}

// The geometry of the path from `from` to `to` over `edge`; false when
// there is none (an end on the edge's line, Keller's point off the edge, a
// reflection point off its face, or rays grazing along the edge).
bool unfold(const TraceScene& scene, const Node& from, const Node& to, const Edge& edge, Unfolded& u) {
  // A reflection on a plane before (after) the edge is unfolded: the edge
  // sees the source's (receiver's) image, along straight legs of the same
  // length, so Keller's point, the UTD angles and the spreading are those of
  // the image; the field takes the face's coefficients at its point.
  auto image = [&](const Vec3& x, const FaceRef* f, Plane& pl) {
    if (!f) return x;
    pl = scene.plane(*f);
    return x - (2 * (dot(pl.normal, x) - pl.offset)) * pl.normal;
  };
  u.tx = image(from.position, u.before, u.pa);
  u.rx = image(to.position, u.after, u.pb);
  const double len = norm(edge.b - edge.a);
  const Vec3 wt = u.tx - edge.a, wr = u.rx - edge.a;
  const double zt = dot(wt, edge.e), zr = dot(wr, edge.e);
  u.vt = wt - zt * edge.e;
  u.vr = wr - zr * edge.e;
  const double rt = norm(u.vt), rr = norm(u.vr);
  if (rt < 1e-6 || rr < 1e-6) return false;  // an antenna (image) on the edge line
  // Keller: equal angles with the edge, i.e. the point where the unfolded
  // straight line crosses the edge.
  const double zq = (zt * rr + zr * rt) / (rt + rr);
  if (zq < 0 || zq > len) return false;
  u.q = edge.a + zq * edge.e;
  if (u.before && !reflection_point(scene, *u.before, u.pa, u.tx, u.q, u.p_before)) return false;
  if (u.after && !reflection_point(scene, *u.after, u.pb, u.rx, u.q, u.p_after)) return false;
  u.sp = norm(u.q - u.tx);
  u.sd = norm(u.rx - u.q);
  u.s_in = (1.0 / u.sp) * (u.q - u.tx);
  u.s_out = (1.0 / u.sd) * (u.rx - u.q);
  u.sin_b = norm(cross(edge.e, u.s_in));
  return !(u.sin_b < 1e-6);  // grazing along the edge
}

// A leg from or to a reflection point, clear of all but its face and,
// at the edge point, the edge's faces (occlusion ignores two faces, so
// with two edge faces each is ignored in turn: a real blocker shows in
// both queries).
bool reflected_leg_clear(const TraceScene& scene, const Edge& edge, const FaceRef& f, const Vec3& a, const Vec3& b,
                         bool at_edge, std::uint64_t* rays) {
  const double l = norm(b - a);
  const Vec3 dir = (1.0 / l) * (b - a);
  const double t0 = scene.slack(a, 0) * 0.1, t1 = l - scene.slack(a, l) * 0.1;
  if (t1 <= t0) return false;
  if (rays) ++*rays;
  if (!scene.occluded(a, dir, t0, t1, &f, at_edge ? &edge.face0 : nullptr)) return true;
  if (!at_edge || edge.face_n == edge.face0) return false;
  if (rays) ++*rays;
  return !scene.occluded(a, dir, t0, t1, &f, &edge.face_n);
}

// Whether every leg of the path is clear.
bool legs_clear(const TraceScene& scene, const Edge& edge, const Node& from, const Node& to, const Unfolded& u,
                std::uint64_t* rays) {
  if (u.before && (!reflected_leg_clear(scene, edge, *u.before, from.position, u.p_before, false, rays) ||
                   !reflected_leg_clear(scene, edge, *u.before, u.q, u.p_before, true, rays)))
    return false;
  if (u.after && (!reflected_leg_clear(scene, edge, *u.after, u.p_after, to.position, false, rays) ||
                  !reflected_leg_clear(scene, edge, *u.after, u.q, u.p_after, true, rays)))
    return false;
  if (!u.before && !leg_clear(scene, edge, from.position, u.s_in, u.sp, rays)) return false;
  if (!u.after && !leg_clear(scene, edge, u.q, u.s_out, u.sd, rays)) return false;
  return true;
}

// The received field (before spreading and phase) of the path: the
// transmit pattern `e_tx` along its first leg, the reflection before the
// edge, the edge's diffraction coefficients `D` in edge-fixed bases, the
// reflection after it, the receive pattern `f_rx`.
cdouble diffracted_field(const TraceScene& scene, const Electromagnetics& em, const Edge& edge, const Unfolded& u,
                         const DiffractionCoefficients& D, const Vec3& d_first, const Vec3& e_tx, const Vec3& f_rx) {
  // Edge-fixed polarisation bases (Kouyoumjian and Pathak).
  const Vec3 phi_in = -1.0 * normalize(cross(edge.e, u.s_in));
  const Vec3 beta_in = cross(u.s_in, phi_in);
  const Vec3 phi_out = normalize(cross(edge.e, u.s_out));
  const Vec3 beta_out = cross(u.s_out, phi_out);
  if (!u.before && !u.after)
    return -(D.soft * dot(e_tx, beta_in) * dot(f_rx, beta_out) + D.hard * dot(e_tx, phi_in) * dot(f_rx, phi_out));
  // A reflection of field e travelling along k_in on face f (plane pl).
  auto reflect = [&](const CVec3& e, const Vec3& k_in, const FaceRef& f, const Plane& pl) {
    const auto mat = scene.material(f);
    return reflect_field(e, k_in, pl.normal, em.reflection(mat, std::fabs(dot(k_in, pl.normal))),
                         em.specular_keep(mat));
  };
  CVec3 e_in = cvec(e_tx);
  if (u.before) e_in = reflect(e_in, d_first, *u.before, u.pa);
  // The diffracted field leaving the edge along s_out.
  CVec3 e_out = combine(-D.soft * cdot(e_in, beta_in), beta_out, -D.hard * cdot(e_in, phi_in), phi_out);
  if (u.after) e_out = reflect(e_out, u.s_out, *u.after, u.pb);
  return cdot(e_out, f_rx);
}

// The path's angles, Doppler and interactions (its gain and delay set).
void describe(const TraceScene& scene, const Node& from, const Node& to, const Edge& edge, const Unfolded& u,
              const Vec3& d_first, const Vec3& d_last, double lambda, Path& path) {
  path.theta_t = zenith(d_first);
  path.phi_t = azimuth(d_first);
  path.theta_r = zenith(-1.0 * d_last);
  path.phi_r = azimuth(-1.0 * d_last);
  double rate = dot(d_first, -1.0 * from.velocity) + dot(d_last, to.velocity);
  if (edge.face0.instance > 0) rate += dot(u.s_in - u.s_out, scene.velocity(edge.face0));  // a vehicle's edge moves
  path.doppler_hz = -rate / lambda;
  if (u.before)
    path.interactions.push_back(
        Interaction{InteractionType::specular, scene.object(*u.before), scene.material(*u.before), u.p_before});
  path.interactions.push_back(Interaction{InteractionType::diffraction, edge.object, edge.material0, u.q});
  if (u.after)
    path.interactions.push_back(
        Interaction{InteractionType::specular, scene.object(*u.after), scene.material(*u.after), u.p_after});
}

}  // namespace

std::optional<Path> compute_diffraction_path(const TraceScene& scene, const Electromagnetics& em, const Node& from,
                                             const Node& to, const Edge& edge, std::uint64_t* rays,
                                             const FaceRef* before, const FaceRef* after, double min_power,
                                             bool* blocked) {
  if (blocked) *blocked = false;
  Unfolded u;
  u.before = before;
  u.after = after;
  if (!unfold(scene, from, to, edge, u)) return std::nullopt;
  // With a power floor, a bound on the field comes first (below): it does
  // not depend on the legs, and most weak candidates then need no ray.
  if (!(min_power > 0) && !legs_clear(scene, edge, from, to, u, rays)) {
    if (blocked) *blocked = true;
    return std::nullopt;
  }
  // Both ends (images) outside the wedge (the callers' edge lists hold
  // that already; here the angles are needed for the coefficients).
  const double phi_i = edge_angle(edge, u.vt), phi_d = edge_angle(edge, u.vr);
  const double ext = edge.n * kPi;
  if (phi_i > ext || phi_d > ext) return std::nullopt;

  const double lambda = em.wavelength();
  const double k = 2 * kPi / lambda;
  const double beta0 = std::acos(std::clamp(dot(edge.e, u.s_in), -1.0, 1.0));
  const double L = u.sd * u.sp * u.sin_b * u.sin_b / (u.sd + u.sp);
  const double length = u.sp + u.sd;
  // The real first and last legs' directions.
  const Vec3 d_first = before ? normalize(u.p_before - from.position) : u.s_in;
  const Vec3 d_last = after ? normalize(to.position - u.p_after) : u.s_out;
  const Vec3 e_tx = antenna_field(em.radio().antenna, d_first, from.forward);
  const Vec3 f_rx = antenna_field(em.radio().antenna, -1.0 * d_last, to.forward);
  // Under a floor, a bound first (|field| <= max |D| |e_tx| |f_rx|: the
  // edge-fixed bases are orthonormal and every reflection coefficient is
  // at most 1): on the ring road's 60 cars it stops 55 % of the vehicle
  // edges' candidates, before their rays and coefficients. Of the rest most
  // are blocked: the legs before the field.
  if (min_power > 0) {
    const double bound = (lambda / (4 * kPi)) * utd_wedge_bound(edge.n, phi_i, phi_d, beta0, L, k) * norm(e_tx) *
                         norm(f_rx) / std::sqrt(u.sp * u.sd * length);
    if (bound * bound < min_power) return std::nullopt;
    if (!legs_clear(scene, edge, from, to, u, rays)) {
      if (blocked) *blocked = true;
      return std::nullopt;
    }
  }
  // Rough faces reflect sqrt(1 - S^2) of the smooth field, in the UTD terms
  // too, so the total stays continuous across reflection boundaries.
  const auto D = utd_wedge(edge.n, phi_i, phi_d, beta0, L, k, &em.material(edge.material0),
                           &em.material(edge.material_n), em.specular_keep(edge.material0),
                           em.specular_keep(edge.material_n));
  const cdouble field = diffracted_field(scene, em, edge, u, D, d_first, e_tx, f_rx);
  Path path;
  path.tau_s = length / kSpeedOfLight;
  const double phase = -2 * kPi * std::fmod(length / lambda, 1.0);
  path.a = (lambda / (4 * kPi)) / std::sqrt(u.sp * u.sd * length) * field * std::polar(1.0, phase);
  if (min_power > 0 && std::norm(path.a) < min_power) return std::nullopt;
  describe(scene, from, to, edge, u, d_first, d_last, lambda, path);
  return path;
}

}  // namespace raysweep::tracer
