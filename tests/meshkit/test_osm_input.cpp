// OSM reading and each kind of bad input: repaired, skipped with the OSM id
// named, or a clear error. Never a crash or a silently wrong building.
#include <gtest/gtest.h>

#include <algorithm>

#include "meshkit/city.hpp"
#include "meshkit/errors.hpp"
#include "meshkit/osm_buildings.hpp"
#include "test_util.hpp"

using namespace raysweep::meshkit;
using raysweep::test::scratch_dir;
using raysweep::test::write_text;

namespace {

// Planar "projection": 1 degree = 100000 m, enough for hand-checked areas.
Vec2 flat(double lon, double lat) { return {lon * 1e5, lat * 1e5}; }

std::string node(long id, double lon, double lat) {
  return "  <node id=\"" + std::to_string(id) + "\" lat=\"" + std::to_string(lat) + "\" lon=\"" +
         std::to_string(lon) + "\" version=\"1\"/>\n";
}
std::string way(long id, std::vector<long> nodes, std::string tags) {
  std::string s = "  <way id=\"" + std::to_string(id) + "\" version=\"1\">\n";
  for (long n : nodes) s += "    <nd ref=\"" + std::to_string(n) + "\"/>\n";
  return s + tags + "  </way>\n";
}
std::string tag(const std::string& k, const std::string& v) { return "    <tag k=\"" + k + "\" v=\"" + v + "\"/>\n"; }

// A 10 m x 10 m square of nodes base..base+3 at (x0, y0) (in 1e-5 degree units).
std::string square_nodes(long base, double x0, double y0) {
  return node(base, x0 * 1e-5, y0 * 1e-5) + node(base + 1, (x0 + 10) * 1e-5, y0 * 1e-5) +
         node(base + 2, (x0 + 10) * 1e-5, (y0 + 10) * 1e-5) + node(base + 3, x0 * 1e-5, (y0 + 10) * 1e-5);
}

std::string osm(const std::string& body) {
  return "<?xml version='1.0' encoding='UTF-8'?>\n<osm version=\"0.6\" generator=\"test\">\n" + body + "</osm>\n";
}

bool skipped_as(const OsmBuildings& b, const std::string& id, const std::string& reason) {
  return std::any_of(b.skipped.begin(), b.skipped.end(),
                     [&](const OsmSkip& s) { return s.source_id == id && s.reason == reason; });
}

}  // namespace

TEST(OsmInput, ClosedWayBecomesBuildingWithTags) {
  auto dir = scratch_dir("osm");
  write_text(dir / "a.osm", osm(square_nodes(1, 0, 0) + way(10, {1, 2, 3, 4, 1}, tag("building", "yes") +
                                                                     tag("height", "12 m") +
                                                                     tag("building:material", "brick"))));
  auto b = read_osm_buildings((dir / "a.osm").string(), flat);
  ASSERT_EQ(b.buildings.size(), 1u);
  EXPECT_EQ(b.buildings[0].source_id, "way/10");
  EXPECT_EQ(b.buildings[0].height, "12 m");
  EXPECT_EQ(b.buildings[0].material, "brick");
  ASSERT_EQ(b.buildings[0].outers.size(), 1u);
  EXPECT_EQ(b.buildings[0].outers[0].size(), 5u);
  EXPECT_NEAR(b.buildings[0].outers[0][2][0], 10, 1e-6);
}

TEST(OsmInput, MalformedXmlNamesFileAndLine) {
  auto dir = scratch_dir("osm");
  write_text(dir / "bad.osm", "<?xml version='1.0'?>\n<osm version=\"0.6\">\n  <node id=\"1\" lat=\"1\" lon=\"2\">\n</osm>\n");
  try {
    read_osm_buildings((dir / "bad.osm").string(), flat);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("bad.osm"), std::string::npos) << what;
    EXPECT_NE(what.find("line 4"), std::string::npos) << what;
  }
}

TEST(OsmInput, MissingFileIsAnError) {
  EXPECT_THROW(read_osm_buildings("/nonexistent/x.osm", flat), InputError);
}

TEST(OsmInput, WayWithMissingNodesIsSkippedAndNamed) {
  auto dir = scratch_dir("osm");
  // Node 4 lies outside the extract (clipped at the bbox).
  write_text(dir / "a.osm", osm(node(1, 0, 0) + node(2, 1e-4, 0) + node(3, 1e-4, 1e-4) +
                                way(20, {1, 2, 3, 4, 1}, tag("building", "house"))));
  auto b = read_osm_buildings((dir / "a.osm").string(), flat);
  EXPECT_TRUE(b.buildings.empty());
  EXPECT_TRUE(skipped_as(b, "way/20", "missing_nodes"));
}

TEST(OsmInput, OneNodeAndOpenWaysAreSkipped) {
  auto dir = scratch_dir("osm");
  write_text(dir / "a.osm", osm(square_nodes(1, 0, 0) + way(30, {1}, tag("building", "yes")) +
                                way(31, {1, 2, 3}, tag("building", "yes"))));
  auto b = read_osm_buildings((dir / "a.osm").string(), flat);
  EXPECT_TRUE(b.buildings.empty());
  EXPECT_TRUE(skipped_as(b, "way/30", "too_few_nodes"));
  EXPECT_TRUE(skipped_as(b, "way/31", "open_way"));
}

TEST(OsmInput, ZeroAreaBuildingIsSkippedByTheCityBuilder) {
  auto dir = scratch_dir("osm");
  write_text(dir / "a.osm", osm(node(1, 0, 0) + node(2, 1e-4, 0) + node(3, 2e-4, 0) +
                                way(40, {1, 2, 3, 1}, tag("building", "yes"))));
  auto b = read_osm_buildings((dir / "a.osm").string(), flat);
  CityOptions opt;
  auto city = build_city(b, {}, opt);
  EXPECT_TRUE(city.report.kept.empty());
  ASSERT_TRUE(city.report.skipped.count("zero_area"));
  EXPECT_EQ(city.report.skipped.at("zero_area").at(0), "way/40");
  bool warned = false;
  for (const auto& w : city.report.warnings) warned |= w.find("way/40") != std::string::npos;
  EXPECT_TRUE(warned);
}

TEST(OsmInput, MultipolygonWithHoleFromSplitWays) {
  auto dir = scratch_dir("osm");
  // Outer ring split into two ways, inner ring closed; 30 m square with a 10 m hole.
  std::string body = node(1, 0, 0) + node(2, 30e-5, 0) + node(3, 30e-5, 30e-5) + node(4, 0, 30e-5) +
                     node(5, 10e-5, 10e-5) + node(6, 20e-5, 10e-5) + node(7, 20e-5, 20e-5) + node(8, 10e-5, 20e-5) +
                     way(50, {1, 2, 3}, "") + way(51, {3, 4, 1}, tag("building", "yes")) +
                     way(52, {5, 6, 7, 8, 5}, "") +
                     "  <relation id=\"60\" version=\"1\">\n"
                     "    <member type=\"way\" ref=\"50\" role=\"outer\"/>\n"
                     "    <member type=\"way\" ref=\"51\" role=\"outer\"/>\n"
                     "    <member type=\"way\" ref=\"52\" role=\"inner\"/>\n" +
                     tag("type", "multipolygon") + tag("building", "yes") + tag("building:levels", "4") +
                     "  </relation>\n";
  write_text(dir / "a.osm", osm(body));
  auto b = read_osm_buildings((dir / "a.osm").string(), flat);
  ASSERT_EQ(b.buildings.size(), 1u);
  EXPECT_EQ(b.buildings[0].source_id, "relation/60");
  EXPECT_EQ(b.buildings[0].inners.size(), 1u);
  auto city = build_city(b, {}, CityOptions{});
  ASSERT_EQ(city.report.kept.size(), 1u);
  EXPECT_NEAR(city.report.kept[0].area_m2, 800, 1e-3);
  EXPECT_EQ(city.report.kept[0].height_source, "levels");
  EXPECT_NEAR(signed_volume(city.scene.mesh_for("concrete", "buildings"), 0), 800 * 12, 0.1);
}

TEST(OsmInput, RelationWithAbsentMembersIsSkipped) {
  auto dir = scratch_dir("osm");
  std::string body = square_nodes(1, 0, 0) +
                     "  <relation id=\"70\" version=\"1\">\n"
                     "    <member type=\"way\" ref=\"999\" role=\"outer\"/>\n" +
                     tag("type", "multipolygon") + tag("building", "yes") + "  </relation>\n";
  write_text(dir / "a.osm", osm(body));
  auto b = read_osm_buildings((dir / "a.osm").string(), flat);
  EXPECT_TRUE(b.buildings.empty());
  EXPECT_TRUE(skipped_as(b, "relation/70", "relation_members_missing"));
}

TEST(OsmInput, UnparsableHeightFallsBackAndWarnsWithId) {
  auto dir = scratch_dir("osm");
  write_text(dir / "a.osm", osm(square_nodes(1, 0, 0) + way(80, {1, 2, 3, 4, 1},
                                                             tag("building", "yes") + tag("height", "tall-ish") +
                                                             tag("building:material", "cardboard"))));
  auto b = read_osm_buildings((dir / "a.osm").string(), flat);
  CityOptions opt;
  opt.heights.default_height_m = 7.5;
  auto city = build_city(b, {}, opt);
  ASSERT_EQ(city.report.kept.size(), 1u);
  EXPECT_EQ(city.report.kept[0].height_source, "default");
  EXPECT_DOUBLE_EQ(city.report.kept[0].top_m, 7.5);
  EXPECT_EQ(city.report.kept[0].material, "concrete");
  int named = 0;
  for (const auto& w : city.report.warnings)
    named += w.find("way/80") != std::string::npos && (w.find("tall-ish") != std::string::npos ||
                                                        w.find("cardboard") != std::string::npos);
  EXPECT_EQ(named, 2) << "one warning for the height, one for the material";
}

TEST(OsmInput, OutlineYieldsToItsParts) {
  auto dir = scratch_dir("osm");
  std::string body = square_nodes(1, 0, 0) + square_nodes(11, 2, 2) +
                     way(90, {1, 2, 3, 4, 1}, tag("building", "yes")) +
                     way(91, {11, 12, 13, 14, 11}, tag("building:part", "yes") + tag("height", "30"));
  // The part is smaller than the outline (scaled 0.5 around its corner).
  body = square_nodes(1, 0, 0) + node(11, 2e-5, 2e-5) + node(12, 6e-5, 2e-5) + node(13, 6e-5, 6e-5) +
         node(14, 2e-5, 6e-5) + way(90, {1, 2, 3, 4, 1}, tag("building", "yes")) +
         way(91, {11, 12, 13, 14, 11}, tag("building:part", "yes") + tag("height", "30"));
  write_text(dir / "a.osm", osm(body));
  auto b = read_osm_buildings((dir / "a.osm").string(), flat);
  auto city = build_city(b, {}, CityOptions{});
  ASSERT_EQ(city.report.kept.size(), 1u);
  EXPECT_EQ(city.report.kept[0].id, "way/91");
  EXPECT_TRUE(city.report.kept[0].part);
  EXPECT_EQ(city.report.skipped.at("replaced_by_parts").at(0), "way/90");
}

TEST(OsmInput, ClipToNetworkDistance) {
  auto dir = scratch_dir("osm");
  // Two buildings: one 20 m from the lane, one 500 m away.
  write_text(dir / "a.osm", osm(square_nodes(1, 0, 20) + square_nodes(11, 0, 500) +
                                way(100, {1, 2, 3, 4, 1}, tag("building", "yes")) +
                                way(101, {11, 12, 13, 14, 11}, tag("building", "yes"))));
  auto b = read_osm_buildings((dir / "a.osm").string(), flat);
  std::vector<std::vector<Vec2>> lanes = {{{-100, 0}, {100, 0}}};
  CityOptions opt;
  opt.clip_distance_m = 100;
  auto city = build_city(b, lanes, opt);
  ASSERT_EQ(city.report.kept.size(), 1u);
  EXPECT_EQ(city.report.kept[0].id, "way/100");
  EXPECT_EQ(city.report.skipped.at("outside_area_of_interest").at(0), "way/101");
  opt.clip_distance_m = 0;  // disabled
  EXPECT_EQ(build_city(b, lanes, opt).report.kept.size(), 2u);
}

TEST(OsmInput, CompressedExtractsReadLikePlainOnes) {
  const auto demo = raysweep::test::source_dir() / "datasets/demo/kirchberg.osm";
  auto dir = scratch_dir("osm");
  ASSERT_EQ(raysweep::test::run_command("gzip -c " + demo.string() + " > " + (dir / "k.osm.gz").string()).exit_code, 0);
  ASSERT_EQ(raysweep::test::run_command("bzip2 -c " + demo.string() + " > " + (dir / "k.osm.bz2").string()).exit_code, 0);
  auto plain = read_osm_buildings(demo.string(), flat);
  for (const char* name : {"k.osm.gz", "k.osm.bz2"}) {
    auto c = read_osm_buildings((dir / name).string(), flat);
    ASSERT_EQ(c.buildings.size(), plain.buildings.size()) << name;
    for (std::size_t i = 0; i < c.buildings.size(); ++i) {
      EXPECT_EQ(c.buildings[i].source_id, plain.buildings[i].source_id);
      EXPECT_EQ(c.buildings[i].outers, plain.buildings[i].outers);
    }
    EXPECT_EQ(c.skipped.size(), plain.skipped.size());
  }
}

TEST(OsmInput, TruncatedCompressedExtractIsAnError) {
  const auto demo = raysweep::test::source_dir() / "datasets/demo/kirchberg.osm";
  auto dir = scratch_dir("osm");
  ASSERT_EQ(raysweep::test::run_command("gzip -c " + demo.string() + " | head -c 3000 > " +
                                        (dir / "t.osm.gz").string()).exit_code, 0);
  EXPECT_THROW(read_osm_buildings((dir / "t.osm.gz").string(), flat), InputError);
}
