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
        else if (key == "sensitivity_dbm") r.sensitivity_dbm = number(path, full, node);
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
        if (v == "image") t.candidates = tracer::CandidateSearch::image;
        else if (v == "sbr") t.candidates = tracer::CandidateSearch::sbr;
        else if (v == "exhaustive") t.candidates = tracer::CandidateSearch::exhaustive;
        else throw ConfigError(where(path, full, node) + ": expected \"image\", \"sbr\" or \"exhaustive\"");
      } else if (key == "diffuse") t.diffuse = boolean(path, full, node);
      else if (key == "diffuse_integration") {
        const std::string v = text(path, full, node);
        if (v == "tiles") t.diffuse_integration = tracer::DiffuseIntegration::tiles;
        else if (v == "rays") t.diffuse_integration = tracer::DiffuseIntegration::rays;
        else throw ConfigError(where(path, full, node) + ": expected \"tiles\" or \"rays\"");
      } else if (key == "diffuse_tile_m") t.diffuse_tile_m = number(path, full, node);
      else if (key == "diffuse_tile_ratio") t.diffuse_tile_ratio = number(path, full, node);
      else if (key == "diffuse_shadow_ratio") t.diffuse_shadow_ratio = number(path, full, node);
      else if (key == "diffraction") t.diffraction = boolean(path, full, node);
      else if (key == "vehicle_diffraction") t.vehicle_diffraction = boolean(path, full, node);
      else if (key == "path_threshold_db") t.path_threshold_db = number(path, full, node);
      else if (key == "range_margin_db") t.range_margin_db = number(path, full, node);
      else {
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
        else if (key == "scattering_coefficient") o.scattering_coefficient = number(path, full, mv);
        else if (key == "xpd") o.xpd = number(path, full, mv);
        else if (key == "lambda_r") o.lambda_r = number(path, full, mv);
        else if (key == "alpha_r") o.alpha_r = integer(path, full, mv);
        else if (key == "alpha_i") o.alpha_i = integer(path, full, mv);
        else if (key == "lobe") {
          try {
            o.lobe = tracer::parse_scattering_lobe(text(path, full, mv));
          } catch (const std::invalid_argument& e) {
            throw ConfigError(where(path, full, mv) + ": " + e.what());
          }
        } else
          throw ConfigError(where(path, full, mv) +
                            ": unknown key (eps_r, sigma, thickness_m, scattering_coefficient, xpd, lobe, alpha_r, "
                            "alpha_i, lambda_r)");
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
    if (o.scattering_coefficient) m["scattering_coefficient"] = *o.scattering_coefficient;
    if (o.xpd) m["xpd"] = *o.xpd;
    if (o.lobe) m["lobe"] = tracer::scattering_lobe_name(*o.lobe);
    if (o.alpha_r) m["alpha_r"] = *o.alpha_r;
    if (o.alpha_i) m["alpha_i"] = *o.alpha_i;
    if (o.lambda_r) m["lambda_r"] = *o.lambda_r;
    materials[name] = m;
  }
  return {{"radio",
           {{"frequency_hz", radio.frequency_hz},
            {"bandwidth_hz", radio.bandwidth_hz},
            {"tx_power_dbm", radio.tx_power_dbm},
            {"sensitivity_dbm", radio.sensitivity_dbm},
            {"antenna", patterns[static_cast<int>(radio.antenna.pattern)]},
            {"polarization", radio.antenna.polarization == tracer::Polarization::V ? "V" : "H"}}},
          {"tracer",
           {{"max_depth", tracer.max_depth},
            {"los", tracer.los},
            {"specular", tracer.specular},
            {"refraction", tracer.refraction},
            {"rays_per_source", tracer.rays_per_source},
            {"reception_radius_factor", tracer.reception_radius_factor},
            {"candidates", tracer.candidates == tracer::CandidateSearch::image ? "image"
                           : tracer.candidates == tracer::CandidateSearch::sbr ? "sbr"
                                                                              : "exhaustive"},
            {"max_transmissions", tracer.max_transmissions},
            {"sbr_transmission_loss_db", tracer.sbr_transmission_loss_db},
            {"diffuse", tracer.diffuse},
            {"diffuse_integration", tracer.diffuse_integration == tracer::DiffuseIntegration::tiles ? "tiles" : "rays"},
            {"diffuse_tile_m", tracer.diffuse_tile_m},
            {"diffuse_tile_ratio", tracer.diffuse_tile_ratio},
            {"diffuse_shadow_ratio", tracer.diffuse_shadow_ratio},
            {"diffraction", tracer.diffraction},
            {"vehicle_diffraction", tracer.vehicle_diffraction},
            {"path_threshold_db", tracer.path_threshold_db},
            {"range_margin_db", tracer.range_margin_db}}},
          {"materials", materials}};
}

}  // namespace raysweep::pipeline
