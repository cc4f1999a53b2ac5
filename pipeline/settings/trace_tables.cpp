#include "pipeline/settings/tables.hpp"

#include "meshkit/materials.hpp"
#include "pipeline/settings/trace.hpp"
#include "pipeline/settings/values.hpp"

namespace raysweep::pipeline {

using json = nlohmann::json;
using namespace schema;

// --- [radio], [tracer], [materials.<name>] ----------------------------------

const Table<TraceSettings>& radio_table() {
  static const Table<TraceSettings> t = [] {
    Table<TraceSettings> t("radio", "The radio link every stage traces: carrier, band, power, antennas.");
    t.key("frequency_hz", number(above(0)), FIELD(radio.frequency_hz), "Hz", "carrier frequency");
    t.key("bandwidth_hz", number(above(0)), FIELD(radio.bandwidth_hz), "Hz", "channel bandwidth");
    t.key("tx_power_dbm", number(), FIELD(radio.tx_power_dbm), "dBm",
          "transmit power (recorded; path gains do not depend on it)");
    t.key("sensitivity_dbm", number(), FIELD(radio.sensitivity_dbm), "dBm",
          "with tx power, antenna gains and range_margin_db: the distance beyond which pairs are not traced");
    t.key("antenna",
          enumeration<tracer::AntennaPattern>({{"isotropic", tracer::AntennaPattern::isotropic},
                                               {"dipole", tracer::AntennaPattern::short_dipole},
                                               {"halfwave", tracer::AntennaPattern::halfwave_dipole}}),
          FIELD(radio.antenna.pattern), "", "antenna pattern at every node (dipole: short dipole)");
    t.key("polarization", enumeration<tracer::Polarization>({{"V", tracer::Polarization::V}, {"H", tracer::Polarization::H}}),
          FIELD(radio.antenna.polarization), "", "antenna polarization");
    return t;
  }();
  return t;
}

const Table<TraceSettings>& tracer_table() {
  // Where a switch matters (its tradeoff study runs only there).
  static const auto rays_diffuse = [](const TraceSettings& c) {
    return c.tracer.diffuse && c.tracer.diffuse_integration == tracer::DiffuseIntegration::rays;
  };
  static const auto image_search = [](int depth) {
    return [depth](const TraceSettings& c) {
      return c.tracer.candidates == tracer::CandidateSearch::image && c.tracer.max_depth >= depth;
    };
  };
  static const Table<TraceSettings> t = [] {
    Table<TraceSettings> t("tracer", "The path solver (docs/tracer.md).");
    t.key("max_depth", integer<int>(between(0, tracer::kMaxDepth)), FIELD(tracer.max_depth), "",
          "specular reflections per path");
    t.key("los", boolean(), FIELD(tracer.los), "", "trace the direct path");
    t.key("specular", boolean(), FIELD(tracer.specular), "", "trace specular reflections");
    t.key("refraction", boolean(), FIELD(tracer.refraction), "", "transmission through slabs, without bending");
    t.toggle("refraction");
    t.key("rays_per_source", integer<int>(at_least(1)), FIELD(tracer.rays_per_source), "",
          "shoot-and-bounce rays per antenna (orders the image search does not cover)");
    t.key("lattice_turn", integer<std::uint64_t>(), FIELD(tracer.lattice_turn), "",
          "the ray lattice turned by the rotation this number draws (0: not turned; an equally good lattice "
          "with other directions; sweeps with lattice_frames > 1 turn it every frame)");
    t.key("vehicle_bundles", boolean(), FIELD(tracer.vehicle_bundles), "",
          "shoot-and-bounce rays aimed at each vehicle the lattice covers sparsely, from each antenna and through "
          "the static faces whose beams reach it (chains of two vehicles, a cabin then another vehicle)");
    t.toggle("vehicle bundles", image_search(2));
    t.key("vehicle_bundle_rays", integer<int>(at_least(1)), FIELD(tracer.vehicle_bundle_rays), "",
          "vehicle bundles: rays per vehicle and source (or face), when the lattice gives the vehicle fewer");
    t.key("vehicle_bundles_via_faces", boolean(), FIELD(tracer.vehicle_bundles_via_faces), "",
          "vehicle bundles also through the static faces whose beams reach a vehicle (a wall, then two vehicles)");
    t.toggle("vehicle bundles via faces",
             [](const TraceSettings& c) { return c.tracer.vehicle_bundles && image_search(2)(c); });
    t.key("reception_radius_factor", number(above(0)), FIELD(tracer.reception_radius_factor), "",
          "reception sphere radius over the rays' angular spacing times the unfolded length");
    t.key("candidates",
          enumeration<tracer::CandidateSearch>({{"image", tracer::CandidateSearch::image},
                                                {"sbr", tracer::CandidateSearch::sbr},
                                                {"exhaustive", tracer::CandidateSearch::exhaustive}}),
          FIELD(tracer.candidates), "",
          "image: exact image search + shoot and bounce; sbr: sampling alone; exhaustive: reference, small scenes only");
    t.key("max_transmissions", integer<int>(at_least(0)), FIELD(tracer.max_transmissions), "",
          "slabs a path may cross; paths over the cap are dropped and counted");
    t.key("sbr_transmission_loss_db", number(at_least(0)), FIELD(tracer.sbr_transmission_loss_db), "dB",
          "search rays continue through slabs within this loss budget");
    t.key("diffuse", boolean(), FIELD(tracer.diffuse), "", "effective-roughness diffuse scattering");
    t.toggle("diffuse");
    t.key("diffuse_integration",
          enumeration<tracer::DiffuseIntegration>({{"tiles", tracer::DiffuseIntegration::tiles},
                                                   {"rays", tracer::DiffuseIntegration::rays},
                                                   {"hybrid", tracer::DiffuseIntegration::hybrid}}),
          FIELD(tracer.diffuse_integration), "",
          "tiles: deterministic, first order; rays: over the shoot-and-bounce hits, any order; hybrid: tiles for "
          "the first order, rays for scattering next to reflections and slabs");
    t.key("diffuse_tile_m", number(above(0)), FIELD(tracer.diffuse_tile_m), "m", "tiles: the finest tile's edge");
    t.key("diffuse_tile_ratio", number(above(0)), FIELD(tracer.diffuse_tile_ratio), "",
          "tiles: largest tile over its distance");
    t.key("diffuse_shadow_ratio", number(at_least(0)), FIELD(tracer.diffuse_shadow_ratio), "",
          "tiles: shadow edges refined to this ratio of the distance (0: to diffuse_tile_m)");
    t.key("diffuse_both_ends", boolean(), FIELD(tracer.diffuse_both_ends), "",
          "rays: both ends' rays gather (first order weighted by the balance heuristic; scattering before "
          "reflections from the end that reaches it); false: the lower end's rays alone");
    t.toggle("", rays_diffuse, "diffuse one end", "diffuse both ends");
    t.key("diffuse_roulette_db", number(at_least(0)), FIELD(tracer.diffuse_roulette_db), "dB",
          "rays: samples this far below the sensitivity (|a|^2 under sensitivity - tx power) play Russian "
          "roulette before their shadow ray (unbiased; >= 300: off)");
    t.key("vehicle_multi_bounce", boolean(), FIELD(tracer.vehicle_multi_bounce), "",
          "image search: two and three reflections on one vehicle from a per-model table of multi-bounce sequences");
    t.toggle("vehicle multi-bounce", image_search(2));
    t.key("ground_order3", boolean(), FIELD(tracer.ground_order3), "",
          "image search: three reflections with one on the ground, exactly: among static faces (wall, ground, "
          "wall; the ground first or last), and a wall, a vehicle and the ground in any order");
    t.toggle("ground order 3", image_search(3));
    t.key("beam_order3", boolean(), FIELD(tracer.beam_order3), "",
          "image search: three reflections beginning on a static face and a second face the rays light "
          "(a wall or a vehicle's), the third face from their beam");
    t.toggle("beam order 3", image_search(3));
    t.key("diffraction", boolean(), FIELD(tracer.diffraction), "", "first-order UTD edge diffraction on the static scene");
    t.toggle("diffraction");
    t.key("diffraction_reflection", boolean(), FIELD(tracer.diffraction_reflection), "",
          "with diffraction: a reflection on a static face before or after the edge (reflection-diffraction, "
          "diffraction-reflection)");
    t.toggle("reflection-diffraction", [](const TraceSettings& c) { return c.tracer.diffraction; });
    t.key("vehicle_diffraction", boolean(), FIELD(tracer.vehicle_diffraction), "",
          "vehicles in the first Fresnel zone: P.526 knife-edge loss on the direct path");
    t.toggle("vehicle knife edges");
    t.key("vehicle_diffraction_reflected", boolean(), FIELD(tracer.vehicle_diffraction_reflected), "",
          "with vehicle_diffraction: the same on every specular path (each leg against the unfolded path's first "
          "zone); a path only vehicles block is traced through them, attenuated (off: 30-70 % more time)");
    t.toggle("reflected knife edges", [](const TraceSettings& c) { return c.tracer.vehicle_diffraction; });
    t.key("vehicle_edge_diffraction", boolean(), FIELD(tracer.vehicle_edge_diffraction), "",
          "first-order UTD diffraction on the vehicles' edges (roofs, hoods, pillars); a vehicle in the direct "
          "path's first zone diffracts by its knife edge instead (faded between 1.0 and 0.55 r1)");
    t.toggle("vehicle edges");
    t.key("vehicle_edge_floor_db", number(), FIELD(tracer.vehicle_edge_floor_db), "dB",
          "with vehicle_edge_diffraction: vehicle-edge paths this far below the pair's direct free-space power "
          "are not traced");
    t.key("facet_reflection",
          enumeration<tracer::FacetReflection>({{"po", tracer::FacetReflection::po},
                                                {"go", tracer::FacetReflection::go}}),
          FIELD(tracer.facet_reflection), "",
          "reflections on vehicle faces: po (physical optics over the face, which returns a fraction of a "
          "mirror's power when the face is smaller than its Fresnel zone) or go (every face an infinite mirror)");
    t.key("path_threshold_db", number(), FIELD(tracer.path_threshold_db), "dB",
          "paths this far below a pair's strongest are dropped and counted (<= 0: keep all)");
    t.key("range_margin_db", number(), FIELD(tracer.range_margin_db), "dB",
          "pairs beyond the sensitivity's free-space reach plus this margin are out of range, not traced");
    return t;
  }();
  return t;
}

namespace {

const Table<tracer::MaterialOverride>& material_table() {
  static const Table<tracer::MaterialOverride> t = [] {
    Table<tracer::MaterialOverride> t("materials.<name>",
                                      "Overrides of one radio material (P.2040 or custom); unset keys keep the built-in "
                                      "value at the carrier.");
    const std::string builtin = "built-in";
    t.key("eps_r", optional(number(at_least(1))), FIELD(eps_r), "",
          "relative permittivity (with sigma: lifts the P.2040 frequency range check)", builtin);
    t.key("sigma", optional(number(at_least(0))), FIELD(sigma), "S/m", "conductivity", builtin);
    t.key("thickness_m", optional(number(at_least(0))), FIELD(thickness_m), "m", "slab thickness (0: half space)", builtin);
    t.key("scattering_coefficient", optional(number(between(0, 1))), FIELD(scattering_coefficient), "",
          "S: S^2 of the reflected power is scattered", builtin);
    t.key("xpd", optional(number(between(0, 1))), FIELD(xpd), "", "cross-polarised fraction of the scattered power",
          builtin);
    t.key("lobe",
          optional(enumeration<tracer::ScatteringLobe>({{"lambertian", tracer::ScatteringLobe::lambertian},
                                                        {"directive", tracer::ScatteringLobe::directive},
                                                        {"backscatter", tracer::ScatteringLobe::backscatter}})),
          FIELD(lobe), "", "scattering lobe", builtin);
    t.key("alpha_r", optional(integer<int>(between(1, 20))), FIELD(alpha_r), "", "directive lobe width", builtin);
    t.key("alpha_i", optional(integer<int>(between(1, 20))), FIELD(alpha_i), "", "backscatter lobe width", builtin);
    t.key("lambda_r", optional(number(between(0, 1))), FIELD(lambda_r), "",
          "backscatter: weight of the specular lobe against the back lobe", builtin);
    return t;
  }();
  return t;
}

}  // namespace

const Table<TraceSettings>& materials_table() {
  static const Table<TraceSettings> t = [] {
    Table<TraceSettings> t("materials", "Radio material overrides, one [materials.<name>] table per material.");
    t.names("<name>",
            map(table(material_table()), "<material>",
                [](const std::string& s) {
                  const auto m = meshkit::radio_material_from_id(s);
                  if (!m) throw std::invalid_argument(unknown("material", s, radio_material_names()));
                  return *m;
                }),
            FIELD(tracer.materials), "[materials.<name>]: any P.2040 or custom material");
    return t;
  }();
  return t;
}

#undef FIELD

}  // namespace raysweep::pipeline
