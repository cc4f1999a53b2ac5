// The beam searches of lit pairs (a static face, then a second face):
// their third faces.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "search/beam_geometry.hpp"
#include "search/beam_search.hpp"
#include "search/source_search.hpp"

namespace raysweep::tracer {

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
      if (f2 != f1 && face_reaches(faces, f1, ds > 0 ? 1 : -1, f2) && !outside(faces.spheres[f2], faces.tol[f2]))
        pairs.push_back({f1, f2});
    });
  }
}

namespace {

// beam_pair_candidates' search, one lit pair (f1, f2) at a time: the beam
// after f2, the third faces in it, and each third face's receivers.
class BeamPairSearch : public CappedSearch {
 public:
  BeamPairSearch(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes, std::uint32_t src,
                 const std::vector<std::uint32_t>& receivers, std::vector<ImageCandidate>& out, const SlabBounds* slabs,
                 bool skip_ground)
      : CappedSearch(scene, faces, nodes, src, receivers, out, slabs), skip_ground(skip_ground) {
    last_leg_bounds(0);
  }

  void pair(const BeamPair& bp) {
    f1 = bp.f1;
    f2 = bp.f2;
    if (over_cap(f1)) return;
    budget = last_leg_budget(f1);
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
  int budget = 0;  // the slabs the pair's first leg leaves to the last (CappedSearch::last_leg_bounds)
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
        [&](const TraceScene::Sphere& sp, double tol, std::uint32_t at) {
          return last_node_over(at, budget) || behind(sp) || outside(sp, tol);
        },
        [&](std::uint32_t f3) {
          if (f3 == f2 || last_face_over(f3, budget) || (f2_static && !face_reaches(faces, f2, side, f3)) ||
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
    const bool f3_static = f3 < faces.static_count;
    for (std::size_t r = 0; r < rx.size(); ++r) {
      if (!scratch.hit[r] || (f3_static && over_cap(f1, r, f3))) continue;
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
                          ImageSearchStats* stats, bool skip_ground, const SlabBounds* slabs) {
  if (beam_pairs.empty() || receivers.empty()) return;
  BeamPairSearch search(scene, faces, nodes, src, receivers, out, slabs, skip_ground);
  for (const BeamPair& bp : beam_pairs) search.pair(bp);
  search.add_stats(stats);
}

}  // namespace raysweep::tracer
