#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "shoot/beam_marks.hpp"
#include "shoot/gathering.hpp"
#include "shoot/ray.hpp"
#include "shoot/reception.hpp"
#include "shoot/shoot.hpp"

namespace raysweep::tracer {

namespace {

// Shoot-and-bounce from one source over a range of lattice rays: each ray
// and the branches it spawns through slabs and off faces, and what they
// feed (the reception spheres, the beam marks, the diffuse gathering); the
// per-ray scratch (chain, stack) is kept across rays.
class Shooter {
 public:
  Shooter(const ShootContext& world, std::uint32_t src, const std::vector<Vec3>& lattice, const ShootFeeds& feeds,
          ShootFinds& finds);

  // Lattice ray r and every branch it spawns.
  void shoot(std::size_t r) {
    r_ = r;
    chain_.clear();
    hit_no_ = 0;
    RayState first{nodes_[src_].position, lattice_[r], 0, 0, 0, false, {}, 0, -1, {}, 0, nodes_[src_].velocity};
    if (scatter_) first.field = cvec(antenna_field(em_.radio().antenna, lattice_[r], nodes_[src_].forward));
    stack_.push_back(first);
    while (!stack_.empty()) {
      RayState st = stack_.back();
      stack_.pop_back();
      segment(st);
    }
  }

  void finish() { marks_.finish(); }

 private:
  // One branch's segment: to its closest hit, the candidates and beams it
  // passes, then the hit's scattering and the branches that leave it.
  void segment(const RayState& st) {
    Hit hit;
    const bool got = scene_.closest_hit(st.o, st.d, st.has_leaving ? 0 : 1e-4,
                                        std::numeric_limits<double>::infinity(), hit,
                                        st.has_leaving ? &st.leaving : nullptr);
    ++rays_;
    if (targets_ && !on_target(st, got, hit)) return;
    const double tseg = got ? hit.t : std::numeric_limits<double>::infinity();
    if (st.n > 0 && propose_) reception_.propose(st, chain_, tseg, reception_spacing());
    marks_.note_beams(st, chain_, std::min(tseg, 1e30));
    if (marks_.bundle_marks()) marks_.note_bundle_marks(st, chain_, std::min(tseg, 1e30), (*targets_)[r_].spacing);
    if (!got) return;
    ++hit_no_;
    at_hit(st, hit);
  }

  bool is_ground(const FaceRef& f) const {
    return f.instance == 0 && std::binary_search(beam_faces_->ground.begin(), beam_faces_->ground.end(), f.face);
  }

  // The reception spheres' angular spacing: the lattice's, or for a bundle
  // ray twice its bundle's own (not more than the lattice's). The lattice's
  // spheres around a bundle's dense rays proposed a third more candidates on
  // the ring road for no path.
  double reception_spacing() const {
    return targets_ ? std::min(spacing_, 2 * (*targets_)[r_].spacing * cfg_.reception_radius_factor) : spacing_;
  }

  // Whether a bundle ray's branch is still the bundle's business: its first
  // hit (after the face it is aimed through) another vehicle or the ground.
  // What meets a building first is the lattice's (far vehicles mostly stand
  // behind buildings), and so is the antenna's own roof below it; a vehicle
  // in front of the target, and the ground that the cap takes in below it,
  // carry chains of their own.
  bool on_target(const RayState& st, bool got, const Hit& hit) const {
    const BundleTarget& t = (*targets_)[r_];
    const int k = st.n + st.transmissions;
    const int mount = nodes_[src_].vehicle;  // -1: a road-side antenna
    const bool own = got && mount >= 0 && static_cast<int>(hit.face.instance) == mount + 1;
    const bool vehicle_or_ground = got && !own && (hit.face.instance != 0 || is_ground(hit.face));
    if (!t.via_face) return k > 0 || vehicle_or_ground;
    if (k == 0) return got && hit.face == t.face;
    if (k == 1) return st.n == 1 && vehicle_or_ground;
    return true;
  }

  // At a hit: the diffuse gathering, then the branches through the slab
  // and off its face.
  void at_hit(const RayState& st, const Hit& hit);

  void transmit(const RayState& st, const HitField& h) {
    const double loss = st.loss_db + em_.normal_transmission_loss_db(h.mat);
    if (!(loss <= cfg_.sbr_transmission_loss_db)) return;
    RayState next = st;
    next.o = h.p;
    next.len = st.len + h.hit->t;
    next.transmissions = st.transmissions + 1;
    next.loss_db = loss;
    next.has_leaving = true;
    next.leaving = h.hit->face;
    if (scatter_) {
      next.field = combine(h.coef.t.te * cdot(st.field, h.es), h.es, h.coef.t.tm * cdot(st.field, h.ep_in), h.ep_in);
      next.dl_dt = h.dl_in;
      next.v_prev = h.v_surf;
    }
    stack_.push_back(next);
  }

  void reflect(const RayState& st, const HitField& h) {
    RayState next = st;
    next.o = h.p;
    next.d = h.k_out;
    next.len = st.len + h.hit->t;
    next.has_leaving = true;
    next.leaving = h.hit->face;
    chain_.push_back(Link{h.hit->face, h.p, st.last});
    next.last = static_cast<std::int32_t>(chain_.size() - 1);
    ++next.n;
    if (scatter_) {
      const double keep = em_.specular_keep(h.mat);
      next.field = {keep * h.e_ref[0], keep * h.e_ref[1], keep * h.e_ref[2]};
      next.dl_dt = h.dl_in;
      next.v_prev = h.v_surf;
    }
    stack_.push_back(next);
  }

  const TraceScene& scene_;
  const Electromagnetics& em_;
  const TracerConfig& cfg_;
  const std::vector<Node>& nodes_;
  const std::uint32_t src_;
  const std::vector<Vec3>& lattice_;
  std::uint64_t& rays_;
  const DiffuseTargets* diffuse_;
  const ImageFaces* beam_faces_;
  const std::vector<BundleTarget>* targets_;
  const double spacing_;
  const bool scatter_;
  const bool propose_;
  std::vector<Link> chain_;
  std::vector<RayState> stack_;
  Reception reception_;
  BeamMarks marks_;
  std::optional<DiffuseGathering> gathering_;
  std::size_t r_ = 0;         // the lattice ray
  std::uint64_t hit_no_ = 0;  // the ray's hits so far: the roulette's sample identity
};

Shooter::Shooter(const ShootContext& world, std::uint32_t src, const std::vector<Vec3>& lattice, const ShootFeeds& feeds,
                 ShootFinds& finds)
    : scene_(world.scene),
      em_(world.em),
      cfg_(world.cfg),
      nodes_(world.nodes),
      src_(src),
      lattice_(lattice),
      rays_(finds.rays),
      diffuse_(feeds.diffuse),
      beam_faces_(feeds.faces),
      targets_(feeds.bundle),
      spacing_(std::sqrt(4 * kPi / static_cast<double>(feeds.spacing_rays ? feeds.spacing_rays : lattice.size())) *
               world.cfg.reception_radius_factor),
      scatter_(feeds.diffuse && (!feeds.diffuse->rx.empty() || !feeds.diffuse->rev.empty())),
      propose_(feeds.propose),
      reception_(world.nodes, src, finds.found),
      marks_(feeds.faces, world.nodes, src, spacing_, feeds.beams ? &finds.beams : nullptr,
             feeds.beam_pairs ? &finds.beam_pairs : nullptr, feeds.bundle_marks ? &finds.beams : nullptr) {
  if (feeds.diffuse) gathering_.emplace(world, src, lattice, *feeds.diffuse, finds.bins, finds.rays, chain_, feeds.sample_salt);
}

void Shooter::at_hit(const RayState& st, const Hit& hit) {
  HitField h;
  h.hit = &hit;
  h.p = st.o + hit.t * st.d;
  h.mat = scene_.material(hit.face);
  h.material = &em_.material(h.mat);
  h.s_coef = scatter_ ? h.material->scattering.s : 0.0;  // scatter implies em's rough surfaces
  const bool can_scatter =
      h.s_coef > 0 && st.n < cfg_.max_depth && (diffuse_->first_order || st.n > 0 || st.transmissions > 0);
  const bool can_reflect = cfg_.specular && st.n < cfg_.max_depth;
  const bool can_transmit = cfg_.refraction && st.transmissions < cfg_.max_transmissions && !em_.opaque(h.mat);
  if (scatter_ || can_reflect) h.plane = scene_.plane(hit.face);
  h.k_out = st.d - (2 * dot(st.d, h.plane.normal)) * h.plane.normal;
  // With diffuse on, the ray tube carries its field: the slab
  // coefficients here, the field a smooth surface would reflect, and
  // dL/dt up to this hit. Not where nothing downstream can scatter any
  // more (the last bounce off a smooth, opaque face): the slab
  // coefficients are the costly part.
  const bool field_needed = can_scatter || can_transmit || (can_reflect && st.n + 1 < cfg_.max_depth);
  if (scatter_ && field_needed) {
    const double cos_in = std::fabs(dot(st.d, h.plane.normal));
    // (The transmission only where the ray goes on through the slab.)
    h.coef = can_transmit ? em_.coefficients(h.mat, cos_in) : SlabCoefficients{em_.reflection(h.mat, cos_in), {}};
    h.es = te_basis(st.d, h.plane.normal);
    h.ep_in = cross(h.es, st.d);
    h.e_ref = combine(h.coef.r.te * cdot(st.field, h.es), h.es, h.coef.r.tm * cdot(st.field, h.ep_in),
                      cross(h.es, h.k_out));
    h.v_surf = scene_.velocity(hit.face);
    h.dl_in = st.dl_dt + dot(st.d, h.v_surf - st.v_prev);
  }
  if (can_scatter) gathering_->at_hit(st, h, r_, hit_no_);
  if (can_transmit) transmit(st, h);
  if (can_reflect) reflect(st, h);
}

}  // namespace

void shoot_from(const ShootContext& world, std::uint32_t src, const std::vector<Vec3>& lattice, std::size_t begin,
                std::size_t end, const ShootFeeds& feeds, ShootFinds& finds) {
  Shooter shooter(world, src, lattice, feeds, finds);
  for (std::size_t r = begin; r < end; ++r) shooter.shoot(r);
  shooter.finish();
}

}  // namespace raysweep::tracer
