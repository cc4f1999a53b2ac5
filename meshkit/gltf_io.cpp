#include "meshkit/gltf_io.hpp"

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string_view>

#include "meshkit/mat4.hpp"
#include "meshkit/errors.hpp"
#include "meshkit/material_colors.hpp"
#include "meshkit/materials.hpp"
#include "meshkit/planar_faces.hpp"

namespace raysweep::meshkit {

namespace {

constexpr const char* kDracoExtension = "KHR_draco_mesh_compression";
constexpr const char* kObjectsKey = "raysweep_objects";
constexpr const char* kTriangleObjectKey = "raysweep_triangle_object";
constexpr const char* kTriangleFaceKey = "raysweep_triangle_face";
constexpr const char* kRootName = "raysweep_z_up";

// -90 degrees about x: scene (x, y, z) -> glTF (x, z, -y), so "up" stays up.
const std::vector<double> kZUpToYUp = {-std::sqrt(0.5), 0.0, 0.0, std::sqrt(0.5)};

// ---------------------------------------------------------------- writing

class BinaryBuffer {
 public:
  explicit BinaryBuffer(tinygltf::Model& model) : model_(model) {}

  int add_view(const void* data, std::size_t bytes, int target) {
    // 4-byte alignment satisfies every component type we store.
    while (data_.size() % 4) data_.push_back(0);
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = data_.size();
    view.byteLength = bytes;
    view.target = target;
    const auto* p = static_cast<const unsigned char*>(data);
    data_.insert(data_.end(), p, p + bytes);
    model_.bufferViews.push_back(view);
    return static_cast<int>(model_.bufferViews.size() - 1);
  }

  void finish() {
    tinygltf::Buffer buffer;
    buffer.data = std::move(data_);
    model_.buffers.push_back(std::move(buffer));
  }

 private:
  tinygltf::Model& model_;
  std::vector<unsigned char> data_;
};

int add_accessor(tinygltf::Model& model, int view, int component, int type, std::size_t count,
                 std::vector<double> min = {}, std::vector<double> max = {}) {
  tinygltf::Accessor a;
  a.bufferView = view;
  a.componentType = component;
  a.type = type;
  a.count = count;
  a.minValues = std::move(min);
  a.maxValues = std::move(max);
  model.accessors.push_back(std::move(a));
  return static_cast<int>(model.accessors.size() - 1);
}

void check_writable(const Mesh& m) {
  auto bad = [&](const std::string& what) {
    return std::invalid_argument("write_glb: mesh '" + m.name + "': " + what);
  };
  if (!is_radio_material(m.material)) throw bad("material '" + m.material + "' is not a radio material");
  if (m.triangle_object.size() != m.triangles.size() || m.triangle_face.size() != m.triangles.size())
    throw bad("triangle_object/triangle_face need one entry per triangle");
  if (m.vertices.size() > std::numeric_limits<std::uint32_t>::max()) throw bad("too many vertices");
  for (const Tri& t : m.triangles)
    for (auto v : t)
      if (v >= m.vertices.size()) throw bad("vertex index " + std::to_string(v) + " out of range");
}

std::vector<unsigned char> encode_draco(const Mesh& m, int bits, int* position_id) {
  draco::Mesh dm;
  dm.set_num_points(static_cast<std::uint32_t>(m.vertices.size()));
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false,
                sizeof(float) * 3, 0);
  const int att = dm.AddAttribute(position, true, static_cast<std::uint32_t>(m.vertices.size()));
  draco::PointAttribute* pa = dm.attribute(att);
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const float v[3] = {static_cast<float>(m.vertices[i][0]), static_cast<float>(m.vertices[i][1]),
                        static_cast<float>(m.vertices[i][2])};
    pa->SetAttributeValue(draco::AttributeValueIndex(static_cast<std::uint32_t>(i)), v);
  }
  for (const Tri& t : m.triangles)
    dm.AddFace({draco::PointIndex(t[0]), draco::PointIndex(t[1]), draco::PointIndex(t[2])});

  draco::Encoder encoder;
  // Edgebreaker would reorder faces and break the per-triangle id accessors.
  encoder.SetEncodingMethod(draco::MESH_SEQUENTIAL_ENCODING);
  if (bits > 0) encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, bits);
  draco::EncoderBuffer out;
  const draco::Status status = encoder.EncodeMeshToBuffer(dm, &out);
  if (!status.ok())
    throw std::runtime_error("Draco encoding of mesh '" + m.name + "' failed: " + status.error_msg_string());
  *position_id = static_cast<int>(pa->unique_id());
  return {out.data(), out.data() + out.size()};
}

int material_index(tinygltf::Model& model, const std::string& material) {
  const std::string name = radio_material_id(material);
  for (std::size_t i = 0; i < model.materials.size(); ++i)
    if (model.materials[i].name == name) return static_cast<int>(i);
  tinygltf::Material mat;
  mat.name = name;
  const auto rgb = material_display_color(material);
  mat.pbrMetallicRoughness.baseColorFactor = {rgb[0], rgb[1], rgb[2], 1.0};
  mat.pbrMetallicRoughness.metallicFactor = material == "metal" ? 1.0 : 0.0;
  mat.pbrMetallicRoughness.roughnessFactor = material == "glass" ? 0.1 : 0.8;
  // Walls are single sheets seen from both sides.
  mat.doubleSided = true;
  model.materials.push_back(std::move(mat));
  return static_cast<int>(model.materials.size() - 1);
}

}  // namespace

const char* const kDracoReadersNote =
    "uses KHR_draco_mesh_compression: raysweep reads it, but tinygltf 2.7 (Debian 12) refuses it without "
    "meshkit::tinygltf27_draco_workaround and Debian's Blender 3.4 has no Draco decoder (libextern_draco); "
    "leave draco off for files other tools read";

double draco_position_step(const Bounds& bounds, int bits) {
  double range = 0;
  for (int k = 0; k < 3; ++k) range = std::max(range, bounds.max[k] - bounds.min[k]);
  if (range <= 0) range = 1;  // Draco's choice for a degenerate box
  return range / static_cast<double>((1u << bits) - 1u);
}

void write_glb(const Scene& scene, const std::string& path, const GltfOptions& options) {
  if (options.draco && (options.draco_position_bits < 0 || options.draco_position_bits > 30))
    throw std::invalid_argument("write_glb: draco_position_bits must be in 0..30");
  for (const Mesh& m : scene.meshes) check_writable(m);

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "raysweep";
  BinaryBuffer bin(model);

  tinygltf::Node root;
  root.name = kRootName;
  root.rotation = kZUpToYUp;

  for (const Mesh& m : scene.meshes) {
    if (m.triangles.empty()) continue;
    std::vector<float> xyz;
    xyz.reserve(m.vertices.size() * 3);
    std::vector<double> lo(3, std::numeric_limits<double>::infinity());
    std::vector<double> hi(3, -std::numeric_limits<double>::infinity());
    for (const Vec3& v : m.vertices)
      for (int k = 0; k < 3; ++k) {
        const float f = static_cast<float>(v[k]);
        xyz.push_back(f);
        lo[k] = std::min(lo[k], static_cast<double>(f));
        hi[k] = std::max(hi[k], static_cast<double>(f));
      }

    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    prim.material = material_index(model, m.material);
    if (options.draco) {
      int position_id = 0;
      const auto blob = encode_draco(m, options.draco_position_bits, &position_id);
      const int view = bin.add_view(blob.data(), blob.size(), 0);
      // Accessors without a bufferView: the data lives in the Draco blob.
      prim.attributes["POSITION"] = add_accessor(model, -1, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                 TINYGLTF_TYPE_VEC3, m.vertices.size(), lo, hi);
      prim.indices = add_accessor(model, -1, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                  TINYGLTF_TYPE_SCALAR, m.triangles.size() * 3);
      tinygltf::Value::Object attributes{{"POSITION", tinygltf::Value(position_id)}};
      prim.extensions[kDracoExtension] = tinygltf::Value(tinygltf::Value::Object{
          {"bufferView", tinygltf::Value(view)}, {"attributes", tinygltf::Value(attributes)}});
    } else {
      const int pview = bin.add_view(xyz.data(), xyz.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER);
      prim.attributes["POSITION"] = add_accessor(model, pview, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                 TINYGLTF_TYPE_VEC3, m.vertices.size(), lo, hi);
      const int iview = bin.add_view(m.triangles.data(), m.triangles.size() * sizeof(Tri),
                                     TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
      prim.indices = add_accessor(model, iview, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                  TINYGLTF_TYPE_SCALAR, m.triangles.size() * 3);
    }
    static_assert(sizeof(Tri) == 3 * sizeof(std::uint32_t));
    const int oview = bin.add_view(m.triangle_object.data(), m.triangle_object.size() * 4, 0);
    const int fview = bin.add_view(m.triangle_face.data(), m.triangle_face.size() * 4, 0);
    const int oacc = add_accessor(model, oview, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                  TINYGLTF_TYPE_SCALAR, m.triangles.size());
    const int facc = add_accessor(model, fview, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                  TINYGLTF_TYPE_SCALAR, m.triangles.size());
    prim.extras = tinygltf::Value(tinygltf::Value::Object{{kTriangleObjectKey, tinygltf::Value(oacc)},
                                                          {kTriangleFaceKey, tinygltf::Value(facc)}});

    tinygltf::Mesh gm;
    gm.name = m.name;
    gm.primitives.push_back(std::move(prim));
    model.meshes.push_back(std::move(gm));
    tinygltf::Node node;
    node.name = m.name;
    node.mesh = static_cast<int>(model.meshes.size() - 1);
    model.nodes.push_back(std::move(node));
    root.children.push_back(static_cast<int>(model.nodes.size() - 1));
  }
  bin.finish();
  model.nodes.push_back(std::move(root));

  tinygltf::Scene gscene;
  gscene.name = "raysweep";
  gscene.nodes.push_back(static_cast<int>(model.nodes.size() - 1));
  tinygltf::Value::Array objects;
  objects.reserve(scene.objects.size());
  for (const SceneObject& o : scene.objects)
    objects.emplace_back(tinygltf::Value::Object{{"kind", tinygltf::Value(o.kind)},
                                                 {"source_id", tinygltf::Value(o.source_id)}});
  gscene.extras = tinygltf::Value(tinygltf::Value::Object{{kObjectsKey, tinygltf::Value(std::move(objects))}});
  model.scenes.push_back(std::move(gscene));
  model.defaultScene = 0;
  if (options.draco) {
    model.extensionsUsed.push_back(kDracoExtension);
    model.extensionsRequired.push_back(kDracoExtension);
  }

  tinygltf::TinyGLTF gltf;
  if (!gltf.WriteGltfSceneToFile(&model, path, /*embedImages=*/false, /*embedBuffers=*/true,
                                 /*prettyPrint=*/false, /*writeBinary=*/true))
    throw std::runtime_error("cannot write " + path);
}

// ---------------------------------------------------------------- reading

namespace {

std::uint32_t read_u32(const unsigned char* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
void write_u32(unsigned char* p, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) p[k] = static_cast<unsigned char>(v >> (8 * k));
}

}  // namespace

// tinygltf 2.7 rejects an indices accessor without a bufferView ("accessor[n]
// invalid bufferView": https://github.com/syoyo/tinygltf/issues/328 and /378,
// fixed upstream in 2023 by https://github.com/syoyo/tinygltf/pull/456), yet that is exactly what KHR_draco_mesh_compression prescribes. Draco
// primitives do not need the accessor (the faces come from the blob), so drop
// the reference before tinygltf sees the JSON. Anything that is not a
// well-formed GLB is passed through untouched for tinygltf to report.
void tinygltf27_draco_workaround(std::vector<unsigned char>& glb) {
  if (glb.size() < 20 || read_u32(&glb[0]) != 0x46546C67u || read_u32(&glb[8]) != glb.size()) return;
  const std::uint32_t json_len = read_u32(&glb[12]);
  if (read_u32(&glb[16]) != 0x4E4F534Au || json_len > glb.size() - 20) return;
  // Parsing the JSON chunk only to find nothing to drop cost as much as tinygltf's own parse.
  const std::string_view text_in(reinterpret_cast<const char*>(glb.data()) + 20, json_len);
  if (text_in.find(kDracoExtension) == std::string_view::npos) return;
  nlohmann::json doc = nlohmann::json::parse(glb.begin() + 20, glb.begin() + 20 + json_len, nullptr, false);
  if (doc.is_discarded() || !doc.is_object() || !doc.contains("meshes") || !doc["meshes"].is_array()) return;
  bool changed = false;
  for (auto& mesh : doc["meshes"]) {
    if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array()) continue;
    for (auto& prim : mesh["primitives"]) {
      if (!prim.is_object() || !prim.contains("extensions") || !prim["extensions"].is_object()) continue;
      if (prim["extensions"].contains(kDracoExtension) && prim.contains("indices")) {
        prim.erase("indices");
        changed = true;
      }
    }
  }
  if (!changed) return;
  std::string text = doc.dump();
  while (text.size() % 4) text.push_back(' ');
  std::vector<unsigned char> out(20);
  out.insert(out.end(), text.begin(), text.end());
  out.insert(out.end(), glb.begin() + 20 + json_len, glb.end());
  std::copy(glb.begin(), glb.begin() + 8, out.begin());
  write_u32(&out[8], static_cast<std::uint32_t>(out.size()));
  write_u32(&out[12], static_cast<std::uint32_t>(text.size()));
  write_u32(&out[16], 0x4E4F534Au);
  glb = std::move(out);
}

namespace {


Mat4 node_matrix(const tinygltf::Node& n) {
  if (n.matrix.size() == 16) {
    Mat4 m;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) m[i * 4 + j] = n.matrix[j * 4 + i];  // glTF is column-major
    return m;
  }
  Mat4 m = identity();
  if (n.rotation.size() == 4) {
    const double x = n.rotation[0], y = n.rotation[1], z = n.rotation[2], w = n.rotation[3];
    m = {1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),     0,
         2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),     0,
         2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y), 0,
         0,                       0,                       0,                       1};
  }
  if (n.scale.size() == 3)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) m[i * 4 + j] *= n.scale[j];
  if (n.translation.size() == 3)
    for (int i = 0; i < 3; ++i) m[i * 4 + 3] = n.translation[i];
  return m;
}

// glTF (x, y, z) -> scene (x, -z, y), the inverse of the root rotation.
const Mat4 kYUpToZUp = {1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1};

struct Reader {
  const std::string& path;
  const tinygltf::Model& model;

  [[noreturn]] void fail(const std::string& element, const std::string& what) const {
    throw InputError(path, element, what);
  }

  // Checked view of an accessor's elements in its buffer.
  struct View {
    const unsigned char* data;
    std::size_t stride;
    std::size_t count;
  };

  View view(int index, int type, const std::vector<int>& components, const std::string& where) const {
    if (index < 0 || static_cast<std::size_t>(index) >= model.accessors.size())
      fail(where, "accessor " + std::to_string(index) + " does not exist");
    const tinygltf::Accessor& a = model.accessors[index];
    const std::string name = where + ", accessor " + std::to_string(index);
    if (a.type != type) fail(name, "unexpected accessor type");
    if (std::find(components.begin(), components.end(), a.componentType) == components.end())
      fail(name, "unexpected component type " + std::to_string(a.componentType));
    if (a.sparse.isSparse) fail(name, "sparse accessors are not supported");
    if (a.bufferView < 0 || static_cast<std::size_t>(a.bufferView) >= model.bufferViews.size())
      fail(name, "no valid bufferView");
    const tinygltf::BufferView& bv = model.bufferViews[a.bufferView];
    if (bv.buffer < 0 || static_cast<std::size_t>(bv.buffer) >= model.buffers.size())
      fail(name, "bufferView names no buffer");
    const auto& buf = model.buffers[bv.buffer].data;
    const std::size_t elem = static_cast<std::size_t>(tinygltf::GetComponentSizeInBytes(a.componentType)) *
                             static_cast<std::size_t>(tinygltf::GetNumComponentsInType(a.type));
    const std::size_t stride = bv.byteStride ? bv.byteStride : elem;
    const std::size_t need = a.count == 0 ? 0 : a.byteOffset + stride * (a.count - 1) + elem;
    if (bv.byteOffset + bv.byteLength > buf.size() || need > bv.byteLength)
      fail(name, "data runs past the end of its buffer (truncated?)");
    return {buf.data() + bv.byteOffset + a.byteOffset, stride, a.count};
  }

  std::vector<std::uint32_t> read_uints(int index, const std::string& where) const {
    const View v = view(index, TINYGLTF_TYPE_SCALAR,
                        {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                         TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
                        where);
    const int ct = model.accessors[index].componentType;
    std::vector<std::uint32_t> out(v.count);
    for (std::size_t i = 0; i < v.count; ++i) {
      const unsigned char* p = v.data + i * v.stride;
      if (ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE) {
        out[i] = p[0];
      } else if (ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) {
        std::uint16_t s;
        std::memcpy(&s, p, 2);
        out[i] = s;
      } else {
        std::memcpy(&out[i], p, 4);
      }
    }
    return out;
  }

  std::vector<Vec3> read_positions(int index, const std::string& where) const {
    const View v = view(index, TINYGLTF_TYPE_VEC3, {TINYGLTF_COMPONENT_TYPE_FLOAT}, where);
    std::vector<Vec3> out(v.count);
    for (std::size_t i = 0; i < v.count; ++i) {
      float f[3];
      std::memcpy(f, v.data + i * v.stride, sizeof f);
      out[i] = {f[0], f[1], f[2]};
    }
    return out;
  }

  void decode_draco(const tinygltf::Value& ext, Mesh& m, const std::string& where) const {
    const std::string name = where + ", " + kDracoExtension;
    if (!ext.IsObject() || !ext.Has("bufferView") || !ext.Get("bufferView").IsInt() || !ext.Has("attributes"))
      fail(name, "malformed extension object");
    const tinygltf::Value& attrs = ext.Get("attributes");
    if (!attrs.Has("POSITION") || !attrs.Get("POSITION").IsInt()) fail(name, "no POSITION attribute");
    const int view_index = ext.Get("bufferView").GetNumberAsInt();
    if (view_index < 0 || static_cast<std::size_t>(view_index) >= model.bufferViews.size())
      fail(name, "bufferView " + std::to_string(view_index) + " does not exist");
    const tinygltf::BufferView& bv = model.bufferViews[view_index];
    if (bv.buffer < 0 || static_cast<std::size_t>(bv.buffer) >= model.buffers.size() ||
        bv.byteOffset + bv.byteLength > model.buffers[bv.buffer].data.size())
      fail(name, "compressed data runs past the end of its buffer (truncated?)");

    draco::DecoderBuffer in;
    in.Init(reinterpret_cast<const char*>(model.buffers[bv.buffer].data.data() + bv.byteOffset), bv.byteLength);
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&in);
    if (!decoded.ok()) fail(name, "Draco: " + decoded.status().error_msg_string());
    const std::unique_ptr<draco::Mesh> dm = std::move(decoded).value();
    const draco::PointAttribute* pa =
        dm->GetAttributeByUniqueId(static_cast<std::uint32_t>(attrs.Get("POSITION").GetNumberAsInt()));
    if (!pa || pa->num_components() != 3) fail(name, "POSITION attribute missing from the Draco data");
    m.vertices.resize(dm->num_points());
    for (draco::PointIndex i(0); i < dm->num_points(); ++i) {
      float f[3];
      if (!pa->ConvertValue<float, 3>(pa->mapped_index(i), f)) fail(name, "unreadable position");
      m.vertices[i.value()] = {f[0], f[1], f[2]};
    }
    m.triangles.resize(dm->num_faces());
    for (draco::FaceIndex f(0); f < dm->num_faces(); ++f) {
      const auto& face = dm->face(f);
      m.triangles[f.value()] = {face[0].value(), face[1].value(), face[2].value()};
    }
  }

  Mesh read_primitive(const tinygltf::Primitive& prim, const std::string& mesh_name) const {
    const std::string where = "mesh '" + mesh_name + "'";
    Mesh m;
    m.name = mesh_name;
    if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1)
      fail(where, "primitive mode " + std::to_string(prim.mode) + " is not TRIANGLES");
    if (prim.material < 0 || static_cast<std::size_t>(prim.material) >= model.materials.size())
      fail(where, "no material (need itu_<material>)");
    const std::string& mat_name = model.materials[prim.material].name;
    const auto material = radio_material_from_id(mat_name);
    if (!material) fail(where, "material '" + mat_name + "' is not a radio material (itu_<material> or a custom one)");
    m.material = *material;

    if (auto ext = prim.extensions.find(kDracoExtension); ext != prim.extensions.end()) {
      decode_draco(ext->second, m, where);
    } else {
      auto pos = prim.attributes.find("POSITION");
      if (pos == prim.attributes.end()) fail(where, "no POSITION attribute");
      m.vertices = read_positions(pos->second, where);
      std::vector<std::uint32_t> idx;
      if (prim.indices >= 0) {
        idx = read_uints(prim.indices, where);
      } else {
        idx.resize(m.vertices.size());
        for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<std::uint32_t>(i);
      }
      if (idx.size() % 3) fail(where, "index count " + std::to_string(idx.size()) + " is not a multiple of 3");
      m.triangles.resize(idx.size() / 3);
      for (std::size_t t = 0; t < m.triangles.size(); ++t)
        m.triangles[t] = {idx[3 * t], idx[3 * t + 1], idx[3 * t + 2]};
    }
    for (std::size_t t = 0; t < m.triangles.size(); ++t)
      for (auto v : m.triangles[t])
        if (v >= m.vertices.size())
          fail(where, "triangle " + std::to_string(t) + " uses vertex " + std::to_string(v) + " of " +
                          std::to_string(m.vertices.size()));

    const bool has_ids = prim.extras.Has(kTriangleObjectKey) || prim.extras.Has(kTriangleFaceKey);
    if (has_ids) {
      for (const char* key : {kTriangleObjectKey, kTriangleFaceKey}) {
        if (!prim.extras.Has(key) || !prim.extras.Get(key).IsInt())
          fail(where, std::string("extras lack an accessor index for ") + key);
        auto ids = read_uints(prim.extras.Get(key).GetNumberAsInt(), where + ", " + key);
        if (ids.size() != m.triangles.size())
          fail(where, std::string(key) + " has " + std::to_string(ids.size()) + " entries for " +
                          std::to_string(m.triangles.size()) + " triangles");
        (key == kTriangleObjectKey ? m.triangle_object : m.triangle_face) = std::move(ids);
      }
    }
    return m;
  }

  void apply(const Mat4& t, Mesh& m) const {
    double dev = 0;
    const Mat4 id = identity();
    for (int k = 0; k < 16; ++k) dev = std::max(dev, std::abs(t[k] - id[k]));
    // Our own files cancel exactly up to rounding of the quaternion; keeping
    // the raw floats then makes the round trip bit-exact.
    if (dev < 1e-9) return;
    for (Vec3& v : m.vertices) {
      const Vec3 p = v;
      for (int i = 0; i < 3; ++i) v[i] = t[i * 4] * p[0] + t[i * 4 + 1] * p[1] + t[i * 4 + 2] * p[2] + t[i * 4 + 3];
    }
    const double det = t[0] * (t[5] * t[10] - t[6] * t[9]) - t[1] * (t[4] * t[10] - t[6] * t[8]) +
                       t[2] * (t[4] * t[9] - t[5] * t[8]);
    if (det < 0)
      for (Tri& tri : m.triangles) std::swap(tri[1], tri[2]);
  }
};

}  // namespace

Scene read_glb(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw InputError(path, "", "cannot open glTF file");
  std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  if (file.bad()) throw InputError(path, "", "read error");
  tinygltf27_draco_workaround(bytes);

  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  if (bytes.empty()) throw InputError(path, "", "empty file");
  if (!loader.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(), static_cast<unsigned int>(bytes.size())))
    throw InputError(path, "", "not a readable glb: " + (err.empty() ? warn : err));

  Reader reader{path, model};
  if (model.scenes.empty()) reader.fail("", "no scene");
  const int scene_index = model.defaultScene >= 0 ? model.defaultScene : 0;
  if (static_cast<std::size_t>(scene_index) >= model.scenes.size()) reader.fail("", "defaultScene out of range");
  const tinygltf::Scene& gscene = model.scenes[scene_index];

  Scene scene;
  const bool has_objects = gscene.extras.Has(kObjectsKey);
  if (has_objects) {
    const tinygltf::Value& list = gscene.extras.Get(kObjectsKey);
    if (!list.IsArray()) reader.fail("scene extras", std::string(kObjectsKey) + " is not an array");
    for (std::size_t i = 0; i < list.ArrayLen(); ++i) {
      const tinygltf::Value& o = list.Get(static_cast<int>(i));
      if (!o.IsObject() || !o.Get("kind").IsString() || !o.Get("source_id").IsString())
        reader.fail("scene extras", std::string(kObjectsKey) + "[" + std::to_string(i) +
                                        "] needs string kind and source_id");
      scene.objects.push_back({o.Get("kind").Get<std::string>(), o.Get("source_id").Get<std::string>()});
    }
  }

  std::uint32_t next_face = 0;
  std::vector<int> visiting;
  auto visit = [&](auto&& self, int node_index, const Mat4& parent) -> void {
    if (node_index < 0 || static_cast<std::size_t>(node_index) >= model.nodes.size())
      reader.fail("node " + std::to_string(node_index), "does not exist");
    if (std::find(visiting.begin(), visiting.end(), node_index) != visiting.end())
      reader.fail("node " + std::to_string(node_index), "node hierarchy has a cycle");
    visiting.push_back(node_index);
    const tinygltf::Node& node = model.nodes[node_index];
    const Mat4 world = multiply(parent, node_matrix(node));
    if (node.mesh >= 0) {
      if (static_cast<std::size_t>(node.mesh) >= model.meshes.size())
        reader.fail("node '" + node.name + "'", "mesh " + std::to_string(node.mesh) + " does not exist");
      const tinygltf::Mesh& gm = model.meshes[node.mesh];
      std::string base = !gm.name.empty() ? gm.name : !node.name.empty() ? node.name : "mesh" + std::to_string(node.mesh);
      for (std::size_t p = 0; p < gm.primitives.size(); ++p) {
        const std::string name = gm.primitives.size() == 1 ? base : base + "-" + std::to_string(p);
        Mesh m = reader.read_primitive(gm.primitives[p], name);
        const bool has_ids = !m.triangle_object.empty() || m.triangles.empty();
        if (has_objects && !has_ids)
          reader.fail("mesh '" + name + "'", "raysweep_objects present but the primitive has no per-triangle ids");
        if (!has_objects && !m.triangle_object.empty())
          reader.fail("mesh '" + name + "'", "per-triangle object ids without raysweep_objects in the scene");
        if (!has_objects) {
          const std::uint32_t obj = scene.add_object("mesh", name);
          m.triangle_object.assign(m.triangles.size(), obj);
          m.triangle_face = group_planar_faces(m.vertices, m.triangles, next_face);
          for (auto f : m.triangle_face) next_face = std::max(next_face, f + 1);
        }
        for (std::size_t t = 0; t < m.triangle_object.size(); ++t)
          if (m.triangle_object[t] >= scene.objects.size())
            reader.fail("mesh '" + name + "'", "triangle " + std::to_string(t) + " names object " +
                                                   std::to_string(m.triangle_object[t]) + " of " +
                                                   std::to_string(scene.objects.size()));
        reader.apply(multiply(kYUpToZUp, world), m);
        scene.meshes.push_back(std::move(m));
      }
    }
    for (int child : node.children) self(self, child, world);
    visiting.pop_back();
  };
  for (int root : gscene.nodes) visit(visit, root, identity());
  return scene;
}

}  // namespace raysweep::meshkit
