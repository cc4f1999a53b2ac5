#include "meshkit/city.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "meshkit/extrude.hpp"
#include "meshkit/materials.hpp"

namespace raysweep::meshkit {

namespace {

// Segments of the network on a uniform grid, for distance queries.
class SegmentGrid {
 public:
  SegmentGrid(const std::vector<std::vector<Vec2>>& lanes, double cell) : cell_(cell) {
    for (const auto& lane : lanes)
      for (std::size_t i = 0; i + 1 < lane.size(); ++i) {
        const auto id = segments_.size();
        segments_.push_back({lane[i], lane[i + 1]});
        for (long cx = key(std::min(lane[i][0], lane[i + 1][0])); cx <= key(std::max(lane[i][0], lane[i + 1][0])); ++cx)
          for (long cy = key(std::min(lane[i][1], lane[i + 1][1])); cy <= key(std::max(lane[i][1], lane[i + 1][1])); ++cy)
            cells_[pack(cx, cy)].push_back(id);
      }
  }
  bool empty() const { return segments_.empty(); }

  template <class F>
  void for_each_near(double xmin, double ymin, double xmax, double ymax, F&& f) const {
    std::vector<std::size_t> seen;
    for (long cx = key(xmin); cx <= key(xmax); ++cx)
      for (long cy = key(ymin); cy <= key(ymax); ++cy) {
        auto it = cells_.find(pack(cx, cy));
        if (it == cells_.end()) continue;
        for (auto id : it->second) seen.push_back(id);
      }
    std::sort(seen.begin(), seen.end());
    seen.erase(std::unique(seen.begin(), seen.end()), seen.end());
    for (auto id : seen) f(segments_[id]);
  }

 private:
  long key(double v) const { return static_cast<long>(std::floor(v / cell_)); }
  static long long pack(long x, long y) { return (static_cast<long long>(x) << 32) ^ (y & 0xffffffffLL); }
  double cell_;
  std::vector<std::array<Vec2, 2>> segments_;
  std::unordered_map<long long, std::vector<std::size_t>> cells_;
};

double point_segment_distance(Vec2 p, Vec2 a, Vec2 b) {
  const double dx = b[0] - a[0], dy = b[1] - a[1];
  const double l2 = dx * dx + dy * dy;
  double t = l2 > 0 ? ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2 : 0;
  t = std::clamp(t, 0.0, 1.0);
  return std::hypot(p[0] - (a[0] + t * dx), p[1] - (a[1] + t * dy));
}

double cross(Vec2 o, Vec2 a, Vec2 b) { return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]); }

double segment_distance(Vec2 a, Vec2 b, Vec2 c, Vec2 d) {
  const double d1 = cross(a, b, c), d2 = cross(a, b, d), d3 = cross(c, d, a), d4 = cross(c, d, b);
  if (((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0)) && d1 != 0 && d2 != 0 && d3 != 0 && d4 != 0) return 0;
  return std::min({point_segment_distance(a, c, d), point_segment_distance(b, c, d), point_segment_distance(c, a, b),
                   point_segment_distance(d, a, b)});
}

struct Prepared {
  FootprintResult fp;
  ResolvedHeight height;
  std::string material, material_source, material_warning;
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;
};

std::vector<std::string> repair_names(const FootprintRepairs& r) {
  std::vector<std::string> names;
  if (r.duplicate_nodes) names.push_back("duplicate_nodes");
  if (r.reoriented) names.push_back("reoriented");
  if (r.self_intersection) names.push_back("self_intersection");
  if (r.holes_fixed) names.push_back("hole_touching_or_outside");
  if (r.rings_merged) names.push_back("overlapping_rings_merged");
  return names;
}

// The building's material: the first of its material tags that maps to a
// P.2040 material (through `material_map`, then the built-in table), else
// the default; unmapped tags noted in material_warning.
void resolve_material(const OsmBuilding& b, const CityOptions& opt, Prepared& p) {
  p.material = opt.default_material;
  p.material_source = "default";
  for (const auto& [key, value] : {std::pair{"building:material", &b.material},
                                   std::pair{"building:facade:material", &b.facade_material}}) {
    if (value->empty()) continue;
    std::optional<std::string> m;
    if (auto it = opt.material_map.find(*value); it != opt.material_map.end())
      m = it->second;
    else
      m = itu_material_from_osm(*value);
    if (m) {
      p.material = *m;
      p.material_source = key;
      break;
    }
    p.material_warning += std::string(key) + "='" + *value + "' has no P.2040 mapping; ";
  }
}

// One building's repaired footprint, height, material and footprint box.
void prepare_building(const OsmBuilding& b, const CityOptions& opt, Prepared& p) {
  p.fp = make_footprint(b.outers, b.inners, opt.footprint);
  BuildingTags tags;
  auto cstr = [](const std::string& s) { return s.empty() ? nullptr : s.c_str(); };
  tags.height = cstr(b.height);
  tags.min_height = cstr(b.min_height);
  tags.levels = cstr(b.levels);
  tags.min_level = cstr(b.min_level);
  tags.roof_levels = cstr(b.roof_levels);
  p.height = resolve_height(tags, opt.heights);
  resolve_material(b, opt, p);
  if (p.fp.footprint) {
    p.xmin = p.ymin = std::numeric_limits<double>::infinity();
    p.xmax = p.ymax = -p.xmin;
    for (const auto& poly : p.fp.footprint->polygons)
      for (const Vec2& v : poly.outer) {
        p.xmin = std::min(p.xmin, v[0]), p.xmax = std::max(p.xmax, v[0]);
        p.ymin = std::min(p.ymin, v[1]), p.ymax = std::max(p.ymax, v[1]);
      }
  }
}

// Footprints are independent: repaired in parallel, each into its own slot,
// so that the assembly in input order gives object and face ids that do not
// depend on the thread count.
std::vector<Prepared> prepare_buildings(const OsmBuildings& osm, const CityOptions& opt, const Progress& progress) {
  const std::size_t n = osm.buildings.size();
  std::vector<Prepared> prep(n);
  std::atomic<std::size_t> done{0};
  tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
    prepare_building(osm.buildings[i], opt, prep[i]);
    const std::size_t d = ++done;
    if (progress && (d % 256 == 0 || d == n)) progress(d, n);
  });
  return prep;
}

// Whether footprint p comes within `d` of a lane segment (or holds one's
// start).
bool near_lanes(const Prepared& p, const SegmentGrid& grid, double d) {
  double best = std::numeric_limits<double>::infinity();
  const Footprint& f = *p.fp.footprint;
  grid.for_each_near(p.xmin - d, p.ymin - d, p.xmax + d, p.ymax + d, [&](const std::array<Vec2, 2>& s) {
    if (best == 0) return;
    for (const auto& poly : f.polygons)
      for (std::size_t k = 0; k < poly.outer.size(); ++k)
        best = std::min(best, segment_distance(poly.outer[k], poly.outer[(k + 1) % poly.outer.size()], s[0], s[1]));
    if (footprint_contains(f, s[0])) best = 0;
  });
  return !(best > d);
}

// The area of interest: which buildings have a footprint inside the clip box
// or near the lanes; the others noted in the report.
std::vector<bool> clip_to_area(const OsmBuildings& osm, const std::vector<Prepared>& prep,
                               const std::vector<std::vector<Vec2>>& lanes, const CityOptions& opt, CityReport& rep) {
  const std::size_t n = prep.size();
  std::vector<bool> keep(n, false);
  const SegmentGrid grid(lanes, std::max(opt.clip_distance_m, 25.0));
  const bool distance_clip = opt.clip_distance_m > 0 && !grid.empty();
  for (std::size_t i = 0; i < n; ++i) {
    const Prepared& p = prep[i];
    const std::string& id = osm.buildings[i].source_id;
    if (!p.fp.footprint) {
      rep.skipped[p.fp.skip_reason].push_back(id);
      rep.warnings.push_back(id + ": skipped (" + p.fp.skip_reason + "): " + p.fp.detail);
      continue;
    }
    if (opt.clip_bbox) {
      const auto& bb = *opt.clip_bbox;
      if (p.xmax < bb[0] || p.xmin > bb[2] || p.ymax < bb[1] || p.ymin > bb[3]) {
        rep.skipped["outside_area_of_interest"].push_back(id);
        continue;
      }
    } else if (distance_clip && !near_lanes(p, grid, opt.clip_distance_m)) {
      rep.skipped["outside_area_of_interest"].push_back(id);
      continue;
    }
    keep[i] = true;
  }
  return keep;
}

// Outlines whose parts are mapped are drawn by the parts: an outline
// holding a kept part's centroid is dropped.
void yield_outlines_to_parts(const OsmBuildings& osm, const std::vector<Prepared>& prep, std::vector<bool>& keep,
                             CityReport& rep) {
  const std::size_t n = prep.size();
  std::vector<std::size_t> parts;
  for (std::size_t i = 0; i < n; ++i)
    if (keep[i] && osm.buildings[i].is_part) parts.push_back(i);
  if (parts.empty()) return;
  for (std::size_t i = 0; i < n; ++i) {
    if (!keep[i] || osm.buildings[i].is_part) continue;
    for (std::size_t j : parts) {
      const Vec2 c = prep[j].fp.footprint->centroid;
      if (c[0] < prep[i].xmin || c[0] > prep[i].xmax || c[1] < prep[i].ymin || c[1] > prep[i].ymax) continue;
      if (footprint_contains(*prep[i].fp.footprint, c)) {
        keep[i] = false;
        rep.skipped["replaced_by_parts"].push_back(osm.buildings[i].source_id);
        break;
      }
    }
  }
}

// Extrudes one kept building into the scene (faces from `next_face` on) and
// records it in the report; its footprint box joins `extent`.
void add_building(const OsmBuilding& b, const Prepared& p, Scene& scene, std::uint32_t& next_face, Bounds& extent,
                  CityReport& rep) {
  const Footprint& f = *p.fp.footprint;
  if (!p.height.warning.empty()) rep.warnings.push_back(b.source_id + ": " + p.height.warning);
  if (!p.material_warning.empty()) {
    rep.warnings.push_back(b.source_id + ": " + p.material_warning + "using " + p.material);
    ++rep.repairs["material_unknown"];
  }
  const std::uint32_t object = scene.add_object("building", b.source_id);
  Mesh& mesh = scene.mesh_for(p.material, "buildings");
  const ExtrudeStats es = extrude_footprint(f, p.height.base_m, p.height.top_m, object, next_face, mesh);
  BuildingRecord r;
  r.id = b.source_id;
  r.part = b.is_part;
  r.base_m = p.height.base_m;
  r.top_m = p.height.top_m;
  r.height_source = to_string(p.height.source);
  r.material = p.material;
  r.material_source = p.material_source;
  r.area_m2 = f.area_m2;
  r.centroid = f.centroid;
  r.repairs = repair_names(f.repairs);
  r.simplified = f.simplified;
  r.triangles = es.triangles;
  for (const auto& name : r.repairs) ++rep.repairs[name];
  if (!p.height.warning.empty()) ++rep.repairs["height_tag_unusable"];
  rep.simplified += f.simplified;
  rep.simplification_undone += f.simplification_undone;
  rep.vertices_in += f.vertices_in;
  rep.vertices_out += f.vertices_out;
  rep.wall_faces += es.faces - 2;
  extent.extend({p.xmin, p.ymin, 0});
  extent.extend({p.xmax, p.ymax, 0});
  rep.kept.push_back(std::move(r));
}

// The ground: one rectangle (two triangles, one face) over `extent` and a
// margin.
void add_ground(const CityOptions& opt, const Bounds& extent, Scene& scene, std::uint32_t& next_face) {
  const double m = opt.ground_margin_m;
  const std::uint32_t object = scene.add_object("ground", "ground");
  Mesh& g = scene.mesh_for(opt.ground_material, "ground");
  const auto v0 = static_cast<std::uint32_t>(g.vertices.size());
  g.vertices.push_back({extent.min[0] - m, extent.min[1] - m, 0});
  g.vertices.push_back({extent.max[0] + m, extent.min[1] - m, 0});
  g.vertices.push_back({extent.max[0] + m, extent.max[1] + m, 0});
  g.vertices.push_back({extent.min[0] - m, extent.max[1] + m, 0});
  const std::uint32_t face = next_face++;
  g.triangles.push_back({v0, v0 + 1, v0 + 2});
  g.triangles.push_back({v0, v0 + 2, v0 + 3});
  g.triangle_object.insert(g.triangle_object.end(), {object, object});
  g.triangle_face.insert(g.triangle_face.end(), {face, face});
}

}  // namespace

CityScene build_city(const OsmBuildings& osm, const std::vector<std::vector<Vec2>>& lanes,
                     const CityOptions& opt, const Progress& progress) {
  CityScene city;
  CityReport& rep = city.report;
  rep.candidates = osm.buildings.size() + osm.skipped.size();
  for (const auto& s : osm.skipped) {
    rep.skipped[s.reason].push_back(s.source_id);
    rep.warnings.push_back(s.source_id + ": skipped (" + s.reason + "): " + s.detail);
  }
  const std::vector<Prepared> prep = prepare_buildings(osm, opt, progress);
  std::vector<bool> keep = clip_to_area(osm, prep, lanes, opt, rep);
  if (opt.outlines_yield_to_parts) yield_outlines_to_parts(osm, prep, keep, rep);

  Scene& scene = city.scene;
  std::uint32_t next_face = 0;
  Bounds extent = Bounds::none();
  for (std::size_t i = 0; i < prep.size(); ++i)
    if (keep[i]) add_building(osm.buildings[i], prep[i], scene, next_face, extent, rep);
  for (const auto& lane : lanes)
    for (const Vec2& v : lane) extent.extend({v[0], v[1], 0});
  if (opt.ground && !extent.empty()) add_ground(opt, extent, scene, next_face);
  for (const Mesh& m : scene.meshes) rep.triangles_by_material[m.material] += m.triangles.size();
  return city;
}

nlohmann::json to_json(const CityReport& rep) {
  using nlohmann::json;
  json j;
  std::size_t skipped = 0;
  json skipped_j = json::object();
  for (const auto& [reason, ids] : rep.skipped) {
    skipped += ids.size();
    skipped_j[reason] = {{"count", ids.size()}, {"ids", ids}};
  }
  std::size_t repaired = 0;
  std::map<std::string, std::size_t> by_source;
  for (const auto& b : rep.kept) {
    // Winding is a normalisation (OSM prescribes none), not a repair of the map.
    repaired += std::any_of(b.repairs.begin(), b.repairs.end(), [](const std::string& r) { return r != "reoriented"; });
    ++by_source[b.height_source];
  }
  std::size_t total_triangles = 0;
  for (const auto& [m, t] : rep.triangles_by_material) total_triangles += t;
  j["buildings"] = {
      {"candidates", rep.candidates},
      {"kept", rep.kept.size()},
      {"repaired", repaired},
      {"skipped", skipped},
      {"skipped_by_reason", skipped_j},
      {"repairs", rep.repairs},
      {"height_sources", by_source},
      {"simplified", rep.simplified},
      {"simplification_undone", rep.simplification_undone},
      {"footprint_vertices_in", rep.vertices_in},
      {"footprint_vertices_out", rep.vertices_out},
      {"wall_faces", rep.wall_faces},
  };
  j["triangles"] = {{"total", total_triangles}, {"by_material", rep.triangles_by_material}};
  json list = json::array();
  for (const auto& b : rep.kept) {
    list.push_back({{"id", b.id},
                    {"part", b.part},
                    {"base_m", b.base_m},
                    {"height_m", b.top_m},
                    {"height_source", b.height_source},
                    {"material", b.material},
                    {"material_source", b.material_source},
                    {"area_m2", b.area_m2},
                    {"centroid", {b.centroid[0], b.centroid[1]}},
                    {"repairs", b.repairs},
                    {"simplified", b.simplified},
                    {"triangles", b.triangles}});
  }
  j["building_list"] = std::move(list);
  j["warnings"] = rep.warnings;
  return j;
}

}  // namespace raysweep::meshkit
