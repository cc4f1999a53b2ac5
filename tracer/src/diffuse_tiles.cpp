#include "diffuse_tiles.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace raysweep::tracer {

namespace {

using CVec3 = std::array<cdouble, 3>;

double longest_edge(const std::array<Vec3, 3>& t) {
  return std::max({norm(t[1] - t[0]), norm(t[2] - t[1]), norm(t[0] - t[2])});
}

// Halves `t` across its longest edge.
std::array<std::array<Vec3, 3>, 2> bisect(const std::array<Vec3, 3>& t) {
  int k = 0;  // the edge t[k] -> t[k + 1] is the longest
  double best = -1;
  for (int e = 0; e < 3; ++e) {
    const double l = norm(t[(e + 1) % 3] - t[e]);
    if (l > best) {
      best = l;
      k = e;
    }
  }
  const Vec3 &a = t[k], &b = t[(k + 1) % 3], &c = t[(k + 2) % 3];
  const Vec3 m = 0.5 * (a + b);
  return {{{a, m, c}, {m, b, c}}};
}

struct SurfaceTile {
  std::array<Vec3, 3> v;  // world triangle
  Vec3 centre{0, 0, 0};
  double area = 0;
  double size = 0;  // longest edge
  std::uint32_t face = 0;  // static face
};

SurfaceTile make_tile(const std::array<Vec3, 3>& t, std::uint32_t face) {
  SurfaceTile s;
  s.v = t;
  s.centre = (1.0 / 3.0) * (t[0] + t[1] + t[2]);
  s.area = 0.5 * norm(cross(t[1] - t[0], t[2] - t[0]));
  s.size = longest_edge(t);
  s.face = face;
  return s;
}


// Static faces for which `wanted[face]` holds, cut into tiles of longest
// edge <= tile_m; ordered by face.
std::vector<SurfaceTile> tile_static_faces(const TraceScene& scene, const std::vector<unsigned char>& wanted,
                                           double tile_m) {
  std::vector<SurfaceTile> tiles;
  std::vector<std::array<Vec3, 3>> tris, stack;
  for (std::uint32_t f = 0; f < wanted.size(); ++f) {
    if (!wanted[f]) continue;
    tris.clear();
    scene.face_triangles(FaceRef{0, f}, tris);
    for (const auto& t : tris) {
      stack.assign(1, t);
      while (!stack.empty()) {
        const auto cur = stack.back();
        stack.pop_back();
        if (longest_edge(cur) <= tile_m) {
          const SurfaceTile s = make_tile(cur, f);
          if (s.area > 0) tiles.push_back(s);
          continue;
        }
        const auto halves = bisect(cur);
        stack.push_back(halves[1]);
        stack.push_back(halves[0]);
      }
    }
  }
  return tiles;
}

}  // namespace

// A tile as node `node` sees it: the incident geometry and the field a
// smooth surface would reflect there (antenna pattern times the slab's
// reflection coefficients, no spreading), all the pair integration needs
// from this end.
struct DiffuseTiles::View {
  std::uint32_t tile = 0;
  // The tile's own record (a copy of the tree's, which the pair walks would
  // otherwise fetch from all over its arrays): centre, size and area, its
  // face, its subtree's end and its second child (0 for a leaf).
  struct Record {
    Vec3 centre{0, 0, 0};
    double size = 0, area = 0;
    std::uint32_t face = 0, end = 0, second = 0;
  } record;
  std::uint32_t object = 0;
  std::uint16_t material = 0;
  double r = 0;               // node -> tile centre
  Vec3 k{0, 0, 0};            // unit, node -> tile (incident direction)
  Vec3 field{0, 0, 0};        // the node's antenna field along k (it transmits and receives with it)
  Vec3 n_front{0, 0, 1};      // face normal on the node's side
  Vec3 spec{0, 0, 0};         // specular direction of k
  CVec3 e_ref{};              // smoothly reflected field
  double e_ref2 = 0;          // |e_ref|^2
  double cos_i = 0;
  ScatteringLobeAt lobe;       // the scattering pattern at this incidence
  const Scattering* sc = nullptr;
  const Node* node = nullptr;
};

// The tile tree in pre-order (depth first, the first half first): node i's
// first child is i + 1, its second child end[i + 1], and its subtree ends
// before end[i] (a leaf: end[i] == i + 1). So every walk of the tree, which
// goes depth first, visits nodes in index order: one end's visited nodes
// are a sorted list, a pair's walk merges its two ends' lists, and both
// read the tree's arrays forwards.
struct DiffuseTiles::Tree {
  struct Tile {  // what the walks read, together (one cache line or two)
    Vec3 centre;
    double size;  // longest edge
    double area;
    std::uint32_t face;  // static face
    std::uint32_t end;
  };
  std::vector<Tile> tile;
  std::vector<std::array<Vec3, 3>> v;  // world triangle
  std::vector<std::uint32_t> roots;
  std::size_t leaves = 0;

  bool leaf(std::uint32_t t) const { return tile[t].end == t + 1; }

  // `t` and its subtree, halved down to leaves of longest edge <= leaf_m.
  void add(const std::array<Vec3, 3>& t, std::uint32_t f, double leaf_m) {
    const auto i = static_cast<std::uint32_t>(tile.size());
    const SurfaceTile s = make_tile(t, f);
    tile.push_back({s.centre, s.size, s.area, f, i + 1});
    v.push_back(t);
    if (s.size <= leaf_m) {
      ++leaves;
      return;
    }
    const auto halves = bisect(t);
    add(halves[0], f, leaf_m);
    add(halves[1], f, leaf_m);
    tile[i].end = static_cast<std::uint32_t>(tile.size());
  }
};

namespace {
enum : std::int32_t { kBelow = -1, kHidden = -2, kRefine = -3 };
constexpr double kRootTileM = 32;

struct Visit {
  std::uint32_t node;
  std::int32_t state;  // kHidden, kRefine, or the index of the node's view of the tile
  // For kRefine: the node's subtree end and second child (the pair walks
  // read them here, in list order, not from the tree).
  std::uint32_t end = 0, second = 0;
};
}  // namespace

// One node's visibility cut through the tile tree: the tree nodes its walk
// visited, in index order, with what it decided there.
struct DiffuseTiles::Sight {
  std::vector<Visit> visits;
  std::vector<View> views;
};

DiffuseTiles::DiffuseTiles(const TraceScene& scene, const Electromagnetics& em, const std::vector<Node>& nodes,
                           const std::vector<unsigned char>& wanted, const TracerConfig& cfg, double range)
    : scene_(scene), em_(em), nodes_(nodes), ratio_(cfg.diffuse_tile_ratio), shadow_ratio_(cfg.diffuse_shadow_ratio) {
  const auto nf = static_cast<std::uint32_t>(scene.face_count(0));
  std::string rough(nf, '\0');
  for (std::uint32_t f = 0; f < nf; ++f) rough[f] = em.material(scene.material(FaceRef{0, f})).scattering.s > 0;
  // The static faces never move: their tree is built once per scene, tile
  // size and set of rough faces.
  const double leaf_m = cfg.diffuse_tile_m;
  char key[64];
  std::snprintf(key, sizeof key, "diffuse-tiles %.17g ", leaf_m);
  tree_ = std::static_pointer_cast<const Tree>(scene.static_memo(key + rough, [&]() -> std::shared_ptr<const void> {
    auto tree = std::make_shared<Tree>();
    const std::vector<unsigned char> wanted_faces(rough.begin(), rough.end());
    for (const SurfaceTile& r : tile_static_faces(scene, wanted_faces, std::max(leaf_m, kRootTileM))) {
      tree->roots.push_back(static_cast<std::uint32_t>(tree->tile.size()));
      tree->add(r.v, r.face, leaf_m);
    }
    return tree;
  }));
  const Tree& T = *tree_;
  sight_.resize(nodes.size());
  std::vector<std::uint64_t> rays(nodes.size(), 0);
  tbb::parallel_for(std::size_t{0}, nodes.size(), [&](std::size_t i) {
    if (!wanted[i]) return;
    Sight& sight = sight_[i];
    const auto node = static_cast<std::uint32_t>(i);
    const Vec3 x = nodes[i].position;
    const double t0 = scene.slack(x, 0) * 0.1;
    std::vector<std::uint32_t> stack(T.roots.rbegin(), T.roots.rend());
    auto refine = [&](std::uint32_t t) {
      sight.visits.push_back({t, kRefine, T.tile[t].end, T.tile[t + 1].end});
      stack.push_back(T.tile[t + 1].end);
      stack.push_back(t + 1);
    };
    View v;  // faces() and complete() set every field a view is read for (tile: here)
    while (!stack.empty()) {
      const std::uint32_t t = stack.back();
      stack.pop_back();
      const Vec3& centre = T.tile[t].centre;
      const double r = norm(centre - x);
      if (r - T.tile[t].size > range) {
        sight.visits.push_back({t, kHidden});
        continue;
      }
      const bool inner = !T.leaf(t);
      if (inner && T.tile[t].size > ratio_ * r) {
        refine(t);
        continue;
      }
      if (!faces(node, centre, T.tile[t].face, v)) {
        sight.visits.push_back({t, kHidden});
        continue;
      }
      // Anything between the antenna and a point of the tile shadows it.
      auto clear = [&](const Vec3& p) {
        const Vec3 w = p - x;
        const double r = norm(w);
        const double tfar = r - std::max(scene.slack(p, 0), 1e-6 * r);
        ++rays[i];
        return !(tfar > t0 && scene.occluded(x, (1.0 / r) * w, t0, tfar));
      };
      const bool seen = clear(centre);
      if (inner && T.tile[t].size > shadow_ratio_ * r) {
        // Not a leaf: where a shadow edge crosses the tile (its corners,
        // pulled a tenth towards the centre, disagree with the centre), the
        // tile is refined down to where they agree, or to the leaves.
        bool agree = true;
        for (int q = 0; q < 3 && agree; ++q) agree = clear(0.9 * T.v[t][q] + 0.1 * centre) == seen;
        if (!agree) {
          refine(t);
          continue;
        }
      }
      if (!seen) {
        sight.visits.push_back({t, kHidden});
        continue;
      }
      complete(node, T.tile[t].face, v);
      v.tile = t;
      const auto& tt = T.tile[t];
      v.record = {tt.centre, tt.size, tt.area, tt.face, tt.end, inner ? T.tile[t + 1].end : 0};
      sight.visits.push_back({t, static_cast<std::int32_t>(sight.views.size())});
      sight.views.push_back(v);
    }
  });
  for (auto r : rays) rays_ += r;
}

DiffuseTiles::~DiffuseTiles() = default;

std::size_t DiffuseTiles::tile_count() const { return tree_->leaves; }

std::uint64_t DiffuseTiles::views() const {
  std::uint64_t n = 0;
  for (const auto& s : sight_) n += s.views.size();
  return n;
}

bool DiffuseTiles::faces(std::uint32_t node, const Vec3& centre, std::uint32_t face, View& v) const {
  const Node& nd = nodes_[node];
  const Plane pl = scene_.plane(FaceRef{0, face});
  const double h = dot(pl.normal, nd.position) - pl.offset;
  if (h == 0) return false;  // in the plane: grazing, nothing scatters
  const Vec3 w = centre - nd.position;
  v.r = norm(w);
  if (!(v.r > 1e-6)) return false;
  v.k = (1.0 / v.r) * w;
  v.n_front = h > 0 ? pl.normal : -pl.normal;
  v.cos_i = -dot(v.k, v.n_front);
  return v.cos_i > 0;
}

void DiffuseTiles::complete(std::uint32_t node, std::uint32_t face, View& v) const {
  const Node& nd = nodes_[node];
  const FaceRef ref{0, face};
  v.material = scene_.material(ref);
  v.object = scene_.object(ref);
  v.sc = &em_.material(v.material).scattering;
  v.node = &nd;
  v.field = antenna_field(em_.radio().antenna, v.k, nd.forward);
  v.spec = v.k + (2 * v.cos_i) * v.n_front;
  const TeTm r = em_.reflection(v.material, v.cos_i);
  const Vec3 es = te_basis(v.k, v.n_front);
  const Vec3 ep_in = cross(es, v.k), ep_out = cross(es, v.spec);
  const cdouble a_te = r.te * dot(v.field, es), a_tm = r.tm * dot(v.field, ep_in);
  for (int q = 0; q < 3; ++q) v.e_ref[q] = a_te * es[q] + a_tm * ep_out[q];
  v.e_ref2 = std::norm(v.e_ref[0]) + std::norm(v.e_ref[1]) + std::norm(v.e_ref[2]);
  v.lobe = ScatteringLobeAt(*v.sc, v.k, scene_.plane(ref).normal);
}

namespace {

// One way of the bistatic term: incident from `a`'s side, received by `b`
// (its views give the scattered direction and the receive pattern).
template <class V>
double one_way(const V& a, const V& b, double area, double lambda) {
  const Vec3 ks = -b.k;  // tile -> receiver
  const double cos_s = dot(ks, a.n_front);
  if (!(cos_s > 0)) return 0;
  const Scattering& sc = *a.sc;
  const double f = a.lobe(ks);
  if (!(f > 0)) return 0;
  // The reflected field's part transverse to ks, co- and cross-polarised
  // against the receive pattern.
  const cdouble along = a.e_ref[0] * ks[0] + a.e_ref[1] * ks[1] + a.e_ref[2] * ks[2];
  const std::array<cdouble, 3> et{a.e_ref[0] - along * ks[0], a.e_ref[1] - along * ks[1], a.e_ref[2] - along * ks[2]};
  const double et2 = std::norm(et[0]) + std::norm(et[1]) + std::norm(et[2]);
  if (!(et2 > 1e-30)) return 0;
  const Vec3& fr = b.field;
  const std::array<cdouble, 3> ex{ks[1] * et[2] - ks[2] * et[1], ks[2] * et[0] - ks[0] * et[2],
                                  ks[0] * et[1] - ks[1] * et[0]};
  const double co = std::norm(et[0] * fr[0] + et[1] * fr[1] + et[2] * fr[2]);
  const double cross_pol = std::norm(ex[0] * fr[0] + ex[1] * fr[1] + ex[2] * fr[2]);
  const double g = ((1 - sc.xpd) * co + sc.xpd * cross_pol) * a.e_ref2 / et2;
  return sc.s * sc.s * f * g * lambda * lambda * area * a.cos_i /
         (16 * kPi * kPi * a.r * a.r * b.r * b.r);
}

struct Bin {
  std::uint32_t object = 0;
  std::int64_t bin = 0;
  double power = 0, tau = 0, doppler = 0;
  Vec3 point{0, 0, 0}, departure{0, 0, 0}, arrival{0, 0, 0};
  std::uint16_t material = 0;
};

}  // namespace

// pair_paths' walk, depth first through the tree. A node's visibility is
// decided at its cut; below it, tiles inherit it (`seen_a`, `seen_b`).
// Where an end refined, its walk visited the children too, so the next
// entry of its list is the tile this walk reaches (both go in index order).
class DiffuseTiles::PairWalk {
 public:
  PairWalk(const DiffuseTiles& tiles, std::uint32_t a, std::uint32_t b, double bin_s)
      : tiles_(tiles),
        a_(a),
        b_(b),
        bin_s_(bin_s),
        lambda_(tiles.em_.wavelength()),
        tree_(*tiles.tree_),
        sa_(tiles.sight_[a]),
        sb_(tiles.sight_[b]) {}

  void run() {
    const Tree& T = tree_;
    for (auto it = T.roots.rbegin(); it != T.roots.rend(); ++it) stack_.push_back({*it, false, false});
    while (!stack_.empty()) {
      const Item item = stack_.back();
      stack_.pop_back();
      const std::uint32_t t = item.t;
      const Visit* visit_a = item.seen_a ? nullptr : &take(sa_, ia_, t);
      const Visit* visit_b = item.seen_b ? nullptr : &take(sb_, ib_, t);
      const std::int32_t slot_a = visit_a ? visit_a->state : kBelow, slot_b = visit_b ? visit_b->state : kBelow;
      const bool seen_a = item.seen_a || slot_a >= 0, seen_b = item.seen_b || slot_b >= 0;
      if ((!seen_a && slot_a != kRefine) || (!seen_b && slot_b != kRefine)) {  // hidden from an end
        if (slot_a == kRefine) skip(sa_, ia_, visit_a->end);
        if (slot_b == kRefine) skip(sb_, ib_, visit_b->end);
        continue;
      }
      if (!seen_a || !seen_b) {
        stack_.push_back({(slot_a == kRefine ? visit_a : visit_b)->second, seen_a, seen_b});
        stack_.push_back({t + 1, seen_a, seen_b});
        continue;
      }
      both_see(t, slot_a, slot_b);
    }
  }

  // The bins as diffuse paths, appended to `out`.
  void emit(std::vector<Path>& out) const {
    for (const Bin& B : bins_) {
      if (!(B.power > 0)) continue;
      Path path = diffuse_record(B.power, B.tau, B.departure, B.arrival, B.doppler, lambda_);
      const double w = 1.0 / B.power;
      path.interactions.push_back(Interaction{InteractionType::diffuse, B.object, B.material, w * B.point});
      out.push_back(std::move(path));
    }
  }

 private:
  struct Item {
    std::uint32_t t;
    bool seen_a, seen_b;
  };

  // The next of an end's visits, which must be tile t's.
  static const Visit& take(const Sight& s, std::size_t& i, std::uint32_t t) {
    if (i >= s.visits.size() || s.visits[i].node != t) throw std::logic_error("diffuse tiles: walks out of step");
    return s.visits[i++];
  }
  // Past an end's visits below t (the other end does not see t): a
  // galloping search, as most skips are short.
  static void skip(const Sight& s, std::size_t& i, std::uint32_t e) {
    const std::size_t n = s.visits.size();
    std::size_t lo = i, step = 1;
    while (lo + step < n && s.visits[lo + step].node < e) {
      lo += step;
      step *= 2;
    }
    const auto first = s.visits.begin() + static_cast<std::ptrdiff_t>(lo);
    const auto last = s.visits.begin() + static_cast<std::ptrdiff_t>(std::min(n, lo + step));
    i = static_cast<std::size_t>(
        std::lower_bound(first, last, e, [](const Visit& v, std::uint32_t x) { return v.node < x; }) -
        s.visits.begin());
  }

  // Both ends see tile t (so neither list goes below it): integrate it,
  // finer where an end is close. Its record from an end's view, or from
  // the tree where both inherited it.
  void both_see(std::uint32_t t, std::int32_t slot_a, std::int32_t slot_b) {
    const Tree& T = tree_;
    const View* va = slot_a >= 0 ? &sa_.views[static_cast<std::size_t>(slot_a)] : nullptr;
    const View* vb = slot_b >= 0 ? &sb_.views[static_cast<std::size_t>(slot_b)] : nullptr;
    View::Record rec;
    if (va || vb) {
      rec = (va ? va : vb)->record;
    } else {
      const auto& tt = T.tile[t];
      rec = {tt.centre, tt.size, tt.area, tt.face, tt.end, T.leaf(t) ? 0 : T.tile[t + 1].end};
    }
    const Vec3& centre = rec.centre;
    const std::uint32_t face = rec.face;
    if (!va) {
      if (!tiles_.view(a_, centre, face, ca_)) return;
      va = &ca_;
    }
    if (!vb) {
      if (!tiles_.view(b_, centre, face, cb_)) return;
      vb = &cb_;
    }
    if (rec.size <= tiles_.ratio_ * std::min(va->r, vb->r)) {
      add(*va, *vb, rec.area, centre);
      return;
    }
    if (rec.end != t + 1) {  // not a leaf
      stack_.push_back({rec.second, true, true});
      stack_.push_back({t + 1, true, true});
      return;
    }
    below_leaf(t, face);
  }

  // Below the leaves: bisected for this pair only.
  void below_leaf(std::uint32_t t, std::uint32_t face) {
    finer_.assign(1, {tree_.v[t], 0});
    while (!finer_.empty()) {
      const auto [tri, depth] = finer_.back();
      finer_.pop_back();
      const SurfaceTile child = make_tile(tri, face);
      if (!tiles_.view(a_, child.centre, face, ca_) || !tiles_.view(b_, child.centre, face, cb_)) continue;
      if (depth < 12 && child.size > tiles_.ratio_ * std::min(ca_.r, cb_.r)) {
        const auto halves = bisect(tri);
        finer_.push_back({halves[1], depth + 1});
        finer_.push_back({halves[0], depth + 1});
        continue;
      }
      add(ca_, cb_, child.area, child.centre);
    }
  }

  // Tile (area, point) as x (a's view) and y (b's) see it, into its bin.
  void add(const View& x, const View& y, double area, const Vec3& point) {
    if (dot(x.n_front, y.n_front) <= 0) return;  // the ends on opposite sides of the face
    // Both ways, averaged: the sum is the same whichever end is `a`.
    const double p = 0.5 * (one_way(x, y, area, lambda_) + one_way(y, x, area, lambda_));
    if (!(p > 0)) return;
    const double tau = (x.r + y.r) / kSpeedOfLight;
    const auto bin = static_cast<std::int64_t>(std::floor(tau / bin_s_));
    if (last_ >= bins_.size() || bins_[last_].object != x.object || bins_[last_].bin != bin) {
      last_ = bins_.size();
      for (std::size_t q = 0; q < bins_.size(); ++q)
        if (bins_[q].object == x.object && bins_[q].bin == bin) last_ = q;
      if (last_ == bins_.size()) {
        bins_.push_back(Bin{});
        bins_.back().object = x.object;
        bins_.back().bin = bin;
        bins_.back().material = x.material;
      }
    }
    Bin& B = bins_[last_];
    B.power += p;
    B.tau += p * tau;
    B.point = B.point + p * point;
    // x is a's view, y b's: departure from a, arrival at b pointing back
    // towards the tile.
    B.departure = B.departure + p * x.k;
    B.arrival = B.arrival + p * y.k;
    const double dl = -(dot(x.k, x.node->velocity) + dot(y.k, y.node->velocity));
    B.doppler += p * (-dl / lambda_);
  }

  const DiffuseTiles& tiles_;
  const std::uint32_t a_, b_;
  const double bin_s_, lambda_;
  const Tree& tree_;
  const Sight& sa_;
  const Sight& sb_;
  std::size_t ia_ = 0, ib_ = 0;  // the next of each end's visits
  std::vector<Item> stack_;
  std::vector<std::pair<std::array<Vec3, 3>, int>> finer_;
  View ca_, cb_;  // views computed here: view() sets every field add() reads
  std::vector<Bin> bins_;
  std::size_t last_ = 0;  // the bin added to last
};

void DiffuseTiles::pair_paths(std::uint32_t a, std::uint32_t b, double bin_s, std::vector<Path>& out) const {
  PairWalk walk(*this, a, b, bin_s);
  walk.run();
  walk.emit(out);
}

}  // namespace raysweep::tracer
