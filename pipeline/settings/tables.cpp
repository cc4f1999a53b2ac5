#include "pipeline/settings/tables.hpp"

#include "meshkit/model_import.hpp"
#include "meshkit/vehicle_classes.hpp"
#include "pipeline/settings/settings.hpp"
#include "pipeline/settings/values.hpp"

namespace raysweep::pipeline {

using json = nlohmann::json;
using namespace schema;

// --- [city] -----------------------------------------------------------------

const Table<CitySettings>& city_table() {
  static const Table<CitySettings> t = [] {
    Table<CitySettings> t("city", "The city's inputs for `raysweep run` (paths relative to this file).");
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

const Table<SceneSettings>& scene_table() {
  static const Table<SceneSettings> t = [] {
    Table<SceneSettings> t("scene", "`raysweep scene`: OSM buildings to a watertight 3D radio scene.");
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

const Table<VehicleEntrySettings>& vehicle_entry_table() {
  static const Table<VehicleEntrySettings> t = [] {
    Table<VehicleEntrySettings> t("vehicles.class.<name>", "Overrides for one library entry (a class or a vType id).");
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

const Table<VehiclesSettings>& vehicles_table() {
  static const Table<VehiclesSettings> t = [] {
    Table<VehiclesSettings> t("vehicles", "`raysweep vehicles`: the vehicle library (one GLB per entry and LOD).");
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

const Table<SweepSettings>& sweep_table() {
  static const Table<SweepSettings> t = [] {
    Table<SweepSettings> t("sweep", "`raysweep sweep`: the FCD trace swept through the tracer into the channel dataset.");
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
          parsed<std::optional<tracer::OfdmGridSpec>>(
              "string", "\"\", \"80211p\" or \"nr:MU:NRB\"", "\"\", \"80211p\" or \"nr:MU:NRB\"",
              [](const std::string& s) -> std::optional<tracer::OfdmGridSpec> {
                if (s.empty()) return std::nullopt;
                return tracer::parse_ofdm_grid_spec(s, "--cfr");
              },
              [](const std::optional<tracer::OfdmGridSpec>& g) { return json(g ? g->text : ""); }),
          FIELD(cfr), "", "also store each link's frequency response on this OFDM grid (\"\": none)");
    t.key("store",
          enumeration<generators::StoreLevel>({{"links", generators::StoreLevel::links},
                                               {"cfr", generators::StoreLevel::cfr},
                                               {"paths", generators::StoreLevel::paths},
                                               {"full", generators::StoreLevel::full}}),
          FIELD(store), "",
          "what the dataset stores: links (link columns and summaries), cfr (+ frequency responses), paths (+ paths "
          "without interaction points), full (+ interaction points)");
    t.key("paths_top_k", integer<std::uint32_t>(), FIELD(paths_top_k), "",
          "store = paths or full: each link keeps only its this many strongest paths (0: all)");
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
    t.key("coherence", boolean(), FIELD(options.coherence), "",
          "samples that add up across frames: each frame's rays on a lattice turned by the frame, and every traced "
          "pair also solving the sampled sequences that gave it a path in its last lattice_frames frames (false: "
          "every frame from scratch on one unturned lattice)");
    t.key("lattice_frames", integer<std::uint32_t>(at_least(1)), FIELD(options.lattice_frames), "",
          "coherence: the frames whose sampled sequences a frame carries (1: none, one unturned lattice)");
    t.key("diffuse_frames", integer<std::uint32_t>(at_least(1)), FIELD(options.diffuse_frames), "",
          "diffuse samples shared by consecutive frames: a frame's diffuse gathering also shoots the lattices of "
          "its diffuse_frames - 1 frames before, all weighted alike (1: its own lattice only)");
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

const Table<FeaturesSettings>& features_table() {
  static const Table<FeaturesSettings> t = [] {
    Table<FeaturesSettings> t("features",
                              "`raysweep features` and `ml`: per-link context from the scene and the traffic "
                              "(schemas/README.md, context-feature file).");
    t.key("along_cells", integer<std::uint32_t>(between(1, 1024)), FIELD(grid.along_cells), "",
          "corridor cells along the link, tx to rx");
    t.key("across_cells", integer<std::uint32_t>(between(1, 1024)), FIELD(grid.across_cells), "",
          "corridor cells across the link");
    t.key("half_width_m", number(above(0)), FIELD(grid.half_width_m), "m", "the corridor reaches this far either side");
    t.key("max_vehicles", integer<std::uint32_t>(between(1, 254)), FIELD(grid.max_vehicles), "",
          "vehicles kept per link: those nearest the tx-rx line");
    t.key("height_scale_m", number(above(0)), FIELD(grid.height_scale_m), "m", "one step of the stored building height");
    t.key("map_resolution_m", number(above(0)), FIELD(grid.map_resolution_m), "m",
          "cell edge of the static height map the corridor samples");
    t.key("frame_stride", integer<std::uint32_t>(at_least(1)), FIELD(grid.frame_stride), "",
          "the links of every this-many-th frame");
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

const std::vector<const TableBase*>& config_tables() {
  static const std::vector<const TableBase*> all = {
      &city_table(),   &scene_table(),  &vehicles_table(),  &traffic_table(), &sweep_table(),   &radio_table(),
      &tracer_table(), &materials_table(), &sinr_table(),   &ns3_table(),     &radiomap_table(),
      &features_table()};
  return all;
}

}  // namespace raysweep::pipeline
