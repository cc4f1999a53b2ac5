// Closed-form validation of diffuse scattering (effective roughness model,
// Degli-Esposti et al. 2007): the lobe integrals and scattering patterns
// against quadrature over the hemisphere, the diffuse power from a plate
// against the bistatic radar-equation integral over its surface (own 2D
// quadrature), the R^2 + S^2 = 1 energy partition of the specular path, the
// switch and thread-count determinism. Reflection coefficients in the
// references come from tracer::slab_coefficients (validated in test_em).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstring>
#include <functional>
#include <random>
#include <vector>

#include "closed_forms.hpp"
#include "em/scattering.hpp"
#include "tracer_fixtures.hpp"

using namespace raysweep;
using namespace raysweep::test;
using cd = std::complex<double>;
using tracer::Vec3;
using tracer::operator+;
using tracer::operator-;
using tracer::operator*;

namespace {

constexpr double kC = 299792458.0, kPi = 3.14159265358979323846;
constexpr double kF = 5.9e9;
const double kLambda = kC / kF;
constexpr double kDeg = kPi / 180;

// Gauss-Legendre nodes on [-1, 1] by Newton's iteration on P_n.
using closed_form::GaussLegendre;
using closed_form::gl20;
// Nodes and weights of a composite 20-point rule over [a, b].
void composite(double a, double b, int panels, std::vector<double>& x, std::vector<double>& w) {
  const auto& g = gl20();
  x.clear();
  w.clear();
  const double h = (b - a) / panels;
  for (int p = 0; p < panels; ++p)
    for (std::size_t i = 0; i < g.x.size(); ++i) {
      x.push_back(a + (p + 0.5) * h + 0.5 * h * g.x[i]);
      w.push_back(0.5 * h * g.w[i]);
    }
}

// Integral over the hemisphere around unit `n` of f(direction): Gauss-Legendre
// in the polar angle, trapezoid in azimuth (exact for trigonometric
// polynomials of degree < m).
double hemisphere(const Vec3& n, const std::function<double(const Vec3&)>& f, int polar_panels = 4, int m = 256) {
  const Vec3 t1 = tracer::any_perpendicular(n), t2 = tracer::cross(n, t1);
  std::vector<double> th, wt;
  composite(0, kPi / 2, polar_panels, th, wt);
  double sum = 0;
  for (std::size_t i = 0; i < th.size(); ++i) {
    const double st = std::sin(th[i]), ct = std::cos(th[i]);
    double ring = 0;
    for (int k = 0; k < m; ++k) {
      const double ph = 2 * kPi * k / m;
      ring += f(st * std::cos(ph) * t1 + st * std::sin(ph) * t2 + ct * n);
    }
    sum += wt[i] * st * ring * (2 * kPi / m);
  }
  return sum;
}

// Degli-Esposti's F_alpha(theta): integral over the hemisphere of
// ((1 + cos psi)/2)^alpha, psi the angle to a direction theta from the normal.
double lobe_integral_ref(int alpha, double theta) {
  const Vec3 n{0, 0, 1}, d{std::sin(theta), 0, std::cos(theta)};
  return hemisphere(n, [&](const Vec3& k) { return std::pow((1 + tracer::dot(k, d)) / 2, alpha); });
}

// F_alpha on a fine theta grid (linear interpolation: relative error < 1e-7).
struct LobeTable {
  int alpha;
  std::vector<double> v;
  static constexpr int kN = 2000;
  explicit LobeTable(int a) : alpha(a), v(kN + 1) {
    for (int i = 0; i <= kN; ++i) v[i] = lobe_integral_ref(a, kPi / 2 * i / kN);
  }
  double operator()(double theta) const {
    const double u = std::clamp(theta / (kPi / 2), 0.0, 1.0) * kN;
    const int i = std::min(kN - 1, static_cast<int>(u));
    return v[i] + (u - i) * (v[i + 1] - v[i]);
  }
};

Vec3 theta_hat(const Vec3& d) {
  const double th = std::acos(std::clamp(d[2], -1.0, 1.0)), ph = std::atan2(d[1], d[0]);
  return {std::cos(th) * std::cos(ph), std::cos(th) * std::sin(ph), -std::sin(th)};
}

// A horizontal plate z = 0 over [-h, h]^2 (normal +z), no ground.
meshkit::Scene plate_scene(double h, const std::string& material) {
  meshkit::Scene s;
  add_quad(s, material, "plate", {-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0});
  return s;
}

// Expected diffuse power (|a|^2 summed) from the plate by the bistatic radar
// equation, V-polarised isotropic antennas, K_x = 1/2 (G_r_eff = G_r / 2):
// int S^2 f |E_refl|^2 (1/2) lambda^2 cos(theta_i) / (16 pi^2 r_i^2 r_s^2) dS,
// |E_refl|^2 = |R_TE|^2 |E.e_s|^2 + |R_TM|^2 |E.e_p|^2 with E = theta_hat.
struct PlateIntegral {
  double h = 2;
  Vec3 tx, rx;
  double s = 1;
  const tracer::RadioMaterial* material = nullptr;
  std::function<double(const Vec3& k_in, const Vec3& k_out, double theta_i)> pattern;
  int panels = 10;
  double operator()() const {
    std::vector<double> x, w;
    composite(-h, h, panels, x, w);
    const Vec3 n{0, 0, 1};
    double sum = 0;
    for (std::size_t i = 0; i < x.size(); ++i)
      for (std::size_t j = 0; j < x.size(); ++j) {
        const Vec3 p{x[i], x[j], 0};
        const Vec3 vi = p - tx, vs = rx - p;
        const double ri = tracer::norm(vi), rs = tracer::norm(vs);
        const Vec3 k_in = (1 / ri) * vi, k_s = (1 / rs) * vs;
        const double cos_i = -tracer::dot(k_in, n);
        const auto r = tracer::slab_coefficients(*material, cos_i).r;
        const Vec3 es = tracer::normalize(tracer::cross(k_in, n)), ep = tracer::cross(es, k_in);
        const Vec3 e = theta_hat(k_in);
        const double refl = std::norm(r.te) * std::pow(tracer::dot(e, es), 2) +
                            std::norm(r.tm) * std::pow(tracer::dot(e, ep), 2);
        const double f = pattern(k_in, k_s, std::acos(cos_i));
        sum += w[i] * w[j] * s * s * f * refl * 0.5 * kLambda * kLambda * cos_i /
               (16 * kPi * kPi * ri * ri * rs * rs);
      }
    return sum;
  }
  // The ER model scatters S^2 |Gamma(theta_i)|^2 of the incident power
  // with a lobe normalised at theta_i: not reciprocal for lossy slabs or
  // directive lobes. The tile integration uses the mean of both directions
  // (tracer/src/diffuse_tiles.hpp); the ray estimator gathers from the first node.
  double symmetric() const {
    PlateIntegral back = *this;
    std::swap(back.tx, back.rx);
    return 0.5 * ((*this)() + back());
  }
  double expected(tracer::DiffuseIntegration how) const {
    return how == tracer::DiffuseIntegration::tiles ? symmetric() : (*this)();
  }
};

// The radar integral of a fully rough (S = 1) Lambertian plate of half side
// 2 m between tx and rx, and the override that makes a material so
// (K_x = 1/2: the received power is G_r / 2 times |E_refl|^2).
PlateIntegral lambertian_plate(const Vec3& tx, const Vec3& rx, const tracer::RadioMaterial* material) {
  PlateIntegral ref;
  ref.h = 2;
  ref.tx = tx;
  ref.rx = rx;
  ref.s = 1;
  ref.material = material;
  ref.pattern = [](const Vec3&, const Vec3& k_s, double) { return std::max(0.0, k_s[2]) / kPi; };
  return ref;
}
tracer::MaterialOverride lambertian_override() {
  tracer::MaterialOverride mo;
  mo.scattering_coefficient = 1.0;
  mo.xpd = 0.5;
  mo.lobe = tracer::ScatteringLobe::lambertian;
  return mo;
}

const char* integration_name(tracer::DiffuseIntegration how) {
  return how == tracer::DiffuseIntegration::tiles ? "tiles" : "rays";
}

// The same integrand summed over the rays of a Fibonacci lattice from tx that
// hit the plate (dOmega = 4 pi / N): the discretisation a shoot-and-bounce
// estimate carries, to show that the Monte Carlo tolerance is honest.
double plate_lattice_sum(const PlateIntegral& pi, int rays) {
  const auto dirs = tracer::fibonacci_sphere(rays);
  const Vec3 n{0, 0, 1};
  double sum = 0;
  for (const auto& d : dirs) {
    if (d[2] >= 0) continue;
    const double t = -pi.tx[2] / d[2];
    const Vec3 p = pi.tx + t * d;
    if (std::fabs(p[0]) > pi.h || std::fabs(p[1]) > pi.h) continue;
    const Vec3 vs = pi.rx - p;
    const double rs = tracer::norm(vs);
    const Vec3 k_s = (1 / rs) * vs;
    const double cos_i = -d[2];
    const auto r = tracer::slab_coefficients(*pi.material, cos_i).r;
    const Vec3 es = tracer::normalize(tracer::cross(d, n)), ep = tracer::cross(es, d);
    const Vec3 e = theta_hat(d);
    const double refl =
        std::norm(r.te) * std::pow(tracer::dot(e, es), 2) + std::norm(r.tm) * std::pow(tracer::dot(e, ep), 2);
    const double f = pi.pattern(d, k_s, std::acos(cos_i));
    sum += pi.s * pi.s * f * refl * 0.5 * kLambda * kLambda * (4 * kPi / rays) / (16 * kPi * kPi * rs * rs);
  }
  return sum;
}

struct Powers {
  double diffuse = 0;          // sum of |a|^2 over paths ending in a diffuse interaction
  std::size_t n_diffuse = 0;
  const tracer::Path* specular = nullptr;  // the single-reflection specular path, if any
  const tracer::Path* direct = nullptr;
};
Powers powers(const tracer::PairResult& p) {
  Powers out;
  for (const auto& path : p.paths) {
    if (path.interactions.empty()) {
      out.direct = &path;
    } else if (std::any_of(path.interactions.begin(), path.interactions.end(),
                           [](const auto& in) { return in.type == tracer::InteractionType::diffuse; })) {
      out.diffuse += std::norm(path.a);
      ++out.n_diffuse;
    } else if (path.interactions.size() == 1 && path.interactions[0].type == tracer::InteractionType::specular) {
      out.specular = &path;
    }
  }
  return out;
}

tracer::TracerConfig diffuse_config(int rays) {
  tracer::TracerConfig c;
  c.max_depth = 1;
  c.diffuse = true;
  c.rays_per_source = rays;
  c.path_threshold_db = 0;
  return c;
}

}  // namespace

// ---------------------------------------------------------------------------
// 7. Lobes.

TEST(Diffuse, LobeIntegralMatchesHemisphereQuadrature) {
  // The reference itself: F_0 = 2 pi, and F_1(0) = pi + pi / 2... by hand:
  // int ((1 + cos t)/2) dOmega = pi + pi/2 at normal incidence.
  EXPECT_NEAR(lobe_integral_ref(0, 0.3), 2 * kPi, 1e-12);
  EXPECT_NEAR(lobe_integral_ref(1, 0), 1.5 * kPi, 1e-12);
  for (int alpha : {1, 2, 4, 8, 20})
    for (double theta_deg : {0.0, 30.0, 60.0, 85.0}) {
      const double expect = lobe_integral_ref(alpha, theta_deg * kDeg);
      const double got = tracer::lobe_integral(alpha, theta_deg * kDeg);
      EXPECT_NEAR(got / expect, 1.0, 1e-4) << "alpha " << alpha << " theta " << theta_deg << ": " << got << " vs "
                                           << expect;
    }
}

// The closed form's angle-free factors are tabled per alpha (and built per
// call past the table): the result must be the per-call recurrence's, bit for
// bit, or the tracer's outputs would move with the table.
TEST(Diffuse, LobeIntegralTabledIsTheRecurrenceBitForBit) {
  auto recurrence = [](int alpha, double ct) {
    const double st2 = std::max(0.0, 1 - ct * ct);
    double sum = 0, binom = 1;
    for (int j = 0; j <= alpha; ++j) {
      double ij = 2 * kPi / (j + 1);
      if (j % 2) {
        double inner = 0, cw = 1, pw = 1;
        for (int w = 0; w <= (j - 1) / 2; ++w) {
          inner += cw * pw;
          cw = cw * (2.0 * w + 1) * (2.0 * w + 2) / ((w + 1.0) * (w + 1.0));
          pw *= st2 / 4;
        }
        ij *= ct * inner;
      }
      sum += binom * ij;
      binom = binom * (alpha - j) / (j + 1.0);
    }
    double p2 = 1;
    for (int k = 0; k < alpha; ++k) p2 *= 2;
    return sum / p2;
  };
  int compared = 0;
  for (int alpha : {0, 1, 2, 3, 4, 7, 8, 13, 20, 64, 65, 90})
    for (int i = 0; i <= 400; ++i) {
      const double theta = kPi / 2 * i / 400;
      const double want = recurrence(alpha, std::cos(theta)), got = tracer::lobe_integral(alpha, theta);
      ASSERT_EQ(std::memcmp(&want, &got, sizeof want), 0) << "alpha " << alpha << " theta " << theta << ": " << got
                                                            << " vs " << want;
      ++compared;
    }
  EXPECT_EQ(compared, 12 * 401);
}

TEST(Diffuse, ScatteringPatternsAreNormalisedAndOneSided) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  auto random_unit = [&] {
    for (;;) {
      const Vec3 v{u(rng), u(rng), u(rng)};
      if (tracer::norm(v) > 0.2 && tracer::norm(v) < 1) return tracer::normalize(v);
    }
  };
  std::vector<tracer::Scattering> lobes;
  {
    tracer::Scattering l;
    l.s = 0.5;
    l.lobe = tracer::ScatteringLobe::lambertian;
    lobes.push_back(l);
    for (int a : {1, 4, 10, 20}) {
      tracer::Scattering d;
      d.s = 0.5;
      d.lobe = tracer::ScatteringLobe::directive;
      d.alpha_r = a;
      lobes.push_back(d);
    }
    for (double lr : {0.0, 0.3, 0.75, 1.0}) {
      tracer::Scattering b;
      b.s = 0.5;
      b.lobe = tracer::ScatteringLobe::backscatter;
      b.alpha_r = 6;
      b.alpha_i = 3;
      b.lambda_r = lr;
      lobes.push_back(b);
    }
  }
  for (int trial = 0; trial < 6; ++trial) {
    const Vec3 n_any = random_unit();
    Vec3 k_in = random_unit();
    if (trial == 0) k_in = -1.0 * n_any;  // normal incidence
    if (std::fabs(tracer::dot(k_in, n_any)) < 0.05) continue;
    // The front side: where the wave comes from.
    const Vec3 front = tracer::dot(k_in, n_any) < 0 ? n_any : -1.0 * n_any;
    const double cos_i = -tracer::dot(k_in, front), theta_i = std::acos(std::clamp(cos_i, 0.0, 1.0));
    const Vec3 spec = k_in + (2 * cos_i) * front;
    for (const auto& sc : lobes) {
      const double total = hemisphere(front, [&](const Vec3& k) { return tracer::scattering_pattern(sc, k_in, k, n_any); });
      EXPECT_NEAR(total, 1.0, 1e-4) << tracer::scattering_lobe_name(sc.lobe) << " alpha_r " << sc.alpha_r
                                    << " lambda_r " << sc.lambda_r << " theta_i " << theta_i / kDeg;
      // Nothing behind the surface; the normal's orientation does not matter.
      for (int k = 0; k < 20; ++k) {
        Vec3 out = random_unit();
        const double c = tracer::dot(out, front);
        if (c < 0) {
          EXPECT_EQ(tracer::scattering_pattern(sc, k_in, out, n_any), 0.0);
        }
        if (c < 0) out = -1.0 * out;
        const double cs = tracer::dot(out, front);
        const double f = tracer::scattering_pattern(sc, k_in, out, n_any);
        EXPECT_DOUBLE_EQ(f, tracer::scattering_pattern(sc, k_in, out, -1.0 * n_any));
        if (sc.lobe == tracer::ScatteringLobe::lambertian) {
          EXPECT_NEAR(f, cs / kPi, 1e-12);
        }
        if (sc.lobe == tracer::ScatteringLobe::directive) {
          const double expect =
              std::pow((1 + tracer::dot(out, spec)) / 2, sc.alpha_r) / lobe_integral_ref(sc.alpha_r, theta_i);
          EXPECT_NEAR(f / expect, 1.0, 1e-6) << "alpha_r " << sc.alpha_r;
        }
        EXPECT_GE(f, 0.0);
      }
    }
  }
}

// ---------------------------------------------------------------------------
// 8. Lambertian plate against the bistatic radar equation.

TEST(Diffuse, LambertianPlateMatchesRadarEquation) {
  const auto scene_def = plate_scene(2, "metal");
  tracer::TraceScene scene(scene_def);
  const Vec3 tx{-3, 0, 5}, rx{4, 1, 6};
  const auto metal = tracer::radio_material("metal", kF);
  // PEC-like: |Gamma| = 1 within 1e-3 over the plate's angles (0 .. 50 deg).
  for (double deg = 0; deg <= 50; deg += 5) {
    const auto r = tracer::slab_coefficients(metal, std::cos(deg * kDeg)).r;
    EXPECT_NEAR(std::abs(r.te), 1.0, 1e-3);
    EXPECT_NEAR(std::abs(r.tm), 1.0, 1e-3);
  }
  PlateIntegral ref = lambertian_plate(tx, rx, &metal);
  const double expect = ref();
  const int rays = 1 << 18;
  const double lattice = plate_lattice_sum(ref, rays);
  std::printf("lambertian plate: radar integral %.6e, lattice sum (N = %d) %.6e (%+.3f %%)\n", expect, rays, lattice,
              100 * (lattice / expect - 1));
  ASSERT_NEAR(lattice / expect, 1.0, 0.01) << "the lattice discretisation alone should be within 1 %";

  auto cfg = diffuse_config(rays);
  cfg.materials["metal"] = lambertian_override();
  // Tiles (the default): the midpoint rule on tiles <= 0.25 x distance;
  // rays: the lattice's discretisation (above) plus the reception binning.
  for (auto how : {tracer::DiffuseIntegration::rays, tracer::DiffuseIntegration::tiles}) {
    cfg.diffuse_integration = how;
    const double want = ref.expected(how);
    const auto s = tracer::trace_snapshot(scene, {node("tx", tx), node("rx", rx)}, cfg, {});
    const auto q = powers(s.pairs[0]);
    std::printf("lambertian plate, %s: expected %.6e, traced %.6e in %zu diffuse paths (%+.3f %%)\n",
                integration_name(how), want, q.diffuse, q.n_diffuse, 100 * (q.diffuse / want - 1));
    EXPECT_NEAR(q.diffuse / want, 1.0, how == tracer::DiffuseIntegration::tiles ? 0.01 : 0.03) << integration_name(how);
  }
  cfg.diffuse_integration = tracer::DiffuseIntegration::tiles;
  const auto snap = tracer::trace_snapshot(scene, {node("tx", tx), node("rx", rx)}, cfg, {});
  ASSERT_EQ(snap.pairs.size(), 1u);
  const auto p = powers(snap.pairs[0]);
  EXPECT_GT(p.n_diffuse, 0u);
  EXPECT_EQ(snap.stats.diffuse_paths, p.n_diffuse);
  // S = 1: nothing is left for the specular reflection.
  if (p.specular) {
    EXPECT_EQ(std::norm(p.specular->a), 0.0);
  }
  // The direct path is untouched.
  ASSERT_TRUE(p.direct);
  const double d = tracer::norm(rx - tx);
  EXPECT_NEAR(std::abs(p.direct->a), kLambda / (4 * kPi * d), 1e-9 * kLambda / (4 * kPi * d));
  // Diffuse paths: scattered on the plate, later than the direct path.
  const auto names = scene.object_names();
  for (const auto& path : snap.pairs[0].paths) {
    if (path.interactions.empty() || path.interactions.back().type != tracer::InteractionType::diffuse) continue;
    ASSERT_EQ(path.interactions.size(), 1u);
    EXPECT_EQ(names.at(path.interactions[0].object), "plate");
    const Vec3 q = path.interactions[0].point;
    EXPECT_NEAR(q[2], 0.0, 1e-9);
    EXPECT_LE(std::fabs(q[0]), 2 + 1e-9);
    EXPECT_LE(std::fabs(q[1]), 2 + 1e-9);
    EXPECT_GT(path.tau_s, d / kC);
    // Within the delay span of the plate.
    EXPECT_LT(path.tau_s, (tracer::norm(Vec3{-2, -2, 0} - tx) + tracer::norm(Vec3{-2, -2, 0} - rx) + 10) / kC);
  }
}

TEST(Diffuse, LambertianConcretePlateMatchesRadarEquation) {
  // A lossy slab: R_TE and R_TM differ in magnitude and phase, so the
  // reflected field is elliptical; with K_x = 1/2 the received power is still
  // G_r / 2 times |E_refl|^2 (co + cross = everything).
  const auto scene_def = plate_scene(2, "concrete");
  tracer::TraceScene scene(scene_def);
  const Vec3 tx{-3, 0, 5}, rx{4, 1, 6};
  const auto concrete = tracer::radio_material("concrete", kF);
  PlateIntegral ref = lambertian_plate(tx, rx, &concrete);
  const double expect = ref();
  const int rays = 1 << 18;
  const double lattice = plate_lattice_sum(ref, rays);
  ASSERT_NEAR(lattice / expect, 1.0, 0.01);
  auto cfg = diffuse_config(rays);
  cfg.materials["concrete"] = lambertian_override();
  std::printf("lambertian concrete plate: radar integral %.6e (one way), %.6e (mean of both ways), lattice %.6e\n",
              expect, ref.symmetric(), lattice);
  // |Gamma| of concrete depends on the angle: the two ways differ.
  EXPECT_GT(std::fabs(ref.symmetric() / expect - 1), 0.01);
  for (auto how : {tracer::DiffuseIntegration::rays, tracer::DiffuseIntegration::tiles}) {
    cfg.diffuse_integration = how;
    const double want = ref.expected(how);
    const auto snap = tracer::trace_snapshot(scene, {node("tx", tx), node("rx", rx)}, cfg, {});
    const auto p = powers(snap.pairs[0]);
    std::printf("lambertian concrete plate, %s: traced %.6e (%+.3f %%)\n", integration_name(how), p.diffuse,
                100 * (p.diffuse / want - 1));
    EXPECT_NEAR(p.diffuse / want, 1.0, how == tracer::DiffuseIntegration::tiles ? 0.01 : 0.03) << integration_name(how);
  }
}

TEST(Diffuse, BothEndsEstimatorSamplesThePlateFromTheNearEnd) {
  // A far transmitter and a receiver 0.6 m above a 4 x 4 m plate: few of the
  // transmitter's rays hit the plate (the one-sided estimate is noisy), the
  // receiver's rays cover it densely. Both ends' samples, combined by the
  // balance heuristic, converge to the radar integral; a reciprocal
  // integrand (lambertian PEC plate) gives the same power either way round.
  const auto scene_def = plate_scene(2, "metal");
  tracer::TraceScene scene(scene_def);
  const Vec3 tx{-30, 5, 20}, rx{0.5, 0.3, 0.6};
  const auto metal = tracer::radio_material("metal", kF);
  PlateIntegral ref = lambertian_plate(tx, rx, &metal);
  ref.panels = 40;  // the receiver is close: a fine rule
  const double want = ref();
  auto cfg = diffuse_config(4096);
  cfg.materials["metal"] = lambertian_override();
  const auto traced = [&](bool both, bool reversed) {
    cfg.diffuse_both_ends = both;
    std::vector<tracer::Node> nodes{node("tx", tx), node("rx", rx)};
    if (reversed) std::swap(nodes[0], nodes[1]);
    return powers(tracer::trace_snapshot(scene, nodes, cfg, {}).pairs.at(0)).diffuse;
  };
  const double one = traced(false, false), both = traced(true, false), back = traced(true, true);
  std::printf("near-end plate: radar integral %.6e, one end %.6e (%+.2f %%), both ends %.6e (%+.2f %%)\n", want, one,
              100 * (one / want - 1), both, 100 * (both / want - 1));
  EXPECT_NEAR(both / want, 1.0, 0.03);
  EXPECT_GT(std::fabs(one / want - 1), 3 * std::fabs(both / want - 1)) << "the far end's rays alone are coarser";
  // Reciprocal up to metal's |Gamma|^2, within 1e-3 of 1 and not the same at
  // both ends' angles: the same samples, the same weights.
  EXPECT_NEAR(back / both, 1.0, 1e-4);
  EXPECT_NE(back, both) << "evaluated from the other end";
}

// A rough (Lambertian, S = 1) metal wall on a smooth ground, and the
// settings both tests below trace it with.
meshkit::Scene wall_on_ground() {
  meshkit::Scene sc;
  add_ground(sc, 100);
  add_box_object(sc, {5, -4, 0}, {6, 4, 5}, "metal", "wall");
  return sc;
}
tracer::TracerConfig wall_on_ground_config() {
  tracer::TracerConfig cfg;
  cfg.max_depth = 2;
  cfg.rays_per_source = 1 << 16;
  cfg.path_threshold_db = 0;
  cfg.diffraction = false;
  cfg.materials["metal"] = lambertian_override();
  return cfg;
}

TEST(Diffuse, ScatteringBeforeAndAfterAReflectionBothCount) {
  // A rough (Lambertian, S = 1) metal wall on a smooth ground, a high
  // transmitter far from it and a low receiver near it. Scattering after the
  // ground bounce (a -> ground -> wall -> b) and before it (a -> wall ->
  // ground -> b) are different paths; the one end's rays reach the first
  // only, so each pair gathers the second from its other end's rays. With
  // both, the pair's diffuse power is the same either way round (a
  // reciprocal integrand: Lambertian on metal, within the rays' noise); the
  // lower end alone gets a different half in each order.
  tracer::TraceScene scene(wall_on_ground());
  auto cfg = wall_on_ground_config();
  const auto a = node("a", {-15, 1, 6}), b = node("b", {3, -1, 1});
  const auto diffuse = [&](bool both, bool reversed) {
    cfg.diffuse_both_ends = both;
    const auto snap = tracer::trace_snapshot(scene, reversed ? std::vector<tracer::Node>{b, a} : std::vector{a, b}, cfg, {});
    return powers(snap.pairs.at(0)).diffuse;
  };
  const double fwd = diffuse(true, false), back = diffuse(true, true);
  const double one_fwd = diffuse(false, false), one_back = diffuse(false, true);
  std::printf("wall and ground: both ends %.6e / %.6e (%+.2f %%), lower end alone %.6e / %.6e (%+.2f %%)\n", fwd, back,
              100 * (back / fwd - 1), one_fwd, one_back, 100 * (one_back / one_fwd - 1));
  EXPECT_NEAR(back / fwd, 1.0, 0.01);
  // The ground reflects |Gamma|^2 ~ 0.1-0.4 here: the half missed is a few %.
  EXPECT_GT(std::fabs(one_back / one_fwd - 1), 0.03) << "the lower end alone misses a different half";
  EXPECT_GT(fwd, std::max(one_fwd, one_back));
}

TEST(Diffuse, HybridIsTheTilesFirstOrderPlusTheRaysChains) {
  // The same wall and ground. `hybrid` integrates first-order scattering by
  // tiles and leaves the rest (a ground bounce before or after the wall) to
  // the rays: its single-interaction diffuse paths are the tiles' own, bit
  // for bit, every other one holds a reflection, and the whole agrees with
  // the rays' estimate of both (two estimators of one integral).
  tracer::TraceScene scene(wall_on_ground());
  auto cfg = wall_on_ground_config();
  const std::vector<tracer::Node> nodes{node("a", {-15, 1, 6}), node("b", {3, -1, 1})};
  const auto trace = [&](tracer::DiffuseIntegration how) {
    cfg.diffuse_integration = how;
    return tracer::trace_snapshot(scene, nodes, cfg, {}).pairs.at(0);
  };
  const auto rays = trace(tracer::DiffuseIntegration::rays);
  const auto tiles = trace(tracer::DiffuseIntegration::tiles);
  const auto hybrid = trace(tracer::DiffuseIntegration::hybrid);
  const auto is_diffuse = [](const tracer::Path& p) {
    return !p.interactions.empty() && p.interactions.back().type == tracer::InteractionType::diffuse;
  };
  std::vector<const tracer::Path*> first_tiles, first_hybrid;
  double chains = 0;
  for (const auto& p : tiles.paths)
    if (is_diffuse(p)) first_tiles.push_back(&p);
  for (const auto& p : hybrid.paths) {
    const bool diffuse = std::any_of(p.interactions.begin(), p.interactions.end(),
                                     [](const auto& in) { return in.type == tracer::InteractionType::diffuse; });
    if (!diffuse) continue;
    if (p.interactions.size() == 1) {
      first_hybrid.push_back(&p);
    } else {
      EXPECT_TRUE(std::any_of(p.interactions.begin(), p.interactions.end(),
                              [](const auto& in) { return in.type == tracer::InteractionType::specular; }));
      chains += std::norm(p.a);
    }
  }
  ASSERT_FALSE(first_tiles.empty());
  ASSERT_EQ(first_hybrid.size(), first_tiles.size());
  for (std::size_t k = 0; k < first_tiles.size(); ++k) {
    EXPECT_EQ(first_hybrid[k]->a, first_tiles[k]->a) << k;
    EXPECT_EQ(first_hybrid[k]->tau_s, first_tiles[k]->tau_s) << k;
    EXPECT_EQ(first_hybrid[k]->doppler_hz, first_tiles[k]->doppler_hz) << k;
  }
  const double p_rays = powers(rays).diffuse, p_tiles = powers(tiles).diffuse, p_hybrid = powers(hybrid).diffuse;
  std::printf("wall and ground: rays %.6e, tiles (first order) %.6e, hybrid %.6e (chains %.2f %%, %+.2f %% of rays)\n",
              p_rays, p_tiles, p_hybrid, 100 * chains / p_hybrid, 100 * (p_hybrid / p_rays - 1));
  EXPECT_GT(chains, 0.01 * p_hybrid) << "the ground bounces before and after the wall";
  EXPECT_NEAR(p_hybrid / (p_tiles + chains), 1.0, 1e-12);
  EXPECT_NEAR(p_hybrid / p_rays, 1.0, 0.03);
}

// ---------------------------------------------------------------------------
// 9. Energy partition and a directive lobe.

TEST(Diffuse, SpecularKeepsOneMinusSSquaredAndDirectiveLobeMatchesIntegral) {
  const auto scene_def = plate_scene(10, "metal");
  tracer::TraceScene scene(scene_def);
  const Vec3 tx{-6, 0, 5}, rx{7, 1, 6};
  const double S = 0.6;
  const int rays = 1 << 18;
  auto cfg = diffuse_config(rays);
  tracer::MaterialOverride mo;
  mo.scattering_coefficient = S;
  mo.xpd = 0.5;
  mo.lobe = tracer::ScatteringLobe::directive;
  mo.alpha_r = 4;
  cfg.materials["metal"] = mo;
  cfg.diffuse_integration = tracer::DiffuseIntegration::rays;
  const std::vector<tracer::Node> nodes = {node("tx", tx), node("rx", rx)};
  const auto on = tracer::trace_snapshot(scene, nodes, cfg, {});
  cfg.diffuse = false;
  const auto off = tracer::trace_snapshot(scene, nodes, cfg, {});
  const auto p_on = powers(on.pairs[0]), p_off = powers(off.pairs[0]);
  ASSERT_TRUE(p_on.specular && p_off.specular);
  EXPECT_NEAR(std::norm(p_on.specular->a) / std::norm(p_off.specular->a), 1 - S * S, 1e-9);
  EXPECT_EQ(p_off.n_diffuse, 0u);
  // Unchanged phase and delay: the partition scales the amplitude only.
  EXPECT_NEAR(std::arg(p_on.specular->a / p_off.specular->a), 0.0, 1e-9);
  EXPECT_EQ(p_on.specular->tau_s, p_off.specular->tau_s);

  const auto metal = tracer::radio_material("metal", kF);
  const LobeTable f4(4);
  PlateIntegral ref;
  ref.h = 10;
  ref.tx = tx;
  ref.rx = rx;
  ref.s = S;
  ref.material = &metal;
  ref.panels = 40;
  ref.pattern = [&](const Vec3& k_in, const Vec3& k_s, double theta_i) {
    if (k_s[2] <= 0) return 0.0;
    const Vec3 spec{k_in[0], k_in[1], -k_in[2]};
    return std::pow((1 + tracer::dot(k_s, spec)) / 2, 4) / f4(theta_i);
  };
  const double expect = ref();
  const double lattice = plate_lattice_sum(ref, rays);
  std::printf("directive plate: radar integral %.6e, lattice %.6e (%+.3f %%), traced %.6e (%+.3f %%) in %zu paths\n",
              expect, lattice, 100 * (lattice / expect - 1), p_on.diffuse, 100 * (p_on.diffuse / expect - 1),
              p_on.n_diffuse);
  ASSERT_NEAR(lattice / expect, 1.0, 0.01);
  EXPECT_NEAR(p_on.diffuse / expect, 1.0, 0.05);
  cfg.diffuse = true;
  cfg.diffuse_integration = tracer::DiffuseIntegration::tiles;
  const auto tiled = tracer::trace_snapshot(scene, nodes, cfg, {});  // outlives `tiles`' path pointers
  const auto tiles = powers(tiled.pairs[0]);
  const double sym = ref.symmetric();
  std::printf("directive plate, tiles: expected (mean of both ways) %.6e, traced %.6e (%+.3f %%)\n", sym, tiles.diffuse,
              100 * (tiles.diffuse / sym - 1));
  EXPECT_NEAR(tiles.diffuse / sym, 1.0, 0.01);
  ASSERT_TRUE(tiles.specular);
  EXPECT_NEAR(std::norm(tiles.specular->a) / std::norm(p_off.specular->a), 1 - S * S, 1e-9);
}

// ---------------------------------------------------------------------------
// 10. Switch and determinism.

TEST(Diffuse, SwitchAndThreadCountDeterminism) {
  meshkit::Scene s;
  add_ground(s, 300);
  add_box_object(s, {10, -20, 0}, {30, -5, 15}, "concrete", "block");  // default S = 0.4
  add_wall_y(s, 25, 200, "brick", "north");
  tracer::TraceScene scene(s);
  const std::vector<tracer::Node> nodes = {node("a", {0, 0, 1.5}), node("b", {40, 3, 1.6}), node("c", {-30, -2, 5}),
                                           node("d", {20, 2, 2})};
  tracer::TracerConfig cfg;
  cfg.max_depth = 2;
  cfg.rays_per_source = 8192;
  cfg.path_threshold_db = 0;
  cfg.diffraction = true;
  cfg.diffuse = false;
  const auto off = tracer::trace_snapshot(scene, nodes, cfg, {});
  EXPECT_EQ(off.stats.diffuse_paths, 0u);
  for (const auto& p : off.pairs)
    for (const auto& path : p.paths)
      for (const auto& in : path.interactions) EXPECT_NE(in.type, tracer::InteractionType::diffuse);

  cfg.diffuse = true;
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    return tracer::trace_snapshot(scene, nodes, cfg, {});
  };
  const auto one = run(1), two = run(2);
  EXPECT_GT(one.stats.diffuse_paths, 0u);
  std::uint64_t diffuse = 0, scatter_first = 0;
  for (const auto& p : one.pairs)
    for (const auto& path : p.paths) {
      std::size_t scatters = 0;
      for (const auto& in : path.interactions) scatters += in.type == tracer::InteractionType::diffuse;
      EXPECT_LE(scatters, 1u);
      diffuse += scatters;
      // The scattering is last, or first (before the reflections, gathered
      // by the pair's higher end); never between two reflections.
      for (std::size_t k = 1; k + 1 < path.interactions.size(); ++k)
        EXPECT_NE(path.interactions[k].type, tracer::InteractionType::diffuse);
      scatter_first += path.interactions.size() > 1 && path.interactions[0].type == tracer::InteractionType::diffuse;
      EXPECT_TRUE(std::isfinite(std::abs(path.a)));
    }
  EXPECT_GT(scatter_first, 0u) << "scattering before a reflection (a wall, then the ground) occurs here";
  EXPECT_EQ(diffuse, one.stats.diffuse_paths);
  ASSERT_EQ(one.pairs.size(), two.pairs.size());
  EXPECT_EQ(one.stats.paths, two.stats.paths);
  EXPECT_EQ(one.stats.diffuse_paths, two.stats.diffuse_paths);
  EXPECT_EQ(one.stats.diffraction_paths, two.stats.diffraction_paths);
  for (std::size_t i = 0; i < one.pairs.size(); ++i) {
    ASSERT_EQ(one.pairs[i].paths.size(), two.pairs[i].paths.size()) << "pair " << i;
    for (std::size_t k = 0; k < one.pairs[i].paths.size(); ++k) {
      const auto &x = one.pairs[i].paths[k], &y = two.pairs[i].paths[k];
      EXPECT_EQ(std::memcmp(&x.a, &y.a, sizeof x.a), 0) << "pair " << i << " path " << k;  // bitwise
      EXPECT_EQ(std::memcmp(&x.tau_s, &y.tau_s, sizeof x.tau_s), 0);
      EXPECT_EQ(x.doppler_hz, y.doppler_hz);
      EXPECT_EQ(x.theta_t, y.theta_t);
      EXPECT_EQ(x.phi_r, y.phi_r);
      ASSERT_EQ(x.interactions.size(), y.interactions.size());
      for (std::size_t q = 0; q < x.interactions.size(); ++q) {
        EXPECT_EQ(x.interactions[q].type, y.interactions[q].type);
        EXPECT_EQ(x.interactions[q].point, y.interactions[q].point);
      }
    }
  }
}

// ---------------------------------------------------------------------------
// 11. The tile integration: convergence, shadows, reciprocity.

namespace {

// A street: ground, a concrete block, a brick wall, and metal boxes of
// vehicle size that shadow parts of the facades.
meshkit::Scene street() {
  meshkit::Scene s;
  add_ground(s, 150);
  add_box_object(s, {10, -25, 0}, {40, -8, 15}, "concrete", "block");
  add_wall_y(s, 9, 80, "brick", "north");
  add_box_object(s, {4, -6.5, 0}, {8.5, -4.7, 1.5}, "metal", "van");
  add_box_object(s, {22, 3, 0}, {26.5, 4.8, 1.5}, "metal", "car");
  return s;
}
std::vector<tracer::Node> street_nodes() {
  return {node("a", {0, 0, 1.5}, {10, 0, 0}), node("b", {40, 3, 1.6}), node("c", {-30, -2, 5}),
          node("d", {20, 2, 2}, {0, 5, 0}), node("e", {15, -5, 1.5}), node("f", {60, -3, 1.5})};
}
// Two reflections, every path kept, no diffraction: the street's diffuse
// tests' tracer.
tracer::TracerConfig street_config(int rays) {
  tracer::TracerConfig cfg;
  cfg.max_depth = 2;
  cfg.rays_per_source = rays;
  cfg.path_threshold_db = 0;
  cfg.diffraction = false;
  return cfg;
}
std::vector<double> pair_diffuse(const tracer::Snapshot& s) {
  std::vector<double> p;
  for (const auto& pair : s.pairs) p.push_back(powers(pair).diffuse);
  return p;
}

}  // namespace

TEST(DiffuseTiles, ConvergeUnderRefinementWithShadows) {
  tracer::TraceScene scene(street());
  const auto nodes = street_nodes();
  tracer::TracerConfig cfg;
  cfg.diffuse_integration = tracer::DiffuseIntegration::tiles;
  cfg.specular = false;  // the diffuse part alone
  cfg.diffraction = false;
  cfg.path_threshold_db = 0;
  auto run = [&](double tile, double ratio, double shadow) {
    auto c = cfg;
    c.diffuse_tile_m = tile;
    c.diffuse_tile_ratio = ratio;
    c.diffuse_shadow_ratio = shadow;
    return pair_diffuse(tracer::trace_snapshot(scene, nodes, c, {}));
  };
  const auto ref = run(0.125, 0.04, 0);  // shadow edges resolved to 0.125 m everywhere
  std::size_t with_diffuse = 0;
  for (double p : ref) with_diffuse += p > 0;
  ASSERT_GE(with_diffuse, 12u);
  // Worst per-pair error (dB) along a refinement sequence ending at the
  // default (1 m, 0.25) and beyond.
  std::vector<double> worst;
  for (auto [tile, ratio] : std::vector<std::pair<double, double>>{{4, 1}, {2, 0.5}, {1, 0.25}, {0.5, 0.1}}) {
    const auto got = run(tile, ratio, cfg.diffuse_shadow_ratio);
    double w = 0;
    for (std::size_t i = 0; i < ref.size(); ++i) {
      if (!(ref[i] > 0)) continue;
      const double e = got[i] > 0 ? std::fabs(10 * std::log10(got[i] / ref[i])) : 200;
      w = std::max(w, e);
    }
    std::printf("tiles %.2f m, ratio %.2f: worst pair %.3f dB from the reference (0.125 m, 0.04)\n", tile, ratio, w);
    worst.push_back(w);
  }
  EXPECT_LT(worst[2], 0.5) << "the default within 0.5 dB of the fine reference on every pair";
  EXPECT_LT(worst[3], worst[0]);
  EXPECT_LT(worst[3], 0.25);
}

TEST(DiffuseTiles, ShadowedPlateMatchesRadarEquationOverTheLitPart) {
  // A metal plate (Lambertian, S = 1) whose middle strips a metal bar hides
  // from the transmitter and the receiver: the reference integrates the
  // radar equation over the points both segments reach without crossing it.
  meshkit::Scene s = plate_scene(4, "metal");
  const Vec3 lo{-0.5, -6, 1.0}, hi{0.5, 6, 1.6};
  add_box_object(s, lo, hi, "metal", "bar");
  tracer::TraceScene scene(s);
  const Vec3 tx{-3, 0, 5}, rx{4, 1, 6};
  const auto metal = tracer::radio_material("metal", kF);
  auto clear = [&](const Vec3& from, const Vec3& p) {  // slab test of the segment from -> p against the box
    double t0 = 0, t1 = 1;
    for (int k = 0; k < 3; ++k) {
      const double d = p[k] - from[k];
      if (std::fabs(d) < 1e-15) {
        if (from[k] < lo[k] || from[k] > hi[k]) return true;
        continue;
      }
      double a = (lo[k] - from[k]) / d, b = (hi[k] - from[k]) / d;
      if (a > b) std::swap(a, b);
      t0 = std::max(t0, a);
      t1 = std::min(t1, b);
    }
    return t0 > t1;
  };
  auto lit = [&](const Vec3& p) { return clear(tx, p) && clear(rx, p); };
  PlateIntegral ref;
  ref.h = 4;
  ref.tx = tx;
  ref.rx = rx;
  ref.s = 1;
  ref.material = &metal;
  ref.panels = 80;
  ref.pattern = [](const Vec3&, const Vec3& k_s, double) { return std::max(0.0, k_s[2]) / kPi; };
  const double full = ref();
  ref.pattern = [&](const Vec3& k_in, const Vec3& k_s, double) {
    // k_in points from tx to the plate point; recover it on z = 0.
    const double t = -tx[2] / k_in[2];
    return lit(tx + t * k_in) ? std::max(0.0, k_s[2]) / kPi : 0.0;
  };
  const double expect = ref();
  EXPECT_LT(expect, 0.9 * full) << "the box must shadow a real part of the plate";
  auto cfg = diffuse_config(1024);
  cfg.materials["metal"] = lambertian_override();
  cfg.specular = false;
  cfg.diffuse_integration = tracer::DiffuseIntegration::tiles;
  // The bar's faces scatter too (metal, S = 1): keep the plate's paths only.
  const auto names = scene.object_names();
  auto plate_power = [&](double tile, double shadow) {
    auto c = cfg;
    c.diffuse_tile_m = tile;
    c.diffuse_shadow_ratio = shadow;
    const auto snap = tracer::trace_snapshot(scene, {node("tx", tx), node("rx", rx)}, c, {});
    double plate = 0;
    for (const auto& path : snap.pairs[0].paths)
      if (!path.interactions.empty() && path.interactions.back().type == tracer::InteractionType::diffuse &&
          names.at(path.interactions.back().object) == "plate")
        plate += std::norm(path.a);
    std::printf("shadowed plate: unshadowed %.6e, lit part %.6e, tiles of %.3f m %.6e (%+.2f %%)\n", full, expect, tile,
                plate, 100 * (plate / expect - 1));
    return plate / expect;
  };
  // Shadow edges are resolved to the finest tiles (here, near the plate,
  // the default's 1 m: a few % against a 1 m bar's two shadows), and the
  // integral converges as they shrink.
  const double coarse = plate_power(1.0, cfg.diffuse_shadow_ratio), fine = plate_power(0.125, 0);
  EXPECT_NEAR(coarse, 1.0, 0.08);
  EXPECT_NEAR(fine, 1.0, 0.015);
  EXPECT_LT(std::fabs(fine - 1), std::fabs(coarse - 1));
}

TEST(DiffuseTiles, ReciprocalBitwise) {
  tracer::TraceScene scene(street());
  auto nodes = street_nodes();
  // Dipoles with different orientations at each end.
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const double a = 0.7 * static_cast<double>(i);
    nodes[i].forward = {std::cos(a), std::sin(a), 0};
  }
  tracer::RadioConfig radio;
  radio.antenna.pattern = tracer::AntennaPattern::halfwave_dipole;
  radio.antenna.polarization = tracer::Polarization::H;
  tracer::TracerConfig cfg;
  cfg.diffuse_integration = tracer::DiffuseIntegration::tiles;
  cfg.specular = false;
  cfg.diffraction = false;
  cfg.path_threshold_db = 0;
  std::vector<tracer::Node> reversed(nodes.rbegin(), nodes.rend());
  const auto fwd = tracer::trace_snapshot(scene, nodes, cfg, radio);
  const auto rev = tracer::trace_snapshot(scene, reversed, cfg, radio);
  const std::size_t n = nodes.size();
  std::size_t compared = 0;
  for (const auto& p : fwd.pairs) {
    // Pair (i, j) is (n-1-j, n-1-i) in the reversed order.
    const std::uint32_t ri = static_cast<std::uint32_t>(n - 1 - p.rx), rj = static_cast<std::uint32_t>(n - 1 - p.tx);
    const auto it = std::find_if(rev.pairs.begin(), rev.pairs.end(),
                                 [&](const tracer::PairResult& q) { return q.tx == ri && q.rx == rj; });
    ASSERT_NE(it, rev.pairs.end());
    std::vector<const tracer::Path*> a, b;
    for (const auto& path : p.paths)
      if (!path.interactions.empty()) a.push_back(&path);
    for (const auto& path : it->paths)
      if (!path.interactions.empty()) b.push_back(&path);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k) {
      EXPECT_EQ(std::memcmp(&a[k]->a, &b[k]->a, sizeof a[k]->a), 0) << "pair " << p.tx << "-" << p.rx;
      EXPECT_EQ(a[k]->tau_s, b[k]->tau_s);
      EXPECT_EQ(a[k]->doppler_hz, b[k]->doppler_hz);
      // Departure and arrival swap.
      EXPECT_EQ(a[k]->theta_t, b[k]->theta_r);
      EXPECT_EQ(a[k]->phi_t, b[k]->phi_r);
      ++compared;
    }
  }
  EXPECT_GT(compared, 10u);
}

TEST(DiffuseTiles, TreeKeptWithTheSceneServesLaterFramesAndOtherMaterials) {
  // The tile tree is built once per scene, tile size and set of rough
  // faces, and kept with the TraceScene: later snapshots (other antenna
  // positions, other materials) on the same scene must give exactly what a
  // fresh scene gives.
  const auto build = [] {
    meshkit::Scene sc;
    add_ground(sc, 60, "metal");
    add_box_object(sc, {5, -6, 0}, {6, 6, 8}, "concrete", "wall");
    return sc;
  };
  const auto sc = build();
  tracer::TraceScene kept(sc);
  tracer::TracerConfig rough, smooth_ground;
  for (auto* c : {&rough, &smooth_ground}) {
    c->max_depth = 1;
    c->diffraction = false;
    c->path_threshold_db = 0;
    c->diffuse_integration = tracer::DiffuseIntegration::tiles;
  }
  rough.materials["metal"] = lambertian_override();  // the ground scatters too; concrete always does
  const std::vector<tracer::Node> first{node("a", {-20, 1, 2}), node("b", {2, -3, 1.5})},
      second{node("a", {-12, 4, 1.6}), node("b", {3, 2, 2.5})};
  const auto diffuse = [](const tracer::Snapshot& s) { return powers(s.pairs.at(0)).diffuse; };
  // The smooth ground first: a tree keyed on the scene alone would then
  // lack the ground's tiles for the rough runs.
  const double s2 = diffuse(tracer::trace_snapshot(kept, second, smooth_ground, {}));
  const double r1 = diffuse(tracer::trace_snapshot(kept, first, rough, {}));
  const double r2 = diffuse(tracer::trace_snapshot(kept, second, rough, {}));
  const double r1_again = diffuse(tracer::trace_snapshot(kept, first, rough, {}));
  tracer::TraceScene fresh_a(sc), fresh_b(sc), fresh_c(sc);
  EXPECT_EQ(r1, r1_again);
  EXPECT_EQ(r1, diffuse(tracer::trace_snapshot(fresh_a, first, rough, {})));
  EXPECT_EQ(s2, diffuse(tracer::trace_snapshot(fresh_b, second, smooth_ground, {})));
  EXPECT_EQ(r2, diffuse(tracer::trace_snapshot(fresh_c, second, rough, {})));
  EXPECT_GT(s2, 0) << "the wall scatters";
  EXPECT_GT(r2, 1.5 * s2) << "the rough ground adds its part";
}

TEST(Diffuse, OneSourceToManyPointsEqualsTheTracedPairs) {
  // diffuse_power (radio maps: one transmitter, many points) gives each
  // point the diffuse power trace_pairs gives the pair, from the same rays.
  meshkit::Scene s;
  add_ground(s, 300);
  add_box_object(s, {10, -20, 0}, {30, -5, 15}, "concrete", "block");
  add_wall_y(s, 25, 200, "brick", "north");
  tracer::TraceScene scene(s);
  const std::vector<tracer::Node> nodes = {node("tx", {0, 0, 6}), node("p1", {40, 3, 1.5}), node("p2", {-30, -2, 2}),
                                           node("p3", {20, 2, 1}), node("p4", {5, 20, 2.5})};
  tracer::TracerConfig cfg;
  cfg.path_threshold_db = 0;         // every diffuse bin kept in the traced pairs
  cfg.diffuse_both_ends = false;     // radio map points do not shoot: the one-sided estimator
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  std::vector<std::uint32_t> points;
  for (std::uint32_t j = 1; j < nodes.size(); ++j) {
    pairs.emplace_back(0, j);
    points.push_back(j);
  }
  const auto snap = tracer::trace_pairs(scene, nodes, pairs, cfg, {});
  const auto power = tracer::diffuse_power(scene, nodes, 0, points, cfg, {});
  ASSERT_EQ(power.size(), points.size());
  for (std::size_t q = 0; q < points.size(); ++q) {
    double traced = 0;
    for (const auto& path : snap.pairs[q].paths)
      if (!path.interactions.empty() && path.interactions.back().type == tracer::InteractionType::diffuse)
        traced += std::norm(path.a);
    EXPECT_GT(traced, 0) << q;
    EXPECT_NEAR(power[q], traced, 1e-9 * traced) << q;
  }
  cfg.diffuse = false;
  for (double p : tracer::diffuse_power(scene, nodes, 0, points, cfg, {})) EXPECT_EQ(p, 0.0);
}

// ---------------------------------------------------------------------------
// 12. Russian roulette on the gathering's shadow rays.

TEST(Diffuse, RouletteIsUnbiasedWithinItsBoundAndSkipsShadowRays) {
  // A threshold above most single samples: they are kept with probability
  // power / threshold and then count the threshold. Against every sample
  // traced, each pair's diffuse power stays within its standard deviation
  // bound sqrt(threshold x power) (the config's 10^(-dB / 20) at the
  // sensitivity), pooled too, and most shadow rays are skipped.
  const tracer::TraceScene scene(street());
  auto nodes = street_nodes();
  nodes.push_back(node("g", {-10, 4, 1.5}));
  nodes.push_back(node("h", {30, -6, 1.5}));
  auto cfg = street_config(4096);
  cfg.diffuse_roulette_db = 300;  // off
  const auto off = tracer::trace_snapshot(scene, nodes, cfg, {});
  const auto p_off = pair_diffuse(off);
  std::vector<double> sorted = p_off;
  std::sort(sorted.begin(), sorted.end());
  const double threshold = sorted[sorted.size() / 2] / 1000;  // the median pair: sigma <= 3.2 %
  ASSERT_GT(threshold, 0);
  tracer::RadioConfig radio;
  radio.tx_power_dbm = 0;
  radio.sensitivity_dbm = 10 * std::log10(threshold);
  cfg.diffuse_roulette_db = 0;
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    return tracer::trace_snapshot(scene, nodes, cfg, radio);
  };
  const auto on = run(2);
  const auto p_on = pair_diffuse(on);
  ASSERT_EQ(p_on.size(), p_off.size());
  double sum_on = 0, sum_off = 0, worst = 0;
  for (std::size_t k = 0; k < p_off.size(); ++k) {
    ASSERT_GT(p_off[k], 0) << "pair " << k;
    const double sigma = std::sqrt(threshold * p_off[k]);
    worst = std::max(worst, std::fabs(p_on[k] - p_off[k]) / sigma);
    EXPECT_LE(std::fabs(p_on[k] - p_off[k]), 4.5 * sigma) << "pair " << k << ": " << p_on[k] << " vs " << p_off[k];
    sum_on += p_on[k];
    sum_off += p_off[k];
  }
  EXPECT_LE(std::fabs(sum_on - sum_off), 4.5 * std::sqrt(threshold * sum_off));
  EXPECT_GT(worst, 0.0) << "the roulette changed nothing: the threshold is below every sample";
  // Shoot rays are the same; shadow rays were skipped.
  std::printf("roulette: rays %llu -> %llu, worst |deviation| %.2f sigma bounds, total %+.3f %%\n",
              static_cast<unsigned long long>(off.stats.rays), static_cast<unsigned long long>(on.stats.rays), worst,
              100 * (sum_on / sum_off - 1));
  EXPECT_LT(on.stats.rays, off.stats.rays * 3 / 4);
  // The same samples whatever the thread count.
  const auto one = run(1);
  EXPECT_EQ(pair_diffuse(one), p_on);
}

// TracerConfig::diffuse_turns: the rays of more lattices gather diffuse
// power, every lattice's samples weighted alike. Without the roulette a
// record's power is linear in its samples, so each pair's diffuse power is
// the mean of the lattices' own estimates (to rounding: the sums run in
// another order), and the paths other than diffuse are the frame's own
// lattice's alone (the other lattices propose nothing).
TEST(Diffuse, MoreLatticesGiveTheMeanOfTheirEstimates) {
  const tracer::TraceScene scene(street());
  const auto nodes = street_nodes();
  auto cfg = street_config(1024);
  cfg.diffuse_roulette_db = 300;  // off
  auto run = [&](std::uint64_t turn, std::vector<std::uint64_t> more) {
    auto c = cfg;
    c.lattice_turn = turn;
    c.diffuse_turns = std::move(more);
    return tracer::trace_snapshot(scene, nodes, c, {});
  };
  const auto one = run(7, {}), mixed = run(7, {8, 9});
  std::vector<double> mean(one.pairs.size(), 0.0);
  for (std::uint64_t turn : {7, 8, 9}) {
    const auto p = pair_diffuse(run(turn, {}));
    for (std::size_t k = 0; k < p.size(); ++k) mean[k] += p[k] / 3;
  }
  const auto got = pair_diffuse(mixed), alone = pair_diffuse(one);
  double moved = 0;
  for (std::size_t k = 0; k < got.size(); ++k) {
    ASSERT_GT(mean[k], 0) << "pair " << k;
    EXPECT_NEAR(got[k] / mean[k], 1.0, 1e-9) << "pair " << k;
    moved = std::max(moved, std::fabs(got[k] / alone[k] - 1));
    // The specular, direct and refracted paths: lattice 7's, bit for bit.
    std::vector<tracer::Path> a, b;
    for (const auto& p : one.pairs[k].paths)
      if (p.origin.kind != tracer::PathOrigin::Kind::diffuse) a.push_back(p);
    for (const auto& p : mixed.pairs[k].paths)
      if (p.origin.kind != tracer::PathOrigin::Kind::diffuse) b.push_back(p);
    ASSERT_EQ(a.size(), b.size()) << "pair " << k;
    for (std::size_t q = 0; q < a.size(); ++q) EXPECT_EQ(a[q].a, b[q].a) << "pair " << k;
  }
  EXPECT_GT(moved, 0.01) << "the lattices' estimates agree: the test shows nothing";
  EXPECT_GT(mixed.stats.rays, one.stats.rays);
}

// Three lattices' samples against one's: over many turns, each pair's
// diffuse power scatters less around a converged estimate (64 x the rays).
// Independent estimates would scatter sqrt(3) x less; the turned lattices
// of one direction set are not independent, so the bound is looser.
TEST(Diffuse, MoreLatticesScatterLessAroundTheConvergedPower) {
  const tracer::TraceScene scene(street());
  const auto nodes = street_nodes();
  auto cfg = street_config(256 * 64);
  cfg.specular = false;
  cfg.refraction = false;
  const auto truth = pair_diffuse(tracer::trace_snapshot(scene, nodes, cfg, {}));
  cfg.rays_per_source = 256;
  double sq1 = 0, sq3 = 0;
  for (std::uint64_t t = 1; t <= 12; ++t) {
    auto c = cfg;
    c.lattice_turn = 3 * t;
    const auto one = pair_diffuse(tracer::trace_snapshot(scene, nodes, c, {}));
    c.diffuse_turns = {3 * t + 1, 3 * t + 2};
    const auto three = pair_diffuse(tracer::trace_snapshot(scene, nodes, c, {}));
    for (std::size_t k = 0; k < truth.size(); ++k) {
      ASSERT_GT(truth[k], 0) << "pair " << k;
      sq1 += std::pow(one[k] / truth[k] - 1, 2);
      sq3 += std::pow(three[k] / truth[k] - 1, 2);
    }
  }
  const double n = 12.0 * static_cast<double>(truth.size());
  std::printf("diffuse power against 64 x the rays, rms relative error: one lattice %.4f, three %.4f\n", std::sqrt(sq1 / n),
              std::sqrt(sq3 / n));
  EXPECT_LT(std::sqrt(sq3 / n), 0.75 * std::sqrt(sq1 / n));
}
