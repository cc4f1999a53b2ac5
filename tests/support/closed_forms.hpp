// Independent references for the tracer tests, written out from the
// formulas (never calling the tracer's own electromagnetics): ITU-R P.2040
// interface and single-layer slab coefficients, and Gauss-Legendre
// quadrature for the integrals the diffraction and diffuse tests check.
#pragma once

#include <cmath>
#include <complex>
#include <vector>

namespace raysweep::test::closed_form {

using cd = std::complex<double>;
inline constexpr double kPi = 3.14159265358979323846;

// Fresnel (P.2040 eqs. 31): air / half space, c = cosine of the incidence angle.
inline cd r_te(cd eta, double c) {
  const cd s = std::sqrt(eta - (1 - c * c));
  return (c - s) / (c + s);
}
inline cd r_tm(cd eta, double c) {
  const cd s = std::sqrt(eta - (1 - c * c));
  return (eta * c - s) / (eta * c + s);
}

// Single-layer slab of thickness d (P.2040 eqs. 43) at wavelength lambda.
struct Slab {
  cd r, t;
};
inline Slab slab(cd eta, double d, double c, bool te, double lambda) {
  const cd rp = te ? r_te(eta, c) : r_tm(eta, c);
  const cd q = 2 * kPi * d / lambda * std::sqrt(eta - (1 - c * c));
  const double q0 = 2 * kPi * d / lambda * c;
  const cd e2 = std::exp(cd(0, -2) * q);
  const cd den = 1.0 - rp * rp * e2;
  return {rp * (1.0 - e2) / den, (1.0 - rp * rp) * std::exp(cd(0, -1) * (q - q0)) / den};
}

// n-point Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_n).
struct GaussLegendre {
  std::vector<double> x, w;
  explicit GaussLegendre(int n) {
    x.resize(n);
    w.resize(n);
    for (int i = 0; i < n; ++i) {
      double z = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 0;
      for (int it = 0; it < 100; ++it) {
        double p0 = 1, p1 = z;
        for (int j = 2; j <= n; ++j) {
          const double p2 = ((2.0 * j - 1) * z * p1 - (j - 1.0) * p0) / j;
          p0 = p1;
          p1 = p2;
        }
        dp = n * (z * p1 - p0) / (z * z - 1);
        const double dz = p1 / dp;
        z -= dz;
        if (std::fabs(dz) < 1e-16) break;
      }
      x[i] = z;
      w[i] = 2 / ((1 - z * z) * dp * dp);
    }
  }
};
inline const GaussLegendre& gl20() {
  static const GaussLegendre g(20);
  return g;
}

}  // namespace raysweep::test::closed_form
