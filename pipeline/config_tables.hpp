// The schema of city.toml: every table and key raysweep accepts, declared once
// in config_tables.cpp (type, unit, default, range, help). Stage loaders read
// their tables through it, provenance records the effective tables it writes,
// and `raysweep config --docs` renders it as docs/config.md.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pipeline/config_schema.hpp"

namespace raysweep::pipeline {

struct CityConfig;
struct SceneConfig;
struct VehiclesConfig;
struct TrafficSettings;
struct SweepConfig;
struct TraceSettings;
struct SinrSettings;
struct Ns3Settings;
struct RadioMapSettings;

// One config file, parsed and checked against the whole schema: TOML syntax,
// unknown tables, and every key of every table (unknown, wrong type, out of
// range), so that a typo anywhere fails before any stage runs. Throws
// ConfigError naming file, line and key.
class ConfigFile {
 public:
  explicit ConfigFile(const std::string& path);
  // Reads table `t` into `cfg` when the file has it; returns whether it has.
  template <class Cfg>
  bool read(const schema::Table<Cfg>& t, Cfg& cfg) const {
    const toml::table* node = root_[t.name()].as_table();
    if (node) t.read(*node, schema::At{&src_, t.name()}, cfg);
    return node != nullptr;
  }
  const std::string& path() const { return src_.file; }
  // A ConfigError about table.key that spans several keys (end before begin):
  // at the key's line when the file gives it, else at the table's, else the file.
  [[noreturn]] void fail(const std::string& table, const std::string& key, const std::string& msg) const;
  // The table's TOML node as written (stage stamps hash it); nullptr when absent.
  const toml::node* node(const std::string& table) const { return root_.get(table); }

 private:
  schema::Source src_;
  toml::table root_;
};

const schema::Table<CityConfig>& city_table();
const schema::Table<SceneConfig>& scene_table();
const schema::Table<VehiclesConfig>& vehicles_table();
const schema::Table<TrafficSettings>& traffic_table();
const schema::Table<SweepConfig>& sweep_table();
const schema::Table<TraceSettings>& radio_table();
const schema::Table<TraceSettings>& tracer_table();
const schema::Table<TraceSettings>& materials_table();
const schema::Table<SinrSettings>& sinr_table();
const schema::Table<Ns3Settings>& ns3_table();
const schema::Table<RadioMapSettings>& radiomap_table();

// Every top-level table, in the order docs/config.md lists them.
const std::vector<const schema::TableBase*>& config_tables();

// Every table of `path` with every key, defaults filled in (`raysweep config`);
// an empty path gives the defaults.
nlohmann::json effective_config(const std::string& path);

// docs/config.md.
std::string config_docs();

}  // namespace raysweep::pipeline
