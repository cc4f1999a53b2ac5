// image_candidates' sequences of two or more static faces: order 2 over
// every pair of static faces, and order 3 through the ground.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "search/beam_geometry.hpp"
#include "search/source_search.hpp"

namespace raysweep::tracer {

namespace {

// The static pairs' search, one first face at a time: the beam it
// reflects, the second faces in it and each second face's receivers.
class StaticPairSearch : public CappedSearch {
 public:
  using CappedSearch::CappedSearch;

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
    last_leg_bounds(higher_from);
    for (std::uint32_t f1 = 0; f1 < faces.static_count; ++f1) from_first_face(f1);
  }

 private:
  // static_pairs' state: the ground planes for order 3 (none without it),
  // every receiver's image in each of them (relative to the source), the
  // beams' pyramids and the tree walk's stack.
  const std::vector<ImageFaces::GroundPlane>* grounds = nullptr;
  Receivers mirrored;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> mirrored_of;  // (ground plane, receiver index)
  std::vector<std::uint32_t> ground_set, ground_sub;  // ground faces of one plane still in play
  std::vector<Vec3> pyramid, pyramid_g;
  std::vector<std::uint32_t> tree_stack;

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
    int budget;  // slabs the first leg leaves to the last (last_leg_budget)
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
    const FirstBounce b1{f1, p1, ds, i1, 2 * faces.tol[f1] / std::fabs(ds), last_leg_budget(f1)};
    // Order 2 (f1, f2), and order 3 (f1, f2, ground) towards the mirrored
    // receivers (whose last leg leaves from the ground, not from f2).
    walk_beam(
        b1, beam, p1, ds, mirrored.size() == 0,
        [&](std::uint32_t f2) { return face_reaches(faces, f1, ds > 0 ? 1 : -1, f2); },
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
  // the rest that `reaches` (f2 reaches the side the beam leaves on). With
  // `f2_last` (every sequence searched ends on f2), also the groups and
  // faces whose last legs put the sequence over the slab cap.
  template <class Reaches, class Leaf>
  void walk_beam(const FirstBounce& b1, const Beam& b, const Plane& plane, double side, bool f2_last,
                 Reaches&& reaches, Leaf&& leaf) {
    walk_static_tree(
        faces, tree_stack,
        [&](const TraceScene::Sphere& sp, double tol, std::uint32_t at) {
          if (f2_last && last_node_over(at, b1.budget)) return true;
          const double h = dot(plane.normal, sp.centre) - plane.offset;
          if ((side > 0 ? h : -h) + sp.radius <= 0) return true;  // wholly behind: no face reaches
          return outside_beam(b1, b, sp, tol, sp.radius);
        },
        [&](std::uint32_t f2) {
          if ((f2_last && last_face_over(f2, b1.budget)) || !reaches(f2) ||
              outside_beam(b1, b, faces.spheres[f2], faces.tol[f2], 0))
            return;
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
      if (g == f1 || !face_reaches(faces, f1, b1.ds > 0 ? 1 : -1, g)) continue;
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
    // tried with those. The faces share one plane (either orientation,
    // bitwise), so the answer is the same for faces of the same flatness.
    auto reaches = [&](std::uint32_t f2) {
      ground_sub.clear();
      double eps = -1;
      bool known = false;
      for (const std::uint32_t j : ground_set) {
        const std::uint32_t g = gp.faces[j];
        if (f2 == g) continue;
        if (faces.off_plane[g] != eps) {
          eps = faces.off_plane[g];
          known = face_reaches(faces, g, (dg > 0) != (gp.flipped[j] != 0) ? 1 : -1, f2);
        }
        if (known) ground_sub.push_back(g);
      }
      return !ground_sub.empty();
    };
    walk_beam(b1, bg, pg, dg, true, reaches, [&](std::uint32_t f2) { after_ground(b1, pg, dg, i1g, f2); });
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

void static_pair_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                            std::uint32_t src, const std::vector<std::uint32_t>& receivers, const SlabBounds* slabs,
                            bool ground3, std::vector<ImageCandidate>& out, ImageSearchStats* stats) {
  StaticPairSearch search(scene, faces, nodes, src, receivers, out, slabs);
  search.static_pairs(ground3);
  search.add_stats(stats);
}

}  // namespace raysweep::tracer
