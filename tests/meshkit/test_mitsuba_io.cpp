// Mitsuba/Sionna scene export and import, the PLY layer under it, and import
// of the VaN3Twin scenes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "scene_fixtures.hpp"
#include "meshkit/errors.hpp"
#include "meshkit/mitsuba_io.hpp"
#include "meshkit/ply_io.hpp"

namespace fs = std::filesystem;
using namespace raysweep::meshkit;
using raysweep::test::add_box;

namespace {

fs::path temp_dir(const std::string& name) {
  fs::path dir = fs::path(::testing::TempDir()) / ("raysweep_mitsuba_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void write_text(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << text;
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}


Scene sample_scene() {
  Scene s;
  std::uint32_t face = 0;
  const auto b1 = s.add_object("building", "way/1");
  const auto b2 = s.add_object("building", "way/2");
  const auto g = s.add_object("ground", "ground");
  Mesh& concrete = s.mesh_for("concrete", "buildings");
  add_box(concrete, {1234.1, -987.3, 0.0}, {1251.7, -960.9, 12.3}, b1, face);
  add_box(concrete, {1300.05, -1000.45, 0.0}, {1320.33, -990.01, 31.7}, b2, face);
  Mesh& brick = s.mesh_for("brick", "buildings");
  add_box(brick, {1400.2, -900.6, 0.0}, {1410.9, -880.1, 8.8}, b2, face);
  Mesh& ground = s.mesh_for("medium_dry_ground", "ground");
  ground.vertices = {{1000.1, -1200.2, 0}, {1600.3, -1200.2, 0}, {1600.3, -700.7, 0}, {1000.1, -700.7, 0}};
  ground.triangles = {{0, 1, 2}, {0, 2, 3}};
  ground.triangle_object = {g, g};
  ground.triangle_face = {face, face};
  return s;
}

// Expects `f` to throw InputError whose message contains every needle.
template <class F>
void expect_input_error(F&& f, const std::vector<std::string>& needles) {
  try {
    f();
    ADD_FAILURE() << "no InputError thrown";
  } catch (const InputError& e) {
    for (const auto& n : needles) EXPECT_NE(std::string(e.what()).find(n), std::string::npos) << e.what();
  }
}

// One shape in a minimal Sionna-style scene around `shape_body`.
std::string scene_xml(const std::string& bsdfs, const std::string& shapes) {
  return "<scene version=\"2.1.0\">\n" + bsdfs + shapes + "</scene>\n";
}
const std::string kConcreteBsdf =
    "<bsdf type=\"diffuse\" id=\"mat-itu_concrete\" name=\"mat-itu_concrete\">"
    "<rgb value=\"0.5 0.5 0.5\" name=\"reflectance\"/></bsdf>\n";

std::string ply_shape(const std::string& id, const std::string& file, const std::string& extra) {
  return "<shape type=\"ply\" id=\"" + id + "\" name=\"" + id + "\">"
         "<string name=\"filename\" value=\"" + file + "\"/>"
         "<boolean name=\"face_normals\" value=\"true\"/>" + extra + "</shape>\n";
}

// A unit quad as two triangles, written through write_ply.
void write_quad_ply(const fs::path& p) {
  fs::create_directories(p.parent_path());
  write_ply(p.string(), {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {{0, 1, 2}, {0, 2, 3}});
}

}  // namespace

TEST(MitsubaIo, RoundTripKeepsMeshesMaterialsTriangles) {
  const Scene scene = sample_scene();
  const fs::path dir = temp_dir("roundtrip");
  write_mitsuba(scene, dir.string());
  ASSERT_TRUE(fs::exists(dir / "scene.xml"));
  for (const Mesh& m : scene.meshes) EXPECT_TRUE(fs::exists(dir / "meshes" / (m.name + ".ply"))) << m.name;

  const Scene back = read_mitsuba((dir / "scene.xml").string());
  ASSERT_EQ(back.meshes.size(), scene.meshes.size());
  ASSERT_EQ(back.objects.size(), scene.meshes.size());  // one object per shape
  std::set<std::uint32_t> all_faces;
  for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
    const Mesh& a = scene.meshes[i];
    const Mesh& b = back.meshes[i];
    SCOPED_TRACE(a.name);
    EXPECT_EQ(b.name, a.name);
    EXPECT_EQ(b.material, a.material);
    EXPECT_EQ(b.triangles, a.triangles);
    ASSERT_EQ(b.vertices.size(), a.vertices.size());
    for (std::size_t v = 0; v < a.vertices.size(); ++v)
      for (int k = 0; k < 3; ++k)
        ASSERT_EQ(b.vertices[v][k], static_cast<double>(static_cast<float>(a.vertices[v][k])));
    EXPECT_EQ(back.objects[i].kind, "mesh");
    EXPECT_EQ(back.objects[i].source_id, "mesh-" + a.name);
    EXPECT_EQ(b.triangle_object, std::vector<std::uint32_t>(a.triangles.size(), static_cast<std::uint32_t>(i)));
    // Planar faces regrouped from geometry: two triangles per box side.
    ASSERT_EQ(b.triangle_face.size(), a.triangles.size());
    std::map<std::uint32_t, int> per_face;
    for (auto f : b.triangle_face) ++per_face[f];
    EXPECT_EQ(per_face.size(), a.triangles.size() / 2);
    for (const auto& [f, n] : per_face) {
      EXPECT_EQ(n, 2) << "face " << f;
      EXPECT_TRUE(all_faces.insert(f).second) << "face id " << f << " reused across meshes";
    }
  }

  // The style Sionna RT 0.x and the VaN3Twin scenes use.
  const std::string xml = read_text(dir / "scene.xml");
  EXPECT_NE(xml.find("<scene version=\"2.1.0\">"), std::string::npos);
  EXPECT_NE(xml.find("<bsdf type=\"diffuse\" id=\"mat-itu_concrete\" name=\"mat-itu_concrete\">"), std::string::npos);
  EXPECT_NE(xml.find("name=\"reflectance\""), std::string::npos);
  EXPECT_NE(xml.find("<shape type=\"ply\" id=\"mesh-buildings-itu_brick\" name=\"mesh-buildings-itu_brick\">"),
            std::string::npos);
  EXPECT_NE(xml.find("<string name=\"filename\" value=\"meshes/buildings-itu_brick.ply\"/>"), std::string::npos);
  EXPECT_NE(xml.find("<boolean name=\"face_normals\" value=\"true\"/>"), std::string::npos);
  EXPECT_NE(xml.find("<ref id=\"mat-itu_brick\" name=\"bsdf\"/>"), std::string::npos);
  // One bsdf per material in use, no more.
  std::size_t bsdfs = 0;
  for (auto p = xml.find("<bsdf "); p != std::string::npos; p = xml.find("<bsdf ", p + 1)) ++bsdfs;
  EXPECT_EQ(bsdfs, 3u);

  // The PLY layout Sionna reads.
  const std::string ply = read_text(dir / "meshes" / "ground-itu_medium_dry_ground.ply");
  EXPECT_EQ(ply.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  for (const char* line : {"property float x\n", "property float y\n", "property float z\n",
                           "element face 2\n", "property list uchar int vertex_indices\n"})
    EXPECT_NE(ply.find(line), std::string::npos) << line;
}

TEST(MitsubaIo, UnknownMaterialNamesTheShape) {
  const fs::path dir = temp_dir("unknown_material");
  write_quad_ply(dir / "meshes" / "q.ply");
  for (const std::string bsdf_id : {"mat-custom", "vacuum", "itu_unobtainium"}) {
    SCOPED_TRACE(bsdf_id);
    const std::string bsdf = "<bsdf type=\"diffuse\" id=\"" + bsdf_id + "\"/>\n";
    write_text(dir / "scene.xml",
               scene_xml(kConcreteBsdf + bsdf,
                         ply_shape("mesh-Fine", "meshes/q.ply", "<ref id=\"mat-itu_concrete\" name=\"bsdf\"/>") +
                             ply_shape("mesh-Custom", "meshes/q.ply", "<ref id=\"" + bsdf_id + "\" name=\"bsdf\"/>")));
    expect_input_error([&] { read_mitsuba((dir / "scene.xml").string()); },
                       {"mesh-Custom", bsdf_id, (dir / "scene.xml").string()});
  }
  // No bsdf at all is no better than an unknown one.
  write_text(dir / "scene.xml", scene_xml(kConcreteBsdf, ply_shape("mesh-Bare", "meshes/q.ply", "")));
  expect_input_error([&] { read_mitsuba((dir / "scene.xml").string()); }, {"mesh-Bare", "no bsdf"});
  // A ref to a bsdf that is never defined.
  write_text(dir / "scene.xml",
             scene_xml("", ply_shape("mesh-Dangling", "meshes/q.ply", "<ref id=\"mat-itu_metal\" name=\"bsdf\"/>")));
  expect_input_error([&] { read_mitsuba((dir / "scene.xml").string()); }, {"mesh-Dangling", "not defined"});
}

TEST(MitsubaIo, MissingPlyNamesShapeAndPath) {
  const fs::path dir = temp_dir("missing_ply");
  write_text(dir / "scene.xml",
             scene_xml(kConcreteBsdf,
                       ply_shape("mesh-Ghost", "meshes/nothere.ply", "<ref id=\"mat-itu_concrete\" name=\"bsdf\"/>")));
  expect_input_error([&] { read_mitsuba((dir / "scene.xml").string()); },
                     {"mesh-Ghost", (dir / "meshes" / "nothere.ply").string()});
}

TEST(MitsubaIo, BrokenPlyNamesShapeAndPath) {
  const fs::path dir = temp_dir("broken_ply");
  write_quad_ply(dir / "meshes" / "q.ply");
  std::string bytes = read_text(dir / "meshes" / "q.ply");
  write_text(dir / "meshes" / "cut.ply", bytes.substr(0, bytes.size() - 7));
  write_text(dir / "scene.xml",
             scene_xml(kConcreteBsdf,
                       ply_shape("mesh-Cut", "meshes/cut.ply", "<ref id=\"mat-itu_concrete\" name=\"bsdf\"/>")));
  expect_input_error([&] { read_mitsuba((dir / "scene.xml").string()); }, {"mesh-Cut", "cut.ply"});
}

TEST(MitsubaIo, UnsupportedShapesAndTransformsAreErrors) {
  const fs::path dir = temp_dir("unsupported");
  write_quad_ply(dir / "meshes" / "q.ply");
  const std::string ref = "<ref id=\"mat-itu_concrete\" name=\"bsdf\"/>";
  for (const std::string type : {"obj", "serialized", "rectangle"}) {
    write_text(dir / "scene.xml",
               scene_xml(kConcreteBsdf, "<shape type=\"" + type + "\" id=\"mesh-Odd\">" + ref + "</shape>\n"));
    expect_input_error([&] { read_mitsuba((dir / "scene.xml").string()); }, {"mesh-Odd", type});
  }
  write_text(dir / "scene.xml",
             scene_xml(kConcreteBsdf,
                       ply_shape("mesh-Look", "meshes/q.ply",
                                 ref + "<transform name=\"to_world\"><lookat origin=\"1,1,1\" target=\"0,0,0\"/>"
                                       "</transform>")));
  expect_input_error([&] { read_mitsuba((dir / "scene.xml").string()); }, {"mesh-Look", "lookat"});
}

TEST(MitsubaIo, ToWorldTransformsAreApplied) {
  const fs::path dir = temp_dir("transform");
  write_quad_ply(dir / "meshes" / "q.ply");
  const std::string ref = "<ref id=\"mat-itu_concrete\" name=\"bsdf\"/>";
  // Scale first, then translate (Mitsuba applies children in order).
  const std::string st = "<transform name=\"to_world\"><scale x=\"2\" y=\"3\"/>"
                         "<translate x=\"10\" y=\"20\" z=\"5\"/></transform>";
  // Row-major matrix: swap x and y (a mirror) and lift by 7.
  const std::string mirror = "<transform name=\"to_world\"><matrix value=\"0 1 0 0  1 0 0 0  0 0 1 7  0 0 0 1\"/>"
                             "</transform>";
  const std::string rot = "<transform name=\"to_world\"><rotate x=\"1\" angle=\"90\"/></transform>";
  write_text(dir / "scene.xml",
             scene_xml(kConcreteBsdf, ply_shape("mesh-A", "meshes/q.ply", ref + st) +
                                          ply_shape("mesh-B", "meshes/q.ply", ref + mirror) +
                                          ply_shape("mesh-C", "meshes/q.ply", ref + rot)));
  const Scene s = read_mitsuba((dir / "scene.xml").string());
  ASSERT_EQ(s.meshes.size(), 3u);
  const Vec3 a = s.meshes[0].vertices[2];  // (1, 1, 0)
  EXPECT_DOUBLE_EQ(a[0], 12.0);
  EXPECT_DOUBLE_EQ(a[1], 23.0);
  EXPECT_DOUBLE_EQ(a[2], 5.0);
  EXPECT_NEAR(triangle_normal(s.meshes[0], 0)[2], 1.0, 1e-12);
  const Vec3 b = s.meshes[1].vertices[1];  // (1, 0, 0)
  EXPECT_DOUBLE_EQ(b[0], 0.0);
  EXPECT_DOUBLE_EQ(b[1], 1.0);
  EXPECT_DOUBLE_EQ(b[2], 7.0);
  // A mirror would turn the quad's normal to -z; the winding is flipped back.
  EXPECT_NEAR(triangle_normal(s.meshes[1], 0)[2], 1.0, 1e-12);
  const Vec3 c = s.meshes[2].vertices[2];  // (1, 1, 0) rotated about x by 90 deg
  EXPECT_NEAR(c[0], 1.0, 1e-12);
  EXPECT_NEAR(c[1], 0.0, 1e-12);
  EXPECT_NEAR(c[2], 1.0, 1e-12);
}

TEST(MitsubaIo, BsdfForms) {
  const fs::path dir = temp_dir("bsdf_forms");
  write_quad_ply(dir / "meshes" / "q.ply");
  const std::string twosided =
      "<bsdf type=\"twosided\" id=\"mat-itu_brick\"><bsdf type=\"principled\" name=\"bsdf\" id=\"inner-x\">"
      "<rgb value=\"0.8 0.8 0.8\" name=\"base_color\"/></bsdf></bsdf>\n";
  const std::string inline_bsdf = "<bsdf type=\"diffuse\" id=\"itu_wood\"><rgb value=\"1 0 0\" name=\"reflectance\"/></bsdf>";
  const std::string inline_no_id = "<bsdf type=\"diffuse\"/>";
  write_text(dir / "scene.xml",
             scene_xml(kConcreteBsdf + twosided,
                       ply_shape("mesh-Twosided", "meshes/q.ply", "<ref id=\"mat-itu_brick\" name=\"bsdf\"/>") +
                           ply_shape("mesh-Inline", "meshes/q.ply", inline_bsdf) +
                           // Mitsuba allows a nameless ref.
                           ply_shape("mesh-Nameless", "meshes/q.ply", "<ref id=\"mat-itu_concrete\"/>")));
  const Scene s = read_mitsuba((dir / "scene.xml").string());
  ASSERT_EQ(s.meshes.size(), 3u);
  EXPECT_EQ(s.meshes[0].material, "brick");
  EXPECT_EQ(s.meshes[1].material, "wood");
  EXPECT_EQ(s.meshes[2].material, "concrete");
  EXPECT_EQ(s.meshes[1].name, "Inline");
  // The inner bsdf of a twosided wrapper is not a material of its own.
  write_text(dir / "scene.xml",
             scene_xml(twosided, ply_shape("mesh-Inner", "meshes/q.ply", "<ref id=\"inner-x\" name=\"bsdf\"/>")));
  expect_input_error([&] { read_mitsuba((dir / "scene.xml").string()); }, {"mesh-Inner", "inner-x"});
  write_text(dir / "scene.xml", scene_xml("", ply_shape("mesh-Anon", "meshes/q.ply", inline_no_id)));
  expect_input_error([&] { read_mitsuba((dir / "scene.xml").string()); }, {"mesh-Anon", "no id"});
}

TEST(MitsubaPly, AsciiPolygonsWithExtraPropertiesAreFanned) {
  const fs::path dir = temp_dir("ply_ascii");
  write_text(dir / "poly.ply",
             "ply\nformat ascii 1.0\ncomment made by hand\n"
             "element vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
             "property float nx\nproperty float s\nproperty float t\nproperty uchar red\n"
             "element face 2\nproperty list uchar int vertex_indices\nproperty uchar flags\n"
             "end_header\n"
             "0 0 0 0 0.1 0.2 255\n2 0 0 0 0.1 0.2 255\n2 2 0 0 0.1 0.2 255\n0 2 0 0 0.1 0.2 255\n"
             "1 3 0 0 0.1 0.2 255\n-1 1 0 0 0.1 0.2 255\n"
             "4 0 1 2 3 7\n"
             "5 0 1 2 4 5 9\n");
  const PlyMesh m = read_ply((dir / "poly.ply").string());
  ASSERT_EQ(m.vertices.size(), 6u);
  EXPECT_EQ(m.vertices[4], (Vec3{1, 3, 0}));
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}, {0, 1, 2}, {0, 2, 4}, {0, 4, 5}}));
  EXPECT_EQ(m.triangle_polygon, (std::vector<std::uint32_t>{0, 0, 1, 1, 1}));

  // Duplicated (non-manifold) faces are kept as they are.
  write_text(dir / "dup.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
             "element face 3\nproperty list uchar uint vertex_indices\nend_header\n"
             "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n3 0 2 1\n");
  EXPECT_EQ(read_ply((dir / "dup.ply").string()).triangles.size(), 3u);
}

// Every proper prefix of a PLY file is an InputError naming the file, on
// both PLY paths (read_ply and a Mitsuba scene's shapes): CGAL's reader used
// to read an uninitialised list length when a binary file ended just before a
// face. For ascii, any cut before the last token's start drops a needed token.
TEST(MitsubaPly, EveryTruncationIsAnInputError) {
  const fs::path dir = temp_dir("ply_cuts");
  write_ply((dir / "q.ply").string(), {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {{0, 1, 2}, {0, 2, 3}});
  const std::string binary = read_text(dir / "q.ply");
  const std::string ascii =
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n";
  ASSERT_EQ(read_ply((dir / "q.ply").string()).triangles.size(), 2u);
  write_text(dir / "a.ply", ascii);
  ASSERT_EQ(read_ply((dir / "a.ply").string()).triangles.size(), 2u);
  const std::string cut = (dir / "cut.ply").string();
  int cases = 0;
  for (std::size_t n = 0; n < binary.size(); ++n, ++cases) {
    write_text(cut, binary.substr(0, n));
    expect_input_error([&] { read_ply(cut); }, {cut});
  }
  const std::size_t last_token = ascii.find_last_not_of("\n ") ;  // the final "3"
  for (std::size_t n = 0; n <= last_token; ++n, ++cases) {
    write_text(cut, ascii.substr(0, n));
    expect_input_error([&] { read_ply(cut); }, {cut});
  }
  EXPECT_GT(cases, 150);
  // Cut just before the second face's list length: the case CGAL read uninitialised.
  write_text(dir / "meshes" / "cut.ply", binary.substr(0, binary.size() - 13));
  write_text(dir / "scene.xml",
             scene_xml(kConcreteBsdf,
                       ply_shape("mesh-Cut", "meshes/cut.ply", "<ref id=\"mat-itu_concrete\" name=\"bsdf\"/>")));
  expect_input_error([&] { read_mitsuba((dir / "scene.xml").string()); }, {"mesh-Cut", "cut.ply", "face 1", "truncated"});
}

// Corrupt counts that no truncation produces: a negative signed list length,
// a length that does not fit its type, a float length type, and an element
// with a huge count but no properties (the readers would loop over it).
TEST(MitsubaPly, CorruptCountsAreInputErrors) {
  const fs::path dir = temp_dir("ply_counts");
  const std::string head = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                           "property float y\nproperty float z\nelement face 1\n";
  std::string verts(36, '\0');
  auto bad = [&](const std::string& name, const std::string& content, const std::string& needle) {
    write_text(dir / name, content);
    expect_input_error([&] { read_ply((dir / name).string()); }, {(dir / name).string(), needle});
  };
  bad("negative.ply", head + "property list char int vertex_indices\nend_header\n" + verts + "\xff" + std::string(12, '\0'),
      "face 0: negative list length");
  bad("float_count.ply", head + "property list float int vertex_indices\nend_header\n" + verts, "not an integer");
  bad("empty_element.ply",
      "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
      "element junk 99999999999999\nend_header\n",
      "element junk");
  bad("overflow.ply",
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n259 0 1 2\n",
      "face 0: list length 259 does not fit");
  bad("minus.ply",
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n",
      "face 0: unreadable list length");
}

TEST(MitsubaPly, BinaryRoundTripAndErrors) {
  const fs::path dir = temp_dir("ply_errors");
  const std::vector<Vec3> v = {{0.1, 0.2, 0.3}, {1e3, -2e3, 5.5}, {7, 8, 9}, {-1, -2, -3}};
  const std::vector<Tri> t = {{0, 1, 2}, {2, 1, 3}};
  write_ply((dir / "ok.ply").string(), v, t);
  const PlyMesh m = read_ply((dir / "ok.ply").string());
  EXPECT_EQ(m.triangles, t);
  ASSERT_EQ(m.vertices.size(), v.size());
  for (std::size_t i = 0; i < v.size(); ++i)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(m.vertices[i][k], static_cast<double>(static_cast<float>(v[i][k])));

  const std::string bytes = read_text(dir / "ok.ply");
  auto expect_bad = [&](const std::string& name, const std::string& content, const std::string& needle) {
    write_text(dir / name, content);
    expect_input_error([&] { read_ply((dir / name).string()); }, {(dir / name).string(), needle});
  };
  expect_bad("truncated.ply", bytes.substr(0, bytes.size() - 5), "truncated");
  expect_bad("header_cut.ply", bytes.substr(0, bytes.find("end_header")), "end_header");
  expect_bad("not_ply.ply", "solid cube\nfacet normal 0 0 1\n", "not a PLY");
  expect_bad("int_coords.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\nproperty int x\nproperty int y\nproperty int z\n"
             "end_header\n1 2 3\n",
             "x, y and z");
  expect_bad("range.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
             "out of range");
  expect_bad("negative.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n",
             "out of range");
  expect_bad("line.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n",
             "corners");
  expect_input_error([&] { read_ply((dir / "absent.ply").string()); }, {"absent.ply", "cannot open"});
}

// ---------------------------------------------------------------- VaN3Twin

namespace {

struct XmlShape {
  std::string id;
  std::string filename;
};

std::string strip_comments(const std::string& xml) {
  std::string out;
  std::size_t pos = 0;
  for (;;) {
    const auto open = xml.find("<!--", pos);
    if (open == std::string::npos) break;
    out.append(xml, pos, open - pos);
    const auto close = xml.find("-->", open + 4);
    if (close == std::string::npos) return out;
    pos = close + 3;
  }
  out.append(xml, pos, std::string::npos);
  return out;
}

std::string attribute(const std::string& tag, const std::string& key) {
  const auto p = tag.find(" " + key + "=\"");
  if (p == std::string::npos) return "";
  const auto start = p + key.size() + 3;
  return tag.substr(start, tag.find('"', start) - start);
}

// Independent of the expat-based reader: plain text search.
std::vector<XmlShape> shapes_in(const std::string& xml_text) {
  const std::string xml = strip_comments(xml_text);
  std::vector<XmlShape> shapes;
  for (auto p = xml.find("<shape"); p != std::string::npos; p = xml.find("<shape", p + 1)) {
    const char next = xml[p + 6];
    if (next != ' ' && next != '\t' && next != '\n' && next != '>') continue;
    const auto body_end = xml.find("</shape>", p);
    const std::string body = xml.substr(p, body_end - p);
    XmlShape s;
    s.id = attribute(body.substr(0, body.find('>')), "id");
    const auto f = body.find("name=\"filename\"");
    if (f != std::string::npos) {
      const auto tag_start = body.rfind('<', f);
      s.filename = attribute(body.substr(tag_start, body.find('>', f) - tag_start), "value");
    }
    shapes.push_back(s);
  }
  return shapes;
}

long ply_header_faces(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("element face ", 0) == 0) return std::stol(line.substr(13));
    if (line.rfind("end_header", 0) == 0) break;
  }
  return -1;
}

}  // namespace

TEST(MitsubaIo, ImportsEveryVaN3TwinScene) {
  const fs::path scenarios =
      fs::path(RAYSWEEP_SHARED_DATA) / "van3twin" / "DriveX-devs_VaN3Twin" / "src" / "sionna" / "scenarios";
  if (!fs::is_directory(scenarios)) GTEST_SKIP() << "no VaN3Twin data at " << scenarios;
  std::vector<fs::path> xmls;
  for (const auto& dir : fs::directory_iterator(scenarios))
    if (dir.is_directory())
      for (const auto& f : fs::directory_iterator(dir.path()))
        if (f.path().extension() == ".xml") xmls.push_back(f.path());
  std::sort(xmls.begin(), xmls.end());
  ASSERT_FALSE(xmls.empty());

  std::size_t total_shapes = 0;
  for (const fs::path& xml : xmls) {
    SCOPED_TRACE(xml.string());
    const auto expected = shapes_in(read_text(xml));
    ASSERT_FALSE(expected.empty());
    total_shapes += expected.size();
    Scene s;
    ASSERT_NO_THROW(s = read_mitsuba(xml.string()));
    ASSERT_EQ(s.meshes.size(), expected.size());
    ASSERT_EQ(s.objects.size(), expected.size());
    std::uint32_t faces_before = 0;
    for (std::size_t i = 0; i < expected.size(); ++i) {
      const Mesh& m = s.meshes[i];
      SCOPED_TRACE(expected[i].id);
      EXPECT_EQ("mesh-" + m.name, expected[i].id);
      EXPECT_EQ(s.objects[i].source_id, expected[i].id);
      EXPECT_TRUE(m.material == "brick" || m.material == "metal" || m.material == "concrete") << m.material;
      const long faces = ply_header_faces(xml.parent_path() / expected[i].filename);
      ASSERT_GT(faces, 0);
      EXPECT_EQ(static_cast<long>(m.triangles.size()), faces);
      EXPECT_EQ(m.triangle_object, std::vector<std::uint32_t>(m.triangles.size(), static_cast<std::uint32_t>(i)));
      ASSERT_EQ(m.triangle_face.size(), m.triangles.size());
      // Face ids continue across meshes, never shared between them.
      for (auto f : m.triangle_face) EXPECT_GE(f, faces_before);
      for (auto f : m.triangle_face) faces_before = std::max(faces_before, f + 1);
      for (const Tri& t : m.triangles)
        for (auto v : t) ASSERT_LT(v, m.vertices.size());
    }
    // Real buildings are boxes and prisms: far fewer planar faces than triangles.
    EXPECT_LT(faces_before, s.triangle_count());
    RecordProperty(xml.filename().string() + "_triangles", std::to_string(s.triangle_count()));
    RecordProperty(xml.filename().string() + "_faces", std::to_string(faces_before));
  }
  EXPECT_EQ(total_shapes, 112u + 102u + 42u);
}

TEST(MitsubaIo, VaN3TwinSceneRoundTrips) {
  const fs::path xml = fs::path(RAYSWEEP_SHARED_DATA) / "van3twin" / "DriveX-devs_VaN3Twin" / "src" / "sionna" /
                       "scenarios" / "SionnaCircleScenario" / "scene.xml";
  if (!fs::exists(xml)) GTEST_SKIP() << "no VaN3Twin data at " << xml;
  const Scene original = read_mitsuba(xml.string());
  const fs::path dir = temp_dir("van3twin_roundtrip");
  write_mitsuba(original, dir.string());
  const Scene back = read_mitsuba((dir / "scene.xml").string());
  ASSERT_EQ(back.meshes.size(), original.meshes.size());
  for (std::size_t i = 0; i < original.meshes.size(); ++i) {
    SCOPED_TRACE(original.meshes[i].name);
    EXPECT_EQ(back.meshes[i].name, original.meshes[i].name);
    EXPECT_EQ(back.meshes[i].material, original.meshes[i].material);
    EXPECT_EQ(back.meshes[i].triangles, original.meshes[i].triangles);
    EXPECT_EQ(back.meshes[i].vertices, original.meshes[i].vertices);  // already float-exact
    EXPECT_EQ(back.meshes[i].triangle_face, original.meshes[i].triangle_face);
    EXPECT_EQ(back.objects[i].source_id, original.objects[i].source_id);
  }
}
