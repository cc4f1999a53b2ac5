#include "search/image_search.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "search/beam_geometry.hpp"
#include "search/source_search.hpp"

namespace raysweep::tracer {

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

// image_candidates' stages on single faces and on one vehicle (the static
// pairs: search/static_pairs.cpp), one method per kind of sequence.
class ImageSearch : public CappedSearch {
 public:
  using CappedSearch::CappedSearch;

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
  // end it is vehicle then ground). The faces of one ground plane (a ground
  // split into patches) share the source's image, bitwise whatever their
  // orientation, and so its reflections on the vehicles: one search per
  // plane, then each face's own on-face test.
  void ground_then_vehicle() {
    for (const auto& gp : faces.ground_planes) {
      const Plane& pg = gp.plane;
      const double ds = dot(pg.normal, xs) - pg.offset;
      if (ds == 0) continue;
      const Vec3 i1 = xs - (2 * ds) * pg.normal;
      for (std::size_t v = 0; v + 1 < faces.vehicle_begin.size(); ++v) {
        const auto& sv = faces.vehicle_spheres[v];
        const double h = dot(pg.normal, sv.centre) - pg.offset;
        if (ds > 0 ? h + sv.radius <= 0 : h - sv.radius >= 0) continue;  // not on the source's side
        for (std::size_t r = 0; r < rx.size(); ++r)
          vehicle_reflections(v, i1, r, [&](std::size_t f, const Vec3& q2) {
            for (const std::uint32_t g : gp.faces) {
              const Plane& pf = faces.planes[g];
              const double dg = dot(pf.normal, xs) - pf.offset, d2 = dot(pf.normal, q2) - pf.offset;
              if (dg * d2 > 0 && on_face(g, crossing(i1, -dg, q2, d2)))
                out.push_back({receivers[r], {faces.refs[g], faces.refs[f]}});
            }
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

 private:
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
};

}  // namespace

void image_candidates(const TraceScene& scene, const ImageFaces& faces, const std::vector<Node>& nodes,
                      std::uint32_t src, const std::vector<std::uint32_t>& receivers, int max_order,
                      std::vector<ImageCandidate>& out, const ImageSearchOptions& options, ImageSearchStats* stats) {
  if (max_order < 1 || receivers.empty()) return;
  ImageSearch search(scene, faces, nodes, src, receivers, out, options.slabs);
  search.static_order1();
  search.vehicle_order1();
  if (max_order >= 2) search.ground_then_vehicle();
  if (options.multi_bounce && max_order >= 2) search.on_one_vehicle(max_order);
  search.add_stats(stats);
  if (max_order >= 2)
    static_pair_candidates(scene, faces, nodes, src, receivers, options.slabs,
                           options.ground_order3 && max_order >= 3 && faces.static_count > 0, out, stats);
}

}  // namespace raysweep::tracer
