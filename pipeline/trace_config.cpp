#include "pipeline/trace_config.hpp"

#include "meshkit/materials.hpp"
#include "pipeline/config.hpp"
#include "pipeline/toml_fields.hpp"

namespace raysweep::pipeline {

using namespace toml_fields;

TraceSettings load_trace_config(const std::string& path) {
  TraceSettings s;
  if (path.empty()) return s;
  load_scene_config(path);  // validates the file and its top-level sections
  const toml::table root = toml::parse_file(path);
  auto& r = s.radio;
  auto& t = s.tracer;
  if (const toml::table* radio = root["radio"].as_table()) {
    for (auto&& [k, node] : *radio) {
      const std::string key(k.str()), full = "radio." + key;
      try {
        if (key == "frequency_hz") r.frequency_hz = number(path, full, node);
        else if (key == "bandwidth_hz") r.bandwidth_hz = number(path, full, node);
        else if (key == "tx_power_dbm") r.tx_power_dbm = number(path, full, node);
        else if (key == "antenna") r.antenna.pattern = tracer::parse_antenna_pattern(text(path, full, node));
        else if (key == "polarization") r.antenna.polarization = tracer::parse_polarization(text(path, full, node));
        else throw ConfigError(where(path, full, node) + ": unknown key");
      } catch (const std::invalid_argument& e) {
        throw ConfigError(where(path, full, node) + ": " + e.what());
      }
    }
  }
  if (const toml::table* tracer = root["tracer"].as_table()) {
    for (auto&& [k, node] : *tracer) {
      const std::string key(k.str()), full = "tracer." + key;
      if (key == "max_depth") t.max_depth = integer(path, full, node);
      else if (key == "los") t.los = boolean(path, full, node);
      else if (key == "specular") t.specular = boolean(path, full, node);
      else if (key == "refraction") t.refraction = boolean(path, full, node);
      else if (key == "rays_per_source") t.rays_per_source = integer(path, full, node);
      else if (key == "reception_radius_factor") t.reception_radius_factor = number(path, full, node);
      else if (key == "max_transmissions") t.max_transmissions = integer(path, full, node);
      else if (key == "sbr_transmission_loss_db") t.sbr_transmission_loss_db = number(path, full, node);
      else if (key == "candidates") {
        const std::string v = text(path, full, node);
        if (v == "sbr") t.candidates = tracer::CandidateSearch::sbr;
        else if (v == "exhaustive") t.candidates = tracer::CandidateSearch::exhaustive;
        else throw ConfigError(where(path, full, node) + ": expected \"sbr\" or \"exhaustive\"");
      } else if (key == "diffuse" || key == "diffraction") {
        if (boolean(path, full, node))
          throw ConfigError(where(path, full, node) + ": not implemented yet (diffuse scattering and diffraction "
                                                      "arrive with the tracer fidelity work); set it to false");
      } else {
        throw ConfigError(where(path, full, node) + ": unknown key");
      }
    }
  }
  if (const toml::table* mats = root["materials"].as_table()) {
    for (auto&& [k, node] : *mats) {
      const std::string name(k.str());
      const toml::table* mt = node.as_table();
      if (!mt) throw ConfigError(where(path, "materials." + name, node) + ": expected a table");
      const auto canonical = meshkit::radio_material_from_id(name);
      if (!canonical) throw ConfigError(where(path, "materials." + name, node) + ": unknown material");
      tracer::MaterialOverride o;
      for (auto&& [mk, mv] : *mt) {
        const std::string key(mk.str()), full = "materials." + name + "." + key;
        if (key == "eps_r") o.eps_r = number(path, full, mv);
        else if (key == "sigma") o.sigma = number(path, full, mv);
        else if (key == "thickness_m") o.thickness_m = number(path, full, mv);
        else throw ConfigError(where(path, full, mv) + ": unknown key (eps_r, sigma, thickness_m)");
      }
      t.materials[*canonical] = o;
    }
  }
  try {
    tracer::validate(t, r);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(path + ": " + e.what());
  }
  return s;
}

nlohmann::json TraceSettings::to_json() const {
  static const char* patterns[] = {"isotropic", "dipole", "halfwave"};
  nlohmann::json materials = nlohmann::json::object();
  for (const auto& [name, o] : tracer.materials) {
    nlohmann::json m = nlohmann::json::object();
    if (o.eps_r) m["eps_r"] = *o.eps_r;
    if (o.sigma) m["sigma"] = *o.sigma;
    if (o.thickness_m) m["thickness_m"] = *o.thickness_m;
    materials[name] = m;
  }
  return {{"radio",
           {{"frequency_hz", radio.frequency_hz},
            {"bandwidth_hz", radio.bandwidth_hz},
            {"tx_power_dbm", radio.tx_power_dbm},
            {"antenna", patterns[static_cast<int>(radio.antenna.pattern)]},
            {"polarization", radio.antenna.polarization == tracer::Polarization::V ? "V" : "H"}}},
          {"tracer",
           {{"max_depth", tracer.max_depth},
            {"los", tracer.los},
            {"specular", tracer.specular},
            {"refraction", tracer.refraction},
            {"rays_per_source", tracer.rays_per_source},
            {"reception_radius_factor", tracer.reception_radius_factor},
            {"candidates", tracer.candidates == tracer::CandidateSearch::sbr ? "sbr" : "exhaustive"},
            {"max_transmissions", tracer.max_transmissions},
            {"sbr_transmission_loss_db", tracer.sbr_transmission_loss_db}}},
          {"materials", materials}};
}

}  // namespace raysweep::pipeline
