#include "pipeline/vtypes.hpp"

#include <cstring>
#include <filesystem>
#include <string_view>

#include "meshkit/errors.hpp"
#include "meshkit/vehicle_classes.hpp"
#include "meshkit/xml_reader.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using meshkit::InputError;

namespace {

// SUMO's predefined vType ids and their vClasses (sumo.dlr.de/docs/Vehicle_Type_Parameter_Defaults.html).
const char* builtin_vclass(const std::string& id) {
  static const std::pair<const char*, const char*> builtins[] = {
      {"DEFAULT_VEHTYPE", "passenger"}, {"DEFAULT_BIKETYPE", "bicycle"}, {"DEFAULT_TAXITYPE", "taxi"},
      {"DEFAULT_PEDTYPE", "pedestrian"}, {"DEFAULT_RAILTYPE", "rail"},   {"DEFAULT_CONTAINERTYPE", "ignoring"},
  };
  for (const auto& [name, vclass] : builtins)
    if (id == name) return vclass;
  return nullptr;
}

// The library class for a SUMO vClass; nullptr when raysweep does not model it.
const meshkit::VehicleClassInfo* library_class(const std::string& vclass) {
  if (const auto* c = meshkit::find_vehicle_class(vclass)) return c;
  // Road vehicles SUMO gives passenger-car defaults (5 x 1.8 x 1.5 m) but the library has no entry for.
  static const char* const car_like[] = {"hov", "vip", "authority", "army", "custom1", "custom2"};
  for (const char* c : car_like)
    if (vclass == c) return meshkit::find_vehicle_class("passenger");
  return nullptr;
}

ResolvedType make(const std::string& id, const meshkit::VehicleClassInfo& c, const meshkit::SumoVType* t, bool known) {
  ResolvedType r;
  r.vtype = id;
  r.vclass = c.vclass;
  r.length_m = t && t->length > 0 ? t->length : c.dims.length;
  r.width_m = t && t->width > 0 ? t->width : c.dims.width;
  r.height_m = t && t->height > 0 ? t->height : c.dims.height;
  r.known = known;
  return r;
}

void split_list(const std::string& value, std::vector<std::string>& out) {
  std::string item;
  for (char ch : value) {
    if (ch == ',' || ch == ' ' || ch == '\t' || ch == '\n' || ch == '\r') {
      if (!item.empty()) out.push_back(std::move(item));
      item.clear();
    } else {
      item += ch;
    }
  }
  if (!item.empty()) out.push_back(std::move(item));
}

}  // namespace

std::vector<SumocfgInput> sumocfg_inputs(const std::string& sumocfg_path) {
  std::vector<SumocfgInput> out;
  const fs::path dir = fs::path(sumocfg_path).parent_path();
  meshkit::XmlCallbacks cb;
  cb.start = [&](const meshkit::XmlStart& e) {
    std::string key;
    if (e.name == "route-files" || e.name == "routes") key = "route-files";
    else if (e.name == "additional-files" || e.name == "additional") key = "additional-files";
    else return;
    const char* value = e.attr("value");
    if (!value)
      throw InputError(sumocfg_path, "line " + std::to_string(e.line) + " " + std::string(e.name),
                       "has no value attribute");
    std::vector<std::string> items;
    split_list(value, items);
    for (const auto& item : items) {
      const fs::path p(item);
      out.push_back({key, (p.is_absolute() ? p : dir / p).lexically_normal().string(), e.line});
    }
  };
  meshkit::parse_xml_file(sumocfg_path, cb);
  return out;
}

void VTypeMap::add_file(const std::string& path) {
  // read_sumo_vtypes takes every <vType> start tag, so members of a
  // <vTypeDistribution> come with their own ids.
  for (auto& t : meshkit::read_sumo_vtypes(path)) {
    auto it = types_.find(t.id);
    if (it == types_.end()) {
      const std::string id = t.id;
      types_.emplace(id, Entry{std::move(t), path});
      continue;
    }
    const meshkit::SumoVType& old = it->second.type;
    if (old.vclass == t.vclass && old.length == t.length && old.width == t.width && old.height == t.height) continue;
    throw InputError(path, "line " + std::to_string(t.line) + " vType " + t.id,
                     "redefines the vType of " + it->second.file + " line " + std::to_string(old.line) +
                         " with a different vClass or dimensions");
  }
}

void VTypeMap::add_sumocfg(const std::string& sumocfg_path) {
  const auto inputs = sumocfg_inputs(sumocfg_path);
  for (const auto& in : inputs) {
    std::error_code ec;
    if (!fs::is_regular_file(in.path, ec))
      throw InputError(sumocfg_path, "line " + std::to_string(in.line) + " " + in.key,
                       "names " + in.path + ", which does not exist");
  }
  for (const auto& in : inputs) add_file(in.path);
}

std::optional<ResolvedType> VTypeMap::resolve(const std::string& type_id) const {
  if (auto it = types_.find(type_id); it != types_.end()) {
    const meshkit::SumoVType& t = it->second.type;
    const auto* c = library_class(t.vclass);
    if (!c) return std::nullopt;
    return make(type_id, *c, &t, true);
  }
  if (const char* vclass = builtin_vclass(type_id)) {
    const auto* c = library_class(vclass);
    if (!c) return std::nullopt;
    return make(type_id, *c, nullptr, true);
  }
  return make(type_id, *meshkit::find_vehicle_class("passenger"), nullptr, false);
}

std::size_t VTypeMap::size() const { return types_.size(); }

VTypeMap read_vtype_files(const std::vector<std::string>& files) {
  VTypeMap vtypes;
  for (const auto& f : files) {
    if (std::filesystem::path(f).extension() == ".sumocfg") vtypes.add_sumocfg(f);
    else vtypes.add_file(f);
  }
  return vtypes;
}

}  // namespace raysweep::pipeline
