// A scene folder's decoded scene.glb kept in its cache/ (pipeline/scene_cache.hpp):
// the same scene as parsing the glb, every time; a damaged or foreign entry is
// rebuilt, never read; a changed glb gets its own entry and the old one goes.
#include <gtest/gtest.h>

#include <fstream>

#include "meshkit/gltf_io.hpp"
#include "pipeline/scene_cache.hpp"
#include "scene_fixtures.hpp"
#include "test_util.hpp"
#include "tracer/precompute.hpp"

using namespace raysweep;
using namespace raysweep::test;

namespace {

meshkit::Scene two_buildings(double height) {
  meshkit::Scene s;
  std::uint32_t face = 0;
  const auto a = s.add_object("building", "way/1");
  const auto b = s.add_object("building", "way/2");
  auto& concrete = s.mesh_for("concrete", "buildings");
  add_box(concrete, {6600.25, 8100.5, 0}, {6620.75, 8110.125, height}, a, face);
  add_box(concrete, {6630.5, 8100.5, 0}, {6641.0, 8120.0, 9.5}, b, face);
  auto& glass = s.mesh_for("glass", "windows");
  add_box(glass, {6600.0, 8090.0, 1}, {6601.0, 8091.0, 2}, b, face);
  return s;
}

// Bit for bit: positions (in their order), ids, names.
void expect_identical(const meshkit::Scene& a, const meshkit::Scene& b) {
  expect_same_scene(a, b, std::vector<double>(a.meshes.size(), 0.0));
  for (std::size_t i = 0; i < std::min(a.meshes.size(), b.meshes.size()); ++i) {
    EXPECT_EQ(a.meshes[i].vertices, b.meshes[i].vertices);
    EXPECT_EQ(a.meshes[i].triangles, b.meshes[i].triangles);
  }
}

std::vector<fs::path> entries(const fs::path& dir) {
  std::vector<fs::path> out;
  if (fs::exists(dir / "cache"))
    for (const auto& e : fs::directory_iterator(dir / "cache"))
      if (e.path().filename().string().rfind("scene-", 0) == 0) out.push_back(e.path());
  return out;
}

}  // namespace

TEST(SceneCache, GivesWhatParsingTheGlbGivesAndKeepsOneEntry) {
  const auto dir = scratch_dir("scene_cache_hit");
  meshkit::write_glb(two_buildings(12.0), (dir / "scene.glb").string());
  const meshkit::Scene parsed = meshkit::read_glb((dir / "scene.glb").string());
  expect_identical(pipeline::read_scene_glb(dir), parsed);  // builds the entry
  ASSERT_EQ(entries(dir).size(), 1u);
  expect_identical(pipeline::read_scene_glb(dir), parsed);  // reads it

  // A changed building: a new entry with the new geometry; the old one is gone.
  meshkit::write_glb(two_buildings(15.0), (dir / "scene.glb").string());
  const meshkit::Scene changed = meshkit::read_glb((dir / "scene.glb").string());
  expect_identical(pipeline::read_scene_glb(dir), changed);
  EXPECT_EQ(entries(dir).size(), 1u);
  expect_identical(pipeline::read_scene_glb(dir), changed);
}

TEST(SceneCache, ADamagedEntryIsRebuiltNotRead) {
  const auto dir = scratch_dir("scene_cache_damaged");
  meshkit::write_glb(two_buildings(12.0), (dir / "scene.glb").string());
  const meshkit::Scene parsed = meshkit::read_glb((dir / "scene.glb").string());
  pipeline::read_scene_glb(dir);
  const fs::path entry = entries(dir).at(0);
  const auto full = fs::file_size(entry);
  fs::resize_file(entry, full / 2);  // truncated
  expect_identical(pipeline::read_scene_glb(dir), parsed);
  EXPECT_EQ(fs::file_size(entry), full);  // stored again, whole
  {
    // The same length, one vertex coordinate's byte changed: the checksum catches it.
    std::fstream f(entry, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(full - 40));
    f.put('\x7f');
  }
  expect_identical(pipeline::read_scene_glb(dir), parsed);
}

TEST(SceneCache, DecodeRefusesWordsThatAreNotAConsistentScene) {
  const auto words = pipeline::encode_scene(two_buildings(12.0));
  std::string why;
  ASSERT_TRUE(pipeline::decode_scene(words, why)) << why;
  for (std::size_t cut : {std::size_t{0}, std::size_t{1}, words.size() / 2, words.size() - 1}) {
    const std::vector<std::uint32_t> part(words.begin(), words.begin() + static_cast<std::ptrdiff_t>(cut));
    EXPECT_FALSE(pipeline::decode_scene(part, why)) << cut;
  }
  auto longer = words;
  longer.push_back(0);
  EXPECT_FALSE(pipeline::decode_scene(longer, why));
  // A triangle pointing past its mesh's 8 vertices: the last vertex index of
  // the last mesh (the glass box, 12 triangles) comes before its two
  // per-triangle id lists of 1 + 12 words each.
  auto bad = words;
  bad[bad.size() - 1 - 2 * 13] = 1000;
  EXPECT_FALSE(pipeline::decode_scene(bad, why));
  EXPECT_NE(why.find("vertex index out of range"), std::string::npos) << why;
  // A count that claims more than the words hold.
  auto huge = words;
  huge[1] = 0xffffffffu;
  EXPECT_FALSE(pipeline::decode_scene(huge, why));
}
