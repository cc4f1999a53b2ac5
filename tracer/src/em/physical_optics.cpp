#include "physical_optics.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

namespace raysweep::tracer {

namespace {

// Gauss-Legendre, 8 points on [-1, 1].
constexpr std::array<double, 4> kNodes = {0.1834346424956498, 0.5255324099163290, 0.7966664774136267,
                                          0.9602898564975363};
constexpr std::array<double, 4> kWeights = {0.3626837833783620, 0.3137066458778873, 0.2223810344533745,
                                            0.1012285362903763};

// (1 - exp(-j x)) / x, written so that it keeps its digits as x -> 0.
cdouble one_minus_exp_over(double x) {
  if (x < 1e-300) return {0.0, 1.0};
  double sh, ch;
  ::sincos(0.5 * x, &sh, &ch);
  return {2.0 * sh * sh / x, 2.0 * sh * ch / x};
}

// Beyond this phase s^2 (radians) an edge's oscillating part is summed by
// its asymptotic series instead of panels: a large facet's far edges cost
// R^2 one-radian panels each otherwise (a bus side's hundreds).
constexpr double kTailPhase = 20;
constexpr int kTailTerms = 12;

// int_{U}^{inf} G(u) e^{-ju} du with G(u) = 1 / (2 sqrt(u) (d2 + u)), by
// parts: e^{-jU} sum_n G^(n)(U) / j^(n+1). The n-th term is about n! / U^n
// of the first, so from U = 20 on twelve of them leave about 1e-7 of G(U)
// (the rectangles' closed forms hold to 1e-9: test_physical_optics).
cdouble oscillating_tail(double d2, double u) {
  // Leibniz on G = (1/2) p q, p = u^(-1/2), q = (d2 + u)^(-1).
  std::array<double, kTailTerms> p{}, q{};
  p[0] = 1 / std::sqrt(u);
  q[0] = 1 / (d2 + u);
  for (int n = 1; n < kTailTerms; ++n) {
    p[n] = p[n - 1] * (-(2.0 * n - 1) / 2) / u;
    q[n] = q[n - 1] * (-n) / (d2 + u);
  }
  cdouble sum = 0, jpow = {0, 1};  // j^(n+1)
  for (int n = 0; n < kTailTerms; ++n) {
    double binom = 1, g = 0;
    for (int i = 0; i <= n; ++i) {
      g += binom * p[i] * q[n - i];
      binom = binom * (n - i) / (i + 1);
    }
    sum += 0.5 * g / jpow;
    jpow *= cdouble{0, 1};
  }
  return std::polar(1.0, -u) * sum;
}

// int_{s0}^{s1} phi(d2 + s^2) ds for 0 <= s0 <= s1, on panels of equal
// steps in s^2 (at most one radian each) and at most half a unit wide, up
// to s^2 = kTailPhase; beyond, 1 / (d2 + s^2) in closed form less the
// oscillating part's asymptotic series.
cdouble monotone_piece(double d2, double s0, double s1) {
  const double cut = std::sqrt(kTailPhase);
  if (s1 > cut) {
    const double mid = std::max(s0, cut);
    const double c = std::sqrt(d2);
    const cdouble head = mid > s0 ? monotone_piece(d2, s0, mid) : cdouble{0};
    // atan(s1 / c) - atan(mid / c) over c, in a form that keeps its digits
    // (and its limit 1 / mid - 1 / s1) as c -> 0, where d2 may underflow.
    const double x = (s1 - mid) / (d2 + s1 * mid);
    const double plain = c > 0 ? std::atan(c * x) / c : x;
    const cdouble waves = std::polar(1.0, -d2) * (oscillating_tail(d2, mid * mid) - oscillating_tail(d2, s1 * s1));
    return head + plain - waves;
  }
  const double span = s1 * s1 - s0 * s0;
  const int n = std::max({1, static_cast<int>(std::ceil(span)), static_cast<int>(std::ceil(2.0 * (s1 - s0)))});
  const double step = span / n;
  cdouble sum = 0;
  double lo = s0;
  for (int i = 1; i <= n; ++i) {
    const double hi = i == n ? s1 : std::sqrt(s0 * s0 + i * step);
    const double mid = 0.5 * (lo + hi), half = 0.5 * (hi - lo);
    cdouble panel = 0;
    for (std::size_t g = 0; g < kNodes.size(); ++g) {
      const double a = mid - half * kNodes[g], b = mid + half * kNodes[g];
      panel += kWeights[g] * (one_minus_exp_over(d2 + a * a) + one_minus_exp_over(d2 + b * b));
    }
    sum += half * panel;
    lo = hi;
  }
  return sum;
}

// One directed edge's int (1 - exp(-j R^2)) dtheta, with the edge's points
// F + s u (F the foot of the origin on its line): dtheta = c ds / R^2, c = F x u.
cdouble edge_term(double ax, double ay, double bx, double by) {
  const double ex = bx - ax, ey = by - ay;
  const double len = std::hypot(ex, ey);
  if (len < 1e-300) return 0;
  const double ux = ex / len, uy = ey / len;
  const double sa = ax * ux + ay * uy, sb = bx * ux + by * uy;
  const double c = ax * uy - ay * ux;
  if (c == 0) return 0;
  const double d2 = c * c;
  // s runs from sa up to sb; the integrand is even in s.
  cdouble sum;
  if (sa >= 0)
    sum = monotone_piece(d2, sa, sb);
  else if (sb <= 0)
    sum = monotone_piece(d2, -sb, -sa);
  else
    sum = monotone_piece(d2, 0, -sa) + monotone_piece(d2, 0, sb);
  return c * sum;
}

// The path length over the facet's plane about a point C on it, to second
// order: L(C + p) = L_C + g . p + p^T H p / 2 = L_q + (p - p*)^T H (p - p*) / 2
// (g = 0 at the specular point), in H's principal directions e1, e2 (scaled
// by sqrt(k h / 2)); the amplitude cos(theta) / (r1 r2) taken at C.
struct Expansion {
  Vec3 centre;       // C + p*, where the quadratic phase is stationary
  Vec3 e1, e2;       // H's principal directions
  double s1, s2;     // sqrt(k h / 2) along each
  double length;     // L_q
  double amplitude;  // cos(theta_C) / (r1 r2 sqrt(det H))
};

Expansion expand(const Vec3& centroid, const Vec3& normal, const Vec3& source, const Vec3& receiver, double k) {
  const Vec3 a = normalize(any_perpendicular(normal));
  const Vec3 b = cross(normal, a);
  const Vec3 to_c = centroid - source, from_c = receiver - centroid;
  const double r1 = norm(to_c), r2 = norm(from_c);
  const Vec3 t1 = (1.0 / r1) * to_c, t2 = (1.0 / r2) * from_c;
  double h11 = 0, h12 = 0, h22 = 0;
  for (const auto& [t, r] : {std::pair{t1, r1}, std::pair{t2, r2}}) {
    const double ta = dot(t, a), tb = dot(t, b);
    h11 += (1.0 - ta * ta) / r;
    h12 += -ta * tb / r;
    h22 += (1.0 - tb * tb) / r;
  }
  const Vec3 g3 = t1 - t2;
  const double ga = dot(g3, a), gb = dot(g3, b);
  const double det = std::max(h11 * h22 - h12 * h12, 1e-300);  // grazing on both legs: no area
  // p* = -H^-1 g
  const double pa = -(h22 * ga - h12 * gb) / det, pb = -(h11 * gb - h12 * ga) / det;
  const double phi = 0.5 * std::atan2(2.0 * h12, h11 - h22);
  const double c = std::cos(phi), s = std::sin(phi);
  const double l1 = c * c * h11 + 2 * c * s * h12 + s * s * h22;
  const double l2 = s * s * h11 - 2 * c * s * h12 + c * c * h22;
  auto scale = [k](double h) { return std::sqrt(0.5 * k * std::max(h, 0.0)); };
  const double lq = r1 + r2 + 0.5 * (ga * pa + gb * pb);
  // The obliquity as the mean of both ends' (equal at the specular point),
  // so that the factor is the same whichever end transmits.
  const double obliquity = 0.5 * (std::fabs(dot(t1, normal)) + std::fabs(dot(t2, normal)));
  const double amplitude = obliquity / (r1 * r2 * std::sqrt(det));
  return {centroid + pa * a + pb * b, c * a + s * b, c * b - s * a, scale(l1), scale(l2), lq, amplitude};
}

}  // namespace

cdouble fresnel_region_factor(const std::vector<std::array<double, 4>>& edges) {
  cdouble sum = 0;
  for (const auto& e : edges) sum += edge_term(e[0], e[1], e[2], e[3]);
  return sum / (2.0 * kPi);
}

namespace {

using Triangle = std::array<Vec3, 3>;

// The area-weighted centroid on the facet's plane (the triangles may lie a
// rounding off it).
Vec3 centroid_of(const std::vector<Triangle>& triangles, const Vec3& normal) {
  Vec3 centroid{0, 0, 0};
  double area = 0;
  for (const auto& t : triangles) {
    const double w = 0.5 * norm(cross(t[1] - t[0], t[2] - t[0]));
    centroid = centroid + (w / 3.0) * (t[0] + t[1] + t[2]);
    area += w;
  }
  if (!(area > 0)) return triangles[0][0];
  centroid = (1.0 / area) * centroid;
  return centroid - (dot(centroid - triangles[0][0], normal)) * normal;
}

// The boundary of the triangles (their counter-clockwise edges, an edge met
// in both directions left out) in the expansion's scaled coordinates.
std::vector<std::array<double, 4>> scaled_boundary(const std::vector<Triangle>& triangles, const Expansion& x) {
  auto scaled = [&](const Vec3& v) {
    const Vec3 p = v - x.centre;
    return std::array<double, 2>{x.s1 * dot(p, x.e1), x.s2 * dot(p, x.e2)};
  };
  using Key = std::array<double, 6>;
  std::map<Key, std::array<double, 4>> edges;
  for (const auto& tri : triangles) {
    std::array<std::array<double, 2>, 3> q = {scaled(tri[0]), scaled(tri[1]), scaled(tri[2])};
    const double area2 = (q[1][0] - q[0][0]) * (q[2][1] - q[0][1]) - (q[1][1] - q[0][1]) * (q[2][0] - q[0][0]);
    std::array<int, 3> order = {0, 1, 2};
    if (area2 < 0) order = {0, 2, 1};
    for (int m = 0; m < 3; ++m) {
      const int i = order[m], j = order[(m + 1) % 3];
      const Key key = {tri[i][0], tri[i][1], tri[i][2], tri[j][0], tri[j][1], tri[j][2]};
      const Key reverse = {tri[j][0], tri[j][1], tri[j][2], tri[i][0], tri[i][1], tri[i][2]};
      if (auto it = edges.find(reverse); it != edges.end()) {
        edges.erase(it);
        continue;
      }
      edges[key] = {q[i][0], q[i][1], q[j][0], q[j][1]};
    }
  }
  std::vector<std::array<double, 4>> boundary;
  boundary.reserve(edges.size());
  for (const auto& [key, e] : edges) boundary.push_back(e);
  return boundary;
}

// The factor under one second-order expansion (about `at`, on the plane),
// over GO's image field e^{-jk L0} / L0 (L0 the distance from the source to
// the receiver's mirror image: the unfolded GO length).
cdouble factor_of(const Expansion& x, const Vec3& at, const Vec3& normal, const Vec3& source, const Vec3& receiver,
                  double k, const std::vector<std::array<double, 4>>& boundary) {
  const Vec3 mirror = receiver - (2.0 * dot(receiver - at, normal)) * normal;
  const double l0 = norm(mirror - source);
  return l0 * x.amplitude * std::polar(1.0, -k * (x.length - l0)) * fresnel_region_factor(boundary);
}

// A facet whose boundary lies this far (scaled: 4 Fresnel radii) from its
// specular point reflects as GO's mirror: the edges' ripple there is at most
// about 1 / (2 sqrt(pi) q) each (0.3 dB), and a far part of a large facet
// costs many panels for next to nothing.
constexpr double kGoMargin = 4 * 1.7724538509055159;

// The specular point: where the segment from the source to the receiver's
// mirror image crosses the facet's plane (nullopt when it does not).
std::optional<Vec3> specular_point(const Vec3& on_plane, const Vec3& normal, const Vec3& source,
                                   const Vec3& receiver) {
  const Vec3 mirror = receiver - (2.0 * dot(receiver - on_plane, normal)) * normal;
  const double across = dot(normal, mirror - source);
  if (std::fabs(across) < 1e-12) return std::nullopt;
  const double u = dot(normal, on_plane - source) / across;
  if (!(u > 0 && u < 1)) return std::nullopt;
  return source + u * (mirror - source);
}

// Whether the origin of the scaled coordinates lies inside the boundary,
// and how far (scaled) from the nearest edge.
std::pair<bool, double> inside(const std::vector<std::array<double, 4>>& boundary) {
  double winding = 0, nearest = 1e300;
  for (const auto& e : boundary) {
    const double ex = e[2] - e[0], ey = e[3] - e[1];
    const double len2 = ex * ex + ey * ey;
    const double t = len2 > 0 ? std::clamp(-(e[0] * ex + e[1] * ey) / len2, 0.0, 1.0) : 0.0;
    nearest = std::min(nearest, std::hypot(e[0] + t * ex, e[1] + t * ey));
    winding += std::atan2(e[0] * e[3] - e[1] * e[2], e[0] * e[2] + e[1] * e[3]);
  }
  return {winding > kPi, nearest};
}

}  // namespace

cdouble facet_factor(const std::vector<std::array<Vec3, 3>>& triangles, const Vec3& normal, const Vec3& source,
                     const Vec3& receiver, double k) {
  if (triangles.empty()) return 0.0;
  const Vec3 centroid = centroid_of(triangles, normal);
  // About the specular point when it lies on the facet (where the tracer
  // uses it: the GO path exists), so that the stationary region is exact and
  // the approximation is left to the edges' terms; about the centroid else.
  if (const auto p = specular_point(centroid, normal, source, receiver)) {
    const Expansion x = expand(*p, normal, source, receiver, k);
    const auto boundary = scaled_boundary(triangles, x);
    const auto [in, nearest] = inside(boundary);
    if (in && nearest >= kGoMargin) return 1.0;
    if (in) return factor_of(x, *p, normal, source, receiver, k, boundary);
  }
  const Expansion x = expand(centroid, normal, source, receiver, k);
  return factor_of(x, centroid, normal, source, receiver, k, scaled_boundary(triangles, x));
}

}  // namespace raysweep::tracer
