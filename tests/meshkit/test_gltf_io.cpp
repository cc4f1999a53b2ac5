// glb round trips (plain and Draco), the file layout other tools see, and
// errors for damaged files.
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <random>
#include <set>

#include "scene_fixtures.hpp"
#include "meshkit/errors.hpp"
#include "meshkit/gltf_io.hpp"
#include "meshkit/mitsuba_io.hpp"

namespace fs = std::filesystem;
using namespace raysweep::meshkit;
using raysweep::test::add_box;
using raysweep::test::expect_same_scene;

namespace {

fs::path temp_dir(const std::string& name) {
  fs::path dir = fs::path(::testing::TempDir()) / ("raysweep_gltf_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}


// Buildings far from the origin (SUMO-like coordinates, not float-exact),
// ground, and an irregular soup with shared and unused vertices.
Scene sample_scene() {
  Scene s;
  std::uint32_t face = 0;
  const auto b1 = s.add_object("building", "way/101");
  const auto b2 = s.add_object("building", "relation/7");
  const auto g = s.add_object("ground", "ground");
  const auto soup = s.add_object("mesh", "mesh-Soup");
  Mesh& concrete = s.mesh_for("concrete", "buildings");
  add_box(concrete, {1234.1, -987.3, 0.0}, {1251.7, -960.9, 12.3}, b1, face);
  add_box(concrete, {1300.05, -1000.45, 0.0}, {1320.33, -990.01, 31.7}, b2, face);
  Mesh& ground = s.mesh_for("medium_dry_ground", "ground");
  ground.vertices = {{1000.1, -1200.2, 0}, {1600.3, -1200.2, 0}, {1600.3, -700.7, 0}, {1000.1, -700.7, 0}};
  ground.triangles = {{0, 1, 2}, {0, 2, 3}};
  ground.triangle_object = {g, g};
  ground.triangle_face = {face, face};
  ++face;
  Mesh& metal = s.mesh_for("metal", "soup");
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> coord(-50.0, 50.0);
  for (int i = 0; i < 300; ++i) metal.vertices.push_back({coord(rng) + 1250, coord(rng) - 980, coord(rng) * 0.2 + 10});
  std::uniform_int_distribution<std::uint32_t> pick(0, 289);  // 290..299 stay unused
  for (int t = 0; t < 500; ++t) {
    Tri tri{pick(rng), pick(rng), pick(rng)};
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) continue;
    metal.triangles.push_back(tri);
    metal.triangle_object.push_back(soup);
    metal.triangle_face.push_back(face++);
  }
  return s;
}

double max_abs_coord(const Mesh& m) {
  double r = 0;
  for (const Vec3& v : m.vertices)
    for (double c : v) r = std::max(r, std::abs(c));
  return r;
}

std::vector<unsigned char> read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void write_bytes(const fs::path& p, const std::vector<unsigned char>& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

nlohmann::json glb_json(const fs::path& p) {
  const auto bytes = read_bytes(p);
  EXPECT_GE(bytes.size(), 20u);
  std::uint32_t magic, length, json_len;
  std::memcpy(&magic, &bytes[0], 4);
  std::memcpy(&length, &bytes[8], 4);
  std::memcpy(&json_len, &bytes[12], 4);
  EXPECT_EQ(magic, 0x46546C67u);
  EXPECT_EQ(length, bytes.size());
  return nlohmann::json::parse(bytes.begin() + 20, bytes.begin() + 20 + json_len);
}

}  // namespace

TEST(GltfIo, PlainRoundTripIsExactToFloat) {
  const Scene scene = sample_scene();
  const fs::path file = temp_dir("plain") / "scene.glb";
  write_glb(scene, file.string(), {});
  const Scene back = read_glb(file.string());
  // Float32 storage: each coordinate within half an ulp of its magnitude.
  std::vector<double> tol;
  for (const Mesh& m : scene.meshes) tol.push_back(max_abs_coord(m) * 0x1p-24 * 1.0001);
  expect_same_scene(scene, back, tol);
  // Nothing beyond float rounding: the raw floats come back bit-exact.
  for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
    ASSERT_EQ(scene.meshes[i].vertices.size(), back.meshes[i].vertices.size());
    EXPECT_EQ(scene.meshes[i].triangles, back.meshes[i].triangles);
    for (std::size_t v = 0; v < scene.meshes[i].vertices.size(); ++v)
      for (int k = 0; k < 3; ++k)
        ASSERT_EQ(back.meshes[i].vertices[v][k], static_cast<double>(static_cast<float>(scene.meshes[i].vertices[v][k])));
  }
}

TEST(GltfIo, DracoRoundTripWithinQuantisationStep) {
  const Scene scene = sample_scene();
  const fs::path dir = temp_dir("draco");
  for (int bits : {11, 14, 16}) {
    SCOPED_TRACE("bits " + std::to_string(bits));
    const fs::path file = dir / ("scene" + std::to_string(bits) + ".glb");
    write_glb(scene, file.string(), {true, bits});
    const Scene back = read_glb(file.string());
    std::vector<double> tol;
    for (const Mesh& m : scene.meshes) {
      Bounds b = Bounds::none();
      for (const Vec3& v : m.vertices) b.extend(v);  // Draco's box covers unused vertices too
      const double step = draco_position_step(b, bits);
      tol.push_back(step / 2 + 4 * max_abs_coord(m) * 0x1p-24);
    }
    expect_same_scene(scene, back, tol);

    // The bound is tight: the error actually reaches a good part of it, so an
    // inflated step formula would show.
    const Mesh& soup = scene.meshes.back();
    const Mesh& soup_back = back.meshes.back();
    double worst = 0;
    for (std::size_t t = 0; t < soup.triangles.size(); ++t)
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k)
          worst = std::max(worst, std::abs(soup.vertices[soup.triangles[t][c]][k] -
                                           soup_back.vertices[soup_back.triangles[t][c]][k]));
    EXPECT_GT(worst, 0.25 * (tol.back() - 4 * max_abs_coord(soup) * 0x1p-24));
    RecordProperty("draco_bits_" + std::to_string(bits) + "_soup_max_error_m", std::to_string(worst));
  }
}

TEST(GltfIo, DracoLosslessWhenBitsZero) {
  const Scene scene = sample_scene();
  const fs::path file = temp_dir("draco0") / "scene.glb";
  write_glb(scene, file.string(), {true, 0});
  const Scene back = read_glb(file.string());
  std::vector<double> tol;
  for (const Mesh& m : scene.meshes) tol.push_back(max_abs_coord(m) * 0x1p-24 * 1.0001);
  expect_same_scene(scene, back, tol);
}

TEST(GltfIo, PlainFileIsValidGlbForTinygltf) {
  const Scene scene = sample_scene();
  const fs::path file = temp_dir("valid") / "scene.glb";
  write_glb(scene, file.string(), {});

  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&model, &err, &warn, file.string())) << err;
  EXPECT_TRUE(err.empty()) << err;
  EXPECT_EQ(model.asset.version, "2.0");
  ASSERT_EQ(model.meshes.size(), scene.meshes.size());
  std::set<std::string> materials;
  for (const auto& m : model.materials) {
    materials.insert(m.name);
    EXPECT_EQ(m.pbrMetallicRoughness.baseColorFactor.size(), 4u);
  }
  EXPECT_EQ(materials, (std::set<std::string>{"itu_concrete", "itu_medium_dry_ground", "itu_metal"}));
  // Distinct colours, so materials can be told apart in a viewer.
  EXPECT_NE(model.materials[0].pbrMetallicRoughness.baseColorFactor,
            model.materials[1].pbrMetallicRoughness.baseColorFactor);

  // One root carrying the z-up -> y-up rotation, meshes as its children.
  ASSERT_EQ(model.scenes.size(), 1u);
  ASSERT_EQ(model.scenes[0].nodes.size(), 1u);
  const auto& root = model.nodes[model.scenes[0].nodes[0]];
  ASSERT_EQ(root.rotation.size(), 4u);
  EXPECT_NEAR(root.rotation[0], -std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(root.rotation[3], std::sqrt(0.5), 1e-12);
  EXPECT_EQ(root.children.size(), scene.meshes.size());
  for (int c : root.children) {
    EXPECT_TRUE(model.nodes[c].rotation.empty() && model.nodes[c].matrix.empty());
    EXPECT_GE(model.nodes[c].mesh, 0);
  }
  EXPECT_EQ(model.scenes[0].extras.Get("raysweep_objects").ArrayLen(), scene.objects.size());

  for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
    const auto& gm = model.meshes[i];
    EXPECT_EQ(gm.name, scene.meshes[i].name);
    ASSERT_EQ(gm.primitives.size(), 1u);
    const auto& prim = gm.primitives[0];
    const auto& pos = model.accessors[prim.attributes.at("POSITION")];
    EXPECT_EQ(pos.componentType, TINYGLTF_COMPONENT_TYPE_FLOAT);
    EXPECT_EQ(pos.type, TINYGLTF_TYPE_VEC3);
    EXPECT_EQ(pos.minValues.size(), 3u);
    EXPECT_EQ(pos.maxValues.size(), 3u);
    EXPECT_EQ(pos.count, scene.meshes[i].vertices.size());
    const auto& idx = model.accessors[prim.indices];
    EXPECT_EQ(idx.componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
    EXPECT_EQ(idx.count, scene.meshes[i].triangles.size() * 3);
    for (const char* key : {"raysweep_triangle_object", "raysweep_triangle_face"}) {
      ASSERT_TRUE(prim.extras.Has(key)) << key;
      const auto& acc = model.accessors[prim.extras.Get(key).GetNumberAsInt()];
      EXPECT_EQ(acc.type, TINYGLTF_TYPE_SCALAR);
      EXPECT_EQ(acc.componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
      EXPECT_EQ(acc.count, scene.meshes[i].triangles.size());
    }
  }
}

TEST(GltfIo, DracoFileFollowsKhrDracoLayout) {
  const Scene scene = sample_scene();
  const fs::path dir = temp_dir("draco_layout");
  write_glb(scene, (dir / "plain.glb").string(), {});
  write_glb(scene, (dir / "draco.glb").string(), {true, 14});
  // tinygltf 2.7 cannot load spec-conformant Draco files itself (indices
  // accessor without bufferView), so the layout is checked on the JSON.
  const auto doc = glb_json(dir / "draco.glb");
  auto contains = [](const nlohmann::json& list, const std::string& s) {
    return std::find(list.begin(), list.end(), s) != list.end();
  };
  EXPECT_TRUE(contains(doc.at("extensionsUsed"), "KHR_draco_mesh_compression"));
  EXPECT_TRUE(contains(doc.at("extensionsRequired"), "KHR_draco_mesh_compression"));
  ASSERT_EQ(doc.at("meshes").size(), scene.meshes.size());
  for (const auto& mesh : doc.at("meshes")) {
    const auto& prim = mesh.at("primitives").at(0);
    const auto& ext = prim.at("extensions").at("KHR_draco_mesh_compression");
    EXPECT_TRUE(ext.at("bufferView").is_number_integer());
    EXPECT_TRUE(ext.at("attributes").at("POSITION").is_number_integer());
    EXPECT_FALSE(doc.at("accessors").at(prim.at("attributes").at("POSITION").get<int>()).contains("bufferView"));
    EXPECT_FALSE(doc.at("accessors").at(prim.at("indices").get<int>()).contains("bufferView"));
  }
  EXPECT_LT(fs::file_size(dir / "draco.glb"), fs::file_size(dir / "plain.glb"));
  RecordProperty("plain_bytes", std::to_string(fs::file_size(dir / "plain.glb")));
  RecordProperty("draco14_bytes", std::to_string(fs::file_size(dir / "draco.glb")));
}

TEST(GltfIo, ReaderUndoesRootRotationOnly) {
  // A viewer applies the root rotation: a roof point at z = 12.3 must end up
  // at glTF y = 12.3 (up), and reading must give z = 12.3 back.
  Scene scene = sample_scene();
  const fs::path file = temp_dir("axes") / "scene.glb";
  write_glb(scene, file.string(), {});
  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&model, &err, &warn, file.string())) << err;
  const auto& q = model.nodes[model.scenes[0].nodes[0]].rotation;
  // Rotate (x, y, z) by quaternion q (x, y, z, w).
  auto rotate = [&](Vec3 v) {
    const double qx = q[0], qy = q[1], qz = q[2], qw = q[3];
    const double tx = 2 * (qy * v[2] - qz * v[1]), ty = 2 * (qz * v[0] - qx * v[2]), tz = 2 * (qx * v[1] - qy * v[0]);
    return Vec3{v[0] + qw * tx + (qy * tz - qz * ty), v[1] + qw * ty + (qz * tx - qx * tz),
                v[2] + qw * tz + (qx * ty - qy * tx)};
  };
  const Vec3 up = rotate({0, 0, 1});
  EXPECT_NEAR(up[1], 1.0, 1e-12);
  const Vec3 north = rotate({0, 1, 0});  // scene +y (north) -> glTF -z (forward)
  EXPECT_NEAR(north[2], -1.0, 1e-12);
}

TEST(GltfIo, DamagedFilesThrowInputError) {
  const Scene scene = sample_scene();
  const fs::path dir = temp_dir("damaged");
  const fs::path good = dir / "good.glb";
  write_glb(scene, good.string(), {});
  const auto bytes = read_bytes(good);

  auto expect_input_error = [&](const fs::path& p, const std::string& needle) {
    try {
      read_glb(p.string());
      ADD_FAILURE() << p << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };

  const fs::path truncated = dir / "truncated.glb";
  write_bytes(truncated, {bytes.begin(), bytes.begin() + static_cast<long>(bytes.size() / 2)});
  expect_input_error(truncated, "glb");

  const fs::path header_only = dir / "header_only.glb";
  write_bytes(header_only, {bytes.begin(), bytes.begin() + 12});
  expect_input_error(header_only, "glb");

  const fs::path empty = dir / "empty.glb";
  write_bytes(empty, {});
  expect_input_error(empty, "empty");

  const fs::path garbage = dir / "garbage.glb";
  std::vector<unsigned char> junk(bytes.size());
  std::mt19937 rng(7);
  for (auto& b : junk) b = static_cast<unsigned char>(rng());
  write_bytes(garbage, junk);
  expect_input_error(garbage, "glb");

  // Same length, so only the JSON content is wrong.
  const fs::path bad_json = dir / "bad_json.glb";
  auto broken = bytes;
  const std::string needle = "\"asset\"";
  auto it = std::search(broken.begin(), broken.end(), needle.begin(), needle.end());
  ASSERT_NE(it, broken.end());
  *it = '{';
  write_bytes(bad_json, broken);
  expect_input_error(bad_json, "glb");

  expect_input_error(dir / "missing.glb", "cannot open");
}

TEST(GltfIo, UnknownMaterialNamesTheMesh) {
  const Scene scene = sample_scene();
  const fs::path dir = temp_dir("material");
  const fs::path file = dir / "scene.glb";
  write_glb(scene, file.string(), {});
  auto bytes = read_bytes(file);
  const std::string from = "\"name\":\"itu_concrete\"", to = "\"name\":\"itu_concreXe\"";
  auto it = std::search(bytes.begin(), bytes.end(), from.begin(), from.end());
  ASSERT_NE(it, bytes.end());
  std::copy(to.begin(), to.end(), it);
  write_bytes(file, bytes);
  try {
    read_glb(file.string());
    FAIL() << "unknown material accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("buildings-itu_concrete"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("itu_concreXe"), std::string::npos) << e.what();
  }
}

TEST(GltfIo, CorruptDracoDataThrowsInputError) {
  const Scene scene = sample_scene();
  const fs::path file = temp_dir("draco_bad") / "scene.glb";
  write_glb(scene, file.string(), {true, 14});
  auto bytes = read_bytes(file);
  const std::string magic = "DRACO";
  auto it = std::search(bytes.begin(), bytes.end(), magic.begin(), magic.end());
  ASSERT_NE(it, bytes.end());
  std::fill(it, it + 5, 'X');
  write_bytes(file, bytes);
  try {
    read_glb(file.string());
    FAIL() << "corrupt Draco data accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("Draco"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(scene.meshes[0].name), std::string::npos) << e.what();
  }
}

TEST(GltfIo, WriterRejectsScenesItCannotRepresent) {
  Scene bad = sample_scene();
  bad.meshes[0].material = "unobtainium";
  const fs::path dir = temp_dir("reject");
  EXPECT_THROW(write_glb(bad, (dir / "a.glb").string(), {}), std::invalid_argument);
  Scene short_ids = sample_scene();
  short_ids.meshes[0].triangle_face.pop_back();
  EXPECT_THROW(write_glb(short_ids, (dir / "b.glb").string(), {}), std::invalid_argument);
  EXPECT_THROW(write_glb(sample_scene(), (dir / "c.glb").string(), {true, 31}), std::invalid_argument);
}

TEST(GltfIo, ForeignGltfWithoutExtrasGetsObjectsAndFaces) {
  // A y-up glTF from another tool: no root rotation, no raysweep extras.
  tinygltf::Model model;
  model.asset.version = "2.0";
  const float xyz[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};  // quad in the glTF x-y plane
  const std::uint32_t idx[] = {0, 1, 2, 0, 2, 3};
  tinygltf::Buffer buffer;
  buffer.data.resize(sizeof xyz + sizeof idx);
  std::memcpy(buffer.data.data(), xyz, sizeof xyz);
  std::memcpy(buffer.data.data() + sizeof xyz, idx, sizeof idx);
  model.buffers.push_back(buffer);
  tinygltf::BufferView pv, iv;
  pv.buffer = iv.buffer = 0;
  pv.byteLength = sizeof xyz;
  iv.byteOffset = sizeof xyz;
  iv.byteLength = sizeof idx;
  model.bufferViews = {pv, iv};
  tinygltf::Accessor pa, ia;
  pa.bufferView = 0;
  pa.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  pa.type = TINYGLTF_TYPE_VEC3;
  pa.count = 4;
  pa.minValues = {0, 0, 0};
  pa.maxValues = {1, 1, 0};
  ia.bufferView = 1;
  ia.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  ia.type = TINYGLTF_TYPE_SCALAR;
  ia.count = 6;
  model.accessors = {pa, ia};
  tinygltf::Material mat;
  mat.name = "itu_glass";
  model.materials.push_back(mat);
  tinygltf::Primitive prim;
  prim.attributes["POSITION"] = 0;
  prim.indices = 1;
  prim.material = 0;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  tinygltf::Mesh mesh;
  mesh.name = "Window";
  mesh.primitives.push_back(prim);
  model.meshes.push_back(mesh);
  tinygltf::Node node;
  node.mesh = 0;
  node.translation = {10, 0, 0};
  model.nodes.push_back(node);
  tinygltf::Scene sc;
  sc.nodes = {0};
  model.scenes.push_back(sc);
  model.defaultScene = 0;
  const fs::path file = temp_dir("foreign") / "window.glb";
  tinygltf::TinyGLTF writer;
  ASSERT_TRUE(writer.WriteGltfSceneToFile(&model, file.string(), false, true, false, true));

  const Scene s = read_glb(file.string());
  ASSERT_EQ(s.meshes.size(), 1u);
  const Mesh& m = s.meshes[0];
  EXPECT_EQ(m.material, "glass");
  ASSERT_EQ(s.objects.size(), 1u);
  EXPECT_EQ(s.objects[0].source_id, "Window");
  EXPECT_EQ(m.triangle_face, (std::vector<std::uint32_t>{0, 0}));  // one planar quad
  // glTF (x, y, z) + (10, 0, 0) -> scene (x + 10, -z, y): the quad stands upright.
  ASSERT_EQ(m.vertices.size(), 4u);
  EXPECT_NEAR(m.vertices[2][0], 11.0, 1e-12);
  EXPECT_NEAR(m.vertices[2][1], 0.0, 1e-12);
  EXPECT_NEAR(m.vertices[2][2], 1.0, 1e-12);
  // Normal was glTF +z (towards the viewer), i.e. scene -y.
  EXPECT_NEAR(triangle_normal(m, 0)[1], -1.0, 1e-12);
}

TEST(GltfIo, VaN3TwinSceneThroughGlb) {
  const fs::path xml = fs::path(RAYSWEEP_SHARED_DATA) / "van3twin" / "DriveX-devs_VaN3Twin" / "src" / "sionna" /
                       "scenarios" / "SionnaCircleScenario" / "scene.xml";
  if (!fs::exists(xml)) GTEST_SKIP() << "no VaN3Twin data at " << xml;
  const Scene scene = read_mitsuba(xml.string());
  ASSERT_GT(scene.triangle_count(), 0u);
  const fs::path dir = temp_dir("van3twin");
  write_glb(scene, (dir / "plain.glb").string(), {});
  const Scene plain = read_glb((dir / "plain.glb").string());
  expect_same_scene(scene, plain, std::vector<double>(scene.meshes.size(), 0.0));  // PLY floats stay exact

  const int bits = 16;
  write_glb(scene, (dir / "draco.glb").string(), {true, bits});
  const Scene draco = read_glb((dir / "draco.glb").string());
  std::vector<double> tol;
  double worst_step = 0;
  for (const Mesh& m : scene.meshes) {
    Bounds b = Bounds::none();
    for (const Vec3& v : m.vertices) b.extend(v);
    const double step = draco_position_step(b, bits);
    worst_step = std::max(worst_step, step);
    tol.push_back(step / 2 + 4 * max_abs_coord(m) * 0x1p-24);
  }
  expect_same_scene(scene, draco, tol);
  RecordProperty("plain_bytes", std::to_string(fs::file_size(dir / "plain.glb")));
  RecordProperty("draco16_bytes", std::to_string(fs::file_size(dir / "draco.glb")));
  RecordProperty("draco16_worst_step_m", std::to_string(worst_step));
}
