// Vehicle models' multi-bounce sequences per arrival direction
// (TraceScene::vehicle_bounce_sequences): built on first use, or taken
// from the precompute store.
#include <tbb/parallel_for.h>

#include <map>

#include "scene/model_tables.hpp"
#include "scene/scene_impl.hpp"
#include "tracer/em/constants.hpp"

namespace raysweep::tracer {

namespace {

constexpr int kBounceCells = 16;
// Angular radius of an octahedral cell (16 x 16: at most ~0.17 rad from its
// centre direction) and the query radii the table is unioned for.
constexpr double kBounceCellRadius = 0.2;
constexpr double kBounceLevels[] = {0.2, 0.4, 0.8};

// Plane waves from every direction cell (2 x 2 directions inside each) as
// bundles of parallel rays over the model's bounding disc (41 x 41 grid),
// followed through up to three specular reflections against the model
// alone, and straight through its low-loss slabs (`see_through` faces:
// glass, plastic, textile), where they branch: a bus's or a car's cabin
// echoes between its windows and roof. Every sequence of two or three
// reflecting faces a ray follows is listed under its cell. Deterministic
// (fixed directions and grid).
void build_bounce_table(const TraceScene::Shape& s, const std::vector<char>& see_through,
                        std::vector<TraceScene::BounceSequence>& seqs, std::vector<std::vector<std::uint32_t>>& cells) {
  using Key = std::array<std::uint32_t, 5>;  // faces, the order, the sides (BounceSequence::front)
  const Vec3 c = s.bounds.centre;
  const double r = s.bounds.radius;
  constexpr int kHalf = 20, kMaxCrossings = 4, kCellCount = kBounceCells * kBounceCells;
  const double h = r / kHalf;
  std::vector<std::vector<Key>> found(kCellCount);
  tbb::parallel_for(0, kCellCount, [&](int cell) {
    const int i = cell / kBounceCells, j = cell % kBounceCells;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct Ray {
      Vec3 o, d;
      double tnear;
      int n, crossings;
      std::array<std::uint32_t, 3> seq;
      unsigned front;
    };
    std::vector<Ray> stack;
    auto& keys = found[cell];
    for (int sub = 0; sub < 4; ++sub) {
      const double u = -1 + (i + 0.25 + 0.5 * (sub & 1)) * 2.0 / kBounceCells;
      const double v = -1 + (j + 0.25 + 0.5 * (sub >> 1)) * 2.0 / kBounceCells;
      const Vec3 d = octa_dir(u, v);
      const Vec3 e1 = any_perpendicular(d), e2 = cross(d, e1);
      for (int gx = -kHalf; gx <= kHalf; ++gx)
        for (int gy = -kHalf; gy <= kHalf; ++gy) {
          if (gx * gx + gy * gy > kHalf * kHalf) continue;
          stack.push_back({c - (2 * r) * d + (gx * h) * e1 + (gy * h) * e2, d, 0, 0, 0, {}, 0u});
          while (!stack.empty()) {
            Ray ray = stack.back();
            stack.pop_back();
            RTCRayHit rh = make_ray(ray.o, ray.d, ray.tnear, 8 * r);
            rtcIntersect1(s.scene, &ctx, &rh);
            if (rh.hit.geomID == kNone) continue;
            const std::uint32_t f = s.tri_face[rh.hit.primID];
            const Vec3 p = ray.o + static_cast<double>(rh.ray.tfar) * ray.d;
            if (see_through[f] && ray.crossings < kMaxCrossings)
              stack.push_back({p, ray.d, 1e-4, ray.n, ray.crossings + 1, ray.seq, ray.front});
            const Vec3& n = s.face_plane[f].normal;
            Ray next{p, ray.d, 1e-4, ray.n + 1, ray.crossings, ray.seq, ray.front};
            next.seq[ray.n] = f;
            if (dot(ray.d, n) < 0) next.front |= 1u << ray.n;
            if (next.n >= 2)
              keys.push_back({next.seq[0], next.seq[1], next.n == 3 ? next.seq[2] : 0u, static_cast<std::uint32_t>(next.n),
                              next.front});
            if (next.n == 3) continue;
            next.d = ray.d - (2 * dot(ray.d, n)) * n;
            stack.push_back(next);
          }
        }
    }
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  });
  // Ids in cell order: the same table for any thread count.
  std::map<Key, std::uint32_t> ids;
  std::vector<std::vector<std::uint32_t>> per_cell(kCellCount);
  for (int cell = 0; cell < kCellCount; ++cell)
    for (const Key& k : found[cell]) {
      auto [it, fresh] = ids.try_emplace(k, static_cast<std::uint32_t>(seqs.size()));
      if (fresh) seqs.push_back({{k[0], k[1], k[2]}, static_cast<int>(k[3]), k[4]});
      per_cell[cell].push_back(it->second);
    }
  // Per level and cell, the union over the cells whose centres lie within
  // the level's radius plus two cell radii of this cell's centre: a query
  // from anywhere in the cell with spread + margin <= the level's radius
  // needs no other cell.
  std::vector<Vec3> centre(kCellCount);
  for (int cell = 0; cell < kCellCount; ++cell)
    centre[cell] = octa_dir(-1 + (cell / kBounceCells + 0.5) * 2.0 / kBounceCells,
                            -1 + (cell % kBounceCells + 0.5) * 2.0 / kBounceCells);
  cells.assign(std::size(kBounceLevels) * kCellCount, {});
  for (std::size_t level = 0; level < std::size(kBounceLevels); ++level)
    for (int cell = 0; cell < kCellCount; ++cell) {
      auto& list = cells[level * kCellCount + cell];
      const double cos_r = std::cos(std::min(kPi, kBounceLevels[level] + 2 * kBounceCellRadius));
      for (int other = 0; other < kCellCount; ++other)
        if (dot(centre[cell], centre[other]) >= cos_r) list.insert(list.end(), per_cell[other].begin(), per_cell[other].end());
      std::sort(list.begin(), list.end());
      list.erase(std::unique(list.begin(), list.end()), list.end());
    }
}

// Sequences (faces, order, sides: 5 words each), then each cell list (its
// length, then its ids).
std::vector<std::uint32_t> encode_bounce_table(const std::vector<TraceScene::BounceSequence>& seqs,
                                               const std::vector<std::vector<std::uint32_t>>& cells) {
  std::vector<std::uint32_t> w{static_cast<std::uint32_t>(seqs.size())};
  for (const auto& q : seqs)
    w.insert(w.end(), {q.faces[0], q.faces[1], q.faces[2], static_cast<std::uint32_t>(q.order), q.front});
  w.push_back(static_cast<std::uint32_t>(cells.size()));
  for (const auto& c : cells) {
    w.push_back(static_cast<std::uint32_t>(c.size()));
    w.insert(w.end(), c.begin(), c.end());
  }
  return w;
}

bool decode_bounce_table(const std::vector<std::uint32_t>& w, const TraceScene::Shape& s,
                         std::vector<TraceScene::BounceSequence>& seqs, std::vector<std::vector<std::uint32_t>>& cells) {
  const std::size_t faces = s.face_plane.size(), n_cells = std::size(kBounceLevels) * kBounceCells * kBounceCells;
  std::size_t at = 0;
  auto next = [&](std::uint32_t& v) { return at < w.size() ? (v = w[at++], true) : false; };
  std::uint32_t n = 0;
  if (!next(n) || n > (w.size() - 1) / 5) return false;
  std::vector<TraceScene::BounceSequence> q(n);
  for (auto& b : q) {
    std::uint32_t order = 0;
    if (!(next(b.faces[0]) && next(b.faces[1]) && next(b.faces[2]) && next(order) && next(b.front))) return false;
    b.order = static_cast<int>(order);
    if (order < 1 || order > 3 || b.front >= (1u << order)) return false;
    for (std::uint32_t k = 0; k < order; ++k)
      if (b.faces[k] >= faces) return false;
  }
  std::uint32_t m = 0;
  if (!next(m) || m != n_cells) return false;
  std::vector<std::vector<std::uint32_t>> c(m);
  for (auto& list : c) {
    std::uint32_t len = 0;
    if (!next(len) || len > w.size() - at) return false;
    list.assign(w.begin() + static_cast<std::ptrdiff_t>(at), w.begin() + static_cast<std::ptrdiff_t>(at + len));
    at += len;
    for (std::size_t k = 0; k < list.size(); ++k)
      if (list[k] >= n || (k > 0 && list[k] <= list[k - 1])) return false;
  }
  if (at != w.size()) return false;
  seqs = std::move(q);
  cells = std::move(c);
  return true;
}

}  // namespace

TraceScene::BounceQuery TraceScene::vehicle_bounce_sequences(std::size_t v, const Vec3& dir, double spread) const {
  const auto& d = *impl_;
  const Shape& s = *d.models[vehicles_.at(v).model];
  std::call_once(s.bounce_once, [&] {
    // Low-loss slabs of the vehicle materials (names as in meshkit's
    // material table); metal, rubber and the riders only reflect here.
    std::vector<char> see_through(s.face_material.size());
    for (std::size_t f = 0; f < see_through.size(); ++f) {
      const std::string& m = materials_.at(s.face_material[f]);
      see_through[f] = m == "glass" || m == "plastic" || m == "textile";
    }
    cached_table(
        d.store.get(), "bounce-" + ContentKey().add(s.content_key).add_vector(see_through).hex(),
        [&](const std::vector<std::uint32_t>& w) { return decode_bounce_table(w, s, s.bounce_seq, s.bounce_near); },
        [&] { build_bounce_table(s, see_through, s.bounce_seq, s.bounce_near); },
        [&] { return encode_bounce_table(s.bounce_seq, s.bounce_near); });
    s.bounce_all.resize(s.bounce_seq.size());
    for (std::uint32_t k = 0; k < s.bounce_all.size(); ++k) s.bounce_all[k] = k;
  });
  std::size_t level = 0;
  while (level < std::size(kBounceLevels) && kBounceLevels[level] < spread) ++level;
  if (level == std::size(kBounceLevels)) return {&s.bounce_seq, &s.bounce_all};
  const double c = d.cos_yaw[v], sn = d.sin_yaw[v];
  const auto [i, j] = octa_cell(Vec3{c * dir[0] + sn * dir[1], -sn * dir[0] + c * dir[1], dir[2]}, kBounceCells);
  return {&s.bounce_seq, &s.bounce_near[level * kBounceCells * kBounceCells + i * kBounceCells + j]};
}

}  // namespace raysweep::tracer
