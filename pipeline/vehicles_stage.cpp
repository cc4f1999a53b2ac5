#include "pipeline/vehicles_stage.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <set>

#include "meshkit/errors.hpp"
#include "meshkit/gltf_io.hpp"
#include "meshkit/materials.hpp"
#include "meshkit/model_import.hpp"
#include "meshkit/sumo_net.hpp"
#include "meshkit/vehicle_classes.hpp"
#include "meshkit/vehicle_lod.hpp"
#include "meshkit/vehicle_parametric.hpp"
#include "pipeline/preview.hpp"
#include "pipeline/provenance.hpp"
#include "pipeline/staged_output.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;
using namespace raysweep::meshkit;

namespace {

json dims_json(const VehicleDims& d) { return {{"length", d.length}, {"width", d.width}, {"height", d.height}}; }

std::string unit_names() {
  std::string out;
  for (const auto& [name, scale] : model_units()) out += (out.empty() ? "" : ", ") + name;
  return out;
}

}  // namespace

BuiltVehicle build_vehicle(const std::string& name, const std::string& vclass, const std::string& model_file,
                           const VehiclesSettings& cfg) {
  const VehicleClassInfo* info = find_vehicle_class(vclass);
  if (!info) throw std::invalid_argument(name + ": vehicle class '" + vclass + "' is not modelled");
  VehicleDims dims = info->dims;
  VehicleEntrySettings entry;
  if (auto it = cfg.entries.find(name); it != cfg.entries.end()) entry = it->second;
  if (entry.dims.length > 0) dims.length = entry.dims.length;
  if (entry.dims.width > 0) dims.width = entry.dims.width;
  if (entry.dims.height > 0) dims.height = entry.dims.height;

  BuiltVehicle out;
  json& rec = out.record;
  VehicleModel& m = out.model;
  if (model_file.empty()) {
    m = parametric_vehicle(name, vclass, info->archetype, dims, cfg.antenna_offset_m);
    rec["source"] = "parametric";
    rec["archetype"] = info->archetype;
  } else {
    ImportOptions iopt;
    iopt.unit = entry.model_unit.empty() ? 0 : parse_model_unit(entry.model_unit);
    iopt.vclass = vclass;
    iopt.class_length = dims.length;
    ImportedModel imp = import_model(model_file, iopt);
    m.name = name;
    m.vclass = vclass;
    m.source = model_file;
    for (auto& p : imp.parts) m.parts.push_back({p.name, p.material, "", "", std::move(p.vertices), std::move(p.triangles)});
    m.repairs = imp.repairs;
    m.warnings = imp.warnings;
    const NormalizeReport norm = normalize(m, cfg.scale_to_class ? dims : VehicleDims{});
    const SegmentReport seg = segment(m, cfg.rules);
    m.antenna = roof_mount(m, -m.dims().length / 2, 0, cfg.antenna_offset_m);
    rec["source"] = model_file;
    rec["unit_scale"] = imp.unit_scale;
    rec["unit_source"] = imp.unit_source;
    rec["file_up_axis"] = imp.up_axis;
    rec["native_dims"] = dims_json(norm.native);
    rec["scale"] = norm.scale;
    rec["orientation"] = norm.orientation;
    rec["segmentation"] = {{"geometric", seg.geometric}, {"by_rule", seg.by_rule}, {"by_default", seg.by_default}};
  }
  if (entry.antenna) m.antenna = *entry.antenna;
  rec["name"] = name;
  rec["vclass"] = vclass;
  rec["dims"] = dims_json(m.dims());
  rec["antenna"] = m.antenna;
  json parts = json::array();
  for (const auto& p : m.parts) {
    VehicleModel one;
    one.parts.push_back(p);
    double area = 0;
    for (const auto& [mat, a] : one.area_by_material()) area += a;
    parts.push_back({{"name", p.name},
                     {"source_material", p.source_material},
                     {"material", p.material},
                     {"rule", p.rule},
                     {"triangles", p.triangles.size()},
                     {"area_m2", area}});
  }
  rec["parts"] = parts;
  rec["area_by_material_m2"] = m.area_by_material();
  rec["repairs"] = m.repairs;
  rec["warnings"] = m.warnings;
  return out;
}

namespace {

struct LibraryEntry {
  std::string name, vclass, file;
};

// The entries with their --model files (recorded as inputs).
void add_models(const VehiclesArgs& args, std::vector<LibraryEntry>& entries, std::vector<InputFile>& inputs) {
  for (const auto& spec : args.models) {
    const auto eq = spec.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == spec.size())
      throw std::invalid_argument("--model expects CLASS=FILE, got '" + spec + "'");
    const std::string cls = spec.substr(0, eq), file = spec.substr(eq + 1);
    if (!find_vehicle_class(cls)) throw std::invalid_argument("--model " + spec + ": unknown vehicle class '" + cls + "'");
    auto it = std::find_if(entries.begin(), entries.end(), [&](const LibraryEntry& e) { return e.name == cls; });
    if (it == entries.end()) entries.push_back({cls, cls, file});
    else it->file = file;
    inputs.push_back({"model:" + cls, file});
  }
}

// One entry per vType of a modelled class; returns the vTypes read.
std::vector<SumoVType> add_vtypes(const VehiclesArgs& args, std::vector<LibraryEntry>& entries,
                                  std::vector<InputFile>& inputs) {
  std::vector<SumoVType> vtypes;
  if (args.vtypes.empty()) return vtypes;
  inputs.push_back({"vtypes", args.vtypes});
  vtypes = read_sumo_vtypes(args.vtypes);
  for (const auto& vt : vtypes) {
    if (!find_vehicle_class(vt.vclass)) {
      spdlog::warn("{}: vType {} has vClass {} which raysweep does not model; skipped", args.vtypes, vt.id, vt.vclass);
      continue;
    }
    if (std::any_of(entries.begin(), entries.end(), [&](const LibraryEntry& e) { return e.name == vt.id; }))
      throw meshkit::InputError(args.vtypes, "line " + std::to_string(vt.line) + " vType " + vt.id,
                                "id collides with a vehicle class name");
    entries.push_back({vt.id, vt.vclass, ""});
  }
  return vtypes;
}

// Model units: a bare UNIT for every model, then the config's, then CLASS=UNIT.
void apply_model_units(const VehiclesArgs& args, const std::vector<LibraryEntry>& entries, VehiclesSettings& effective) {
  std::string every_unit;
  std::map<std::string, std::string> class_unit;
  for (const auto& spec : args.model_units) {
    const auto eq = spec.find('=');
    const std::string cls = eq == std::string::npos ? "" : spec.substr(0, eq);
    const std::string unit = eq == std::string::npos ? spec : spec.substr(eq + 1);
    if (parse_model_unit(unit) <= 0)
      throw std::invalid_argument("--model-unit " + spec + ": unknown unit '" + unit + "' (expected " + unit_names() + ")");
    if (eq == std::string::npos) every_unit = unit;
    else if (std::none_of(entries.begin(), entries.end(),
                          [&](const LibraryEntry& e) { return e.name == cls && !e.file.empty(); }))
      throw std::invalid_argument("--model-unit " + spec + ": no --model for '" + cls + "'");
    else class_unit[cls] = unit;
  }
  for (const auto& e : entries) {
    if (e.file.empty()) continue;
    const auto configured = effective.entries.find(e.name);
    std::string unit = configured == effective.entries.end() ? "" : configured->second.model_unit;
    if (auto it = class_unit.find(e.name); it != class_unit.end()) unit = it->second;
    else if (unit.empty()) unit = every_unit;
    if (!unit.empty()) effective.entries[e.name].model_unit = unit;
  }
}

// Entry `index` of `count` built and written at each LOD that shrinks it; its manifest record.
json write_entry(const LibraryEntry& e, std::size_t index, std::size_t count, const VehiclesSettings& effective,
                 const VehiclesSettings& cfg, const fs::path& dir, const GltfOptions& gopt) {
  const auto te = std::chrono::steady_clock::now();
  BuiltVehicle built = build_vehicle(e.name, e.vclass, e.file, effective);
  for (const auto& w : built.model.warnings) spdlog::warn("{}: {}", e.name, w);
  json lods = json::array();
  int default_lod = 0;
  std::size_t previous = SIZE_MAX;
  for (std::size_t k = 0; k < cfg.lod_ratios.size(); ++k) {
    VehicleModel lod =
        cfg.lod_ratios[k] >= 1 ? built.model : simplify_vehicle(built.model, cfg.lod_ratios[k], cfg.lod_max_error_m);
    const std::size_t tris = lod.triangle_count();
    if (tris >= previous) continue;  // cannot shrink further: no duplicate LOD
    previous = tris;
    const double h = k == 0 ? 0.0 : hausdorff_distance(built.model, lod);
    const std::string file = e.name + "_lod" + std::to_string(lods.size()) + ".glb";
    write_glb(to_scene(lod), (dir / file).string(), gopt);
    const auto er = welded_edge_report(lod);
    if (h <= cfg.lod_tolerance_m) default_lod = static_cast<int>(lods.size());
    lods.push_back({{"lod", lods.size()},
                    {"file", file},
                    {"ratio", cfg.lod_ratios[k]},
                    {"triangles", tris},
                    {"hausdorff_m", h},
                    {"boundary_edges", er.boundary_edges},
                    {"area_by_material_m2", lod.area_by_material()}});
  }
  built.record["lods"] = lods;
  built.record["default_lod"] = default_lod;
  built.record["build_seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - te).count();
  spdlog::info("vehicles {}/{}: {} ({} triangles, {} LODs, default LOD {})", index + 1, count, e.name,
               built.model.triangle_count(), lods.size(), default_lod);
  return built.record;
}

json custom_materials_json() {
  json materials = json::array();
  for (const auto& cm : custom_materials())
    materials.push_back({{"name", cm.name},
                         {"eps_r", cm.eps_r},
                         {"sigma_s_per_m", cm.sigma_s_per_m},
                         {"thickness_m", cm.thickness_m},
                         {"basis", cm.basis}});
  return materials;
}

}  // namespace

json run_vehicles_stage(const VehiclesArgs& args, const Settings& settings, const std::vector<std::string>& argv) {
  const auto t0 = std::chrono::steady_clock::now();
  if (args.out.empty()) throw std::invalid_argument("--out is required");
  const VehiclesSettings& cfg = settings.vehicles;
  std::vector<InputFile> inputs;
  if (!settings.file.empty()) inputs.push_back({"config", settings.file});

  // Entries: built-in classes, then imported models replacing a class, then vTypes.
  std::vector<LibraryEntry> entries;
  std::vector<std::string> classes = cfg.classes;
  if (classes.empty())
    for (const auto& c : vehicle_classes()) classes.push_back(c.vclass);
  for (const auto& c : classes) entries.push_back({c, c, ""});
  add_models(args, entries, inputs);
  const std::vector<SumoVType> vtypes = add_vtypes(args, entries, inputs);
  VehiclesSettings effective = cfg;
  for (const auto& vt : vtypes) {
    auto& e = effective.entries[vt.id];
    if (e.dims.length <= 0) e.dims.length = vt.length;
    if (e.dims.width <= 0) e.dims.width = vt.width;
    if (e.dims.height <= 0) e.dims.height = vt.height;
  }
  apply_model_units(args, entries, effective);

  StagedDirectory out(args.out);
  GltfOptions gopt;
  gopt.draco = cfg.draco;
  gopt.draco_position_bits = cfg.draco_position_bits;
  if (gopt.draco) spdlog::warn("the vehicle library {}", kDracoReadersNote);
  json list = json::array();
  for (std::size_t i = 0; i < entries.size(); ++i)
    list.push_back(write_entry(entries[i], i, entries.size(), effective, cfg, out.path(), gopt));
  json manifest = {{"frame", "metres; z up; front along +x; origin at the front-bumper centre on the ground"},
                   {"vehicles", list},
                   {"custom_materials", custom_materials_json()},
                   {"provenance", provenance("vehicles", inputs, effective.to_json(), argv)}};
  settings.record_sets(manifest["provenance"]);
  // Build times vary run to run; keep them out of the byte-compared manifest.
  json timings = json::object();
  for (auto& v : manifest["vehicles"]) {
    timings[v["name"].get<std::string>()] = v["build_seconds"];
    v.erase("build_seconds");
  }
  write_file_atomic(out.path() / "manifest.json", manifest.dump(2) + "\n");
  write_file_atomic(out.path() / "timings.json", timings.dump(2) + "\n");
  if (args.preview && run_python_script("vehicles_preview.py", {out.path().string()})) {
    manifest["files"] = {{"preview", "preview.png"}};
    write_file_atomic(out.path() / "manifest.json", manifest.dump(2) + "\n");
  }
  out.commit();
  spdlog::info("vehicle library written to {} ({} entries, {:.2f} s)", args.out, entries.size(),
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return manifest;
}

}  // namespace raysweep::pipeline
