#include "search/face_index.hpp"

#include <algorithm>
#include <array>

namespace raysweep::tracer {

namespace {

// Convex hull of a face's vertices in its plane (Andrew's monotone chain),
// appended to `out` counter-clockwise about the normal.
void convex_outline(const std::vector<std::array<Vec3, 3>>& tris, const Plane& pl, std::vector<Vec3>& out) {
  const Vec3 e1 = any_perpendicular(pl.normal), e2 = cross(pl.normal, e1);
  struct Q {
    double x, y;
    Vec3 p;
  };
  std::vector<Q> pts;
  for (const auto& t : tris)
    for (const auto& p : t) pts.push_back({dot(p, e1), dot(p, e2), p});
  std::sort(pts.begin(), pts.end(), [](const Q& a, const Q& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  auto turn = [](const Q& o, const Q& a, const Q& b) { return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x); };
  std::vector<Q> hull;
  for (int pass = 0; pass < 2; ++pass) {
    const std::size_t start = hull.size();
    for (std::size_t k = 0; k < pts.size(); ++k) {
      const Q& q = pass == 0 ? pts[k] : pts[pts.size() - 1 - k];
      while (hull.size() >= start + 2 && turn(hull[hull.size() - 2], hull.back(), q) <= 0) hull.pop_back();
      hull.push_back(q);
    }
    hull.pop_back();
  }
  for (const auto& q : hull) out.push_back(q.p);
}

// ImageFaces::ground_planes from ImageFaces::ground. Bitwise equality only,
// so that a plane's mirror images are bitwise each face's own (negating a
// normal and its offset negates a distance and leaves every image and
// crossing point as it was).
void group_ground_planes(ImageFaces& t) {
  for (const std::uint32_t g : t.ground) {
    const Plane& pg = t.planes[g];
    auto same = [&](const ImageFaces::GroundPlane& gp, double sign) {
      return pg.offset == sign * gp.plane.offset && pg.normal[0] == sign * gp.plane.normal[0] &&
             pg.normal[1] == sign * gp.plane.normal[1] && pg.normal[2] == sign * gp.plane.normal[2];
    };
    auto it = std::find_if(t.ground_planes.begin(), t.ground_planes.end(),
                           [&](const auto& gp) { return same(gp, 1) || same(gp, -1); });
    if (it == t.ground_planes.end()) it = t.ground_planes.insert(it, {pg, {}, {}});
    it->faces.push_back(g);
    it->flipped.push_back(same(*it, 1) ? 0 : 1);
  }
}

}  // namespace

void build_sphere_tree(const std::vector<TraceScene::Sphere>& spheres, const std::vector<double>& tols,
                       std::vector<ImageFaces::SphereNode>& tree, std::vector<std::uint32_t>& order, std::uint32_t b,
                       std::uint32_t e) {
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (std::uint32_t k = b; k < e; ++k) {
    const auto& s = spheres[order[k]];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], s.centre[a] - s.radius);
      hi[a] = std::max(hi[a], s.centre[a] + s.radius);
    }
  }
  ImageFaces::SphereNode node;
  node.sphere.centre = 0.5 * (lo + hi);
  for (std::uint32_t k = b; k < e; ++k) {
    const auto f = order[k];
    const auto& s = spheres[f];
    node.sphere.radius = std::max(node.sphere.radius, norm(s.centre - node.sphere.centre) + s.radius);
    node.tol = std::max(node.tol, tols[f]);
  }
  const std::size_t at = tree.size();
  tree.push_back(node);
  if (e - b <= 4) {
    tree[at].begin = b;
    tree[at].count = e - b;
    return;
  }
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (hi[a] - lo[a] > hi[axis] - lo[axis]) axis = a;
  const std::uint32_t mid = b + (e - b) / 2;
  // Ties broken by index: the same tree on every run.
  std::nth_element(order.begin() + b, order.begin() + mid, order.begin() + e, [&](std::uint32_t x, std::uint32_t y) {
    const double cx = spheres[x].centre[axis], cy = spheres[y].centre[axis];
    return cx < cy || (cx == cy && x < y);
  });
  build_sphere_tree(spheres, tols, tree, order, b, mid);
  tree[at].right = static_cast<std::uint32_t>(tree.size());
  build_sphere_tree(spheres, tols, tree, order, mid, e);
}

ImageFaces image_faces(const TraceScene& scene) {
  ImageFaces t;
  const std::uint32_t instances = static_cast<std::uint32_t>(scene.vehicles().size() + 1);
  for (std::uint32_t inst = 0; inst < instances; ++inst) {
    const auto nf = static_cast<std::uint32_t>(scene.face_count(inst));
    for (std::uint32_t f = 0; f < nf; ++f) {
      const FaceRef ref{inst, f};
      t.refs.push_back(ref);
      t.planes.push_back(scene.plane(ref));
      t.spheres.push_back(scene.face_sphere(ref));
      // Generous against Embree's float rounding (the exact path's own ray
      // test decides) and a bent "planar" face's deviation from its plane.
      const auto& s = t.spheres.back();
      t.tol.push_back(2 * scene.slack(s.centre, s.radius) + 2 * scene.flatness(ref));
    }
    if (inst == 0) t.static_count = static_cast<std::uint32_t>(t.refs.size());
    t.vehicle_begin.push_back(static_cast<std::uint32_t>(t.refs.size()));
  }
  for (std::size_t v = 0; v < scene.vehicles().size(); ++v) t.vehicle_spheres.push_back(scene.vehicle_sphere(v));
  auto& bs = t.beam_spheres;
  auto push_sphere = [&](const TraceScene::Sphere& sp, double tol) {
    bs.x.push_back(sp.centre[0]);
    bs.y.push_back(sp.centre[1]);
    bs.z.push_back(sp.centre[2]);
    bs.r.push_back(sp.radius);
    bs.tol.push_back(tol);
  };
  for (std::size_t f = t.vehicle_begin.front(); f < t.refs.size(); ++f) push_sphere(t.spheres[f], t.tol[f]);
  t.beam_vehicles_begin = static_cast<std::uint32_t>(bs.x.size());
  for (const auto& sv : t.vehicle_spheres) push_sphere(sv, 0);
  for (std::uint32_t f = 0; f < t.static_count; ++f)
    if (scene.is_ground(f)) t.ground.push_back(f);
  group_ground_planes(t);
  for (std::uint32_t f = 0; f < t.static_count; ++f)
    if (t.spheres[f].radius < ImageFaces::kSmallFace) t.small.push_back(f);
  std::vector<std::array<Vec3, 3>> tris;
  for (std::uint32_t f = 0; f < t.static_count; ++f) {
    t.outline_begin.push_back(static_cast<std::uint32_t>(t.outline.size()));
    tris.clear();
    scene.face_triangles(t.refs[f], tris);
    convex_outline(tris, t.planes[f], t.outline);
    t.vertex_begin.push_back(static_cast<std::uint32_t>(t.vertices.size()));
    for (const auto& tr : tris) t.vertices.insert(t.vertices.end(), tr.begin(), tr.end());
    std::sort(t.vertices.begin() + t.vertex_begin.back(), t.vertices.end());
    t.vertices.erase(std::unique(t.vertices.begin() + t.vertex_begin.back(), t.vertices.end()), t.vertices.end());
    t.off_plane.push_back(1e-9 + scene.flatness(t.refs[f]));
    // Convex when the triangles fill their convex outline.
    double area = 0, hull = 0;
    for (const auto& tr : tris) area += 0.5 * norm(cross(tr[1] - tr[0], tr[2] - tr[0]));
    const std::uint32_t o0 = t.outline_begin.back(), o1 = static_cast<std::uint32_t>(t.outline.size());
    for (std::uint32_t k = o0 + 1; k + 1 < o1; ++k)
      hull += 0.5 * norm(cross(t.outline[k] - t.outline[o0], t.outline[k + 1] - t.outline[o0]));
    t.convex.push_back(o1 - o0 >= 3 && hull <= area * (1 + 1e-9) + 1e-12);
  }
  t.outline_begin.push_back(static_cast<std::uint32_t>(t.outline.size()));
  t.outline_inward.resize(t.outline.size());
  for (std::uint32_t f = 0; f < t.static_count; ++f) {
    const std::uint32_t o0 = t.outline_begin[f], o1 = t.outline_begin[f + 1];
    for (std::uint32_t k = o0; k < o1; ++k) {
      const Vec3 side = t.outline[k + 1 < o1 ? k + 1 : o0] - t.outline[k];
      const double len = norm(side);
      t.outline_inward[k] = len > 0 ? (1.0 / len) * cross(t.planes[f].normal, side) : Vec3{0, 0, 0};
    }
    // A side of no length starts where the next one does: that side's
    // constraint is its own (a face of no sides at all stays all zero and
    // holds no point deep inside).
    for (std::uint32_t k = o1; k-- > o0;) {
      const Vec3& u = t.outline_inward[k];
      const std::uint32_t next = k + 1 < o1 ? k + 1 : o0;
      if (u[0] == 0 && u[1] == 0 && u[2] == 0 && next != k) t.outline_inward[k] = t.outline_inward[next];
    }
  }
  t.vertex_begin.push_back(static_cast<std::uint32_t>(t.vertices.size()));
  t.static_order.resize(t.static_count);
  for (std::uint32_t f = 0; f < t.static_count; ++f) t.static_order[f] = f;
  if (t.static_count > 0) build_sphere_tree(t.spheres, t.tol, t.static_tree, t.static_order, 0, t.static_count);
  // The diffracting edges: each one's sphere, and a tree over them.
  const auto& edges = scene.edges();
  for (const Edge& e : edges) t.edge_spheres.push_back({0.5 * (e.a + e.b), 0.5 * norm(e.b - e.a)});
  const std::vector<double> no_tol(edges.size(), 0.0);
  t.edge_order.resize(edges.size());
  for (std::uint32_t k = 0; k < edges.size(); ++k) t.edge_order[k] = k;
  if (!edges.empty())
    build_sphere_tree(t.edge_spheres, no_tol, t.edge_tree, t.edge_order, 0, static_cast<std::uint32_t>(edges.size()));
  return t;
}

}  // namespace raysweep::tracer
