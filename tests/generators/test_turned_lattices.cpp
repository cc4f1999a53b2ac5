// Turned lattices and carried sequences (tracer.lattice_turn,
// trace_pairs' carried sequences, [sweep] lattice_frames): a turned lattice
// is a rotation of the Fibonacci lattice (dot products and the quadrature
// kept); a carried sequence adds exactly the path a search proposing it
// finds; a sweep that carries K frames' proposals over static scenery gives
// the bits of one search over the union of those K lattices and approaches
// the exhaustive search; under moving traffic no frame loses a path of its
// own lattice; threads and block boundaries (shards, resume) do not change
// a bit, also when the diffuse gathering shoots the frames before's
// lattices too ([sweep] diffuse_frames).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "generators/sweep/sweep.hpp"
#include "sweep_fixtures.hpp"
#include "tracer_fixtures.hpp"
#include "vehicle_fixtures.hpp"

using namespace raysweep;
using namespace raysweep::test;
using generators::FrameRecord;
using generators::SweepVehicle;
using tracer::FaceRef;
using tracer::FaceSequences;

namespace {

constexpr auto vehicle = sweep_vehicle;

// A street of buildings with gaps and a kiosk: order-3 static chains the
// image search leaves to the rays.
meshkit::Scene street_geometry() {
  meshkit::Scene s;
  add_ground(s, 400);
  add_box_object(s, {-150, -30, 0}, {-20, -12, 15}, "concrete", "way/1");
  add_box_object(s, {0, -30, 0}, {150, -12, 9}, "concrete", "way/2");
  add_box_object(s, {-150, 12, 0}, {-5, 30, 12}, "brick", "way/3");
  add_box_object(s, {10, 12, 0}, {150, 30, 18}, "brick", "way/4");
  add_box_object(s, {-6, -9, 0}, {-2, -7, 3}, "metal", "way/5");
  return s;
}

// Few rays, so that lattices differ in what they find; no threshold, so
// that a path added never drops another.
tracer::TracerConfig sparse_config() {
  tracer::TracerConfig c;
  c.rays_per_source = 384;
  c.path_threshold_db = 1000;
  c.diffuse = false;
  c.diffraction = false;
  return c;
}

tracer::Snapshot trace_turned(const tracer::TraceScene& scene, const std::vector<tracer::Node>& nodes,
                              const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs,
                              tracer::TracerConfig cfg, std::uint64_t turn, const std::vector<FaceSequences>& carried) {
  cfg.lattice_turn = turn;
  return tracer::trace_pairs(scene, nodes, pairs, cfg, {}, carried);
}

std::vector<std::pair<std::uint32_t, std::uint32_t>> all_pairs(std::uint32_t n) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
  for (std::uint32_t i = 0; i < n; ++i)
    for (std::uint32_t j = i + 1; j < n; ++j) out.emplace_back(i, j);
  return out;
}

// A pair's paths through face sequences, by their sequence.
std::map<std::vector<FaceRef>, const tracer::Path*> sequence_paths(const tracer::PairResult& r) {
  std::map<std::vector<FaceRef>, const tracer::Path*> out;
  for (const auto& p : r.paths)
    if (p.origin.kind == tracer::PathOrigin::Kind::sequence) out[p.origin.faces] = &p;
  return out;
}

bool same_frame(const FrameRecord& a, const FrameRecord& b) {
  if (a.links.size() != b.links.size() || a.paths.size() != b.paths.size()) return false;
  for (std::size_t l = 0; l < a.links.size(); ++l)
    if (a.links[l].gain_incoherent_db != b.links[l].gain_incoherent_db ||
        a.links[l].gain_coherent_db != b.links[l].gain_coherent_db || a.links[l].path_count != b.links[l].path_count)
      return false;
  for (std::size_t p = 0; p < a.paths.size(); ++p)
    if (a.paths[p].a != b.paths[p].a || a.paths[p].tau_s != b.paths[p].tau_s) return false;
  return true;
}

std::vector<generators::SweepRsu> street_rsus() {
  return {{0, {-60, 8, 5}}, {1, {-15, -10, 2}}, {2, {25, 9, 6}}, {3, {70, -8, 4}}, {4, {120, 6, 3}}};
}

generators::SweepOptions turned_options(std::uint32_t lattice_frames) {
  generators::SweepOptions o;
  o.cache = generators::CacheMode::none;
  o.block_frames = 1000;
  o.lattice_frames = lattice_frames;
  return o;
}

}  // namespace

TEST(TurnedLattice, IsARotationOfTheLatticeAndAsGoodAQuadrature) {
  const int n = 6144;
  const auto plain = tracer::fibonacci_sphere(n);
  EXPECT_EQ(tracer::fibonacci_sphere(n, 0), plain);
  // f = x^2 + z^4: its integral over the sphere is 4 pi / 3 + 4 pi / 5.
  const double exact = 4 * M_PI / 3 + 4 * M_PI / 5;
  for (std::uint64_t turn : {1ull, 2ull, 77ull, 0xFFFFFFFFFFFFull}) {
    const auto d = tracer::fibonacci_sphere(n, turn);
    ASSERT_EQ(d.size(), plain.size());
    double moved = 0, sum = 0;
    for (int i = 0; i < n; ++i) {
      EXPECT_NEAR(tracer::norm(d[i]), 1.0, 1e-12);
      moved = std::max(moved, tracer::norm(tracer::operator-(d[i], plain[i])));
      sum += d[i][0] * d[i][0] + std::pow(d[i][2], 4);
      const int j = (i * 37 + 11) % n;  // angles between directions are kept
      EXPECT_NEAR(tracer::dot(d[i], d[j]), tracer::dot(plain[i], plain[j]), 1e-12);
    }
    EXPECT_GT(moved, 0.1) << "turn " << turn;
    EXPECT_NEAR(sum * 4 * M_PI / n, exact, 2e-3 * exact) << "turn " << turn;
  }
  EXPECT_NE(tracer::fibonacci_sphere(n, 1), tracer::fibonacci_sphere(n, 2));
}

// Two lattices' proposals: carrying one into the other's search gives the
// union of both searches' sequence paths, each with exactly the values its
// own search gives it; carrying a search's own proposals changes nothing.
TEST(TurnedLattice, CarriedSequencesAddExactlyTheirPaths) {
  tracer::TraceScene scene(street_geometry());
  std::vector<tracer::Node> nodes;
  for (const auto& r : street_rsus()) nodes.push_back(node(std::to_string(r.node), r.position));
  const auto pairs = all_pairs(static_cast<std::uint32_t>(nodes.size()));
  const std::vector<FaceSequences> none(pairs.size());
  const auto cfg = sparse_config();
  const auto a = trace_turned(scene, nodes, pairs, cfg, 1, none), b = trace_turned(scene, nodes, pairs, cfg, 2, none);
  std::vector<FaceSequences> from_a, from_b;
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    from_a.push_back(a.pairs[p].proposed);
    from_b.push_back(b.pairs[p].proposed);
  }
  EXPECT_NE(from_a, from_b) << "the two lattices proposed the same sequences";
  const auto ab = trace_turned(scene, nodes, pairs, cfg, 2, from_a);
  const auto bb = trace_turned(scene, nodes, pairs, cfg, 2, from_b);
  std::size_t gained = 0;
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    EXPECT_EQ(ab.pairs[p].proposed, b.pairs[p].proposed) << "carried sequences are not proposals";
    const auto pa = sequence_paths(a.pairs[p]), pb = sequence_paths(b.pairs[p]), pab = sequence_paths(ab.pairs[p]);
    auto want = pb;
    want.insert(pa.begin(), pa.end());
    ASSERT_EQ(pab.size(), want.size()) << "pair " << p;
    for (const auto& [faces, path] : pab) {
      ASSERT_TRUE(want.count(faces));
      EXPECT_EQ(path->a, want.at(faces)->a);
      EXPECT_EQ(path->tau_s, want.at(faces)->tau_s);
    }
    gained += pab.size() - pb.size();
    // Its own proposals carried: the same paths, bit for bit.
    ASSERT_EQ(bb.pairs[p].paths.size(), b.pairs[p].paths.size());
    for (std::size_t q = 0; q < b.pairs[p].paths.size(); ++q) EXPECT_EQ(bb.pairs[p].paths[q].a, b.pairs[p].paths[q].a);
  }
  EXPECT_GT(gained, 0u) << "lattice 1 found nothing lattice 2 missed: the test shows nothing";
  EXPECT_THROW(trace_turned(scene, nodes, pairs, cfg, 2, std::vector<FaceSequences>(1)), std::invalid_argument);
}

// Nothing moving: frame f of a sweep with lattice_frames = K is one search
// over the lattices of frames 0 .. f (a path found holds, so it is kept):
// the same paths; they grow frame by frame towards the exhaustive
// search's.
TEST(TurnedLattice, StaticSceneryKeepsEveryLatticesPathsAndApproachesTheExhaustiveSearch) {
  tracer::TraceScene scene(street_geometry());
  const std::uint32_t K = 6;
  const auto cfg = sparse_config();
  generators::Sweep sweep(scene, cfg, {}, turned_options(K), street_rsus());
  std::vector<FrameRecord> frames;
  for (std::uint64_t f = 0; f < K + 2; ++f) frames.push_back(sweep.step(f, 0.1 * static_cast<double>(f), {}));

  std::vector<tracer::Node> nodes;
  for (const auto& r : street_rsus()) nodes.push_back(node(std::to_string(r.node), r.position));
  const auto pairs = all_pairs(static_cast<std::uint32_t>(nodes.size()));
  // The union by hand for the last frame: the proposals of every frame
  // before it, carried into its own lattice's search.
  const std::uint64_t last = K + 1;
  std::vector<std::set<std::vector<FaceRef>>> seen(pairs.size());
  for (std::uint64_t f = 0; f < last; ++f) {
    const auto s = trace_turned(scene, nodes, pairs, cfg, generators::frame_lattice_turn(0, f),
                                std::vector<FaceSequences>(pairs.size()));
    for (std::size_t p = 0; p < pairs.size(); ++p)
      seen[p].insert(s.pairs[p].proposed.begin(), s.pairs[p].proposed.end());
  }
  std::vector<FaceSequences> carried;
  for (const auto& s : seen) carried.emplace_back(s.begin(), s.end());
  const auto by_hand = trace_turned(scene, nodes, pairs, cfg, generators::frame_lattice_turn(0, last), carried);
  ASSERT_EQ(frames[last].links.size(), pairs.size());
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    EXPECT_EQ(frames[last].links[p].path_count, by_hand.pairs[p].paths.size()) << "pair " << p;
    EXPECT_NEAR(frames[last].links[p].gain_incoherent_db, 10 * std::log10(by_hand.pairs[p].stats.gain_incoherent),
                1e-4)
        << "pair " << p;
  }

  auto total_paths = [](const FrameRecord& fr) {
    std::size_t n = 0;
    for (const auto& l : fr.links) n += l.path_count;
    return n;
  };
  auto exhaustive_cfg = cfg;
  exhaustive_cfg.candidates = tracer::CandidateSearch::exhaustive;
  std::size_t exhaustive = 0;
  for (const auto& r : tracer::trace_pairs(scene, nodes, pairs, exhaustive_cfg, {}).pairs) exhaustive += r.paths.size();
  for (std::uint32_t f = 1; f < K + 2; ++f)
    EXPECT_GE(total_paths(frames[f]), total_paths(frames[f - 1])) << "frame " << f;
  EXPECT_GT(total_paths(frames[K - 1]), total_paths(frames[0])) << "K lattices found nothing one missed";
  EXPECT_LE(total_paths(frames[K + 1]), exhaustive);
  EXPECT_LT(exhaustive - total_paths(frames[K - 1]), exhaustive - total_paths(frames[0]));
  RecordProperty("paths_one_lattice", std::to_string(total_paths(frames[0])));
  RecordProperty("paths_k_lattices", std::to_string(total_paths(frames[K - 1])));
  RecordProperty("paths_exhaustive", std::to_string(exhaustive));
}

// Moving traffic: every link of every frame has at least the power the
// frame's own lattice finds alone (carried sequences only add paths, each
// solved exactly at the frame's positions), and somewhere more.
TEST(TurnedLattice, MovingTrafficKeepsEveryPathOfTheFramesOwnLattice) {
  tracer::TraceScene scene(street_geometry());
  const auto car = add_library_model(scene, "passenger"), bus = add_library_model(scene, "bus");
  auto cfg = sparse_config();
  cfg.diffuse = true;  // the frame's own, in both
  generators::Sweep turned(scene, cfg, {}, turned_options(4), {{10, {0, 9, 6}}});
  std::size_t richer = 0;
  for (std::uint64_t f = 0; f < 10; ++f) {
    const double t = 0.1 * static_cast<double>(f);
    const std::vector<SweepVehicle> now = {vehicle(0, car, -40 + 12 * t, -4, 90, 12),
                                           vehicle(1, bus, 30 - 10 * t, 4, 270, 10),
                                           vehicle(2, car, 60 - 15 * t, 4, 270, 15)};
    const FrameRecord fr = turned.step(f, t, now);
    // The frame's lattice alone, on the same placed scene.
    auto own = cfg;
    own.lattice_turn = generators::frame_lattice_turn(0, f);
    generators::SweepOptions fresh_opts = turned_options(1);
    generators::Sweep fresh(scene, own, {}, fresh_opts, {{10, {0, 9, 6}}});
    const FrameRecord alone = fresh.step(0, t, now);
    ASSERT_EQ(fr.links.size(), alone.links.size());
    for (std::size_t l = 0; l < fr.links.size(); ++l) {
      EXPECT_GE(fr.links[l].gain_incoherent_db, alone.links[l].gain_incoherent_db - 1e-4f)
          << "frame " << f << " link " << l;
      richer += fr.links[l].path_count > alone.links[l].path_count;
    }
  }
  EXPECT_GT(richer, 0u);
  EXPECT_GT(turned.stats().carried, 0u);
}

// With the frame's own diffuse lattice, and with the two frames' before too.
class TurnedLatticeSplit : public ::testing::TestWithParam<std::uint32_t> {};

TEST_P(TurnedLatticeSplit, ThreadsAndBlockBoundariesDoNotMatter) {
  tracer::TraceScene scene(street_geometry());
  const auto car = add_library_model(scene, "passenger"), bus = add_library_model(scene, "bus");
  auto cfg = sparse_config();
  cfg.diffuse = true;
  auto traffic = [&](std::uint64_t f) {
    const double t = 0.1 * static_cast<double>(f);
    return std::vector<SweepVehicle>{vehicle(0, car, -40 + 12 * t, -4, 90, 12),
                                     vehicle(1, bus, 30 - 10 * t, 4, 270, 10),
                                     vehicle(2, car, 60 - 15 * t, 4, 270, 15)};
  };
  auto opts = turned_options(4);
  opts.block_frames = 5;
  opts.diffuse_frames = GetParam();
  auto run = [&](int threads, std::uint64_t first) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    generators::Sweep sweep(scene, cfg, {}, opts, {{10, {0, 9, 6}}});
    std::vector<FrameRecord> out;
    for (std::uint64_t f = first; f < 10; ++f) out.push_back(sweep.step(f, 0.1 * static_cast<double>(f), traffic(f)));
    return out;
  };
  const auto one = run(1, 0), two = run(2, 0), second_block = run(2, 5);
  for (std::size_t f = 0; f < one.size(); ++f) EXPECT_TRUE(same_frame(one[f], two[f])) << "frame " << f;
  for (std::size_t f = 5; f < one.size(); ++f) EXPECT_TRUE(same_frame(one[f], second_block[f - 5])) << "frame " << f;
}

INSTANTIATE_TEST_SUITE_P(DiffuseFrames, TurnedLatticeSplit, ::testing::Values(1u, 3u));

// [sweep] diffuse_frames = D: frame f's diffuse records are those of its own
// lattice and the lattices of frames f - 1 .. f - D + 1, all shot from frame
// f's positions (tracer.diffuse_turns): the same numbers as that trace.
TEST(TurnedLattice, DiffuseFramesShootTheFramesBeforesLattices) {
  tracer::TraceScene scene(street_geometry());
  const auto car = add_library_model(scene, "passenger"), bus = add_library_model(scene, "bus");
  auto cfg = sparse_config();
  cfg.diffuse = true;
  cfg.diffuse_roulette_db = 300;  // every sample: the mean is then exact
  auto opts = turned_options(1);
  opts.diffuse_frames = 3;
  generators::Sweep sweep(scene, cfg, {}, opts, {{10, {0, 9, 6}}});
  std::size_t differs = 0;
  for (std::uint64_t f = 0; f < 6; ++f) {
    const double t = 0.1 * static_cast<double>(f);
    const std::vector<SweepVehicle> now = {vehicle(0, car, -40 + 12 * t, -4, 90, 12),
                                           vehicle(1, bus, 30 - 10 * t, 4, 270, 10)};
    const FrameRecord fr = sweep.step(f, t, now);
    auto by_hand = cfg;
    // Frames 0 and 1: the turn of frame -1 is the unturned lattice (the
    // sweep's own here), drawn from the other stream instead.
    auto before = [&](std::uint64_t k) {
      const std::uint64_t t = generators::frame_lattice_turn(0, f - k);
      return t == 0 ? generators::frame_lattice_turn(~std::uint64_t{0}, f - k) : t;
    };
    by_hand.diffuse_turns = {before(1), before(2)};
    generators::Sweep fresh(scene, by_hand, {}, turned_options(1), {{10, {0, 9, 6}}});
    const FrameRecord want = fresh.step(0, t, now);
    generators::Sweep own(scene, cfg, {}, turned_options(1), {{10, {0, 9, 6}}});
    const FrameRecord alone = own.step(0, t, now);
    ASSERT_EQ(fr.links.size(), want.links.size());
    for (std::size_t l = 0; l < fr.links.size(); ++l) {
      EXPECT_EQ(fr.links[l].gain_incoherent_db, want.links[l].gain_incoherent_db) << "frame " << f << " link " << l;
      differs += fr.links[l].gain_incoherent_db != alone.links[l].gain_incoherent_db;
    }
  }
  EXPECT_GT(differs, 0u) << "the frames before's lattices changed nothing";
  generators::SweepOptions bad = turned_options(1);
  bad.diffuse_frames = 0;
  EXPECT_THROW(generators::Sweep(scene, cfg, {}, bad, {{10, {0, 9, 6}}}), std::invalid_argument);
}
