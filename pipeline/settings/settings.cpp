#include "pipeline/settings/settings.hpp"

#include <filesystem>
#include <stdexcept>

#include "pipeline/settings/config_file.hpp"
#include "pipeline/settings/tables.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;
using json = nlohmann::json;

json SceneSettings::to_json() const { return scene_table().write(*this); }
json VehiclesSettings::to_json() const { return vehicles_table().write(*this); }
json TrafficSettings::to_json() const { return traffic_table().write(*this); }
json SweepSettings::to_json() const { return sweep_table().write(*this); }
json SinrSettings::to_json() const { return sinr_table().write(*this); }
json Ns3Settings::to_json() const { return ns3_table().write(*this); }
json FeaturesSettings::to_json() const { return features_table().write(*this); }
json RadioMapSettings::to_json() const { return radiomap_table().write(*this); }
json TraceSettings::to_json() const {
  return {{"radio", radio_table().write(*this)},
          {"tracer", tracer_table().write(*this)},
          {"materials", materials_table().write(*this)}};
}

namespace {

fs::path relative_to(const fs::path& file, const std::string& p) {
  if (p.empty()) return {};
  const fs::path q(p);
  return q.is_absolute() ? q : (file.parent_path() / q).lexically_normal();
}

// [city] with [traffic]'s sources: exactly one of osm and mitsuba, at most
// one of sumocfg and fcd, and every input present.
void read_city(const ConfigFile& file, CitySettings& c) {
  const std::string& path = file.path();
  if (!file.read(city_table(), c)) throw ConfigError(path + ": no [city] table (name, osm, net)");
  TrafficSettings traffic;
  file.read(traffic_table(), traffic);
  c.sumocfg = traffic.sumo.sumocfg;
  c.fcd = traffic.fcd;
  if (c.osm.empty() == c.mitsuba.empty())
    file.fail("city", c.osm.empty() ? "osm" : "mitsuba", "give exactly one of city.osm and city.mitsuba");
  if (!c.sumocfg.empty() && !c.fcd.empty())
    file.fail("traffic", "fcd", "give at most one of traffic.sumocfg and traffic.fcd");
  for (const auto* p : {&c.osm, &c.net, &c.mitsuba, &c.rsus, &c.sumocfg, &c.fcd})
    if (!p->empty() && !fs::exists(*p))
      throw ConfigError(path + ": input " + *p + " not found" +
                        (p->find("shared/data") != std::string::npos
                             ? " (this recipe reads the third-party data in ../shared/data next to the checkout)"
                             : ""));
  c.out = c.out.empty() ? ("out/" + c.name) : relative_to(fs::current_path() / "x", c.out).string();
}

// Every stage table, and the checks of settings that depend on each other
// (the schema checks each key alone).
void read_stages(const ConfigFile& file, Settings& s) {
  const std::string path = file.path().empty() ? std::string("--set") : file.path();
  file.read(scene_table(), s.scene);
  file.read(vehicles_table(), s.vehicles);
  file.read(traffic_table(), s.traffic);
  file.read(radio_table(), s.trace);
  file.read(tracer_table(), s.trace);
  file.read(materials_table(), s.trace);
  try {
    tracer::validate(s.trace.tracer, s.trace.radio);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(path + ": " + e.what());
  }
  file.read(sweep_table(), s.sweep);
  if (!(s.sweep.begin_s <= s.sweep.end_s)) file.fail("sweep", "end_s", "must not be before sweep.begin_s");
  s.sinr.present = file.read(sinr_table(), s.sinr);
  try {
    s.sinr.config.check();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(path + ": [sinr]: " + e.what());
  }
  s.ns3.present = file.read(ns3_table(), s.ns3);
  s.radiomap.present = file.read(radiomap_table(), s.radiomap);
  file.read(features_table(), s.features);
}

Settings defaults() {
  Settings s;
  s.effective = effective_config("");
  return s;
}

}  // namespace

void Settings::record_sets(json& provenance) const {
  if (!sets.empty()) provenance["set"] = sets;
}

Settings load_settings(const std::string& path, const std::vector<std::string>& sets) {
  if (path.empty() && sets.empty()) return defaults();
  const ConfigFile file(path, sets);
  Settings s;
  s.file = path;
  s.sets = sets;
  s.effective = file.effective();
  read_stages(file, s);
  return s;
}

Settings load_city_settings(const std::string& path, const std::vector<std::string>& sets) {
  const ConfigFile file(path, sets);
  Settings s;
  s.file = path;
  s.sets = sets;
  s.effective = file.effective();
  read_city(file, s.city);
  read_stages(file, s);
  // SUMO runs only without a finished trace; its span matters only then.
  const TrafficArgs& t = s.traffic.sumo;
  if (s.city.fcd.empty() && !(t.end_s > t.begin_s)) file.fail("traffic", "end_s", "must be after traffic.begin_s");
  return s;
}

}  // namespace raysweep::pipeline
