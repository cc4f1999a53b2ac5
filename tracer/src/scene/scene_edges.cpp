#include "scene/scene_edges.hpp"

#include <tbb/parallel_for.h>

#include <map>

#include "scene/scene_impl.hpp"
#include "tracer/em/constants.hpp"

namespace raysweep::tracer {

namespace {

// Edges turning by less are not wedges (extract_edges).
constexpr double kMinTurn = 10.0 * kPi / 180.0;

// Whether x lies inside a static solid: the nearest face straight up is
// seen from behind (a building's roof from inside). Not down or sideways:
// floors lie on the ground plane and touching buildings' walls coincide, so
// the nearest face there is either of two. A roofless mesh reads as outside.
bool inside_solid(const TraceScene& scene, const Vec3& x) {
  const Vec3 up{0, 0, 1};
  Hit hit;
  return scene.closest_hit(x, up, 0, std::numeric_limits<double>::infinity(), hit) &&
         dot(scene.plane(hit.face).normal, up) > 0;
}

// A point of an edge is buried when another solid fills part of the
// exterior wedge next to it: two buildings that touch (row houses, OSM
// footprints sharing a wall) keep each other's corners inside the block,
// where the meshes still carry them as wedges (a corner where the fronts are
// flush, a lower roof's edge along its taller neighbour's wall). Probes
// across the exterior wedge, kProbeReach from the edge.
constexpr int kProbes = 6;
constexpr double kProbeReach = 0.05;
bool buried(const TraceScene& scene, const Edge& e, const Vec3& p) {
  for (int k = 0; k < kProbes; ++k) {
    const double phi = (k + 0.5) / kProbes * e.n * kPi;
    if (inside_solid(scene, p + kProbeReach * (std::cos(phi) * e.t0 + std::sin(phi) * e.n0))) return true;
  }
  return false;
}

// exposed_parts' probe spacing along an edge and the bisection's tolerance.
constexpr double kProbeSpacing = 0.5;
constexpr double kCutTolerance = 1e-3;

}  // namespace

std::vector<Edge> extract_edges(const TraceScene::Shape& s, const std::vector<std::string>& object_names,
                                bool floor_on_ground) {
  // Vertex ids by position on a 0.1 mm grid.
  std::map<std::array<long long, 3>, std::uint32_t> grid;
  std::vector<std::uint32_t> canon(s.vertices.size());
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    std::array<long long, 3> key;
    for (int k = 0; k < 3; ++k) key[k] = std::llround(s.vertices[i][k] * 1e4);
    canon[i] = grid.try_emplace(key, static_cast<std::uint32_t>(i)).first->second;
  }
  struct Side {
    std::uint32_t tri;
    std::uint32_t face;
    std::uint32_t third;  // vertex opposite the edge
  };
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<Side>> sides;
  for (std::uint32_t t = 0; t < s.triangles.size(); ++t) {
    const auto& tri = s.triangles[t];
    for (int k = 0; k < 3; ++k) {
      std::uint32_t u = canon[tri[k]], v = canon[tri[(k + 1) % 3]];
      if (u == v) continue;
      if (u > v) std::swap(u, v);
      sides[{u, v}].push_back(Side{t, s.tri_face[t], tri[(k + 2) % 3]});
    }
  }
  auto is_floor = [&](std::uint32_t f) {
    const Plane& pl = s.face_plane[f];
    return pl.normal[2] < -0.9 && (!floor_on_ground || pl.offset / pl.normal[2] < 0.02);
  };
  auto is_ground = [&](std::uint32_t f) {
    const auto o = s.face_object[f];
    return o < object_names.size() && object_names[o] == "ground";
  };
  // Direction from the edge into the face of `side`, perpendicular to the edge.
  auto inward = [&](const Vec3& p, const Vec3& dir, const Side& side) {
    const Vec3 w = s.vertices[side.third] - p;
    return normalize(w - dot(w, dir) * dir);
  };
  std::vector<Edge> pieces;
  for (const auto& [uv, list] : sides) {
    const Vec3 p = s.vertices[uv.first], q = s.vertices[uv.second];
    if (norm(q - p) < 1e-6) continue;
    const Vec3 dir = normalize(q - p);
    Edge e;
    if (list.size() == 1) {
      const std::uint32_t f = list[0].face;
      if (is_ground(f) || is_floor(f)) continue;
      e.face0 = e.face_n = FaceRef{0, f};
      e.t0 = inward(p, dir, list[0]);
      e.n0 = s.face_plane[f].normal;
      e.n = 2;
    } else if (list.size() == 2 && list[0].face != list[1].face) {
      const Side &A = list[0], &B = list[1];
      if (is_floor(A.face) || is_floor(B.face) || is_ground(A.face) || is_ground(B.face)) continue;
      const Vec3 ta = inward(p, dir, A), tb = inward(p, dir, B);
      const Vec3 na = s.face_plane[A.face].normal, nb = s.face_plane[B.face].normal;
      double ext = std::atan2(dot(tb, na), dot(tb, ta));
      if (ext <= 0) ext += 2 * kPi;
      if (ext < kPi + kMinTurn || ext > 2 * kPi - 1e-9) continue;  // concave, flat or a fold
      // Face n's normal must point into the exterior (at angle ext - pi/2):
      // meshes whose windings disagree have no well-defined outside here.
      const Vec3 expect = std::cos(ext - kPi / 2) * ta + std::sin(ext - kPi / 2) * na;
      if (dot(nb, expect) < 0.5) continue;
      e.face0 = FaceRef{0, A.face};
      e.face_n = FaceRef{0, B.face};
      e.t0 = ta;
      e.n0 = na;
      e.n = ext / kPi;
    } else {
      continue;  // inside a planar face, or non-manifold
    }
    e.e = normalize(cross(e.t0, e.n0));
    const bool forward = dot(e.e, dir) > 0;
    e.a = forward ? p : q;
    e.b = forward ? q : p;
    e.object = s.face_object[e.face0.face];
    e.material0 = s.face_material[e.face0.face];
    e.material_n = s.face_material[e.face_n.face];
    pieces.push_back(e);
  }
  // Merge collinear pieces of the same face pair, so a diffraction point on
  // the seam of two triangles is found once.
  std::sort(pieces.begin(), pieces.end(), [](const Edge& x, const Edge& y) {
    if (x.face0 != y.face0) return x.face0 < y.face0;
    if (x.face_n != y.face_n) return x.face_n < y.face_n;
    return dot(x.a, x.e) < dot(y.a, y.e);
  });
  std::vector<Edge> edges;
  for (const auto& e : pieces) {
    if (!edges.empty()) {
      Edge& last = edges.back();
      const Vec3 w = e.a - last.a;
      const double off = norm(w - dot(w, last.e) * last.e);
      if (last.face0 == e.face0 && last.face_n == e.face_n && dot(e.e, last.e) > 1 - 1e-9 && off < 1e-4 &&
          dot(e.a - last.b, last.e) < 1e-4) {
        if (dot(e.b - last.b, last.e) > 0) last.b = e.b;
        continue;
      }
    }
    edges.push_back(e);
  }
  return edges;
}

std::vector<Edge> exposed_parts(const TraceScene& scene, const std::vector<Edge>& edges) {
  std::vector<std::vector<Edge>> parts(edges.size());
  tbb::parallel_for(std::size_t{0}, edges.size(), [&](std::size_t i) {
    const Edge& e = edges[i];
    const double len = norm(e.b - e.a);
    const int n = std::clamp(static_cast<int>(std::ceil(len / kProbeSpacing)), 2, 4096);
    auto at = [&](double z) { return e.a + z * e.e; };
    auto z_of = [&](int k) { return (k + 0.5) * len / n; };
    std::vector<char> hidden(n);
    bool any = false;
    for (int k = 0; k < n; ++k) any |= (hidden[k] = buried(scene, e, at(z_of(k))));
    if (!any) {
      parts[i].push_back(e);
      return;
    }
    auto emit = [&](double z0, double z1) {
      if (z1 - z0 < kCutTolerance) return;
      Edge piece = e;
      piece.a = at(z0);
      piece.b = at(z1);
      parts[i].push_back(piece);
    };
    double start = 0;
    for (int k = 1; k < n; ++k) {
      if (hidden[k] == hidden[k - 1]) continue;
      double lo = z_of(k - 1), hi = z_of(k);  // lo has hidden[k - 1]'s state
      while (hi - lo > kCutTolerance) {
        const double mid = 0.5 * (lo + hi);
        (buried(scene, e, at(mid)) == static_cast<bool>(hidden[k - 1]) ? lo : hi) = mid;
      }
      const double cut = 0.5 * (lo + hi);
      if (hidden[k - 1]) start = cut;
      else emit(start, cut);
    }
    if (!hidden[n - 1]) emit(start, len);
  });
  std::vector<Edge> out;
  for (auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

const std::vector<Edge>& TraceScene::edges() const { return impl_->edges; }

void TraceScene::vehicle_edges(std::size_t v, std::vector<Edge>& out) const {
  const auto& d = *impl_;
  const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
  const Vec3& at = vehicles_[v].position;
  auto turn = [&](const Vec3& x) { return Vec3{c * x[0] - sn * x[1], sn * x[0] + c * x[1], x[2]}; };
  const auto inst = static_cast<std::uint32_t>(v + 1);
  for (Edge e : d.models[vehicles_[v].model]->model_edges) {
    e.a = turn(e.a) + at;
    e.b = turn(e.b) + at;
    e.e = turn(e.e);
    e.t0 = turn(e.t0);
    e.n0 = turn(e.n0);
    e.face0.instance = e.face_n.instance = inst;
    e.object = vehicle_object(v);
    out.push_back(e);
  }
}

}  // namespace raysweep::tracer
