// The SINR generator's channel trace (generators/sinr/channel_trace.cpp): from
// records, loading a channel dataset back, and load errors naming the file.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "channel_fixtures.hpp"
#include "generators/dataset/dataset_writer.hpp"
#include "generators/sinr/channel_models.hpp"
#include "generators/sinr/channel_trace.hpp"
#include "hdf5_test_util.hpp"
#include "meshkit/errors.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace raysweep::generators;
using namespace raysweep::generators::sinr;
using namespace raysweep::generators::sinr::channel_fixtures;
using raysweep::meshkit::InputError;
using raysweep::test::H5;
using raysweep::test::scratch_dir;

// ---------------------------------------------------------------------------
// ChannelTrace.

namespace {

// RSU 0 and vehicles 1, 2 over three frames; vehicle 1 leaves before the last.
std::vector<FrameRecord> trace_records() {
  std::vector<FrameRecord> out(3);
  for (std::size_t f = 0; f < 3; ++f) {
    out[f].time_s = 0.5 + 0.25 * static_cast<double>(f);  // exact in binary
    for (std::uint32_t n = 0; n < 3; ++n) {
      if (f == 2 && n == 1) continue;
      NodeState s = at(n, 10.0 * n + static_cast<double>(f), -2.0 * n, n == 0 ? 6.0 : 0.0);
      s.vx = 10.f * static_cast<float>(n), s.vy = 0.5f, s.vz = 0.f;
      s.heading_deg = 90.f + static_cast<float>(n);
      out[f].nodes.push_back(s);
    }
  }
  auto add = [](FrameRecord& f, LinkRecord l) {
    const bool in_range = !(l.flags & kLinkOutOfRange);
    l.path_count = in_range ? 1 : 0;
    l.first_delay_s = in_range ? 1e-7 : 0;
    f.links.push_back(l);
    if (in_range) {
      PathRecord p;
      p.a = {1e-4f, 0.f};
      p.tau_s = 1e-7;
      f.paths.push_back(p);
    }
  };
  add(out[0], link_rec(0, 1, -61.5f, 0));
  add(out[0], link_rec(0, 2, -83.25f, 2));
  add(out[0], link_rec(1, 2, kNoGain, 2, kLinkOutOfRange));
  add(out[1], link_rec(0, 1, -62.f, 1, kLinkCached));
  add(out[2], link_rec(0, 2, -84.f, 0));
  return out;
}

std::vector<NodeInfo> trace_nodes() {
  std::vector<NodeInfo> n(3);
  n[0].id = "rsu0", n[0].kind = NodeKind::rsu;
  n[1].id = "veh.a", n[1].vclass = "passenger", n[1].vtype = "DEFAULT_VEHTYPE";
  n[1].length_m = 4.5f, n[1].width_m = 1.8f, n[1].height_m = 1.5f;
  n[2].id = "veh.b", n[2].vclass = "truck", n[2].vtype = "lorry";
  n[2].length_m = 12.f, n[2].width_m = 2.5f, n[2].height_m = 3.75f;
  return n;
}

void write_trace(const fs::path& file, bool finish = true) {
  DatasetHeader h;
  h.raysweep_version = "test";
  h.git_hash = "unknown";
  h.seed = 1234;
  h.carrier_hz = kFc;
  h.bandwidth_hz = 20e6;
  DatasetWriter w(file, h);
  for (const auto& f : trace_records()) w.append(f);
  if (finish) w.finish(trace_nodes(), {"ground", "rsu0", "veh.a", "veh.b"});
}

void check_trace(const ChannelTrace& t) {
  ASSERT_EQ(t.frames(), 3u);
  EXPECT_EQ(t.time(1), 0.75);
  EXPECT_EQ(t.frame_step(), 0.25);
  EXPECT_EQ(t.frame_at(0.0), 0u);
  EXPECT_EQ(t.frame_at(0.5), 0u);
  EXPECT_EQ(t.frame_at(0.74), 0u);
  EXPECT_EQ(t.frame_at(0.75), 1u);
  EXPECT_EQ(t.frame_at(0.9), 1u);
  EXPECT_EQ(t.frame_at(1.0), 2u);
  EXPECT_EQ(t.frame_at(99), 2u);
  ASSERT_EQ(t.nodes().size(), 3u);
  EXPECT_EQ(t.nodes()[2].vtype, "lorry");
  EXPECT_EQ(t.nodes()[0].kind, NodeKind::rsu);
  EXPECT_FLOAT_EQ(t.nodes()[2].height_m, 3.75f);
  EXPECT_EQ(t.states_end(0) - t.states_begin(0), 3);
  EXPECT_EQ(t.states_end(2) - t.states_begin(2), 2);
  const NodeState* s = t.state(1, 2);
  ASSERT_NE(s, nullptr);
  EXPECT_DOUBLE_EQ(s->x, 21.0);
  EXPECT_DOUBLE_EQ(s->y, -4.0);
  EXPECT_FLOAT_EQ(s->vx, 20.f);
  EXPECT_FLOAT_EQ(s->heading_deg, 92.f);
  EXPECT_DOUBLE_EQ(t.state(0, 0)->z, 6.0);
  EXPECT_EQ(t.state(2, 1), nullptr);
  const ChannelTrace::Link* l = t.link(0, 2, 0);
  ASSERT_NE(l, nullptr);
  EXPECT_EQ(l, t.link(0, 0, 2));
  EXPECT_FLOAT_EQ(l->gain_db, -83.25f);
  EXPECT_EQ(l->los_class, 2);
  l = t.link(0, 2, 1);
  ASSERT_NE(l, nullptr);
  EXPECT_EQ(l->gain_db, kNoGain);
  EXPECT_EQ(l->flags, kLinkOutOfRange);
  EXPECT_EQ(t.link(1, 1, 0)->flags, kLinkCached);
  EXPECT_EQ(t.link(1, 0, 2), nullptr);
  EXPECT_EQ(t.link(2, 0, 1), nullptr);
  EXPECT_FLOAT_EQ(t.link(2, 0, 2)->gain_db, -84.f);
  EXPECT_EQ(t.carrier_hz(), kFc);
}

}  // namespace

TEST(ChannelTrace, FromRecords) {
  const ChannelTrace t = ChannelTrace::from_records(trace_nodes(), trace_records(), kFc, 20e6);
  check_trace(t);
  EXPECT_EQ(t.path(), "");

  auto bad = trace_records();
  std::swap(bad[0].links[0], bad[0].links[1]);
  EXPECT_THROW(ChannelTrace::from_records(trace_nodes(), bad, kFc, 20e6), std::invalid_argument);
  bad = trace_records();
  bad[2].links.push_back(link_rec(1, 2, -70, 0));  // node 1 is absent from frame 2
  EXPECT_THROW(ChannelTrace::from_records(trace_nodes(), bad, kFc, 20e6), std::invalid_argument);
  bad = trace_records();
  bad[2].time_s = 0.1;
  EXPECT_THROW(ChannelTrace::from_records(trace_nodes(), bad, kFc, 20e6), std::invalid_argument);
  bad = trace_records();
  std::swap(bad[1].nodes[0], bad[1].nodes[1]);
  EXPECT_THROW(ChannelTrace::from_records(trace_nodes(), bad, kFc, 20e6), std::invalid_argument);
  EXPECT_THROW(ChannelTrace::from_records(vehicles(2), trace_records(), kFc, 20e6), std::invalid_argument);
}

TEST(ChannelTrace, LoadRoundTrip) {
  const fs::path dir = scratch_dir(std::to_string(::getpid()));
  const fs::path file = dir / "trace.h5";
  write_trace(file);
  const ChannelTrace t = ChannelTrace::load(file.string());
  check_trace(t);
  EXPECT_EQ(t.path(), file.string());
  EXPECT_EQ(t.seed(), 1234u);
  EXPECT_EQ(t.bandwidth_hz(), 20e6);
  EXPECT_EQ(t.nodes()[1].id, "veh.a");
  EXPECT_EQ(t.nodes()[1].vclass, "passenger");
  // The ray model over the loaded trace.
  auto m = make_channel_model(ChannelModelKind::ray, t, StochasticOptions{});
  EXPECT_FLOAT_EQ(static_cast<float>(m->link(0, 1, 0).gain_db), -61.5f);
  EXPECT_EQ(m->link(0, 1, 2).gain_db, -std::numeric_limits<double>::infinity());
}

namespace {

// The InputError that loading `file` throws ("" when none).
std::string load_error(const fs::path& file) {
  try {
    ChannelTrace::load(file.string());
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), file.string());
    return e.what();
  }
  return "";
}

}  // namespace

TEST(ChannelTrace, LoadErrors) {
  const fs::path dir = scratch_dir(std::to_string(::getpid()));
  const fs::path text = dir / "notes.h5";
  raysweep::test::write_text(text, "not an HDF5 file\n");
  std::string e = load_error(text);
  EXPECT_NE(e.find(text.string()), std::string::npos) << e;
  EXPECT_NE(e.find("HDF5"), std::string::npos) << e;
  EXPECT_NE(load_error(dir / "missing.h5").find("missing.h5"), std::string::npos);

  const fs::path unfinished = dir / "unfinished.h5";
  write_trace(unfinished, false);
  e = load_error(unfinished);
  EXPECT_NE(e.find("incomplete"), std::string::npos) << e;
  EXPECT_NE(e.find(unfinished.string()), std::string::npos) << e;

  auto corrupt = [&](const std::string& name, auto&& edit) {
    const fs::path p = dir / name;
    write_trace(p);
    {
      H5 f{H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
      EXPECT_GE(f.id, 0);
      edit(f.id);
    }
    return load_error(p);
  };
  e = corrupt("version.h5", [](hid_t f) {
    H5Adelete(f, "schema_version");
    H5 t{H5Tcopy(H5T_C_S1), H5Tclose};
    H5Tset_size(t.id, H5T_VARIABLE);
    H5 s{H5Screate(H5S_SCALAR), H5Sclose};
    H5 a{H5Acreate2(f, "schema_version", t.id, s.id, H5P_DEFAULT, H5P_DEFAULT), H5Aclose};
    const char* v = "2.0.0";
    H5Awrite(a.id, t.id, &v);
  });
  EXPECT_NE(e.find("schema_version"), std::string::npos) << e;
  EXPECT_NE(e.find("2.0.0"), std::string::npos) << e;
  e = corrupt("norx.h5", [](hid_t f) { H5Ldelete(f, "/links/rx", H5P_DEFAULT); });
  EXPECT_NE(e.find("/links/rx"), std::string::npos) << e;
  EXPECT_NE(e.find("missing"), std::string::npos) << e;
  e = corrupt("offset.h5", [](hid_t f) {
    H5 d{H5Dopen2(f, "/frames/link_offset", H5P_DEFAULT), H5Dclose};
    H5 fs_{H5Dget_space(d.id), H5Sclose};
    const hsize_t row = 1, count = 1;
    H5Sselect_hyperslab(fs_.id, H5S_SELECT_SET, &row, nullptr, &count, nullptr);
    H5 ms{H5Screate_simple(1, &count, nullptr), H5Sclose};
    const std::uint64_t v = 2;
    H5Dwrite(d.id, H5T_NATIVE_UINT64, ms.id, fs_.id, H5P_DEFAULT, &v);
  });
  EXPECT_NE(e.find("/frames/link_offset"), std::string::npos) << e;
  e = corrupt("unsorted.h5", [](hid_t f) {  // frame 0's links become (0,2), (0,2), (1,2)
    H5 d{H5Dopen2(f, "/links/rx", H5P_DEFAULT), H5Dclose};
    H5 fs_{H5Dget_space(d.id), H5Sclose};
    const hsize_t row = 0, count = 1;
    H5Sselect_hyperslab(fs_.id, H5S_SELECT_SET, &row, nullptr, &count, nullptr);
    H5 ms{H5Screate_simple(1, &count, nullptr), H5Sclose};
    const std::uint32_t v = 2;
    H5Dwrite(d.id, H5T_NATIVE_UINT32, ms.id, fs_.id, H5P_DEFAULT, &v);
  });
  EXPECT_NE(e.find("/links"), std::string::npos) << e;
  EXPECT_NE(e.find("sorted"), std::string::npos) << e;
}
