// Tracer behaviour on scenes with vehicles: LoS classes, instanced vehicles
// moving between frames, reciprocity, determinism across thread counts,
// Doppler, the slab cap, and channel helpers on traced paths.
#include <gtest/gtest.h>

#include <map>
#include <tbb/global_control.h>

#include <cmath>

#include "meshkit/vehicle_model.hpp"
#include "meshkit/vehicle_library.hpp"
#include "tracer_fixtures.hpp"
#include "vehicle_fixtures.hpp"

using namespace raysweep;
using namespace raysweep::test;
using tracer::operator+;
using tracer::operator-;
using tracer::operator*;

namespace {

constexpr double kC = 299792458.0;

// Ground + one building block south of the road, and a car / bus library.
struct Street {
  tracer::TraceScene scene;
  std::uint32_t car, bus;
  static meshkit::Scene geometry() {
    meshkit::Scene s;
    add_ground(s, 400);
    add_box_object(s, {-40, -30, 0}, {40, -12, 15}, "concrete", "way/1");
    return s;
  }
  Street() : scene(geometry()), car(add_library_model(scene, "passenger")), bus(add_library_model(scene, "bus")) {}
  // Vehicles along the x axis heading east (yaw 0), front bumper at x.
  tracer::VehiclePose at(const std::string& id, std::uint32_t model, double x, double y, double speed = 0) {
    return tracer::VehiclePose{id, model, {x, y, 0}, 0, {speed, 0, 0}};
  }
};

// The exact (geometrical-optics and UTD) paths: diffuse power is a Monte
// Carlo estimate from one end's rays, reciprocal only in expectation, so the
// bitwise invariants here leave it out (test_diffuse covers it).
tracer::TracerConfig config() {
  tracer::TracerConfig c;
  c.rays_per_source = 4096;
  c.diffuse = false;
  return c;
}

std::size_t object_index(const tracer::TraceScene& scene, const std::string& name) {
  const auto names = scene.object_names();
  return std::find(names.begin(), names.end(), name) - names.begin();
}

}  // namespace

TEST(TracerScene, VehicleBlockingGivesNlosvAndBuildingGivesNlos) {
  Street st;
  // Two cars 40 m apart, a bus between them: blocked by a vehicle only.
  st.scene.set_vehicles({st.at("a", st.car, 0, 0), st.at("bus", st.bus, 26, 0), st.at("b", st.car, 40, 0)});
  auto nodes = tracer::vehicle_nodes(st.scene);
  auto snap = tracer::trace_snapshot(st.scene, nodes, config(), {});
  const auto& ab = snap.pairs[1];  // (a, b)
  ASSERT_EQ(nodes[ab.tx].id, "a");
  ASSERT_EQ(nodes[ab.rx].id, "b");
  EXPECT_EQ(ab.los_class, tracer::LosClass::NLOSV);
  ASSERT_EQ(ab.blockers.size(), 1u);
  EXPECT_EQ(ab.blockers[0], object_index(st.scene, "vehicle/bus"));
  EXPECT_FALSE(ab.paths.empty());  // reflections (ground is shadowed, the building is not)

  // Moving the bus aside (a new frame: instance transforms only) clears it.
  st.scene.set_vehicles({st.at("a", st.car, 0, 0), st.at("bus", st.bus, 26, 8), st.at("b", st.car, 40, 0)});
  nodes = tracer::vehicle_nodes(st.scene);
  snap = tracer::trace_snapshot(st.scene, nodes, config(), {});
  EXPECT_EQ(snap.pairs[1].los_class, tracer::LosClass::LOS);
  EXPECT_TRUE(snap.pairs[1].blockers.empty());
  ASSERT_FALSE(snap.pairs[1].paths.empty());
  EXPECT_TRUE(snap.pairs[1].paths[0].interactions.empty());  // the direct path arrives first
  EXPECT_NEAR(snap.pairs[1].paths[0].tau_s, tracer::norm(nodes[2].position - nodes[0].position) / kC, 1e-15);

  // A node behind the building: static geometry blocks it.
  nodes.push_back(node("rsu", {0, -40, 5}));
  snap = tracer::trace_snapshot(st.scene, nodes, config(), {});
  const auto& a_rsu = snap.pairs[2];  // (a, rsu)
  EXPECT_EQ(nodes[a_rsu.rx].id, "rsu");
  EXPECT_EQ(a_rsu.los_class, tracer::LosClass::NLOS);
  EXPECT_TRUE(std::count(a_rsu.blockers.begin(), a_rsu.blockers.end(), object_index(st.scene, "way/1")));
}

TEST(TracerScene, ReciprocityWhicheverEndTransmits) {
  Street st;
  st.scene.set_vehicles({st.at("a", st.car, 0, 2, 13.9), st.at("bus", st.bus, 20, -5, 8), st.at("b", st.car, 45, 1.5, -10)});
  auto nodes = tracer::vehicle_nodes(st.scene);
  nodes.push_back(node("rsu", {25, 8, 6}));
  tracer::RadioConfig radio;
  radio.antenna.pattern = tracer::AntennaPattern::halfwave_dipole;
  const auto fwd = tracer::trace_snapshot(st.scene, nodes, config(), radio);
  std::vector<tracer::Node> reversed(nodes.rbegin(), nodes.rend());
  const auto rev = tracer::trace_snapshot(st.scene, reversed, config(), radio);
  const std::size_t n = nodes.size();
  std::size_t compared = 0;
  for (const auto& p : fwd.pairs) {
    // The same unordered pair in the reversed list: indices n-1-rx < n-1-tx.
    const auto& q = *std::find_if(rev.pairs.begin(), rev.pairs.end(), [&](const tracer::PairResult& r) {
      return r.tx == n - 1 - p.rx && r.rx == n - 1 - p.tx;
    });
    EXPECT_EQ(p.los_class, q.los_class);
    ASSERT_EQ(p.paths.size(), q.paths.size()) << nodes[p.tx].id << "-" << nodes[p.rx].id;
    for (std::size_t i = 0; i < p.paths.size(); ++i) {
      const auto &x = p.paths[i], &y = q.paths[i];
      EXPECT_NEAR(x.tau_s, y.tau_s, 1e-15);
      EXPECT_LT(std::abs(x.a - y.a), 1e-9 * std::abs(x.a) + 1e-300);
      EXPECT_NEAR(x.doppler_hz, y.doppler_hz, 1e-9);
      EXPECT_NEAR(x.theta_t, y.theta_r, 1e-9);
      EXPECT_NEAR(x.theta_r, y.theta_t, 1e-9);
      ++compared;
    }
  }
  EXPECT_GT(compared, 10u);
}

TEST(TracerScene, IdenticalResultsForAnyThreadCount) {
  Street st;
  st.scene.set_vehicles({st.at("a", st.car, 0, 2, 10), st.at("bus", st.bus, 20, -5, 8), st.at("b", st.car, 45, 1.5),
                         st.at("c", st.car, -30, -3), st.at("d", st.bus, 70, 4)});
  const auto nodes = tracer::vehicle_nodes(st.scene);
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    return tracer::trace_snapshot(st.scene, nodes, config(), {});
  };
  const auto one = run(1), many = run(8);
  ASSERT_EQ(one.pairs.size(), many.pairs.size());
  EXPECT_EQ(one.stats.paths, many.stats.paths);
  EXPECT_EQ(one.stats.candidates, many.stats.candidates);
  for (std::size_t i = 0; i < one.pairs.size(); ++i) {
    ASSERT_EQ(one.pairs[i].paths.size(), many.pairs[i].paths.size());
    for (std::size_t k = 0; k < one.pairs[i].paths.size(); ++k) {
      EXPECT_EQ(one.pairs[i].paths[k].a, many.pairs[i].paths[k].a);  // bitwise
      EXPECT_EQ(one.pairs[i].paths[k].tau_s, many.pairs[i].paths[k].tau_s);
    }
  }
}

TEST(TracerScene, DopplerOfDirectAndGroundPaths) {
  meshkit::Scene s;
  add_ground(s, 2000);
  tracer::TraceScene scene(s);
  const double lambda = kC / 5.9e9, h = 1.5;
  for (double d : {20.0, 200.0}) {
    // tx drives towards rx at 20 m/s, rx drives away at 5 m/s.
    const auto snap = tracer::trace_snapshot(
        scene, {node("tx", {0, 0, h}, {20, 0, 0}), node("rx", {d, 0, h}, {5, 0, 0})}, config(), {});
    const auto& p = snap.pairs[0];
    ASSERT_EQ(p.paths.size(), 2u);
    EXPECT_NEAR(p.paths[0].doppler_hz, (20.0 - 5.0) / lambda, 1e-9);
    // Ground path: L = sqrt(x^2 + (2h)^2), dL/dt = (x/L) (v_rx - v_tx).
    const double L = std::hypot(d, 2 * h);
    EXPECT_NEAR(p.paths[1].doppler_hz, -(d / L) * (5.0 - 20.0) / lambda, 1e-6);
  }
}

TEST(TracerScene, MovingReflectorShiftsDoppler) {
  // Two static nodes in front of a bus driving past along the wall normal:
  // the reflected path shortens at 2 v cos(theta).
  meshkit::Scene s;
  tracer::TraceScene scene(s);
  meshkit::VehicleLibrary lib;
  const auto& b = lib.model("bus");
  const auto bus = scene.add_vehicle_model("bus", meshkit::to_scene(b), b.antenna);
  // Bus heading +x with its front face at x = 10 (front bumper), driving
  // towards the nodes at -x: yaw = pi, front at x = 10 facing -x.
  const double v = 10;
  scene.set_vehicles({tracer::VehiclePose{"bus", bus, {10, 0, 0}, M_PI, {-v, 0, 0}}});
  auto cfg = config();
  cfg.max_depth = 1;
  cfg.refraction = false;
  const auto snap = tracer::trace_snapshot(scene, {node("a", {0, -2, 1.5}), node("b", {0, 2, 1.5})}, cfg, {});
  const tracer::Path* front = nullptr;
  for (const auto& p : snap.pairs[0].paths)
    if (p.interactions.size() == 1 && std::fabs(p.interactions[0].point[0] - 10) < 0.05) front = &p;
  ASSERT_NE(front, nullptr) << "no reflection off the bus front";
  const double cos_inc = 10 / std::hypot(10.0, 2.0);
  EXPECT_NEAR(front->doppler_hz, 2 * v * cos_inc / (kC / 5.9e9), 1.0);
}

TEST(TracerScene, SlabCapIsReportedNotSilent) {
  meshkit::Scene s;
  for (int i = 0; i < 4; ++i) add_wall_x(s, 2.0 + i, 100, "glass", "pane" + std::to_string(i));
  tracer::TraceScene scene(s);
  auto cfg = config();
  cfg.max_transmissions = 3;
  auto snap = tracer::trace_snapshot(scene, {node("a", {0, 0, 0}), node("b", {10, 0, 0})}, cfg, {});
  EXPECT_TRUE(snap.pairs[0].paths.empty());
  // The direct path through four panes and the paths bouncing between panes
  // (reflection points on their panes, more than three crossings): the
  // exhaustive search counts every one; the image search at least the
  // direct path (its slab bounds skip reflections whose legs already cross
  // too many panes: never proposed, so not counted).
  auto exhaustive = cfg;
  exhaustive.candidates = tracer::CandidateSearch::exhaustive;
  const auto ref = tracer::trace_snapshot(scene, {node("a", {0, 0, 0}), node("b", {10, 0, 0})}, exhaustive, {});
  EXPECT_GE(snap.pairs[0].dropped_transmission_cap, 1u);
  EXPECT_LE(snap.pairs[0].dropped_transmission_cap, ref.pairs[0].dropped_transmission_cap);
  EXPECT_EQ(ref.pairs[0].dropped_transmission_cap, 7u);
  EXPECT_EQ(snap.stats.dropped_transmission_cap, snap.pairs[0].dropped_transmission_cap);
  cfg.max_transmissions = 4;
  snap = tracer::trace_snapshot(scene, {node("a", {0, 0, 0}), node("b", {10, 0, 0})}, cfg, {});
  // The direct path through all four panes; the others bounce between panes.
  std::size_t direct = 0;
  for (const auto& p : snap.pairs[0].paths) {
    const bool through = std::all_of(p.interactions.begin(), p.interactions.end(), [](const tracer::Interaction& i) {
      return i.type == tracer::InteractionType::refraction;
    });
    if (through) {
      ++direct;
      EXPECT_EQ(p.interactions.size(), 4u);
    }
  }
  EXPECT_EQ(direct, 1u);
}

TEST(TracerScene, MechanismsSwitchOff) {
  Street st;
  st.scene.set_vehicles({st.at("a", st.car, 0, 0), st.at("b", st.car, 40, 0)});
  const auto nodes = tracer::vehicle_nodes(st.scene);
  auto cfg = config();
  cfg.specular = false;
  cfg.diffraction = false;
  auto snap = tracer::trace_snapshot(st.scene, nodes, cfg, {});
  ASSERT_EQ(snap.pairs[0].paths.size(), 1u);
  EXPECT_TRUE(snap.pairs[0].paths[0].interactions.empty());
  cfg.specular = true;
  cfg.los = false;
  snap = tracer::trace_snapshot(st.scene, nodes, cfg, {});
  for (const auto& p : snap.pairs[0].paths) EXPECT_FALSE(p.interactions.empty());
}

TEST(TracerScene, FrequencyResponseOfTracedPathsAtTheCarrierIsTheCoherentSum) {
  Street st;
  st.scene.set_vehicles({st.at("a", st.car, 0, 0), st.at("b", st.car, 60, 3)});
  const auto snap = tracer::trace_snapshot(st.scene, tracer::vehicle_nodes(st.scene), config(), {});
  const auto& p = snap.pairs[0];
  ASSERT_GE(p.paths.size(), 2u);
  const auto h = tracer::frequency_response(p.paths, tracer::ofdm_80211p());
  EXPECT_NEAR(std::norm(h[32]), p.stats.gain_coherent, 1e-9 * p.stats.gain_coherent);
  const auto nr = tracer::frequency_response(p.paths, tracer::ofdm_nr(2, 10));
  EXPECT_EQ(nr.size(), 120u);
}

TEST(TracerScene, InvalidInputsAreClearErrors) {
  meshkit::Scene s;
  add_ground(s, 100);
  tracer::TraceScene scene(s);
  auto bad = node("x", {0, 0, std::nan("")});
  EXPECT_THROW(tracer::trace_snapshot(scene, {node("a", {0, 0, 1}), bad}, config(), {}), std::invalid_argument);
  tracer::RadioConfig radio;
  radio.frequency_hz = 30e9;  // outside the ground's P.2040 validity (1-10 GHz)
  try {
    tracer::trace_snapshot(scene, {node("a", {0, 0, 1}), node("b", {5, 0, 1})}, config(), radio);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("medium_dry_ground"), std::string::npos) << e.what();
  }
  auto cfg = config();
  cfg.max_depth = 17;
  EXPECT_THROW(tracer::trace_snapshot(scene, {node("a", {0, 0, 1}), node("b", {5, 0, 1})}, cfg, {}),
               std::invalid_argument);
}

TEST(TracerScene, RaysThroughSharedEdgesAndVerticesCrossOnce) {
  // A closed box around the origin: a ray from inside aimed exactly at an
  // edge or a corner (shared by two or three faces, split into triangles
  // along diagonals) must cross the surface once: no leak, no double count.
  meshkit::Scene s;
  add_box_object(s, {-3, -2, -1}, {3, 2, 1}, "glass", "box");
  tracer::TraceScene scene(s);
  std::vector<tracer::Vec3> targets;
  for (int i = 0; i < 8; ++i) targets.push_back({i & 1 ? 3.0 : -3.0, i & 2 ? 2.0 : -2.0, i & 4 ? 1.0 : -1.0});
  for (double t = -0.95; t <= 0.95; t += 0.1) {
    targets.push_back({3 * t, 2, 1});
    targets.push_back({3, 2 * t, -1});
    targets.push_back({-3, -2, t});
    targets.push_back({3 * t, -2 * t, 1});  // face diagonals (triangle seams)
    targets.push_back({3, 2 * t, t});
  }
  std::vector<tracer::Hit> hits;
  for (const auto& target : targets) {
    for (const tracer::Vec3 origin : {tracer::Vec3{0, 0, 0}, tracer::Vec3{0.3, -0.2, 0.1}}) {
      const auto dir = tracer::normalize(target - origin);
      ASSERT_TRUE(scene.all_hits(origin, dir, 0, 100, hits, 16));
      EXPECT_EQ(hits.size(), 1u) << "towards " << target[0] << "," << target[1] << "," << target[2];
      if (!hits.empty()) {
        EXPECT_NEAR(hits[0].t, tracer::norm(target - origin), 1e-4);
      }
    }
  }
}

TEST(TracerScene, GroundIsTheLowestLargeFlatLevelNotALargeFlatRoof) {
  // Ground at z = 0 and a raised plaza at 1.5 m (both within the ground's
  // band), a 120 x 80 m block with a flat roof at 12 m, a 10 m kiosk.
  meshkit::Scene s;
  add_ground(s, 200);
  add_ground(s, 40, "concrete", 300, 0, 1.5);
  add_box_object(s, {-60, -40, 0}, {60, 40, 12}, "concrete", "way/1");
  add_box_object(s, {100, 100, 0}, {110, 110, 8}, "concrete", "way/2");
  const tracer::TraceScene scene(s);
  std::map<long, bool> ground_at;  // height in cm of each upward-facing horizontal face -> is_ground
  for (std::uint32_t f = 0; f < scene.face_count(0); ++f) {
    const tracer::Plane p = scene.plane({0, f});
    if (p.normal[2] > 0.999) ground_at[std::lround(100 * p.offset / p.normal[2])] = scene.is_ground(f);
  }
  EXPECT_TRUE(ground_at.at(0));
  EXPECT_TRUE(ground_at.at(150));
  EXPECT_FALSE(ground_at.at(1200));  // large and flat, but a roof
  EXPECT_FALSE(ground_at.at(800));   // small
}

// An antenna inside a building's closed volume (a lane through its
// footprint) is named; one beside it, above it, under a roof with no walls,
// on the roof, or under a vehicle is not. Points on the box's vertical edge
// and corner line (rays through edges) count as inside once, not twice.
TEST(TracerScene, EnclosingObjectIsTheBuildingAnAntennaStandsIn) {
  meshkit::Scene s;
  add_ground(s, 200);
  add_box_object(s, {-10, -10, 0}, {10, 10, 12}, "concrete", "way/7");
  add_box_object(s, {30, -10, 0}, {50, 10, 8}, "concrete", "way/8");
  // A free-standing roof (a carport): one face, no walls.
  add_quad(s, "metal", "way/9", {-60, -5, 4}, {-40, -5, 4}, {-40, 5, 4}, {-60, 5, 4});
  tracer::TraceScene scene(s);
  const auto way7 = static_cast<std::int64_t>(object_index(scene, "way/7"));
  const auto way8 = static_cast<std::int64_t>(object_index(scene, "way/8"));
  EXPECT_EQ(scene.enclosing_object({0, 0, 1.5}), way7);
  EXPECT_EQ(scene.enclosing_object({3.3, -7.1, 11.9}), way7);
  EXPECT_EQ(scene.enclosing_object({0, 0, 6}), way7);     // under the roof's diagonal (two triangles)
  EXPECT_EQ(scene.enclosing_object({40, 0, 1.5}), way8);
  EXPECT_EQ(scene.enclosing_object({15, 0, 1.5}), -1);    // in the street between
  EXPECT_EQ(scene.enclosing_object({0, 0, 13}), -1);      // above the roof
  EXPECT_EQ(scene.enclosing_object({-50, 0, 1.5}), -1);   // under the carport
  EXPECT_EQ(scene.enclosing_object({-50, 0, 5}), -1);     // on the carport
  EXPECT_EQ(scene.enclosing_object({0, 0, -1}), -1);      // below the ground
  Street street;
  street.scene.set_vehicles({street.at("v", street.bus, 10, 0)});
  EXPECT_EQ(street.scene.enclosing_object(street.scene.vehicle_antenna(0)), -1);
  EXPECT_EQ(street.scene.enclosing_object({5, 0, 1.0}), -1);  // inside the bus's body: not a building
}
