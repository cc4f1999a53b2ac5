#include "meshkit/vehicle_segment.hpp"


#include <algorithm>
#include <cmath>
#include <map>
#include <regex>
#include <stdexcept>

#include "meshkit/materials.hpp"
#include "meshkit/openmesh_util.hpp"

namespace raysweep::meshkit {

SegmentationRules default_segmentation_rules() {
  SegmentationRules r;
  // Order matters: glass and lights before the generic body words, because a
  // "Window" part may use a "Paint" material in badly authored models and a
  // light lens is glass-like whatever plastic it is made of.
  r.rules = {
      {"material", "glass|window", "glass"},
      {"part", "window|windscreen|windshield|glass|glazing", "glass"},
      {"part", "light|lamp|lens|indicator|bulb|reflector|beam", "glass"},
      {"material", "rubber|tire|tyre", "rubber"},
      {"part", "tire|tyre|rubber", "rubber"},
      {"material", "paint|chrome|metal|steel|alumin|iron", "metal"},
      {"part", "body|rim|door|roof|hood|bonnet|trunk|boot|chassis|frame|cabin|engine|tank|bed|mirror|fender|"
               "wing|axle|bumper_high|holder|wheel",
       "metal"},
      {"any", "plastic|bumper|plate|grille|grill", "plastic"},
      {"any", "tissue|fabric|seat|canvas|leather|convertible", "textile"},
      {"any", "wood", "wood"},
  };
  return r;
}

namespace {

struct Compiled {
  std::string field;
  std::regex re;
  std::string material;
  std::string label;
};

std::vector<Compiled> compile(const SegmentationRules& rules) {
  std::vector<Compiled> out;
  for (std::size_t i = 0; i < rules.rules.size(); ++i) {
    const auto& r = rules.rules[i];
    if (r.field != "part" && r.field != "material" && r.field != "any")
      throw std::invalid_argument("segmentation rule " + std::to_string(i + 1) + ": field must be part, material or any");
    if (!is_radio_material(r.material))
      throw std::invalid_argument("segmentation rule " + std::to_string(i + 1) + ": unknown material '" + r.material + "'");
    try {
      out.push_back({r.field, std::regex(r.pattern, std::regex::icase | std::regex::ECMAScript), r.material,
                     "rule " + std::to_string(i + 1) + " (" + r.field + " ~ /" + r.pattern + "/)"});
    } catch (const std::regex_error& e) {
      throw std::invalid_argument("segmentation rule " + std::to_string(i + 1) + ": bad pattern '" + r.pattern +
                                  "': " + e.what());
    }
  }
  if (!is_radio_material(rules.default_material))
    throw std::invalid_argument("segmentation default material '" + rules.default_material + "' is unknown");
  return out;
}

}  // namespace

SegmentReport segment(VehicleModel& model, const SegmentationRules& rules) {
  const auto compiled = compile(rules);
  SegmentReport rep;
  std::vector<const Compiled*> match(model.parts.size(), nullptr);
  for (std::size_t p = 0; p < model.parts.size(); ++p) {
    const auto& part = model.parts[p];
    for (const auto& c : compiled) {
      const bool on_part = c.field != "material" && std::regex_search(part.name, c.re);
      const bool on_mat = c.field != "part" && std::regex_search(part.source_material, c.re);
      if (on_part || on_mat) {
        match[p] = &c;
        break;
      }
    }
  }
  const bool any_named = std::any_of(match.begin(), match.end(), [](const Compiled* c) { return c != nullptr; });
  if (!any_named && !model.parts.empty()) {
    segment_geometric(model, rules);
    rep.geometric = true;
    model.warnings.push_back("no part or material name matched a rule: segmented geometrically");
    return rep;
  }
  for (std::size_t p = 0; p < model.parts.size(); ++p) {
    auto& part = model.parts[p];
    if (match[p]) {
      part.material = match[p]->material;
      part.rule = match[p]->label;
      ++rep.by_rule;
    } else {
      part.material = rules.default_material;
      part.rule = "default";
      ++rep.by_default;
      model.warnings.push_back("part '" + part.name + "' (material '" + part.source_material +
                               "') matches no rule: using " + rules.default_material);
    }
  }
  return rep;
}

void segment_geometric(VehicleModel& model, const SegmentationRules& rules) {
  using OM = OMMesh;
  OM mesh;
  OpenMeshWelder welder(mesh);
  std::vector<std::array<Vec3, 3>> rejected;  // faces OpenMesh cannot hold (non-manifold)
  for (const auto& p : model.parts)
    for (const auto& t : p.triangles) {
      std::array<OM::VertexHandle, 3> vh;
      if (!welder.add(p.vertices[t[0]], p.vertices[t[1]], p.vertices[t[2]], vh))
        rejected.push_back({p.vertices[t[0]], p.vertices[t[1]], p.vertices[t[2]]});
    }
  mesh.request_face_normals();
  mesh.update_face_normals();

  const Bounds b = model.bounds();
  const double H = b.max[2] - b.min[2];
  // Connected components by flood fill over face adjacency.
  std::vector<int> comp(mesh.n_faces(), -1);
  int ncomp = 0;
  for (auto f : mesh.faces()) {
    if (comp[f.idx()] != -1) continue;
    std::vector<OM::FaceHandle> stack{f};
    comp[f.idx()] = ncomp;
    while (!stack.empty()) {
      auto cur = stack.back();
      stack.pop_back();
      for (auto nb : mesh.ff_range(cur))
        if (comp[nb.idx()] == -1) {
          comp[nb.idx()] = ncomp;
          stack.push_back(nb);
        }
    }
    ++ncomp;
  }
  std::vector<Bounds> cb(ncomp, Bounds::none());
  for (auto f : mesh.faces())
    for (auto v : mesh.fv_range(f)) {
      const auto& p = mesh.point(v);
      cb[comp[f.idx()]].extend({p[0], p[1], p[2]});
    }
  // A wheel: a low component that looks round from the side.
  std::vector<bool> is_wheel(ncomp, false);
  for (int c = 0; c < ncomp; ++c) {
    const double dx = cb[c].max[0] - cb[c].min[0], dy = cb[c].max[1] - cb[c].min[1], dz = cb[c].max[2] - cb[c].min[2];
    is_wheel[c] = cb[c].max[2] - b.min[2] < 0.5 * H && dz > 0.1 * H && std::abs(dx - dz) < 0.2 * std::max(dx, dz) &&
                  dy < 0.8 * dx;
  }
  VehiclePart body{"body", "", "metal", "geometric", {}, {}}, windows{"windows", "", "glass", "geometric", {}, {}},
      wheel{"wheels", "", "rubber", "geometric", {}, {}};
  auto add = [](VehiclePart& part, const Vec3& a, const Vec3& b2, const Vec3& c) {
    const auto base = static_cast<std::uint32_t>(part.vertices.size());
    part.vertices.insert(part.vertices.end(), {a, b2, c});
    part.triangles.push_back({base, base + 1, base + 2});
  };
  const double z_lo = b.min[2] + rules.window_band_low * H, z_hi = b.min[2] + rules.window_band_high * H;
  for (auto f : mesh.faces()) {
    std::array<Vec3, 3> v;
    int k = 0;
    double zc = 0;
    for (auto vh : mesh.fv_range(f)) {
      const auto& p = mesh.point(vh);
      v[k++] = {p[0], p[1], p[2]};
      zc += p[2] / 3;
    }
    const auto n = mesh.normal(f);
    if (is_wheel[comp[f.idx()]])
      add(wheel, v[0], v[1], v[2]);
    else if (zc > z_lo && zc < z_hi && std::abs(n[2]) < 0.9)  // up to ~25 deg windscreens
      add(windows, v[0], v[1], v[2]);
    else
      add(body, v[0], v[1], v[2]);
  }
  for (const auto& r : rejected) add(body, r[0], r[1], r[2]);
  if (!rejected.empty())
    model.repairs.push_back(std::to_string(rejected.size()) +
                            " non-manifold faces kept as body outside the connectivity analysis");
  model.parts.clear();
  for (auto* p : {&body, &windows, &wheel})
    if (!p->triangles.empty()) model.parts.push_back(std::move(*p));
}

}  // namespace raysweep::meshkit
