// The beam searches of (static face, vehicle) combinations: the wall's echo
// off a car, with the ground between or last.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "search/beam_geometry.hpp"
#include "search/beam_search.hpp"
#include "search/source_search.hpp"

namespace raysweep::tracer {

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
                             const BeamVehicleOptions& options, ImageSearchStats* stats) {
  if (combos.empty() || receivers.empty()) return;
  BeamVehicleSearch search(scene, faces, nodes, src, receivers, out, options.with_ground, options.method);
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

}  // namespace raysweep::tracer
