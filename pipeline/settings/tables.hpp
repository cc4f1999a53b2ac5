// The schema of city.toml: every table and key raysweep accepts, declared once
// (type, unit, default, range, help) over the settings structs of this
// folder. ConfigFile checks a file against it, Settings reads its tables
// through it, provenance records the effective tables it writes, and
// `raysweep config --docs` renders it as docs/config.md.
#pragma once

#include <string>
#include <vector>

#include "pipeline/settings/schema.hpp"

namespace raysweep::pipeline {

struct CitySettings;
struct SceneSettings;
struct VehiclesSettings;
struct TrafficSettings;
struct SweepSettings;
struct TraceSettings;
struct SinrSettings;
struct Ns3Settings;
struct FeaturesSettings;
struct RadioMapSettings;

const schema::Table<CitySettings>& city_table();
const schema::Table<SceneSettings>& scene_table();
const schema::Table<VehiclesSettings>& vehicles_table();
const schema::Table<TrafficSettings>& traffic_table();
const schema::Table<SweepSettings>& sweep_table();
const schema::Table<TraceSettings>& radio_table();
const schema::Table<TraceSettings>& tracer_table();
const schema::Table<TraceSettings>& materials_table();
const schema::Table<SinrSettings>& sinr_table();
const schema::Table<Ns3Settings>& ns3_table();
const schema::Table<FeaturesSettings>& features_table();
const schema::Table<RadioMapSettings>& radiomap_table();

// Every top-level table, in the order docs/config.md lists them.
const std::vector<const schema::TableBase*>& config_tables();

// docs/config.md.
std::string config_docs();

}  // namespace raysweep::pipeline
