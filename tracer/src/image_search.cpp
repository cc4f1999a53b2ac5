#include "image_search.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include <tbb/parallel_for.h>

namespace raysweep::tracer {

namespace {

// Where the line from image `img` (signed distance `d_img` from the plane)
// to `target` (signed distance `d_t`, opposite sign) crosses the plane.
Vec3 crossing(const Vec3& img, double d_img, const Vec3& target, double d_t) {
  const double s = d_img / (d_img - d_t);
  return img + s * (target - img);
}

// The cone from `apex` containing sphere `s`: sine and cosine of its
// half-angle and its unit axis; false when the apex is inside the sphere.
struct Cone {
  Vec3 axis{0, 0, 1};
  double sin_h = 1, cos_h = 0;
};
bool cone_to(const Vec3& apex, const TraceScene::Sphere& s, Cone& c) {
  const Vec3 w = s.centre - apex;
  const double d = norm(w);
  if (d <= s.radius) return false;
  c.axis = (1.0 / d) * w;
  c.sin_h = s.radius / d;
  c.cos_h = std::sqrt(1 - c.sin_h * c.sin_h);
  return true;
}
// Whether two cones from one apex overlap (half-angles summed < pi).
bool cones_overlap(const Cone& a, const Cone& b) {
  const double cos_angle = dot(a.axis, b.axis);
  const double cos_sum = a.cos_h * b.cos_h - a.sin_h * b.sin_h;  // cos(h_a + h_b)
  if (a.cos_h * b.cos_h - a.sin_h * b.sin_h < -1 + 1e-12) return true;
  // cos_sum < 0 with h_a + h_b > pi cannot happen (both < pi / 2).
  return cos_angle >= cos_sum - 1e-12;
}

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

// Builds a sphere tree over items order[b, e) (spheres[i], tol[i]) into
// `tree`: median split on the longest axis of the spheres' box, four items
// per leaf. Each node's sphere holds its items' spheres; its tol is their
// largest.
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
    // Convex when the triangles fill their convex outline.
    double area = 0, hull = 0;
    for (const auto& tr : tris) area += 0.5 * norm(cross(tr[1] - tr[0], tr[2] - tr[0]));
    const std::uint32_t o0 = t.outline_begin.back(), o1 = static_cast<std::uint32_t>(t.outline.size());
    for (std::uint32_t k = o0 + 1; k + 1 < o1; ++k)
      hull += 0.5 * norm(cross(t.outline[k] - t.outline[o0], t.outline[k + 1] - t.outline[o0]));
    t.convex.push_back(o1 - o0 >= 3 && hull <= area * (1 + 1e-9) + 1e-12);
  }
  t.outline_begin.push_back(static_cast<std::uint32_t>(t.outline.size()));
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

bool image_complete(const TraceScene& scene, const ImageFaces& faces, const std::vector<FaceRef>& seq,
                    bool ground_order3) {
  if (seq.size() == 1) return true;
  auto is_ground = [&](const FaceRef& f) {
    return f.instance == 0 && std::binary_search(faces.ground.begin(), faces.ground.end(), f.face);
  };
  if (seq.size() == 3)
    return ground_order3 && !scene.is_vehicle(seq[0]) && !scene.is_vehicle(seq[1]) && !scene.is_vehicle(seq[2]) &&
           (is_ground(seq[0]) || is_ground(seq[1]) || is_ground(seq[2]));
  if (seq.size() != 2) return false;
  const bool v0 = scene.is_vehicle(seq[0]), v1 = scene.is_vehicle(seq[1]);
  if (!v0 && !v1) return true;
  if (v0 == v1) return false;  // two vehicle faces
  // Ground and a vehicle; a wall and a vehicle come from the rays' beams.
  const FaceRef& st = v0 ? seq[1] : seq[0];
  return std::binary_search(faces.ground.begin(), faces.ground.end(), st.face);
}

namespace {

// Faces of vehicle v that can reflect from point `a` to point `b`: the
// reflection point lies in the vehicle's sphere, so the directions to a and
// b are within asin(R / distance) of those from its centre, and the face
// normal within delta of their bisector (sin delta <= (alpha + beta) / |u_a + u_b|).
// With an end inside the sphere every face is returned (cos_delta = -1).
// The window itself (its half-angle's cosine and sine): false (any face,
// cos_delta = -1) when it is void.
bool normal_window(const TraceScene::Sphere& sv, const Vec3& a, const Vec3& b, Vec3& bisector, double& cos_delta,
                   double& sin_delta) {
  const Vec3 wa = a - sv.centre, wb = b - sv.centre;
  const double da = norm(wa), db = norm(wb);
  cos_delta = -1;
  sin_delta = 1;
  bisector = Vec3{0, 0, 1};
  if (da <= sv.radius || db <= sv.radius) return false;
  const Vec3 m = (1.0 / da) * wa + (1.0 / db) * wb;
  const double lm = norm(m);
  // asin(x) <= x pi / 2 on [0, 1].
  const double eps = (kPi / 2) * (sv.radius / da + sv.radius / db);
  if (eps >= lm) return false;
  bisector = (1.0 / lm) * m;
  sin_delta = eps / lm;
  cos_delta = std::sqrt(1 - sin_delta * sin_delta);
  return true;
}
const std::vector<std::uint32_t>& faces_towards(const TraceScene& scene, const TraceScene::Sphere& sv, std::size_t v,
                                                const Vec3& a, const Vec3& b, Vec3& bisector, double& cos_delta) {
  double sin_delta;
  if (!normal_window(sv, a, b, bisector, cos_delta, sin_delta))
    return scene.vehicle_faces_near_normal(v, bisector, 10.0);
  return scene.vehicle_faces_near_normal(v, bisector, std::asin(sin_delta));
}

}  // namespace

namespace {

// Receivers in structure-of-arrays form, relative to the source (so the
// branch-free passes below vectorise and stay exact at city offsets).
struct Receivers {
  static constexpr std::size_t kLanes = 8;
  std::vector<double> x, y, z;  // padded to whole lanes with NaN (never marked)
  std::vector<std::int64_t> hit;  // 0 or 1; as wide as a lane, so no packing to bytes
  std::size_t n = 0;
  std::size_t size() const { return n; }
  void push(const Vec3& w) {
    x.resize(n), y.resize(n), z.resize(n);
    x.push_back(w[0]);
    y.push_back(w[1]);
    z.push_back(w[2]);
    ++n;
    pad();
  }
  void pad() {
    const std::size_t padded = (n + kLanes - 1) / kLanes * kLanes;
    x.resize(padded, std::numeric_limits<double>::quiet_NaN());
    y.resize(padded, std::numeric_limits<double>::quiet_NaN());
    z.resize(padded, std::numeric_limits<double>::quiet_NaN());
    hit.resize(padded);
  }
};

// The kernel of mark_crossings on raw arrays. Branch-free, so it
// vectorises; x86-64's baseline (SSE2) has no packed double-to-byte
// conversion, so an AVX-512 or AVX2 clone is chosen at load time where the
// CPU has it (eight or four receivers a vector: the receivers are padded to
// eight). AVX-512 carries FMA, so contraction is off: every clone computes
// bitwise the same flags.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("avx512f", "avx2", "default"), optimize("fp-contract=off")))
#endif
unsigned mark_crossings_kernel(const double* __restrict x, const double* __restrict y, const double* __restrict z,
                               std::int64_t* __restrict hit, std::size_t begin, std::size_t n, const double* nrm,
                               double plane_offset_rel, double ds, const double* img, const double* c, double r2) {
  const double nx = nrm[0], ny = nrm[1], nz = nrm[2];
  const double ix = img[0], iy = img[1], iz = img[2];
  // The crossing is img + s (x - img), s = ds / (ds + d); its offset from
  // the centre, scaled by den = ds + d, needs no division (a divide per
  // receiver was this loop's bottleneck): |den (img - c) + ds (x - img)|^2
  // <= r2 den^2. den != 0 wherever ds d > 0.
  const double ax = ix - c[0], ay = iy - c[1], az = iz - c[2];
  // Whole lanes only (the arrays are padded with NaN, which no test
  // passes): a scalar remainder loop cost as much as the vector body at
  // the few dozen receivers a source has. Lanes before `begin` are masked.
  constexpr std::size_t kLanes = Receivers::kLanes;
  const std::size_t from = begin / kLanes * kLanes, to = (n + kLanes - 1) / kLanes * kLanes;
  std::int64_t any = 0;
  for (std::size_t r = from; r < to; ++r) {
    const double d = nx * x[r] + ny * y[r] + nz * z[r] - plane_offset_rel;
    const double den = ds + d;
    const double px = den * ax + ds * (x[r] - ix), py = den * ay + ds * (y[r] - iy), pz = den * az + ds * (z[r] - iz);
    const std::int64_t in = static_cast<std::int64_t>(r >= begin) & static_cast<std::int64_t>(ds * d > 0) &
                            static_cast<std::int64_t>(px * px + py * py + pz * pz <= r2 * (den * den));
    hit[r] = in;
    any |= in;
  }
  return any != 0;
}

// Depth-first down a sphere tree (`order` its items): prune(sphere, tol)
// true skips a node and everything below it (its sphere and tol bound
// theirs); leaf(i) for each item of the leaves reached, in the tree's order.
template <class Prune, class Leaf>
void walk_tree(const std::vector<ImageFaces::SphereNode>& tree, const std::vector<std::uint32_t>& order,
               std::vector<std::uint32_t>& stack, Prune&& prune, Leaf&& leaf) {
  if (tree.empty()) return;
  stack.assign(1, 0);
  while (!stack.empty()) {
    const std::uint32_t at = stack.back();
    stack.pop_back();
    const auto& node = tree[at];
    if (prune(node.sphere, node.tol)) continue;
    if (node.count == 0) {
      stack.push_back(node.right);
      stack.push_back(at + 1);
      continue;
    }
    for (std::uint32_t k = node.begin; k < node.begin + node.count; ++k) leaf(order[k]);
  }
}
template <class Prune, class Leaf>
void walk_static_tree(const ImageFaces& faces, std::vector<std::uint32_t>& stack, Prune&& prune, Leaf&& leaf) {
  walk_tree(faces.static_tree, faces.static_order, stack, prune, leaf);
}

// The pyramid from `apex` through static face f's convex outline: one
// plane through the apex per outline edge, as inward unit normals, appended
// to `out` (none for a degenerate edge: conservative).
void outline_pyramid(const ImageFaces& faces, std::uint32_t f, const Vec3& apex, std::vector<Vec3>& out) {
  const std::uint32_t o0 = faces.outline_begin[f], o1 = faces.outline_begin[f + 1];
  if (o1 - o0 < 3) return;
  Vec3 centre{0, 0, 0};
  for (std::uint32_t k = o0; k < o1; ++k) centre = centre + faces.outline[k];
  centre = (1.0 / (o1 - o0)) * centre;
  for (std::uint32_t k = o0; k < o1; ++k) {
    const Vec3 a = faces.outline[k] - apex, b = faces.outline[k + 1 < o1 ? k + 1 : o0] - apex;
    Vec3 nrm = cross(a, b);
    const double l = norm(nrm);
    if (!(l > 1e-9 * norm(a) * norm(b))) continue;
    nrm = (1.0 / l) * nrm;
    if (dot(nrm, centre - apex) < 0) nrm = -nrm;
    out.push_back(nrm);
  }
}

// Whether sphere `sp`, grown by `tol`, lies wholly outside the pyramid of
// inward unit normals `planes` through `apex`, padded by `spread_per_m` per
// metre from the apex (the first face's on-face tolerance carried along
// its beam).
bool outside_pyramid(const std::vector<Vec3>& planes, const Vec3& apex, const TraceScene::Sphere& sp, double tol,
                     double spread_per_m) {
  const Vec3 w = sp.centre - apex;
  const double reach = sp.radius + tol + (spread_per_m + 1e-6) * (norm(w) + sp.radius);
  for (const auto& nrm : planes)
    if (dot(nrm, w) < -reach) return true;
  return false;
}

// Marks the receivers r whose line from image `img` (signed distance -ds
// from the plane, the source at +ds) crosses the plane inside `sphere`
// (+ tol): the cheap necessary part of "the reflection point is on the
// face". Returns whether any is marked. Inlined at every call: a wrapper
// call per image otherwise.
[[gnu::always_inline]] inline bool mark_crossings(const Receivers& rx, std::size_t begin, const Plane& pl,
                                                  double plane_offset_rel, double ds, const Vec3& img,
                                                  const TraceScene::Sphere& sphere, const Vec3& centre_rel, double tol,
                                                  Receivers& scratch) {
  const double r2 = (sphere.radius + tol) * (sphere.radius + tol);
  return mark_crossings_kernel(rx.x.data(), rx.y.data(), rx.z.data(), scratch.hit.data(), begin, rx.size(),
                               pl.normal.data(), plane_offset_rel, ds, img.data(), centre_rel.data(), r2) != 0;
}

// Which spheres k < n (columns x..tol) meet a beam: keep[k] = 1 when the
// sphere is not wholly behind the plane (p2n, p2off) seen from `side` and
// not wholly outside the pyramid of inward unit normals `planes` (np of
// them, x y z each) through `apex`, padded by spread_per_m per metre from
// the apex, 1e-6 per metre and the sphere's tol: beam_pair_candidates'
// scalar tests, sphere by sphere, over whole vectors of spheres. Contraction
// off in every clone, so the flags are bitwise the scalar tests'.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("avx512f", "avx2", "default"), optimize("fp-contract=off")))
#endif
void beam_keep_kernel(const double* __restrict x, const double* __restrict y, const double* __restrict z,
                      const double* __restrict r, const double* __restrict tol, std::size_t n, const double* planes,
                      std::size_t np, const double* apex, double spread_per_m, const double* p2n, double p2off,
                      double side, double* __restrict wx, double* __restrict wy, double* __restrict wz,
                      double* __restrict lim, std::int64_t* __restrict keep) {
  const double ax = apex[0], ay = apex[1], az = apex[2];
  const double nx = p2n[0], ny = p2n[1], nz = p2n[2];
  for (std::size_t k = 0; k < n; ++k) {
    wx[k] = x[k] - ax, wy[k] = y[k] - ay, wz[k] = z[k] - az;
    const double d = std::sqrt(wx[k] * wx[k] + wy[k] * wy[k] + wz[k] * wz[k]);
    const double pad = spread_per_m * (d + r[k]) + tol[k] + 1e-6 * (d + r[k]);
    lim[k] = -(r[k] + pad);
    keep[k] = static_cast<std::int64_t>(!(side * (nx * x[k] + ny * y[k] + nz * z[k] - p2off) + r[k] <= 0));
  }
  for (std::size_t p = 0; p < np; ++p) {
    const double px = planes[3 * p], py = planes[3 * p + 1], pz = planes[3 * p + 2];
    for (std::size_t k = 0; k < n; ++k)
      keep[k] &= static_cast<std::int64_t>(!(px * wx[k] + py * wy[k] + pz * wz[k] < lim[k]));
  }
}

// beam_keep_kernel over the spheres [begin, begin + count) of
// ImageFaces::beam_spheres, with its scratch kept between calls.
struct BeamSphereTest {
  std::vector<double> planes, wx, wy, wz, lim;
  // The pyramid's inward normals, as the kernel takes them.
  void set_pyramid(const std::vector<Vec3>& pyramid) {
    planes.clear();
    for (const auto& nrm : pyramid) planes.insert(planes.end(), nrm.begin(), nrm.end());
  }
  // keep[0, count): the spheres in the pyramid (set_pyramid) through `apex`
  // and not behind `plane` seen from `side` (a zero normal: no plane).
  void run(const ImageFaces& faces, std::uint32_t begin, std::uint32_t count, const Vec3& apex, double spread_per_m,
           const Plane& plane, double side, std::vector<std::int64_t>& keep) {
    if (keep.size() < count) keep.resize(count);
    if (lim.size() < count) wx.resize(count), wy.resize(count), wz.resize(count), lim.resize(count);
    const auto& c = faces.beam_spheres;
    beam_keep_kernel(c.x.data() + begin, c.y.data() + begin, c.z.data() + begin, c.r.data() + begin,
                     c.tol.data() + begin, count, planes.data(), planes.size() / 3, apex.data(), spread_per_m,
                     plane.normal.data(), plane.offset, side, wx.data(), wy.data(), wz.data(), lim.data(),
                     keep.data());
  }
};

}  // namespace

namespace {

// What one source's searches share: the source, its receivers relative to it
// (the vectorised passes' form), the on-face test and the counters.
class SourceSearch {
 public:
  SourceSearch(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes, std::uint32_t src,
               const std::vector<std::uint32_t>& receivers, std::vector<ImageCandidate>& out)
      : scene(scene), faces(faces), nodes(nodes), receivers(receivers), out(out), xs(nodes[src].position) {
    for (auto r : receivers) rx.push(nodes[r].position - xs);
    scratch.n = rx.size();
    scratch.pad();
  }
  void add_stats(ImageSearchStats* stats) const {
    if (stats) {
      stats->image_sources += local.image_sources;
      stats->tests += local.tests;
    }
  }

 protected:
  const TraceScene& scene;
  const ImageFaces& faces;
  const std::vector<Node>& nodes;
  const std::vector<std::uint32_t>& receivers;
  std::vector<ImageCandidate>& out;
  const Vec3 xs;
  // Everything relative to the source: the source is the origin.
  Receivers rx, scratch;
  ImageSearchStats local;

  // Inlined at every call (as the lambda it replaces was): it runs per
  // candidate point, and a call costs as much as its sphere test.
  [[gnu::always_inline]] inline bool on_face(std::size_t f, const Vec3& p) const {
    const Vec3 w = p - faces.spheres[f].centre;
    const double rr = faces.spheres[f].radius + faces.tol[f];
    return dot(w, w) <= rr * rr && scene.face_contains(faces.refs[f], p, faces.tol[f]);
  }
};

// image_candidates' search, one method per kind of sequence.
class ImageSearch : public SourceSearch {
 public:
  ImageSearch(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes, std::uint32_t src,
              const std::vector<std::uint32_t>& receivers, std::vector<ImageCandidate>& out, const SlabBounds* slabs)
      : SourceSearch(scene, faces, nodes, src, receivers, out),
        src(src),
        slabs(slabs),
        higher_from(
            static_cast<std::size_t>(std::upper_bound(receivers.begin(), receivers.end(), src) - receivers.begin())) {}

  // Order 1, static faces (towards higher receivers).
  void static_order1() {
    for (std::uint32_t f = 0; f < faces.static_count; ++f) {
      if (over_cap(f)) continue;
      const Plane& pl = faces.planes[f];
      const double off = pl.offset - dot(pl.normal, xs);  // plane offset relative to the source
      const double ds = -off;                              // the source's signed distance
      if (ds == 0) continue;  // the source on the plane sees no image
      const Vec3 img = (-2 * ds) * pl.normal;
      ++local.image_sources;
      local.tests += rx.size();
      if (!mark_crossings(rx, higher_from, pl, off, ds, img, faces.spheres[f], faces.spheres[f].centre - xs,
                          faces.tol[f], scratch))
        continue;
      for (std::size_t r = higher_from; r < rx.size(); ++r) {
        if (!scratch.hit[r] || over_cap(f, r, f)) continue;
        const Vec3 xr = receiver(r);
        const double d = dot(pl.normal, xr) - pl.offset;
        if (on_face(f, crossing(xs - (2 * ds) * pl.normal, -ds, xr, d)))
          out.push_back({receivers[r], {faces.refs[f]}});
      }
    }
  }

  // Order 1, vehicle faces, through their normals (towards higher receivers).
  void vehicle_order1() {
    for (std::size_t v = 0; v + 1 < faces.vehicle_begin.size(); ++v)
      for (std::size_t r = higher_from; r < rx.size(); ++r)
        vehicle_reflections(v, xs, r,
                            [&](std::size_t f, const Vec3&) { out.push_back({receivers[r], {faces.refs[f]}}); });
  }

  // Order 2, ground then vehicle (towards every receiver: from the other
  // end it is vehicle then ground).
  void ground_then_vehicle() {
    for (std::uint32_t g : faces.ground) {
      const Plane& pg = faces.planes[g];
      const double ds = dot(pg.normal, xs) - pg.offset;
      if (ds == 0) continue;
      const Vec3 i1 = xs - (2 * ds) * pg.normal;
      for (std::size_t v = 0; v + 1 < faces.vehicle_begin.size(); ++v) {
        const auto& sv = faces.vehicle_spheres[v];
        const double h = dot(pg.normal, sv.centre) - pg.offset;
        if (ds > 0 ? h + sv.radius <= 0 : h - sv.radius >= 0) continue;  // not on the source's side
        for (std::size_t r = 0; r < rx.size(); ++r)
          vehicle_reflections(v, i1, r, [&](std::size_t f, const Vec3& q2) {
            const double d2 = dot(pg.normal, q2) - pg.offset;
            if (ds * d2 > 0 && on_face(g, crossing(i1, -ds, q2, d2)))
              out.push_back({receivers[r], {faces.refs[g], faces.refs[f]}});
          });
      }
    }
  }

  // Orders 2 and 3 on one vehicle (its concave parts: hood and windscreen,
  // a truck's cab and box), towards every receiver not riding it: the face
  // sequences its model's table lists for the direction the wave arrives
  // from, each decided by its images and on-face tests. Not for the
  // source's own vehicle (the source sits inside its sphere).
  void on_one_vehicle(int max_order) {
    for (std::size_t v = 0; v + 1 < faces.vehicle_begin.size(); ++v) {
      if (static_cast<int>(v) == nodes[src].vehicle) continue;
      const auto& sv = faces.vehicle_spheres[v];
      const Vec3 w = sv.centre - xs;
      const double dist = norm(w);
      if (dist <= sv.radius) continue;
      const auto query = scene.vehicle_bounce_sequences(v, (1.0 / dist) * w, std::asin(sv.radius / dist));
      for (const std::uint32_t id : *query.ids) {
        const auto& sq = (*query.table)[id];
        if (sq.order > max_order) continue;
        bounce_sequence(v, sq);
      }
    }
  }

  // Order 2 over static faces: image I1 of the source in f1, then the image
  // I2 of I1 in f2; the receiver sees I2 through f2, and the line from I1 to
  // that point must cross f1.
  //
  // Order 3 through the ground (a static face, the ground and another, in
  // any order) with `ground3`, which shoot and bounce misses most of (a
  // wall's beam bent down by the ground passes the receivers' spheres at
  // grazing angles):
  // - the ground last: the receiver's image in the ground plane sees I2
  //   through f2, and the line from f2 to the receiver crosses the ground
  //   face. The mirrored receivers join the same vectorised pass, towards
  //   every receiver, so that the other end's search gives the ground first;
  // - the ground between f1 and f2: the beam f1 reflects, mirrored in the
  //   ground plane (apex I1', I1's image), walks the sphere tree as f1's own
  //   beam does, and I2 is the image of I1' in f2.
  void static_pairs(bool ground3) {
    static const std::vector<ImageFaces::GroundPlane> no_planes;
    grounds = ground3 ? &faces.ground_planes : &no_planes;
    mirror_receivers();
    for (std::uint32_t f1 = 0; f1 < faces.static_count; ++f1) from_first_face(f1);
  }

 private:
  const std::uint32_t src;
  const SlabBounds* slabs;        // null: no slab bounds
  const std::size_t higher_from;  // the first receiver above the source

  // Whether a first leg from the source to static face f1 (and a last leg
  // from static face fl to receiver r) cross more slabs than the cap.
  bool over_cap(std::uint32_t f1) const { return slabs && slabs->at(src, f1) > slabs->cap; }
  bool over_cap(std::uint32_t f1, std::size_t r, std::uint32_t fl) const {
    return slabs && slabs->at(src, f1) + slabs->at(receivers[r], fl) > slabs->cap;
  }
  // static_pairs' state: the ground planes for order 3 (none without it),
  // every receiver's image in each of them (relative to the source), the
  // beams' pyramids and the tree walk's stack.
  const std::vector<ImageFaces::GroundPlane>* grounds = nullptr;
  Receivers mirrored;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> mirrored_of;  // (ground plane, receiver index)
  std::vector<std::uint32_t> ground_set, ground_sub;  // ground faces of one plane still in play
  std::vector<Vec3> pyramid, pyramid_g;
  std::vector<std::uint32_t> tree_stack;

  Vec3 receiver(std::size_t r) const { return Vec3{rx.x[r], rx.y[r], rx.z[r]} + xs; }

  // The reflection on face f (world plane) from point `from` to receiver r,
  // appended when its point lies on the face.
  bool reflect_to(std::size_t f, const Vec3& from, const Vec3& xr, Vec3& point) {
    const Plane& pl = faces.planes[f];
    const double df = dot(pl.normal, from) - pl.offset;
    const double d = dot(pl.normal, xr) - pl.offset;
    if (!(df * d > 0)) return false;
    ++local.tests;
    point = crossing(from - (2 * df) * pl.normal, -df, xr, d);
    return on_face(f, point);
  }

  // Reflections on vehicle v's faces from `from` to receiver r: emit(face,
  // point) for each face whose reflection point lies on it, the faces taken
  // from the normal index.
  template <class Emit>
  void vehicle_reflections(std::size_t v, const Vec3& from, std::size_t r, Emit&& emit) {
    const Vec3 xr = receiver(r);
    Vec3 m;
    double cos_delta = -1;
    const auto& list = faces_towards(scene, faces.vehicle_spheres[v], v, from, xr, m, cos_delta);
    ++local.image_sources;
    for (auto lf : list) {
      const std::size_t f = faces.vehicle_begin[v] + lf;
      if (cos_delta > -1 && std::fabs(dot(faces.planes[f].normal, m)) < cos_delta - 1e-12) continue;
      Vec3 p;
      if (reflect_to(f, from, xr, p)) emit(f, p);
    }
  }

  // One sequence of vehicle v's table: its images, the receivers whose line
  // from the last image crosses the last face's sphere (a vectorised pass),
  // then the exact walk back.
  void bounce_sequence(std::size_t v, const TraceScene::BounceSequence& sq) {
    std::array<Vec3, 4> img;
    std::array<std::size_t, 3> fi{};
    img[0] = xs;
    bool ok = true;
    for (int k = 0; k < sq.order && ok; ++k) {
      fi[k] = faces.vehicle_begin[v] + sq.faces[k];
      const Plane& pl = faces.planes[fi[k]];
      const double dk = dot(pl.normal, img[k]) - pl.offset;
      // The image before reflection k lies on the side the face is met
      // from (the table's rays came from there).
      ok = ((sq.front >> k) & 1u) ? dk > 0 : dk < 0;
      img[k + 1] = img[k] - (2 * dk) * pl.normal;
    }
    if (!ok) return;
    ++local.image_sources;
    const int last = sq.order - 1;
    const Plane& pl_last = faces.planes[fi[last]];
    const double d_last = dot(pl_last.normal, img[last]) - pl_last.offset;
    local.tests += rx.size();
    if (!mark_crossings(rx, 0, pl_last, pl_last.offset - dot(pl_last.normal, xs), d_last, img[last + 1] - xs,
                        faces.spheres[fi[last]], faces.spheres[fi[last]].centre - xs, faces.tol[fi[last]], scratch))
      return;
    for (std::size_t r = 0; r < rx.size(); ++r) {
      if (!scratch.hit[r] || nodes[receivers[r]].vehicle == static_cast<int>(v)) continue;
      Vec3 target = receiver(r);
      bool on = true;
      for (int k = sq.order - 1; k >= 0 && on; --k) {
        const Plane& pl = faces.planes[fi[k]];
        const double di = dot(pl.normal, img[k]) - pl.offset, dt = dot(pl.normal, target) - pl.offset;
        on = di * dt > 0;
        if (!on) break;
        ++local.tests;
        const Vec3 q = crossing(img[k + 1], -di, target, dt);
        on = on_face(fi[k], q);
        target = q;
      }
      if (!on) continue;
      ImageCandidate c{receivers[r], {}};
      for (int k = 0; k < sq.order; ++k) c.faces.push_back(faces.refs[fi[k]]);
      out.push_back(std::move(c));
    }
  }

  // Every receiver's image in each ground plane of `grounds`.
  void mirror_receivers() {
    for (std::uint32_t k = 0; k < grounds->size(); ++k) {
      const Plane& pg = (*grounds)[k].plane;
      for (std::size_t r = 0; r < rx.size(); ++r) {
        const Vec3 xr = receiver(r);
        const double d = dot(pg.normal, xr) - pg.offset;
        if (d == 0) continue;  // on the ground plane: no image
        const Vec3 m = xr - (2 * d) * pg.normal - xs;
        mirrored.push(m);
        mirrored_of.emplace_back(k, static_cast<std::uint32_t>(r));
      }
    }
  }

  // The beam of f1's reflections: apex (I1, or its image in the ground),
  // the cone through f1's sphere and the pyramid through its outline.
  struct Beam {
    Vec3 apex;
    Cone cone;
    bool narrow;
    const std::vector<Vec3>* pyramid;
  };
  // The first reflection of a static pair: face f1, the source's distance
  // ds from its plane and its image I1 there. A reflection point accepted
  // within tol of f1's outline moves the continuation by up to tol times
  // (distance / |ds|) at f2: spread_per_m.
  struct FirstBounce {
    std::uint32_t f1;
    const Plane& p1;
    double ds;
    Vec3 i1;
    double spread_per_m;
  };
  // The second: face f2, the apex's distance di from its plane and its
  // image I2 there.
  struct SecondBounce {
    std::uint32_t f2;
    const Plane& p2;
    double di;
    Vec3 i2;
  };

  void from_first_face(std::uint32_t f1) {
    if (over_cap(f1)) return;
    const Plane& p1 = faces.planes[f1];
    const double ds = dot(p1.normal, xs) - p1.offset;
    if (ds == 0) return;
    const Vec3 i1 = xs - (2 * ds) * p1.normal;
    // Every continuation of a path reflected by f1 lies in the cone from I1
    // through f1 (on the source's side of f1).
    Beam beam{i1, {}, false, &pyramid};
    beam.narrow = cone_to(i1, faces.spheres[f1], beam.cone);
    // Tighter: the pyramid from I1 through f1's convex outline, one plane
    // per outline edge (inward normals), padded by the on-face tolerance.
    pyramid.clear();
    outline_pyramid(faces, f1, i1, pyramid);
    const FirstBounce b1{f1, p1, ds, i1, 2 * faces.tol[f1] / std::fabs(ds)};
    // Order 2 (f1, f2), and order 3 (f1, f2, ground) towards the mirrored receivers.
    walk_beam(
        b1, beam, p1, ds, [&](std::uint32_t f2) { return scene.static_face_reaches(f1, ds > 0 ? 1 : -1, f2); },
        [&](std::uint32_t f2) { second_face(b1, f2); });
    // Order 3 (f1, ground, f2): f1's beam mirrored in each ground face it reaches.
    for (const auto& gp : *grounds) ground_between(b1, beam, gp);
  }

  // Whether sphere sp (+ tol) lies outside beam b. (`spread`: a node's faces
  // lie up to its radius farther than its centre.)
  bool outside_beam(const FirstBounce& b1, const Beam& b, const TraceScene::Sphere& sp, double tol,
                    double spread) const {
    // One square root for both tests (this runs for every tree node and
    // face a beam meets); the pyramid first, as it rejects most.
    const Vec3 w = sp.centre - b.apex;
    const double dist = norm(w);
    const double pad = b1.spread_per_m * (dist + sp.radius) + tol + 1e-6 * (dist + spread);
    for (const auto& nrm : *b.pyramid)
      if (dot(nrm, w) < -(sp.radius + pad)) return true;
    if (!b.narrow || dist <= sp.radius) return false;
    // The cone from the apex through sp against the beam's cone.
    Cone c;
    c.axis = (1.0 / dist) * w;
    c.sin_h = sp.radius / dist;
    c.cos_h = std::sqrt(1 - c.sin_h * c.sin_h);
    return !cones_overlap(b.cone, c);
  }

  // The second faces in beam b: down the sphere tree, groups wholly on the
  // far side of `plane` (from the side `side` > 0 or < 0 the beam leaves
  // it on) or outside the beam skipped whole (their faces would each fail
  // the same tests: a node's sphere and tol bound theirs); leaf(f2) for
  // the rest that `reaches` (f2 reaches the side the beam leaves on).
  template <class Reaches, class Leaf>
  void walk_beam(const FirstBounce& b1, const Beam& b, const Plane& plane, double side, Reaches&& reaches,
                 Leaf&& leaf) {
    walk_static_tree(
        faces, tree_stack,
        [&](const TraceScene::Sphere& sp, double tol) {
          const double h = dot(plane.normal, sp.centre) - plane.offset;
          if ((side > 0 ? h : -h) + sp.radius <= 0) return true;  // wholly behind: no face reaches
          return outside_beam(b1, b, sp, tol, sp.radius);
        },
        [&](std::uint32_t f2) {
          if (!reaches(f2) || outside_beam(b1, b, faces.spheres[f2], faces.tol[f2], 0)) return;
          leaf(f2);
        });
  }

  // The image I2 of `apex` in f2 (di: the apex's distance from f2's
  // plane); false when the apex lies on it.
  bool image_in(std::uint32_t f2, const Vec3& apex, double& di, Vec3& i2) {
    const Plane& p2 = faces.planes[f2];
    di = dot(p2.normal, apex) - p2.offset;
    if (di == 0) return false;
    i2 = apex - (2 * di) * p2.normal;
    ++local.image_sources;
    return true;
  }

  // q2 on f2 towards `target`, then f1 on the way back from q2.
  bool back_to_f1(const FirstBounce& b1, const SecondBounce& b2, const Vec3& target, Vec3& q2) const {
    const Plane& p1 = b1.p1;
    const Plane& p2 = b2.p2;
    const double d = dot(p2.normal, target) - p2.offset;
    q2 = crossing(b2.i2, -b2.di, target, d);
    if (!on_face(b2.f2, q2)) return false;
    const double d2 = dot(p1.normal, q2) - p1.offset;
    return b1.ds * d2 > 0 && on_face(b1.f1, crossing(b1.i1, -b1.ds, q2, d2));
  }

  // Order 2 (f1, f2) towards the higher receivers, then order 3 (f1, f2,
  // ground) towards the mirrored ones.
  void second_face(const FirstBounce& b1, std::uint32_t f2) {
    const std::uint32_t f1 = b1.f1;
    const auto& s2 = faces.spheres[f2];
    double di;
    Vec3 i2;
    if (!image_in(f2, b1.i1, di, i2)) return;
    const SecondBounce b2{f2, faces.planes[f2], di, i2};
    const Plane& p2 = b2.p2;
    // Relative to the source: I1 is at distance di from f2's plane.
    const double off2 = p2.offset - dot(p2.normal, xs);
    local.tests += rx.size();
    if (mark_crossings(rx, higher_from, p2, off2, di, i2 - xs, s2, s2.centre - xs, faces.tol[f2], scratch))
      for (std::size_t r = higher_from; r < rx.size(); ++r) {
        Vec3 q2;
        if (scratch.hit[r] && !over_cap(f1, r, f2) && back_to_f1(b1, b2, receiver(r), q2))
          out.push_back({receivers[r], {faces.refs[f1], faces.refs[f2]}});
      }
    if (mirrored.size() == 0) return;
    local.tests += mirrored.size();
    if (!mark_crossings(mirrored, 0, p2, off2, di, i2 - xs, s2, s2.centre - xs, faces.tol[f2], mirrored)) return;
    ground_last(b1, b2);
  }

  // Order 3 (f1, f2, ground) towards the mirrored receivers marked: the
  // image and the point on the plane once, then each of its faces.
  void ground_last(const FirstBounce& b1, const SecondBounce& b2) {
    const std::uint32_t f1 = b1.f1, f2 = b2.f2;
    const Plane& p2 = b2.p2;
    for (std::size_t m = 0; m < mirrored.size(); ++m) {
      if (!mirrored.hit[m]) continue;
      const auto [k, r] = mirrored_of[m];
      const auto& gp = (*grounds)[k];
      // Ground, f2, ground: after the first ground reflection the path
      // leaves the ground's plane, and a face perpendicular to it (a
      // wall) keeps that component: it never comes back.
      const bool g_f2_g = std::fabs(dot(p2.normal, gp.plane.normal)) < 1e-9;
      auto excluded = [&](std::uint32_t g) { return g == f2 || (g == f1 && g_f2_g); };
      if (std::all_of(gp.faces.begin(), gp.faces.end(), excluded)) continue;
      const Vec3 xr = receiver(r), xm = Vec3{mirrored.x[m], mirrored.y[m], mirrored.z[m]} + xs;
      Vec3 q2;
      if (!back_to_f1(b1, b2, xm, q2)) continue;
      // The last leg, from q2 down to the ground and up to the receiver.
      const Plane& pg = gp.plane;
      const double dq = dot(pg.normal, q2) - pg.offset, dr = dot(pg.normal, xr) - pg.offset;
      if (!(dq * dr > 0)) continue;
      const Vec3 qg = crossing(xm, -dr, q2, dq);
      for (const std::uint32_t g : gp.faces)
        if (!excluded(g) && on_face(g, qg))
          out.push_back({receivers[r], {faces.refs[f1], faces.refs[f2], faces.refs[g]}});
    }
  }

  // Order 3 (f1, ground g, f2): f1's beam mirrored in the ground plane, for
  // the faces of it that the beam reaches.
  void ground_between(const FirstBounce& b1, const Beam& beam, const ImageFaces::GroundPlane& gp) {
    const std::uint32_t f1 = b1.f1;
    const Plane& pg = gp.plane;
    const double dg = dot(pg.normal, b1.i1) - pg.offset;
    if (dg == 0) return;
    ground_set.clear();
    for (std::size_t j = 0; j < gp.faces.size(); ++j) {
      const std::uint32_t g = gp.faces[j];
      if (g == f1 || !scene.static_face_reaches(f1, b1.ds > 0 ? 1 : -1, g)) continue;
      if (outside_beam(b1, beam, faces.spheres[g], faces.tol[g], 0)) continue;
      ground_set.push_back(static_cast<std::uint32_t>(j));
    }
    if (ground_set.empty()) return;
    const Vec3 i1g = b1.i1 - (2 * dg) * pg.normal;
    auto mirror = [&](const Vec3& v) { return v - (2 * dot(pg.normal, v)) * pg.normal; };
    pyramid_g.clear();
    for (const auto& nrm : pyramid) pyramid_g.push_back(mirror(nrm));
    Beam bg{i1g, beam.cone, beam.narrow, &pyramid_g};
    bg.cone.axis = mirror(beam.cone.axis);
    // After the ground the path runs on I1's side of it (q2 with I1): f2
    // must reach that side of some face g (its own orientation), and is
    // tried with those.
    auto reaches = [&](std::uint32_t f2) {
      ground_sub.clear();
      for (const std::uint32_t j : ground_set) {
        const std::uint32_t g = gp.faces[j];
        if (f2 != g && scene.static_face_reaches(g, (dg > 0) != (gp.flipped[j] != 0) ? 1 : -1, f2))
          ground_sub.push_back(g);
      }
      return !ground_sub.empty();
    };
    walk_beam(b1, bg, pg, dg, reaches, [&](std::uint32_t f2) { after_ground(b1, pg, dg, i1g, f2); });
  }

  // Order 3 (f1, g, f2) through second face f2 of the mirrored beam (apex
  // i1g, at distance dg from the ground plane pg), towards the higher
  // receivers, for each face g of ground_sub.
  void after_ground(const FirstBounce& b1, const Plane& pg, double dg, const Vec3& i1g, std::uint32_t f2) {
    const std::uint32_t f1 = b1.f1;
    const Plane& p1 = b1.p1;
    const auto& s2 = faces.spheres[f2];
    const Plane& p2 = faces.planes[f2];
    double di;
    Vec3 i2;
    if (!image_in(f2, i1g, di, i2)) return;
    local.tests += rx.size() - higher_from;
    if (!mark_crossings(rx, higher_from, p2, p2.offset - dot(p2.normal, xs), di, i2 - xs, s2, s2.centre - xs,
                        faces.tol[f2], scratch))
      return;
    for (std::size_t r = higher_from; r < rx.size(); ++r) {
      if (!scratch.hit[r] || over_cap(f1, r, f2)) continue;
      const Vec3 xr = receiver(r);
      const double d = dot(p2.normal, xr) - p2.offset;
      const Vec3 q2 = crossing(i2, -di, xr, d);
      if (!on_face(f2, q2)) continue;
      const double dq = dot(pg.normal, q2) - pg.offset;
      if (!(dg * dq > 0)) continue;
      const Vec3 qg = crossing(i1g, -dg, q2, dq);
      const double d1 = dot(p1.normal, qg) - p1.offset;
      if (!(b1.ds * d1 > 0)) continue;
      int first_leg = -1;  // whether f1 holds the first point: tested once, when a face holds qg
      for (const std::uint32_t g : ground_sub) {
        if (!on_face(g, qg)) continue;
        if (first_leg < 0) first_leg = on_face(f1, crossing(b1.i1, -b1.ds, qg, d1)) ? 1 : 0;
        if (first_leg == 0) break;
        out.push_back({receivers[r], {faces.refs[f1], faces.refs[g], faces.refs[f2]}});
      }
    }
  }
};

}  // namespace

void image_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                      std::uint32_t src, const std::vector<std::uint32_t>& receivers, int max_order,
                      std::vector<ImageCandidate>& out, ImageSearchStats* stats, bool multi_bounce,
                      bool ground_order3, bool static_pairs, const SlabBounds* slabs) {
  if (max_order < 1 || receivers.empty()) return;
  ImageSearch search(scene, faces, nodes, src, receivers, out, slabs);
  search.static_order1();
  search.vehicle_order1();
  if (max_order >= 2) search.ground_then_vehicle();
  if (multi_bounce && max_order >= 2) search.on_one_vehicle(max_order);
  if (max_order >= 2 && static_pairs)
    search.static_pairs(ground_order3 && max_order >= 3 && faces.static_count > 0);
  search.add_stats(stats);
}

namespace {

// The kinds of path through a (static face, vehicle) combination: the
// wall's echo off the car (W-V), the ground between (W-G-V) and the ground
// last (W-V-G).
enum class Kind { echo, between, last };

// beam_vehicle_candidates' search, one combination at a time.
class BeamVehicleSearch : public SourceSearch {
 public:
  BeamVehicleSearch(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                    std::uint32_t src, const std::vector<std::uint32_t>& receivers, std::vector<ImageCandidate>& out,
                    bool with_ground, BeamVehicleMethod method)
      : SourceSearch(scene, faces, nodes, src, receivers, out), method(method) {
    mirror_receivers(with_ground);
    pyramid_g.resize(faces.ground.size());
    between.resize(faces.ground.size());
    i1g.resize(faces.ground.size());
    keep_between.resize(faces.ground.size());
  }

  void combination(const BeamVehicle& combo) {
    const std::uint32_t f1 = combo.face, v = combo.vehicle;
    const Plane& p1 = faces.planes[f1];
    const double ds = dot(p1.normal, xs) - p1.offset;
    if (ds == 0) return;
    const Vec3 i1 = xs - (2 * ds) * p1.normal;
    const auto& sv = faces.vehicle_spheres[v];
    const double h = dot(p1.normal, sv.centre) - p1.offset;
    if (ds > 0 ? h + sv.radius <= 0 : h - sv.radius >= 0) return;  // not on the source's side of f1
    // The rays' widened test is loose: the vehicle must meet f1's beam, the
    // pyramid from I1 through f1's outline (padded by the on-face
    // tolerance carried to the distance); with the ground between, that
    // pyramid mirrored in the ground.
    pyramid.clear();
    outline_pyramid(faces, f1, i1, pyramid);
    const double spread_per_m = 2 * faces.tol[f1] / std::fabs(ds);
    const bool direct = !outside_pyramid(pyramid, i1, sv, 0, spread_per_m);
    const std::uint32_t fb = faces.vehicle_begin[v], fe = faces.vehicle_begin[v + 1];
    const Combo c{f1, v, p1, ds, i1, sv, spread_per_m, direct, fb, fe, fe - fb};
    const bool any_between = ground_beams(c);
    if (!direct && !any_between) return;
    ++local.image_sources;
    // The images the paths unfold from: I1, and for the ground between,
    // I1's image in each ground face.
    for (std::uint32_t k = 0; k < between.size(); ++k)
      if (between[k]) {
        const Plane& pg = faces.planes[faces.ground[k]];
        i1g[k] = i1 - (2 * (dot(pg.normal, i1) - pg.offset)) * pg.normal;
      }
    // Only the faces in the beam (the pyramid through f1, or its image in
    // the ground) can hold the reflection point.
    if (direct) in_beam(c, pyramid, i1, keep_direct);
    for (std::uint32_t k = 0; k < mirrored.size(); ++k)
      if (between[k]) in_beam(c, pyramid_g[k], i1g[k], keep_between[k]);
    if (by_passes(c))
      search_by_passes(c);
    else
      search_by_lookups(c);
  }

 private:
  // One combination: static face f1 (the source's distance ds from its
  // plane, its image I1 there), vehicle v (sphere sv, faces [fb, fe)), the
  // on-face tolerance's spread per metre along f1's beam, and whether the
  // vehicle meets that beam without the ground between (`direct`).
  struct Combo {
    std::uint32_t f1, v;
    const Plane& p1;
    double ds;
    Vec3 i1;
    const TraceScene::Sphere& sv;
    double spread_per_m;
    bool direct;
    std::uint32_t fb, fe, nf;
  };
  // A kind of path to one receiver, for the normal table's lookup.
  struct Variant {
    Kind kind;
    std::uint32_t k;  // ground index (between, last)
    Vec3 from, to;    // the image before the car, and the point after it
    Vec3 bisector{0, 0, 1};
    double cos_delta = -1, sin_delta = 1;
  };

  const BeamVehicleMethod method;
  // The receivers' images in each ground face (for the ground last; none
  // without `with_ground`; NaN, never marked, for a receiver on the
  // ground's plane), relative to the source and in world coordinates.
  std::vector<Receivers> mirrored;
  std::vector<std::vector<Vec3>> mirrored_at;
  std::vector<Vec3> pyramid;
  std::vector<std::vector<Vec3>> pyramid_g;  // f1's pyramid mirrored in each ground face
  std::vector<char> between;                 // per ground face: the vehicle meets f1's beam mirrored in it
  std::vector<Vec3> i1g;                     // I1's image in each ground face
  BeamSphereTest sphere_test;
  std::vector<std::int64_t> keep_direct;
  std::vector<std::vector<std::int64_t>> keep_between;
  std::vector<Variant> variants;

  void mirror_receivers(bool with_ground) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    mirrored.resize(with_ground ? faces.ground.size() : 0);
    mirrored_at.resize(mirrored.size());
    for (std::uint32_t k = 0; k < mirrored.size(); ++k) {
      const Plane& pg = faces.planes[faces.ground[k]];
      for (auto r : receivers) {
        const Vec3 xr = nodes[r].position;
        const double d = dot(pg.normal, xr) - pg.offset;
        mirrored_at[k].push_back(d != 0 ? xr - (2 * d) * pg.normal : Vec3{nan, nan, nan});
        mirrored[k].push(mirrored_at[k].back() - xs);
      }
    }
  }

  // A receiver riding vehicle v takes its echoes off v from the faces its
  // mount sees (a normal bound or image pass is void inside the vehicle).
  const std::vector<std::uint32_t>* mount_of(std::uint32_t v, std::uint32_t r) const {
    return static_cast<int>(v) == nodes[r].vehicle ? scene.faces_seen_from_mount(v, nodes[r].position) : nullptr;
  }

  // Which ground faces the vehicle meets f1's beam mirrored in (between,
  // pyramid_g); whether any.
  bool ground_beams(const Combo& c) {
    bool any_between = false;
    for (std::uint32_t k = 0; k < between.size() && !mirrored.empty(); ++k) {
      const Plane& pg = faces.planes[faces.ground[k]];
      const double dg = dot(pg.normal, c.i1) - pg.offset, hg = dot(pg.normal, c.sv.centre) - pg.offset;
      between[k] = faces.ground[k] != c.f1 && dg != 0 && (dg > 0 ? hg + c.sv.radius > 0 : hg - c.sv.radius < 0);
      if (!between[k]) continue;
      pyramid_g[k].clear();
      for (const auto& nrm : pyramid) pyramid_g[k].push_back(nrm - (2 * dot(pg.normal, nrm)) * pg.normal);
      between[k] = !outside_pyramid(pyramid_g[k], c.i1 - (2 * dg) * pg.normal, c.sv, 0, c.spread_per_m);
      any_between |= between[k] != 0;
    }
    return any_between;
  }

  // keep[i]: face fb + i lies in the beam of pyramid `planes` from `apex`.
  void in_beam(const Combo& c, const std::vector<Vec3>& planes, const Vec3& apex, std::vector<std::int64_t>& keep) {
    // (No plane to be behind: a zero normal keeps every face.)
    const Plane no_plane{{0, 0, 0}, -1};
    sphere_test.set_pyramid(planes);
    sphere_test.run(faces, c.fb - faces.vehicle_begin[0], c.nf, apex, c.spread_per_m, no_plane, 1, keep);
  }

  // The reflection on vehicle face f from `from` towards `to`, then the
  // way back through the ground (if any) to f1; appended when every point
  // lies on its face.
  void try_face(const Combo& c, Kind kind, std::uint32_t k, const Vec3& from, const Vec3& to, std::size_t f,
                std::uint32_t r) {
    const Plane& p1 = c.p1;
    const Plane& pl = faces.planes[f];
    const double df = dot(pl.normal, from) - pl.offset, d = dot(pl.normal, to) - pl.offset;
    if (!(df * d > 0)) return;
    const Vec3 q = crossing(from - (2 * df) * pl.normal, -df, to, d);
    if (!on_face(f, q)) return;
    Vec3 back = q;  // the point the line from I1 must reach through f1
    const std::uint32_t g = kind == Kind::echo ? 0 : faces.ground[k];
    if (kind != Kind::echo) {
      const Plane& pg = faces.planes[g];
      const double dq = dot(pg.normal, q) - pg.offset;
      if (kind == Kind::between) {
        // From I1's image (below the ground, I1 above) to q above it.
        const double dg = dot(pg.normal, from) - pg.offset;
        if (!(dg * dq < 0)) return;
        back = crossing(from, dg, q, dq);
        if (!on_face(g, back)) return;
      } else {
        // From q down to the ground, then up to the receiver.
        const Vec3 xr = nodes[r].position;
        const double dr = dot(pg.normal, xr) - pg.offset;
        if (!(dq * dr > 0) || !on_face(g, crossing(to, -dr, q, dq))) return;
      }
    }
    const double d1 = dot(p1.normal, back) - p1.offset;
    if (!(c.ds * d1 > 0) || !on_face(c.f1, crossing(c.i1, -c.ds, back, d1))) return;
    switch (kind) {
      case Kind::echo: out.push_back({r, {faces.refs[c.f1], faces.refs[f]}}); break;
      case Kind::between: out.push_back({r, {faces.refs[c.f1], faces.refs[g], faces.refs[f]}}); break;
      case Kind::last: out.push_back({r, {faces.refs[c.f1], faces.refs[f], faces.refs[g]}}); break;
    }
  }

  // Per face of the vehicle and kind of path, its image and one
  // vectorised pass over the receivers (or their images in the ground),
  // then the exact test for those marked.
  void pass(const Combo& c, Kind kind, std::uint32_t k, const Vec3& from, const Receivers& to, std::size_t f) {
    const Plane& pl = faces.planes[f];
    const double df = dot(pl.normal, from) - pl.offset;
    if (df == 0) return;
    const auto& sf = faces.spheres[f];
    local.tests += to.size();
    // The pass is a necessary condition only (try_face decides), so its
    // sphere is padded against rounding.
    if (!mark_crossings(to, 0, pl, pl.offset - dot(pl.normal, xs), df, from - (2 * df) * pl.normal - xs, sf,
                        sf.centre - xs, faces.tol[f] + 1e-9 * (sf.radius + 1), scratch))
      return;
    for (std::size_t ri = 0; ri < to.size(); ++ri) {
      if (!scratch.hit[ri]) continue;
      const std::uint32_t r = receivers[ri];
      if (kind == Kind::echo && mount_of(c.v, r)) continue;
      try_face(c, kind, k, from, kind == Kind::last ? mirrored_at[k][ri] : nodes[r].position, f, r);
    }
  }

  // Two exact ways to the same candidates (try_face decides each): per
  // face and kind an image and a vectorised pass over the receivers, or
  // per receiver a lookup in the vehicle's normal table around the
  // union of its kinds' normal windows. The passes cost faces x kinds x
  // receivers / 8, the lookups receivers x (10 + 8 kinds) in the same
  // unit (measured: equal on the ring road, whose one ground plane makes
  // two kinds; on the demo city's ground tiles the lookups' union
  // window holds most faces and the passes take half the time).
  bool by_passes(const Combo& c) const {
    std::uint64_t passes = 0;
    int kinds = c.direct ? 1 : 0;
    for (std::uint32_t k = 0; k < mirrored.size(); ++k) {
      const bool last = c.direct && faces.ground[k] != c.f1;
      kinds += (between[k] ? 1 : 0) + (last ? 1 : 0);
      for (std::uint32_t i = 0; i < c.nf; ++i)
        passes += (between[k] && keep_between[k][i] ? 1 : 0) + (last && keep_direct[i] ? 1 : 0);
    }
    for (std::uint32_t i = 0; c.direct && i < c.nf; ++i) passes += keep_direct[i] ? 1 : 0;
    const std::uint64_t lanes = (receivers.size() + Receivers::kLanes - 1) / Receivers::kLanes;
    return method == BeamVehicleMethod::cheaper
               ? passes * lanes < receivers.size() * (10 + 8 * static_cast<std::uint64_t>(kinds))
               : method == BeamVehicleMethod::passes;
  }

  void search_by_passes(const Combo& c) {
    for (std::uint32_t f = c.fb; f < c.fe; ++f) {
      const bool in_direct = c.direct && keep_direct[f - c.fb];
      if (in_direct) pass(c, Kind::echo, 0, c.i1, rx, f);
      for (std::uint32_t k = 0; k < mirrored.size(); ++k) {
        if (between[k] && keep_between[k][f - c.fb]) pass(c, Kind::between, k, i1g[k], rx, f);
        if (in_direct && faces.ground[k] != c.f1) pass(c, Kind::last, k, c.i1, mirrored[k], f);
      }
    }
    for (std::size_t ri = 0; c.direct && ri < receivers.size(); ++ri)
      if (const auto* mount = mount_of(c.v, receivers[ri]))
        for (auto lf : *mount)
          try_face(c, Kind::echo, 0, c.i1, nodes[receivers[ri]].position, c.fb + lf, receivers[ri]);
  }

  void search_by_lookups(const Combo& c) {
    for (std::size_t ri = 0; ri < receivers.size(); ++ri) {
      const std::uint32_t r = receivers[ri];
      const Vec3 xr = nodes[r].position;
      // Each kind its own normal window, all from one table lookup around
      // the first window wide enough to hold the others (the lookup, not
      // the face tests, is what these cost).
      variants.clear();
      const auto* mount = mount_of(c.v, r);
      if (c.direct && !mount) variants.push_back({Kind::echo, 0, c.i1, xr});
      for (std::uint32_t k = 0; k < mirrored.size(); ++k) {
        if (between[k]) variants.push_back({Kind::between, k, i1g[k], xr});
        if (c.direct && faces.ground[k] != c.f1 && !std::isnan(mirrored_at[k][ri][0]))
          variants.push_back({Kind::last, k, c.i1, mirrored_at[k][ri]});
      }
      if (c.direct && mount)
        for (auto lf : *mount) try_face(c, Kind::echo, 0, c.i1, xr, c.fb + lf, r);
      if (variants.empty()) continue;
      const double angle = union_window(c.sv);
      for (auto lf : scene.vehicle_faces_near_normal(c.v, variants[0].bisector, angle)) {
        const std::size_t f = c.fb + lf;
        const Vec3& n = faces.planes[f].normal;
        for (const auto& w : variants)
          if (w.cos_delta <= -1 || std::fabs(dot(n, w.bisector)) >= w.cos_delta - 1e-12) {
            ++local.tests;
            try_face(c, w.kind, w.k, w.from, w.to, f, r);
          }
      }
    }
  }

  // Sets each variant's normal window; returns the half-angle around the
  // first one's bisector that holds them all (10: every face).
  double union_window(const TraceScene::Sphere& sv) {
    bool all = false;
    for (auto& w : variants) all |= !normal_window(sv, w.from, w.to, w.bisector, w.cos_delta, w.sin_delta);
    double angle = 10.0;  // every face
    if (!all) {
      // Bounds without inverse trigonometry: an angle is at most pi / 2
      // times its chord (or its sine).
      angle = 0;
      for (const auto& w : variants) {
        const double c = dot(variants[0].bisector, w.bisector);
        const Vec3 chord = w.bisector - (c < 0 ? -1.0 : 1.0) * variants[0].bisector;
        angle = std::max(angle, (kPi / 2) * (norm(chord) + w.sin_delta));
      }
    }
    return angle;
  }
};

}  // namespace

void beam_vehicle_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                             std::uint32_t src, const std::vector<std::uint32_t>& receivers,
                             const std::vector<BeamVehicle>& combos, std::vector<ImageCandidate>& out,
                             ImageSearchStats* stats, bool with_ground, BeamVehicleMethod method) {
  if (combos.empty() || receivers.empty()) return;
  BeamVehicleSearch search(scene, faces, nodes, src, receivers, out, with_ground, method);
  for (const BeamVehicle& combo : combos) search.combination(combo);
  search.add_stats(stats);
}

void small_face_beams(const ImageFaces& faces, const Vec3& src, std::vector<BeamVehicle>& combos) {
  for (const std::uint32_t f : faces.small) {
    const Plane& pl = faces.planes[f];
    const double ds = dot(pl.normal, src) - pl.offset;
    if (ds == 0) continue;
    const Vec3 i1 = src - (2 * ds) * pl.normal;
    Cone beam;
    const bool narrow =
        cone_to(i1, TraceScene::Sphere{faces.spheres[f].centre, faces.spheres[f].radius + faces.tol[f]}, beam);
    for (std::uint32_t v = 0; v < faces.vehicle_spheres.size(); ++v) {
      const auto& sv = faces.vehicle_spheres[v];
      const double h = dot(pl.normal, sv.centre) - pl.offset;
      if (ds > 0 ? h + sv.radius <= 0 : h - sv.radius >= 0) continue;  // behind the face
      Cone c;
      if (narrow && cone_to(i1, sv, c) && !cones_overlap(beam, c)) continue;
      combos.push_back({f, v});
    }
  }
}

void small_face_pairs(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, std::vector<BeamPair>& pairs) {
  std::vector<Vec3> pyramid;
  std::vector<std::uint32_t> stack;
  for (const std::uint32_t f1 : faces.small) {
    const Plane& pl = faces.planes[f1];
    const double ds = dot(pl.normal, src) - pl.offset;
    if (ds == 0) continue;
    const Vec3 i1 = src - (2 * ds) * pl.normal;
    pyramid.clear();
    outline_pyramid(faces, f1, i1, pyramid);
    const double spread_per_m = 2 * faces.tol[f1] / std::fabs(ds);
    // Outside the beam: behind f1 (on the far side from the source) or
    // outside the pyramid from I1 through its outline, padded by the
    // on-face tolerances carried to the distance.
    auto outside = [&](const TraceScene::Sphere& sp, double tol) {
      const double h = dot(pl.normal, sp.centre) - pl.offset;
      return (ds > 0 ? h : -h) + sp.radius <= 0 || outside_pyramid(pyramid, i1, sp, tol, spread_per_m);
    };
    walk_static_tree(faces, stack, outside, [&](std::uint32_t f2) {
      if (f2 != f1 && scene.static_face_reaches(f1, ds > 0 ? 1 : -1, f2) && !outside(faces.spheres[f2], faces.tol[f2]))
        pairs.push_back({f1, f2});
    });
  }
}

namespace {

// beam_pair_candidates' search, one lit pair (f1, f2) at a time: the beam
// after f2, the third faces in it, and each third face's receivers.
class BeamPairSearch : public SourceSearch {
 public:
  BeamPairSearch(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes, std::uint32_t src,
                 const std::vector<std::uint32_t>& receivers, std::vector<ImageCandidate>& out, bool skip_ground)
      : SourceSearch(scene, faces, nodes, src, receivers, out), skip_ground(skip_ground) {}

  void pair(const BeamPair& bp) {
    f1 = bp.f1;
    f2 = bp.f2;
    if (!unfold()) return;
    ++local.image_sources;
    beam_after_f2();
    // Static third faces: down the sphere tree, in the beam and in front of
    // f2. Three static faces with one on the ground are image_candidates'
    // (ground_order3); after a vehicle face the ground is this search's.
    const bool skip = skip_ground && f2_static;
    third_faces.clear();
    if (!(skip && (is_ground(f1) || is_ground(f2)))) {
      static_third_faces(skip);
      std::sort(third_faces.begin(), third_faces.end());  // the output's order does not depend on the tree's
    }
    // Vehicles in the beam: each of their faces in it (no normal index:
    // the receivers riding the vehicle included). Not after a vehicle face
    // (two cars after a wall: +17 % of a 120-vehicle demo snapshot, and no
    // such path missing on the snapshots measured).
    if (f2_static && !faces.vehicle_spheres.empty()) vehicle_third_faces();
    for (const std::uint32_t f3 : third_faces) third_face(f3);
  }

 private:
  const bool skip_ground;
  std::vector<Vec3> pyramid, mirrored;
  std::vector<std::uint32_t> tree_stack, third_faces, kept_vehicles;
  BeamSphereTest sphere_test;
  std::vector<std::int64_t> keep;
  // The pair being searched: the images of the source in f1, then f2
  // (img[0] = the source), and each one's signed distance from the next
  // face's plane; the beam after f2 (pyramid, spread_per_m, cone when
  // narrow) and the side of f2 it leaves on.
  std::uint32_t f1 = 0, f2 = 0;
  std::array<Vec3, 3> img;
  std::array<double, 2> dist{};
  bool f2_static = false;
  double spread_per_m = 0;
  Cone cone;
  bool narrow = false;
  int side = 1;

  bool is_ground(std::uint32_t f) const { return std::binary_search(faces.ground.begin(), faces.ground.end(), f); }

  // The images in f1 and f2; false when one lies on its face's plane.
  bool unfold() {
    dist = {};
    img[0] = xs;
    bool ok = true;
    for (int k = 0; k < 2 && ok; ++k) {
      const Plane& pl = faces.planes[k == 0 ? f1 : f2];
      dist[k] = dot(pl.normal, img[k]) - pl.offset;
      ok = dist[k] != 0;
      img[k + 1] = img[k] - (2 * dist[k]) * pl.normal;
    }
    return ok;
  }

  // The beam after f2: apex I2, inside the pyramid through f2's outline
  // and inside f1's, mirrored in f2's plane (I1's image is I2), padded
  // by both faces' on-face tolerances carried to the distance.
  // (A vehicle face as f2 has no outline here: the cone through its
  // sphere instead, narrow as vehicle faces are small.)
  void beam_after_f2() {
    const Plane& p2 = faces.planes[f2];
    f2_static = f2 < faces.static_count;
    pyramid.clear();
    if (f2_static) outline_pyramid(faces, f2, img[2], pyramid);
    mirrored.clear();
    outline_pyramid(faces, f1, img[1], mirrored);
    for (const auto& nrm : mirrored) pyramid.push_back(nrm - (2 * dot(p2.normal, nrm)) * p2.normal);
    spread_per_m = 2 * faces.tol[f1] / std::fabs(dist[0]) + 2 * faces.tol[f2] / std::fabs(dist[1]);
    cone = Cone{};
    narrow =
        !f2_static &&
        cone_to(img[2], TraceScene::Sphere{faces.spheres[f2].centre, faces.spheres[f2].radius + faces.tol[f2]}, cone);
    side = dist[1] > 0 ? 1 : -1;  // I1's side of f2: where the beam leaves it
  }

  bool outside(const TraceScene::Sphere& sp, double tol) const {
    const Vec3 w = sp.centre - img[2];
    const double d = norm(w);
    const double pad = spread_per_m * (d + sp.radius) + tol + 1e-6 * (d + sp.radius);
    for (const auto& nrm : pyramid)
      if (dot(nrm, w) < -(sp.radius + pad)) return true;
    if (!narrow || d <= sp.radius + pad) return false;
    Cone c;
    c.axis = (1.0 / d) * w;
    c.sin_h = (sp.radius + pad) / d;
    c.cos_h = std::sqrt(1 - c.sin_h * c.sin_h);
    return !cones_overlap(cone, c);
  }
  bool behind(const TraceScene::Sphere& sp) const {
    const Plane& p2 = faces.planes[f2];
    return side * (dot(p2.normal, sp.centre) - p2.offset) + sp.radius <= 0;
  }

  // The static faces in the beam, in front of f2 (the ground skipped with
  // `skip`), into third_faces.
  void static_third_faces(bool skip) {
    walk_static_tree(
        faces, tree_stack,
        [&](const TraceScene::Sphere& sp, double tol) { return behind(sp) || outside(sp, tol); },
        [&](std::uint32_t f3) {
          if (f3 == f2 || (f2_static && !scene.static_face_reaches(f2, side, f3)) ||
              outside(faces.spheres[f3], faces.tol[f3]))
            return;
          if (skip && is_ground(f3)) return;
          third_faces.push_back(f3);
        });
  }

  // The faces of the vehicles in the beam, into third_faces: the same tests
  // as behind() and outside() (not narrow: f2 is static), vectorised over
  // the vehicles, then over each kept vehicle's faces.
  void vehicle_third_faces() {
    const Plane& p2 = faces.planes[f2];
    sphere_test.set_pyramid(pyramid);
    auto keep_spheres = [&](std::uint32_t begin, std::uint32_t count) {
      sphere_test.run(faces, begin, count, img[2], spread_per_m, p2, side, keep);
    };
    const auto vehicles = static_cast<std::uint32_t>(faces.vehicle_spheres.size());
    keep_spheres(faces.beam_vehicles_begin, vehicles);
    kept_vehicles.clear();
    for (std::uint32_t v = 0; v < vehicles; ++v)
      if (keep[v]) kept_vehicles.push_back(v);
    for (const std::uint32_t v : kept_vehicles) {
      const std::uint32_t b = faces.vehicle_begin[v], e = faces.vehicle_begin[v + 1];
      keep_spheres(b - faces.vehicle_begin[0], e - b);
      for (std::uint32_t f = b; f < e; ++f)
        if (f != f2 && keep[f - b]) third_faces.push_back(f);
    }
  }

  // From the third reflection's point q3 back through f2 and f1.
  bool back_through_f2_f1(const Vec3& q3) {
    const Plane& p1 = faces.planes[f1];
    const Plane& p2 = faces.planes[f2];
    const double d3 = dot(p2.normal, q3) - p2.offset;
    if (!(dist[1] * d3 > 0)) return false;
    ++local.tests;
    const Vec3 q2 = crossing(img[2], -dist[1], q3, d3);
    if (!on_face(f2, q2)) return false;
    const double d2 = dot(p1.normal, q2) - p1.offset;
    return dist[0] * d2 > 0 && on_face(f1, crossing(img[1], -dist[0], q2, d2));
  }

  // The third face's image, the receivers seen through it (a vectorised
  // pass), then the walk back.
  void third_face(std::uint32_t f3) {
    const Plane& p3 = faces.planes[f3];
    const double d3 = dot(p3.normal, img[2]) - p3.offset;
    if (d3 == 0) return;
    const Vec3 i3 = img[2] - (2 * d3) * p3.normal;
    ++local.image_sources;
    local.tests += rx.size();
    const auto& s3 = faces.spheres[f3];
    if (!mark_crossings(rx, 0, p3, p3.offset - dot(p3.normal, xs), d3, i3 - xs, s3, s3.centre - xs, faces.tol[f3],
                        scratch))
      return;
    for (std::size_t r = 0; r < rx.size(); ++r) {
      if (!scratch.hit[r]) continue;
      const Vec3 xr = nodes[receivers[r]].position;
      const Vec3 q3 = crossing(i3, -d3, xr, dot(p3.normal, xr) - p3.offset);
      if (on_face(f3, q3) && back_through_f2_f1(q3))
        out.push_back({receivers[r], {faces.refs[f1], faces.refs[f2], faces.refs[f3]}});
    }
  }
};

}  // namespace

void beam_pair_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                          std::uint32_t src, const std::vector<BeamPair>& beam_pairs,
                          const std::vector<std::uint32_t>& receivers, std::vector<ImageCandidate>& out,
                          ImageSearchStats* stats, bool skip_ground) {
  if (beam_pairs.empty() || receivers.empty()) return;
  BeamPairSearch search(scene, faces, nodes, src, receivers, out, skip_ground);
  for (const BeamPair& bp : beam_pairs) search.pair(bp);
  search.add_stats(stats);
}

}  // namespace raysweep::tracer

namespace raysweep::tracer {

namespace {

// p inside static face g's convex outline by at least `margin` (the
// outline runs counter-clockwise about the normal: inside is to the left).
bool deep_inside(const ImageFaces& faces, std::uint32_t g, const Vec3& p, double margin) {
  const std::uint32_t o0 = faces.outline_begin[g], o1 = faces.outline_begin[g + 1];
  const Vec3& n = faces.planes[g].normal;
  for (std::uint32_t k = o0; k < o1; ++k) {
    const Vec3 a = faces.outline[k], b = faces.outline[k + 1 < o1 ? k + 1 : o0];
    if (dot(cross(b - a, p - a), n) < margin * norm(b - a)) return false;
  }
  return true;
}

// Whether the segment from src to p crosses static face g (hit at distance
// t along unit dir) as hidden_by_convex_face needs it: g convex, src and p
// on opposite sides of its plane and both at least `margin` from it, the
// crossing at least `margin` inside its outline.
bool crosses_deep(const ImageFaces& faces, std::uint32_t g, const Vec3& src, const Vec3& p, const Vec3& dir,
                  double t, double margin) {
  if (!faces.convex[g]) return false;
  const Plane& pb = faces.planes[g];
  const double h_src = dot(pb.normal, src) - pb.offset, h_p = dot(pb.normal, p) - pb.offset;
  return h_src * h_p < 0 && std::fabs(h_src) >= margin && std::fabs(h_p) >= margin &&
         deep_inside(faces, g, src + t * dir, margin);
}

// SlabBounds::at(node at src, f): the faces every ray from src to f's
// outline vertices crosses deep (ascending, intersected ray by ray).
int slabs_to_face(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, std::uint32_t f, int limit,
                  std::vector<Hit>& hits, std::vector<std::uint32_t>& common, std::vector<std::uint32_t>& next) {
  const std::uint32_t o0 = faces.outline_begin[f], o1 = faces.outline_begin[f + 1];
  if (o1 - o0 < 3) return 0;
  const double margin = 0.01 + 4 * scene.slack(src, 0) + 4 * faces.tol[f];
  const FaceRef self{0, f};
  for (std::uint32_t k = o0; k < o1; ++k) {
    const Vec3 w = faces.outline[k] - src;
    const double len = norm(w);
    if (!(len > 2 * margin)) return 0;
    const Vec3 dir = (1.0 / len) * w;
    scene.all_hits(src, dir, 0, len, hits, 16, &self);  // the first 16 (a lower bound either way)
    next.clear();
    for (const Hit& h : hits)
      if (h.face.instance == 0 && crosses_deep(faces, h.face.face, src, faces.outline[k], dir, h.t, margin))
        next.push_back(h.face.face);
    std::sort(next.begin(), next.end());
    next.erase(std::unique(next.begin(), next.end()), next.end());
    if (k == o0) {
      common.swap(next);
    } else {
      const auto end = std::set_intersection(common.begin(), common.end(), next.begin(), next.end(), common.begin());
      common.erase(end, common.end());
    }
    if (common.empty()) return 0;
  }
  return std::min(static_cast<int>(common.size()), limit);
}

}  // namespace

SlabBounds slab_bounds(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                       const std::vector<char>& wanted, int cap) {
  SlabBounds b;
  b.cap = cap;
  b.static_count = faces.static_count;
  b.lb.assign(nodes.size() * faces.static_count, 0);
  tbb::parallel_for(std::size_t{0}, nodes.size(), [&](std::size_t n) {
    if (!wanted[n]) return;
    std::vector<Hit> hits;
    std::vector<std::uint32_t> common, next;
    for (std::uint32_t f = 0; f < faces.static_count; ++f)
      b.lb[n * faces.static_count + f] =
          static_cast<std::uint8_t>(slabs_to_face(scene, faces, nodes[n].position, f, cap + 1, hits, common, next));
  });
  return b;
}

bool hidden_by_convex_face(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, const Vec3* points,
                           std::size_t count, const FaceRef* skip, double tol) {
  if (count < 2) return false;
  const double margin = 0.01 + 4 * scene.slack(src, 0) + 4 * tol;
  std::uint32_t blocker = ~0u;
  for (std::size_t k = 0; k < count; ++k) {
    const Vec3 w = points[k] - src;
    const double len = norm(w);
    if (!(len > 2 * margin)) return false;
    const Vec3 dir = (1.0 / len) * w;
    Hit hit;
    if (!scene.closest_hit(src, dir, 0, len, hit, skip)) return false;
    if (hit.face.instance != 0 || !faces.convex[hit.face.face]) return false;
    if (blocker != ~0u && hit.face.face != blocker) return false;
    blocker = hit.face.face;
    if (!crosses_deep(faces, blocker, src, points[k], dir, hit.t, margin)) return false;
  }
  return true;
}

void reflected_edges(const TraceScene& scene, const ImageFaces& faces, const Vec3& src, double range,
                     std::vector<ReflectedEdge>& out, const std::vector<std::uint32_t>* only) {
  const auto& edges = scene.edges();
  if (edges.empty() || (only && only->empty())) return;
  // The tree the walk runs down: every edge's, or one over `only`.
  const std::vector<ImageFaces::SphereNode>* tree = &faces.edge_tree;
  const std::vector<std::uint32_t>* order = &faces.edge_order;
  std::vector<ImageFaces::SphereNode> only_tree;
  std::vector<std::uint32_t> only_order;
  if (only) {
    only_order = *only;
    const std::vector<double> no_tol(edges.size(), 0.0);
    build_sphere_tree(faces.edge_spheres, no_tol, only_tree, only_order, 0,
                      static_cast<std::uint32_t>(only_order.size()));
    tree = &only_tree;
    order = &only_order;
  }
  std::vector<Vec3> pyramid;
  std::vector<std::uint32_t> stack;
  for (std::uint32_t f = 0; f < faces.static_count; ++f) {
    const Plane& pl = faces.planes[f];
    const double ds = dot(pl.normal, src) - pl.offset;
    if (ds == 0) continue;
    // A face hidden whole from src by one convex face reflects nothing to
    // its edges (a few rays: cheaper than the walk below).
    const FaceRef self{0, f};
    if (hidden_by_convex_face(scene, faces, src, &faces.outline[faces.outline_begin[f]],
                              faces.outline_begin[f + 1] - faces.outline_begin[f], &self, faces.tol[f]))
      continue;
    const Vec3 img = src - (2 * ds) * pl.normal;
    pyramid.clear();
    outline_pyramid(faces, f, img, pyramid);
    const double spread_per_m = 2 * faces.tol[f] / std::fabs(ds);
    const double side = ds > 0 ? 1 : -1;
    // Outside the beam: wholly behind the face (seen from the source), out
    // of range of the image, or outside the pyramid through the outline.
    auto outside = [&](const TraceScene::Sphere& sp, double tol) {
      const double h = dot(pl.normal, sp.centre) - pl.offset;
      if (side * h + sp.radius <= 0) return true;
      if (norm(sp.centre - img) - sp.radius > range) return true;
      return outside_pyramid(pyramid, img, sp, tol + faces.tol[f], spread_per_m);
    };
    walk_tree(*tree, *order, stack, outside, [&](std::uint32_t k) {
      if (outside(faces.edge_spheres[k], 0)) return;
      const Edge& e = edges[k];
      // The part of the edge inside the beam: the segment clipped by the
      // face's plane (the source's side) and the pyramid's planes, each
      // padded as the tests above pad them (at the edge's far end).
      const double len = norm(e.b - e.a);
      const double far = norm(faces.edge_spheres[k].centre - img) + 0.5 * len;
      const double pad = faces.tol[f] + (spread_per_m + 1e-6) * far + 1e-9 * len;
      double z0 = 0, z1 = len;
      auto clip = [&](const Vec3& nrm, double h_a) {  // keep z where h_a + z (nrm . e) >= -pad
        const double slope = dot(nrm, e.e);
        if (slope == 0) {
          if (h_a < -pad) z1 = -1;
          return;
        }
        const double z = (-pad - h_a) / slope;
        if (slope > 0) z0 = std::max(z0, z);
        else z1 = std::min(z1, z);
      };
      clip(side * pl.normal, side * (dot(pl.normal, e.a) - pl.offset));
      for (const auto& nrm : pyramid) clip(nrm, dot(nrm, e.a - img));
      if (!(z0 <= z1)) return;
      // The image must see the edge from outside its wedge.
      const Vec3 w = img - e.a;
      const double zt = dot(w, e.e);
      const Vec3 v = w - zt * e.e;
      double angle = std::atan2(dot(v, e.n0), dot(v, e.t0));
      if (angle < 0) angle += 2 * kPi;
      if (angle > e.n * kPi) return;
      // A face in the wedge's own planes reflects onto its edge at grazing
      // incidence: the UTD coefficient's reflection terms hold that already.
      for (const FaceRef* wf : {&e.face0, &e.face_n}) {
        const Plane& pw = faces.planes[wf->face];
        if (wf->face == f || (std::fabs(dot(pw.normal, pl.normal)) > 1 - 1e-9 &&
                              std::fabs(dot(pw.normal, pl.normal) * pw.offset - pl.offset) < 1e-6))
          return;
      }
      // The reflection points of this part: a segment on f (the central
      // projection of the part from the image); hidden whole from src, no
      // path reflected there reaches the edge.
      const Vec3 ends[2] = {crossing(img, -ds, e.a + z0 * e.e, dot(pl.normal, e.a + z0 * e.e) - pl.offset),
                            crossing(img, -ds, e.a + z1 * e.e, dot(pl.normal, e.a + z1 * e.e) - pl.offset)};
      if (hidden_by_convex_face(scene, faces, src, ends, 2, &self, faces.tol[f])) return;
      out.push_back({f, k, z0, z1, zt, norm(v)});
    });
  }
  std::sort(out.begin(), out.end());
}

}  // namespace raysweep::tracer
