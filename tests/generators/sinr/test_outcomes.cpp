// run_sinr end to end (generators/sinr/outcomes.cpp): RAT assignment, file
// validity, determinism across runs, threads and schedule reuse, NR-only runs.
#include <gtest/gtest.h>

#if __has_include(<hdf5.h>)
#include <hdf5.h>
#else
#include <hdf5/serial/hdf5.h>  // Debian's serial HDF5 (the test target has no HDF5 include path)
#endif

#include <tbb/global_control.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "generators/formats.hpp"
#include "generators/sinr/channel_models.hpp"
#include "generators/sinr/channel_trace.hpp"
#include "generators/sinr/outcomes.hpp"
#include "generators/sinr/schedule.hpp"
#include "generators/sinr/sinr_config.hpp"
#include "generators/sinr/sinr_file.hpp"
#include "sinr_fixtures.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using namespace raysweep::generators::sinr::fixtures;
using raysweep::test::read_text;
using raysweep::test::scratch_dir;

namespace {

// ---------------------------------------------------------------------------
// HDF5 column reading (receptions are only in the file).

template <class T>
std::vector<T> read_column(const fs::path& file, const std::string& dataset, hid_t mtype) {
  std::vector<T> v;
  const hid_t f = H5Fopen(file.string().c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) {
    ADD_FAILURE() << "cannot open " << file;
    return v;
  }
  const hid_t d = H5Dopen2(f, dataset.c_str(), H5P_DEFAULT);
  if (d < 0) {
    ADD_FAILURE() << "no dataset " << dataset << " in " << file;
    H5Fclose(f);
    return v;
  }
  const hid_t sp = H5Dget_space(d);
  const hssize_t n = H5Sget_simple_extent_npoints(sp);
  v.resize(static_cast<std::size_t>(n));
  if (n > 0 && H5Dread(d, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0)
    ADD_FAILURE() << "cannot read " << dataset;
  H5Sclose(sp);
  H5Dclose(d);
  H5Fclose(f);
  return v;
}

}  // namespace

// ===========================================================================
// run_sinr end to end.

namespace {

// Node 0: an RSU; nodes 1..6: vehicles driving east at 10 m/s in two lanes, 20 frames at 10 Hz.
ChannelTrace e2e_trace() {
  std::vector<NodeInfo> nodes(7);
  nodes[0].id = "rsu0";
  nodes[0].kind = NodeKind::rsu;
  for (int i = 1; i <= 6; ++i) {
    nodes[i].id = "veh" + std::to_string(i);
    nodes[i].kind = NodeKind::vehicle;
    nodes[i].vtype = "car";
  }
  std::vector<FrameRecord> frames;
  for (int f = 0; f < 20; ++f) {
    FrameRecord fr;
    fr.time_s = f * 0.1;
    fr.nodes.push_back(at(0, 60, 15));
    for (std::uint32_t i = 1; i <= 6; ++i)
      fr.nodes.push_back(at(i, 20.0 * i + 1.0 * f, (i % 2) * 3.5, 10, 0, 90));
    frames.push_back(fr);
  }
  return ChannelTrace::from_records(nodes, frames, kFc, 10e6);
}

SinrConfig e2e_config(std::uint64_t seed) {
  SinrConfig c;
  c.seed = seed;
  c.nr.bandwidth_hz = 20e6;
  c.cpm.enabled = true;
  c.cpm.bytes = 400;  // 2 subchannels
  c.cpm.period_s = 0.1;
  return c;
}

SinrRunStats run_to_file(const fs::path& p, const ChannelTrace& tr, const ChannelModel& ch, const SinrConfig& c,
                         const std::vector<Rat>& rats, const std::vector<Transmission>* reuse = nullptr) {
  const auto [b, e] = sinr_window(tr, c);
  SinrHeader h;
  h.raysweep_version = "test";
  h.git_hash = "unknown";
  h.config = nlohmann::json{{"test", "e2e"}};
  h.inputs = nlohmann::json::object();
  h.provenance = nlohmann::json::object();
  h.seed = 1;  // the same in every file, so files differ only by their content
  h.channel_model = "ray";
  h.carrier_hz = kFc;
  h.sinr_threshold_db = c.sinr_threshold_db;
  h.sensitivity_dbm = c.sensitivity_dbm;
  h.gain_threshold_db = c.gain_threshold_db;
  h.time_start_s = b;
  h.time_end_s = e;
  SinrWriter w(p, h);
  return run_sinr(tr, ch, c, rats, reuse, w);
}

bool same_transmissions(const std::vector<Transmission>& a, const std::vector<Transmission>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const auto &x = a[i], &y = b[i];
    if (x.node != y.node || x.rat != y.rat || x.message != y.message || x.packet != y.packet ||
        x.attempt != y.attempt || x.size_bytes != y.size_bytes || x.start_s != y.start_s ||
        x.duration_s != y.duration_s || x.f_lo_hz != y.f_lo_hz || x.f_hi_hz != y.f_hi_hz ||
        x.power_dbm != y.power_dbm)
      return false;
  }
  return true;
}

}  // namespace

TEST(RunSinr, AssignRats) {
  const ChannelTrace tr = e2e_trace();
  RatAssignment a;  // nr_fraction 0.5
  const auto rats = assign_rats(tr, a, 3);
  ASSERT_EQ(rats.size(), 7u);
  EXPECT_EQ(rats[0], Rat::none) << "RSUs are silent unless listed";
  int nr = 0, wifi = 0;
  for (int i = 1; i <= 6; ++i) nr += rats[i] == Rat::nr_v2x, wifi += rats[i] == Rat::wifi80211p;
  EXPECT_EQ(nr, 3);
  EXPECT_EQ(wifi, 3);
  EXPECT_EQ(assign_rats(tr, a, 3), rats) << "deterministic for a seed";

  // Some seed gives another split (an exact 3/3 each time).
  bool differs = false;
  for (std::uint64_t seed = 4; seed < 20 && !differs; ++seed) {
    const auto r = assign_rats(tr, a, seed);
    EXPECT_EQ(std::count(r.begin(), r.end(), Rat::nr_v2x), 3);
    differs = r != rats;
  }
  EXPECT_TRUE(differs);

  // nrv2x-only: the same NR vehicles, the 802.11p ones silenced.
  RatAssignment only = a;
  only.enabled = "nrv2x-only";
  const auto r2 = assign_rats(tr, only, 3);
  for (int i = 0; i <= 6; ++i) EXPECT_EQ(r2[i], rats[i] == Rat::nr_v2x ? Rat::nr_v2x : Rat::none) << i;
  only.enabled = "80211p-only";
  const auto r3 = assign_rats(tr, only, 3);
  for (int i = 0; i <= 6; ++i) EXPECT_EQ(r3[i], rats[i] == Rat::wifi80211p ? Rat::wifi80211p : Rat::none) << i;

  // active_vehicles 4: vehicles 1..4 split 2/2, 5 and 6 silent.
  RatAssignment act = a;
  act.active_vehicles = 4;
  const auto r4 = assign_rats(tr, act, 3);
  EXPECT_EQ(r4[5], Rat::none);
  EXPECT_EQ(r4[6], Rat::none);
  EXPECT_EQ(std::count(r4.begin(), r4.end(), Rat::nr_v2x), 2);
  EXPECT_EQ(std::count(r4.begin(), r4.end(), Rat::wifi80211p), 2);

  // Lists take precedence over vTypes, vTypes over the fraction.
  RatAssignment lists;
  lists.by_vtype["car"] = Rat::nr_v2x;
  lists.wifi_ids = {"veh2"};
  lists.nr_ids = {"rsu0"};
  lists.silent_ids = {"veh5"};
  const auto r5 = assign_rats(tr, lists, 3);
  EXPECT_EQ(r5, (std::vector<Rat>{Rat::nr_v2x, Rat::nr_v2x, Rat::wifi80211p, Rat::nr_v2x, Rat::nr_v2x, Rat::none,
                                  Rat::nr_v2x}));
  RatAssignment unknown;
  unknown.nr_ids = {"veh99"};
  EXPECT_THROW(assign_rats(tr, unknown, 3), std::invalid_argument);
}

TEST(RunSinr, EndToEndFileDeterminismAndReuse) {
  const ChannelTrace tr = e2e_trace();
  FakeChannel ch(tr, distance_gain(1e9));
  const SinrConfig c = e2e_config(7);
  const auto rats = assign_rats(tr, c.rats, c.seed);
  const fs::path dir = scratch_dir("sinr");
  const fs::path f1 = dir / "run1.h5", f2 = dir / "run2.h5";

  const SinrRunStats st = run_to_file(f1, tr, ch, c, rats);
  EXPECT_EQ(validate_dataset(f1.string()), std::vector<std::string>{});
  EXPECT_DOUBLE_EQ(st.time_start_s, 0.0);
  EXPECT_NEAR(st.time_end_s, 2.0, 1e-9);
  ASSERT_GT(st.transmissions, 50u);
  // All six vehicles are present in every frame: each transmission has exactly the two
  // other vehicles of its RAT as receivers (the RSU has none).
  EXPECT_EQ(st.receptions, 2 * st.transmissions);

  const auto r_tr = read_column<std::uint32_t>(f1, "/receptions/transmission", H5T_NATIVE_UINT32);
  const auto r_tx = read_column<std::uint32_t>(f1, "/receptions/tx", H5T_NATIVE_UINT32);
  const auto r_rx = read_column<std::uint32_t>(f1, "/receptions/rx", H5T_NATIVE_UINT32);
  const auto r_rat = read_column<std::uint8_t>(f1, "/receptions/rat", H5T_NATIVE_UINT8);
  const auto t_node = read_column<std::uint32_t>(f1, "/transmissions/node", H5T_NATIVE_UINT32);
  const auto t_rat = read_column<std::uint8_t>(f1, "/transmissions/rat", H5T_NATIVE_UINT8);
  const auto n_rat = read_column<std::uint8_t>(f1, "/nodes/rat", H5T_NATIVE_UINT8);
  ASSERT_EQ(r_rx.size(), st.receptions);
  ASSERT_EQ(t_node.size(), st.transmissions);
  ASSERT_EQ(n_rat.size(), 7u);
  for (std::uint32_t n = 0; n < 7; ++n) EXPECT_EQ(n_rat[n], static_cast<std::uint8_t>(rats[n]));
  std::size_t nr_tx = 0, wifi_tx = 0;
  for (std::size_t i = 0; i < t_node.size(); ++i) {
    EXPECT_EQ(t_rat[i], static_cast<std::uint8_t>(rats[t_node[i]])) << "a node sends with its own RAT";
    nr_tx += t_rat[i] == 2;
    wifi_tx += t_rat[i] == 1;
  }
  EXPECT_GT(nr_tx, 0u);
  EXPECT_GT(wifi_tx, 0u);
  for (std::size_t i = 0; i < r_rx.size(); ++i) {
    ASSERT_LT(r_tr[i], t_node.size());
    EXPECT_NE(r_rx[i], t_node[r_tr[i]]) << "the sender is not a receiver";
    EXPECT_EQ(r_tx[i], t_node[r_tr[i]]);
    EXPECT_EQ(r_rat[i], t_rat[r_tr[i]]);
    EXPECT_EQ(static_cast<std::uint8_t>(rats[r_rx[i]]), t_rat[r_tr[i]]) << "receiver of the transmission's RAT";
  }

  // The same seed: a byte-identical file.
  run_to_file(f2, tr, ch, c, rats);
  EXPECT_TRUE(read_text(f1) == read_text(f2)) << "two runs with the same seed differ";

  // One thread vs four threads: byte-identical.
  const fs::path f_one = dir / "one.h5", f_four = dir / "four.h5";
  {
    tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 1);
    run_to_file(f_one, tr, ch, c, rats);
  }
  {
    tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 4);
    run_to_file(f_four, tr, ch, c, rats);
  }
  EXPECT_TRUE(read_text(f_one) == read_text(f_four)) << "results depend on the number of threads";
  EXPECT_TRUE(read_text(f_one) == read_text(f1));

  // Another seed: another schedule.
  const fs::path f_other = dir / "other.h5";
  run_to_file(f_other, tr, ch, e2e_config(8), rats);
  const SinrSchedule s1 = read_sinr_schedule(f1.string());
  const SinrSchedule s_other = read_sinr_schedule(f_other.string());
  EXPECT_FALSE(same_transmissions(s1.transmissions, s_other.transmissions));

  // Schedule reuse: the transmissions of the first run, evaluated again.
  ASSERT_EQ(s1.transmissions.size(), st.transmissions);
  ASSERT_EQ(s1.nodes.size(), 7u);
  for (std::uint32_t n = 0; n < 7; ++n) {
    EXPECT_EQ(s1.nodes[n].id, tr.nodes()[n].id);
    EXPECT_EQ(s1.nodes[n].rat, rats[n]);
  }
  const fs::path f_reuse = dir / "reuse.h5";
  const SinrRunStats st_reuse = run_to_file(f_reuse, tr, ch, c, rats, &s1.transmissions);
  EXPECT_EQ(validate_dataset(f_reuse.string()), std::vector<std::string>{});
  const SinrSchedule s_reuse = read_sinr_schedule(f_reuse.string());
  EXPECT_TRUE(same_transmissions(s1.transmissions, s_reuse.transmissions));
  EXPECT_EQ(st_reuse.receptions, st.receptions);
  EXPECT_EQ(st_reuse.decoded, st.decoded);
  const auto sinr1 = read_column<float>(f1, "/receptions/sinr_db", H5T_NATIVE_FLOAT);
  const auto sinr_r = read_column<float>(f_reuse, "/receptions/sinr_db", H5T_NATIVE_FLOAT);
  EXPECT_TRUE(sinr1 == sinr_r) << "the same transmissions under the same channel give the same SINRs";

  // A reused schedule naming a node the trace does not have is refused.
  std::vector<Transmission> bad = s1.transmissions;
  bad[0].node = 7;
  EXPECT_THROW(run_to_file(dir / "bad.h5", tr, ch, c, rats, &bad), std::invalid_argument);
}

TEST(RunSinr, NrOnlyRunHasNoWifiTraffic) {
  const ChannelTrace tr = e2e_trace();
  FakeChannel ch(tr, distance_gain(1e9));
  SinrConfig c = e2e_config(7);
  c.rats.enabled = "nrv2x-only";
  const auto rats = assign_rats(tr, c.rats, c.seed);
  const fs::path f = scratch_dir("sinr") / "nr.h5";
  const SinrRunStats st = run_to_file(f, tr, ch, c, rats);
  EXPECT_EQ(validate_dataset(f.string()), std::vector<std::string>{});
  const SinrSchedule s = read_sinr_schedule(f.string());
  ASSERT_FALSE(s.transmissions.empty());
  for (const auto& t : s.transmissions) {
    EXPECT_EQ(t.rat, Rat::nr_v2x);
    EXPECT_EQ(rats[t.node], Rat::nr_v2x);
  }
  EXPECT_EQ(st.receptions, 2 * st.transmissions);  // 3 NR vehicles
  for (const auto& e : st.prr_rats) EXPECT_EQ(e.rat, Rat::nr_v2x);
}
