#include "meshkit/osm_buildings.hpp"

#include <osmium/io/any_input.hpp>
#include <osmium/osm.hpp>
#include <osmium/visitor.hpp>
#include <protozero/exception.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <string_view>
#include <unordered_map>
#include <unordered_set>

#include "meshkit/errors.hpp"

namespace raysweep::meshkit {

namespace {

using NodeId = osmium::object_id_type;

struct WayRec {
  std::vector<NodeId> nodes;
};

const char* tag_or_empty(const osmium::TagList& tags, const char* key) {
  const char* v = tags.get_value_by_key(key);
  return v ? v : "";
}

// libosmium walks a tag list string by string (strlen) until it meets the
// list's end exactly. A PBF string-table entry holding a NUL byte splits into
// two strings, an odd count of NULs makes the walk step over the end, and it
// reads on past the buffer (heap overflow found by tests/fuzz/fuzz_osm_pbf).
// Such a list is refused before any tag is looked up.
void check_tag_list(const osmium::TagList& tags, const std::string& path, const std::string& element) {
  const unsigned char* begin = tags.data() + sizeof(osmium::TagList);
  const unsigned char* end = tags.data() + tags.byte_size();
  if (end < begin) throw InputError(path, element, "corrupt tag list");
  const auto nuls = std::count(begin, end, static_cast<unsigned char>(0));
  if (nuls % 2 != 0 || (end > begin && end[-1] != 0))
    throw InputError(path, element, "corrupt tag list (a key or value holds a NUL byte)");
}

bool is_building(const osmium::TagList& tags, bool& is_part) {
  const char* b = tags.get_value_by_key("building");
  const char* p = tags.get_value_by_key("building:part");
  auto yes = [](const char* v) { return v && std::string_view(v) != "no"; };
  is_part = !yes(b) && yes(p);
  return yes(b) || yes(p);
}

void copy_tags(const osmium::TagList& tags, OsmBuilding& b) {
  b.height = tag_or_empty(tags, "height");
  b.min_height = tag_or_empty(tags, "min_height");
  b.levels = tag_or_empty(tags, "building:levels");
  b.min_level = tag_or_empty(tags, "building:min_level");
  b.roof_levels = tag_or_empty(tags, "roof:levels");
  b.material = tag_or_empty(tags, "building:material");
  b.facade_material = tag_or_empty(tags, "building:facade:material");
}

// Joins way segments end to end into closed rings, by node id. Returns the
// rings or, when some segment cannot be closed, nullopt.
std::optional<std::vector<std::vector<NodeId>>> join_rings(std::vector<std::vector<NodeId>> segments) {
  std::vector<std::vector<NodeId>> rings;
  std::vector<bool> used(segments.size(), false);
  for (std::size_t start = 0; start < segments.size(); ++start) {
    if (used[start]) continue;
    used[start] = true;
    std::vector<NodeId> ring = segments[start];
    // Extend until closed; each pass looks for a segment touching the open end.
    while (ring.size() < 2 || ring.front() != ring.back()) {
      bool extended = false;
      for (std::size_t k = 0; k < segments.size() && !extended; ++k) {
        if (used[k] || segments[k].empty()) continue;
        const auto& s = segments[k];
        if (s.front() == ring.back()) {
          ring.insert(ring.end(), s.begin() + 1, s.end());
        } else if (s.back() == ring.back()) {
          ring.insert(ring.end(), s.rbegin() + 1, s.rend());
        } else {
          continue;
        }
        used[k] = true;
        extended = true;
      }
      if (!extended) return std::nullopt;
    }
    rings.push_back(std::move(ring));
  }
  return rings;
}

// What one pass over the file keeps: every node's location, every way's
// nodes, and the ways and relations tagged as buildings.
struct PendingWay {
  NodeId id;
  OsmBuilding b;
  std::vector<NodeId> ring;
};
struct Member {
  NodeId way;
  std::string role;
};
struct PendingRelation {
  NodeId id;
  OsmBuilding b;
  std::vector<Member> members;
};
struct RawOsm {
  std::unordered_map<NodeId, osmium::Location> nodes;
  std::unordered_map<NodeId, WayRec> ways;
  std::vector<PendingWay> building_ways;
  std::vector<PendingRelation> building_relations;
  double min_lon = std::numeric_limits<double>::infinity(), min_lat = min_lon;
  double max_lon = -min_lon, max_lat = -min_lon;
};

void read_node(const osmium::Node& n, OsmBuildings& out, RawOsm& raw) {
  ++out.nodes;
  if (!n.location().valid()) return;
  raw.nodes[n.id()] = n.location();
  raw.min_lon = std::min(raw.min_lon, n.location().lon());
  raw.max_lon = std::max(raw.max_lon, n.location().lon());
  raw.min_lat = std::min(raw.min_lat, n.location().lat());
  raw.max_lat = std::max(raw.max_lat, n.location().lat());
}

void read_way(const osmium::Way& w, const std::string& path, OsmBuildings& out, RawOsm& raw) {
  ++out.ways;
  WayRec rec;
  for (const auto& nr : w.nodes()) rec.nodes.push_back(nr.ref());
  check_tag_list(w.tags(), path, "way/" + std::to_string(w.id()));
  bool part = false;
  if (is_building(w.tags(), part)) {
    PendingWay pw{w.id(), {}, rec.nodes};
    pw.b.source_id = "way/" + std::to_string(w.id());
    pw.b.is_part = part;
    copy_tags(w.tags(), pw.b);
    raw.building_ways.push_back(std::move(pw));
  }
  raw.ways.emplace(w.id(), std::move(rec));
}

void read_relation(const osmium::Relation& r, const std::string& path, OsmBuildings& out, RawOsm& raw) {
  ++out.relations;
  check_tag_list(r.tags(), path, "relation/" + std::to_string(r.id()));
  const char* type = r.tags().get_value_by_key("type");
  bool part = false;
  if (!type || (std::string_view(type) != "multipolygon" && std::string_view(type) != "building")) return;
  if (!is_building(r.tags(), part)) return;
  if (std::string_view(type) == "building") return;  // grouping relation; its ways carry the geometry
  PendingRelation pr{r.id(), {}, {}};
  pr.b.source_id = "relation/" + std::to_string(r.id());
  pr.b.is_part = part;
  copy_tags(r.tags(), pr.b);
  for (const auto& m : r.members())
    if (m.type() == osmium::item_type::way) pr.members.push_back({m.ref(), m.role()});
  raw.building_relations.push_back(std::move(pr));
}

// Runs `read`, turning what libosmium and protozero throw into InputError
// naming the file.
template <class Read>
void with_input_errors(const std::string& path, Read&& read) {
  try {
    read();
  } catch (const InputError&) {
    throw;  // already names the file and element
  } catch (const osmium::xml_error& e) {
    throw InputError(path, "line " + std::to_string(e.line) + " column " + std::to_string(e.column),
                     std::string("malformed OSM XML: ") + e.error_string);
  } catch (const osmium::format_version_error& e) {
    throw InputError(path, "", std::string("unsupported OSM format: ") + e.what());
  } catch (const osmium::io_error& e) {
    throw InputError(path, "", std::string("cannot read OSM file: ") + e.what());
  } catch (const std::runtime_error& e) {
    // libosmium reports truncated compressed input and PBF errors this way.
    throw InputError(path, "", std::string("cannot read OSM file: ") + e.what());
  } catch (const std::logic_error& e) {
    // libosmium's XML parser throws std::invalid_argument for an attribute it
    // cannot read (visible="x"), std::length_error for an over-long string
    // (found by tests/fuzz/fuzz_osm_xml).
    throw InputError(path, "", std::string("malformed OSM data: ") + e.what());
  } catch (const protozero::exception& e) {
    // A PBF block whose protobuf encoding ends early or is malformed: protozero's
    // exceptions derive from std::exception only (found by tests/fuzz/fuzz_osm_pbf).
    throw InputError(path, "", std::string("corrupt OSM PBF data: ") + e.what());
  }
}

// One pass over the file: nodes, ways and relations into `raw`, their counts
// into `out`.
void read_elements(const std::string& path, OsmBuildings& out, RawOsm& raw) {
  with_input_errors(path, [&] {
    osmium::io::File file(path);
    // PBF is read from memory: libosmium 2.19 leaks the file's descriptor when a
    // PBF block is corrupt (one per failed read, found by tests/fuzz/fuzz_osm_pbf),
    // and PBF extracts are compact. XML streams from the file.
    std::string pbf;
    if (file.format() == osmium::io::file_format::pbf) {
      std::ifstream in(path, std::ios::binary);
      if (!in) throw InputError(path, "", "cannot open OSM file");
      pbf.assign(std::istreambuf_iterator<char>(in), {});
      if (in.bad()) throw InputError(path, "", "cannot read OSM file");
      file = osmium::io::File(pbf.data(), pbf.size(), "pbf");
    }
    osmium::io::Reader reader(file, osmium::osm_entity_bits::node | osmium::osm_entity_bits::way |
                                        osmium::osm_entity_bits::relation);
    while (osmium::memory::Buffer buffer = reader.read()) {
      for (const auto& item : buffer) {
        if (item.type() == osmium::item_type::node)
          read_node(static_cast<const osmium::Node&>(item), out, raw);
        else if (item.type() == osmium::item_type::way)
          read_way(static_cast<const osmium::Way&>(item), path, out, raw);
        else if (item.type() == osmium::item_type::relation)
          read_relation(static_cast<const osmium::Relation&>(item), path, out, raw);
      }
    }
    reader.close();
  });
}

// Projects a ring of node ids; missing nodes are counted, not guessed.
std::vector<Vec2> project_ring(const RawOsm& raw, const Projector& project, const std::vector<NodeId>& ids,
                               std::size_t& missing) {
  std::vector<Vec2> pts;
  pts.reserve(ids.size());
  for (NodeId id : ids) {
    auto it = raw.nodes.find(id);
    if (it == raw.nodes.end()) {
      ++missing;
      continue;
    }
    pts.push_back(project(it->second.lon(), it->second.lat()));
  }
  return pts;
}

// The building multipolygons, each as a building or a skip; their outer
// ways into `outer_ways` (not to be drawn twice).
void assemble_relations(RawOsm& raw, const Projector& project, OsmBuildings& out,
                        std::unordered_set<NodeId>& outer_ways) {
  for (auto& pr : raw.building_relations) {
    const std::string& id = pr.b.source_id;
    std::vector<std::vector<NodeId>> outer_segs, inner_segs;
    std::size_t absent = 0;
    std::vector<NodeId> outer_way_ids;
    for (const auto& m : pr.members) {
      auto it = raw.ways.find(m.way);
      if (it == raw.ways.end()) {
        ++absent;
        continue;
      }
      (m.role == "inner" ? inner_segs : outer_segs).push_back(it->second.nodes);
      if (m.role != "inner") outer_way_ids.push_back(m.way);
    }
    if (pr.members.empty() || absent) {
      out.skipped.push_back({id, "relation_members_missing",
                             std::to_string(absent) + " of " + std::to_string(pr.members.size()) +
                                 " member ways absent from the extract"});
      continue;
    }
    auto outer_rings = join_rings(outer_segs);
    auto inner_rings = join_rings(inner_segs);
    if (!outer_rings || !inner_rings || outer_rings->empty()) {
      out.skipped.push_back({id, "rings_not_closed", "member ways do not form closed rings"});
      continue;
    }
    std::size_t missing = 0;
    for (const auto& r : *outer_rings) pr.b.outers.push_back(project_ring(raw, project, r, missing));
    for (const auto& r : *inner_rings) pr.b.inners.push_back(project_ring(raw, project, r, missing));
    if (missing) {
      out.skipped.push_back({id, "missing_nodes", std::to_string(missing) + " nodes absent from the extract"});
      continue;
    }
    outer_ways.insert(outer_way_ids.begin(), outer_way_ids.end());
    out.buildings.push_back(std::move(pr.b));
  }
}

// The building ways, each as a building or a skip.
void assemble_ways(RawOsm& raw, const Projector& project, const std::unordered_set<NodeId>& relation_outer_ways,
                   OsmBuildings& out) {
  for (auto& pw : raw.building_ways) {
    const std::string& id = pw.b.source_id;
    if (relation_outer_ways.count(pw.id) && !pw.b.is_part) {
      out.skipped.push_back({id, "drawn_by_relation", "outer member of a building multipolygon"});
      continue;
    }
    if (pw.ring.size() < 2) {
      out.skipped.push_back({id, "too_few_nodes", std::to_string(pw.ring.size()) + " node(s)"});
      continue;
    }
    if (pw.ring.front() != pw.ring.back()) {
      // A building way used only as a multipolygon member is not a building
      // by itself; any other open way is (usually clipped at the extract's edge).
      out.skipped.push_back({id, "open_way", "first and last node differ"});
      continue;
    }
    std::size_t missing = 0;
    auto ring = project_ring(raw, project, pw.ring, missing);
    if (missing) {
      out.skipped.push_back({id, "missing_nodes",
                             std::to_string(missing) + " of " + std::to_string(pw.ring.size()) +
                                 " nodes absent from the extract"});
      continue;
    }
    pw.b.outers.push_back(std::move(ring));
    out.buildings.push_back(std::move(pw.b));
  }
}

}  // namespace

OsmBuildings read_osm_buildings(const std::string& path, const Projector& project) {
  OsmBuildings out;
  RawOsm raw;
  read_elements(path, out, raw);
  if (out.nodes > 0 && std::isfinite(raw.min_lon)) {
    out.min_lon = raw.min_lon;
    out.min_lat = raw.min_lat;
    out.max_lon = raw.max_lon;
    out.max_lat = raw.max_lat;
  }
  // Relations first: their tagged outer ways must not be drawn twice.
  std::unordered_set<NodeId> relation_outer_ways;
  assemble_relations(raw, project, out, relation_outer_ways);
  assemble_ways(raw, project, relation_outer_ways, out);
  return out;
}

}  // namespace raysweep::meshkit
