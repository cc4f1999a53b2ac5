// Precomputed vehicle-model tables kept between processes (tracer/precompute.hpp):
// a scene that loads them traces exactly what one that builds them traces; a
// changed model or a damaged table is rebuilt, never read. (The file store:
// tests/pipeline/test_precompute_store.cpp.)
#include <gtest/gtest.h>

#include <cstring>
#include <map>

#include "tracer_fixtures.hpp"
#include "vehicle_fixtures.hpp"

using namespace raysweep;
using namespace raysweep::test;

namespace {

// A store in memory that counts what the tracer asks of it.
class MemoryStore : public tracer::PrecomputeStore {
 public:
  std::optional<std::string> load(const std::string& key) const override {
    ++loads;
    auto it = tables.find(key);
    if (it == tables.end()) return std::nullopt;
    return it->second;
  }
  void save(const std::string& key, const std::string& bytes) const override {
    ++saves;
    tables[key] = bytes;
  }
  void rejected(const std::string& key, const std::string& why) const override { rejections[key] = why; }
  mutable std::map<std::string, std::string> tables, rejections;
  mutable int loads = 0, saves = 0;
};

meshkit::Scene street() {
  meshkit::Scene s;
  add_ground(s, 60);
  add_wall_x(s, 12, 60, "concrete", "wall_a");
  add_wall_x(s, -12, 60, "brick", "wall_b");
  return s;
}

struct Traced {
  std::unique_ptr<tracer::TraceScene> scene;
  tracer::Snapshot snap;
};

// Four vehicles of two models among the walls, every mechanism of the default config.
Traced trace_street(std::shared_ptr<const tracer::PrecomputeStore> store, double truck_scale = 1.0) {
  Traced t;
  t.scene = std::make_unique<tracer::TraceScene>(street());
  if (store) t.scene->set_precompute_store(store);
  const auto car = add_library_model(*t.scene, "passenger");
  meshkit::VehicleLibrary lib;
  auto truck_model = lib.model("truck");
  meshkit::Scene truck = meshkit::to_scene(truck_model);
  for (auto& mesh : truck.meshes)
    for (auto& v : mesh.vertices) v[2] *= truck_scale;
  const auto tr = t.scene->add_vehicle_model("truck", truck, truck_model.antenna);
  t.scene->set_vehicles({{"a", car, {-20, -4, 0}, 0, {10, 0, 0}},
                         {"b", tr, {0, 4, 0}, tracer::kPi, {-8, 0, 0}},
                         {"c", car, {15, -4, 0}, 0, {12, 0, 0}},
                         {"d", tr, {30, 4, 0}, tracer::kPi, {-9, 0, 0}}});
  t.snap = tracer::trace_snapshot(*t.scene, tracer::vehicle_nodes(*t.scene), tracer::TracerConfig{}, {});
  return t;
}

// Every path of every pair, bit for bit.
void expect_same_paths(const tracer::Snapshot& a, const tracer::Snapshot& b) {
  ASSERT_EQ(a.pairs.size(), b.pairs.size());
  std::size_t paths = 0;
  for (std::size_t p = 0; p < a.pairs.size(); ++p) {
    ASSERT_EQ(a.pairs[p].paths.size(), b.pairs[p].paths.size()) << "pair " << p;
    for (std::size_t k = 0; k < a.pairs[p].paths.size(); ++k, ++paths) {
      const auto &x = a.pairs[p].paths[k], &y = b.pairs[p].paths[k];
      EXPECT_EQ(std::memcmp(&x.a, &y.a, sizeof x.a), 0);
      EXPECT_EQ(std::memcmp(&x.tau_s, &y.tau_s, sizeof x.tau_s), 0);
      EXPECT_EQ(x.interactions.size(), y.interactions.size());
    }
  }
  EXPECT_GT(paths, 20u);
}

// The tables themselves: each vehicle's mount list and its bounce sequences
// for arrival directions all over the sphere at every spread level.
void expect_same_tables(const tracer::TraceScene& a, const tracer::TraceScene& b) {
  ASSERT_EQ(a.vehicles().size(), b.vehicles().size());
  std::size_t ids = 0;
  for (std::size_t v = 0; v < a.vehicles().size(); ++v) {
    const auto* ma = a.faces_seen_from_mount(v, a.vehicle_antenna(v));
    const auto* mb = b.faces_seen_from_mount(v, b.vehicle_antenna(v));
    ASSERT_TRUE(ma && mb);
    EXPECT_EQ(*ma, *mb);
    EXPECT_FALSE(ma->empty());
    for (const auto& dir : tracer::fibonacci_sphere(200))
      for (double spread : {0.0, 0.3, 0.6, 1.0}) {
        const auto qa = a.vehicle_bounce_sequences(v, dir, spread), qb = b.vehicle_bounce_sequences(v, dir, spread);
        ASSERT_EQ(*qa.ids, *qb.ids);
        ids += qa.ids->size();
        ASSERT_EQ(qa.table->size(), qb.table->size());
        for (std::size_t k = 0; k < qa.table->size(); ++k) {
          const auto &x = (*qa.table)[k], &y = (*qb.table)[k];
          ASSERT_TRUE(x.faces == y.faces && x.order == y.order && x.front == y.front) << k;
        }
      }
  }
  EXPECT_GT(ids, 1000u);
}

}  // namespace

TEST(Precompute, ContentKeysFollowTheBytes) {
  const std::vector<double> v{1, 2, 3};
  auto w = v;
  w[1] = std::nextafter(2.0, 3.0);
  const auto k = tracer::ContentKey().add_vector(v).hex();
  EXPECT_EQ(k.size(), 32u);
  EXPECT_EQ(k, tracer::ContentKey().add_vector(v).hex());
  EXPECT_NE(k, tracer::ContentKey().add_vector(w).hex());
  // Lengths count: "ab" + "c" is not "a" + "bc".
  EXPECT_NE(tracer::ContentKey().add("ab").add("c").hex(), tracer::ContentKey().add("a").add("bc").hex());
}

TEST(Precompute, FramedTablesRoundTripAndDamageIsNamed) {
  const std::vector<std::uint32_t> words{7, 0, 4294967295u, 12};
  const std::string bytes = tracer::frame_table(words);
  std::string why;
  ASSERT_EQ(tracer::unframe_table(bytes, why), words);
  EXPECT_FALSE(tracer::unframe_table(bytes.substr(0, bytes.size() - 1), why));
  EXPECT_NE(why.find("truncated"), std::string::npos) << why;
  std::string flipped = bytes;
  flipped[flipped.size() - 3] ^= 0x10;
  EXPECT_FALSE(tracer::unframe_table(flipped, why));
  EXPECT_NE(why.find("checksum"), std::string::npos) << why;
  EXPECT_FALSE(tracer::unframe_table("RSPX" + bytes.substr(4), why));
  EXPECT_FALSE(tracer::unframe_table("", why));
}

TEST(Precompute, LoadedTablesTraceExactlyWhatBuiltOnesTrace) {
  const Traced plain = trace_street(nullptr);
  auto store = std::make_shared<MemoryStore>();
  const Traced first = trace_street(store);
  // Each model's mount list and bounce table, stored once.
  EXPECT_EQ(store->tables.size(), 4u);
  EXPECT_EQ(store->saves, 4);
  expect_same_paths(plain.snap, first.snap);
  const Traced second = trace_street(store);
  EXPECT_EQ(store->saves, 4);  // all four loaded, none rebuilt
  EXPECT_TRUE(store->rejections.empty());
  expect_same_paths(plain.snap, second.snap);
  expect_same_tables(*plain.scene, *second.scene);
}

TEST(Precompute, AChangedModelGetsItsOwnTables) {
  auto store = std::make_shared<MemoryStore>();
  trace_street(store);
  const Traced taller = trace_street(store, 1.2);
  EXPECT_EQ(store->saves, 6);  // the truck's two tables again; the car's loaded
  EXPECT_EQ(store->tables.size(), 6u);
  expect_same_paths(trace_street(nullptr, 1.2).snap, taller.snap);
}

TEST(Precompute, DamagedTablesAreRebuiltNotRead) {
  const Traced plain = trace_street(nullptr);
  auto store = std::make_shared<MemoryStore>();
  trace_street(store);
  int k = 0;
  for (auto& [key, bytes] : store->tables) {
    if (k == 0) bytes.resize(bytes.size() / 2);  // truncated
    if (k == 1) bytes[bytes.size() - 1] ^= 1;     // one bit
    if (k == 2) {
      // Well framed, but naming a face the model does not have.
      std::string why;
      auto words = *tracer::unframe_table(bytes, why);
      for (auto& w : words) w = 4000000000u;
      bytes = tracer::frame_table(words);
    }
    ++k;
  }
  const Traced again = trace_street(store);
  EXPECT_EQ(store->rejections.size(), 3u);
  EXPECT_EQ(store->saves, 4 + 3);
  expect_same_paths(plain.snap, again.snap);
  expect_same_tables(*plain.scene, *again.scene);
}
