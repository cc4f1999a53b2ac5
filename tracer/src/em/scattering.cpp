#include "em/scattering.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace raysweep::tracer {

namespace {

double ipow(double x, int n) {
  double r = 1;
  for (; n > 0; n >>= 1, x *= x)
    if (n & 1) r *= x;
  return r;
}

// The factors of lobe_integral_cos's sum that do not depend on the angle,
// for one alpha: C(alpha, j), 2 pi / (j + 1), C(2w, w) and 2^alpha, by the
// recurrences the sum once ran on every call, so it gives the same bits.
// Every view of a diffuse tile and every rough-surface hit builds a lobe,
// and these divisions were most of its cost.
struct LobeTerms {
  std::vector<double> binom, ij, cw;
  double pow2 = 1;
};

LobeTerms lobe_terms(int alpha) {
  LobeTerms t;
  double binom = 1, cw = 1;
  for (int j = 0; j <= alpha; ++j) {
    t.binom.push_back(binom);
    t.ij.push_back(2 * kPi / (j + 1));
    binom = binom * (alpha - j) / (j + 1.0);
  }
  for (int w = 0; w <= (alpha - 1) / 2; ++w) {
    t.cw.push_back(cw);
    cw = cw * (2.0 * w + 1) * (2.0 * w + 2) / ((w + 1.0) * (w + 1.0));
  }
  t.pow2 = ipow(2.0, alpha);
  return t;
}

// Tabled up to this alpha (the config allows 1..20); beyond, built per call.
constexpr int kTabledAlpha = 64;

// lobe_integral with theta given by its cosine.
double lobe_integral_cos(int alpha, double ct) {
  // ((1 + cos psi)/2)^alpha = 2^-alpha sum_j C(alpha, j) cos^j psi, and the
  // hemisphere integral of cos^j psi is 2 pi / (j + 1) for even j and
  // 2 pi / (j + 1) cos(theta) sum_{w <= (j-1)/2} C(2w, w) sin^2w(theta) / 4^w
  // for odd j (Degli-Esposti et al. 2007, eq. 9).
  static const std::vector<LobeTerms> table = [] {
    std::vector<LobeTerms> t;
    for (int a = 0; a <= kTabledAlpha; ++a) t.push_back(lobe_terms(a));
    return t;
  }();
  LobeTerms own;
  const bool tabled = alpha >= 0 && alpha <= kTabledAlpha;
  if (!tabled) own = lobe_terms(alpha);
  const LobeTerms& t = tabled ? table[static_cast<std::size_t>(alpha)] : own;
  const double st2 = std::max(0.0, 1 - ct * ct);
  // The odd terms' inner sums are prefixes of one sum: each odd j adds the
  // term w = (j - 1) / 2 to the previous one's.
  double sum = 0, inner = 0, pw = 1;  // pw = (sin^2 / 4)^w
  std::size_t w = 0;
  for (int j = 0; j <= alpha; ++j) {
    const auto uj = static_cast<std::size_t>(j);
    double ij = t.ij[uj];
    if (j % 2) {
      inner += t.cw[w++] * pw;
      pw *= st2 / 4;
      ij *= ct * inner;
    }
    sum += t.binom[uj] * ij;
  }
  return sum / t.pow2;
}

}  // namespace

double lobe_integral(int alpha, double theta) { return lobe_integral_cos(alpha, std::cos(theta)); }

ScatteringLobeAt::ScatteringLobeAt(const Scattering& sc, const Vec3& k_in, const Vec3& n_any) : sc_(&sc), k_in_(k_in) {
  // The front side is where the incident wave comes from.
  n_ = dot(k_in, n_any) < 0 ? n_any : -n_any;
  const double cos_i = std::clamp(-dot(k_in, n_), 0.0, 1.0);
  spec_ = k_in + (2 * cos_i) * n_;
  if (sc.lobe == ScatteringLobe::lambertian) inv_norm_ = 1 / kPi;
  else if (sc.lobe == ScatteringLobe::directive) inv_norm_ = 1 / lobe_integral_cos(sc.alpha_r, cos_i);
  // The back lobe points along -k_in, also theta_i from the normal.
  else
    inv_norm_ = 1 / (sc.lambda_r * lobe_integral_cos(sc.alpha_r, cos_i) +
                     (1 - sc.lambda_r) * lobe_integral_cos(sc.alpha_i, cos_i));
}

double ScatteringLobeAt::operator()(const Vec3& k_out) const {
  const double cos_s = dot(k_out, n_);
  if (!(cos_s > 0)) return 0;
  if (sc_->lobe == ScatteringLobe::lambertian) return cos_s * inv_norm_;
  const double lobe_r = ipow((1 + std::clamp(dot(k_out, spec_), -1.0, 1.0)) / 2, sc_->alpha_r);
  if (sc_->lobe == ScatteringLobe::directive) return lobe_r * inv_norm_;
  const double lobe_i = ipow((1 + std::clamp(-dot(k_out, k_in_), -1.0, 1.0)) / 2, sc_->alpha_i);
  return (sc_->lambda_r * lobe_r + (1 - sc_->lambda_r) * lobe_i) * inv_norm_;
}

double scattering_pattern(const Scattering& sc, const Vec3& k_in, const Vec3& k_out, const Vec3& n_any) {
  return ScatteringLobeAt(sc, k_in, n_any)(k_out);
}

}  // namespace raysweep::tracer
