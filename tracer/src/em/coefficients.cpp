#include "tracer/em/coefficients.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace raysweep::tracer {

namespace {

// sqrt(eta - sin^2 theta): the principal root has Re >= 0 and, because
// Im(eta) <= 0, Im <= 0, so exp(-j k0 d s) decays inside a lossy slab.
cdouble normal_wavenumber_ratio(cdouble eta, double cos_theta) {
  const double sin2 = (1 - cos_theta) * (1 + cos_theta);
  return std::sqrt(eta - sin2);
}

TeTm interface_from_root(cdouble eta, double c, cdouble s) {
  const cdouble te_den = c + s;
  const cdouble tm_den = eta * c + s;
  // Both vanish only for eta = 1 at grazing: no contrast, no reflection
  // (the limit along any other angle).
  if (te_den == 0.0 || tm_den == 0.0) return {0.0, 0.0};
  return {(c - s) / te_den, (eta * c - s) / tm_den};
}

}  // namespace

TeTm interface_reflection(cdouble eta, double cos_theta) {
  const double c = std::clamp(cos_theta, 0.0, 1.0);
  return interface_from_root(eta, c, normal_wavenumber_ratio(eta, c));
}

namespace {

// slab_coefficients, with the transmission when kTransmission: one body, so
// the reflection is the same arithmetic either way.
template <bool kTransmission>
SlabCoefficients slab(const RadioMaterial& m, double cos_theta) {
  const double c = std::clamp(cos_theta, 0.0, 1.0);
  const cdouble eta = m.eta();
  const cdouble s = normal_wavenumber_ratio(eta, c);
  const TeTm r_if = interface_from_root(eta, c, s);
  // A half space never transmits; at exact grazing the slab formula is 0/0
  // for a lossless slab whose q is a multiple of pi, and its limit is the
  // interface value (R' = -1 -> R = -1, T = 0) for every other q.
  if (m.thickness_m == 0) return {r_if, {0.0, 0.0}};
  if (c == 0) return {r_if, eta == 1.0 ? TeTm{1.0, 1.0} : TeTm{0.0, 0.0}};
  if (!(m.frequency_hz > 0))
    throw std::invalid_argument("material '" + m.name + "': a slab needs a positive frequency");

  const double k0d = 2 * kPi * m.frequency_hz / kSpeedOfLight * m.thickness_m;
  const cdouble q = k0d * s;
  // Written out as exp(real) * phase so the decaying factors underflow to 0
  // (metal: Im q ~ -1e3) instead of forming inf * 0 anywhere.
  const cdouble e2 = std::polar(std::exp(2 * q.imag()), -2 * q.real());  // e^{-j2q}
  auto reflection = [&](cdouble rp, cdouble& den) {
    const cdouble rp2 = rp * rp;
    den = 1.0 - rp2 * e2;
    return rp * (1.0 - e2) / den;
  };
  cdouble den_te, den_tm;
  const TeTm r{reflection(r_if.te, den_te), reflection(r_if.tm, den_tm)};
  if constexpr (!kTransmission) {
    return {r, {0.0, 0.0}};
  } else {
    const double q0 = k0d * c;
    const cdouble e1 = std::polar(std::exp(q.imag()), -(q.real() - q0));  // e^{-j(q-q0)}
    auto transmission = [&](cdouble rp, cdouble den) { return (1.0 - rp * rp) * e1 / den; };
    return {r, {transmission(r_if.te, den_te), transmission(r_if.tm, den_tm)}};
  }
}

}  // namespace

SlabCoefficients slab_coefficients(const RadioMaterial& m, double cos_theta) { return slab<true>(m, cos_theta); }

TeTm slab_reflection(const RadioMaterial& m, double cos_theta) { return slab<false>(m, cos_theta).r; }

Electromagnetics::Electromagnetics(const std::vector<std::string>& names, const RadioConfig& radio,
                                   const std::map<std::string, MaterialOverride>& overrides, bool rough)
    : radio_(radio) {
  for (const auto& name : names) {
    auto it = overrides.find(name);
    materials_.push_back(radio_material(name, radio.frequency_hz, it == overrides.end() ? MaterialOverride{} : it->second));
    const auto c = slab_coefficients(materials_.back(), 1.0);
    const double t = std::max(std::abs(c.t.te), std::abs(c.t.tm));
    opaque_.push_back(t < 1e-12);
    normal_loss_db_.push_back(t > 0 ? -20 * std::log10(t) : 1e300);
    const double S = materials_.back().scattering.s;
    keep_.push_back(rough ? std::sqrt(1 - S * S) : 1.0);
  }
}

SlabCoefficients Electromagnetics::coefficients(std::uint16_t i, double cos_theta) const {
  return slab_coefficients(materials_.at(i), std::clamp(cos_theta, 0.0, 1.0));
}

TeTm Electromagnetics::reflection(std::uint16_t i, double cos_theta) const {
  return slab_reflection(materials_.at(i), std::clamp(cos_theta, 0.0, 1.0));
}

}  // namespace raysweep::tracer
