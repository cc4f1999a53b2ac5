#include <gtest/gtest.h>

#include "meshkit/materials.hpp"
#include "meshkit/osm_tags.hpp"

using namespace raysweep::meshkit;

TEST(HeightParsing, MetresInAllSpellings) {
  EXPECT_DOUBLE_EQ(*parse_osm_length("12"), 12.0);
  EXPECT_DOUBLE_EQ(*parse_osm_length("12.5"), 12.5);
  EXPECT_DOUBLE_EQ(*parse_osm_length(" 12 m "), 12.0);
  EXPECT_DOUBLE_EQ(*parse_osm_length("12m"), 12.0);
  EXPECT_DOUBLE_EQ(*parse_osm_length("12,5"), 12.5);
  EXPECT_DOUBLE_EQ(*parse_osm_length("350 cm"), 3.5);
}

TEST(HeightParsing, FeetAndInches) {
  EXPECT_NEAR(*parse_osm_length("40'"), 12.192, 1e-9);
  EXPECT_NEAR(*parse_osm_length("40 ft"), 12.192, 1e-9);
  EXPECT_NEAR(*parse_osm_length("12'6\""), 12 * 0.3048 + 6 * 0.0254, 1e-9);
}

TEST(HeightParsing, RejectsGarbage) {
  EXPECT_FALSE(parse_osm_length(""));
  EXPECT_FALSE(parse_osm_length("tall"));
  EXPECT_FALSE(parse_osm_length("12 storeys"));
  EXPECT_FALSE(parse_osm_length("-3"));
  EXPECT_FALSE(parse_osm_length("12'6"));  // inches without the closing mark
}

TEST(LevelParsing, NumbersAndLists) {
  EXPECT_DOUBLE_EQ(*parse_osm_levels("3"), 3.0);
  EXPECT_DOUBLE_EQ(*parse_osm_levels(" 2.5 "), 2.5);
  EXPECT_DOUBLE_EQ(*parse_osm_levels("3;4"), 3.0);
  EXPECT_FALSE(parse_osm_levels("three"));
  EXPECT_FALSE(parse_osm_levels("3 levels"));
}

TEST(ResolveHeight, PriorityHeightThenLevelsThenDefault) {
  HeightRules rules;  // 3 m per level, 9 m default
  BuildingTags t;
  t.height = "15";
  t.levels = "2";
  auto r = resolve_height(t, rules);
  EXPECT_EQ(r.source, HeightSource::Height);
  EXPECT_DOUBLE_EQ(r.top_m, 15);

  t.height = nullptr;
  t.roof_levels = "1";
  r = resolve_height(t, rules);
  EXPECT_EQ(r.source, HeightSource::Levels);
  EXPECT_DOUBLE_EQ(r.top_m, 9);  // (2 + 1) x 3 m

  r = resolve_height(BuildingTags{}, rules);
  EXPECT_EQ(r.source, HeightSource::Default);
  EXPECT_DOUBLE_EQ(r.top_m, 9);
  EXPECT_TRUE(r.warning.empty());
}

TEST(ResolveHeight, UnparsableHeightFallsBackWithWarning) {
  BuildingTags t;
  t.height = "very tall";
  t.levels = "4";
  auto r = resolve_height(t, HeightRules{});
  EXPECT_EQ(r.source, HeightSource::Levels);
  EXPECT_DOUBLE_EQ(r.top_m, 12);
  EXPECT_NE(r.warning.find("very tall"), std::string::npos);

  t.height = "1e9";  // implausible: beyond max_height_m
  t.levels = nullptr;
  r = resolve_height(t, HeightRules{});
  EXPECT_EQ(r.source, HeightSource::Default);
  EXPECT_FALSE(r.warning.empty());
}

TEST(ResolveHeight, PartsFloatAboveMinHeight) {
  BuildingTags t;
  t.height = "20";
  t.min_height = "12";
  auto r = resolve_height(t, HeightRules{});
  EXPECT_DOUBLE_EQ(r.base_m, 12);
  EXPECT_DOUBLE_EQ(r.top_m, 20);

  BuildingTags u;
  u.levels = "5";
  u.min_level = "2";
  r = resolve_height(u, HeightRules{});
  EXPECT_DOUBLE_EQ(r.base_m, 6);
  EXPECT_DOUBLE_EQ(r.top_m, 15);

  // A height below min_height is contradictory: it falls back and warns.
  BuildingTags v;
  v.height = "5";
  v.min_height = "10";
  r = resolve_height(v, HeightRules{});
  EXPECT_GT(r.top_m, r.base_m);
  EXPECT_FALSE(r.warning.empty());
}

TEST(MaterialMapping, OsmValuesToP2040) {
  EXPECT_EQ(*itu_material_from_osm("brick"), "brick");
  EXPECT_EQ(*itu_material_from_osm("Concrete"), "concrete");
  EXPECT_EQ(*itu_material_from_osm("glass"), "glass");
  EXPECT_EQ(*itu_material_from_osm("timber_framing"), "wood");
  EXPECT_EQ(*itu_material_from_osm("steel"), "metal");
  EXPECT_EQ(*itu_material_from_osm("plaster"), "plasterboard");
  EXPECT_EQ(*itu_material_from_osm("stone"), "concrete");
  EXPECT_EQ(*itu_material_from_osm("brick;concrete"), "brick");
  EXPECT_FALSE(itu_material_from_osm("cardboard"));
  EXPECT_FALSE(itu_material_from_osm(""));
}

TEST(MaterialMapping, MitsubaIds) {
  EXPECT_EQ(*itu_material_from_id("mat-itu_concrete"), "concrete");
  EXPECT_EQ(*itu_material_from_id("itu_medium_dry_ground"), "medium_dry_ground");
  EXPECT_EQ(*itu_material_from_id("metal"), "metal");
  EXPECT_FALSE(itu_material_from_id("mat-vacuum"));
  EXPECT_FALSE(itu_material_from_id("mat-itu_unobtainium"));
}
