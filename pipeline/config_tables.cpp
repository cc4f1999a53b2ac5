#include "pipeline/config_tables.hpp"

#include <filesystem>
#include <sstream>

#include "generators/sinr/types.hpp"
#include "meshkit/materials.hpp"
#include "meshkit/model_import.hpp"
#include "meshkit/vehicle_classes.hpp"
#include "pipeline/city_run.hpp"
#include "pipeline/config.hpp"
#include "pipeline/ns3_stage.hpp"
#include "pipeline/radiomap_stage.hpp"
#include "pipeline/sinr_stage.hpp"
#include "pipeline/sweep_stage.hpp"
#include "pipeline/trace_config.hpp"
#include "pipeline/trace_stage.hpp"
#include "pipeline/traffic_stage.hpp"
#include "pipeline/vehicles_stage.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;
using namespace schema;

// A field of the bound struct, for reading (Cfg&) and writing (const Cfg&) alike.
#define FIELD(member) [](auto& c) -> auto& { return c.member; }

namespace {

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

// A name out of `names`, or an error saying which names there are.
std::string unknown(const std::string& what, const std::string& s, const std::vector<std::string>& names) {
  const std::string hint = suggest(s, names);
  return "unknown " + what + " '" + s + "'" + (hint.empty() ? " (" + joined(names) + ")" : " (did you mean '" + hint + "'?)");
}

// A path, relative to the config file's folder unless absolute.
Value<std::string> path() {
  Value<std::string> v = text();
  v.type = "path";
  v.range = "relative to the file";
  auto inner = v.read;
  v.read = [inner](const toml::node& n, const At& at) {
    const std::string p = inner(n, at);
    if (p.empty() || fs::path(p).is_absolute() || !at.src) return p;
    return (at.src->dir / p).lexically_normal().string();
  };
  return v;
}

Value<std::string> itu_material() {
  const auto& names = meshkit::itu_material_names();
  return parsed<std::string>(
      "string", "a P.2040 name: " + joined(names), "an ITU-R P.2040 material name",
      [&names](const std::string& s) {
        const auto m = meshkit::itu_material_from_id(s);
        if (!m) throw std::invalid_argument(unknown("ITU-R P.2040 material", s, names));
        return *m;
      },
      [](const std::string& s) { return json(s); });
}

std::vector<std::string> radio_material_names() {
  std::vector<std::string> names = meshkit::itu_material_names();
  for (const auto& c : meshkit::custom_materials()) names.push_back(c.name);
  return names;
}

// P.2040 or custom (plastic, rubber, ...): what vehicle parts may be made of.
Value<std::string> radio_material() {
  return parsed<std::string>(
      "string", "a P.2040 or custom material: " + joined(radio_material_names()), "a radio material name",
      [](const std::string& s) {
        if (!meshkit::is_radio_material(s)) throw std::invalid_argument(unknown("radio material", s, radio_material_names()));
        return s;
      },
      [](const std::string& s) { return json(s); });
}

// 0 keeps positions exact; below 8 bits Draco's grid is coarser than a wavelength.
Value<int> draco_bits() {
  return checked(integer<int>(), std::function<bool(const int&)>([](const int& b) { return b == 0 || (b >= 8 && b <= 30); }),
                 "an integer, 0 (lossless) or in 8..30", "0 or 8..30");
}

template <class Box>
Value<Box> box(Value<Box> v) {
  return checked(std::move(v), std::function<bool(const Box&)>([](const Box& b) { return b[0] < b[2] && b[1] < b[3]; }),
                 "[xmin, ymin, xmax, ymax] with xmin < xmax and ymin < ymax", "xmin < xmax, ymin < ymax");
}

// [[sinr_db, bler], ...], increasing SINR (SinrConfig::check).
Value<std::vector<std::pair<double, double>>> bler_curve() {
  auto p = numbers<2>();
  Value<std::pair<double, double>> pt;
  pt.type = "[sinr_db, bler] pair";
  pt.expect = "a [sinr_db, bler] pair";
  pt.read = [p](const toml::node& n, const At& at) {
    const auto a = p.read(n, at);
    return std::make_pair(a[0], a[1]);
  };
  pt.write = [](const std::pair<double, double>& x) { return json::array({x.first, x.second}); };
  return list(pt);
}

}  // namespace

// --- [city] -----------------------------------------------------------------

const Table<CityConfig>& city_table() {
  static const Table<CityConfig> t = [] {
    Table<CityConfig> t("city", "The city's inputs for `raysweep run` (paths relative to this file).");
    t.key("name", checked(text(), std::function<bool(const std::string&)>([](const std::string& s) { return !s.empty(); }),
                          "a non-empty string"),
          FIELD(name), "", "the city's name; outputs go to out/<name> by default")
        .required();
    t.key("osm", path(), FIELD(osm), "", "OpenStreetMap extract (.osm, .osm.gz, .osm.bz2, .osm.pbf); give osm or mitsuba");
    t.key("mitsuba", path(), FIELD(mitsuba), "", "a Sionna RT / Mitsuba scene.xml instead of osm");
    t.key("net", path(), FIELD(net), "", "SUMO network (.net.xml[.gz]): projection, clipping, traffic").required();
    t.key("rsus", path(), FIELD(rsus), "", "CSV id,x,y,z of road-side-unit antennas (optional)");
    t.key("out", text(), FIELD(out), "", "output folder, relative to the working directory", "out/<name>");
    return t;
  }();
  return t;
}

// --- [scene] ----------------------------------------------------------------

const Table<SceneConfig>& scene_table() {
  static const Table<SceneConfig> t = [] {
    Table<SceneConfig> t("scene", "`raysweep scene`: OSM buildings to a watertight 3D radio scene.");
    t.key("clip_distance_m", number(), FIELD(city.clip_distance_m), "m",
          "keep buildings within this distance of a lane (<= 0: all)");
    t.key("clip_bbox", optional(box(numbers<4>())), FIELD(city.clip_bbox), "m",
          "or keep the buildings meeting this box [xmin, ymin, xmax, ymax] in network coordinates", "none");
    t.key("default_material", itu_material(), FIELD(city.default_material), "",
          "material of buildings whose OSM tags give none");
    t.key("ground", boolean(), FIELD(city.ground), "", "add a ground plane under buildings and network");
    t.key("ground_material", itu_material(), FIELD(city.ground_material), "", "the ground plane's material");
    t.key("ground_margin_m", number(at_least(0)), FIELD(city.ground_margin_m), "m",
          "margin of the ground plane around buildings and network");
    t.key("level_height_m", number(above(0)), FIELD(city.heights.level_height_m), "m",
          "height per building:level (and roof:level)");
    t.key("default_height_m", number(above(0)), FIELD(city.heights.default_height_m), "m",
          "height of buildings without height or levels");
    t.key("max_height_m", number(above(0)), FIELD(city.heights.max_height_m), "m",
          "tagged heights above this are errors in the data (the default is used)");
    t.key("simplify_tolerance_m", number(at_least(0)), FIELD(city.footprint.simplify_tolerance_m), "m",
          "footprint simplification: largest distance of a removed vertex from the outline");
    t.key("max_area_change", number(at_least(0)), FIELD(city.footprint.max_area_change), "",
          "relative area change beyond which a simplification is undone");
    t.key("max_centroid_shift_m", number(at_least(0)), FIELD(city.footprint.max_centroid_shift_m), "m",
          "centroid shift beyond which a simplification is undone");
    t.key("min_area_m2", number(at_least(0)), FIELD(city.footprint.min_area_m2), "m^2",
          "smaller footprints are dropped as degenerate");
    t.key("outlines_yield_to_parts", boolean(), FIELD(city.outlines_yield_to_parts), "",
          "an outline with building:part inside is drawn by its parts");
    t.key("draco", boolean(), FIELD(draco), "", "Draco-compress scene.glb (tinygltf 2.7 and Blender 3.4 cannot read it)");
    t.key("draco_position_bits", draco_bits(), FIELD(draco_position_bits), "bits",
          "Draco position quantisation over each mesh's extent (0: lossless)");
    t.key("material_map", map(itu_material(), "OSM value"), FIELD(city.material_map), "",
          "[scene.material_map]: extra OSM material value -> P.2040 name mappings");
    return t;
  }();
  return t;
}

// --- [vehicles] -------------------------------------------------------------

namespace {

const Table<VehicleEntryConfig>& vehicle_entry_table() {
  static const Table<VehicleEntryConfig> t = [] {
    Table<VehicleEntryConfig> t("vehicles.class.<name>", "Overrides for one library entry (a class or a vType id).");
    t.key("length", number(at_least(0)), FIELD(dims.length), "m", "length (0: the class default)");
    t.key("width", number(at_least(0)), FIELD(dims.width), "m", "width (0: the class default)");
    t.key("height", number(at_least(0)), FIELD(dims.height), "m", "height (0: the class default)");
    t.key("antenna", optional(numbers<3>()), FIELD(antenna), "m",
          "antenna mount [x, y, z] in the library frame (front bumper centre, z up)", "on the roof");
    const auto units = [] {
      std::vector<std::string> u;
      for (const auto& [name, scale] : meshkit::model_units()) u.push_back(name);
      return u;
    }();
    t.key("model_unit",
          parsed<std::string>(
              "string", quoted_alternatives(units), quoted_alternatives(units),
              [units](const std::string& s) {
                if (meshkit::parse_model_unit(s) <= 0) throw std::invalid_argument(unknown("unit", s, units));
                return s;
              },
              [](const std::string& s) { return json(s); }),
          FIELD(model_unit), "", "the --model file's length unit (glTF: metres; else guessed from the size)",
          "the file's own, else guessed");
    return t;
  }();
  return t;
}

const Table<meshkit::SegmentationRule>& vehicle_rule_table() {
  static const Table<meshkit::SegmentationRule> t = [] {
    Table<meshkit::SegmentationRule> t("[vehicles.rules]",
                                       "Part -> material rules, first match wins; a list replaces the built-in table.",
                                       meshkit::SegmentationRule{"any", "", ""});
    t.key("field", choice({"part", "material", "any"}), FIELD(field), "", "which name the pattern is searched in");
    t.key("pattern", text(), FIELD(pattern), "", "ECMAScript regex, case-insensitive (empty: every name)");
    t.key("material", radio_material(), FIELD(material), "", "the matched parts' material").required();
    return t;
  }();
  return t;
}

}  // namespace

const Table<VehiclesConfig>& vehicles_table() {
  static const Table<VehiclesConfig> t = [] {
    Table<VehiclesConfig> t("vehicles", "`raysweep vehicles`: the vehicle library (one GLB per entry and LOD).");
    std::vector<std::string> classes;
    for (const auto& c : meshkit::vehicle_classes()) classes.push_back(c.vclass);
    t.key("classes",
          list(parsed<std::string>(
              "string", "a built-in class: " + joined(classes), "a vehicle class name",
              [classes](const std::string& s) {
                if (!meshkit::find_vehicle_class(s)) throw std::invalid_argument(unknown("vehicle class", s, classes));
                return s;
              },
              [](const std::string& s) { return json(s); })),
          FIELD(classes), "", "the built-in classes to build", "every built-in class");
    t.key("lod_ratios", list(number({0, 1, true, false}), 1), FIELD(lod_ratios), "",
          "triangle ratio of each level of detail");
    t.key("lod_tolerance_m", number(at_least(0)), FIELD(lod_tolerance_m), "m",
          "default LOD: the smallest within this Hausdorff distance of LOD 0");
    t.key("lod_max_error_m", number(at_least(0)), FIELD(lod_max_error_m), "m",
          "no decimation step may move the surface more");
    t.key("antenna_offset_m", number(), FIELD(antenna_offset_m), "m",
          "antenna height above the roof point straight below the mount");
    t.key("scale_to_class", boolean(), FIELD(scale_to_class), "", "imported models take the class dimensions");
    t.key("draco", boolean(), FIELD(draco), "", "Draco-compress the GLB files (tinygltf 2.7 and Blender 3.4 cannot read them)");
    t.key("draco_position_bits", draco_bits(), FIELD(draco_position_bits), "bits",
          "Draco position quantisation (0: lossless)");
    t.key("default_material", radio_material(), FIELD(rules.default_material), "",
          "material of parts no rule matches (warned)");
    t.key("rules", list(table(vehicle_rule_table())), FIELD(rules.rules), "",
          "[[vehicles.rules]]: part -> material rules, replacing the built-in table", "the built-in table (README)");
    t.key("class", map(table(vehicle_entry_table()), "<name>"), FIELD(entries), "",
          "[vehicles.class.<name>]: per-entry overrides", "none");
    return t;
  }();
  return t;
}

// --- [traffic] --------------------------------------------------------------

const Table<TrafficSettings>& traffic_table() {
  static const Table<TrafficSettings> t = [] {
    Table<TrafficSettings> t("traffic",
                             "`raysweep run`'s traffic: SUMO on a .sumocfg's demand or on random trips, or an FCD "
                             "trace taken as given.");
    t.key("sumocfg", path(), FIELD(sumo.sumocfg), "", "SUMO config with the demand (else random trips)");
    t.key("fcd", path(), FIELD(fcd), "", "an existing FCD trace instead of running SUMO");
    t.key("seed", integer<std::uint64_t>(), FIELD(sumo.seed), "", "SUMO's and randomTrips' seed");
    t.key("begin_s", number(), FIELD(sumo.begin_s), "s", "simulation begin");
    t.key("end_s", number(), FIELD(sumo.end_s), "s", "simulation end (after begin_s)");
    t.key("step_length_s", number(above(0)), FIELD(sumo.step_length_s), "s", "simulation step = FCD sampling");
    t.key("period_s", number(above(0)), FIELD(sumo.period_s), "s", "random trips: one trip every period");
    t.key("fringe_factor", number(at_least(0)), FIELD(sumo.fringe_factor), "",
          "random trips: weight of trips starting at the network's fringe");
    t.key("classes", map(number(at_least(0)), "vClass"), FIELD(sumo.classes), "",
          "random trips: class mix, e.g. { passenger = 8, truck = 1, bus = 1 }");
    return t;
  }();
  return t;
}

// --- [sweep] ----------------------------------------------------------------

const Table<SweepConfig>& sweep_table() {
  static const Table<SweepConfig> t = [] {
    Table<SweepConfig> t("sweep", "`raysweep sweep`: the FCD trace swept through the tracer into the channel dataset.");
    t.key("begin_s", number(), FIELD(begin_s), "s", "first FCD time swept", "the trace's start");
    t.key("end_s", number(), FIELD(end_s), "s", "last FCD time swept (not before begin_s)", "the trace's end");
    t.key("step_s", number(at_least(0)), FIELD(step_s), "s", "minimum frame step (0: every frame)");
    t.key("ids", list(text()), FIELD(ids), "", "only these vehicle ids (empty: all)");
    t.key("types", list(text()), FIELD(types), "", "only these vType ids (empty: all)");
    t.key("area", box(list(number(), 4, 4)), FIELD(area), "m",
          "only vehicles inside [xmin, ymin, xmax, ymax] (network coordinates)", "everywhere");
    t.key("max_vehicles", integer<std::size_t>(), FIELD(max_vehicles), "",
          "0: all; else the first N vehicles to appear, refilled as they leave");
    t.key("outside", choice({"error", "drop"}), FIELD(outside), "", "a vehicle outside the scene: an error, or dropped and counted");
    t.key("cfr",
          parsed<std::string>(
              "string", "\"\", \"80211p\" or \"nr:MU:NRB\"", "\"\", \"80211p\" or \"nr:MU:NRB\"",
              [](const std::string& s) {
                if (!s.empty()) parse_ofdm_grid(s, 5.9e9);
                return s;
              },
              [](const std::string& s) { return json(s); }),
          FIELD(cfr), "", "also store each link's frequency response on this OFDM grid (\"\": none)");
    t.key("lod", integer<int>(at_least(-1)), FIELD(lod), "", "vehicle level of detail (-1: each entry's default)");
    t.key("exclude_objects", text(), FIELD(exclude_objects), "",
          "regex on static object ids to leave out (Sionna's placeholder cars: \"car_\")");
    t.key("d0_m", number(at_least(0)), FIELD(options.d0_m), "m",
          "a vehicle is re-placed once it moved this far (0: every frame)");
    t.key("coherence_time_s", number(at_least(0)), FIELD(options.coherence_time_s), "s",
          "or once this much time passed since it was placed");
    t.key("cache",
          enumeration<generators::CacheMode>({{"none", generators::CacheMode::none},
                                              {"per_pair", generators::CacheMode::per_pair},
                                              {"global", generators::CacheMode::global}}),
          FIELD(options.cache), "", "reuse of pair channels between frames (global: any update clears all pairs)");
    t.key("cache_margin_m", number(at_least(0)), FIELD(options.cache_margin_m), "m",
          "per_pair: a cached pair is retraced when a moved vehicle comes this close to it");
    t.key("block_frames", integer<std::uint32_t>(at_least(1)), FIELD(options.block_frames), "",
          "frames per committed block (resume granularity; caches restart at each block)");
    return t;
  }();
  return t;
}

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

// --- [sinr] -----------------------------------------------------------------

const Table<SinrSettings>& sinr_table() {
  static const Table<SinrSettings> t = [] {
    namespace gs = generators::sinr;
    Table<SinrSettings> t("sinr",
                          "`raysweep sinr` and `run`: 802.11p and NR-V2X sharing the channel (docs/sinr.md). With "
                          "this table `raysweep run` computes the outcomes and their report.");
    t.key("enabled", boolean(), FIELD(enabled), "", "`run`: compute the outcomes");
    t.key("seed", integer<std::uint64_t>(), FIELD(config.seed), "", "RAT assignment, schedules and shadowing");
    t.key("begin_s", number(), FIELD(config.begin_s), "s", "simulated window within the channel dataset (-1: all of it)");
    t.key("end_s", number(), FIELD(config.end_s), "s", "(-1: all of it)");
    t.key("nr_fraction", number(between(0, 1)), FIELD(config.rats.nr_fraction), "",
          "exact share of NR-V2X among the vehicles no list assigns");
    t.key("rat_by_vtype",
          map(enumeration<gs::Rat>({{"80211p", gs::Rat::wifi80211p}, {"nrv2x", gs::Rat::nr_v2x}, {"none", gs::Rat::none}}),
              "vType"),
          FIELD(config.rats.by_vtype), "", "the RAT of every vehicle of a vType");
    t.key("nr_ids", list(text()), FIELD(config.rats.nr_ids), "", "vehicles that use NR-V2X");
    t.key("wifi_ids", list(text()), FIELD(config.rats.wifi_ids), "", "vehicles that use 802.11p");
    t.key("silent_ids", list(text()), FIELD(config.rats.silent_ids), "", "vehicles that send nothing");
    t.key("active_vehicles", integer<std::uint32_t>(), FIELD(config.rats.active_vehicles), "",
          "the first N vehicles to appear take part (0: all); the others only block and reflect");
    t.key("rats_enabled", choice({"both", "80211p-only", "nrv2x-only"}), FIELD(config.rats.enabled), "",
          "silence one RAT after the assignment (the same vehicles without coexistence)");
    t.key("cam", boolean(), FIELD(config.cam.enabled), "", "send CAMs (ETSI EN 302 637-2 rules)");
    t.key("cam_bytes", integer<std::uint32_t>(at_least(1)), FIELD(config.cam.bytes), "bytes", "CAM size");
    t.key("cam_low_frequency_bytes", integer<std::uint32_t>(), FIELD(config.cam.low_frequency_bytes), "bytes",
          "added when the low-frequency container is due (every 500 ms)");
    t.key("cam_t_gen_min_s", number(above(0)), FIELD(config.cam.t_gen_min_s), "s", "T_GenCamMin");
    t.key("cam_t_gen_max_s", number(above(0)), FIELD(config.cam.t_gen_max_s), "s", "T_GenCamMax");
    t.key("cam_check_period_s", number(above(0)), FIELD(config.cam.check_period_s), "s", "T_CheckCamGen");
    t.key("cpm", boolean(), FIELD(config.cpm.enabled), "", "also send periodic CPMs");
    t.key("cpm_period_s", number(above(0)), FIELD(config.cpm.period_s), "s", "CPM period");
    t.key("cpm_bytes", integer<std::uint32_t>(), FIELD(config.cpm.bytes), "bytes", "CPM size");
    t.key("wifi_data_rate_bps", number(above(0)), FIELD(config.wifi.data_rate_bps), "bit/s",
          "802.11p rate: 3, 4.5, 6, 9, 12, 18, 24 or 27 Mb/s");
    t.key("wifi_access_category", choice({"BK", "BE", "VI", "VO"}), FIELD(config.wifi_mac.access_category), "",
          "EDCA access category");
    t.key("wifi_cca_signal_dbm", number(), FIELD(config.wifi_mac.cca_signal_dbm), "dBm",
          "an 802.11p preamble above this makes the medium busy");
    t.key("wifi_cca_energy_dbm", number(), FIELD(config.wifi_mac.cca_energy_dbm), "dBm",
          "any in-band energy above this makes the medium busy (NR included)");
    t.key("nr_bandwidth_hz", number(above(0)), FIELD(config.nr.bandwidth_hz), "Hz", "NR-V2X channel bandwidth");
    t.key("nr_numerology", integer<int>(between(0, 2)), FIELD(config.nr.numerology), "",
          "mu: subcarrier spacing 15 kHz x 2^mu");
    t.key("nr_subchannel_rbs", integer<int>(between(10, 100)), FIELD(config.nr.subchannel_rbs), "RBs",
          "subchannel size (sl-SubchannelSize)");
    t.key("nr_mcs", integer<int>(between(0, 28)), FIELD(config.nr.mcs), "", "MCS index (TS 38.214 64QAM table)");
    t.key("nr_data_symbols", integer<int>(between(1, 12)), FIELD(config.nr.data_symbols), "",
          "PSSCH symbols per slot carrying data");
    t.key("nr_reservation_period_s", number(above(0)), FIELD(config.nr_mac.reservation_period_s), "s",
          "semi-persistent reservation period (whole slots)");
    t.key("nr_selection", enumeration<bool>({{"random", false}, {"sensing", true}}), FIELD(config.nr_mac.sensing), "",
          "resource selection: random (the paper) or TS 38.214 sensing-based exclusion");
    t.key("nr_sensing_threshold_dbm", number(), FIELD(config.nr_mac.sensing_threshold_dbm), "dBm",
          "RSRP per resource element above which a reserved resource is excluded");
    t.key("nr_keep_probability", number(between(0, 1)), FIELD(config.nr_mac.keep_probability), "",
          "sl-ProbResourceKeep");
    t.key("nr_retransmissions", integer<int>(between(0, 31)), FIELD(config.nr_mac.retransmissions), "",
          "blind retransmissions per packet");
    t.key("tx_power_dbm", number(), FIELD(config.tx_power_dbm), "dBm", "transmit power");
    t.key("sensitivity_dbm", number(), FIELD(config.sensitivity_dbm), "dBm", "weakest decodable power");
    t.key("sinr_threshold_db", number(), FIELD(config.sinr_threshold_db), "dB", "decoded when SINR reaches this");
    t.key("noise_figure_db", number(), FIELD(config.noise_figure_db), "dB", "receiver noise figure");
    t.key("gain_threshold_db", number(), FIELD(config.gain_threshold_db), "dB",
          "inter-RAT interferers count only above this channel gain");
    t.key("wifi_bler", bler_curve(), FIELD(config.wifi_bler), "",
          "802.11p BLER curve [[sinr_db, bler], ...] replacing the threshold");
    t.key("nr_bler", bler_curve(), FIELD(config.nr_bler), "", "NR-V2X BLER curve replacing the threshold");
    t.key("prr_range_m", number(above(0)), FIELD(config.prr_range_m), "m", "receivers within this distance count in PRR");
    t.key("max_receiver_distance_m", number(at_least(0)), FIELD(config.max_receiver_distance_m), "m",
          "0: every present receiver of the RAT gets a row");
    t.key("shadowing", boolean(), FIELD(stochastic.shadowing), "", "3GPP baselines: spatially consistent shadowing");
    t.key("antenna_height_m", number(above(0)), FIELD(stochastic.antenna_height_m), "m", "3GPP baselines: antenna height");
    t.key("blocker_height_m", number(above(0)), FIELD(stochastic.blocker_height_m), "m",
          "TR 37.885 NLOSV blockage: vehicle height");
    t.key("decorrelation_m", number(above(0)), FIELD(stochastic.decorrelation_m), "m",
          "shadowing and LoS-state correlation distance");
    t.key("models",
          list(parsed<SinrModel>(
                   "string",
                   "\"ray\", \"tr36885\", \"tr37885-urban\" or \"tr37885-highway\", the 3GPP ones optionally "
                   "+ \"+los-from-ray\"",
                   "a channel model name", [](const std::string& s) { return parse_sinr_model(s); },
                   [](const SinrModel& m) { return json(m.label()); }),
               1),
          FIELD(models), "", "`run`: the channel models compared; the first is the reference");
    t.key("schedule", enumeration<bool>({{"shared", true}, {"own", false}}), FIELD(shared_schedule), "",
          "`run`: the other models evaluate the reference's transmissions (shared) or draw their own");
    t.key("isolated_runs", boolean(), FIELD(isolated_runs), "", "`run`: also the reference with each RAT alone");
    return t;
  }();
  return t;
}

// --- [ns3], [radiomap] ------------------------------------------------------

const Table<Ns3Settings>& ns3_table() {
  static const Table<Ns3Settings> t = [] {
    Table<Ns3Settings> t("ns3", "`raysweep ns3-table` and `run`: the lookup table ns-3's raysweep models read.");
    t.key("enabled", boolean(), FIELD(enabled), "", "`run`: write <out>/ns3/table.h5");
    t.key("subcarriers_per_band", integer<std::uint32_t>(), FIELD(subcarriers_per_band), "",
          "per-band gains from the stored CFR, this many subcarriers a band (0: none)");
    return t;
  }();
  return t;
}

const Table<RadioMapSettings>& radiomap_table() {
  static const Table<RadioMapSettings> t = [] {
    Table<RadioMapSettings> t("radiomap", "`raysweep radiomap` and `run`: path gain at every voxel (docs/radiomap.md).");
    t.key("tx",
          list(parsed<RadioMapTx>(
              "string", "\"ID,X,Y,Z[,POWER_DBM]\"", "a transmitter \"ID,X,Y,Z[,POWER_DBM]\"",
              [](const std::string& s) { return parse_radiomap_tx(s, "transmitter"); },
              [](const RadioMapTx& x) {
                json j = {{"id", x.id}, {"position", x.position}};
                if (x.power_given) j["power_dbm"] = x.power_dbm;
                return j;
              })),
          FIELD(tx), "", "transmitters (power default: radio.tx_power_dbm); --tx adds more");
    t.key("voxel_m", number(above(0)), FIELD(voxel_m), "m", "voxel edge");
    t.key("z_min_m", number(), FIELD(z_min_m), "m", "lowest voxel centre");
    t.key("z_max_m", number(), FIELD(z_max_m), "m", "voxel centres z_min + k voxel_m stay below this");
    t.key("region", choice({"streets", "all"}), FIELD(region), "",
          "voxels near the lanes, or the whole scene box", "streets when a network is known, else all");
    t.key("street_margin_m", number(above(0)), FIELD(street_margin_m), "m",
          "streets: voxel centres within this distance of a lane centre line");
    t.key("diffuse_block_m", number(at_least(0)), FIELD(diffuse_block_m), "m",
          "diffuse field (rays) gathered once per block of this size and spread over it (0: every voxel)");
    t.key("png", boolean(), FIELD(png), "", "`run`: also radiomap.png");
    return t;
  }();
  return t;
}

#undef FIELD

// --- the file ---------------------------------------------------------------

const std::vector<const TableBase*>& config_tables() {
  static const std::vector<const TableBase*> all = {
      &city_table(),   &scene_table(),  &vehicles_table(),  &traffic_table(), &sweep_table(),   &radio_table(),
      &tracer_table(), &materials_table(), &sinr_table(),   &ns3_table(),     &radiomap_table()};
  return all;
}

ConfigFile::ConfigFile(const std::string& path) {
  src_.file = path;
  src_.dir = fs::absolute(path).parent_path();
  try {
    root_ = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    throw ConfigError(path + ":" + std::to_string(e.source().begin.line) + ": " + std::string(e.description()));
  }
  std::vector<std::string> names;
  for (const auto* t : config_tables()) names.push_back(t->name());
  const At top{&src_, ""};
  for (auto&& [k, node] : root_) {
    const std::string name(k.str());
    const TableBase* table = nullptr;
    for (const auto* t : config_tables())
      if (t->name() == name) table = t;
    if (!table) {
      const std::string hint = suggest(name, names);
      top.fail(node, "unknown table [" + name + "]" + (hint.empty() ? "" : " (did you mean [" + hint + "]?)"));
    }
    if (!node.is_table()) top.child(name).expected(node, "a table [" + name + "]");
    // Every table is checked here, whichever stage asked: a typo in [sinr]
    // must not wait for the SINR stage an hour later.
    table->effective(node.as_table(), top.child(name));
  }
}

void ConfigFile::fail(const std::string& table, const std::string& key, const std::string& msg) const {
  const At at{&src_, table + "." + key};
  if (const toml::node* n = root_.at_path(table + "." + key).node()) at.fail(*n, msg);
  if (const toml::node* n = root_.get(table)) at.fail(*n, msg);
  throw ConfigError(src_.file + ": " + at.key + ": " + msg);
}

json effective_config(const std::string& path) {
  json out = json::object();
  if (path.empty()) {
    for (const auto* t : config_tables()) out[t->name()] = t->effective(nullptr, At{});
    return out;
  }
  const ConfigFile file(path);
  const Source src{path, fs::absolute(path).parent_path()};
  for (const auto* t : config_tables()) {
    const toml::node* n = file.node(t->name());
    out[t->name()] = t->effective(n ? n->as_table() : nullptr, At{&src, t->name()});
  }
  return out;
}

// --- docs/config.md ---------------------------------------------------------

namespace {

std::string cell(std::string s) {
  for (std::size_t p = s.find('|'); p != std::string::npos; p = s.find('|', p + 2)) s.replace(p, 1, "\\|");
  return s;
}

void table_docs(std::ostringstream& md, const TableBase& t, const std::string& heading) {
  const std::string name = t.name();
  md << heading << " `[" << name << "]`\n\n" << t.help() << "\n\n";
  md << "| key | type | unit | default | allowed | description |\n|---|---|---|---|---|---|\n";
  std::vector<const TableBase*> subs;
  for (const auto& k : t.docs()) {
    md << "| `" << k.key << "` | " << cell(k.type) << " | " << cell(k.unit) << " | "
       << cell(k.required ? "**required**" : k.default_value) << " | " << cell(k.range) << " | "
       << cell(k.help) << " |\n";
    if (k.sub) subs.push_back(k.sub);
  }
  md << "\n";
  for (const auto* s : subs) table_docs(md, *s, heading + "#");
}

}  // namespace

std::string config_docs() {
  std::ostringstream md;
  md << "# City and stage configuration (`city.toml`)\n\n"
        "<!-- Generated by `raysweep config --docs > docs/config.md` from pipeline/config_tables.cpp; "
        "tests/cli/test_cli_config.cpp fails when this file is stale. Do not edit by hand. -->\n\n"
        "`raysweep run CITY.toml` reads every table below; the stage commands read the tables they need from "
        "`--config FILE`. Every key is optional unless marked required. Unknown tables and keys, values of the "
        "wrong type and values out of range are errors naming the file, the line and the key, e.g.\n\n"
        "    city.toml:12: tracer.rays_per_source: expected an integer >= 1, got -3\n\n"
        "and the command exits with status 2. `raysweep config CITY.toml` prints the effective configuration "
        "(every key, defaults filled in) as JSON; the outputs' provenance records the same tables.\n\n";
  for (const auto* t : config_tables()) table_docs(md, *t, "##");
  return md.str();
}

}  // namespace raysweep::pipeline
