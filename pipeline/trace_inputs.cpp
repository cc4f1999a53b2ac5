#include "pipeline/trace_inputs.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>

#include "meshkit/gltf_io.hpp"
#include "meshkit/vehicle_classes.hpp"
#include "pipeline/vehicles_stage.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;

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

VehicleLibrary::VehicleLibrary(const std::string& dir, int lod) : dir_(dir), lod_(lod) {
  if (!dir_.empty() && !fs::exists(fs::path(dir_) / "manifest.json"))
    throw std::invalid_argument(dir_ + ": not a vehicle library (no manifest.json; run `raysweep vehicles`)");
}

const meshkit::VehicleModel& VehicleLibrary::model(const std::string& vclass) {
  if (auto it = cache_.find(vclass); it != cache_.end()) return it->second;
  if (dir_.empty()) {
    if (!meshkit::find_vehicle_class(vclass))
      throw std::invalid_argument("vehicle class '" + vclass + "' has no built-in model");
    auto built = build_vehicle(vclass, vclass, "", VehiclesSettings{});
    return cache_.emplace(vclass, std::move(built.model)).first->second;
  }
  const fs::path manifest_path = fs::path(dir_) / "manifest.json";
  std::ifstream in(manifest_path);
  const auto manifest = nlohmann::json::parse(in);
  const nlohmann::json* entry = nullptr;
  for (const auto& v : manifest.at("vehicles"))
    if (v.at("name") == vclass) entry = &v;
  if (!entry)
    for (const auto& v : manifest.at("vehicles"))
      if (v.value("vclass", "") == vclass) {
        entry = &v;
        break;
      }
  if (!entry) throw std::invalid_argument(manifest_path.string() + ": no entry for vehicle class '" + vclass + "'");
  const int lod = lod_ >= 0 ? lod_ : entry->value("default_lod", 0);
  std::string file;
  for (const auto& l : entry->at("lods"))
    if (l.at("lod") == lod) file = l.at("file");
  if (file.empty())
    throw std::invalid_argument(manifest_path.string() + ": entry '" + entry->at("name").get<std::string>() +
                                "' has no LOD " + std::to_string(lod));
  const std::string path = (fs::path(dir_) / file).string();
  auto model = meshkit::from_scene(meshkit::read_glb(path), entry->at("name"));
  model.vclass = entry->value("vclass", vclass);
  const auto& a = entry->at("antenna");
  model.antenna = {a.at(0).get<double>(), a.at(1).get<double>(), a.at(2).get<double>()};
  files_.push_back(path);
  return cache_.emplace(vclass, std::move(model)).first->second;
}

std::vector<std::string> VehicleLibrary::files() const { return files_; }

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

namespace {

// Footprint of a vehicle in the ground plane: front point, unit heading, size.
struct Footprint {
  double x, y, ux, uy, length, width;
  std::array<std::array<double, 2>, 4> corners() const {
    const double px = -uy * width / 2, py = ux * width / 2;
    const double bx = x - ux * length, by = y - uy * length;
    return {{{x + px, y + py}, {x - px, y - py}, {bx - px, by - py}, {bx + px, by + py}}};
  }
};

// Separating-axis test on the two rectangles grown by `margin`.
bool overlap(const Footprint& a, const Footprint& b, double margin) {
  const auto ca = a.corners(), cb = b.corners();
  const std::array<std::array<double, 2>, 4> axes = {{{a.ux, a.uy}, {-a.uy, a.ux}, {b.ux, b.uy}, {-b.uy, b.ux}}};
  for (const auto& ax : axes) {
    double amin = 1e300, amax = -1e300, bmin = 1e300, bmax = -1e300;
    for (const auto& c : ca) {
      const double p = c[0] * ax[0] + c[1] * ax[1];
      amin = std::min(amin, p);
      amax = std::max(amax, p);
    }
    for (const auto& c : cb) {
      const double p = c[0] * ax[0] + c[1] * ax[1];
      bmin = std::min(bmin, p);
      bmax = std::max(bmax, p);
    }
    if (amax + margin < bmin || bmax + margin < amin) return false;
  }
  return true;
}

}  // namespace

std::vector<PoseRow> place_on_lanes(const meshkit::SumoNetwork& net, int count, std::uint64_t seed,
                                    const std::map<std::string, double>& class_mix, double min_gap_m) {
  struct Segment {
    meshkit::Vec2 a, b;
    double len;
  };
  std::vector<Segment> segments;
  std::vector<double> cumulative;
  double total = 0;
  for (const auto& lane : net.lane_shapes)
    for (std::size_t i = 1; i < lane.size(); ++i) {
      const double len = std::hypot(lane[i][0] - lane[i - 1][0], lane[i][1] - lane[i - 1][1]);
      if (len < 1e-6) continue;
      segments.push_back({lane[i - 1], lane[i], len});
      total += len;
      cumulative.push_back(total);
    }
  if (segments.empty()) throw std::invalid_argument(net.path + ": the network has no lanes to place vehicles on");
  double weight_sum = 0;
  for (const auto& [c, w] : class_mix) {
    if (!meshkit::find_vehicle_class(c)) throw std::invalid_argument("unknown vehicle class '" + c + "'");
    if (!(w >= 0)) throw std::invalid_argument("class weight for '" + c + "' must be >= 0");
    weight_sum += w;
  }
  if (!(weight_sum > 0)) throw std::invalid_argument("class mix has no positive weight");
  std::mt19937_64 rng(seed);
  auto uniform = [&rng] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  std::vector<PoseRow> rows;
  std::vector<Footprint> placed;
  // Stratified along the lanes (even spacing, jittered), so dense snapshots
  // fill the network instead of jamming early; then random retries.
  const double spacing = total / count;
  const double margin = std::max(0.0, min_gap_m - 5.0) / 2 + 0.25;
  for (int k = 0, attempt = 0; static_cast<int>(rows.size()) < count; ++attempt) {
    if (attempt > 200 * count)
      throw std::invalid_argument(net.path + ": cannot place " + std::to_string(count) + " vehicles without overlap on " +
                                  std::to_string(total) + " m of lanes (placed " + std::to_string(rows.size()) + ")");
    const double s = k < count ? (k + 0.5 + 0.4 * (uniform() - 0.5)) * spacing : uniform() * total;
    ++k;
    double pick = uniform() * weight_sum;
    std::string vclass = class_mix.begin()->first;
    for (const auto& [c, w] : class_mix) {
      if (pick < w) {
        vclass = c;
        break;
      }
      pick -= w;
    }
    const double speed = 5 + 10 * uniform();
    const auto idx = static_cast<std::size_t>(std::lower_bound(cumulative.begin(), cumulative.end(), s) - cumulative.begin());
    const auto& seg = segments[std::min(idx, segments.size() - 1)];
    const double along = std::clamp(1.0 - (cumulative[std::min(idx, segments.size() - 1)] - s) / seg.len, 0.0, 1.0);
    const double ux = (seg.b[0] - seg.a[0]) / seg.len, uy = (seg.b[1] - seg.a[1]) / seg.len;
    const auto& dims = meshkit::find_vehicle_class(vclass)->dims;
    const Footprint f{seg.a[0] + along * (seg.b[0] - seg.a[0]), seg.a[1] + along * (seg.b[1] - seg.a[1]), ux, uy,
                      dims.length, dims.width};
    bool clear = true;
    for (const auto& o : placed) clear = clear && !overlap(f, o, margin);
    if (!clear) continue;
    placed.push_back(f);
    PoseRow r;
    r.id = "veh" + std::to_string(rows.size());
    r.vclass = vclass;
    r.x = f.x;
    r.y = f.y;
    r.heading_deg = std::fmod(std::atan2(ux, uy) * 180 / M_PI + 360, 360);
    r.speed_mps = speed;
    rows.push_back(r);
  }
  return rows;
}

}  // namespace raysweep::pipeline
