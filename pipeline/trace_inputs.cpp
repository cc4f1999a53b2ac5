#include "pipeline/trace_inputs.hpp"

#include <cmath>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>

namespace raysweep::pipeline {

namespace {

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) {
    const auto b = cell.find_first_not_of(" \t\r");
    const auto e = cell.find_last_not_of(" \t\r");
    out.push_back(b == std::string::npos ? "" : cell.substr(b, e - b + 1));
  }
  if (!line.empty() && line.back() == ',') out.push_back("");
  return out;
}

double parse_number(const std::string& s, const std::string& where, const std::string& column) {
  std::size_t used = 0;
  double v;
  try {
    v = std::stod(s, &used);
  } catch (const std::exception&) {
    throw std::invalid_argument(where + ": column '" + column + "': '" + s + "' is not a number");
  }
  if (used != s.size() || !std::isfinite(v))
    throw std::invalid_argument(where + ": column '" + column + "': '" + s + "' is not a finite number");
  return v;
}

// Calls row(cells, where) for each data line of a CSV file.
template <class F>
void for_each_row(const std::string& path, F row) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument(path + ": cannot open");
  std::string line;
  long n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    auto cells = split_csv(line);
    if (n == 1 && !cells.empty() && cells[0] == "id") continue;
    row(cells, path + ":" + std::to_string(n));
  }
}

}  // namespace

std::vector<PoseRow> read_poses_csv(const std::string& path) {
  std::vector<PoseRow> rows;
  std::set<std::string> ids;
  for_each_row(path, [&](const std::vector<std::string>& c, const std::string& where) {
    if (c.size() != 6 && c.size() != 7)
      throw std::invalid_argument(where + ": expected id,class,x,y,heading_deg,speed_mps[,z] (" +
                                  std::to_string(c.size()) + " columns)");
    PoseRow r;
    r.id = c[0];
    r.vclass = c[1];
    if (r.id.empty()) throw std::invalid_argument(where + ": empty vehicle id");
    if (!ids.insert(r.id).second) throw std::invalid_argument(where + ": duplicate vehicle id '" + r.id + "'");
    r.x = parse_number(c[2], where, "x");
    r.y = parse_number(c[3], where, "y");
    r.heading_deg = parse_number(c[4], where, "heading_deg");
    r.speed_mps = parse_number(c[5], where, "speed_mps");
    if (c.size() == 7) r.z = parse_number(c[6], where, "z");
    rows.push_back(r);
  });
  return rows;
}

std::vector<NodeRow> read_nodes_csv(const std::string& path) {
  std::vector<NodeRow> rows;
  std::set<std::string> ids;
  for_each_row(path, [&](const std::vector<std::string>& c, const std::string& where) {
    if (c.size() != 4) throw std::invalid_argument(where + ": expected id,x,y,z");
    NodeRow r;
    r.id = c[0];
    if (r.id.empty()) throw std::invalid_argument(where + ": empty node id");
    if (!ids.insert(r.id).second) throw std::invalid_argument(where + ": duplicate node id '" + r.id + "'");
    r.x = parse_number(c[1], where, "x");
    r.y = parse_number(c[2], where, "y");
    r.z = parse_number(c[3], where, "z");
    rows.push_back(r);
  });
  return rows;
}

std::string poses_csv(const std::vector<PoseRow>& rows) {
  std::ostringstream out;
  out.precision(10);
  out << "id,class,x,y,heading_deg,speed_mps,z\n";
  for (const auto& r : rows)
    out << r.id << ',' << r.vclass << ',' << r.x << ',' << r.y << ',' << r.heading_deg << ',' << r.speed_mps << ','
        << r.z << '\n';
  return out.str();
}

meshkit::Scene exclude_objects(const meshkit::Scene& in, const std::string& pattern, std::size_t* dropped) {
  if (dropped) *dropped = 0;
  if (pattern.empty()) return in;
  std::regex re;
  try {
    re = std::regex(pattern);
  } catch (const std::regex_error& e) {
    throw std::invalid_argument("--exclude-objects '" + pattern + "': not a valid regex (" + e.what() + ")");
  }
  std::vector<bool> drop(in.objects.size());
  for (std::size_t i = 0; i < in.objects.size(); ++i) {
    drop[i] = std::regex_search(in.objects[i].source_id, re);
    if (dropped && drop[i]) ++*dropped;
  }
  meshkit::Scene out;
  out.objects = in.objects;  // triangles keep referring to the same indices
  for (const auto& m : in.meshes) {
    meshkit::Mesh kept;
    kept.name = m.name;
    kept.material = m.material;
    kept.vertices = m.vertices;  // unreferenced vertices are harmless
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      const auto obj = t < m.triangle_object.size() ? m.triangle_object[t] : 0;
      if (obj < drop.size() && drop[obj]) continue;
      kept.triangles.push_back(m.triangles[t]);
      kept.triangle_object.push_back(obj);
      if (t < m.triangle_face.size()) kept.triangle_face.push_back(m.triangle_face[t]);
    }
    if (!kept.triangles.empty()) out.meshes.push_back(std::move(kept));
  }
  return out;
}

double yaw_from_heading(double heading_deg) { return (90.0 - heading_deg) * M_PI / 180.0; }

void place_vehicles(tracer::TraceScene& scene, VehicleLibrary& library, const std::vector<PoseRow>& poses) {
  std::map<std::string, std::uint32_t> model_index;
  for (std::uint32_t m = 0; m < scene.model_count(); ++m) model_index[scene.model_name(m)] = m;
  std::vector<tracer::VehiclePose> placed;
  for (const auto& p : poses) {
    const std::string key = "vehicle model " + p.vclass;
    auto it = model_index.find(key);
    if (it == model_index.end()) {
      const auto& m = library.model(p.vclass);
      it = model_index.emplace(key, scene.add_vehicle_model(p.vclass, meshkit::to_scene(m), m.antenna)).first;
    }
    const double yaw = yaw_from_heading(p.heading_deg);
    placed.push_back(tracer::VehiclePose{p.id, it->second, {p.x, p.y, p.z}, yaw,
                                         {p.speed_mps * std::cos(yaw), p.speed_mps * std::sin(yaw), 0}});
  }
  scene.set_vehicles(placed);
}

}  // namespace raysweep::pipeline
