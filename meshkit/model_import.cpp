#include "meshkit/model_import.hpp"

#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/Options.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <regex>
#include <sstream>
#include <unordered_map>
#include <utility>

#include "meshkit/mat4.hpp"
#include "meshkit/errors.hpp"
#include "meshkit/ply_io.hpp"

namespace raysweep::meshkit {

Bounds ImportedModel::bounds() const {
  Bounds b = Bounds::none();
  for (const ImportedPart& p : parts)
    for (const Tri& t : p.triangles)
      for (auto v : t) b.extend(p.vertices[v]);
  return b;
}

std::size_t ImportedModel::triangle_count() const {
  std::size_t n = 0;
  for (const ImportedPart& p : parts) n += p.triangles.size();
  return n;
}

namespace {

namespace fs = std::filesystem;

std::string quote(const std::string& s) { return "'" + s + "'"; }

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string number(double v) {
  std::ostringstream os;
  os.precision(6);
  os << v;
  return os.str();
}

std::vector<unsigned char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open file");
  std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path, "", "read error");
  return bytes;
}

// Lets triangles that index a shared (file- or accessor-wide) vertex array
// go into a part that stores only the vertices it uses.
class VertexRemap {
 public:
  std::uint32_t operator()(ImportedPart& part, std::size_t global, const Vec3& p) {
    auto [it, fresh] = remap_.try_emplace(global, static_cast<std::uint32_t>(part.vertices.size()));
    if (fresh) part.vertices.push_back(p);
    return it->second;
  }

 private:
  std::unordered_map<std::size_t, std::uint32_t> remap_;
};

// ---------------------------------------------------------------- finishing

void unique_names(ImportedModel& m) {
  std::set<std::string> taken;
  for (ImportedPart& p : m.parts) {
    std::string name = p.name;
    for (int k = 2; taken.count(name); ++k) name = p.name + "." + std::to_string(k);
    p.name = name;
    taken.insert(name);
  }
}

// Drops degenerate triangles and unused vertices; returns the dropped count.
std::size_t clean_part(ImportedPart& p) {
  std::vector<Tri> kept;
  kept.reserve(p.triangles.size());
  for (const Tri& t : p.triangles) {
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    const Vec3& a = p.vertices[t[0]];
    const Vec3& b = p.vertices[t[1]];
    const Vec3& c = p.vertices[t[2]];
    const Vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const Vec3 v{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const Vec3 w{c[0] - b[0], c[1] - b[1], c[2] - b[2]};
    const Vec3 n{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    const double cross = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    auto sq = [](const Vec3& e) { return e[0] * e[0] + e[1] * e[1] + e[2] * e[2]; };
    // Relative, so the test does not depend on the model's units; it catches
    // coincident and collinear corners, not thin but valid slivers.
    if (cross <= 1e-12 * std::max({sq(u), sq(v), sq(w)})) continue;
    kept.push_back(t);
  }
  const std::size_t dropped = p.triangles.size() - kept.size();
  p.triangles = std::move(kept);

  std::vector<std::uint32_t> remap(p.vertices.size(), UINT32_MAX);
  std::vector<Vec3> used;
  for (Tri& t : p.triangles)
    for (auto& v : t) {
      if (remap[v] == UINT32_MAX) {
        remap[v] = static_cast<std::uint32_t>(used.size());
        used.push_back(p.vertices[v]);
      }
      v = remap[v];
    }
  p.vertices = std::move(used);
  return dropped;
}

constexpr double kVehicleMin = 1.0, kVehicleMax = 25.0;  // metres, bicycle to semitrailer

std::string unit_name(double metres_per_unit) {
  for (const auto& [name, scale] : model_units())
    if (scale == metres_per_unit) return name == "m" ? "metres" : name == "cm" ? "centimetres" : name == "mm" ? "millimetres" : name;
  return number(metres_per_unit) + " m units";
}

// OBJ/PLY/OFF carry no unit. Of metres, centimetres and millimetres, the one
// that brings the largest extent closest (by ratio) to the class length, or
// into the 1 to 25 m of any vehicle when the class is unknown; ties keep the
// larger unit, so a 2.5-unit toy car stays in metres.
double guess_unit(double raw, double class_length) {
  double best = 1.0, best_distance = INFINITY;
  for (double scale : {1.0, 0.01, 0.001}) {
    const double len = raw * scale;
    const double distance = class_length > 0 ? std::abs(std::log(len / class_length))
                            : len < kVehicleMin ? std::log(kVehicleMin / len)
                            : len > kVehicleMax ? std::log(len / kVehicleMax)
                                                : 0.0;
    if (distance < best_distance - 1e-12) {
      best = scale;
      best_distance = distance;
    }
  }
  return best;
}

void finish(ImportedModel& m, const ImportOptions& options) {
  unique_names(m);
  for (const ImportedPart& p : m.parts)
    for (std::size_t i = 0; i < p.vertices.size(); ++i)
      for (double c : p.vertices[i])
        if (!std::isfinite(c))
          throw InputError(m.path, "part " + quote(p.name) + (p.source.empty() ? "" : " (" + p.source + ")"),
                           "vertex " + std::to_string(i) + " has a non-finite coordinate (NaN or Inf)");

  std::vector<ImportedPart> kept;
  for (ImportedPart& p : m.parts) {
    const std::size_t dropped = clean_part(p);
    if (dropped)
      m.repairs.push_back("dropped " + std::to_string(dropped) + " degenerate triangle" + (dropped == 1 ? "" : "s") +
                          " in part " + quote(p.name));
    if (p.triangles.empty()) {
      m.warnings.push_back("part " + quote(p.name) + " has no triangles left: dropped");
      continue;
    }
    kept.push_back(std::move(p));
  }
  m.parts = std::move(kept);
  if (m.parts.empty()) throw InputError(m.path, "", "no triangles in the model");

  auto extent = [&] {
    const Bounds b = m.bounds();
    return std::max({b.max[0] - b.min[0], b.max[1] - b.min[1], b.max[2] - b.min[2]});
  };
  const double raw = extent();
  const bool gltf = m.up_axis == "y";
  double scale = 1.0;
  if (options.unit > 0) {
    scale = options.unit;
    m.unit_source = "given";
  } else if (gltf) {
    m.unit_source = "glTF (metres by specification)";
  } else {
    scale = guess_unit(raw, options.class_length);
    m.unit_source = "guessed from the size";
  }
  if (scale != 1.0) {
    m.unit_scale = scale;
    for (ImportedPart& p : m.parts)
      for (Vec3& v : p.vertices)
        for (double& c : v) c *= scale;
    m.repairs.push_back("model in " + unit_name(scale) + " (" + m.unit_source + ", extent " + number(raw) +
                        "): scaled by " + number(scale));
  }
  const double size = extent();
  if (size < 0.05)
    throw InputError(m.path, "", "zero-size model (largest extent " + number(size) + " m after transforms)");
  // Plausibility: within a factor of 3 of the class length, else 1 to 25 m.
  const double lo = options.class_length > 0 ? options.class_length / 3 : kVehicleMin;
  const double hi = options.class_length > 0 ? options.class_length * 3 : kVehicleMax;
  if (size < lo || size > hi)
    m.warnings.push_back("model is " + number(size) + " m long in " + unit_name(scale) + " (" + m.unit_source + "), " +
                         (options.class_length > 0 ? "implausible for a " + options.vclass + " (about " +
                                                         number(options.class_length) + " m)"
                                                   : "outside the 1 to 25 m of any vehicle") +
                         ": set its unit (--model-unit, or model_unit in [vehicles.class." +
                         (options.vclass.empty() ? "<class>" : options.vclass) + "])");
}

// ---------------------------------------------------------------- glTF


constexpr Mat4 kIdentity = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
// (x, y, z)_raysweep = (z, x, y)_glTF.
constexpr Mat4 kYUpToZUp = {0, 0, 1, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1};
constexpr const char* kDraco = "KHR_draco_mesh_compression";
constexpr const char* kQuantization = "KHR_mesh_quantization";


double det3(const Mat4& t) {
  return t[0] * (t[5] * t[10] - t[6] * t[9]) - t[1] * (t[4] * t[10] - t[6] * t[8]) +
         t[2] * (t[4] * t[9] - t[5] * t[8]);
}

Vec3 transform_point(const Mat4& t, const Vec3& p) {
  Vec3 r;
  for (int i = 0; i < 3; ++i) r[i] = t[i * 4] * p[0] + t[i * 4 + 1] * p[1] + t[i * 4 + 2] * p[2] + t[i * 4 + 3];
  return r;
}

std::uint32_t u32(const unsigned char* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
void put_u32(std::vector<unsigned char>& out, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) out.push_back(static_cast<unsigned char>(v >> (8 * k)));
}

std::string url_decode(const std::string& s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && std::isxdigit(static_cast<unsigned char>(s[i + 1])) &&
        std::isxdigit(static_cast<unsigned char>(s[i + 2]))) {
      out.push_back(static_cast<char>(std::stoi(s.substr(i + 1, 2), nullptr, 16)));
      i += 2;
    } else {
      out.push_back(s[i]);
    }
  }
  return out;
}

const char* mode_name(int mode) {
  switch (mode) {
    case TINYGLTF_MODE_POINTS: return "POINTS";
    case TINYGLTF_MODE_LINE: return "LINES";
    case TINYGLTF_MODE_LINE_LOOP: return "LINE_LOOP";
    case TINYGLTF_MODE_LINE_STRIP: return "LINE_STRIP";
    default: return "unknown";
  }
}

// The file split into what tinygltf needs: JSON text and, for GLB, the chunks
// after it (kept verbatim).
struct GltfFile {
  bool binary = false;
  std::string json;
  std::vector<unsigned char> tail;  // GLB chunks after the JSON chunk
  std::size_t bin_size = 0;         // payload of the BIN chunk, 0 if none
};

GltfFile split_gltf(const std::string& path, const std::vector<unsigned char>& bytes) {
  GltfFile f;
  if (bytes.empty()) throw InputError(path, "", "empty file");
  if (bytes.size() < 4 || std::memcmp(bytes.data(), "glTF", 4) != 0) {
    f.json.assign(bytes.begin(), bytes.end());
    return f;
  }
  f.binary = true;
  if (bytes.size() < 20)
    throw InputError(path, "GLB header", "truncated: " + std::to_string(bytes.size()) + " bytes, a GLB needs at least 20");
  if (u32(&bytes[4]) != 2) throw InputError(path, "GLB header", "unsupported GLB version " + std::to_string(u32(&bytes[4])));
  const std::size_t length = u32(&bytes[8]);
  if (length < 20) throw InputError(path, "GLB header", "declares " + std::to_string(length) + " bytes, less than a header");
  if (length > bytes.size())
    throw InputError(path, "GLB header",
                     "truncated: the header declares " + std::to_string(length) + " bytes, the file has " +
                         std::to_string(bytes.size()));
  const std::size_t json_len = u32(&bytes[12]);
  if (u32(&bytes[16]) != 0x4E4F534Au) throw InputError(path, "GLB chunk 0", "first chunk is not JSON");
  if (json_len > length - 20)
    throw InputError(path, "GLB JSON chunk",
                     "truncated: chunk of " + std::to_string(json_len) + " bytes runs past the end of the file");
  f.json.assign(bytes.begin() + 20, bytes.begin() + 20 + json_len);
  f.tail.assign(bytes.begin() + 20 + json_len, bytes.begin() + length);
  if (f.tail.size() >= 8 && u32(&f.tail[4]) == 0x004E4942u) {
    f.bin_size = u32(&f.tail[0]);
    if (f.bin_size > f.tail.size() - 8)
      throw InputError(path, "GLB BIN chunk",
                       "truncated: chunk of " + std::to_string(f.bin_size) + " bytes, only " +
                           std::to_string(f.tail.size() - 8) + " present");
  }
  return f;
}

class GltfImporter {
 public:
  GltfImporter(const std::string& path, ImportedModel& out) : path_(path), out_(out) {}

  void run() {
    load();
    const std::vector<int> roots = scene_roots();
    seen_.assign(model_.nodes.size(), false);
    std::vector<int> visiting;
    for (int r : roots) visit(r, kIdentity, visiting);
  }

 private:
  const std::string& path_;
  ImportedModel& out_;
  tinygltf::Model model_;
  bool quantized_ = false;
  std::vector<bool> seen_;  // nodes already imported

  [[noreturn]] void fail(const std::string& element, const std::string& what) const {
    throw InputError(path_, element, what);
  }

  // Checks and adjusts the JSON before tinygltf sees it: tinygltf's own
  // messages do not name the buffer file it misses, it rejects Draco
  // primitives' indices accessors (no bufferView, as the extension
  // prescribes) and it fails on textures it cannot decode, which geometry
  // does not need.
  void prepare(nlohmann::json& doc, const GltfFile& file) {
    if (!doc.is_object()) fail("JSON", "top level is not an object");
    for (const char* key : {"extensionsUsed", "extensionsRequired"}) {
      if (!doc.contains(key) || !doc[key].is_array()) continue;
      for (const auto& e : doc[key]) {
        if (!e.is_string()) continue;
        const std::string name = e.get<std::string>();
        if (name == "EXT_meshopt_compression" || name == "KHR_meshopt_compression")
          fail(key, name + " is not supported (decompress the model first, e.g. gltfpack -noq or gltf-transform)");
        if (name == "EXT_mesh_gpu_instancing")
          fail(key, name + " is not supported (instanced meshes would be lost)");
        if (name == kQuantization) quantized_ = true;
      }
    }
    const fs::path base = fs::path(path_).parent_path();
    if (doc.contains("buffers") && doc["buffers"].is_array()) {
      const auto& buffers = doc["buffers"];
      for (std::size_t i = 0; i < buffers.size(); ++i) {
        const auto& b = buffers[i];
        if (!b.is_object()) continue;
        const std::size_t declared =
            b.contains("byteLength") && b["byteLength"].is_number_unsigned() ? b["byteLength"].get<std::size_t>() : 0;
        if (!b.contains("uri")) {
          if (!file.binary) fail("buffer " + std::to_string(i), "has no uri in a .gltf file");
          if (i != 0) fail("buffer " + std::to_string(i), "only buffer 0 can refer to the GLB BIN chunk");
          if (declared > file.bin_size)
            fail("buffer 0 (GLB BIN chunk)", "truncated: byteLength " + std::to_string(declared) + ", the chunk has " +
                                                 std::to_string(file.bin_size) + " bytes");
          continue;
        }
        if (!b["uri"].is_string()) fail("buffer " + std::to_string(i), "uri is not a string");
        const std::string uri = b["uri"].get<std::string>();
        if (uri.rfind("data:", 0) == 0) continue;
        const std::string element = "buffer " + std::to_string(i) + " " + quote(uri);
        const fs::path file_path = base / url_decode(uri);
        std::error_code ec;
        if (!fs::is_regular_file(file_path, ec))
          fail(element, "external buffer file not found: " + file_path.string());
        const auto size = fs::file_size(file_path, ec);
        if (ec) fail(element, "cannot read " + file_path.string());
        if (size < declared)
          fail(element, "truncated: " + file_path.string() + " has " + std::to_string(size) +
                            " bytes, byteLength says " + std::to_string(declared));
      }
    }
    doc.erase("images");
    if (doc.contains("meshes") && doc["meshes"].is_array())
      for (auto& mesh : doc["meshes"]) {
        if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array()) continue;
        for (auto& prim : mesh["primitives"])
          if (prim.is_object() && prim.contains("extensions") && prim["extensions"].is_object() &&
              prim["extensions"].contains(kDraco))
            prim.erase("indices");
      }
  }

  void load() {
    const std::vector<unsigned char> bytes = read_bytes(path_);
    GltfFile file = split_gltf(path_, bytes);
    nlohmann::json doc;
    try {
      doc = nlohmann::json::parse(file.json);
    } catch (const nlohmann::json::exception& e) {
      fail("JSON", std::string("malformed JSON: ") + e.what());
    }
    try {
      prepare(doc, file);
    } catch (const nlohmann::json::exception& e) {
      fail("JSON", std::string("unexpected structure: ") + e.what());
    }
    // Invalid UTF-8 cannot get here (the parser rejects it); replace keeps dump() from throwing regardless.
    std::string text = doc.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);

    tinygltf::TinyGLTF loader;
    std::string err, warn;
    bool ok = false;
    const std::string base = fs::path(path_).parent_path().string();
    try {
      ok = run_tinygltf(loader, file, text, base, err, warn);
    } catch (const std::exception& e) {
      fail("", std::string("not a readable glTF: ") + e.what());
    }
    if (!ok) fail("", "not a readable glTF: " + (err.empty() ? warn : err));
    std::istringstream lines(warn);
    for (std::string line; std::getline(lines, line);)
      if (!line.empty()) out_.warnings.push_back("tinygltf: " + line);
  }

  bool run_tinygltf(tinygltf::TinyGLTF& loader, const GltfFile& file, std::string& text, const std::string& base,
                    std::string& err, std::string& warn) {
    if (file.binary) {
      while (text.size() % 4) text.push_back(' ');
      std::vector<unsigned char> glb;
      glb.reserve(20 + text.size() + file.tail.size());
      put_u32(glb, 0x46546C67u);
      put_u32(glb, 2);
      put_u32(glb, static_cast<std::uint32_t>(20 + text.size() + file.tail.size()));
      put_u32(glb, static_cast<std::uint32_t>(text.size()));
      put_u32(glb, 0x4E4F534Au);
      glb.insert(glb.end(), text.begin(), text.end());
      glb.insert(glb.end(), file.tail.begin(), file.tail.end());
      return loader.LoadBinaryFromMemory(&model_, &err, &warn, glb.data(), static_cast<unsigned int>(glb.size()), base);
    }
    return loader.LoadASCIIFromString(&model_, &err, &warn, text.data(), static_cast<unsigned int>(text.size()), base);
  }

  std::vector<int> scene_roots() const {
    if (!model_.scenes.empty()) {
      const int s = model_.defaultScene >= 0 ? model_.defaultScene : 0;
      if (static_cast<std::size_t>(s) >= model_.scenes.size())
        fail("scene", "default scene " + std::to_string(s) + " does not exist");
      return model_.scenes[s].nodes;
    }
    // No scene: every node that is nobody's child is a root.
    std::vector<bool> child(model_.nodes.size(), false);
    for (const auto& n : model_.nodes)
      for (int c : n.children)
        if (c >= 0 && static_cast<std::size_t>(c) < child.size()) child[c] = true;
    std::vector<int> roots;
    for (std::size_t i = 0; i < child.size(); ++i)
      if (!child[i]) roots.push_back(static_cast<int>(i));
    return roots;
  }

  std::string node_label(int index) const {
    const std::string& name = model_.nodes[index].name;
    return "node " + std::to_string(index) + (name.empty() ? "" : " " + quote(name));
  }

  Mat4 local_matrix(int index) const {
    const tinygltf::Node& n = model_.nodes[index];
    if (!n.matrix.empty()) {
      if (n.matrix.size() != 16) fail(node_label(index), "matrix needs 16 numbers");
      Mat4 m;
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) m[i * 4 + j] = n.matrix[j * 4 + i];  // glTF stores columns
      return m;
    }
    Mat4 m = kIdentity;
    if (!n.rotation.empty()) {
      if (n.rotation.size() != 4) fail(node_label(index), "rotation needs 4 numbers");
      double x = n.rotation[0], y = n.rotation[1], z = n.rotation[2], w = n.rotation[3];
      const double len = std::sqrt(x * x + y * y + z * z + w * w);
      if (!(len > 1e-9)) fail(node_label(index), "rotation quaternion has zero length");
      // Exporters write unit quaternions rounded to float; renormalising keeps
      // the rotation part orthonormal.
      x /= len, y /= len, z /= len, w /= len;
      m = {1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),     0,
           2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),     0,
           2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y), 0,
           0,                       0,                       0,                       1};
    }
    if (!n.scale.empty()) {
      if (n.scale.size() != 3) fail(node_label(index), "scale needs 3 numbers");
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) m[i * 4 + j] *= n.scale[j];
    }
    if (!n.translation.empty()) {
      if (n.translation.size() != 3) fail(node_label(index), "translation needs 3 numbers");
      for (int i = 0; i < 3; ++i) m[i * 4 + 3] = n.translation[i];
    }
    return m;
  }

  static double component(const unsigned char* p, int type, bool normalized) {
    switch (type) {
      case TINYGLTF_COMPONENT_TYPE_BYTE: {
        std::int8_t v;
        std::memcpy(&v, p, 1);
        return normalized ? std::max(v / 127.0, -1.0) : v;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0 : p[0];
      case TINYGLTF_COMPONENT_TYPE_SHORT: {
        std::int16_t v;
        std::memcpy(&v, p, 2);
        return normalized ? std::max(v / 32767.0, -1.0) : v;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        std::uint16_t v;
        std::memcpy(&v, p, 2);
        return normalized ? v / 65535.0 : v;
      }
      case TINYGLTF_COMPONENT_TYPE_INT: {
        std::int32_t v;
        std::memcpy(&v, p, 4);
        return v;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
        std::uint32_t v;
        std::memcpy(&v, p, 4);
        return normalized ? v / 4294967295.0 : v;
      }
      case TINYGLTF_COMPONENT_TYPE_FLOAT: {
        float v;
        std::memcpy(&v, p, 4);
        return v;
      }
      default: {
        double v;
        std::memcpy(&v, p, 8);
        return v;
      }
    }
  }

  // Checked pointer to `count` elements of `elem` bytes, `stride` apart,
  // starting `offset` bytes into buffer view `view`.
  const unsigned char* view_data(int view, std::size_t offset, std::size_t stride, std::size_t elem,
                                 std::size_t count, const std::string& element) const {
    if (view < 0 || static_cast<std::size_t>(view) >= model_.bufferViews.size())
      fail(element, "bufferView " + std::to_string(view) + " does not exist");
    const tinygltf::BufferView& bv = model_.bufferViews[view];
    if (bv.buffer < 0 || static_cast<std::size_t>(bv.buffer) >= model_.buffers.size())
      fail(element, "bufferView " + std::to_string(view) + " names buffer " + std::to_string(bv.buffer) +
                        ", which does not exist");
    const auto& data = model_.buffers[bv.buffer].data;
    if (bv.byteOffset > data.size() || bv.byteLength > data.size() - bv.byteOffset)
      fail(element, "bufferView " + std::to_string(view) + " runs past the end of buffer " +
                        std::to_string(bv.buffer) + " (" + std::to_string(data.size()) + " bytes)");
    if (count > 0) {
      const bool fits = offset <= bv.byteLength && elem <= bv.byteLength - offset &&
                        (count - 1) <= (bv.byteLength - offset - elem) / stride;
      if (!fits)
        fail(element, std::to_string(count) + " elements of " + std::to_string(elem) + " bytes (stride " +
                          std::to_string(stride) + ") from offset " + std::to_string(offset) +
                          " run past the end of bufferView " + std::to_string(view) + " (" +
                          std::to_string(bv.byteLength) + " bytes)");
    }
    return data.data() + bv.byteOffset + offset;
  }

  // An accessor's elements as doubles, row by row, with sparse substitution
  // and normalisation applied.
  std::vector<double> read_accessor(int index, int type, const std::vector<int>& components,
                                    const std::string& where) const {
    if (index < 0 || static_cast<std::size_t>(index) >= model_.accessors.size())
      fail(where, "accessor " + std::to_string(index) + " does not exist (the file has " +
                      std::to_string(model_.accessors.size()) + ")");
    const tinygltf::Accessor& a = model_.accessors[index];
    const std::string element = where + ", accessor " + std::to_string(index);
    if (a.type != type) fail(element, "unexpected type " + std::to_string(a.type));
    if (std::find(components.begin(), components.end(), a.componentType) == components.end())
      fail(element, "unsupported component type " + std::to_string(a.componentType));
    const std::size_t width = static_cast<std::size_t>(tinygltf::GetNumComponentsInType(a.type));
    const std::size_t csize = static_cast<std::size_t>(tinygltf::GetComponentSizeInBytes(a.componentType));
    const std::size_t elem = width * csize;
    std::vector<double> out;
    if (a.bufferView >= 0) {
      if (static_cast<std::size_t>(a.bufferView) >= model_.bufferViews.size())
        fail(element, "bufferView " + std::to_string(a.bufferView) + " does not exist");
      const tinygltf::BufferView& bv = model_.bufferViews[a.bufferView];
      const std::size_t stride = bv.byteStride ? bv.byteStride : elem;
      if (stride < elem)
        fail(element, "byteStride " + std::to_string(stride) + " is smaller than an element (" +
                          std::to_string(elem) + " bytes)");
      const unsigned char* p = view_data(a.bufferView, a.byteOffset, stride, elem, a.count, element);
      out.resize(a.count * width);
      for (std::size_t i = 0; i < a.count; ++i)
        for (std::size_t k = 0; k < width; ++k)
          out[i * width + k] = component(p + i * stride + k * csize, a.componentType, a.normalized);
    } else {
      if (!a.sparse.isSparse) fail(element, "has neither a bufferView nor sparse data");
      // All-zero base: guard the allocation against absurd counts.
      if (a.count > (std::size_t(1) << 28)) fail(element, "count " + std::to_string(a.count) + " is implausible");
      out.assign(a.count * width, 0.0);
    }
    if (a.sparse.isSparse) {
      const std::string sparse = element + " sparse";
      if (a.sparse.count < 0 || static_cast<std::size_t>(a.sparse.count) > a.count)
        fail(sparse, "count " + std::to_string(a.sparse.count) + " exceeds the accessor count " +
                         std::to_string(a.count));
      const std::size_t n = static_cast<std::size_t>(a.sparse.count);
      const int ict = a.sparse.indices.componentType;
      if (ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
          ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
        fail(sparse, "indices have unsupported component type " + std::to_string(ict));
      const std::size_t isize = static_cast<std::size_t>(tinygltf::GetComponentSizeInBytes(ict));
      if (a.sparse.indices.byteOffset < 0 || a.sparse.values.byteOffset < 0) fail(sparse, "negative byteOffset");
      const unsigned char* ip = view_data(a.sparse.indices.bufferView, a.sparse.indices.byteOffset, isize, isize, n,
                                          sparse + " indices");
      const unsigned char* vp = view_data(a.sparse.values.bufferView, a.sparse.values.byteOffset, elem, elem, n,
                                          sparse + " values");
      for (std::size_t s = 0; s < n; ++s) {
        const auto target = static_cast<std::size_t>(component(ip + s * isize, ict, false));
        if (target >= a.count)
          fail(sparse, "index " + std::to_string(target) + " is out of range (count " + std::to_string(a.count) + ")");
        for (std::size_t k = 0; k < width; ++k)
          out[target * width + k] = component(vp + s * elem + k * csize, a.componentType, a.normalized);
      }
    }
    return out;
  }

  std::vector<Vec3> read_positions(int index, const std::string& where) const {
    std::vector<int> types = {TINYGLTF_COMPONENT_TYPE_FLOAT};
    if (index >= 0 && static_cast<std::size_t>(index) < model_.accessors.size()) {
      const int ct = model_.accessors[index].componentType;
      if (ct != TINYGLTF_COMPONENT_TYPE_FLOAT && !quantized_)
        fail(where + ", accessor " + std::to_string(index),
             "POSITION must be FLOAT VEC3 (component type " + std::to_string(ct) +
                 " needs KHR_mesh_quantization, which the file does not declare)");
      if (quantized_)
        types.insert(types.end(), {TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                   TINYGLTF_COMPONENT_TYPE_SHORT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT});
    }
    const std::vector<double> v = read_accessor(index, TINYGLTF_TYPE_VEC3, types, where);
    std::vector<Vec3> out(v.size() / 3);
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
    return out;
  }

  std::vector<std::uint32_t> read_indices(int index, const std::string& where) const {
    if (index >= 0 && static_cast<std::size_t>(index) < model_.accessors.size() && model_.accessors[index].normalized)
      fail(where + ", accessor " + std::to_string(index), "indices cannot be normalized");
    const std::vector<double> v =
        read_accessor(index, TINYGLTF_TYPE_SCALAR,
                      {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                       TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
                      where);
    return std::vector<std::uint32_t>(v.begin(), v.end());
  }

  void read_draco(const tinygltf::Value& ext, std::vector<Vec3>& positions, std::vector<std::uint32_t>& indices,
                  const std::string& where) const {
    const std::string element = where + ", " + kDraco;
    if (!ext.IsObject() || !ext.Get("bufferView").IsInt() || !ext.Get("attributes").IsObject() ||
        !ext.Get("attributes").Get("POSITION").IsInt())
      fail(element, "needs an integer bufferView and attributes.POSITION");
    const int view = ext.Get("bufferView").GetNumberAsInt();
    if (view < 0 || static_cast<std::size_t>(view) >= model_.bufferViews.size())
      fail(element, "bufferView " + std::to_string(view) + " does not exist");
    const unsigned char* p = view_data(view, 0, 1, 1, model_.bufferViews[view].byteLength, element);
    draco::DecoderBuffer in;
    in.Init(reinterpret_cast<const char*>(p), model_.bufferViews[view].byteLength);
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&in);
    if (!decoded.ok()) fail(element, "Draco: " + decoded.status().error_msg_string());
    const std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
    const draco::PointAttribute* pa = mesh->GetAttributeByUniqueId(
        static_cast<std::uint32_t>(ext.Get("attributes").Get("POSITION").GetNumberAsInt()));
    if (!pa || pa->num_components() != 3) fail(element, "no 3-component POSITION attribute in the Draco data");
    positions.resize(mesh->num_points());
    for (draco::PointIndex i(0); i < mesh->num_points(); ++i) {
      float f[3];
      if (!pa->ConvertValue<float, 3>(pa->mapped_index(i), f)) fail(element, "unreadable position");
      positions[i.value()] = {f[0], f[1], f[2]};
    }
    indices.clear();
    indices.reserve(mesh->num_faces() * 3);
    for (draco::FaceIndex f(0); f < mesh->num_faces(); ++f)
      for (int k = 0; k < 3; ++k) indices.push_back(mesh->face(f)[k].value());
  }

  // Triangles of one primitive (indices into `positions`), or nullopt-like
  // empty result with a warning for points and lines.
  bool read_primitive(const tinygltf::Primitive& prim, const std::string& where, const std::string& node,
                      std::vector<Vec3>& positions, std::vector<Tri>& tris) {
    int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
        mode != TINYGLTF_MODE_TRIANGLE_FAN) {
      out_.warnings.push_back(node + ": " + where + " has mode " + mode_name(mode) + " (" + std::to_string(mode) +
                              "), not triangles: skipped");
      return false;
    }
    std::vector<std::uint32_t> idx;
    if (auto ext = prim.extensions.find(kDraco); ext != prim.extensions.end()) {
      read_draco(ext->second, positions, idx, where);
      mode = TINYGLTF_MODE_TRIANGLES;  // Draco decodes strips to a triangle list
    } else {
      auto pos = prim.attributes.find("POSITION");
      if (pos == prim.attributes.end()) fail(where, "no POSITION attribute");
      positions = read_positions(pos->second, where + " POSITION");
      if (prim.indices >= 0) {
        idx = read_indices(prim.indices, where + " indices");
        for (std::size_t i = 0; i < idx.size(); ++i)
          if (idx[i] >= positions.size())
            fail(where + " indices, accessor " + std::to_string(prim.indices),
                 "index " + std::to_string(idx[i]) + " at position " + std::to_string(i) +
                     " is out of range: POSITION accessor " + std::to_string(pos->second) + " has " +
                     std::to_string(positions.size()) + " vertices");
      } else {
        idx.resize(positions.size());
        for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<std::uint32_t>(i);
      }
    }
    tris.clear();
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      if (idx.size() % 3)
        fail(where, std::to_string(idx.size()) + " vertex indices for TRIANGLES, not a multiple of 3");
      for (std::size_t i = 0; i + 2 < idx.size(); i += 3) tris.push_back({idx[i], idx[i + 1], idx[i + 2]});
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      // Odd triangles swap their last two corners so the strip keeps one winding.
      for (std::size_t i = 0; i + 2 < idx.size(); ++i)
        tris.push_back(i % 2 == 0 ? Tri{idx[i], idx[i + 1], idx[i + 2]} : Tri{idx[i], idx[i + 2], idx[i + 1]});
    } else {
      for (std::size_t i = 1; i + 1 < idx.size(); ++i) tris.push_back({idx[i], idx[i + 1], idx[0]});
    }
    return true;
  }

  void add_mesh(int node_index, const Mat4& world) {
    const tinygltf::Node& node = model_.nodes[node_index];
    if (static_cast<std::size_t>(node.mesh) >= model_.meshes.size())
      fail(node_label(node_index), "mesh " + std::to_string(node.mesh) + " does not exist");
    const tinygltf::Mesh& mesh = model_.meshes[node.mesh];
    const std::string mesh_label = "mesh " + std::to_string(node.mesh) + (mesh.name.empty() ? "" : " " + quote(mesh.name));
    const std::string base = !node.name.empty()   ? node.name
                             : !mesh.name.empty() ? mesh.name
                                                  : "part" + std::to_string(node_index);
    const Mat4 full = multiply(kYUpToZUp, world);
    const bool mirrored = det3(world) < 0;

    std::vector<int> materials;  // in order of first use
    std::vector<ImportedPart> parts;
    for (std::size_t p = 0; p < mesh.primitives.size(); ++p) {
      const tinygltf::Primitive& prim = mesh.primitives[p];
      const std::string where = mesh_label + " primitive " + std::to_string(p);
      std::vector<Vec3> positions;
      std::vector<Tri> tris;
      if (!read_primitive(prim, where, node_label(node_index), positions, tris)) continue;
      if (prim.material >= 0 && static_cast<std::size_t>(prim.material) >= model_.materials.size())
        fail(where, "material " + std::to_string(prim.material) + " does not exist");
      const int mat = prim.material < 0 ? -1 : prim.material;
      auto it = std::find(materials.begin(), materials.end(), mat);
      if (it == materials.end()) {
        materials.push_back(mat);
        ImportedPart part;
        part.material = mat < 0 ? "" : model_.materials[mat].name;
        parts.push_back(std::move(part));
        it = materials.end() - 1;
      }
      ImportedPart& part = parts[it - materials.begin()];
      VertexRemap remap;
      for (Tri t : tris) {
        if (mirrored) std::swap(t[1], t[2]);
        Tri local;
        for (int k = 0; k < 3; ++k) local[k] = remap(part, t[k], transform_point(full, positions[t[k]]));
        part.triangles.push_back(local);
      }
    }
    for (std::size_t k = 0; k < parts.size(); ++k) {
      parts[k].name = parts.size() == 1 ? base : base + "#" + std::to_string(k);
      parts[k].source = node_label(node_index) + ", " + mesh_label;
      out_.parts.push_back(std::move(parts[k]));
    }
  }

  void visit(int index, const Mat4& parent, std::vector<int>& visiting) {
    if (index < 0 || static_cast<std::size_t>(index) >= model_.nodes.size())
      fail("node " + std::to_string(index), "does not exist (the file has " + std::to_string(model_.nodes.size()) +
                                                " nodes)");
    if (std::find(visiting.begin(), visiting.end(), index) != visiting.end())
      fail(node_label(index), "node hierarchy has a cycle");
    // glTF nodes form trees; a node reached twice would be imported twice, and
    // shared subtrees could multiply without bound.
    if (seen_[index]) fail(node_label(index), "has more than one parent (glTF node hierarchies are trees)");
    seen_[index] = true;
    const tinygltf::Node& node = model_.nodes[index];
    if (node.extensions.count("EXT_mesh_gpu_instancing"))
      fail(node_label(index), "EXT_mesh_gpu_instancing is not supported");
    visiting.push_back(index);
    const Mat4 world = multiply(parent, local_matrix(index));
    if (node.mesh >= 0) add_mesh(index, world);
    for (int child : node.children) visit(child, world, visiting);
    visiting.pop_back();
  }
};

// ---------------------------------------------------------------- OBJ/PLY/OFF

// Receives what OpenMesh's parsers read, as a polygon soup. Its own TriMesh
// importer changes what it cannot store: a face on a non-manifold ("complex")
// edge is re-added on duplicated vertices, detached from its neighbours, and
// faces with repeated or invalid vertex indices are dropped with only a log
// line. Here every face arrives as written and is checked afterwards.
class SoupImporter : public OpenMesh::IO::BaseImporter {
 public:
  std::vector<Vec3> points;
  std::vector<std::vector<int>> faces;
  bool declared = false;  // readers that know the counts (PLY, OFF) call reserve()
  std::size_t declared_vertices = 0, declared_faces = 0;

  using VH = OpenMesh::VertexHandle;
  using FH = OpenMesh::FaceHandle;
  using HH = OpenMesh::HalfedgeHandle;
  using EH = OpenMesh::EdgeHandle;

  VH add_vertex(const OpenMesh::Vec3f& p) override {
    points.push_back({p[0], p[1], p[2]});
    return VH(static_cast<int>(points.size() - 1));
  }
  VH add_vertex(const OpenMesh::Vec3d& p) override {
    points.push_back({p[0], p[1], p[2]});
    return VH(static_cast<int>(points.size() - 1));
  }
  VH add_vertex() override {
    points.push_back({0, 0, 0});
    return VH(static_cast<int>(points.size() - 1));
  }
  void set_point(VH v, const OpenMesh::Vec3f& p) override {
    if (v.is_valid() && static_cast<std::size_t>(v.idx()) < points.size()) points[v.idx()] = {p[0], p[1], p[2]};
  }
  FH add_face(const VHandles& corners) override {
    std::vector<int> f;
    f.reserve(corners.size());
    for (const VH& v : corners) f.push_back(v.idx());
    faces.push_back(std::move(f));
    return FH(static_cast<int>(faces.size() - 1));
  }
  void reserve(unsigned int nv, unsigned int, unsigned int nf) override {
    declared = true;
    declared_vertices = nv;
    declared_faces = nf;
  }
  std::size_t n_vertices() const override { return points.size(); }
  std::size_t n_faces() const override { return faces.size(); }
  std::size_t n_edges() const override { return 0; }

  // Attributes raysweep does not use.
  HH add_edge(VH, VH) override { return HH(); }
  FH add_face(HH) override { return FH(); }
  void add_face_texcoords(FH, VH, const std::vector<OpenMesh::Vec2f>&) override {}
  void add_face_texcoords(FH, VH, const std::vector<OpenMesh::Vec3f>&) override {}
  void set_face_texindex(FH, int) override {}
  void set_halfedge(VH, HH) override {}
  void set_normal(VH, const OpenMesh::Vec3f&) override {}
  void set_normal(VH, const OpenMesh::Vec3d&) override {}
  void set_color(VH, const OpenMesh::Vec3uc&) override {}
  void set_color(VH, const OpenMesh::Vec4uc&) override {}
  void set_color(VH, const OpenMesh::Vec3f&) override {}
  void set_color(VH, const OpenMesh::Vec4f&) override {}
  void set_texcoord(VH, const OpenMesh::Vec2f&) override {}
  void set_status(VH, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_next(HH, HH) override {}
  void set_face(HH, FH) override {}
  void request_face_texcoords2D() override {}
  void set_texcoord(HH, const OpenMesh::Vec2f&) override {}
  void set_texcoord(VH, const OpenMesh::Vec3f&) override {}
  void set_texcoord(HH, const OpenMesh::Vec3f&) override {}
  void set_status(HH, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_color(EH, const OpenMesh::Vec3uc&) override {}
  void set_color(EH, const OpenMesh::Vec4uc&) override {}
  void set_color(EH, const OpenMesh::Vec3f&) override {}
  void set_color(EH, const OpenMesh::Vec4f&) override {}
  void set_status(EH, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_normal(FH, const OpenMesh::Vec3f&) override {}
  void set_normal(FH, const OpenMesh::Vec3d&) override {}
  void set_color(FH, const OpenMesh::Vec3uc&) override {}
  void set_color(FH, const OpenMesh::Vec4uc&) override {}
  void set_color(FH, const OpenMesh::Vec3f&) override {}
  void set_color(FH, const OpenMesh::Vec4f&) override {}
  void set_status(FH, const OpenMesh::Attributes::StatusInfo&) override {}
  void add_texture_information(int, std::string) override {}
};

// What OpenMesh does not keep from an OBJ: the o/g/usemtl state of every face
// line, plus the resolved corners, so the labels can be matched to the faces
// the reader produced.
struct ObjLabels {
  struct Face {
    std::string group;  // g name, else o name, else ""
    std::string material;
    std::vector<int> corners;  // 0-based, duplicates removed as OpenMesh does
    std::size_t line;
  };
  std::size_t vertices = 0;
  std::vector<Face> faces;
  std::map<std::string, std::size_t> short_faces;  // per group: face lines with fewer than 3 distinct corners
};

ObjLabels scan_obj(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "", "cannot open file");
  ObjLabels out;
  std::string object, group, material, line;
  for (std::size_t number = 1; std::getline(in, line); ++number) {
    std::istringstream ss(line);
    std::string key;
    if (!(ss >> key) || key[0] == '#') continue;
    auto rest = [&] {
      std::string r;
      std::getline(ss, r);
      const auto a = r.find_first_not_of(" \t\r");
      const auto b = r.find_last_not_of(" \t\r");
      return a == std::string::npos ? std::string() : r.substr(a, b - a + 1);
    };
    if (key == "v") {
      double c[3];
      std::string tok;
      for (double& x : c) {
        if (!(ss >> tok)) throw InputError(path, "line " + std::to_string(number), "vertex needs 3 coordinates");
        char* end = nullptr;
        x = std::strtod(tok.c_str(), &end);
        if (end == tok.c_str() || *end != '\0')
          throw InputError(path, "line " + std::to_string(number), "unreadable vertex coordinate " + quote(tok));
        if (!std::isfinite(x))
          throw InputError(path, "line " + std::to_string(number), "vertex coordinate " + quote(tok) + " is not finite");
      }
      ++out.vertices;
    } else if (key == "o") {
      object = rest();
      group.clear();
    } else if (key == "g") {
      group = rest();
    } else if (key == "usemtl") {
      material = rest();
    } else if (key == "f") {
      ObjLabels::Face f;
      f.group = !group.empty() ? group : object;
      f.material = material;
      f.line = number;
      std::string tok;
      while (ss >> tok) {
        const std::string first = tok.substr(0, tok.find('/'));
        int v = 0;
        const auto [ptr, ec] = std::from_chars(first.data(), first.data() + first.size(), v);
        if (ec != std::errc() || ptr != first.data() + first.size() || v == 0)
          throw InputError(path, "line " + std::to_string(number), "unreadable face corner " + quote(tok));
        // Negative indices count back from the vertices read so far; positive
        // ones may point ahead (OpenMesh reads all vertices first) and are
        // checked once the whole file is scanned.
        const long long resolved = v < 0 ? static_cast<long long>(out.vertices) + v : v - 1;
        if (resolved < 0)
          throw InputError(path, "line " + std::to_string(number),
                           "face corner " + quote(tok) + " refers to a vertex before the first one");
        if (std::find(f.corners.begin(), f.corners.end(), resolved) == f.corners.end())
          f.corners.push_back(static_cast<int>(resolved));
      }
      if (f.corners.size() < 3) {
        ++out.short_faces[f.group];
        continue;
      }
      out.faces.push_back(std::move(f));
    }
  }
  for (const ObjLabels::Face& f : out.faces)
    for (int c : f.corners)
      if (static_cast<std::size_t>(c) >= out.vertices)
        throw InputError(path, "line " + std::to_string(f.line),
                         "face refers to vertex " + std::to_string(c + 1) + " of " + std::to_string(out.vertices));
  return out;
}

// OpenMesh's OFF and PLY readers trust the counts in a file: a file that ends
// early makes the OFF reader add its last face again and the binary PLY reader
// use uninitialised values, and a corrupt list length (a face "with 4 billion
// corners") makes them loop or allocate without bound. These checks walk the
// layout first, so only well-formed data reaches them (check_ply_layout, in
// ply_io, guards the CGAL reader the same way).

std::vector<std::string> tokens_of(const std::string& line) {
  std::istringstream ss(line);
  std::vector<std::string> out;
  for (std::string t; ss >> t;) out.push_back(t);
  return out;
}

bool parse_count(const std::string& token, std::size_t& value) {
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && ptr == token.data() + token.size();
}

void check_off_layout(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  std::vector<std::string> data;  // non-empty lines, comments removed
  while (std::getline(in, line)) {
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    // A data line holds a token by the stream's whitespace (also \v and \f), as
    // the checks below and OpenMesh read it (a "\v" line made the face check
    // index an empty token list: tests/fuzz/fuzz_off).
    if (!tokens_of(line).empty()) data.push_back(line);
  }
  if (data.empty()) throw InputError(path, "header", "empty file");
  if (data[0].find("BINARY") != std::string::npos) throw InputError(path, "header", "binary OFF is not supported");
  if (data.size() < 2) throw InputError(path, "header", "no vertex and face counts");
  const auto counts = tokens_of(data[1]);
  std::size_t nv = 0, nf = 0;
  if (counts.size() < 2 || !parse_count(counts[0], nv) || !parse_count(counts[1], nf))
    throw InputError(path, "header", "unreadable vertex and face counts");
  if (data.size() - 2 < nv || data.size() - 2 - nv < nf)
    throw InputError(path, "", "truncated: the header declares " + std::to_string(nv) + " vertices and " +
                                   std::to_string(nf) + " faces, the file has " + std::to_string(data.size() - 2) +
                                   " data lines");
  // OpenMesh 9.0's OFF reader loops forever once its stream fails on a token
  // (a vertex index or a colour past 2^32 did: tests/fuzz/fuzz_off), so every
  // token of the counts, vertex and face lines must be a plain decimal number,
  // integers within 32 bits, and the indices below the vertex count.
  static const std::regex decimal(R"([+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?)");
  static const std::regex integer(R"([+-]?[0-9]+)");
  auto check_numbers = [&](const std::vector<std::string>& t, const std::string& element) {
    for (const std::string& tok : t) {
      const bool is_int = std::regex_match(tok, integer);
      const double v = std::strtod(tok.c_str(), nullptr);
      if (!std::regex_match(tok, decimal) || !std::isfinite(v) || (is_int && std::fabs(v) > 2147483647.0))
        throw InputError(path, element, quote(tok) + " is not a finite number (integers within 32 bits)");
    }
  };
  check_numbers(counts, "header");
  for (std::size_t i = 0; i < nv; ++i) {
    const auto t = tokens_of(data[2 + i]);
    if (t.size() < 3) throw InputError(path, "vertex " + std::to_string(i), "needs 3 coordinates");
    check_numbers(t, "vertex " + std::to_string(i));
  }
  for (std::size_t f = 0; f < nf; ++f) {
    const auto t = tokens_of(data[2 + nv + f]);
    std::size_t k = 0;
    if (!parse_count(t[0], k) || t.size() < k + 1)
      throw InputError(path, "face " + std::to_string(f), "corner count " + quote(t[0]) + " does not match its line");
    check_numbers(t, "face " + std::to_string(f));
    // OpenMesh reads what follows the indices as a colour (3 or 4 values, 0-255
    // or 0-1); anything else desynchronised it into a 3 GB face (fuzz_off).
    if (k < 3) throw InputError(path, "face " + std::to_string(f), "has " + std::to_string(k) + " corners (at least 3)");
    if (t.size() > k + 5)
      throw InputError(path, "face " + std::to_string(f), "more values after the indices than a colour");
    for (std::size_t c = k + 1; c < t.size(); ++c) {
      const double v = std::strtod(t[c].c_str(), nullptr);
      if (!(v >= 0 && v <= 255))
        throw InputError(path, "face " + std::to_string(f), "colour value " + quote(t[c]) + " is not within 0 to 255");
    }
    for (std::size_t c = 1; c <= k; ++c) {
      std::size_t index = 0;
      if (!parse_count(t[c], index) || index >= nv)
        throw InputError(path, "face " + std::to_string(f),
                         "vertex index " + quote(t[c]) + " out of range (" + std::to_string(nv) + " vertices)");
    }
  }
}

std::mutex& openmesh_mutex() {
  static std::mutex m;
  return m;
}

void import_polygon_file(const std::string& path, const std::string& ext, ImportedModel& out) {
  const std::string stem = fs::path(path).stem().string();
  ObjLabels labels;
  if (ext == ".obj") labels = scan_obj(path);
  if (ext == ".off") check_off_layout(path);
  if (ext == ".ply") check_ply_layout(path);

  SoupImporter soup;
  bool ok;
  {
    std::lock_guard<std::mutex> lock(openmesh_mutex());
    OpenMesh::IO::Options options;
    ok = OpenMesh::IO::IOManager().read(path, soup, options);
  }
  if (!ok) {
    if (ext != ".ply") throw InputError(path, "", "OpenMesh cannot read this file (malformed or unsupported)");
    // CGAL's reader accepts PLY variants OpenMesh refuses; it throws its own
    // InputError naming the file when it cannot read it either.
    PlyMesh ply = read_ply(path);
    out.warnings.push_back("part " + quote(stem) + ": OpenMesh could not read " + path +
                           "; read with the CGAL PLY reader instead");
    ImportedPart part{stem, "", std::move(ply.vertices), std::move(ply.triangles), "file " + path};
    out.parts.push_back(std::move(part));
    return;
  }

  if (soup.declared && (soup.points.size() != soup.declared_vertices || soup.faces.size() != soup.declared_faces))
    throw InputError(path, "", "truncated or malformed: the header declares " +
                                   std::to_string(soup.declared_vertices) + " vertices and " +
                                   std::to_string(soup.declared_faces) + " faces, read " +
                                   std::to_string(soup.points.size()) + " and " + std::to_string(soup.faces.size()));
  if (ext == ".obj" && soup.points.size() != labels.vertices)
    throw InputError(path, "", "OpenMesh read " + std::to_string(soup.points.size()) + " vertices, the file has " +
                                   std::to_string(labels.vertices) + " 'v' lines");
  for (std::size_t f = 0; f < soup.faces.size(); ++f) {
    const auto& corners = soup.faces[f];
    if (corners.size() < 3)
      throw InputError(path, "face " + std::to_string(f),
                       "has " + std::to_string(corners.size()) + " corners (truncated or malformed file)");
    for (int v : corners)
      if (v < 0 || static_cast<std::size_t>(v) >= soup.points.size())
        throw InputError(path, "face " + std::to_string(f),
                         "vertex index " + std::to_string(v) + " is out of range (" +
                             std::to_string(soup.points.size()) + " vertices)");
  }

  // OBJ labels apply only if they describe exactly the faces OpenMesh read.
  bool labelled = ext == ".obj" && labels.faces.size() == soup.faces.size();
  for (std::size_t f = 0; labelled && f < soup.faces.size(); ++f) labelled = labels.faces[f].corners == soup.faces[f];
  if (ext == ".obj" && !labelled)
    out.warnings.push_back("part " + quote(stem) + ": could not match the OBJ groups of " + path +
                           " to the faces read; one part for the whole file");

  std::map<std::pair<std::string, std::string>, std::size_t> part_of;
  std::vector<VertexRemap> remaps;
  for (std::size_t f = 0; f < soup.faces.size(); ++f) {
    std::pair<std::string, std::string> key{stem, ""};
    if (labelled) key = {labels.faces[f].group.empty() ? stem : labels.faces[f].group, labels.faces[f].material};
    auto [it, fresh] = part_of.try_emplace(key, out.parts.size());
    if (fresh) {
      ImportedPart part;
      part.name = key.first;
      part.material = key.second;
      part.source = labelled ? "OBJ faces from line " + std::to_string(labels.faces[f].line) : "file " + path;
      out.parts.push_back(std::move(part));
      remaps.emplace_back();
    }
    ImportedPart& part = out.parts[it->second];
    VertexRemap& remap = remaps[it->second];
    const auto& c = soup.faces[f];
    std::vector<std::uint32_t> local(c.size());
    for (std::size_t k = 0; k < c.size(); ++k) local[k] = remap(part, static_cast<std::size_t>(c[k]), soup.points[c[k]]);
    for (std::size_t k = 1; k + 1 < c.size(); ++k) part.triangles.push_back({local[0], local[k], local[k + 1]});
  }
  // As for glTF nodes: a group whose faces use k > 1 materials gives "<group>#0" ..
  std::map<std::string, int> per_group;
  for (const ImportedPart& p : out.parts) ++per_group[p.name];
  std::map<std::string, int> next;
  for (ImportedPart& p : out.parts)
    if (per_group[p.name] > 1) {
      const int k = next[p.name]++;
      p.name += "#" + std::to_string(k);
    }
  for (const auto& [group, count] : labels.short_faces)
    out.repairs.push_back("dropped " + std::to_string(count) + " OBJ face line" + (count == 1 ? "" : "s") +
                          " with fewer than 3 distinct corners in part " + quote(group.empty() ? stem : group));
}

}  // namespace

const std::vector<std::pair<std::string, double>>& model_units() {
  static const std::vector<std::pair<std::string, double>> units = {
      {"m", 1.0}, {"dm", 0.1}, {"cm", 0.01}, {"mm", 0.001}, {"in", 0.0254}, {"ft", 0.3048}};
  return units;
}

double parse_model_unit(const std::string& name) {
  for (const auto& [n, scale] : model_units())
    if (n == name) return scale;
  return 0;
}

ImportedModel import_model(const std::string& path, const ImportOptions& options) {
  ImportedModel model;
  model.path = path;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path, "", "file not found");
  if (!fs::is_regular_file(path, ec)) throw InputError(path, "", "not a regular file");
  const std::string ext = lower(fs::path(path).extension().string());
  if (ext == ".gltf" || ext == ".glb") {
    model.up_axis = "y";
    GltfImporter(path, model).run();
  } else if (ext == ".obj" || ext == ".ply" || ext == ".off") {
    model.up_axis = "z";
    import_polygon_file(path, ext, model);
  } else {
    throw InputError(path, "", "unsupported model format " + quote(ext) + " (expected .gltf, .glb, .obj, .ply, .off)");
  }
  finish(model, options);
  return model;
}

}  // namespace raysweep::meshkit
