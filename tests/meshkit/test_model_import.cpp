// Third-party model import: glTF node hierarchies and the y-up -> z-up frame
// checked against hand-computed coordinates, part naming, accessor variants,
// unit repair, OBJ/PLY/OFF through OpenMesh (non-manifold faces kept), every
// kind of broken input, and the real vehicle models in the shared data.
#include <gtest/gtest.h>

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "meshkit/errors.hpp"
#include "meshkit/gltf_io.hpp"
#include "meshkit/model_import.hpp"
#include "meshkit/ply_io.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using json = nlohmann::json;
using namespace raysweep::meshkit;
using raysweep::test::scratch_dir;
using raysweep::test::write_text;

namespace {

constexpr int kByte = 5120, kUByte = 5121, kShort = 5122, kUShort = 5123, kUInt = 5125, kFloat = 5126;

std::string base64(const std::vector<unsigned char>& data) {
  static const char* abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < data.size(); i += 3) {
    const unsigned v = data[i] << 16 | data[i + 1] << 8 | data[i + 2];
    for (int k = 3; k >= 0; --k) out.push_back(abc[(v >> (6 * k)) & 63]);
  }
  if (i + 1 == data.size()) {
    const unsigned v = data[i] << 16;
    out += {abc[v >> 18], abc[(v >> 12) & 63], '=', '='};
  } else if (i + 2 == data.size()) {
    const unsigned v = data[i] << 16 | data[i + 1] << 8;
    out += {abc[v >> 18], abc[(v >> 12) & 63], abc[(v >> 6) & 63], '='};
  }
  return out;
}

// Minimal glTF author for hand-built test files: one binary buffer, written
// as a data URI, an external .bin or a GLB chunk.
class GltfWriter {
 public:
  json doc = {{"asset", {{"version", "2.0"}}}};
  std::vector<unsigned char> bin;

  int view(const void* data, std::size_t bytes, int stride = 0) {
    while (bin.size() % 4) bin.push_back(0);
    json v = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes}};
    if (stride) v["byteStride"] = stride;
    const auto* p = static_cast<const unsigned char*>(data);
    bin.insert(bin.end(), p, p + bytes);
    return push("bufferViews", v);
  }
  int accessor(int view, int component, const std::string& type, std::size_t count, std::size_t offset = 0,
               bool normalized = false) {
    json a = {{"componentType", component}, {"type", type}, {"count", count}};
    if (view >= 0) a["bufferView"] = view;
    if (offset) a["byteOffset"] = offset;
    if (normalized) a["normalized"] = true;
    return push("accessors", a);
  }
  int positions(const std::vector<Vec3>& pts) {
    std::vector<float> f;
    for (const Vec3& p : pts) f.insert(f.end(), {float(p[0]), float(p[1]), float(p[2])});
    return accessor(view(f.data(), f.size() * 4), kFloat, "VEC3", pts.size());
  }
  int indices(const std::vector<std::uint32_t>& idx, int component = kUInt) {
    std::vector<unsigned char> raw;
    for (auto i : idx) {
      const int n = component == kUByte ? 1 : component == kUShort ? 2 : 4;
      for (int k = 0; k < n; ++k) raw.push_back(static_cast<unsigned char>(i >> (8 * k)));
    }
    return accessor(view(raw.data(), raw.size()), component, "SCALAR", idx.size());
  }
  int material(const std::string& name) { return push("materials", json{{"name", name}}); }
  static json prim(int pos, int idx = -1, int material = -1, int mode = -1) {
    json p = {{"attributes", {{"POSITION", pos}}}};
    if (idx >= 0) p["indices"] = idx;
    if (material >= 0) p["material"] = material;
    if (mode >= 0) p["mode"] = mode;
    return p;
  }
  int mesh(const std::string& name, const std::vector<json>& prims) {
    json m = {{"primitives", prims}};
    if (!name.empty()) m["name"] = name;
    return push("meshes", m);
  }
  int node(const json& n) { return push("nodes", n); }
  void scene(const std::vector<int>& roots) {
    doc["scenes"] = json::array({json{{"nodes", roots}}});
    doc["scene"] = 0;
  }

  // .gltf with the buffer as a data URI, or as `bin_name` next to it.
  fs::path write_gltf(const fs::path& dir, const std::string& name, const std::string& bin_name = "") {
    json d = doc;
    if (bin_name.empty()) {
      d["buffers"] = json::array({{{"byteLength", bin.size()},
                                   {"uri", "data:application/octet-stream;base64," + base64(bin)}}});
    } else {
      d["buffers"] = json::array({{{"byteLength", bin.size()}, {"uri", bin_name}}});
      std::ofstream(dir / bin_name, std::ios::binary).write(reinterpret_cast<const char*>(bin.data()), bin.size());
    }
    write_text(dir / name, d.dump(1));
    return dir / name;
  }
  fs::path write_glb(const fs::path& dir, const std::string& name) {
    json d = doc;
    std::vector<unsigned char> payload = bin;
    while (payload.size() % 4) payload.push_back(0);
    d["buffers"] = json::array({{{"byteLength", bin.size()}}});
    std::string text = d.dump();
    while (text.size() % 4) text.push_back(' ');
    std::vector<unsigned char> out;
    auto u32 = [&](std::uint32_t v) {
      for (int k = 0; k < 4; ++k) out.push_back(static_cast<unsigned char>(v >> (8 * k)));
    };
    u32(0x46546C67);
    u32(2);
    u32(static_cast<std::uint32_t>(12 + 8 + text.size() + 8 + payload.size()));
    u32(static_cast<std::uint32_t>(text.size()));
    u32(0x4E4F534A);
    out.insert(out.end(), text.begin(), text.end());
    u32(static_cast<std::uint32_t>(payload.size()));
    u32(0x004E4942);
    out.insert(out.end(), payload.begin(), payload.end());
    std::ofstream(dir / name, std::ios::binary).write(reinterpret_cast<const char*>(out.data()), out.size());
    return dir / name;
  }

 private:
  int push(const char* key, const json& v) {
    if (!doc.contains(key)) doc[key] = json::array();
    doc[key].push_back(v);
    return static_cast<int>(doc[key].size() - 1);
  }
};

// Unit cube [0,1]^3 as 12 outward triangles; vertex i = (i&1, i&2, i&4).
std::vector<Vec3> cube_vertices(double size = 1.0) {
  std::vector<Vec3> v;
  for (int i = 0; i < 8; ++i) v.push_back({i & 1 ? size : 0.0, i & 2 ? size : 0.0, i & 4 ? size : 0.0});
  return v;
}
const int kCubeQuads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
std::vector<std::uint32_t> cube_indices() {
  std::vector<std::uint32_t> idx;
  for (const auto& q : kCubeQuads) idx.insert(idx.end(), {std::uint32_t(q[0]), std::uint32_t(q[1]), std::uint32_t(q[2]),
                                                         std::uint32_t(q[0]), std::uint32_t(q[2]), std::uint32_t(q[3])});
  return idx;
}

double signed_volume(const ImportedPart& p) {
  double v = 0;
  for (const Tri& t : p.triangles) {
    const Vec3 &a = p.vertices[t[0]], &b = p.vertices[t[1]], &c = p.vertices[t[2]];
    v += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
  }
  return v / 6.0;
}

const ImportedPart* find_part(const ImportedModel& m, const std::string& name) {
  for (const ImportedPart& p : m.parts)
    if (p.name == name) return &p;
  return nullptr;
}

bool has_vertex(const ImportedPart& p, const Vec3& want, double tol = 1e-6) {
  for (const Vec3& v : p.vertices)
    if (std::abs(v[0] - want[0]) <= tol && std::abs(v[1] - want[1]) <= tol && std::abs(v[2] - want[2]) <= tol)
      return true;
  return false;
}

std::string vec(const Vec3& v) {
  return "(" + std::to_string(v[0]) + ", " + std::to_string(v[1]) + ", " + std::to_string(v[2]) + ")";
}

// Runs import_model expecting an InputError whose message names the file and
// contains `fragment`.
void expect_input_error(const fs::path& file, const std::string& fragment) {
  try {
    import_model(file.string());
    ADD_FAILURE() << file << ": expected an InputError containing '" << fragment << "'";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(file.filename().string()), std::string::npos) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << "'" << fragment << "' missing from: " << what;
  }
}

bool contains(const std::vector<std::string>& lines, const std::string& a, const std::string& b = "") {
  return std::any_of(lines.begin(), lines.end(), [&](const std::string& l) {
    return l.find(a) != std::string::npos && l.find(b) != std::string::npos;
  });
}

}  // namespace

// ---------------------------------------------------------------- glTF frames and transforms

TEST(ModelImport, GltfAxesMapToZUp) {
  const fs::path dir = scratch_dir("axes");
  GltfWriter w;
  // One triangle; its glTF normal is along (6, 3, 2).
  const int pos = w.positions({{1, 0, 0}, {0, 2, 0}, {0, 0, 3}});
  w.node({{"name", "Tri"}, {"mesh", w.mesh("", {GltfWriter::prim(pos)})}});
  w.scene({0});
  const ImportedModel m = import_model(w.write_gltf(dir, "axes.gltf").string());
  EXPECT_EQ(m.up_axis, "y");
  EXPECT_EQ(m.unit_scale, 1.0);
  ASSERT_EQ(m.parts.size(), 1u);
  const ImportedPart& p = m.parts[0];
  EXPECT_EQ(p.name, "Tri");
  EXPECT_EQ(p.material, "");
  ASSERT_EQ(p.triangles.size(), 1u);
  // (x, y, z)_raysweep = (z, x, y)_glTF: glTF's forward +Z is raysweep's +x,
  // glTF's +x (the model's left) is +y, glTF's up +y is +z.
  const Vec3 expect[3] = {{0, 1, 0}, {0, 0, 2}, {3, 0, 0}};
  for (int k = 0; k < 3; ++k) {
    const Vec3& v = p.vertices[p.triangles[0][k]];
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(v[i], expect[k][i], 1e-12) << "corner " << k;
  }
  // Same winding, so the normal is the mapped glTF normal (2, 6, 3).
  const Vec3 &a = p.vertices[p.triangles[0][0]], &b = p.vertices[p.triangles[0][1]], &c = p.vertices[p.triangles[0][2]];
  const Vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const Vec3 n{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  EXPECT_NEAR(n[0], 2, 1e-12);
  EXPECT_NEAR(n[1], 6, 1e-12);
  EXPECT_NEAR(n[2], 3, 1e-12);
}

TEST(ModelImport, GltfHierarchyTransformsExact) {
  const fs::path dir = scratch_dir("hierarchy");
  GltfWriter w;
  const int pos = w.positions(cube_vertices());
  const int idx = w.indices(cube_indices(), kUShort);
  const int cube = w.mesh("CubeMesh", {GltfWriter::prim(pos, idx)});
  const double s45 = std::sqrt(0.5);
  // Parent: translation only. Child: T(1,0,0) * R(90 deg about glTF +Y) * S(2,3,4).
  const int child = w.node({{"name", "Child"},
                            {"mesh", cube},
                            {"translation", {1, 0, 0}},
                            {"rotation", {0, s45, 0, s45}},
                            {"scale", {2, 3, 4}}});
  // Column-major matrix: x scaled by 1, y by 2, then translated by (5, 0, 0).
  const int matrix = w.node({{"name", "Matrix"},
                             {"mesh", cube},
                             {"matrix", {1, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1, 0, 5, 0, 0, 1}}});
  const int parent = w.node({{"name", "Parent"}, {"translation", {10, 20, 30}}, {"children", {child, matrix}}});
  w.scene({parent});

  for (const fs::path& file : {w.write_gltf(dir, "h.gltf", "h.bin"), w.write_glb(dir, "h.glb")}) {
    SCOPED_TRACE(file.string());
    const ImportedModel m = import_model(file.string());
    ASSERT_EQ(m.parts.size(), 2u);
    const ImportedPart* c = find_part(m, "Child");
    ASSERT_NE(c, nullptr);
    EXPECT_EQ(c->vertices.size(), 8u);
    EXPECT_EQ(c->triangles.size(), 12u);
    // Hand computation, glTF frame: p -> (10,20,30) + (1,0,0) + R(S p) with
    // R(x,y,z) = (z, y, -x); then (x,y,z)_raysweep = (z,x,y)_glTF.
    //   (0,0,0) -> (11,20,30) -> (30,11,20)     (1,0,0) -> (11,20,28) -> (28,11,20)
    //   (0,1,0) -> (11,23,30) -> (30,11,23)     (0,0,1) -> (15,20,30) -> (30,15,20)
    //   (1,1,1) -> (15,23,28) -> (28,15,23)
    for (const Vec3& want : {Vec3{30, 11, 20}, Vec3{28, 11, 20}, Vec3{30, 11, 23}, Vec3{30, 15, 20}, Vec3{28, 15, 23}})
      EXPECT_TRUE(has_vertex(*c, want)) << "missing " << vec(want);
    // 2*3*4 = 24, outward.
    EXPECT_NEAR(signed_volume(*c), 24.0, 1e-9);

    const ImportedPart* mp = find_part(m, "Matrix");
    ASSERT_NE(mp, nullptr);
    // (1,1,1) -> (1,2,1) + (5,0,0) + (10,20,30) = (16,22,31) -> (31,16,22).
    EXPECT_TRUE(has_vertex(*mp, {31, 16, 22}));
    EXPECT_TRUE(has_vertex(*mp, {30, 15, 20}));  // (0,0,0) -> (15,20,30)
    EXPECT_NEAR(signed_volume(*mp), 2.0, 1e-9);
    EXPECT_TRUE(m.repairs.empty());
    EXPECT_TRUE(m.warnings.empty());
  }
}

TEST(ModelImport, MirroredNodesKeepOutwardWinding) {
  const fs::path dir = scratch_dir("mirror");
  GltfWriter w;
  const int pos = w.positions(cube_vertices());
  const int cube = w.mesh("Cube", {GltfWriter::prim(pos, w.indices(cube_indices()))});
  const int plain = w.node({{"name", "Plain"}, {"mesh", cube}});
  const int mirrored = w.node({{"name", "Mirrored"}, {"mesh", cube}, {"scale", {-1, 1, 1}}, {"translation", {3, 0, 0}}});
  // Two mirrors cancel: no flip.
  const int inner = w.node({{"name", "DoubleMirrored"}, {"mesh", cube}, {"scale", {1, -1, 1}}});
  const int outer = w.node({{"name", "MirrorParent"}, {"scale", {-1, 1, 1}}, {"children", {inner}}});
  // A mirroring matrix (det -2).
  const int mat = w.node({{"name", "MirrorMatrix"},
                          {"mesh", cube},
                          {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -2, 0, 0, 0, 0, 1}}});
  w.scene({plain, mirrored, outer, mat});
  const ImportedModel m = import_model(w.write_gltf(dir, "mirror.gltf").string());
  ASSERT_EQ(m.parts.size(), 4u);
  for (const auto& [name, volume] : std::vector<std::pair<std::string, double>>{
           {"Plain", 1.0}, {"Mirrored", 1.0}, {"DoubleMirrored", 1.0}, {"MirrorMatrix", 2.0}}) {
    const ImportedPart* p = find_part(m, name);
    ASSERT_NE(p, nullptr) << name;
    EXPECT_NEAR(signed_volume(*p), volume, 1e-9) << name << " must stay outward (positive volume)";
  }
  // The mirrored copy really is mirrored: glTF x in [-1,0] + 3 -> raysweep y in [2,3].
  const Bounds b = [&] {
    Bounds r = Bounds::none();
    for (const Vec3& v : find_part(m, "Mirrored")->vertices) r.extend(v);
    return r;
  }();
  EXPECT_NEAR(b.min[1], 2.0, 1e-12);
  EXPECT_NEAR(b.max[1], 3.0, 1e-12);
}

// ---------------------------------------------------------------- parts and names

TEST(ModelImport, MultiPrimitiveNodeGivesOnePartPerMaterial) {
  const fs::path dir = scratch_dir("multi");
  GltfWriter w;
  const int paint = w.material("Paint_Red");
  const int glass = w.material("Glass");
  const int tri_a = w.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  const int tri_b = w.positions({{0, 0, 1}, {1, 0, 1}, {0, 1, 1}});
  const int tri_c = w.positions({{0, 0, 2}, {1, 0, 2}, {0, 1, 2}});
  const int tri_d = w.positions({{0, 0, 3}, {1, 0, 3}, {0, 1, 3}});
  const int line = w.positions({{0, 0, 0}, {1, 1, 1}});
  const int mesh = w.mesh("BodyMesh", {GltfWriter::prim(tri_a, -1, paint), GltfWriter::prim(tri_b, -1, glass),
                                       GltfWriter::prim(tri_c, -1, paint), GltfWriter::prim(line, -1, paint, 1),
                                       GltfWriter::prim(tri_d)});
  w.node({{"name", "Body"}, {"mesh", mesh}});
  w.scene({0});
  const fs::path file = w.write_gltf(dir, "multi.gltf");
  const ImportedModel m = import_model(file.string());
  ASSERT_EQ(m.parts.size(), 3u);
  EXPECT_EQ(m.parts[0].name, "Body#0");
  EXPECT_EQ(m.parts[0].material, "Paint_Red");
  EXPECT_EQ(m.parts[0].triangles.size(), 2u);  // primitives 0 and 2
  EXPECT_EQ(m.parts[1].name, "Body#1");
  EXPECT_EQ(m.parts[1].material, "Glass");
  EXPECT_EQ(m.parts[1].triangles.size(), 1u);
  EXPECT_EQ(m.parts[2].name, "Body#2");
  EXPECT_EQ(m.parts[2].material, "");
  // The LINES primitive is skipped with a warning naming the node.
  EXPECT_TRUE(contains(m.warnings, "Body", "LINES")) << ::testing::PrintToString(m.warnings);
}

TEST(ModelImport, NameFallbacksAndDuplicates) {
  const fs::path dir = scratch_dir("names");
  GltfWriter w;
  const int pos = w.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  const int named = w.mesh("WheelMesh", {GltfWriter::prim(pos)});
  const int anon = w.mesh("", {GltfWriter::prim(pos)});
  w.node({{"mesh", named}, {"translation", {0, 0, 1}}});                 // 0: mesh name
  w.node({{"mesh", anon}, {"translation", {0, 0, 2}}});                  // 1: part1
  w.node({{"name", "Wheel"}, {"mesh", named}, {"translation", {0, 0, 3}}});  // 2
  w.node({{"name", "Wheel"}, {"mesh", named}, {"translation", {0, 0, 4}}});  // 3: duplicate
  w.scene({0, 1, 2, 3});
  const ImportedModel m = import_model(w.write_gltf(dir, "names.gltf").string());
  std::vector<std::string> names;
  for (const auto& p : m.parts) names.push_back(p.name);
  EXPECT_EQ(names, (std::vector<std::string>{"WheelMesh", "part1", "Wheel", "Wheel.2"}));
}

TEST(ModelImport, NoScenesUsesRootNodes) {
  const fs::path dir = scratch_dir("noscene");
  GltfWriter w;
  const int pos = w.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  const int mesh = w.mesh("M", {GltfWriter::prim(pos)});
  const int child = w.node({{"name", "Child"}, {"mesh", mesh}});
  w.node({{"name", "Root"}, {"mesh", mesh}, {"translation", {0, 0, 5}}, {"children", {child}}});
  const ImportedModel m = import_model(w.write_gltf(dir, "noscene.gltf").string());
  ASSERT_EQ(m.parts.size(), 2u);  // the child is visited once, under its parent
  EXPECT_TRUE(has_vertex(*find_part(m, "Child"), {5, 0, 0}));
}

// ---------------------------------------------------------------- accessor variants

TEST(ModelImport, AccessorVariants) {
  const fs::path dir = scratch_dir("variants");
  GltfWriter w;
  w.doc["extensionsUsed"] = {"KHR_mesh_quantization"};
  const std::vector<Vec3> quad = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const int pos = w.positions(quad);
  auto add = [&](const std::string& name, const json& prim) {
    w.node({{"name", name}, {"mesh", w.mesh("", {prim})}});
  };
  add("u8", GltfWriter::prim(pos, w.indices({0, 1, 2, 0, 2, 3}, kUByte)));
  add("u16", GltfWriter::prim(pos, w.indices({0, 1, 2, 0, 2, 3}, kUShort)));
  add("u32", GltfWriter::prim(pos, w.indices({0, 1, 2, 0, 2, 3}, kUInt)));
  add("strip", GltfWriter::prim(pos, w.indices({1, 2, 0, 3}), -1, 5));
  add("fan", GltfWriter::prim(pos, w.indices({0, 1, 2, 3}), -1, 6));
  add("plain", GltfWriter::prim(w.positions({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0}})));
  {
    // Interleaved position + normal, stride 24.
    std::vector<float> data;
    for (const Vec3& p : quad) data.insert(data.end(), {float(p[0]), float(p[1]), float(p[2]), 0.f, 0.f, 1.f});
    const int view = w.view(data.data(), data.size() * 4, 24);
    add("strided", GltfWriter::prim(w.accessor(view, kFloat, "VEC3", 4), w.indices({0, 1, 2, 0, 2, 3})));
  }
  {
    // Sparse positions over an implicit all-zero base: corners 1..3 set.
    const std::vector<std::uint16_t> sidx = {1, 2, 3};
    const std::vector<float> svals = {1, 0, 0, 1, 1, 0, 0, 1, 0};
    const int iv = w.view(sidx.data(), sidx.size() * 2);
    const int vv = w.view(svals.data(), svals.size() * 4);
    const int acc = w.accessor(-1, kFloat, "VEC3", 4);
    w.doc["accessors"][acc]["sparse"] = {{"count", 3},
                                         {"indices", {{"bufferView", iv}, {"componentType", kUShort}}},
                                         {"values", {{"bufferView", vv}}}};
    add("sparse", GltfWriter::prim(acc, w.indices({0, 1, 2, 0, 2, 3})));
  }
  {
    // KHR_mesh_quantization: normalized SHORT positions (32767 -> 1.0).
    const std::vector<std::int16_t> q = {0, 0, 0, 0, 32767, 0, 0, 0, 32767, 32767, 0, 0, 0, 32767, 0, 0};
    const int view = w.view(q.data(), q.size() * 2, 8);
    add("normalized", GltfWriter::prim(w.accessor(view, kShort, "VEC3", 4, 0, true), w.indices({0, 1, 2, 0, 2, 3})));
  }
  std::vector<int> roots;
  for (std::size_t i = 0; i < w.doc["nodes"].size(); ++i) roots.push_back(static_cast<int>(i));
  w.scene(roots);

  const ImportedModel m = import_model(w.write_glb(dir, "variants.glb").string());
  ASSERT_EQ(m.parts.size(), roots.size());
  for (const ImportedPart& p : m.parts) {
    SCOPED_TRACE(p.name);
    EXPECT_EQ(p.triangles.size(), 2u);
    EXPECT_EQ(p.vertices.size(), p.name == "plain" ? 6u : 4u);  // no welding by position
    // The unit quad in glTF's z = 0 plane is raysweep's x = 0 plane: y, z in [0, 1].
    for (const Vec3& want : {Vec3{0, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 1, 1}, Vec3{0, 0, 1}})
      EXPECT_TRUE(has_vertex(p, want, 1e-6)) << vec(want);
    // Strips and fans keep one winding: every normal is glTF +z = raysweep +x.
    for (const Tri& t : p.triangles) {
      const Vec3 &a = p.vertices[t[0]], &b = p.vertices[t[1]], &c = p.vertices[t[2]];
      const double nx = (b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]);
      EXPECT_GT(nx, 0.0);
    }
  }
}

TEST(ModelImport, DracoAndRaysweepGlbRoundTrip) {
  const fs::path dir = scratch_dir("draco");
  Scene s;
  const auto obj = s.add_object("mesh", "box");
  Mesh& m = s.mesh_for("metal", "vehicle");
  m.vertices = {{0, 0, 0}, {4, 0, 0}, {0, 2, 0}, {4, 2, 0}, {0, 0, 1.5}, {4, 0, 1.5}, {0, 2, 1.5}, {4, 2, 1.5}};
  for (const auto& q : kCubeQuads) {
    m.triangles.push_back({std::uint32_t(q[0]), std::uint32_t(q[1]), std::uint32_t(q[2])});
    m.triangles.push_back({std::uint32_t(q[0]), std::uint32_t(q[2]), std::uint32_t(q[3])});
  }
  m.triangle_object.assign(12, obj);
  m.triangle_face.resize(12);
  for (std::uint32_t i = 0; i < 12; ++i) m.triangle_face[i] = i / 2;
  for (bool draco : {false, true}) {
    SCOPED_TRACE(draco ? "draco" : "plain");
    const fs::path file = dir / (draco ? "draco.glb" : "plain.glb");
    write_glb(s, file.string(), GltfOptions{draco, 0});
    const ImportedModel im = import_model(file.string());
    ASSERT_EQ(im.parts.size(), 1u);
    EXPECT_EQ(im.parts[0].name, m.name);
    EXPECT_EQ(im.parts[0].material, "itu_metal");
    EXPECT_EQ(im.parts[0].triangles.size(), 12u);
    // write_glb turns the z-up scene into y-up glTF, (x,y,z) -> (x, z, -y);
    // import maps glTF to (z, x, y): together (x, y, z) -> (-y, x, z).
    for (const Vec3& v : m.vertices) EXPECT_TRUE(has_vertex(im.parts[0], {-v[1], v[0], v[2]}, 1e-6)) << vec(v);
    EXPECT_NEAR(signed_volume(im.parts[0]), 12.0, 1e-6);
  }
}

// ---------------------------------------------------------------- units and repairs

// glTF is metres by specification: a 450-unit glTF is not rescaled on a
// guess but warned about, and takes the unit it is given.
TEST(ModelImport, GltfIsMetresUnlessTheUnitIsGiven) {
  const fs::path dir = scratch_dir("cm");
  GltfWriter w;
  const int pos = w.positions({{0, 0, 0}, {180, 0, 0}, {180, 150, 0}, {0, 150, 0}, {0, 0, 450}, {180, 0, 450}});
  w.node({{"name", "Car"}, {"mesh", w.mesh("", {GltfWriter::prim(pos, w.indices({0, 1, 2, 0, 2, 3, 0, 4, 5, 0, 5, 1}))})}});
  w.scene({0});
  const std::string file = w.write_gltf(dir, "cm.gltf").string();
  const ImportedModel as_is = import_model(file, {0, "passenger", 5.0});
  EXPECT_EQ(as_is.unit_scale, 1.0);
  EXPECT_EQ(as_is.unit_source, "glTF (metres by specification)");
  EXPECT_TRUE(contains(as_is.warnings, "model is 450 m long in metres", "implausible for a passenger (about 5 m)"))
      << ::testing::PrintToString(as_is.warnings);
  EXPECT_TRUE(contains(as_is.warnings, "--model-unit", "model_unit in [vehicles.class.passenger]"));

  const ImportedModel m = import_model(file, {parse_model_unit("cm"), "passenger", 5.0});
  EXPECT_DOUBLE_EQ(m.unit_scale, 0.01);
  EXPECT_EQ(m.unit_source, "given");
  EXPECT_TRUE(contains(m.repairs, "model in centimetres (given, extent 450)", "scaled by 0.01"))
      << ::testing::PrintToString(m.repairs);
  EXPECT_TRUE(m.warnings.empty()) << ::testing::PrintToString(m.warnings);
  const Bounds b = m.bounds();
  EXPECT_NEAR(b.max[0] - b.min[0], 4.5, 1e-9);  // glTF z (length) -> x
  EXPECT_NEAR(b.max[1] - b.min[1], 1.8, 1e-9);
  EXPECT_NEAR(b.max[2] - b.min[2], 1.5, 1e-9);
}

// OBJ/PLY/OFF carry no unit: the guess picks the unit whose length is nearest
// the class (or 1 to 25 m). The 4,500-unit millimetre car used to be taken as
// centimetres (45 m long).
TEST(ModelImport, PolygonFileUnitIsGuessedOrGiven) {
  const fs::path dir = scratch_dir("units");
  struct Case {
    double length;        // file units
    double class_length;  // 0: unknown
    double want_scale;
  };
  const Case cases[] = {{4.5, 0, 1.0},   {450, 0, 0.01},  {4500, 0, 0.001}, {4500, 5.0, 0.001}, {2.5, 5.0, 1.0},
                        {1200, 12, 0.01}, {12000, 12, 0.001}, {30, 0, 1.0}, {1600, 1.6, 0.001}};
  for (const Case& c : cases) {
    std::vector<Vec3> v = cube_vertices();
    for (Vec3& p : v) p = {p[0] * c.length, p[1] * c.length * 0.4, p[2] * c.length * 0.3};
    const std::string file = (dir / "box.obj").string();
    std::string obj;
    for (const Vec3& p : v) obj += "v " + std::to_string(p[0]) + " " + std::to_string(p[1]) + " " + std::to_string(p[2]) + "\n";
    for (const auto& q : kCubeQuads) obj += "f " + std::to_string(q[0] + 1) + " " + std::to_string(q[1] + 1) + " " +
                                           std::to_string(q[2] + 1) + " " + std::to_string(q[3] + 1) + "\n";
    write_text(dir / "box.obj", obj);
    const ImportedModel m = import_model(file, {0, "car", c.class_length});
    EXPECT_DOUBLE_EQ(m.unit_scale, c.want_scale) << c.length << " units, class " << c.class_length;
    EXPECT_EQ(m.unit_source, "guessed from the size");
    const Bounds b = m.bounds();
    EXPECT_NEAR(b.max[0] - b.min[0], c.length * c.want_scale, 1e-9 * c.length);
  }
  // A unit that is given is taken even when implausible, with a warning.
  const ImportedModel given = import_model((dir / "box.obj").string(), {parse_model_unit("m"), "bicycle", 1.6});
  EXPECT_EQ(given.unit_scale, 1.0);
  EXPECT_TRUE(contains(given.warnings, "1600 m long in metres (given)", "implausible for a bicycle"))
      << ::testing::PrintToString(given.warnings);
  EXPECT_EQ(parse_model_unit("mm"), 0.001);
  EXPECT_EQ(parse_model_unit("in"), 0.0254);
  EXPECT_EQ(parse_model_unit("furlong"), 0.0);
}

TEST(ModelImport, ZeroSizeModelIsAnError) {
  const fs::path dir = scratch_dir("tiny");
  GltfWriter w;
  const int pos = w.positions({{0, 0, 0}, {0.01, 0, 0}, {0, 0.01, 0}});
  w.node({{"name", "Speck"}, {"mesh", w.mesh("", {GltfWriter::prim(pos)})}});
  w.scene({0});
  expect_input_error(w.write_gltf(dir, "tiny.gltf"), "zero-size model");
}

TEST(ModelImport, DegenerateTrianglesDroppedAndCounted) {
  const fs::path dir = scratch_dir("degenerate");
  GltfWriter w;
  // Triangle 1 repeats a vertex, triangle 2 is collinear, triangle 3 uses two
  // coincident positions; only triangle 0 survives.
  const int pos = w.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}, {0, 1, 0}});
  const int good = w.mesh("", {GltfWriter::prim(pos, w.indices({0, 1, 2, 0, 1, 1, 0, 1, 3, 0, 2, 4}))});
  const int flat = w.mesh("", {GltfWriter::prim(pos, w.indices({0, 1, 3}))});
  w.node({{"name", "Panel"}, {"mesh", good}});
  w.node({{"name", "Sliver"}, {"mesh", flat}});
  w.scene({0, 1});
  const ImportedModel m = import_model(w.write_gltf(dir, "degenerate.gltf").string());
  ASSERT_EQ(m.parts.size(), 1u);
  EXPECT_EQ(m.parts[0].name, "Panel");
  EXPECT_EQ(m.parts[0].triangles.size(), 1u);
  EXPECT_EQ(m.parts[0].vertices.size(), 3u);
  EXPECT_TRUE(contains(m.repairs, "dropped 3 degenerate triangles in part 'Panel'")) << ::testing::PrintToString(m.repairs);
  EXPECT_TRUE(contains(m.repairs, "dropped 1 degenerate triangle in part 'Sliver'"));
  EXPECT_TRUE(contains(m.warnings, "'Sliver'", "dropped"));
}

// ---------------------------------------------------------------- bad input

TEST(ModelImport, BadGltfInputsAreInputErrors) {
  const fs::path dir = scratch_dir("bad");
  auto cube_writer = [] {
    GltfWriter w;
    const int pos = w.positions(cube_vertices());
    w.node({{"name", "Body"}, {"mesh", w.mesh("BodyMesh", {GltfWriter::prim(pos, w.indices(cube_indices()))})}});
    w.scene({0});
    return w;
  };

  expect_input_error(dir / "does_not_exist.glb", "file not found");
  write_text(dir / "model.stl", "solid x\nendsolid x\n");
  expect_input_error(dir / "model.stl", "unsupported model format");
  write_text(dir / "empty.glb", "");
  expect_input_error(dir / "empty.glb", "empty file");

  // Truncated GLB: cut anywhere.
  {
    GltfWriter w = cube_writer();
    const fs::path full = w.write_glb(dir, "full.glb");
    const std::string bytes = raysweep::test::read_text(full);
    expect_input_error([&] {
      write_text(dir / "truncated.glb", bytes.substr(0, bytes.size() / 2));
      return dir / "truncated.glb";
    }(), "truncated");
    for (std::size_t n = 1; n < bytes.size(); n += 7) {
      write_text(dir / "cut.glb", bytes.substr(0, n));
      EXPECT_THROW(import_model((dir / "cut.glb").string()), InputError) << n << " bytes";
    }
  }
  // A header declaring less than itself.
  {
    GltfWriter w = cube_writer();
    std::string bytes = raysweep::test::read_text(w.write_glb(dir, "short_header.glb"));
    bytes[8] = 10, bytes[9] = bytes[10] = bytes[11] = 0;
    write_text(dir / "short_header.glb", bytes);
    expect_input_error(dir / "short_header.glb", "less than a header");
  }
  // Broken JSON.
  write_text(dir / "broken.gltf", R"({"asset": {"version": "2.0"}, "meshes": [{"primitives": [)");
  expect_input_error(dir / "broken.gltf", "malformed JSON");
  // Missing external buffer: the message names its uri.
  {
    GltfWriter w = cube_writer();
    const fs::path file = w.write_gltf(dir, "missing.gltf", "missing_data.bin");
    fs::remove(dir / "missing_data.bin");
    expect_input_error(file, "missing_data.bin");
  }
  // Accessor running past its bufferView: names the accessor and the mesh.
  {
    GltfWriter w = cube_writer();
    w.doc["accessors"][0]["count"] = 9;
    expect_input_error(w.write_gltf(dir, "accessor.gltf"), "BodyMesh");
    expect_input_error(dir / "accessor.gltf", "accessor 0");
  }
  // Accessor index that does not exist.
  {
    GltfWriter w = cube_writer();
    w.doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 42;
    expect_input_error(w.write_gltf(dir, "noaccessor.gltf"), "42");
  }
  // Index out of range.
  {
    GltfWriter w;
    const int pos = w.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    w.node({{"name", "Body"}, {"mesh", w.mesh("BodyMesh", {GltfWriter::prim(pos, w.indices({0, 1, 7}))})}});
    w.scene({0});
    expect_input_error(w.write_gltf(dir, "index.gltf"), "index 7");
    expect_input_error(dir / "index.gltf", "BodyMesh");
  }
  // NaN vertex: names the part.
  {
    GltfWriter w;
    const int pos = w.positions({{0, 0, 0}, {std::nan(""), 0, 0}, {0, 1, 0}});
    w.node({{"name", "Hood"}, {"mesh", w.mesh("", {GltfWriter::prim(pos)})}});
    w.scene({0});
    expect_input_error(w.write_glb(dir, "nan.glb"), "part 'Hood'");
    expect_input_error(dir / "nan.glb", "non-finite");
  }
  // No triangles at all (points only).
  {
    GltfWriter w;
    const int pos = w.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    w.node({{"name", "Dots"}, {"mesh", w.mesh("", {GltfWriter::prim(pos, -1, -1, 0)})}});
    w.scene({0});
    expect_input_error(w.write_gltf(dir, "points.gltf"), "no triangles");
  }
  // Unnormalised integer positions without KHR_mesh_quantization.
  {
    GltfWriter w;
    const std::vector<std::int16_t> q = {0, 0, 0, 0, 100, 0, 0, 0, 0, 100, 0, 0};
    const int pos = w.accessor(w.view(q.data(), q.size() * 2, 8), kShort, "VEC3", 3);
    w.node({{"name", "Q"}, {"mesh", w.mesh("QMesh", {GltfWriter::prim(pos)})}});
    w.scene({0});
    expect_input_error(w.write_gltf(dir, "quant.gltf"), "POSITION must be FLOAT VEC3");
  }
  // Node cycle.
  {
    GltfWriter w = cube_writer();
    w.doc["nodes"][0]["children"] = {0};
    expect_input_error(w.write_gltf(dir, "cycle.gltf"), "cycle");
  }
  // A node with two parents (a DAG, not a tree).
  {
    GltfWriter w = cube_writer();
    const int a = w.node({{"name", "A"}, {"children", {0}}});
    const int b = w.node({{"name", "B"}, {"children", {0}}});
    w.scene({a, b});
    expect_input_error(w.write_gltf(dir, "dag.gltf"), "more than one parent");
  }
}

TEST(ModelImport, MutatedFilesNeverCrash) {
  const fs::path dir = scratch_dir("fuzz");
  GltfWriter w;
  const int pos = w.positions(cube_vertices());
  w.node({{"name", "Body"}, {"mesh", w.mesh("BodyMesh", {GltfWriter::prim(pos, w.indices(cube_indices()))})}});
  w.scene({0});
  const std::string glb = raysweep::test::read_text(w.write_glb(dir, "seed.glb"));
  const std::string gltf = raysweep::test::read_text(w.write_gltf(dir, "seed.gltf"));
  std::mt19937 rng(7);
  int loaded = 0, rejected = 0;
  for (int round = 0; round < 300; ++round) {
    const bool binary = round % 2 == 0;
    std::string bytes = binary ? glb : gltf;
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int k = 0; k < flips; ++k) bytes[rng() % bytes.size()] = static_cast<char>(rng() % 256);
    const fs::path file = dir / (binary ? "m.glb" : "m.gltf");
    write_text(file, bytes);
    try {
      const ImportedModel m = import_model(file.string());
      ++loaded;
      for (const auto& p : m.parts)
        for (const Tri& t : p.triangles)
          for (auto v : t) ASSERT_LT(v, p.vertices.size());
    } catch (const InputError&) {
      ++rejected;
    }
  }
  EXPECT_EQ(loaded + rejected, 300);
}

// ---------------------------------------------------------------- OBJ / PLY / OFF

namespace {

const char* kCubeObj = R"(# unit cube, quads
v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
v 0 0 1
v 1 0 1
v 0 1 1
v 1 1 1
f 1 3 4 2
f 5 6 8 7
f 1 2 6 5
f 3 7 8 4
f 1 5 7 3
f 2 4 8 6
)";

const char* kCubeOff = R"(OFF
8 6 0
0 0 0
1 0 0
0 1 0
1 1 0
0 0 1
1 0 1
0 1 1
1 1 1
4 0 2 3 1
4 4 5 7 6
4 0 1 5 4
4 2 6 7 3
4 0 4 6 2
4 1 3 7 5
)";

std::string cube_ply_ascii() {
  std::string s = "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n"
                  "element face 12\nproperty list uchar int vertex_indices\nend_header\n";
  for (const Vec3& v : cube_vertices()) s += std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + "\n";
  const auto idx = cube_indices();
  for (std::size_t i = 0; i < idx.size(); i += 3)
    s += "3 " + std::to_string(idx[i]) + " " + std::to_string(idx[i + 1]) + " " + std::to_string(idx[i + 2]) + "\n";
  return s;
}

// Three triangles on the edge (0,1): a "complex edge" for OpenMesh.
const std::vector<Vec3> kFin = {{0, 0, 0}, {1, 0, 0}, {0.5, 1, 0}, {0.5, -1, 0}, {0.5, 0, 1}};
const std::vector<Tri> kFinTris = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};

}  // namespace

TEST(ModelImport, ObjOffPlyCubes) {
  const fs::path dir = scratch_dir("cubes");
  write_text(dir / "cube.obj", kCubeObj);
  write_text(dir / "cube.off", kCubeOff);
  write_text(dir / "cube.ply", cube_ply_ascii());
  std::vector<Tri> tris;
  const auto idx = cube_indices();
  for (std::size_t i = 0; i < idx.size(); i += 3) tris.push_back({idx[i], idx[i + 1], idx[i + 2]});
  write_ply((dir / "cube_binary.ply").string(), cube_vertices(), tris);
  for (const char* name : {"cube.obj", "cube.off", "cube.ply", "cube_binary.ply"}) {
    SCOPED_TRACE(name);
    const ImportedModel m = import_model((dir / name).string());
    EXPECT_EQ(m.up_axis, "z");
    ASSERT_EQ(m.parts.size(), 1u);
    EXPECT_EQ(m.parts[0].name, fs::path(name).stem().string());
    EXPECT_EQ(m.parts[0].material, "");
    EXPECT_EQ(m.parts[0].vertices.size(), 8u);
    EXPECT_EQ(m.parts[0].triangles.size(), 12u);
    EXPECT_NEAR(signed_volume(m.parts[0]), 1.0, 1e-9);  // z-up kept as is, outward
    EXPECT_TRUE(m.warnings.empty()) << ::testing::PrintToString(m.warnings);
  }
}

TEST(ModelImport, ObjGroupsAndMaterialsNameParts) {
  const fs::path dir = scratch_dir("objgroups");
  write_text(dir / "car.mtl", "newmtl paint\nKd 1 0 0\nnewmtl glass\nKd 0 0 1\n");
  std::string obj = "mtllib car.mtl\n";
  for (const Vec3& v : cube_vertices()) obj += "v " + std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + "\n";
  obj += "o Car\ng Body\nusemtl paint\nf 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\n"
         "usemtl glass\nf -8 -4 -2 -6\n"  // negative indices: 1 5 7 3
         "g Door\nusemtl paint\nf 2/1/1 4/1/1 8/1/1 6/1/1\n"
         "f 1 1 2\n";  // fewer than 3 distinct corners
  write_text(dir / "car.obj", obj);
  const ImportedModel m = import_model((dir / "car.obj").string());
  ASSERT_EQ(m.parts.size(), 3u) << ::testing::PrintToString(m.warnings);
  EXPECT_EQ(m.parts[0].name, "Body#0");
  EXPECT_EQ(m.parts[0].material, "paint");
  EXPECT_EQ(m.parts[0].triangles.size(), 8u);
  EXPECT_EQ(m.parts[1].name, "Body#1");
  EXPECT_EQ(m.parts[1].material, "glass");
  EXPECT_EQ(m.parts[1].triangles.size(), 2u);
  EXPECT_EQ(m.parts[2].name, "Door");
  EXPECT_EQ(m.parts[2].material, "paint");
  EXPECT_EQ(m.triangle_count(), 12u);
  EXPECT_TRUE(contains(m.repairs, "dropped 1 OBJ face line with fewer than 3 distinct corners in part 'Door'"))
      << ::testing::PrintToString(m.repairs);
}

TEST(ModelImport, NonManifoldFacesAreKept) {
  const fs::path dir = scratch_dir("nonmanifold");
  write_ply((dir / "fin.ply").string(), kFin, kFinTris);
  {
    // For the record: OpenMesh's own TriMesh import keeps the third face only
    // by giving it copies of its corners, which cuts it off from the edge.
    OpenMesh::TriMesh_ArrayKernelT<> tri;
    ASSERT_TRUE(OpenMesh::IO::read_mesh(tri, (dir / "fin.ply").string()));
    std::cout << "OpenMesh TriMesh: " << tri.n_faces() << " faces, " << tri.n_vertices() << " vertices (file: 3, 5)\n";
  }
  std::string obj, off = "OFF\n5 3 0\n";
  for (const Vec3& v : kFin) {
    obj += "v " + std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + "\n";
    off += std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + "\n";
  }
  for (const Tri& t : kFinTris) {
    obj += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " + std::to_string(t[2] + 1) + "\n";
    off += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + "\n";
  }
  write_text(dir / "fin.obj", obj);
  write_text(dir / "fin.off", off);
  for (const char* name : {"fin.ply", "fin.obj", "fin.off"}) {
    SCOPED_TRACE(name);
    const ImportedModel m = import_model((dir / name).string());
    ASSERT_EQ(m.parts.size(), 1u);
    const ImportedPart& p = m.parts[0];
    EXPECT_EQ(p.triangles.size(), 3u);
    ASSERT_EQ(p.vertices.size(), 5u);
    // All three triangles still share one edge (same two vertex indices).
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> edge_use;
    for (const Tri& t : p.triangles)
      for (int k = 0; k < 3; ++k) ++edge_use[std::minmax(t[k], t[(k + 1) % 3])];
    EXPECT_EQ(std::count_if(edge_use.begin(), edge_use.end(), [](const auto& e) { return e.second == 3; }), 1);
    EXPECT_TRUE(m.warnings.empty()) << ::testing::PrintToString(m.warnings);
  }
}

TEST(ModelImport, BadPolygonFilesAreInputErrors) {
  const fs::path dir = scratch_dir("badpoly");
  write_text(dir / "nan.obj", "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n");
  expect_input_error(dir / "nan.obj", "line 3");
  write_text(dir / "index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
  expect_input_error(dir / "index.obj", "line 4");
  write_text(dir / "index.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n");
  expect_input_error(dir / "index.off", "out of range");
  write_text(dir / "short.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  expect_input_error(dir / "short.off", "truncated");
  const std::string ply = cube_ply_ascii();
  write_text(dir / "short.ply", ply.substr(0, ply.size() - 30));
  expect_input_error(dir / "short.ply", "short.ply");
  {
    std::vector<Tri> tris;
    const auto idx = cube_indices();
    for (std::size_t i = 0; i < idx.size(); i += 3) tris.push_back({idx[i], idx[i + 1], idx[i + 2]});
    write_ply((dir / "binary.ply").string(), cube_vertices(), tris);
    const std::string bytes = raysweep::test::read_text(dir / "binary.ply");
    // Every cut inside the data (ending just before a face's list length
    // included, where the readers used to read an uninitialised count).
    const std::size_t data_start = bytes.find("end_header\n") + 11;
    for (std::size_t n = data_start; n < bytes.size(); ++n) {
      write_text(dir / "short_binary.ply", bytes.substr(0, n));
      expect_input_error(dir / "short_binary.ply", "truncated");
    }
    // A corrupt list length in the middle of the faces (13 bytes per face).
    std::string corrupt = bytes;
    corrupt[bytes.size() - 13 * 6] = static_cast<char>(200);
    write_text(dir / "corrupt_binary.ply", corrupt);
    expect_input_error(dir / "corrupt_binary.ply", "face");
  }
  // Absurd corner counts must not make the readers loop or allocate without bound.
  write_text(dir / "huge.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4294967295 0 1 2\n");
  expect_input_error(dir / "huge.off", "face 0");
  {
    std::string huge = cube_ply_ascii();
    huge.replace(huge.rfind("\n3 ") + 1, 1, "4294967295");
    write_text(dir / "huge.ply", huge);
    expect_input_error(dir / "huge.ply", "face 11");
  }
  write_text(dir / "binary.off", "OFF BINARY\n");
  expect_input_error(dir / "binary.off", "binary OFF");
  write_text(dir / "garbage.ply", "this is not a ply file\n");
  expect_input_error(dir / "garbage.ply", "garbage.ply");
  write_text(dir / "lines.obj", "v 0 0 0\nv 1 0 0\nl 1 2\n");
  expect_input_error(dir / "lines.obj", "no triangles");
}

// ---------------------------------------------------------------- shared vehicle models

namespace {

struct VehicleFacts {
  const char* file;
  std::size_t mesh_nodes;
  // Reference box, z-up metres, from tests/data/gltf_bbox.py (numpy; walks the
  // node hierarchy and accessors independently of this code), run as
  //   /usr/bin/python3 tests/data/gltf_bbox.py <model>
  Vec3 min, max;
};

const fs::path kBmw = raysweep::test::shared_data() / "openmaterial-validation-vehicles" / "objects";

void check_vehicle(const VehicleFacts& facts, ImportedModel& out) {
  const fs::path file = kBmw / facts.file;
  out = import_model(file.string());
  // Every node with a mesh is one part (each has one primitive), named after it.
  std::ifstream in(file);
  const json doc = json::parse(in);
  std::set<std::string> mesh_nodes, material_names;
  for (const auto& n : doc["nodes"])
    if (n.contains("mesh")) mesh_nodes.insert(n["name"].get<std::string>());
  for (const auto& mat : doc["materials"]) material_names.insert(mat["name"].get<std::string>());
  ASSERT_EQ(mesh_nodes.size(), facts.mesh_nodes);
  std::set<std::string> part_names;
  for (const auto& p : out.parts) {
    part_names.insert(p.name);
    EXPECT_TRUE(material_names.count(p.material)) << p.name << ": " << p.material;
  }
  EXPECT_EQ(part_names, mesh_nodes);
  EXPECT_EQ(out.unit_scale, 1.0);
  const Bounds b = out.bounds();
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(b.min[k], facts.min[k], 1e-4) << "axis " << k;
    EXPECT_NEAR(b.max[k], facts.max[k], 1e-4) << "axis " << k;
  }
  std::cout << facts.file << ": " << out.parts.size() << " parts, " << out.triangle_count() << " triangles, bbox "
            << vec(b.min) << " .. " << vec(b.max) << ", size " << vec({b.max[0] - b.min[0], b.max[1] - b.min[1], b.max[2] - b.min[2]})
            << "\n";
  std::map<std::string, std::vector<std::string>> by_material;
  for (const auto& p : out.parts) by_material[p.material].push_back(p.name);
  for (const auto& [mat, names] : by_material) {
    std::cout << "  " << mat << ":";
    for (const auto& n : names) std::cout << " " << n;
    std::cout << "\n";
  }
  for (const auto& r : out.repairs) std::cout << "  repair: " << r << "\n";
  for (const auto& w : out.warnings) std::cout << "  warning: " << w << "\n";
}

double horizontal_length(const Bounds& b) { return std::max(b.max[0] - b.min[0], b.max[1] - b.min[1]); }
double horizontal_width(const Bounds& b) { return std::min(b.max[0] - b.min[0], b.max[1] - b.min[1]); }

}  // namespace

TEST(ModelImport, BmwCarIsAPlausibleVehicle) {
  if (!fs::exists(kBmw / "vehicle_example.gltf")) GTEST_SKIP() << "shared data absent: " << kBmw;
  ImportedModel m;
  check_vehicle({"vehicle_example.gltf", 48, {-0.808840, -0.672877, -0.330420}, {0.808840, 3.181690, 0.965954}}, m);
  const Bounds b = m.bounds();
  EXPECT_GT(horizontal_length(b), 3.5);
  EXPECT_LT(horizontal_length(b), 5.5);
  EXPECT_GT(horizontal_width(b), 1.5);
  EXPECT_LT(horizontal_width(b), 2.2);
  EXPECT_GT(b.max[2] - b.min[2], 1.0);
  EXPECT_LT(b.max[2] - b.min[2], 1.8);
}

TEST(ModelImport, BmwTruckIsAPlausibleVehicle) {
  if (!fs::exists(kBmw / "truck_example.gltf")) GTEST_SKIP() << "shared data absent: " << kBmw;
  ImportedModel m;
  check_vehicle({"truck_example.gltf", 80, {-1.437871, -1.453267, -0.545193}, {1.437870, 6.986021, 2.837388}}, m);
  const Bounds b = m.bounds();
  EXPECT_GT(horizontal_length(b), 6.0);
  EXPECT_LT(horizontal_length(b), 12.0);
  EXPECT_GT(b.max[2] - b.min[2], 2.5);
  EXPECT_LT(b.max[2] - b.min[2], 4.5);
}

TEST(ModelImport, KenneySedanLoads) {
  const fs::path file = raysweep::test::shared_data() / "kenney-car-kit-sedan" / "sedan.glb";
  if (!fs::exists(file)) GTEST_SKIP() << "shared data absent: " << file;
  const ImportedModel m = import_model(file.string());
  std::set<std::string> names;
  for (const auto& p : m.parts) {
    names.insert(p.name);
    EXPECT_EQ(p.material, "colormap");
  }
  EXPECT_EQ(names, (std::set<std::string>{"body", "wheel-front-left", "wheel-front-right", "wheel-back-left",
                                          "wheel-back-right"}));
  // Game scale, in metres as far as the heuristic can tell: left unscaled.
  EXPECT_EQ(m.unit_scale, 1.0);
  const Bounds b = m.bounds();
  // Front along +x (glTF +Z), 2.55 long, 1.5 wide, 1.3 high, on the ground;
  // same numbers from tests/data/gltf_bbox.py.
  EXPECT_NEAR(b.min[0], -1.30, 1e-4);
  EXPECT_NEAR(b.max[0], 1.25, 1e-4);
  EXPECT_NEAR(b.min[1], -0.75, 1e-4);
  EXPECT_NEAR(b.max[1], 0.75, 1e-4);
  EXPECT_NEAR(b.min[2], 0.0, 1e-4);
  EXPECT_NEAR(b.max[2], 1.30, 1e-4);
  std::cout << "sedan.glb: " << m.parts.size() << " parts, " << m.triangle_count() << " triangles, bbox " << vec(b.min)
            << " .. " << vec(b.max) << "\n";
  for (const auto& r : m.repairs) std::cout << "  repair: " << r << "\n";
  for (const auto& w : m.warnings) std::cout << "  warning: " << w << "\n";
}

TEST(ModelImport, ObjFacesMayReferToLaterVertices) {
  const fs::path dir = scratch_dir("objforward");
  write_text(dir / "forward.obj", "g Panel\nf 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
  const ImportedModel m = import_model((dir / "forward.obj").string());
  ASSERT_EQ(m.parts.size(), 1u);
  EXPECT_EQ(m.parts[0].name, "Panel");
  EXPECT_EQ(m.parts[0].triangles.size(), 1u);
}
