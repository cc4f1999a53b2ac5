#include "em/utd.hpp"

#include <algorithm>
#include <cmath>

#include "tracer/em/coefficients.hpp"

namespace raysweep::tracer {

namespace {

// erfc(z) for z = r e^{j pi/4}, r >= 0 (the ray the Fresnel integrals live
// on): Maclaurin series of erf for small |z| (terms stay below e^{|z|^2}, so
// about 4 digits are lost at |z| = 3), the Laplace continued fraction
// (modified Lentz) beyond.
cdouble erfc_diagonal(cdouble z) {
  const double r = std::abs(z);
  if (r < 3.0) {
    const cdouble z2 = z * z;
    cdouble term = z, sum = z;  // term = (-1)^n z^{2n+1} / n!
    for (int k = 1; k < 200; ++k) {
      term *= -z2 / static_cast<double>(k);
      const cdouble add = term / (2.0 * k + 1);
      sum += add;
      if (std::abs(add) < 1e-17 * std::abs(sum)) break;
    }
    return 1.0 - (2.0 / std::sqrt(kPi)) * sum;
  }
  // erfc z = e^{-z^2}/sqrt(pi) * 1/(z + (1/2)/(z + 1/(z + (3/2)/(z + ...)))).
  const double tiny = 1e-300;
  cdouble f = z, c = z, d = 0.0;
  for (int k = 1; k < 5000; ++k) {
    const double a = k / 2.0;
    d = z + a * d;
    if (std::abs(d) < tiny) d = tiny;
    c = z + a / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const cdouble delta = c * d;
    f *= delta;
    if (std::abs(delta - 1.0) < 1e-16) break;
  }
  return std::exp(-z * z) / (std::sqrt(kPi) * f);
}

// G(x) = int_x^inf e^{-j pi t^2 / 2} dt = (1 - j)/2 erfc(sqrt(pi)/2 (1 + j) x), x >= 0.
cdouble fresnel_tail(double x) {
  const cdouble z = (std::sqrt(kPi) / 2) * cdouble(1, 1) * x;
  return cdouble(0.5, -0.5) * erfc_diagonal(z);
}

}  // namespace

std::pair<double, double> fresnel_cs(double x) {
  const double ax = std::fabs(x);
  const cdouble g = fresnel_tail(ax);  // (1/2 - C) - j (1/2 - S)
  const double c = 0.5 - g.real(), s = 0.5 + g.imag();
  return x < 0 ? std::pair{-c, -s} : std::pair{c, s};
}

cdouble utd_transition(double x) {
  if (!(x > 0)) return 0.0;
  // Far from the shadow and reflection boundaries (most terms of most
  // paths: kL is hundreds to thousands) the asymptotic series
  // F(x) ~ sum_m (2m - 1)!! (j / 2x)^m: its terms shrink while 2m + 1 < 2x,
  // and from x = 40 on they fall below 1e-16 before turning (the smallest
  // is about e^-x), so the sum is as exact as the continued fraction
  // below without its complex divisions, exponential and hypot (a
  // snapshot's diffraction: 0.78-0.88 of its thread time; docs/tracer.md).
  if (x >= 40) {
    const double h = 0.5 / x;
    double re = 1, im = 0, t = 1;  // t = (2m - 1)!! h^m
    for (int m = 1; m < 64; ++m) {
      t *= (2 * m - 1) * h;
      switch (m & 3) {  // j^m
        case 1: im += t; break;
        case 2: re -= t; break;
        case 3: im -= t; break;
        default: re += t; break;
      }
      if (t < 1e-17) break;
    }
    return {re, im};
  }
  const double u = std::sqrt(x);
  // int_u^inf e^{-j t^2} dt = sqrt(pi/2) G(u sqrt(2/pi)).
  const cdouble tail = std::sqrt(kPi / 2) * fresnel_tail(u * std::sqrt(2 / kPi));
  return cdouble(0, 2) * u * std::polar(1.0, x) * tail;
}

namespace {

// One cot * F term's geometry: N, the integer most nearly satisfying
// 2 pi n N - beta = sign * pi; eps, 0 on the shadow or reflection boundary;
// a = a^{sign}(beta), F's argument over kL; and the cotangent's angle.
struct CotTerm {
  double eps, a, angle;
};
CotTerm cot_term(int sign, double beta, double n) {
  const double N = std::round((sign * kPi + beta) / (2 * kPi * n));
  return {kPi + sign * (beta - 2 * kPi * n * N), 2 * std::pow(std::cos((2 * kPi * n * N - beta) / 2), 2),
          (kPi + sign * beta) / (2 * n)};
}
// Within this of a boundary the term takes its finite limit.
constexpr double kBoundaryEps = 1e-5;

// cot((pi + sign*beta)/(2n)) F(kL a^{sign}(beta)), with the finite limit
// n [sqrt(2 pi kL) sgn(eps) - 2 kL eps e^{j pi/4}] e^{j pi/4} close to the
// boundary where eps -> 0 (Kouyoumjian and Pathak's eq. for the transition
// region), so a receiver on a shadow or reflection boundary gets a finite
// coefficient.
cdouble cot_f(int sign, double beta, double n, double kL) {
  const CotTerm t = cot_term(sign, beta, n);
  if (std::fabs(t.eps) < kBoundaryEps) {
    const cdouble ej = std::polar(1.0, kPi / 4);
    return n * (std::sqrt(2 * kPi * kL) * (t.eps >= 0 ? 1.0 : -1.0) - 2 * kL * t.eps * ej) * ej;
  }
  return utd_transition(kL * t.a) / std::tan(t.angle);
}

// A bound on |cot_f|: |F(x)| <= min(1, sqrt(pi x)) (F(x) = 2j sqrt(x) e^{jx}
// times a Fresnel tail of modulus at most sqrt(pi) / 2, and |F| rises to 1).
double cot_f_bound(int sign, double beta, double n, double kL) {
  const CotTerm t = cot_term(sign, beta, n);
  if (std::fabs(t.eps) < kBoundaryEps) return n * (std::sqrt(2 * kPi * kL) + 2 * kL * std::fabs(t.eps));
  return std::min(1.0, std::sqrt(kPi * kL * t.a)) / std::fabs(std::tan(t.angle));
}

}  // namespace

double utd_wedge_bound(double n, double phi_i, double phi_d, double beta0, double L, double k) {
  const double kL = k * L;
  const double pre = 1 / (2 * n * std::sqrt(2 * kPi * k) * std::fabs(std::sin(beta0)));
  const double dm = phi_d - phi_i, dp = phi_d + phi_i;
  const double sum = cot_f_bound(+1, dm, n, kL) + cot_f_bound(-1, dm, n, kL) + cot_f_bound(-1, dp, n, kL) +
                     cot_f_bound(+1, dp, n, kL);
  return (1 + 1e-9) * pre * sum;  // the margin covers rounding
}

DiffractionCoefficients utd_wedge(double n, double phi_i, double phi_d, double beta0, double L, double k,
                                  const RadioMaterial* face0, const RadioMaterial* face_n, double keep0,
                                  double keep_n) {
  const double kL = k * L;
  const double sb = std::sin(beta0);
  const cdouble pre = -std::polar(1.0, -kPi / 4) / (2 * n * std::sqrt(2 * kPi * k) * sb);
  const double dm = phi_d - phi_i, dp = phi_d + phi_i;
  const cdouble t1 = cot_f(+1, dm, n, kL), t2 = cot_f(-1, dm, n, kL);
  const cdouble t3 = cot_f(-1, dp, n, kL), t4 = cot_f(+1, dp, n, kL);
  // Luebbers: face 0 seen at the grazing angle phi_i, face n at n pi - phi_d.
  // That rule is not reciprocal (swapping the ends swaps the angles), so each
  // face takes the mean of its coefficients at the grazing angles of the ends
  // that see it (angle from the face in (0, pi)), or of both when neither
  // does. At a face's reflection boundary both ends see it at angles of equal
  // sine, so the boundary values, hence continuity, are Luebbers'.
  auto refl = [&](const RadioMaterial* m, double a, double b) -> TeTm {
    if (!m) return {-1.0, 1.0};
    auto at = [&](double grazing) {
      return slab_reflection(*m, std::clamp(sb * std::fabs(std::sin(grazing)), 0.0, 1.0));
    };
    const bool sa = a > 0 && a < kPi, sb_ = b > 0 && b < kPi;
    if (sa != sb_) return at(sa ? a : b);
    const TeTm x = at(a), y = at(b);
    return {0.5 * (x.te + y.te), 0.5 * (x.tm + y.tm)};
  };
  TeTm r0 = refl(face0, phi_i, phi_d);
  TeTm rn = refl(face_n, n * kPi - phi_d, n * kPi - phi_i);
  r0 = {keep0 * r0.te, keep0 * r0.tm};
  rn = {keep_n * rn.te, keep_n * rn.tm};
  return {pre * (t1 + t2 + r0.te * t3 + rn.te * t4), pre * (t1 + t2 + r0.tm * t3 + rn.tm * t4)};
}

}  // namespace raysweep::tracer
