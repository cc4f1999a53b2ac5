// Frame-to-frame coherence (generators/sweep/sweep.hpp, tracer/coherence.hpp):
// a coherent sweep against the same sweep searching every frame from
// scratch (coherence = false): nothing moving gives the same bits; moving
// traffic stays inside the error budget (gain difference p99 <= 0.25 dB,
// worst <= 3 dB, docs/tracer.md); the events that change
// a pair's path set (a vehicle into the direct ray, a car coming round a
// corner out of a building's shadow) are picked up in the frame they happen.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "generators/sweep/sweep.hpp"
#include "sweep_fixtures.hpp"
#include "tracer_fixtures.hpp"
#include "vehicle_fixtures.hpp"

using namespace raysweep;
using namespace raysweep::test;
using generators::CacheMode;
using generators::FrameRecord;
using generators::SweepVehicle;

namespace {

constexpr auto vehicle = sweep_vehicle;

tracer::TracerConfig tracer_config() {
  tracer::TracerConfig c;
  c.rays_per_source = 2048;
  return c;
}

// `every_pair`: re-solve every pair whatever its paths (the rule's
// thresholds off), so that the re-solve itself is what is tested.
generators::SweepOptions options(bool coherence, bool every_pair = true) {
  generators::SweepOptions o;
  o.cache = CacheMode::none;  // every pair every frame: the comparison is the coherence's alone
  o.block_frames = 1000;
  o.lattice_frames = 1;  // the coherence against one lattice's search (turned lattices: test_turned_lattices)
  o.coherence = coherence;
  if (every_pair) {
    o.coherence_volatile_share = 1;
    o.coherence_direct_share = 0;
    o.coherence_clear_zone_only = false;
  }
  return o;
}

// A street (ground, a building each side) with a car and a bus model.
struct Street {
  tracer::TraceScene scene;
  std::uint32_t car, bus;
  static meshkit::Scene geometry() {
    meshkit::Scene s;
    add_ground(s, 400);
    add_box_object(s, {-150, -30, 0}, {-20, -12, 15}, "concrete", "way/1");
    add_box_object(s, {0, -30, 0}, {150, -12, 9}, "concrete", "way/2");
    add_box_object(s, {-150, 12, 0}, {150, 30, 12}, "brick", "way/3");
    return s;
  }
  Street() : scene(geometry()), car(add_library_model(scene, "passenger")), bus(add_library_model(scene, "bus")) {}
};

bool same_frame(const FrameRecord& a, const FrameRecord& b) {
  if (a.links.size() != b.links.size() || a.paths.size() != b.paths.size() ||
      a.interactions.size() != b.interactions.size())
    return false;
  for (std::size_t l = 0; l < a.links.size(); ++l)
    if (a.links[l].gain_incoherent_db != b.links[l].gain_incoherent_db ||
        a.links[l].gain_coherent_db != b.links[l].gain_coherent_db || a.links[l].los_class != b.links[l].los_class)
      return false;
  for (std::size_t p = 0; p < a.paths.size(); ++p) {
    const auto &x = a.paths[p], &y = b.paths[p];
    if (x.a != y.a || x.tau_s != y.tau_s || x.theta_t != y.theta_t || x.phi_t != y.phi_t || x.theta_r != y.theta_r ||
        x.phi_r != y.phi_r || x.doppler_hz != y.doppler_hz || x.interaction_count != y.interaction_count)
      return false;
  }
  for (std::size_t q = 0; q < a.interactions.size(); ++q) {
    const auto &x = a.interactions[q], &y = b.interactions[q];
    if (x.type != y.type || x.object != y.object || x.x != y.x || x.y != y.y || x.z != y.z) return false;
  }
  return true;
}

// The wideband gain floored at the sensitivity floor (what a receiver sees).
double floored_gain(const generators::LinkRecord& l, const tracer::RadioConfig& radio) {
  const double floor = radio.sensitivity_dbm - radio.tx_power_dbm;
  return std::isfinite(l.gain_incoherent_db) ? std::max<double>(l.gain_incoherent_db, floor) : floor;
}

// Every link of a coherent and a from-scratch frame: the same links, both
// labels equal; the floored gain differences appended to `diff`.
void compare(const FrameRecord& a, const FrameRecord& b, std::vector<double>& diff, int frame) {
  ASSERT_EQ(a.links.size(), b.links.size()) << "frame " << frame;
  for (std::size_t l = 0; l < a.links.size(); ++l) {
    const auto &la = a.links[l], &lb = b.links[l];
    ASSERT_EQ(la.tx, lb.tx);
    ASSERT_EQ(la.rx, lb.rx);
    EXPECT_EQ(la.los_class, lb.los_class) << "frame " << frame << " link " << la.tx << "-" << la.rx;
    EXPECT_EQ(la.los_class_fresnel, lb.los_class_fresnel) << "frame " << frame << " link " << la.tx << "-" << la.rx;
    diff.push_back(std::fabs(floored_gain(la, {}) - floored_gain(lb, {})));
  }
}

double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

}  // namespace

TEST(Coherence, NothingMovingGivesTheSameBitsAsSearching) {
  Street s;
  const std::vector<SweepVehicle> parked = {vehicle(0, s.car, -30, -4, 90, 0), vehicle(1, s.car, 10, 4, 270, 0),
                                            vehicle(2, s.bus, 40, -4, 90, 0), vehicle(3, s.car, 80, 4, 270, 0)};
  const std::vector<generators::SweepRsu> rsus = {{9, {20, 9, 6}}};
  generators::Sweep coherent(s.scene, tracer_config(), {}, options(true), rsus);
  generators::Sweep fresh(s.scene, tracer_config(), {}, options(false), rsus);
  for (int f = 0; f < 4; ++f) {
    const FrameRecord a = coherent.step(f, 0.1 * f, parked), b = fresh.step(f, 0.1 * f, parked);
    EXPECT_TRUE(same_frame(a, b)) << "frame " << f;
  }
  // Only the first frame searched; the others re-solved every pair.
  EXPECT_EQ(coherent.stats().searched_links, 10u);
  EXPECT_EQ(coherent.stats().traced_links, 40u);
  EXPECT_EQ(fresh.stats().searched_links, 40u);
}

// Random traffic on the street for 50 frames (10 Hz), three seeds: the
// coherent sweep with its default rule inside the error budget against
// searching every frame.
TEST(Coherence, MovingTrafficStaysInsideTheErrorBudget) {
  Street s;
  std::vector<double> diff;
  std::uint64_t searched = 0, traced = 0;
  for (unsigned seed : {1u, 2u, 3u}) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> x0(-100, 100), speed(5, 15);
    std::vector<SweepVehicle> start;
    for (std::uint32_t k = 0; k < 6; ++k) {
      const bool east = k % 2 == 0;
      start.push_back(vehicle(k, k == 3 ? s.bus : s.car, x0(rng), east ? -4 : 4, east ? 90 : 270, speed(rng)));
    }
    const std::vector<generators::SweepRsu> rsus = {{10, {0, 9, 6}}};
    generators::Sweep coherent(s.scene, tracer_config(), {}, options(true, false), rsus);
    generators::Sweep fresh(s.scene, tracer_config(), {}, options(false), rsus);
    for (int f = 0; f < 50; ++f) {
      auto now = start;
      for (auto& v : now) v.position = tracer::operator+(v.position, tracer::operator*(0.1 * f, v.velocity));
      compare(coherent.step(f, 0.1 * f, now), fresh.step(f, 0.1 * f, now), diff, f);
    }
    searched += coherent.stats().searched_links;
    traced += coherent.stats().traced_links;
  }
  const double p99 = quantile(diff, 0.99), worst = quantile(diff, 1.0);
  RecordProperty("p99_db", std::to_string(p99));
  RecordProperty("max_db", std::to_string(worst));
  RecordProperty("searched_share", std::to_string(static_cast<double>(searched) / static_cast<double>(traced)));
  EXPECT_LE(p99, 0.25);
  EXPECT_LE(worst, 3.0);
  // The rule re-solved some pairs (those a strong, clear direct path holds).
  EXPECT_LT(searched, traced);
}

TEST(Coherence, ThreadsDoNotMatter) {
  Street s;
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    generators::Sweep sweep(s.scene, tracer_config(), {}, options(true), {{10, {0, 9, 6}}});
    std::vector<FrameRecord> out;
    for (int f = 0; f < 12; ++f)
      out.push_back(sweep.step(f, 0.1 * f,
                               {vehicle(0, s.car, -40 + 1.2 * f, -4, 90, 12), vehicle(1, s.bus, 30 - f, 4, 270, 10),
                                vehicle(2, s.car, 60 - 1.5 * f, 4, 270, 15)}));
    return out;
  };
  const auto one = run(1), two = run(2);
  for (std::size_t f = 0; f < one.size(); ++f) EXPECT_TRUE(same_frame(one[f], two[f])) << "frame " << f;
}

// The events that change a pair's path set, each in the frame it happens:
// a bus driving into the direct ray between two parked cars (LoS ->
// NLoSv -> LoS), and a car coming round a corner, out of a building's
// shadow, towards a road-side unit (NLoS -> LoS).
TEST(Coherence, PicksUpEachChangeInTheFrameItHappens) {
  meshkit::Scene g;
  add_ground(g, 400);
  add_box_object(g, {-80, 12, 0}, {-12, 80, 15}, "concrete", "way/corner");  // the crossing's north-west block
  tracer::TraceScene scene(g);
  const std::uint32_t car = add_library_model(scene, "passenger"), bus = add_library_model(scene, "bus");
  auto frame = [&](int f) {
    return std::vector<SweepVehicle>{
        vehicle(0, car, 30, -6, 90, 0), vehicle(1, car, 70, 6, 90, 0),
        vehicle(2, bus, 95 - 2.0 * f, 0, 270, 20),  // westwards through the cars' direct ray
        vehicle(3, car, -4, 45 - 1.5 * f, 180, 15)  // southwards, round the block's corner
    };
  };
  const std::vector<generators::SweepRsu> rsus = {{9, {-45, 0, 5}}};
  generators::Sweep coherent(scene, tracer_config(), {}, options(true), rsus);
  generators::Sweep fresh(scene, tracer_config(), {}, options(false), rsus);
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint8_t> before;
  std::vector<std::string> changes;
  for (int f = 0; f < 40; ++f) {
    const FrameRecord a = coherent.step(f, 0.1 * f, frame(f)), b = fresh.step(f, 0.1 * f, frame(f));
    ASSERT_EQ(a.links.size(), b.links.size());
    for (std::size_t l = 0; l < a.links.size(); ++l) {
      const auto &la = a.links[l], &lb = b.links[l];
      EXPECT_EQ(la.los_class, lb.los_class) << "frame " << f;
      const auto key = std::make_pair(lb.tx, lb.rx);
      if (f > 0 && before[key] != lb.los_class) {
        changes.push_back(std::to_string(lb.tx) + "-" + std::to_string(lb.rx) + "@" + std::to_string(f));
        // Searched in that frame: the very channel of searching from scratch.
        EXPECT_EQ(la.gain_incoherent_db, lb.gain_incoherent_db) << changes.back();
        EXPECT_EQ(la.path_count, lb.path_count) << changes.back();
      }
      before[key] = lb.los_class;
    }
  }
  // The bus crosses the cars' ray (0-1), the car leaves the block's shadow (3-9).
  auto has = [&](const std::string& pair) {
    return std::any_of(changes.begin(), changes.end(), [&](const std::string& c) { return c.rfind(pair, 0) == 0; });
  };
  EXPECT_TRUE(has("0-1@")) << ::testing::PrintToString(changes);
  EXPECT_TRUE(has("3-9@")) << ::testing::PrintToString(changes);
}
