#include "pipeline/peer_export.hpp"

#include <array>
#include <fstream>
#include <map>
#include <stdexcept>
#include <tuple>

#include "pipeline/staged_output.hpp"
#include "tracer/em/coefficients.hpp"

namespace raysweep::pipeline {

namespace {

using nlohmann::json;

// One mesh per (instance, material), its vertices welded by exact equality:
// faces that share a vertex in the tracer share it in the file.
struct MeshBuilder {
  meshkit::Mesh mesh;
  std::map<std::array<double, 3>, std::uint32_t> index;

  std::uint32_t vertex(const tracer::Vec3& p) {
    const std::array<double, 3> key{p[0], p[1], p[2]};
    auto [it, added] = index.emplace(key, static_cast<std::uint32_t>(mesh.vertices.size()));
    if (added) mesh.vertices.push_back({p[0], p[1], p[2]});
    return it->second;
  }
};

std::string mesh_prefix(std::uint32_t instance) {
  return instance == 0 ? std::string("static") : "veh" + std::to_string(instance - 1);
}

json material_json(const tracer::RadioMaterial& m, const meshkit::MitsubaRadioMaterial& exported) {
  const auto& sc = m.scattering;
  return {{"relative_permittivity", m.eps_r},
          {"conductivity", m.sigma},
          {"thickness_m", m.thickness_m},
          {"exported_thickness_m", exported.thickness_m},
          {"exported_scattering_coefficient", exported.scattering_coefficient},
          {"scattering_coefficient", sc.s},
          {"xpd_coefficient", sc.xpd},
          {"lobe", tracer::scattering_lobe_name(sc.lobe)},
          {"alpha_r", sc.alpha_r},
          {"alpha_i", sc.alpha_i},
          {"lambda_r", sc.lambda_r}};
}

json nodes_json(const std::vector<tracer::Node>& nodes) {
  json out = json::array();
  for (const auto& n : nodes)
    out.push_back({{"id", n.id},
                   {"position", {n.position[0], n.position[1], n.position[2]}},
                   {"velocity", {n.velocity[0], n.velocity[1], n.velocity[2]}},
                   {"forward", {n.forward[0], n.forward[1], n.forward[2]}},
                   {"vehicle", n.vehicle}});
  return out;
}

}  // namespace

meshkit::Scene snapshot_meshes(const tracer::TraceScene& scene) {
  const auto& names = scene.material_names();
  const auto instances = static_cast<std::uint32_t>(scene.vehicles().size() + 1);
  meshkit::Scene out;
  const std::uint32_t static_object = out.add_object("static", "static");
  std::vector<std::array<tracer::Vec3, 3>> tris;
  for (std::uint32_t inst = 0; inst < instances; ++inst) {
    const std::uint32_t object =
        inst == 0 ? static_object : out.add_object("vehicle", "vehicle/" + scene.vehicles()[inst - 1].id);
    std::map<std::uint16_t, MeshBuilder> by_material;
    for (std::uint32_t f = 0; f < scene.face_count(inst); ++f) {
      const tracer::FaceRef ref{inst, f};
      tris.clear();
      scene.face_triangles(ref, tris);
      auto& b = by_material[scene.material(ref)];
      for (const auto& t : tris) {
        b.mesh.triangles.push_back({b.vertex(t[0]), b.vertex(t[1]), b.vertex(t[2])});
        b.mesh.triangle_object.push_back(object);
        b.mesh.triangle_face.push_back(f);
      }
    }
    for (auto& [material, b] : by_material) {
      b.mesh.material = names.at(material);
      b.mesh.name = mesh_prefix(inst) + "-" + b.mesh.material;
      out.meshes.push_back(std::move(b.mesh));
    }
  }
  return out;
}

std::map<std::string, meshkit::MitsubaRadioMaterial> peer_materials(const tracer::TraceScene& scene,
                                                                    const TraceSettings& settings) {
  const tracer::Electromagnetics em(scene.material_names(), settings.radio, settings.tracer.materials,
                                    settings.tracer.diffuse);
  // Without diffuse scattering raysweep's surfaces are smooth (a specular
  // reflection keeps its whole field); a peer that scales its reflections
  // by sqrt(1 - S^2) whatever it traces (Sionna RT) must see S = 0 then.
  const bool rough = settings.tracer.diffuse;
  std::map<std::string, meshkit::MitsubaRadioMaterial> out;
  for (std::size_t i = 0; i < scene.material_names().size(); ++i) {
    const auto& m = em.material(static_cast<std::uint16_t>(i));
    out[m.name] = {m.eps_r, m.sigma, m.thickness_m > 0 ? m.thickness_m : kHalfSpaceExportThicknessM,
                   rough ? m.scattering.s : 0.0, rough ? m.scattering.xpd : 0.0};
  }
  return out;
}

void write_peer_scene(const tracer::TraceScene& scene, const std::vector<tracer::Node>& nodes,
                      const TraceSettings& settings, const json& provenance, const std::string& dir) {
  const meshkit::Scene meshes = snapshot_meshes(scene);
  const auto radio = peer_materials(scene, settings);
  const tracer::Electromagnetics em(scene.material_names(), settings.radio, settings.tracer.materials,
                                    settings.tracer.diffuse);
  StagedDirectory staged(dir);
  meshkit::write_mitsuba(meshes, staged.path().string(), radio);

  const json config = settings.to_json();
  json doc = {{"format", "raysweep-peer-scene"}, {"version", 1}, {"radio", config.at("radio")},
              {"tracer", config.at("tracer")}, {"materials", json::object()}, {"nodes", nodes_json(nodes)},
              {"shapes", json::array()}, {"provenance", provenance}};
  for (std::size_t i = 0; i < scene.material_names().size(); ++i) {
    const auto& m = em.material(static_cast<std::uint16_t>(i));
    doc["materials"][m.name] = material_json(m, radio.at(m.name));
  }
  for (const auto& m : meshes.meshes) {
    if (m.triangles.empty()) continue;
    const int vehicle = m.name.rfind("veh", 0) == 0 ? std::stoi(m.name.substr(3)) : -1;
    doc["shapes"].push_back(
        {{"id", "mesh-" + m.name}, {"material", m.material}, {"vehicle", vehicle}, {"triangles", m.triangles.size()}});
  }
  std::ofstream out(staged.path() / "peer.json", std::ios::binary | std::ios::trunc);
  out << doc.dump(1) << '\n';
  if (!out.flush()) throw std::runtime_error(dir + "/peer.json: write failed");
  out.close();
  staged.commit();
}

}  // namespace raysweep::pipeline
