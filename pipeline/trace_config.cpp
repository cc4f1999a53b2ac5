#include "pipeline/trace_config.hpp"

#include "pipeline/config.hpp"
#include "pipeline/config_tables.hpp"

namespace raysweep::pipeline {

TraceSettings load_trace_config(const std::string& path) {
  TraceSettings s;
  if (path.empty()) return s;
  const ConfigFile file(path);
  file.read(radio_table(), s);
  file.read(tracer_table(), s);
  file.read(materials_table(), s);
  // Settings that depend on each other (the schema checks each key alone).
  try {
    tracer::validate(s.tracer, s.radio);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(path + ": " + e.what());
  }
  return s;
}

nlohmann::json TraceSettings::to_json() const {
  return {{"radio", radio_table().write(*this)},
          {"tracer", tracer_table().write(*this)},
          {"materials", materials_table().write(*this)}};
}

}  // namespace raysweep::pipeline
