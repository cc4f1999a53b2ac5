#include "generators/sweep/context_features.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "generators/dataset/dataset_writer.hpp"
#include "generators/hdf5/checked_file.hpp"
#include "generators/hdf5/column_file.hpp"
#include "meshkit/errors.hpp"
#include "tracer/trace_scene.hpp"

namespace raysweep::generators {

namespace {

constexpr double kPi = std::numbers::pi;

std::uint8_t code_of(const char* table, std::string_view name, std::uint8_t fallback_none) {
  const auto& values = features_schema().at("codes").at(table).at("values");
  std::uint8_t other = fallback_none;
  for (const auto& [k, v] : values.items()) {
    const auto& s = v.get_ref<const std::string&>();
    if (s == name) return static_cast<std::uint8_t>(std::stoul(k));
    if (s == "other") other = static_cast<std::uint8_t>(std::stoul(k));
  }
  return other;
}

// A code table as a JSON list, index = code.
std::string code_list(const char* table) {
  const auto& values = features_schema().at("codes").at(table).at("values");
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t k = 0; values.contains(std::to_string(k)); ++k) list.push_back(values.at(std::to_string(k)));
  return list.dump();
}

double wrap_pi(double a) {
  a = std::fmod(a + kPi, 2 * kPi);
  if (a <= 0) a += 2 * kPi;
  return a - kPi;
}

}  // namespace

void FeatureGridSpec::check() const {
  if (along_cells == 0 || along_cells > 1024) throw std::invalid_argument("along_cells must be in [1, 1024]");
  if (across_cells == 0 || across_cells > 1024) throw std::invalid_argument("across_cells must be in [1, 1024]");
  if (!(half_width_m > 0)) throw std::invalid_argument("half_width_m must be positive");
  if (max_vehicles == 0 || max_vehicles > 254) throw std::invalid_argument("max_vehicles must be in [1, 254]");
  if (!(height_scale_m > 0)) throw std::invalid_argument("height_scale_m must be positive");
  if (!(map_resolution_m > 0)) throw std::invalid_argument("map_resolution_m must be positive");
  if (frame_stride == 0) throw std::invalid_argument("frame_stride must be at least 1");
}

std::uint8_t material_code(std::string_view material) {
  if (material.empty()) return 0;
  return code_of("material_class", material, 0);
}

std::uint8_t vehicle_class_code(std::string_view vclass) { return code_of("vehicle_class", vclass, kNoVehicle); }

// --- the height map ---------------------------------------------------------

HeightMap HeightMap::build(const tracer::TraceScene& scene, const meshkit::Bounds& bounds, double resolution_m) {
  HeightMap m;
  if (bounds.empty()) return m;
  m.res_ = resolution_m;
  m.x0_ = bounds.min[0];
  m.y0_ = bounds.min[1];
  m.nx_ = static_cast<std::size_t>(std::ceil((bounds.max[0] - bounds.min[0]) / resolution_m)) + 1;
  m.ny_ = static_cast<std::size_t>(std::ceil((bounds.max[1] - bounds.min[1]) / resolution_m)) + 1;
  m.samples_.assign(m.nx_ * m.ny_, Sample{});
  std::vector<std::uint8_t> codes;
  for (const auto& name : scene.material_names()) codes.push_back(material_code(name));
  const double top = bounds.max[2] + 1, depth = bounds.max[2] - bounds.min[2] + 2;
  tbb::parallel_for(std::size_t{0}, m.ny_, [&](std::size_t iy) {
    std::vector<tracer::Hit> hits;
    for (std::size_t ix = 0; ix < m.nx_; ++ix) {
      const tracer::Vec3 o{m.x0_ + (static_cast<double>(ix) + 0.5) * m.res_,
                           m.y0_ + (static_cast<double>(iy) + 0.5) * m.res_, top};
      hits.clear();
      scene.all_hits(o, {0, 0, -1}, 0, depth, hits, 64);
      // The lowest surface is the ground (or a building's floor on it); one
      // surface alone is open ground.
      if (hits.size() < 2) continue;
      const double h = hits.back().t - hits.front().t;
      if (h < 0.05) continue;
      Sample& s = m.samples_[iy * m.nx_ + ix];
      s.height_m = static_cast<float>(h);
      const std::uint16_t mat = scene.material(hits.front().face);
      s.material = mat < codes.size() ? codes[mat] : material_code("other");
    }
  });
  return m;
}

HeightMap::Sample HeightMap::at(double x, double y) const {
  const double fx = std::floor((x - x0_) / res_), fy = std::floor((y - y0_) / res_);
  // Written so that a NaN coordinate (a damaged input's) is outside too.
  if (!(fx >= 0 && fy >= 0 && fx < static_cast<double>(nx_) && fy < static_cast<double>(ny_))) return {};
  return samples_[static_cast<std::size_t>(fy) * nx_ + static_cast<std::size_t>(fx)];
}

// --- per link ---------------------------------------------------------------

FeatureNode feature_node(const NodeInfo& info, const NodeState& state) {
  FeatureNode n;
  n.node = state.node;
  // SUMO's heading: clockwise from north; the front bumper is the FCD point.
  const double h = static_cast<double>(state.heading_deg) * kPi / 180;
  n.yaw_rad = wrap_pi(kPi / 2 - h);
  n.vehicle = info.kind == NodeKind::vehicle;
  n.x = state.x;
  n.y = state.y;
  if (n.vehicle) {
    n.x -= std::sin(h) * info.length_m / 2;
    n.y -= std::cos(h) * info.length_m / 2;
    n.length_m = info.length_m;
    n.width_m = info.width_m;
    n.height_m = info.height_m;
    n.vclass = vehicle_class_code(info.vclass);
  } else {
    n.height_m = static_cast<float>(state.z);
  }
  return n;
}

namespace {

void fill_corridor(const FeatureGridSpec& spec, const HeightMap& map, double ox, double oy, double ux, double uy,
                   double d, LinkFeatures& f) {
  const std::uint32_t A = spec.along_cells, C = spec.across_cells;
  f.height.assign(spec.cells(), 0);
  f.material.assign(spec.cells(), 0);
  const double cap = 255 * spec.height_scale_m;
  for (std::uint32_t i = 0; i < A; ++i) {
    const double along = (i + 0.5) * d / A;
    for (std::uint32_t j = 0; j < C; ++j) {
      const double across = -spec.half_width_m + (j + 0.5) * 2 * spec.half_width_m / C;
      const HeightMap::Sample s = map.at(ox + along * ux - across * uy, oy + along * uy + across * ux);
      const double h = std::min<double>(s.height_m, cap);
      f.height[i * C + j] = static_cast<std::uint8_t>(std::lround(h / spec.height_scale_m));
      f.material[i * C + j] = s.material;
    }
  }
}

void fill_vehicles(const FeatureGridSpec& spec, const std::vector<FeatureNode>& nodes, std::size_t tx, std::size_t rx,
                   double ux, double uy, double d, LinkFeatures& f) {
  const FeatureNode& a = nodes[tx];
  const double link_yaw = std::atan2(uy, ux);
  std::vector<CorridorVehicle> in;
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    const FeatureNode& n = nodes[k];
    if (k == tx || k == rx || !n.vehicle) continue;
    const double dx = n.x - a.x, dy = n.y - a.y;
    const double along = dx * ux + dy * uy, across = -dx * uy + dy * ux;
    if (along < 0 || along > d || std::abs(across) > spec.half_width_m) continue;
    in.push_back({static_cast<float>(along), static_cast<float>(across), n.height_m, n.length_m, n.width_m,
                  static_cast<float>(wrap_pi(n.yaw_rad - link_yaw)), n.vclass});
  }
  f.in_corridor = static_cast<std::uint32_t>(in.size());
  // The nearest to the line are the likeliest blockers; ties by along keep the order total.
  auto nearer = [](const CorridorVehicle& p, const CorridorVehicle& q) {
    const float ap = std::abs(p.across_m), aq = std::abs(q.across_m);
    return ap != aq ? ap < aq : p.along_m < q.along_m;
  };
  if (in.size() > spec.max_vehicles) {
    std::nth_element(in.begin(), in.begin() + spec.max_vehicles, in.end(), nearer);
    in.resize(spec.max_vehicles);
  }
  std::sort(in.begin(), in.end(), [](const CorridorVehicle& p, const CorridorVehicle& q) {
    return p.along_m != q.along_m ? p.along_m < q.along_m : p.across_m < q.across_m;
  });
  f.vehicles = std::move(in);
}

}  // namespace

LinkFeatures link_features(const FeatureGridSpec& spec, const HeightMap& map, const std::vector<FeatureNode>& nodes,
                           std::size_t tx, std::size_t rx) {
  LinkFeatures f;
  const FeatureNode &a = nodes[tx], &b = nodes[rx];
  const double dx = b.x - a.x, dy = b.y - a.y, d = std::hypot(dx, dy);
  // Coincident ends have no direction: take +x.
  const double ux = d > 1e-9 ? dx / d : 1, uy = d > 1e-9 ? dy / d : 0;
  f.distance_2d_m = static_cast<float>(d);
  f.height_m[0] = a.height_m;
  f.height_m[1] = b.height_m;
  fill_corridor(spec, map, a.x, a.y, ux, uy, d, f);
  fill_vehicles(spec, nodes, tx, rx, ux, uy, d, f);
  return f;
}

// --- the file ---------------------------------------------------------------

namespace {

using hdf5::Dtype;

// What the builder reads of a channel dataset: nothing the tracer computed.
struct DatasetInputs {
  hdf5::CheckedFile file;
  std::uint64_t F = 0, L = 0;
  std::vector<std::uint64_t> node_offset, link_offset;
  std::vector<std::uint32_t> node_count, link_count;
  std::vector<NodeInfo> nodes;

  explicit DatasetInputs(const std::filesystem::path& path) : file(path.string()) {
    file.open();
    const auto format = file.attr<std::string>("/", "format");
    if (format != kDatasetFormat)
      file.fail("attribute format", "is \"" + format + "\", not a channel dataset (" + kDatasetFormat + ")");
    if (file.attr_if<std::uint64_t>("/", "complete").value_or(0) != 1)
      file.fail("attribute complete", "missing: the sweep did not finish this file");
    F = file.dataset("/frames/time_s").rows();
    L = file.dataset("/links/tx").rows();
    node_offset = file.dataset("/frames/node_offset").read_all<std::uint64_t>(F);
    link_offset = file.dataset("/frames/link_offset").read_all<std::uint64_t>(F);
    node_count = file.dataset("/frames/node_count").read_all<std::uint32_t>(F);
    link_count = file.dataset("/frames/link_count").read_all<std::uint32_t>(F);
    read_nodes();
  }

  void read_nodes() {
    const auto id = file.dataset("/nodes/id").strings();
    const auto vclass = file.dataset("/nodes/vclass").strings();
    const std::size_t N = id.size();
    const auto kind = file.dataset("/nodes/kind").read_all<std::uint8_t>(N);
    const auto dims = file.dataset("/nodes/dimensions").read_all<float>(N, 3);
    if (vclass.size() != N) file.fail("/nodes/vclass", "has " + std::to_string(vclass.size()) + " rows, /nodes/id " + std::to_string(N));
    nodes.resize(N);
    for (std::size_t i = 0; i < N; ++i) {
      nodes[i].id = id[i];
      nodes[i].kind = kind[i] == 1 ? NodeKind::rsu : NodeKind::vehicle;
      nodes[i].vclass = vclass[i];
      nodes[i].length_m = dims[3 * i];
      nodes[i].width_m = dims[3 * i + 1];
      nodes[i].height_m = dims[3 * i + 2];
    }
  }

  // Frame f's nodes (sorted by node index) and its links as slots into them.
  void frame(std::uint64_t f, std::vector<FeatureNode>& out, std::vector<std::pair<std::size_t, std::size_t>>& links) {
    const std::uint64_t s0 = node_offset[f], ns = node_count[f], l0 = link_offset[f], nl = link_count[f];
    const auto node = file.dataset("/node_states/node").read<std::uint32_t>(s0, ns);
    const auto pos = file.dataset("/node_states/position").read<double>(s0, ns, 3);
    const auto head = file.dataset("/node_states/heading_deg").read<float>(s0, ns);
    const auto tx = file.dataset("/links/tx").read<std::uint32_t>(l0, nl);
    const auto rx = file.dataset("/links/rx").read<std::uint32_t>(l0, nl);
    out.clear();
    for (std::size_t k = 0; k < ns; ++k) {
      if (node[k] >= nodes.size())
        file.fail("/node_states/node", "row " + std::to_string(s0 + k) + ": node " + std::to_string(node[k]) +
                                           " is not in /nodes");
      NodeState st;
      st.node = node[k];
      st.x = pos[3 * k];
      st.y = pos[3 * k + 1];
      st.z = pos[3 * k + 2];
      st.heading_deg = head[k];
      out.push_back(feature_node(nodes[node[k]], st));
    }
    links.clear();
    auto slot = [&](std::uint32_t n, std::uint64_t row, const char* end) {
      auto it = std::lower_bound(node.begin(), node.end(), n);
      if (it == node.end() || *it != n)
        file.fail(std::string("/links/") + end, "row " + std::to_string(row) + ": node " + std::to_string(n) +
                                                    " is not present in frame " + std::to_string(f));
      return static_cast<std::size_t>(it - node.begin());
    };
    for (std::size_t k = 0; k < nl; ++k) links.emplace_back(slot(tx[k], l0 + k, "tx"), slot(rx[k], l0 + k, "rx"));
  }
};

class FeaturesWriter {
 public:
  FeaturesWriter(const std::filesystem::path& out, const FeatureGridSpec& spec, const FeaturesHeader& h,
                 const DatasetInputs& in)
      : spec_(spec),
        file_(out.string(), features_schema(), {{"G", spec.cells()}, {"K", spec.max_vehicles}}) {
    file_.create();
    file_.identity_attrs(kFeaturesFormat, kFeaturesSchemaVersion, h.raysweep_version, h.git_hash, h.config, h.inputs,
                         h.provenance, 0);
    file_.attr("", "along_cells", spec.along_cells);
    file_.attr("", "across_cells", spec.across_cells);
    file_.attr("", "cells", spec.cells());
    file_.attr("", "half_width_m", spec.half_width_m);
    file_.attr("", "max_vehicles", spec.max_vehicles);
    file_.attr("", "height_scale_m", spec.height_scale_m);
    file_.attr("", "map_resolution_m", spec.map_resolution_m);
    file_.attr("", "frame_stride", spec.frame_stride);
    file_.attr("", "material_classes", code_list("material_class"));
    file_.attr("", "vehicle_classes", code_list("vehicle_class"));
    file_.attr("", "dataset_link_count", in.L);
    file_.attr("", "dataset_frame_count", in.F);
    cols_.push_back(file_.column("links", "link", Dtype::u64));
    cols_.push_back(file_.column("links", "frame", Dtype::u32));
    cols_.push_back(file_.column("links", "distance_2d_m", Dtype::f32));
    cols_.push_back(file_.column("links", "height_m", Dtype::f32));
    cols_.push_back(file_.column("corridor", "height", Dtype::u8));
    cols_.push_back(file_.column("corridor", "material", Dtype::u8));
    cols_.push_back(file_.column("vehicles", "count", Dtype::u8));
    cols_.push_back(file_.column("vehicles", "in_corridor", Dtype::u32));
    for (const char* n : {"along_m", "across_m", "height_m", "length_m", "width_m", "yaw_rad"})
      cols_.push_back(file_.column("vehicles", n, Dtype::f32));
    cols_.push_back(file_.column("vehicles", "vclass", Dtype::u8));
  }
  ~FeaturesWriter() {
    if (file_.open()) file_.abandon();
  }

  void put(std::uint64_t link, std::uint32_t frame, const LinkFeatures& f) {
    cols_[0]->put(link);
    cols_[1]->put(frame);
    cols_[2]->put(f.distance_2d_m);
    cols_[3]->put(f.height_m[0]);
    cols_[3]->put(f.height_m[1]);
    for (auto v : f.height) cols_[4]->put(v);
    for (auto v : f.material) cols_[5]->put(v);
    cols_[6]->put(static_cast<std::uint8_t>(f.vehicles.size()));
    cols_[7]->put(f.in_corridor);
    const float nan = std::nanf("");
    for (std::uint32_t k = 0; k < spec_.max_vehicles; ++k) {
      const bool has = k < f.vehicles.size();
      const CorridorVehicle& v = has ? f.vehicles[k] : CorridorVehicle{};
      const float vals[6] = {v.along_m, v.across_m, v.height_m, v.length_m, v.width_m, v.yaw_rad};
      for (int c = 0; c < 6; ++c) cols_[8 + c]->put(has ? vals[c] : nan);
      cols_[14]->put(has ? v.vclass : kNoVehicle);
    }
    ++rows_;
  }
  void maybe_flush() { file_.maybe_flush(); }
  void finish() {
    file_.flush_all();
    file_.attr("", "row_count", rows_);
    file_.close_all(true);
  }
  std::uint64_t rows() const { return rows_; }

 private:
  FeatureGridSpec spec_;
  hdf5::ColumnFile file_;
  std::vector<hdf5::Column*> cols_;
  std::uint64_t rows_ = 0;
};

}  // namespace

FeaturesStats write_features(const FeatureGridSpec& spec, const HeightMap& map, const std::filesystem::path& dataset,
                             const std::filesystem::path& out, const FeaturesHeader& header,
                             const std::function<void(std::uint64_t, std::uint64_t)>& progress) {
  spec.check();
  const auto t0 = std::chrono::steady_clock::now();
  DatasetInputs in(dataset);
  FeaturesWriter w(out, spec, header, in);
  FeaturesStats stats;
  std::vector<FeatureNode> nodes;
  std::vector<std::pair<std::size_t, std::size_t>> links;
  std::vector<LinkFeatures> feats;
  const std::uint64_t every = std::max<std::uint64_t>(1, in.F / spec.frame_stride / 10);
  for (std::uint64_t f = 0; f < in.F; f += spec.frame_stride) {
    in.frame(f, nodes, links);
    feats.assign(links.size(), LinkFeatures{});
    tbb::parallel_for(std::size_t{0}, links.size(), [&](std::size_t k) {
      feats[k] = link_features(spec, map, nodes, links[k].first, links[k].second);
    });
    for (std::size_t k = 0; k < links.size(); ++k)
      w.put(in.link_offset[f] + k, static_cast<std::uint32_t>(f), feats[k]);
    w.maybe_flush();
    ++stats.frames;
    if (progress && (f / spec.frame_stride) % every == 0) progress(f + 1, in.F);
  }
  w.finish();
  if (progress) progress(in.F, in.F);
  stats.rows = w.rows();
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return stats;
}

std::optional<nlohmann::json> finished_features_provenance(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) return std::nullopt;
  try {
    hdf5::QuietHdf5 quiet;
    hdf5::CheckedFile f(path.string());
    f.open();
    if (f.attr<std::string>("/", "format") != kFeaturesFormat) return std::nullopt;
    if (f.attr_if<std::uint64_t>("/", "complete").value_or(0) != 1) return std::nullopt;
    return nlohmann::json::parse(f.attr<std::string>("/", "provenance"));
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace raysweep::generators
