// The sweep engine: the VaN3Twin update rule, the per-pair and global path
// caches against tracing every pair afresh, block restarts, trace_pairs
// against trace_snapshot, and determinism across thread counts.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <map>

#include "generators/sweep/sweep.hpp"
#include "meshkit/vehicle_model.hpp"
#include "tracer_fixtures.hpp"
#include "vehicle_fixtures.hpp"

using namespace raysweep;
using namespace raysweep::test;
using generators::CacheMode;
using generators::FrameRecord;
using generators::SweepVehicle;

namespace {

// A street canyon (ground, a building each side) with a car and a bus model.
struct Canyon {
  tracer::TraceScene scene;
  std::uint32_t car, bus;
  static meshkit::Scene geometry() {
    meshkit::Scene s;
    add_ground(s, 400);
    add_box_object(s, {-80, -30, 0}, {80, -10, 15}, "concrete", "way/1");
    add_box_object(s, {-80, 10, 0}, {80, 30, 12}, "brick", "way/2");
    return s;
  }
  Canyon() : scene(geometry()), car(add_library_model(scene, "passenger")), bus(add_library_model(scene, "bus")) {}
};

SweepVehicle vehicle(std::uint32_t node, std::uint32_t model, double x, double y, double speed_east,
                     double length = 5) {
  SweepVehicle v;
  v.node = node;
  v.model = model;
  v.position = {x, y, 0};
  v.heading_deg = 90;  // east
  v.velocity = {speed_east, 0, 0};
  v.length_m = length;
  v.width_m = 2.5;
  v.height_m = 3.4;
  return v;
}

tracer::TracerConfig tracer_config() {
  tracer::TracerConfig c;
  c.rays_per_source = 2048;
  return c;
}

// Frame f of a small scenario: two parked cars, one car driving east at
// 10 m/s (1 m per frame) 60 m away from them, one bus west of them that
// stops for frames 6..11.
std::vector<SweepVehicle> scenario(const Canyon& c, int f) {
  std::vector<SweepVehicle> v;
  v.push_back(vehicle(0, c.car, -20, -3, 0));
  v.push_back(vehicle(1, c.car, 0, 3, 0));
  v.push_back(vehicle(2, c.car, 60 + f, -3, 10));
  const double bus_x = f < 6 ? -70 + 2 * f : f < 12 ? -60 : -60 + 2 * (f - 11);
  v.push_back(vehicle(3, c.bus, bus_x, 3, f >= 6 && f < 12 ? 0 : 20, 12));
  return v;
}

bool same_path(const generators::PathRecord& a, const generators::PathRecord& b) {
  return a.a == b.a && a.tau_s == b.tau_s && a.theta_t == b.theta_t && a.phi_t == b.phi_t &&
         a.doppler_hz == b.doppler_hz && a.interaction_count == b.interaction_count;
}

// The paths of each link of a frame.
std::vector<std::vector<generators::PathRecord>> link_paths(const FrameRecord& f) {
  std::vector<std::vector<generators::PathRecord>> out;
  std::size_t p = 0;
  for (const auto& l : f.links) {
    out.emplace_back(f.paths.begin() + p, f.paths.begin() + p + l.path_count);
    p += l.path_count;
  }
  return out;
}

}  // namespace

TEST(TracePairs, SubsetEqualsFullSnapshot) {
  Canyon c;
  std::vector<tracer::VehiclePose> poses;
  for (const auto& v : scenario(c, 3))
    poses.push_back({std::to_string(v.node), v.model, v.position, 0.0, v.velocity});
  c.scene.set_vehicles(poses);
  auto nodes = tracer::vehicle_nodes(c.scene);
  nodes.push_back(node("rsu", {10, 8, 6}));
  const auto full = tracer::trace_snapshot(c.scene, nodes, tracer_config(), {});
  const std::vector<std::pair<std::uint32_t, std::uint32_t>> some = {{3, 4}, {0, 2}, {1, 4}};
  const auto part = tracer::trace_pairs(c.scene, nodes, some, tracer_config(), {});
  ASSERT_EQ(part.pairs.size(), 3u);
  for (std::size_t k = 0; k < some.size(); ++k) {
    const auto& a = part.pairs[k];
    const auto& b = *std::find_if(full.pairs.begin(), full.pairs.end(),
                                  [&](const tracer::PairResult& r) { return r.tx == a.tx && r.rx == a.rx; });
    EXPECT_EQ(a.tx, some[k].first);
    ASSERT_EQ(a.paths.size(), b.paths.size());
    EXPECT_GT(a.paths.size(), 1u);
    for (std::size_t p = 0; p < a.paths.size(); ++p) {
      EXPECT_EQ(a.paths[p].a, b.paths[p].a);
      EXPECT_EQ(a.paths[p].tau_s, b.paths[p].tau_s);
    }
  }
  EXPECT_THROW(tracer::trace_pairs(c.scene, nodes, {{2, 1}}, tracer_config(), {}), std::invalid_argument);
  EXPECT_THROW(tracer::trace_pairs(c.scene, nodes, {{0, 1}, {0, 1}}, tracer_config(), {}), std::invalid_argument);
}

TEST(Sweep, UpdateRuleMovesAMeshOnlyPastTheThreshold) {
  // One car driving 0.5 m per frame, d0 = 2 m: its mesh moves when it is
  // more than 2 m from where it was last placed: at frames 5, 10, 15 (2.5 m).
  Canyon c;
  generators::SweepOptions opt;
  opt.lattice_frames = 1;  // one lattice (turned lattices: test_turned_lattices)
  opt.d0_m = 2.0;
  opt.block_frames = 1000;
  generators::Sweep sweep(c.scene, tracer_config(), {}, opt, {{0, {0, 8, 5}}});
  std::vector<int> updated_frames;
  for (int f = 0; f < 16; ++f) {
    const auto before = sweep.stats().vehicle_updates;
    auto rec = sweep.step(f, 0.1 * f, {vehicle(1, c.car, -30 + 0.5 * f, -3, 5)});
    if (sweep.stats().vehicle_updates > before) updated_frames.push_back(f);
    ASSERT_EQ(rec.links.size(), 1u);
    // The link is traced exactly when the mesh moved; otherwise it is reused.
    EXPECT_EQ((rec.links[0].flags & generators::kLinkCached) != 0,
              std::find(updated_frames.begin(), updated_frames.end(), f) == updated_frames.end())
        << "frame " << f;
    // The recorded node state is the true position, not the placed one.
    EXPECT_DOUBLE_EQ(rec.nodes[1].x, -30 + 0.5 * f);
  }
  EXPECT_EQ(updated_frames, (std::vector<int>{0, 5, 10, 15}));
  EXPECT_EQ(sweep.stats().updates_deferred, 12u);

  // v * Tc dominates: 5 m/s * 1 s = 5 m -> updates at frames 0 and 11 (5.5 m).
  opt.d0_m = 0.5;
  opt.coherence_time_s = 1.0;
  generators::Sweep slow(c.scene, tracer_config(), {}, opt, {{0, {0, 8, 5}}});
  for (int f = 0; f < 12; ++f) slow.step(f, 0.1 * f, {vehicle(1, c.car, -30 + 0.5 * f, -3, 5)});
  EXPECT_EQ(slow.stats().vehicle_updates, 2u);
}

TEST(Sweep, PerPairCacheKeepsExactlyThePathsFreshTracingFinds) {
  Canyon c;
  generators::SweepOptions cached_opt, fresh_opt;
  cached_opt.lattice_frames = fresh_opt.lattice_frames = 1;  // one lattice: compared with a fresh sweep's frame 0
  cached_opt.cache = CacheMode::per_pair;
  fresh_opt.cache = CacheMode::none;
  cached_opt.block_frames = fresh_opt.block_frames = 1000;
  const std::vector<generators::SweepRsu> rsus = {{4, {10, 8, 6}}};
  generators::Sweep cached(c.scene, tracer_config(), {}, cached_opt, rsus);
  std::size_t reused = 0, reused_with_new_paths = 0;
  for (int f = 0; f < 16; ++f) {
    const auto a = cached.step(f, 0.1 * f, scenario(c, f));
    // A fresh sweep traces every pair of this frame from scratch.
    generators::Sweep fresh(c.scene, tracer_config(), {}, fresh_opt, rsus);
    const auto b = fresh.step(0, 0.1 * f, scenario(c, f));
    ASSERT_EQ(a.links.size(), b.links.size());
    const auto pa = link_paths(a), pb = link_paths(b);
    for (std::size_t l = 0; l < a.links.size(); ++l) {
      const auto& la = a.links[l];
      const auto& lb = b.links[l];
      ASSERT_EQ(la.tx, lb.tx);
      ASSERT_EQ(la.rx, lb.rx);
      if (!(la.flags & generators::kLinkCached)) {
        // Traced in this frame: identical to fresh tracing.
        ASSERT_EQ(pa[l].size(), pb[l].size()) << "frame " << f << " link " << l;
        EXPECT_EQ(la.gain_coherent_db, lb.gain_coherent_db);
        continue;
      }
      ++reused;
      // Reused: same LoS class and blockers; every stored path is still
      // there, unchanged; fresh tracing may only add longer paths.
      EXPECT_EQ(la.los_class, lb.los_class) << "frame " << f << " link " << l;
      EXPECT_EQ(la.blocker_count, lb.blocker_count);
      for (const auto& p : pa[l]) {
        const bool found = std::any_of(pb[l].begin(), pb[l].end(), [&](const auto& q) { return same_path(p, q); });
        EXPECT_TRUE(found) << "frame " << f << " link " << la.tx << "-" << la.rx << ": cached path tau " << p.tau_s
                           << " gone";
      }
      if (pb[l].size() != pa[l].size()) {
        // Only new paths (via a vehicle outside the strong ellipsoid) can be
        // missing, and they are longer than the strongest stored path.
        ++reused_with_new_paths;
        double strongest = 0, strongest_tau = 0;
        for (const auto& p : pa[l])
          if (std::norm(p.a) > strongest) strongest = std::norm(p.a), strongest_tau = p.tau_s;
        for (const auto& q : pb[l]) {
          if (!std::any_of(pa[l].begin(), pa[l].end(), [&](const auto& p) { return same_path(p, q); })) {
            EXPECT_GT(q.tau_s, strongest_tau) << "a missed path is shorter than the strongest stored one";
          }
        }
      }
    }
  }
  // The parked pair and the RSU see hits while the bus is far away.
  EXPECT_GT(reused, 20u);
  EXPECT_GT(cached.stats().hit_ratio(), 0.1);
  RecordProperty("reused", static_cast<int>(reused));
  RecordProperty("reused_with_new_paths", static_cast<int>(reused_with_new_paths));
}

TEST(Sweep, GlobalCacheRetracesEverythingOnAnyMove) {
  Canyon c;
  generators::SweepOptions opt;
  opt.lattice_frames = 1;  // one lattice (turned lattices: test_turned_lattices)
  opt.cache = CacheMode::global;
  opt.block_frames = 1000;
  generators::Sweep sweep(c.scene, tracer_config(), {}, opt, {});
  auto parked = [&](double x3) {
    return std::vector<SweepVehicle>{vehicle(0, c.car, -20, -3, 0), vehicle(1, c.car, 0, 3, 0),
                                      vehicle(2, c.car, 20, -3, 0), vehicle(3, c.car, x3, 3, 0)};
  };
  auto count_cached = [](const FrameRecord& r) {
    return std::count_if(r.links.begin(), r.links.end(),
                         [](const auto& l) { return (l.flags & generators::kLinkCached) != 0; });
  };
  EXPECT_EQ(count_cached(sweep.step(0, 0, parked(150))), 0);
  EXPECT_EQ(count_cached(sweep.step(1, 0.1, parked(150))), 6);  // nothing moved: all reused
  EXPECT_EQ(count_cached(sweep.step(2, 0.2, parked(300))), 0);  // one far move: all retraced
  // Per-pair mode on the same move: only pairs near the mover are traced.
  opt.cache = CacheMode::per_pair;
  generators::Sweep per_pair(c.scene, tracer_config(), {}, opt, {});
  per_pair.step(0, 0, parked(150));
  const auto r = per_pair.step(1, 0.1, parked(300));
  EXPECT_GT(count_cached(r), 0);
  EXPECT_LT(count_cached(r), 6);
  // A vehicle that leaves invalidates like a move.
  const auto gone = per_pair.step(2, 0.2, {vehicle(0, c.car, -20, -3, 0), vehicle(1, c.car, 0, 3, 0)});
  ASSERT_EQ(gone.links.size(), 1u);
}

TEST(Sweep, EveryBlockStartsAfresh) {
  Canyon c;
  generators::SweepOptions opt;
  opt.lattice_frames = 1;  // one lattice (turned lattices: test_turned_lattices)
  opt.cache = CacheMode::per_pair;
  opt.d0_m = 100;  // nothing would ever move without the block restart
  opt.block_frames = 4;
  generators::Sweep sweep(c.scene, tracer_config(), {}, opt, {});
  for (int f = 0; f < 9; ++f) {
    const auto r = sweep.step(f, 0.1 * f, scenario(c, f));
    const bool all_traced = std::none_of(r.links.begin(), r.links.end(),
                                         [](const auto& l) { return (l.flags & generators::kLinkCached) != 0; });
    EXPECT_EQ(all_traced, f % 4 == 0) << "frame " << f;
  }
  // A sweep started at frame 4 (a resumed run) gives frame 4..7 exactly.
  generators::Sweep a(c.scene, tracer_config(), {}, opt, {});
  generators::Sweep b(c.scene, tracer_config(), {}, opt, {});
  for (int f = 0; f < 8; ++f) {
    const auto ra = a.step(f, 0.1 * f, scenario(c, f));
    if (f < 4) continue;
    const auto rb = b.step(f, 0.1 * f, scenario(c, f));
    ASSERT_EQ(ra.links.size(), rb.links.size());
    for (std::size_t l = 0; l < ra.links.size(); ++l) {
      EXPECT_EQ(ra.links[l].gain_coherent_db, rb.links[l].gain_coherent_db);
      EXPECT_EQ(ra.links[l].flags, rb.links[l].flags);
    }
  }
}

TEST(Sweep, VehicleInteractionsNameTheNodeAndThreadsDoNotMatter) {
  Canyon c;
  generators::SweepOptions opt;
  opt.lattice_frames = 1;  // one lattice (turned lattices: test_turned_lattices)
  opt.block_frames = 1000;
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    generators::Sweep sweep(c.scene, tracer_config(), {}, opt, {{7, {10, 8, 6}}});
    std::vector<FrameRecord> out;
    for (int f = 0; f < 5; ++f) {
      // Node ids are not slot numbers: 11, 20, 30, 45.
      auto v = scenario(c, f);
      const std::uint32_t ids[] = {11, 20, 30, 45};
      for (std::size_t i = 0; i < v.size(); ++i) v[i].node = ids[i];
      out.push_back(sweep.step(f, 0.1 * f, v));
    }
    return out;
  };
  const auto one = run(1), many = run(4);
  const std::uint32_t statics = c.scene.static_object_count();
  bool saw_vehicle = false;
  for (std::size_t f = 0; f < one.size(); ++f) {
    ASSERT_EQ(one[f].paths.size(), many[f].paths.size());
    for (std::size_t p = 0; p < one[f].paths.size(); ++p) EXPECT_TRUE(same_path(one[f].paths[p], many[f].paths[p]));
    for (const auto& in : one[f].interactions)
      if (in.object >= statics) {
        saw_vehicle = true;
        const std::uint32_t node = in.object - statics;
        EXPECT_TRUE(node == 11 || node == 20 || node == 30 || node == 45) << node;
      }
    // Links are (tx < rx) in node order; RSU node 7 comes first.
    EXPECT_EQ(one[f].links.front().tx, 7u);
    EXPECT_EQ(one[f].nodes.front().node, 7u);
  }
  EXPECT_TRUE(saw_vehicle);
}

// The tracer's budget rules: links beyond the sensitivity's free-space reach are
// labelled out of range without paths; paths 60 dB below a link's strongest
// are dropped and counted, and tracing with the threshold off finds exactly
// the kept plus the dropped ones.
TEST(Sweep, OutOfRangeLinksAndThresholdDropsAreRecorded) {
  Canyon c;
  generators::SweepOptions opt;
  opt.lattice_frames = 1;  // one lattice (turned lattices: test_turned_lattices)
  opt.cache = CacheMode::none;
  tracer::RadioConfig radio;
  radio.sensitivity_dbm = -44;  // free-space reach ~40 m with 30 dBm and the 6 dB margin
  const double range = tracer::max_range_m(tracer_config(), radio);
  ASSERT_NEAR(range, 0.0508 / (4 * M_PI) * std::pow(10.0, (30 + 44 + 6) / 20.0), 0.5);
  auto cfg_off = tracer_config();
  cfg_off.path_threshold_db = 0;
  generators::Sweep near(c.scene, tracer_config(), radio, opt, {});
  generators::Sweep all(c.scene, cfg_off, radio, opt, {});
  std::size_t out_of_range = 0, in_range = 0, dropped = 0;
  for (int f = 0; f < 3; ++f) {
    const FrameRecord a = near.step(f, 0.1 * f, scenario(c, f));
    const FrameRecord b = all.step(f, 0.1 * f, scenario(c, f));
    ASSERT_EQ(a.links.size(), b.links.size());
    std::map<std::uint32_t, tracer::Vec3> pos;
    for (const auto& s : a.nodes) pos[s.node] = {s.x, s.y, s.z};
    for (std::size_t l = 0; l < a.links.size(); ++l) {
      const auto &la = a.links[l], &lb = b.links[l];
      const double d = tracer::norm(tracer::operator-(pos[la.tx], pos[la.rx]));  // bumper points: antennas are within a few metres
      EXPECT_EQ(la.los_class, lb.los_class);
      EXPECT_EQ(la.flags, lb.flags);
      if (la.flags & generators::kLinkOutOfRange) {
        ++out_of_range;
        EXPECT_GT(d, range - 10);
        EXPECT_EQ(la.path_count, 0u);
        EXPECT_EQ(la.paths_below_threshold, 0u);
        EXPECT_TRUE(std::isinf(la.gain_incoherent_db));
      } else {
        ++in_range;
        EXPECT_LT(d, range + 10);
        EXPECT_EQ(lb.paths_below_threshold, 0u);
        EXPECT_EQ(la.path_count + la.paths_below_threshold, lb.path_count);
        dropped += la.paths_below_threshold;
      }
    }
  }
  EXPECT_GT(out_of_range, 0u);
  EXPECT_GT(in_range, 0u);
  EXPECT_GT(dropped, 0u) << "the canyon has through-building paths far below the direct one";
}

// Antennas inside a building's closed volume (lanes through footprints) are
// counted per frame, named by node and flagged on their links: one car parked inside the south
// building, one driving into it (outside at x = -95 and -85, inside from
// x = -75 on: the box starts at -80), the scenario's four outside.
TEST(Sweep, AntennasInsideBuildingsAreCountedAndNamed) {
  Canyon c;
  generators::SweepOptions opt;
  generators::Sweep sweep(c.scene, tracer_config(), {}, opt, {});
  for (int f = 0; f < 4; ++f) {
    auto v = scenario(c, f);
    v.push_back(vehicle(4, c.car, 0, -20, 0));
    v.push_back(vehicle(5, c.car, -95 + 10 * f, -20, 100));
    const auto frame = sweep.step(f, 0.1 * f, v);
    // The links of an antenna inside carry the flag, the others do not.
    for (const auto& l : frame.links) {
      const bool inside = l.tx == 4 || l.rx == 4 || ((l.tx == 5 || l.rx == 5) && f >= 2);
      EXPECT_EQ((l.flags & generators::kLinkEnclosed) != 0, inside) << "frame " << f << " link " << l.tx << "-" << l.rx;
    }
  }
  EXPECT_EQ(sweep.stats().enclosed, 4u + 2u);
  EXPECT_EQ(sweep.stats().enclosed_nodes, (std::vector<std::uint32_t>{4, 5}));
}
