#include "fresnel_zone.hpp"

#include "tracer/em/constants.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace raysweep::tracer {

namespace {

struct P2 {
  double x, y;
};
P2 sub2(P2 a, P2 b) { return {a.x - b.x, a.y - b.y}; }
double dot2(P2 a, P2 b) { return a.x * b.x + a.y * b.y; }
double cross2(P2 a, P2 b) { return a.x * b.y - a.y * b.x; }

// Closest point of triangle (a, b, c) to the origin: its distance and
// barycentric weights (Ericson, Real-Time Collision Detection 5.1.5, in 2D).
double closest_to_origin(P2 a, P2 b, P2 c, std::array<double, 3>& w) {
  const P2 p{0, 0};
  const P2 ab = sub2(b, a), ac = sub2(c, a), ap = sub2(p, a);
  // Seen edge-on (no area): the nearest of its three sides. The regions
  // below would round into "inside" and report a crossing far from it.
  const double scale = dot2(ab, ab) + dot2(ac, ac);
  if (std::fabs(cross2(ab, ac)) <= 1e-12 * scale) {
    const P2 v[3] = {a, b, c};
    double best = 1e300;
    for (int k = 0; k < 3; ++k) {
      const P2 e = sub2(v[(k + 1) % 3], v[k]);
      const double ee = dot2(e, e);
      const double s = ee > 0 ? std::clamp(-dot2(v[k], e) / ee, 0.0, 1.0) : 0.0;
      const P2 q{v[k].x + s * e.x, v[k].y + s * e.y};
      const double dist = std::sqrt(dot2(q, q));
      if (dist < best) {
        best = dist;
        w = {0, 0, 0};
        w[k] = 1 - s;
        w[(k + 1) % 3] = s;
      }
    }
    return best;
  }
  const double d1 = dot2(ab, ap), d2 = dot2(ac, ap);
  auto at = [&](double wa, double wb, double wc) {
    w = {wa, wb, wc};
    const P2 q{wa * a.x + wb * b.x + wc * c.x, wa * a.y + wb * b.y + wc * c.y};
    return std::sqrt(dot2(q, q));
  };
  if (d1 <= 0 && d2 <= 0) return at(1, 0, 0);
  const P2 bp = sub2(p, b);
  const double d3 = dot2(ab, bp), d4 = dot2(ac, bp);
  if (d3 >= 0 && d4 <= d3) return at(0, 1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return at(1 - v, v, 0);
  }
  const P2 cp = sub2(p, c);
  const double d5 = dot2(ab, cp), d6 = dot2(ac, cp);
  if (d6 >= 0 && d5 <= d6) return at(0, 0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double v = d2 / (d2 - d6);
    return at(1 - v, 0, v);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double v = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return at(0, 1 - v, v);
  }
  const double den = 1 / (va + vb + vc);
  if (!std::isfinite(den)) return at(1, 0, 0);  // degenerate (a segment or a point seen end-on)
  const double v = vb * den, x = vc * den;
  w = {1 - v - x, v, x};
  return 0;  // inside
}

// Where the ray s * dir (s >= 0) leaves triangle (a, b, c), or -1 when it
// does not meet it. Triangles seen edge-on (faces parallel to the line) have
// no inside: their outline is covered by the faces across the line.
double exit_along(P2 a, P2 b, P2 c, P2 dir) {
  const double area2 = cross2(sub2(b, a), sub2(c, a));
  const double scale = dot2(sub2(b, a), sub2(b, a)) + dot2(sub2(c, a), sub2(c, a));
  if (std::fabs(area2) <= 1e-9 * scale) return -1;
  const double orient = area2 >= 0 ? 1 : -1;
  double lo = 0, hi = 1e300;
  const P2 v[3] = {a, b, c};
  for (int k = 0; k < 3; ++k) {
    const P2 e = sub2(v[(k + 1) % 3], v[k]);
    const P2 n{-orient * e.y, orient * e.x};  // inward normal
    // Inside: n . (s dir - v_k) >= 0.
    const double nd = dot2(n, dir), nv = dot2(n, v[k]);
    if (std::fabs(nd) < 1e-300) {
      if (nv > 0) return -1;
      continue;
    }
    const double s = nv / nd;
    if (nd > 0) lo = std::max(lo, s);
    else hi = std::min(hi, s);
  }
  return lo <= hi ? hi : -1;
}

// An obstacle as the line sees it: its clearance, and the point the line
// must pass to clear it (the obstacle's knife edge for this line).
struct Clearance {
  double clearance = 1e300;
  Vec3 edge{0, 0, 0};
};

// Clearance of one obstacle (its triangles) from the line a + t u, t in
// (0, d), over the first Fresnel radius there. `near`: its faces near the
// zone with a lower bound of their clearance, ascending; faces are skipped
// once their bound reaches `bound` (the caller's worst so far: they cannot
// lower it) or the obstacle's own best. Faces the line may cross have a
// bound <= 0 and are never skipped.
Clearance obstacle_clearance(const std::vector<std::array<Vec3, 3>>& tris, const std::vector<std::uint32_t>& face_begin,
                             const std::vector<FresnelObstacles::NearFace>& near, const Vec3& a, const Vec3& u,
                             const Vec3& e1, const Vec3& e2, double d, double lambda, double bound,
                             const FresnelZone& zone, bool upward_exits = false) {
  auto r1 = [&](double t) { return zone.r1(t, lambda); };
  Clearance best;
  double blocked_t = -1;
  const double mid = zone.widest(-1e300, 1e300);  // where r1 is largest, in line coordinates
  // Projection onto the plane across the line; false: beyond an end.
  auto project = [&](const std::array<Vec3, 3>& tri, std::array<P2, 3>& q, std::array<double, 3>& t) {
    int before = 0, after = 0;
    for (int k = 0; k < 3; ++k) {
      const Vec3 w = tri[k] - a;
      t[k] = dot(w, u);
      q[k] = {dot(w, e1), dot(w, e2)};
      before += t[k] <= 0;
      after += t[k] >= d;
    }
    return before < 3 && after < 3;
  };
  for (const auto& nf : near) {
    if (nf.bound > 0 && nf.bound >= std::min(bound, best.clearance)) break;
    for (std::uint32_t index = face_begin[nf.face]; index < face_begin[nf.face + 1]; ++index) {
      std::array<P2, 3> q;
      std::array<double, 3> t;
      if (!project(tris[index], q, t)) continue;
      std::array<double, 3> w;
      const double h = closest_to_origin(q[0], q[1], q[2], w);
      const double tc = w[0] * t[0] + w[1] * t[1] + w[2] * t[2];
      if (h <= 0) {
        // Of several crossings, the one nearest mid-path (where r1 is
        // largest): independent of the order triangles are visited in.
        if (tc > 0 && tc < d && (blocked_t < 0 || std::fabs(tc - mid) < std::fabs(blocked_t - mid)))
          blocked_t = tc;
        continue;
      }
      const double c = h / r1(tc);
      if (c < best.clearance) {
        best.clearance = c;
        const double qx = w[0] * q[0].x + w[1] * q[1].x + w[2] * q[2].x, qy = w[0] * q[0].y + w[1] * q[1].y + w[2] * q[2].y;
        best.edge = a + tc * u + qx * e1 + qy * e2;
      }
    }
  }
  if (blocked_t < 0) return best;
  // Crossed: the shortest shift that clears the outline (every triangle),
  // over 32 directions. Exact pruning: triangles in decreasing order of
  // their farthest vertex; a direction stops once no further triangle can
  // push its exit out, or once it cannot beat the best direction.
  // `upward_exits`: not downwards (a leg near a ground reflection runs at
  // the vehicle's base, where an exit below it would pass through the
  // ground; the direct line at antenna height never exits there anyway).
  struct Piece {
    double reach;  // farthest vertex from the line
    P2 centre;     // bounding circle (cheap test before exit_along)
    double radius;
    std::array<P2, 3> q;
  };
  thread_local std::vector<Piece> outline;  // (no allocation per crossed obstacle)
  outline.clear();
  for (const auto& tri : tris) {
    std::array<P2, 3> q;
    std::array<double, 3> t;
    if (!project(tri, q, t)) continue;
    double reach = 0, radius = 0;
    const P2 m{(q[0].x + q[1].x + q[2].x) / 3, (q[0].y + q[1].y + q[2].y) / 3};
    for (const P2& v : q) {
      reach = std::max(reach, dot2(v, v));
      radius = std::max(radius, dot2(sub2(v, m), sub2(v, m)));
    }
    outline.push_back({std::sqrt(reach), m, std::sqrt(radius) * (1 + 1e-9) + 1e-12, q});
  }
  std::sort(outline.begin(), outline.end(), [](const Piece& x, const Piece& y) { return x.reach > y.reach; });
  double depth = 1e300;
  P2 best_dir{0, 1};
  // The 32 directions, evaluated once (the same std::cos / std::sin values).
  static const std::array<P2, 32> directions = [] {
    std::array<P2, 32> out{};
    for (int k = 0; k < 32; ++k) {
      const double phi = 2 * kPi * k / 32;
      out[k] = P2{std::cos(phi), std::sin(phi)};
    }
    return out;
  }();
  for (int k = 0; k < 32; ++k) {
    const P2 dir = directions[k];
    if (upward_exits && dir.x * e1[2] + dir.y * e2[2] < -1e-9) continue;
    double out = 0;
    for (const Piece& pc : outline) {
      if (pc.reach <= out || out >= depth) break;
      // The ray s * dir, s >= 0, misses the piece's bounding circle.
      const double along = dot2(pc.centre, dir), across = cross2(dir, pc.centre);
      if (std::fabs(across) > pc.radius || along < -pc.radius) continue;
      out = std::max(out, exit_along(pc.q[0], pc.q[1], pc.q[2], dir));
    }
    if (out < depth) {
      depth = out;
      best_dir = dir;
    }
  }
  best.clearance = -depth / r1(blocked_t);
  best.edge = a + blocked_t * u + (depth * best_dir.x) * e1 + (depth * best_dir.y) * e2;
  return best;
}

// The reach of the first zone around the line a + t u, t in [0, d], near
// a sphere: the zone radius at the sphere's axial point nearest mid-path
// (r1 is largest there), or -1 when the sphere cannot come within it.
double zone_reach(const TraceScene::Sphere& s, const Vec3& a, const Vec3& u, double d, double lambda,
                  const FresnelZone& zone) {
  const Vec3 w = s.centre - a;
  const double t = dot(w, u);
  if (t < -s.radius || t > d + s.radius) return -1.0;
  const double t_mid = zone.widest(std::clamp(t - s.radius, 0.0, d), std::clamp(t + s.radius, 0.0, d));
  const double sm = zone.before + t_mid;
  const double reach = std::sqrt(lambda * sm * (zone.total - sm) / zone.total);
  return dot(w, w) - t * t <= (s.radius + reach) * (s.radius + reach) ? reach : -1.0;
}

}  // namespace

FresnelObstacles::FresnelObstacles(const TraceScene& scene) {
  auto sphere_of = [](const std::vector<std::array<Vec3, 3>>& tris) {
    Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (const auto& t : tris)
      for (const auto& p : t)
        for (int k = 0; k < 3; ++k) {
          lo[k] = std::min(lo[k], p[k]);
          hi[k] = std::max(hi[k], p[k]);
        }
    return TraceScene::Sphere{0.5 * (lo + hi), 0.5 * norm(hi - lo)};
  };
  for (std::size_t v = 0; v < scene.vehicles().size(); ++v) {
    Obstacle o;
    o.vehicle = true;
    const auto inst = static_cast<std::uint32_t>(v + 1);
    for (std::uint32_t face = 0; face < scene.face_count(inst); ++face) {
      o.face_begin.push_back(static_cast<std::uint32_t>(o.triangles.size()));
      o.face_spheres.push_back(scene.face_sphere({inst, face}));
      scene.face_triangles({inst, face}, o.triangles);
    }
    o.face_begin.push_back(static_cast<std::uint32_t>(o.triangles.size()));
    o.sphere = scene.vehicle_sphere(v);
    obstacles_.push_back(std::move(o));
  }
  std::vector<std::pair<std::uint32_t, std::uint32_t>> faces;  // (object, face)
  for (std::uint32_t face = 0; face < scene.face_count(0); ++face)
    if (!scene.is_ground(face)) faces.emplace_back(scene.object({0, face}), face);
  std::sort(faces.begin(), faces.end());
  for (std::size_t i = 0; i < faces.size();) {
    Obstacle o;
    std::size_t j = i;
    for (; j < faces.size() && faces[j].first == faces[i].first; ++j) {
      o.face_begin.push_back(static_cast<std::uint32_t>(o.triangles.size()));
      o.face_spheres.push_back(scene.face_sphere({0, faces[j].second}));
      scene.face_triangles({0, faces[j].second}, o.triangles);
    }
    o.face_begin.push_back(static_cast<std::uint32_t>(o.triangles.size()));
    o.sphere = sphere_of(o.triangles);
    obstacles_.push_back(std::move(o));
    i = j;
  }
}

FresnelObstruction FresnelObstacles::between(const Vec3& a, const Vec3& b, double lambda, int skip_a,
                                             int skip_b) const {
  FresnelObstruction f;
  const double d = norm(b - a);
  if (!(d > 0)) return f;
  const Vec3 u = (1.0 / d) * (b - a);
  const Vec3 e1 = any_perpendicular(u), e2 = cross(u, e1);
  std::vector<NearFace> near;
  for (std::size_t k = 0; k < obstacles_.size(); ++k) {
    const Obstacle& o = obstacles_[k];
    if (o.vehicle && (static_cast<int>(k) == skip_a || static_cast<int>(k) == skip_b)) continue;
    double& worst = o.vehicle ? f.vehicle_clearance : f.static_clearance;
    if (!near_faces(o, a, u, d, lambda, FresnelZone{0, d}, near)) continue;
    worst = std::min(worst, obstacle_clearance(o.triangles, o.face_begin, near, a, u, e1, e2, d, lambda,
                                               std::min(worst, 1.0), FresnelZone{0, d}).clearance);
  }
  f.vehicle_clearance = std::min(f.vehicle_clearance, 1.0);
  f.static_clearance = std::min(f.static_clearance, 1.0);
  f.clearance = std::min(f.vehicle_clearance, f.static_clearance);
  return f;
}

double FresnelObstacles::vehicle_clearance(const Vec3& a, const Vec3& b, double lambda, int v) const {
  const double d = norm(b - a);
  if (!(d > 0) || v < 0 || static_cast<std::size_t>(v) >= obstacles_.size() || !obstacles_[v].vehicle) return 1;
  const Vec3 u = (1.0 / d) * (b - a);
  const Vec3 e1 = any_perpendicular(u), e2 = cross(u, e1);
  std::vector<NearFace> near;
  const Obstacle& o = obstacles_[v];
  if (!near_faces(o, a, u, d, lambda, FresnelZone{0, d}, near)) return 1;
  return std::min(1.0, obstacle_clearance(o.triangles, o.face_begin, near, a, u, e1, e2, d, lambda, 1.0,
                                          FresnelZone{0, d}).clearance);
}

bool FresnelObstacles::near_faces(const Obstacle& o, const Vec3& a, const Vec3& u, double d, double lambda,
                                  const FresnelZone& zone, std::vector<NearFace>& near) const {
  near.clear();
  const double reach = zone_reach(o.sphere, a, u, d, lambda, zone);  // bounds r1 over every face of the obstacle
  if (reach < 0) return false;
  // obstacle_clearance's r1 clamp, in line coordinates
  const double t_lo = 1e-3 * zone.total - zone.before, t_hi = zone.total - 1e-3 * zone.total - zone.before;
  for (std::size_t face = 0; face + 1 < o.face_begin.size(); ++face) {
    const auto& fs = o.face_spheres[face];
    const Vec3 w = fs.centre - a;
    const double t = dot(w, u), r = fs.radius + reach;
    const double h2 = dot(w, w) - t * t;
    if (t < -fs.radius || t > d + fs.radius || h2 > r * r) continue;
    // Every point of the face is at least h - radius from the line, where
    // r1 is at most its value at the point of [t - radius, t + radius]
    // nearest mid-path.
    const double gap = std::sqrt(std::max(0.0, h2)) - fs.radius;
    double bound = -1e300;
    if (gap > 0) {
      const double tm = zone.widest(std::clamp(t - fs.radius, t_lo, t_hi), std::clamp(t + fs.radius, t_lo, t_hi));
      bound = gap / zone.r1(tm, lambda);
    }
    near.push_back({bound, static_cast<std::uint32_t>(face)});
  }
  std::sort(near.begin(), near.end(), [](const NearFace& x, const NearFace& y) {
    return x.bound != y.bound ? x.bound < y.bound : x.face < y.face;
  });
  return !near.empty();
}

double knife_edge_loss_db(double v) {
  if (v <= kKnifeEdgeOnset) return 0;
  const double x = v - 0.1;
  return 6.9 + 20 * std::log10(std::sqrt(x * x + 1) + x);
}

KnifeEdges FresnelObstacles::vehicle_knife_edges(const Vec3& a, const Vec3& b, double lambda, int skip_a,
                                                 int skip_b) const {
  struct Edge {
    double v = -1e300;
    int k = -1;
    Vec3 point{0, 0, 0};
  };
  std::vector<NearFace> near;
  // The vehicle with the largest v over the line p -> q (`exclude` aside).
  auto main_edge = [&](const Vec3& p, const Vec3& q, int exclude) {
    Edge best;
    const double d = norm(q - p);
    if (!(d > 0)) return best;
    const Vec3 u = (1.0 / d) * (q - p);
    const Vec3 e1 = any_perpendicular(u), e2 = cross(u, e1);
    for (std::size_t k = 0; k < obstacles_.size(); ++k) {
      const Obstacle& o = obstacles_[k];
      const int ki = static_cast<int>(k);
      if (!o.vehicle || ki == skip_a || ki == skip_b || ki == exclude) continue;
      if (!near_faces(o, p, u, d, lambda, FresnelZone{0, d}, near)) continue;
      // Only a vehicle clearer than the best so far can be skipped.
      const double bound = best.k >= 0 ? -best.v / std::sqrt(2.0) : 1e300;
      const Clearance c =
          obstacle_clearance(o.triangles, o.face_begin, near, p, u, e1, e2, d, lambda, bound, FresnelZone{0, d});
      const double v = -std::sqrt(2.0) * c.clearance;
      if (v > best.v) best = Edge{v, ki, c.edge};
    }
    return best;
  };
  KnifeEdges out;
  const Edge m = main_edge(a, b, -1);
  if (m.k < 0 || m.v <= kKnifeEdgeOnset) return out;
  out.v_main = m.v;
  out.main_vehicle = m.k;
  out.loss_db = knife_edge_loss_db(m.v);
  out.edges = 1;
  // Deygout: the strongest edge, then the strongest on each side of it,
  // each over the path from its end to the main edge.
  for (const Edge& s : {main_edge(a, m.point, m.k), main_edge(m.point, b, m.k)}) {
    const double l = s.k >= 0 ? knife_edge_loss_db(s.v) : 0.0;
    if (l > 0) {
      out.loss_db += l;
      ++out.edges;
    }
  }
  return out;
}

KnifeEdges FresnelObstacles::path_knife_edges(const std::vector<Vec3>& points, const std::vector<int>& host,
                                              double lambda, int skip_a, int skip_b) const {
  KnifeEdges out;
  if (points.size() < 2 || host.size() != points.size()) return out;
  const std::size_t legs = points.size() - 1;
  std::vector<double> start(legs + 1, 0.0);  // path coordinate of each point
  for (std::size_t m = 0; m < legs; ++m) start[m + 1] = start[m] + norm(points[m + 1] - points[m]);
  const double length = start[legs];
  struct Edge {
    double v = -1e300;
    int k = -1;
    double s = 0;  // path coordinate of the edge's foot on the path
  };
  std::vector<NearFace> near;
  // The vehicle with the largest v over the part [sa, sb] of the path.
  auto main_edge = [&](double sa, double sb, int exclude) {
    Edge best;
    const double total = sb - sa;
    if (!(total > 0)) return best;
    for (std::size_t m = 0; m < legs; ++m) {
      const double l0 = std::max(sa, start[m]), l1 = std::min(sb, start[m + 1]);
      const double leg = start[m + 1] - start[m];
      if (!(l1 > l0) || !(leg > 0)) continue;
      const Vec3 u = (1.0 / leg) * (points[m + 1] - points[m]);
      const Vec3 p = points[m] + (l0 - start[m]) * u;
      const double d = l1 - l0;
      const Vec3 e1 = any_perpendicular(u), e2 = cross(u, e1);
      const FresnelZone zone{l0 - sa, total};
      for (std::size_t k = 0; k < obstacles_.size(); ++k) {
        const Obstacle& o = obstacles_[k];
        const int ki = static_cast<int>(k);
        if (!o.vehicle || ki == skip_a || ki == skip_b || ki == exclude || ki == host[m] || ki == host[m + 1])
          continue;
        if (!near_faces(o, p, u, d, lambda, zone, near)) continue;
        const double bound = best.k >= 0 ? -best.v / std::sqrt(2.0) : 1e300;
        const Clearance c =
            obstacle_clearance(o.triangles, o.face_begin, near, p, u, e1, e2, d, lambda, bound, zone, true);
        const double v = -std::sqrt(2.0) * c.clearance;
        if (v > best.v) best = Edge{v, ki, l0 + std::clamp(dot(c.edge - p, u), 0.0, d)};
      }
    }
    return best;
  };
  const Edge m = main_edge(0, length, -1);
  if (m.k < 0 || m.v <= kKnifeEdgeOnset) return out;
  out.v_main = m.v;
  out.main_vehicle = m.k;
  out.loss_db = knife_edge_loss_db(m.v);
  out.edges = 1;
  for (const Edge& e : {main_edge(0, m.s, m.k), main_edge(m.s, length, m.k)}) {
    const double l = e.k >= 0 ? knife_edge_loss_db(e.v) : 0.0;
    if (l > 0) {
      out.loss_db += l;
      ++out.edges;
    }
  }
  return out;
}

FresnelObstruction fresnel_obstruction(const TraceScene& scene, const Vec3& a, const Vec3& b, double lambda, int skip_a,
                                       int skip_b) {
  return FresnelObstacles(scene).between(a, b, lambda, skip_a, skip_b);
}

LosClass fresnel_class(LosClass geometric, const FresnelObstruction& f) {
  if (geometric == LosClass::NLOS || f.static_clearance < kFresnelZoneFraction) return LosClass::NLOS;
  if (geometric == LosClass::NLOSV || f.vehicle_clearance < kFresnelZoneFraction) return LosClass::NLOSV;
  return LosClass::LOS;
}

}  // namespace raysweep::tracer
