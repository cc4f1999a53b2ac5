#include "shoot/gathering.hpp"

#include <cmath>

#include "em/scattering.hpp"

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

DiffuseGathering::DiffuseGathering(const ShootContext& world, std::uint32_t src, const std::vector<Vec3>& lattice,
                                   const DiffuseTargets& targets, DiffuseBins& out, std::uint64_t& rays,
                                   const std::vector<Link>& chain, std::uint64_t salt)
    : scene_(world.scene),
      em_(world.em),
      nodes_(world.nodes),
      src_(src),
      lattice_(lattice),
      diffuse_(&targets),
      diffuse_out_(&out),
      rays_(rays),
      chain_(chain),
      d_omega_(4 * kPi / static_cast<double>(lattice.size()) * targets.share),
      lambda_(world.em.wavelength()),
      rx_peak_gain_(peak_gain(world.em.radio().antenna.pattern)),
      salt_(salt) {}

// The diffuse gathering at one hit: S^2 of the smooth reflection's power is
// scattered, (1 - K_x) in its polarisation and K_x across it, towards each
// receiver whose shadow ray is clear, binned per receiver, object and delay.
class DiffuseGathering::AtHit {
 public:
  AtHit(DiffuseGathering& s, const RayState& st, const HitField& h)
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
      unwind(s_.chain_, st_, acc.faces.data(), acc.prefix.data());
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
                               sample_uniform((std::uint64_t{s_.src_} << 32 | s_.r_) ^ s_.salt_, s_.hit_no_,
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
                               sample_uniform((std::uint64_t{s_.src_} << 32 | s_.r_) ^ s_.salt_, s_.hit_no_,
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

  DiffuseGathering& s_;
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

void DiffuseGathering::at_hit(const RayState& st, const HitField& h, std::size_t r, std::uint64_t hit_no) {
  r_ = r;
  hit_no_ = hit_no;
  AtHit(*this, st, h).run();
}

}  // namespace raysweep::tracer
