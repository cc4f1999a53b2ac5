// Radio materials: ITU-R P.2040 materials at the carrier, their slab
// thickness and their roughness (the effective roughness model's
// parameters), with the config's overrides.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "tracer/em/constants.hpp"

namespace raysweep::tracer {

// One row of ITU-R P.2040 Table 3: eps_r = a f^b, sigma = c f^d with f in GHz,
// valid for f_min_ghz <= f <= f_max_ghz.
struct P2040Row {
  std::string name;  // meshkit name without "itu_" ("concrete", "medium_dry_ground"...)
  double a, b, c, d;
  double f_min_ghz, f_max_ghz;
};
const std::vector<P2040Row>& p2040_table();

// Diffuse scattering of a rough surface, effective roughness model
// (Degli-Esposti et al., IEEE TAP 55(1), 2007): a fraction S^2 of the power a
// smooth surface would reflect is scattered; of it, a fraction `xpd` goes to
// the cross polarisation. The lobe sets the angular spread:
//  - lambertian: f ~ cos theta_s;
//  - directive: f ~ ((1 + cos psi_R) / 2)^alpha_r around the specular direction;
//  - backscatter: lambda_r of the directive lobe plus (1 - lambda_r) of a lobe
//    ((1 + cos psi_i) / 2)^alpha_i around the direction back to the source.
enum class ScatteringLobe { lambertian, directive, backscatter };
ScatteringLobe parse_scattering_lobe(const std::string& s);  // "lambertian" | "directive" | "backscatter"
const char* scattering_lobe_name(ScatteringLobe l);

struct Scattering {
  double s = 0;    // scattering coefficient S in [0, 1]
  double xpd = 0;  // cross-polarised fraction K_x of the scattered power, [0, 1]
  ScatteringLobe lobe = ScatteringLobe::directive;
  int alpha_r = 4, alpha_i = 4;  // lobe widths (integers 1..20)
  double lambda_r = 0.75;        // backscatter: weight of the specular lobe against the back lobe, [0, 1]
                                 // (both normalised together, as in Degli-Esposti)
};

// Default roughness by material: building facades (concrete, brick) S = 0.4
// and wood, plasterboard, boards S = 0.2 with a directive lobe alpha_r = 4 and
// K_x = 0.1 (Degli-Esposti's urban fits); glass, metal and grounds (smooth at
// a few cm wavelength) and custom materials S = 0.
Scattering default_scattering(const std::string& name);

// A material evaluated at one carrier frequency.
struct RadioMaterial {
  std::string name;
  double eps_r = 1;         // real relative permittivity
  double sigma = 0;         // conductivity, S/m
  double thickness_m = 0;   // slab thickness; 0 = half space (reflects, never transmits)
  double frequency_hz = 0;  // the carrier it was evaluated at
  Scattering scattering;
  // Complex relative permittivity eps_r - j sigma / (2 pi f eps0).
  cdouble eta() const;
};

// Config overrides of a material ([materials.<name>] in the TOML config).
struct MaterialOverride {
  std::optional<double> eps_r, sigma, thickness_m;
  std::optional<double> scattering_coefficient, xpd, lambda_r;
  std::optional<ScatteringLobe> lobe;
  std::optional<int> alpha_r, alpha_i;
};

// Default slab thickness by name: glass 5 mm, concrete 0.3 m, brick 0.25 m,
// plasterboard 12.5 mm, wood 40 mm, ceiling board / chipboard / floorboard
// 20 mm, metal 2 mm, grounds 0 (half space); custom materials: their own.
double default_thickness_m(const std::string& name);

// The material `name` (a P.2040 name or a meshkit custom material) at
// `frequency_hz`. Throws std::invalid_argument naming the material and its
// validity range when the frequency is outside it, or when the name is
// unknown. Overrides replace the computed values (an override of both eps_r
// and sigma lifts the validity check).
RadioMaterial radio_material(const std::string& name, double frequency_hz, const MaterialOverride& override = {});

}  // namespace raysweep::tracer
