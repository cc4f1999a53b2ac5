#include "shoot.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

#include "em/field.hpp"
#include "em/scattering.hpp"
#include "search/image_search.hpp"
#include "search/visibility.hpp"
#include "snapshot_plan.hpp"

namespace raysweep::tracer {

namespace {

// A uniform number in [0, 1) from a sample's identity (splitmix64's
// finaliser over the mixed fields): the roulette gives the same answer
// whatever the thread count or the order the samples run in.
inline double sample_uniform(std::uint64_t a, std::uint64_t b, std::uint64_t c) {
  std::uint64_t z = a * 0x9E3779B97F4A7C15ull ^ (b + 0x632BE59BD9B4E019ull) * 0xBF58476D1CE4E5B9ull ^
                    (c + 0x8CB92BA72F3D8DD7ull) * 0x94D049BB133111EBull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

// Russian roulette for a sample whose power is at most `bound`: the weight
// to multiply its power by when it is kept (1 above the threshold), or 0
// when it is dropped (then its shadow ray is never traced).
inline double roulette_weight(double bound, double threshold, double u) {
  if (!(bound < threshold)) return 1.0;
  const double q = bound / threshold;
  return u < q ? 1.0 / q : 0.0;
}

// Balance-heuristic weight of the samples of end a for first-order
// scattering at a point seen from a and b: each end's rays hit the surface
// with area density (rays / 4 pi) cos / distance^2, so the weight is
// q_a / (q_a + q_b), q = cos / distance^2. Both ends' weighted sums add up
// to one unbiased estimate whose samples come mostly from the nearer end.
inline double balance_weight(double cos_a, double dist_a, double cos_b, double dist_b) {
  const double qa = cos_a / (dist_a * dist_a), qb = cos_b / (dist_b * dist_b);
  return qa + qb > 0 ? qa / (qa + qb) : 0.0;
}

}  // namespace

// The roulette's threshold for `cfg` (TracerConfig::diffuse_roulette_db).
double roulette_power(const TracerConfig& cfg, const RadioConfig& radio) {
  if (cfg.diffuse_roulette_db >= 300) return 0;
  return std::pow(10.0, (radio.sensitivity_dbm - radio.tx_power_dbm - cfg.diffuse_roulette_db) / 10);
}

namespace {

// A ray's reflections so far, as links into the ray's chain (the states of
// one ray share their prefixes): copying whole face and point arrays of
// kMaxDepth entries per state cost more than the rest of the loop.
struct Link {
  FaceRef face;
  Vec3 point;
  std::int32_t parent;
};

// One branch of a ray: a segment's origin and direction, what it went
// through so far.
struct RayState {
  Vec3 o, d;
  double len;
  int transmissions;
  double loss_db;
  bool has_leaving;
  FaceRef leaving;
  int n;               // reflections so far
  std::int32_t last;   // the last one's link (-1: none)
  // Diffuse bookkeeping: the ray tube's field (transmit pattern times
  // every coefficient so far), dL/dt of the legs so far, the velocity of
  // the last interaction point.
  CVec3 field;
  double dl_dt;
  Vec3 v_prev;
};

// A bundle ray's aim (shoot_vehicle_bundles): straight at a vehicle, or at
// one through `face` (a static face, or another vehicle's). `spacing` is the
// bundle's angular spacing at the source.
struct BundleTarget {
  FaceRef face{};
  bool via_face = false;
  double spacing = 0;
};

// What one hit gives every branch leaving it: the face's plane and
// material, the mirror direction and, with diffuse on, the ray tube's
// slab coefficients, the field a smooth surface would reflect and dL/dt.
struct HitField {
  const Hit* hit;
  Vec3 p;
  std::uint16_t mat;
  const RadioMaterial* material;
  double s_coef;
  Plane plane;
  Vec3 k_out;
  SlabCoefficients coef{};
  Vec3 es{0, 0, 0}, ep_in{0, 0, 0}, v_surf{0, 0, 0};
  CVec3 e_ref{};
  double dl_in = 0;
};

// Shoot-and-bounce from one source over a range of lattice rays; the
// per-ray scratch (chain, stack, the nodes relative to the source) is kept
// across rays.
class Shooter {
 public:
  Shooter(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& cfg, const std::vector<Node>& nodes,
          std::uint32_t src, const std::vector<Vec3>& lattice, std::vector<CandidateKey>& out, std::uint64_t& rays,
          const DiffuseTargets* diffuse, DiffuseBins* diffuse_out, const ImageFaces* beam_faces,
          std::vector<BeamVehicle>* beams, std::vector<BeamPair>* beam_pairs, std::size_t spacing_rays = 0,
          const std::vector<BundleTarget>* targets = nullptr, std::vector<BeamVehicle>* bundle_marks = nullptr)
      : scene_(scene),
        em_(em),
        cfg_(cfg),
        nodes_(nodes),
        src_(src),
        lattice_(lattice),
        out_(out),
        rays_(rays),
        diffuse_(diffuse),
        diffuse_out_(diffuse_out),
        beam_faces_(beam_faces),
        beams_(beams),
        beam_pairs_(beam_pairs),
        targets_(targets),
        bundle_marks_(bundle_marks),
        spacing_(std::sqrt(4 * kPi / static_cast<double>(spacing_rays ? spacing_rays : lattice.size())) *
                 cfg.reception_radius_factor),
        scatter_(diffuse && (!diffuse->rx.empty() || !diffuse->rev.empty())),
        d_omega_(4 * kPi / static_cast<double>(lattice.size())),
        lambda_(em.wavelength()),
        rx_peak_gain_(peak_gain(em.radio().antenna.pattern)),
        ref_(nodes[src].position) {
    nx_.resize(nodes.size());
    ny_.resize(nodes.size());
    nz_.resize(nodes.size());
    for (std::size_t j = 0; j < nodes.size(); ++j) {
      nx_[j] = static_cast<float>(nodes[j].position[0] - ref_[0]);
      ny_[j] = static_cast<float>(nodes[j].position[1] - ref_[1]);
      nz_[j] = static_cast<float>(nodes[j].position[2] - ref_[2]);
    }
    inside_.resize(nodes.size());
  }

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

  // Beams and beam pairs sorted, once per task.
  void finish() {
    if (beams_) {
      std::sort(beams_->begin(), beams_->end());
      beams_->erase(std::unique(beams_->begin(), beams_->end()), beams_->end());
    }
    if (beam_pairs_) {
      std::sort(beam_pairs_->begin(), beam_pairs_->end());
      beam_pairs_->erase(std::unique(beam_pairs_->begin(), beam_pairs_->end()), beam_pairs_->end());
    }
  }

 private:
  // The faces of st's reflections in order into out[0, st.n), their points
  // into points (when given).
  void unwind(const RayState& st, FaceRef* out, Vec3* points) const {
    std::int32_t l = st.last;
    for (int k = st.n - 1; k >= 0; --k, l = chain_[l].parent) {
      out[k] = chain_[l].face;
      if (points) points[k] = chain_[l].point;
    }
  }

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
    if (st.n > 0) propose(st, tseg);
    note_beams(st, std::min(tseg, 1e30));
    if (bundle_marks_) note_bundle_marks(st, std::min(tseg, 1e30));
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

  // The nodes this segment passes within the reception sphere propose the
  // ray's face sequence to the pair (src, node).
  void propose(const RayState& st, double tseg) {
    // Branch-free pass over all nodes first (vectorises), keys only for hits.
    const std::size_t nn = nodes_.size();
    // Single precision relative to the source (city-sized offsets keep
    // millimetres): a candidate test only, the exact path is recomputed
    // in double; float doubles the SIMD width of this hot loop.
    const float ox = static_cast<float>(st.o[0] - ref_[0]), oy = static_cast<float>(st.o[1] - ref_[1]),
                oz = static_cast<float>(st.o[2] - ref_[2]);
    const float dx = static_cast<float>(st.d[0]), dy = static_cast<float>(st.d[1]), dz = static_cast<float>(st.d[2]);
    const float len = static_cast<float>(st.len), sp = static_cast<float>(reception_spacing());
    const float tmax = static_cast<float>(std::min(tseg, 1e30));
    const float* nx = nx_.data();
    const float* ny = ny_.data();
    const float* nz = nz_.data();
    unsigned char* inside = inside_.data();
    unsigned any = 0;
    for (std::size_t j = 0; j < nn; ++j) {
      const float wx = nx[j] - ox, wy = ny[j] - oy, wz = nz[j] - oz;
      const float s = wx * dx + wy * dy + wz * dz;
      const float r = sp * (len + s);
      const unsigned in = (s > 0) & (s <= tmax) & (wx * wx + wy * wy + wz * wz - s * s <= r * r);
      inside[j] = static_cast<unsigned char>(in);
      any |= in;
    }
    for (std::uint32_t j = 0; any && j < nn; ++j) {
      if (!inside[j] || j == src_) continue;
      key_.other = j;
      key_.faces.resize(st.n);
      unwind(st, key_.faces.data(), nullptr);
      if (seen_.insert(key_).second) out_.push_back(key_);
    }
  }

  // Whether the segment [0, seg_end] of st passes within `radius` of
  // `centre`, widened by twice the ray spacing at that distance (what it may
  // miss between rays: a vehicle, a small face).
  bool passes(const RayState& st, double seg_end, const Vec3& centre, double radius) const {
    return passes(st, seg_end, centre, radius, spacing_);
  }
  bool passes(const RayState& st, double seg_end, const Vec3& centre, double radius, double spacing) const {
    const Vec3 c = centre - st.o;
    const double t = std::clamp(dot(c, st.d), 0.0, seg_end);
    const Vec3 q = c - t * st.d;
    const double reach = radius + 2 * spacing * (st.len + t);
    return dot(q, q) <= reach * reach;
  }

  // A bundle ray reflected once, on a vehicle's face: the other vehicles
  // it passes (within its bundle's spacing) are in that face's beam, and
  // get a bundle of their own through the face (a car's echo off a car).
  void note_bundle_marks(const RayState& st, double seg_end) {
    if (st.n != 1 || chain_[st.last].face.instance == 0) return;
    const FaceRef& f = chain_[st.last].face;
    const std::uint32_t from = f.instance - 1, face = beam_faces_->vehicle_begin[from] + f.face;
    const auto& spheres = beam_faces_->vehicle_spheres;
    const double sp = (*targets_)[r_].spacing;
    for (std::uint32_t v = 0; v < spheres.size(); ++v)
      if (v != from && static_cast<int>(v) != nodes_[src_].vehicle &&
          passes(st, seg_end, spheres[v].centre, spheres[v].radius, sp))
        bundle_marks_->push_back({face, v});
  }

  void note_beams(const RayState& st, double seg_end) {
    // After one reflection on a static face: the vehicles this ray passes
    // are in that face's beam (BeamVehicle).
    if (beams_ && st.n == 1 && chain_[st.last].face.instance == 0 &&
        !std::binary_search(beam_faces_->ground.begin(), beam_faces_->ground.end(), chain_[st.last].face.face)) {
      const auto& spheres = beam_faces_->vehicle_spheres;
      for (std::uint32_t v = 0; v < spheres.size(); ++v)
        if (passes(st, seg_end, spheres[v].centre, spheres[v].radius))
          beams_->push_back({chain_[st.last].face.face, v});
    }
    // After two reflections, the first on a static face: their pair's beam
    // is lit (BeamPair); after one, so is the pair with a small static face
    // the ray passes.
    if (beam_pairs_ && st.n == 2 && chain_[chain_[st.last].parent].face.instance == 0) {
      // The second face may be a vehicle's (a wall's echo off a car onto a
      // wall): its index among ImageFaces' faces.
      const FaceRef& f2 = chain_[st.last].face;
      beam_pairs_->push_back({chain_[chain_[st.last].parent].face.face,
                              f2.instance == 0 ? f2.face : beam_faces_->vehicle_begin[f2.instance - 1] + f2.face});
    }
    if (beam_pairs_ && st.n == 1 && chain_[st.last].face.instance == 0) {
      const std::uint32_t f1 = chain_[st.last].face.face;
      for (const std::uint32_t f2 : beam_faces_->small)
        if (f2 != f1 && passes(st, seg_end, beam_faces_->spheres[f2].centre,
                               beam_faces_->spheres[f2].radius + beam_faces_->tol[f2]))
          beam_pairs_->push_back({f1, f2});
    }
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

  class Gathering;

  const TraceScene& scene_;
  const Electromagnetics& em_;
  const TracerConfig& cfg_;
  const std::vector<Node>& nodes_;
  const std::uint32_t src_;
  const std::vector<Vec3>& lattice_;
  std::vector<CandidateKey>& out_;
  std::uint64_t& rays_;
  const DiffuseTargets* diffuse_;
  DiffuseBins* diffuse_out_;
  const ImageFaces* beam_faces_;
  std::vector<BeamVehicle>* beams_;
  std::vector<BeamPair>* beam_pairs_;
  const std::vector<BundleTarget>* targets_;
  std::vector<BeamVehicle>* bundle_marks_;
  const double spacing_;
  const bool scatter_;
  const double d_omega_, lambda_, rx_peak_gain_;
  const Vec3 ref_;
  std::vector<float> nx_, ny_, nz_;
  std::vector<unsigned char> inside_;
  std::vector<Link> chain_;
  std::vector<RayState> stack_;
  std::unordered_set<CandidateKey, CandidateHash> seen_;
  CandidateKey key_;
  std::unordered_map<DiffuseKey, std::size_t, DiffuseKeyHash> bin_index_;
  std::size_t r_ = 0;         // the lattice ray
  std::uint64_t hit_no_ = 0;  // the ray's hits so far: the roulette's sample identity
};

// The diffuse gathering at one hit: S^2 of the smooth reflection's power is
// scattered, (1 - K_x) in its polarisation and K_x across it, towards each
// receiver whose shadow ray is clear, binned per receiver, object and delay.
class Shooter::Gathering {
 public:
  Gathering(Shooter& s, const RayState& st, const HitField& h)
      : s_(s),
        st_(st),
        h_(h),
        hit_(*h.hit),
        d_(*s.diffuse_),
        sc_(h.material->scattering),
        len_in_(st.len + hit_.t),
        lobe_(sc_, st.d, h.plane.normal),
        // First order, nothing crossed: the other end's rays sample these
        // points too (both ends' estimator).
        mis_(d_.both_ends && st.n == 0 && st.transmissions == 0),
        cos_in_(std::fabs(dot(st.d, h.plane.normal))),
        // The side the ray arrives from (the lobe's front, ScatteringLobeAt).
        front_(dot(st.d, h.plane.normal) < 0 ? h.plane.normal : -1.0 * h.plane.normal),
        hit_object_(s.scene_.object(hit_.face)),
        // The roulette's bound on a sample's power, per lobe value, incident
        // |E|^2 and 1 / distance^2: scattered()'s factors with the received
        // part of the field at most its whole and the receive pattern at its
        // peak gain (|R| <= 1 on a passive surface bounds the incident field
        // of the samples lit from the other end).
        bound_per_gain_(h.s_coef * h.s_coef * s.rx_peak_gain_ * s.lambda_ * s.lambda_ * s.d_omega_ /
                        (16 * kPi * kPi)),
        e_ref2_(d_.roulette > 0 ? std::norm(h.e_ref[0]) + std::norm(h.e_ref[1]) + std::norm(h.e_ref[2]) : 0.0) {}

  void run() {
    for (std::uint32_t j : d_.rx) gather(j, false);
    if (d_.both_ends && !mis_)
      for (std::uint32_t j : d_.rev) gather(j, true);
    // The same first-order scattering for the pairs (j, src), j < src,
    // evaluated as from j to src (each pair's field runs from its lower
    // end): the point is lit by j, and seen by src along this ray.
    for (std::size_t q = 0; mis_ && q < d_.rev.size(); ++q) gather_lit_by(d_.rev[q]);
  }

 private:
  // A node clearly behind the surface gets nothing, and costs no square
  // root or lobe (a third of the evaluations on the bench scenes). Within
  // rounding of the plane it takes the full test.
  bool behind(const Vec3& w) const {
    return dot(w, front_) < -1e-9 * (std::fabs(w[0]) + std::fabs(w[1]) + std::fabs(w[2]));
  }

  void record(std::uint32_t j, bool reverse, double power, double tau, const Vec3& departure, const Vec3& arrival,
              double dl, bool scatter_first = false) {
    DiffuseKey dk;
    dk.rx = j;
    dk.object = hit_object_;
    dk.bin = static_cast<std::int64_t>(std::floor(tau / d_.bin_s));
    dk.reverse = reverse;
    auto [it, fresh] = s_.bin_index_.try_emplace(dk, s_.diffuse_out_->size());
    if (fresh) s_.diffuse_out_->emplace_back(dk, DiffuseAcc{});
    // Summed in place (DiffuseAcc::add's terms and order); the chain is
    // copied only when this sample is the bin's new peak.
    DiffuseAcc& acc = (*s_.diffuse_out_)[it->second].second;
    acc.power += power;
    acc.tau += power * tau;
    acc.point = acc.point + power * h_.p;
    acc.departure = acc.departure + power * departure;
    acc.arrival = acc.arrival + power * arrival;
    acc.doppler += power * (-dl / s_.lambda_);
    if (power > acc.peak) {
      acc.peak = power;
      acc.n = st_.n + 1;
      acc.faces.fill(FaceRef{});
      acc.prefix.fill(Vec3{0, 0, 0});
      s_.unwind(st_, acc.faces.data(), acc.prefix.data());
      acc.faces[st_.n] = hit_.face;
      acc.scatter_first = scatter_first;
    }
  }

  // Received power from the reflected field e_in (the field a smooth
  // surface would reflect) scattered towards ks, at distance rs, by a tube
  // of d_omega, into the receive pattern looking along -ks.
  double scattered(const CVec3& e_in, const Vec3& ks, double f, double rs, const Vec3& rx_forward) const {
    const cdouble along = cdot(e_in, ks);
    const CVec3 et{e_in[0] - along * ks[0], e_in[1] - along * ks[1], e_in[2] - along * ks[2]};
    const double et2 = std::norm(et[0]) + std::norm(et[1]) + std::norm(et[2]);
    const double er2 = std::norm(e_in[0]) + std::norm(e_in[1]) + std::norm(e_in[2]);
    if (!(et2 > 1e-30)) return 0.0;
    const Vec3 fr = antenna_field(s_.em_.radio().antenna, -1.0 * ks, rx_forward);
    const CVec3 ex{ks[1] * et[2] - ks[2] * et[1], ks[2] * et[0] - ks[0] * et[2], ks[0] * et[1] - ks[1] * et[0]};
    const double co = std::norm(cdot(et, fr)), cross_pol = std::norm(cdot(ex, fr));
    const double g_eff = ((1 - sc_.xpd) * co + sc_.xpd * cross_pol) * er2 / et2;
    const double lambda = s_.lambda_;
    return h_.s_coef * h_.s_coef * f * g_eff * lambda * lambda * s_.d_omega_ / (16 * kPi * kPi * rs * rs);
  }

  // Towards node j along ks: this ray's chain, then the scattering.
  void gather(std::uint32_t j, bool reverse) {
    const auto& nodes = s_.nodes_;
    const Vec3 w = nodes[j].position - h_.p;
    if (behind(w)) return;
    const double rs = norm(w);
    if (rs < 1e-6) return;
    const Vec3 ks = (1.0 / rs) * w;
    const double f = lobe_(ks);
    if (!(f > 0)) return;
    const double balance = mis_ ? balance_weight(cos_in_, len_in_, std::fabs(dot(ks, h_.plane.normal)), rs) : 1.0;
    double weight = 1;
    if (d_.roulette > 0) {
      weight = roulette_weight(bound_per_gain_ * f * e_ref2_ / (rs * rs) * balance, d_.roulette,
                               sample_uniform(std::uint64_t{s_.src_} << 32 | s_.r_, s_.hit_no_,
                                              std::uint64_t{j} << 1 | reverse));
      if (weight == 0) return;
    }
    if (d_.hides(j, hit_.face)) return;  // its shadow ray would be blocked
    ++s_.rays_;
    if (s_.scene_.occluded(h_.p, ks, 0, rs - s_.scene_.slack(nodes[j].position, 0) * 0.1, &hit_.face)) return;
    const double power = scattered(h_.e_ref, ks, f, rs, nodes[j].forward) * balance * weight;
    if (!(power > 0)) return;
    const double dl = h_.dl_in + dot(ks, nodes[j].velocity - h_.v_surf), tau = (len_in_ + rs) / kSpeedOfLight;
    const Vec3& dep = s_.lattice_[s_.r_];
    if (!reverse) {
      record(j, false, power, tau, dep, -1.0 * ks, dl);
    } else {
      // The pair (j, src) read from j: scattered first, then this ray's
      // reflections back to src (evaluated along this ray's direction;
      // equal for a reciprocal lobe).
      record(j, true, power, tau, -1.0 * ks, dep, dl, true);
    }
  }

  // The point lit by node j (j < src), seen by src back along this ray.
  void gather_lit_by(std::uint32_t j) {
    const auto& nodes = s_.nodes_;
    const auto& em = s_.em_;
    const Vec3 w = h_.p - nodes[j].position;
    // Lit from j's side, seen back along this ray: j must be in front too.
    if (behind(-1.0 * w)) return;
    const double la = norm(w);
    if (la < 1e-6) return;
    const Vec3 ki = (1.0 / la) * w;
    const Vec3 ks = -1.0 * st_.d;
    const Vec3& normal = h_.plane.normal;
    const double f = ScatteringLobeAt(sc_, ki, normal)(ks);
    if (!(f > 0)) return;
    const double cos_a = std::fabs(dot(ki, normal));
    const double balance = balance_weight(cos_a, la, cos_in_, hit_.t);
    const CVec3 e_a = cvec(antenna_field(em.radio().antenna, ki, nodes[j].forward));
    // The roulette's bound before the slab coefficients (the costly part):
    // |R| <= 1 on a passive surface, and the received part of the
    // scattered field is at most its whole (scattered()'s terms).
    double weight = 1;
    if (d_.roulette > 0) {
      const double e2 = std::norm(e_a[0]) + std::norm(e_a[1]) + std::norm(e_a[2]);
      weight = roulette_weight(bound_per_gain_ * f * e2 / (hit_.t * hit_.t) * balance, d_.roulette,
                               sample_uniform(std::uint64_t{s_.src_} << 32 | s_.r_, s_.hit_no_,
                                              std::uint64_t{j} << 1 | 1));
      if (weight == 0) return;
    }
    if (d_.hides(j, hit_.face)) return;
    ++s_.rays_;
    if (s_.scene_.occluded(h_.p, -1.0 * ki, 0, la - s_.scene_.slack(nodes[j].position, 0) * 0.1, &hit_.face))
      return;
    const TeTm ra = em.reflection(h_.mat, cos_a);
    const Vec3 es_a = te_basis(ki, normal);
    const Vec3 ko_a = ki - (2 * dot(ki, normal)) * normal;
    const CVec3 e_ref_a = combine(ra.te * cdot(e_a, es_a), es_a, ra.tm * cdot(e_a, cross(es_a, ki)), cross(es_a, ko_a));
    double power = scattered(e_ref_a, ks, f, hit_.t, nodes[s_.src_].forward);
    power *= balance * weight;
    if (!(power > 0)) return;
    record(j, true, power, (la + hit_.t) / kSpeedOfLight, ki, st_.d,
           dot(ki, h_.v_surf - nodes[j].velocity) + dot(ks, nodes[s_.src_].velocity - h_.v_surf));
  }

  Shooter& s_;
  const RayState& st_;
  const HitField& h_;
  const Hit& hit_;
  const DiffuseTargets& d_;
  const Scattering& sc_;
  const double len_in_;
  const ScatteringLobeAt lobe_;
  const bool mis_;
  const double cos_in_;
  const Vec3 front_;
  const std::uint32_t hit_object_;
  const double bound_per_gain_, e_ref2_;
};

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
  if (can_scatter) Gathering(*this, st, h).run();
  if (can_transmit) transmit(st, h);
  if (can_reflect) reflect(st, h);
}

}  // namespace

void shoot_from(const TraceScene& scene, const Electromagnetics& em, const TracerConfig& cfg,
                const std::vector<Node>& nodes, std::uint32_t src, const std::vector<Vec3>& lattice,
                std::size_t begin, std::size_t end, std::vector<CandidateKey>& out, std::uint64_t& rays,
                const DiffuseTargets* diffuse, DiffuseBins* diffuse_out, const ImageFaces* beam_faces,
                std::vector<BeamVehicle>* beams, std::vector<BeamPair>* beam_pairs) {
  Shooter shooter(scene, em, cfg, nodes, src, lattice, out, rays, diffuse, diffuse_out, beam_faces, beams, beam_pairs);
  for (std::size_t r = begin; r < end; ++r) shooter.shoot(r);
  shooter.finish();
}

std::vector<double> diffuse_power(const TraceScene& scene, const std::vector<Node>& nodes, std::uint32_t src,
                                  const std::vector<std::uint32_t>& receivers, const TracerConfig& cfg,
                                  const RadioConfig& radio) {
  validate(cfg, radio);
  std::vector<double> out(receivers.size(), 0.0);
  if (!cfg.diffuse || cfg.max_depth <= 0 || cfg.diffuse_integration == DiffuseIntegration::tiles) return out;
  if (src >= nodes.size()) throw std::invalid_argument("diffuse_power: source index out of range");
  const Electromagnetics em(scene.material_names(), radio, cfg.materials, cfg.diffuse);
  const double range = max_range_m(cfg, radio);
  DiffuseTargets targets;
  targets.bin_s = 1.0 / radio.bandwidth_hz;
  targets.roulette = roulette_power(cfg, radio);
  std::unordered_map<std::uint32_t, std::size_t> slot;
  for (std::size_t k = 0; k < receivers.size(); ++k) {
    const auto r = receivers[k];
    if (r >= nodes.size()) throw std::invalid_argument("diffuse_power: receiver index out of range");
    if (r == src || norm(nodes[r].position - nodes[src].position) > range) continue;
    if (slot.emplace(r, k).second) targets.rx.push_back(r);
  }
  std::sort(targets.rx.begin(), targets.rx.end());
  if (targets.rx.empty()) return out;
  // The same rays, chunks and merge order as trace_pairs' shoot stage.
  TracerConfig local = cfg;
  local.specular = cfg.specular && cfg.candidates != CandidateSearch::exhaustive;
  const auto lattice = fibonacci_sphere(cfg.rays_per_source);
  const std::size_t chunk = kShootChunk, chunks = (lattice.size() + chunk - 1) / chunk;
  std::vector<DiffuseBins> bins(chunks);
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    std::vector<CandidateKey> found;
    std::uint64_t rays = 0;
    shoot_from(scene, em, local, nodes, src, lattice, c * chunk, std::min(lattice.size(), (c + 1) * chunk), found, rays,
               &targets, &bins[c]);
  });
  for (const auto& b : bins)
    for (const auto& [dk, acc] : b) out[slot.at(dk.rx)] += acc.power;
  return out;
}

namespace {

// Per source, the receivers its rays gather diffuse power for: the lower
// end's rays gather towards the higher end, and with both ends on, the
// higher end's rays towards the lower.
std::vector<DiffuseTargets> diffuse_targets(const SnapshotPlan& plan) {
  const auto& cfg = plan.cfg;
  std::vector<DiffuseTargets> targets(plan.n);
  for (std::size_t p = 0; p < plan.pairs.size(); ++p) {
    if (!plan.in_range[p]) continue;
    auto [i, j] = plan.pairs[p];
    targets[i].rx.push_back(j);
    if (cfg.diffuse_both_ends) targets[j].rev.push_back(i);
  }
  for (auto& t : targets) {
    std::sort(t.rx.begin(), t.rx.end());
    std::sort(t.rev.begin(), t.rev.end());
    t.both_ends = cfg.diffuse_both_ends;
    t.first_order = !plan.tile_diffuse;
    t.bin_s = 1.0 / plan.radio.bandwidth_hz;
    t.roulette = roulette_power(cfg, plan.radio);
  }
  return targets;
}

// The rough static faces one convex face hides whole from each source: the
// diffuse gathering's shadow rays from them to it are blocked, so not cast.
std::vector<std::vector<std::uint64_t>> hidden_faces(const SnapshotPlan& plan) {
  const auto& faces = plan.faces();
  std::vector<std::vector<std::uint64_t>> hidden(plan.n);
  tbb::parallel_for(std::uint32_t{0}, plan.n, [&](std::uint32_t j) {
    if (!plan.is_source[j]) return;
    auto& bits = hidden[j];
    bits.assign((faces.static_count + 63) / 64, 0);
    for (std::uint32_t f = 0; f < faces.static_count; ++f) {
      if (!(plan.em.material(plan.scene.material(faces.refs[f])).scattering.s > 0)) continue;
      const FaceRef self{0, f};
      if (hidden_by_convex_face(plan.scene, faces, plan.nodes[j].position, &faces.outline[faces.outline_begin[f]],
                                faces.outline_begin[f + 1] - faces.outline_begin[f], &self, faces.tol[f]))
        bits[f >> 6] |= std::uint64_t{1} << (f & 63);
    }
  });
  return hidden;
}

// One shooting task's finds: a source's chunk of the lattice.
struct TaskOut {
  std::vector<CandidateKey> found;
  DiffuseBins bins;
  std::vector<BeamVehicle> beams;
  std::vector<BeamPair> beam_pairs;
  std::uint64_t rays = 0;
};

constexpr std::size_t kNoSlot = ~std::size_t{0};

// The pair slot of each task's finds (kNoSlot: no requested, in-range pair,
// or a sequence the image search already enumerated completely), with the
// sequences and bins turned to run from the pair's lower end.
void slot_finds(const SnapshotPlan& plan, const ImageFaces* image_faces, std::uint32_t src, TaskOut& out,
                std::vector<std::size_t>& found_slot, std::vector<std::size_t>& bin_slot) {
  const auto& cfg = plan.cfg;
  found_slot.assign(out.found.size(), kNoSlot);
  for (std::size_t q = 0; q < out.found.size(); ++q) {
    auto& k = out.found[q];
    if (image_faces && image_complete(plan.scene, *image_faces, k.faces, cfg.ground_order3 && cfg.max_depth >= 3))
      continue;
    const std::uint32_t a = std::min(src, k.other), b = std::max(src, k.other);
    const auto it = plan.slot.find(SnapshotPlan::key(a, b));
    if (it == plan.slot.end() || !plan.in_range[it->second]) continue;
    if (src > k.other) std::reverse(k.faces.begin(), k.faces.end());
    found_slot[q] = it->second;
  }
  bin_slot.assign(out.bins.size(), kNoSlot);
  for (std::size_t q = 0; q < out.bins.size(); ++q) {
    auto& dk = out.bins[q].first;
    // Both ends' samples of a pair's bin merge into one record.
    const std::uint32_t a = dk.reverse ? dk.rx : src, b = dk.reverse ? src : dk.rx;
    const auto it = plan.slot.find(SnapshotPlan::key(a, b));
    if (it == plan.slot.end()) continue;
    dk.rx = b;
    dk.reverse = false;
    bin_slot[q] = it->second;
  }
}

// Per pair, its entries in task order: (task, index) lists by counting.
struct Entry {
  std::uint32_t task, index;
};
struct Grouped {
  std::vector<std::size_t> begin;  // pair p's entries: [begin[p], begin[p + 1])
  std::vector<Entry> entries;
};
Grouped group_by_pair(const std::vector<std::vector<std::size_t>>& slots, std::size_t pairs) {
  std::vector<std::size_t> begin(pairs + 1, 0);
  for (const auto& v : slots)
    for (auto sl : v)
      if (sl != kNoSlot) ++begin[sl + 1];
  for (std::size_t p = 0; p < pairs; ++p) begin[p + 1] += begin[p];
  std::vector<Entry> entries(begin.back());
  std::vector<std::size_t> at(begin.begin(), begin.end() - 1);
  for (std::size_t t = 0; t < slots.size(); ++t)
    for (std::size_t q = 0; q < slots[t].size(); ++q)
      if (slots[t][q] != kNoSlot)
        entries[at[slots[t][q]]++] = Entry{static_cast<std::uint32_t>(t), static_cast<std::uint32_t>(q)};
  return Grouped{std::move(begin), std::move(entries)};
}

// Merged in task order, so the sums are the same for any thread count; the
// slot lookups run per task and the merging per pair, both in parallel (a
// serial merge held one core idle for 20-30 ms).
void merge_tasks(const SnapshotPlan& plan, std::vector<TaskOut>& tasks, const std::vector<std::uint32_t>& task_src,
                 ShootPass& pass) {
  // The image search enumerated these sequences completely already.
  const ImageFaces* image_faces = plan.image_search ? &plan.faces() : nullptr;
  std::vector<std::vector<std::size_t>> found_slot(tasks.size()), bin_slot(tasks.size());
  tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t task) {
    slot_finds(plan, image_faces, task_src[task], tasks[task], found_slot[task], bin_slot[task]);
  });
  const Grouped found_by_pair = group_by_pair(found_slot, plan.pairs.size());
  const Grouped bins_by_pair = group_by_pair(bin_slot, plan.pairs.size());
  tbb::parallel_for(std::size_t{0}, plan.pairs.size(), [&](std::size_t p) {
    for (std::size_t e = found_by_pair.begin[p]; e < found_by_pair.begin[p + 1]; ++e) {
      const Entry& en = found_by_pair.entries[e];
      pass.candidates[p].push_back(std::move(tasks[en.task].found[en.index].faces));
    }
    for (std::size_t e = bins_by_pair.begin[p]; e < bins_by_pair.begin[p + 1]; ++e) {
      const Entry& en = bins_by_pair.entries[e];
      const auto& bin = tasks[en.task].bins[en.index];
      pass.diffuse[p][bin.first].add(bin.second);
    }
  });
  for (std::size_t task = 0; task < tasks.size(); ++task) {
    pass.rays += tasks[task].rays;
    if (!pass.beams.empty()) {
      auto& b = pass.beams[task_src[task]];
      b.insert(b.end(), tasks[task].beams.begin(), tasks[task].beams.end());
    }
    if (!pass.beam_pairs.empty()) {
      auto& b = pass.beam_pairs[task_src[task]];
      b.insert(b.end(), tasks[task].beam_pairs.begin(), tasks[task].beam_pairs.end());
    }
  }
  tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t t) { tasks[t] = TaskOut{}; });
}

// 1 - cos of the half angle of the cap the sphere subtends from `from`
// (its solid angle over 2 pi); 2, the whole sphere, from inside it.
double cap_one_minus_cos(const Vec3& from, const TraceScene::Sphere& s) {
  const double d = norm(s.centre - from);
  if (!(d > s.radius)) return 2;
  const double sin_half = s.radius / d;
  return sin_half * sin_half / (1 + std::sqrt(1 - sin_half * sin_half));
}

// Directions from `from` spread evenly in solid angle over the cap the
// sphere subtends (a Fibonacci spiral), `n` of them; none from inside it.
// Returns the cap's 1 - cos (0 from inside).
double cap_directions(const Vec3& from, const TraceScene::Sphere& s, int n, std::vector<Vec3>& out) {
  const Vec3 c = s.centre - from;
  const double d = norm(c);
  if (!(d > s.radius)) return 0;
  const Vec3 w = (1 / d) * c, u = any_perpendicular(w), v = cross(w, u);
  const double one_minus_cos = cap_one_minus_cos(from, s);
  const double golden = kPi * (3 - std::sqrt(5.0));
  for (int k = 0; k < n; ++k) {
    const double z = 1 - one_minus_cos * (k + 0.5) / n, r = std::sqrt(std::fmax(0.0, 1 - z * z));
    out.push_back(std::cos(golden * k) * r * u + std::sin(golden * k) * r * v + z * w);
  }
  return one_minus_cos;
}

// The angular spacing of n rays over a cap (solid angle 2 pi (1 - cos)).
double bundle_spacing(double one_minus_cos, int n) { return std::sqrt(2 * kPi * one_minus_cos / n); }

// Lattice rays a cap of this size receives (solid angle 2 pi (1 - cos) over
// 4 pi / rays each).
double lattice_rays_on_cap(double one_minus_cos, int rays) { return one_minus_cos * rays / 2; }

// A bundle from source s through face f (ImageFaces' index) at vehicle v:
// from s's image in f, n rays over the smaller of the caps of f's and v's
// spheres, kept where they cross f's plane within f's sphere and pass
// within v's; each cast from s at its crossing point. With `sparse_only`,
// none when the lattice already gives v's cap from the image n rays.
void bundle_through_face(const ImageFaces& faces, const Vec3& s, std::uint32_t f, std::uint32_t v, int n, int rays,
                         bool sparse_only, std::vector<Vec3>& dirs, std::vector<BundleTarget>& targets) {
  const Plane& pl = faces.planes[f];
  const Vec3 img = s - 2 * (dot(pl.normal, s) - pl.offset) * pl.normal;
  const auto& fs = faces.spheres[f];
  const auto& vs = faces.vehicle_spheres[v];
  const double cap_v = cap_one_minus_cos(img, vs);
  if (sparse_only && lattice_rays_on_cap(cap_v, rays) >= n) return;
  const TraceScene::Sphere face_sphere{fs.centre, fs.radius + faces.tol[f]};
  const double cap_f = cap_one_minus_cos(img, face_sphere);
  const bool aim_at_face = cap_f < cap_v;
  std::vector<Vec3> aimed;
  const double cap = cap_directions(img, aim_at_face ? face_sphere : vs, n, aimed);
  const BundleTarget target{faces.refs[f], true, bundle_spacing(cap, n)};
  for (const Vec3& e : aimed) {
    const double den = dot(pl.normal, e);
    if (den == 0) continue;
    const double t = (pl.offset - dot(pl.normal, img)) / den;
    const Vec3 p = img + t * e;
    const Vec3 off = p - face_sphere.centre;
    if (!(t > 0) || dot(off, off) > face_sphere.radius * face_sphere.radius) continue;
    const Vec3 c = vs.centre - img;
    const double along = dot(c, e);
    if (along < t || dot(c, c) - along * along > vs.radius * vs.radius) continue;
    dirs.push_back(normalize(p - s));
    targets.push_back(target);
  }
}

// The first bundles of one source (TracerConfig::vehicle_bundles): at every
// other vehicle the lattice covers with fewer than vehicle_bundle_rays rays,
// and through every static face whose beam the lattice showed reaching one.
void first_bundles(const SnapshotPlan& plan, const ImageFaces& faces, std::uint32_t src,
                   std::vector<BeamVehicle> combos, std::vector<Vec3>& dirs, std::vector<BundleTarget>& targets) {
  const int n = plan.cfg.vehicle_bundle_rays, rays = plan.cfg.rays_per_source;
  const Vec3 s = plan.nodes[src].position;
  const auto own = static_cast<std::uint32_t>(plan.nodes[src].vehicle);
  for (std::uint32_t v = 0; v < faces.vehicle_spheres.size(); ++v) {
    if (v == own) continue;
    const std::size_t at = dirs.size();
    const double cap = cap_directions(s, faces.vehicle_spheres[v], n, dirs);
    if (lattice_rays_on_cap(cap, rays) >= n) dirs.resize(at);
    targets.resize(dirs.size(), BundleTarget{{v + 1, 0}, false, bundle_spacing(cap, n)});
  }
  if (!plan.cfg.vehicle_bundles_via_faces) return;
  std::sort(combos.begin(), combos.end());
  combos.erase(std::unique(combos.begin(), combos.end()), combos.end());
  for (const BeamVehicle& c : combos)
    if (c.vehicle != own) bundle_through_face(faces, s, c.face, c.vehicle, n, rays, true, dirs, targets);
}

// One round of bundles: each source's rays in tasks of kShootChunk, their
// finds merged into the pass; with `marks`, the (vehicle face, vehicle)
// beams the rays show, per source.
void shoot_bundles(const SnapshotPlan& plan, const ImageFaces& faces, const std::vector<std::vector<Vec3>>& dirs,
                   const std::vector<std::vector<BundleTarget>>& targets, ShootPass& pass,
                   std::vector<std::vector<BeamVehicle>>* marks) {
  struct Job {
    std::uint32_t src;
    std::size_t begin, end;
  };
  std::vector<Job> jobs;
  for (const auto src : plan.sources)
    for (std::size_t b = 0; b < dirs[src].size(); b += kShootChunk)
      jobs.push_back({src, b, std::min(dirs[src].size(), b + kShootChunk)});
  std::vector<TaskOut> tasks(jobs.size());
  std::vector<std::uint32_t> task_src(jobs.size());
  tbb::parallel_for(std::size_t{0}, jobs.size(), [&](std::size_t t) {
    const Job& j = jobs[t];
    task_src[t] = j.src;
    TracerConfig local = plan.cfg;
    local.specular = true;
    Shooter shooter(plan.scene, plan.em, local, plan.nodes, j.src, dirs[j.src], tasks[t].found, tasks[t].rays, nullptr,
                    nullptr, &faces, nullptr, nullptr, static_cast<std::size_t>(plan.cfg.rays_per_source),
                    &targets[j.src], marks ? &tasks[t].beams : nullptr);
    for (std::size_t r = j.begin; r < j.end; ++r) shooter.shoot(r);
    shooter.finish();
  });
  if (marks) {
    marks->assign(plan.n, {});
    for (std::size_t t = 0; t < tasks.size(); ++t) {
      auto& m = (*marks)[task_src[t]];
      m.insert(m.end(), tasks[t].beams.begin(), tasks[t].beams.end());
      tasks[t].beams.clear();
    }
  }
  merge_tasks(plan, tasks, task_src, pass);
}

// Rays aimed at the vehicles the lattice covers sparsely (two vehicles in a
// chain, a car's cabin and then another car, a wall, a car and a car): their
// face sequences join the lattice's candidates (reception spheres:
// Shooter::reception_spacing). Then,
// through every vehicle face those rays reflect on towards another vehicle,
// a bundle at that vehicle. No diffuse gathering: the diffuse estimator
// weights its rays by the lattice's solid angle.
void shoot_vehicle_bundles(const SnapshotPlan& plan, const ImageFaces& faces, ShootPass& pass) {
  std::vector<std::vector<Vec3>> dirs(plan.n);
  std::vector<std::vector<BundleTarget>> targets(plan.n);
  tbb::parallel_for(std::size_t{0}, plan.sources.size(), [&](std::size_t k) {
    const auto src = plan.sources[k];
    first_bundles(plan, faces, src, pass.beams.empty() ? std::vector<BeamVehicle>{} : pass.beams[src], dirs[src],
                  targets[src]);
  });
  std::vector<std::vector<BeamVehicle>> marks;
  shoot_bundles(plan, faces, dirs, targets, pass, &marks);
  tbb::parallel_for(std::size_t{0}, plan.sources.size(), [&](std::size_t k) {
    const auto src = plan.sources[k];
    auto& m = marks[src];
    std::sort(m.begin(), m.end());
    m.erase(std::unique(m.begin(), m.end()), m.end());
    dirs[src].clear();
    targets[src].clear();
    for (const BeamVehicle& c : m)
      bundle_through_face(faces, plan.nodes[src].position, c.face, c.vehicle, plan.cfg.vehicle_bundle_rays,
                          plan.cfg.rays_per_source, false, dirs[src], targets[src]);
  });
  shoot_bundles(plan, faces, dirs, targets, pass, nullptr);
}

}  // namespace

ShootPass run_shoot_pass(const SnapshotPlan& plan) {
  const auto& cfg = plan.cfg;
  const auto t0 = std::chrono::steady_clock::now();
  ShootPass pass;
  pass.candidates.resize(plan.pairs.size());
  pass.diffuse.resize(plan.ray_diffuse ? plan.pairs.size() : 0);
  // A static face then any vehicle: the rays say which combinations can
  // exist, the image method enumerates their faces exactly.
  const bool beam_search = plan.image_search && cfg.max_depth >= 2;
  // A static face, then a static or vehicle face, then the third (order 3).
  const bool triple_search = beam_search && cfg.max_depth >= 3 && cfg.beam_order3;
  pass.beams.resize(beam_search ? plan.n : 0);
  pass.beam_pairs.resize(triple_search ? plan.n : 0);
  if (!(plan.sbr_specular || plan.ray_diffuse) || plan.n <= 1) return pass;
  std::vector<DiffuseTargets> targets;
  std::vector<std::vector<std::uint64_t>> hidden;
  if (plan.ray_diffuse) {
    targets = diffuse_targets(plan);
    hidden = hidden_faces(plan);
    for (auto& t : targets) t.hidden = &hidden;
  }
  const auto lattice = fibonacci_sphere(cfg.rays_per_source);
  const std::size_t chunk = kShootChunk, chunks = (lattice.size() + chunk - 1) / chunk;
  std::vector<TaskOut> tasks(plan.sources.size() * chunks);
  const ImageFaces* faces = beam_search ? &plan.faces() : nullptr;
  tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t task) {
    const auto src = plan.sources[task / chunks];
    const std::size_t c = task % chunks;
    TaskOut& out = tasks[task];
    TracerConfig local = cfg;
    local.specular = plan.sbr_specular;
    shoot_from(plan.scene, plan.em, local, plan.nodes, src, lattice, c * chunk,
               std::min(lattice.size(), (c + 1) * chunk), out.found, out.rays,
               plan.ray_diffuse ? &targets[src] : nullptr, &out.bins, faces, beam_search ? &out.beams : nullptr,
               triple_search ? &out.beam_pairs : nullptr);
    if (!plan.sbr_specular) out.found.clear();
  });
  std::vector<std::uint32_t> task_src(tasks.size());
  for (std::size_t t = 0; t < tasks.size(); ++t) task_src[t] = plan.sources[t / chunks];
  merge_tasks(plan, tasks, task_src, pass);
  if (faces && plan.sbr_specular && cfg.vehicle_bundles) shoot_vehicle_bundles(plan, *faces, pass);
  pass.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return pass;
}

}  // namespace raysweep::tracer
