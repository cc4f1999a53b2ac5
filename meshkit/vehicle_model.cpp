#include "meshkit/vehicle_model.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <regex>

#include "meshkit/planar_faces.hpp"

namespace raysweep::meshkit {

Bounds VehicleModel::bounds() const {
  Bounds b = Bounds::none();
  for (const auto& p : parts)
    for (const auto& t : p.triangles)
      for (auto v : t) b.extend(p.vertices[v]);
  return b;
}

VehicleDims VehicleModel::dims() const {
  const Bounds b = bounds();
  if (b.empty()) return {};
  return {b.max[0] - b.min[0], b.max[1] - b.min[1], b.max[2] - b.min[2]};
}

std::size_t VehicleModel::triangle_count() const {
  std::size_t n = 0;
  for (const auto& p : parts) n += p.triangles.size();
  return n;
}

static double tri_area(const std::vector<Vec3>& v, const Tri& t) {
  const Vec3 &a = v[t[0]], &b = v[t[1]], &c = v[t[2]];
  const double ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
  const double wx = c[0] - a[0], wy = c[1] - a[1], wz = c[2] - a[2];
  const double nx = uy * wz - uz * wy, ny = uz * wx - ux * wz, nz = ux * wy - uy * wx;
  return 0.5 * std::sqrt(nx * nx + ny * ny + nz * nz);
}

std::map<std::string, double> VehicleModel::area_by_material() const {
  std::map<std::string, double> area;
  for (const auto& p : parts)
    for (const auto& t : p.triangles) area[p.material] += tri_area(p.vertices, t);
  return area;
}

Scene to_scene(const VehicleModel& model) {
  Scene scene;
  std::uint32_t next_face = 0;
  for (const auto& part : model.parts) {
    if (part.triangles.empty()) continue;
    const std::uint32_t object = scene.add_object("part", part.name);
    Mesh& mesh = scene.mesh_for(part.material, "vehicle");
    const auto base = static_cast<std::uint32_t>(mesh.vertices.size());
    mesh.vertices.insert(mesh.vertices.end(), part.vertices.begin(), part.vertices.end());
    auto faces = group_planar_faces(part.vertices, part.triangles, next_face);
    for (std::size_t t = 0; t < part.triangles.size(); ++t) {
      const Tri& tri = part.triangles[t];
      mesh.triangles.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
      mesh.triangle_object.push_back(object);
      mesh.triangle_face.push_back(faces[t]);
      next_face = std::max(next_face, faces[t] + 1);
    }
  }
  return scene;
}

VehicleModel from_scene(const Scene& scene, const std::string& name) {
  VehicleModel model;
  model.name = name;
  model.parts.resize(scene.objects.size());
  for (std::size_t o = 0; o < scene.objects.size(); ++o) model.parts[o].name = scene.objects[o].source_id;
  for (const Mesh& mesh : scene.meshes) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> remap;  // (part, mesh vertex) -> part vertex
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      const std::uint32_t o = mesh.triangle_object[t];
      VehiclePart& part = model.parts.at(o);
      part.material = mesh.material;
      Tri out;
      for (int k = 0; k < 3; ++k) {
        auto [it, fresh] = remap.emplace(std::make_pair(o, mesh.triangles[t][k]),
                                         static_cast<std::uint32_t>(part.vertices.size()));
        if (fresh) part.vertices.push_back(mesh.vertices[mesh.triangles[t][k]]);
        out[k] = it->second;
      }
      part.triangles.push_back(out);
    }
  }
  return model;
}

namespace {

void transform(VehicleModel& m, const std::function<Vec3(const Vec3&)>& f) {
  for (auto& p : m.parts)
    for (auto& v : p.vertices) v = f(v);
}

// Part-name evidence for where the front is: +1 for front words, -1 for rear.
int front_evidence(const std::string& name) {
  static const std::regex front(R"((^|[^a-z])(front|head|headlight|windscreen|windshield|bonnet|hood)|_f([lr])?($|[_.\d])|(^|_)f(l|r)($|_))",
                                std::regex::icase);
  static const std::regex rear(R"((^|[^a-z])(rear|back|tail|trunk|boot|brake)|_[br]([lr])?($|[_.\d])|(^|_)(b|r)(l|r)($|_))",
                               std::regex::icase);
  const bool f = std::regex_search(name, front), r = std::regex_search(name, rear);
  return f == r ? 0 : (f ? 1 : -1);
}

}  // namespace

NormalizeReport normalize(VehicleModel& model, const VehicleDims& target) {
  NormalizeReport rep;
  Bounds b = model.bounds();
  // Length along the longer horizontal axis.
  if (b.max[1] - b.min[1] > b.max[0] - b.min[0]) {
    transform(model, [](const Vec3& v) { return Vec3{v[1], -v[0], v[2]}; });  // rotate -90 deg about z
    rep.orientation = "rotated 90 deg about z (length was along y); ";
    b = model.bounds();
  }
  // Which end is the front: the side where front-named parts sit.
  const double cx = (b.min[0] + b.max[0]) / 2;
  double vote = 0;
  for (const auto& p : model.parts) {
    const int e = front_evidence(p.name);
    if (e == 0 || p.vertices.empty()) continue;
    double mx = 0;
    for (const auto& v : p.vertices) mx += v[0];
    mx /= p.vertices.size();
    vote += e * (mx > cx ? 1 : -1);
  }
  if (vote < 0) {
    transform(model, [](const Vec3& v) { return Vec3{-v[0], -v[1], v[2]}; });  // 180 deg about z
    rep.orientation += "turned 180 deg about z (front-named parts were at -x)";
    b = model.bounds();
  } else {
    rep.orientation += vote > 0 ? "front on +x (confirmed by part names)" : "front on +x (glTF convention; no named parts)";
  }
  rep.native = model.dims();
  const double ox = b.max[0], oy = (b.min[1] + b.max[1]) / 2, oz = b.min[2];
  const double sx = target.length > 0 && rep.native.length > 0 ? target.length / rep.native.length : 1;
  const double sy = target.width > 0 && rep.native.width > 0 ? target.width / rep.native.width : 1;
  const double sz = target.height > 0 && rep.native.height > 0 ? target.height / rep.native.height : 1;
  rep.scale = {sx, sy, sz};
  transform(model, [&](const Vec3& v) { return Vec3{(v[0] - ox) * sx, (v[1] - oy) * sy, (v[2] - oz) * sz}; });
  // A mirroring scale would turn the surface inside out.
  if (sx * sy * sz < 0)
    for (auto& p : model.parts)
      for (auto& t : p.triangles) std::swap(t[1], t[2]);
  return rep;
}

Vec3 roof_mount(const VehicleModel& model, double x, double y, double offset) {
  // Highest crossing of the vertical line through (x, y) with any triangle.
  double top = -std::numeric_limits<double>::infinity();
  for (const auto& p : model.parts)
    for (const auto& t : p.triangles) {
      const Vec3 &a = p.vertices[t[0]], &b = p.vertices[t[1]], &c = p.vertices[t[2]];
      const double d = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
      if (std::abs(d) < 1e-14) continue;  // vertical triangle
      const double u = ((x - a[0]) * (c[1] - a[1]) - (y - a[1]) * (c[0] - a[0])) / d;
      const double v = ((b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0])) / d;
      if (u < -1e-9 || v < -1e-9 || u + v > 1 + 1e-9) continue;
      top = std::max(top, a[2] + u * (b[2] - a[2]) + v * (c[2] - a[2]));
    }
  if (!std::isfinite(top)) top = model.bounds().max[2];
  return {x, y, top + offset};
}

EdgeReport welded_edge_report(const VehicleModel& model) {
  Mesh all;
  std::map<Vec3, std::uint32_t> weld;
  for (const auto& p : model.parts)
    for (const auto& t : p.triangles) {
      Tri w;
      for (int k = 0; k < 3; ++k) {
        auto [it, fresh] = weld.emplace(p.vertices[t[k]], static_cast<std::uint32_t>(all.vertices.size()));
        if (fresh) all.vertices.push_back(p.vertices[t[k]]);
        w[k] = it->second;
      }
      all.triangles.push_back(w);
    }
  return edge_report(all);
}

}  // namespace raysweep::meshkit
