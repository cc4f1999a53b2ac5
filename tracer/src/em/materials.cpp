#include "tracer/em/materials.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "meshkit/materials.hpp"

namespace raysweep::tracer {

namespace {

// "itu_concrete", "mat-itu_concrete", "concrete", "rubber" -> canonical name.
std::string canonical_name(const std::string& name) {
  if (auto n = meshkit::radio_material_from_id(name)) return *n;
  throw std::invalid_argument("unknown radio material '" + name + "'");
}

const P2040Row* find_p2040(const std::string& name) {
  for (const auto& row : p2040_table())
    if (row.name == name) return &row;
  return nullptr;
}

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

const std::vector<P2040Row>& p2040_table() {
  // ITU-R P.2040-2/-3 Table 3 (the -1 edition had e.g. concrete 5.31/0.0326/
  // 0.8095; the later fits are the ones Sionna RT ships, so scenes agree).
  static const std::vector<P2040Row> table = {
      {"concrete", 5.24, 0.0, 0.0462, 0.7822, 1, 100},
      {"brick", 3.91, 0.0, 0.0238, 0.16, 1, 40},
      {"plasterboard", 2.73, 0.0, 0.0085, 0.9395, 1, 100},
      {"wood", 1.99, 0.0, 0.0047, 1.0718, 0.001, 100},
      {"glass", 6.31, 0.0, 0.0036, 1.3394, 0.1, 100},
      {"ceiling_board", 1.48, 0.0, 0.0011, 1.0750, 1, 100},
      {"chipboard", 2.58, 0.0, 0.0217, 0.7800, 1, 100},
      {"floorboard", 3.66, 0.0, 0.0044, 1.3515, 50, 100},
      {"metal", 1.0, 0.0, 1e7, 0.0, 1, 100},
      {"very_dry_ground", 3.0, 0.0, 0.00015, 2.52, 1, 10},
      {"medium_dry_ground", 15.0, -0.1, 0.035, 1.63, 1, 10},
      {"wet_ground", 30.0, -0.4, 0.15, 1.30, 1, 10},
  };
  return table;
}

cdouble RadioMaterial::eta() const {
  if (sigma == 0) return {eps_r, 0.0};
  if (!(frequency_hz > 0))
    throw std::invalid_argument("material '" + name + "': conductive material needs a positive frequency");
  return {eps_r, -sigma / (2 * kPi * frequency_hz * kVacuumPermittivity)};
}

double default_thickness_m(const std::string& name) {
  const std::string n = canonical_name(name);
  if (const auto* c = meshkit::find_custom_material(n)) return c->thickness_m;
  if (n == "glass") return 0.005;
  if (n == "concrete") return 0.3;
  if (n == "brick") return 0.25;
  if (n == "plasterboard") return 0.0125;
  if (n == "wood") return 0.04;
  if (n == "ceiling_board" || n == "chipboard" || n == "floorboard") return 0.02;
  if (n == "metal") return 0.002;
  if (n == "very_dry_ground" || n == "medium_dry_ground" || n == "wet_ground") return 0.0;
  throw std::invalid_argument("no default thickness for radio material '" + n + "'");
}

RadioMaterial radio_material(const std::string& name, double frequency_hz, const MaterialOverride& override) {
  RadioMaterial m;
  m.name = canonical_name(name);
  m.frequency_hz = frequency_hz;
  if (!std::isfinite(frequency_hz) || frequency_hz <= 0)
    throw std::invalid_argument("material '" + m.name + "': invalid frequency " + fmt(frequency_hz) + " Hz");

  const bool fully_overridden = override.eps_r && override.sigma;
  if (const auto* c = meshkit::find_custom_material(m.name)) {
    m.eps_r = c->eps_r;
    m.sigma = c->sigma_s_per_m;
  } else if (!fully_overridden) {
    const P2040Row* row = find_p2040(m.name);
    if (!row) throw std::invalid_argument("radio material '" + m.name + "' has no ITU-R P.2040 parameters");
    const double f_ghz = frequency_hz / 1e9;
    // The relative slack keeps band edges given as e.g. 10e9 Hz inside.
    const double slack = 1e-9;
    if (f_ghz < row->f_min_ghz * (1 - slack) || f_ghz > row->f_max_ghz * (1 + slack))
      throw std::invalid_argument("material '" + m.name + "': ITU-R P.2040 parameters are valid for " +
                                  fmt(row->f_min_ghz) + "-" + fmt(row->f_max_ghz) + " GHz, not " + fmt(f_ghz) +
                                  " GHz (override eps_r and sigma to use it there)");
    m.eps_r = row->a * std::pow(f_ghz, row->b);
    m.sigma = row->c * std::pow(f_ghz, row->d);
  }
  m.thickness_m = default_thickness_m(m.name);
  if (override.eps_r) m.eps_r = *override.eps_r;
  if (override.sigma) m.sigma = *override.sigma;
  if (override.thickness_m) m.thickness_m = *override.thickness_m;
  m.scattering = default_scattering(m.name);
  auto& sc = m.scattering;
  if (override.scattering_coefficient) sc.s = *override.scattering_coefficient;
  if (override.xpd) sc.xpd = *override.xpd;
  if (override.lobe) sc.lobe = *override.lobe;
  if (override.alpha_r) sc.alpha_r = *override.alpha_r;
  if (override.alpha_i) sc.alpha_i = *override.alpha_i;
  if (override.lambda_r) sc.lambda_r = *override.lambda_r;
  auto unit = [&](double v, const char* what) {
    if (!(v >= 0 && v <= 1))
      throw std::invalid_argument("material '" + m.name + "': " + what + " must be within [0, 1], got " + fmt(v));
  };
  unit(sc.s, "scattering_coefficient");
  unit(sc.xpd, "xpd");
  unit(sc.lambda_r, "lambda_r");
  for (int a : {sc.alpha_r, sc.alpha_i})
    if (a < 1 || a > 20)
      throw std::invalid_argument("material '" + m.name + "': alpha_r and alpha_i must be within 1..20, got " +
                                  std::to_string(a));

  if (!std::isfinite(m.eps_r) || m.eps_r < 1)
    throw std::invalid_argument("material '" + m.name + "': eps_r must be finite and >= 1, got " + fmt(m.eps_r));
  if (!std::isfinite(m.sigma) || m.sigma < 0)
    throw std::invalid_argument("material '" + m.name + "': sigma must be finite and >= 0, got " + fmt(m.sigma));
  if (!std::isfinite(m.thickness_m) || m.thickness_m < 0)
    throw std::invalid_argument("material '" + m.name + "': thickness must be finite and >= 0, got " +
                                fmt(m.thickness_m));
  return m;
}

ScatteringLobe parse_scattering_lobe(const std::string& s) {
  if (s == "lambertian") return ScatteringLobe::lambertian;
  if (s == "directive") return ScatteringLobe::directive;
  if (s == "backscatter") return ScatteringLobe::backscatter;
  throw std::invalid_argument("unknown scattering lobe '" + s + "' (expected lambertian, directive or backscatter)");
}
const char* scattering_lobe_name(ScatteringLobe l) {
  switch (l) {
    case ScatteringLobe::lambertian: return "lambertian";
    case ScatteringLobe::directive: return "directive";
    case ScatteringLobe::backscatter: return "backscatter";
  }
  return "?";
}
Scattering default_scattering(const std::string& name) {
  Scattering sc;
  if (name == "concrete" || name == "brick") sc.s = 0.4;
  else if (name == "wood" || name == "plasterboard" || name == "ceiling_board" || name == "chipboard" ||
           name == "floorboard")
    sc.s = 0.2;
  else
    return sc;
  sc.xpd = 0.1;
  sc.lobe = ScatteringLobe::directive;
  sc.alpha_r = 4;
  return sc;
}

}  // namespace raysweep::tracer
