// HDF5 channel dataset: writer round trip (read back with the HDF5 C API),
// validation of corrupt files, determinism, and the Python reader. Frame
// blocks: test_frame_block.cpp.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <complex>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "dataset_fixtures.hpp"
#include "generators/dataset/dataset_schema.hpp"
#include "generators/dataset/dataset_writer.hpp"
#include "generators/formats.hpp"
#include "hdf5_test_util.hpp"
#include "meshkit/errors.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace raysweep::generators;
using namespace raysweep::generators::fixtures;
using raysweep::meshkit::InputError;
using raysweep::test::H5;
using raysweep::test::has_attr;
using raysweep::test::num_attr;
using raysweep::test::poke_u64;
using raysweep::test::read_bytes;
using raysweep::test::read_complex;
using raysweep::test::read_ds;
using raysweep::test::read_strings;
using raysweep::test::run_command;
using raysweep::test::set_str_attr;
using raysweep::test::str_attr;
using raysweep::test::scratch_dir;
using raysweep::test::source_dir;

namespace {

void write_test_dataset(const fs::path& file, bool finish = true) {
  Builder b;
  const auto frames = b.frames();
  DatasetWriter w(file, test_header());
  for (const auto& f : frames) w.append(f);
  if (finish) w.finish(test_nodes(), test_objects());
}

bool mentions(const std::vector<std::string>& problems, const std::string& what) {
  return std::any_of(problems.begin(), problems.end(),
                     [&](const std::string& p) { return p.find(what) != std::string::npos; });
}

std::string joined(const std::vector<std::string>& problems) {
  std::string s;
  for (const auto& p : problems) s += "  " + p + "\n";
  return s;
}

// Expected flat tables, computed from the records (independently of the writer).
struct Flat {
  std::vector<double> time;
  std::vector<std::uint64_t> node_offset, link_offset, path_offset, interaction_offset;
  std::vector<std::uint32_t> node_count, link_count, link_frame;
  std::vector<NodeState> states;
  std::vector<LinkRecord> links;
  std::vector<PathRecord> paths;
  std::vector<InteractionRecord> interactions;
  std::vector<std::complex<float>> cfr;
};

Flat flatten(const std::vector<FrameRecord>& frames) {
  Flat x;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const auto& fr = frames[f];
    x.time.push_back(fr.time_s);
    x.node_offset.push_back(x.states.size());
    x.node_count.push_back(static_cast<std::uint32_t>(fr.nodes.size()));
    x.link_offset.push_back(x.links.size());
    x.link_count.push_back(static_cast<std::uint32_t>(fr.links.size()));
    x.states.insert(x.states.end(), fr.nodes.begin(), fr.nodes.end());
    for (const auto& l : fr.links) {
      x.link_frame.push_back(static_cast<std::uint32_t>(f));
      x.links.push_back(l);
    }
    x.paths.insert(x.paths.end(), fr.paths.begin(), fr.paths.end());
    x.interactions.insert(x.interactions.end(), fr.interactions.begin(), fr.interactions.end());
    x.cfr.insert(x.cfr.end(), fr.cfr.begin(), fr.cfr.end());
  }
  std::uint64_t p = 0;
  for (const auto& l : x.links) x.path_offset.push_back(p), p += l.path_count;
  std::uint64_t m = 0;
  for (const auto& q : x.paths) x.interaction_offset.push_back(m), m += q.interaction_count;
  return x;
}

}  // namespace

// ---------------------------------------------------------------------------

TEST(Dataset, RoundTripEveryField) {
  const fs::path dir = tmp_dir("roundtrip");
  const fs::path file = dir / "channels.h5";
  Builder b;
  const auto frames = b.frames();
  const Flat x = flatten(frames);
  ASSERT_EQ(x.links.size(), 6u);
  ASSERT_EQ(x.paths.size(), 9u);
  ASSERT_EQ(x.interactions.size(), 10u);
  {
    DatasetWriter w(file, test_header());
    for (const auto& f : frames) w.append(f);
    EXPECT_EQ(w.frames(), 3u);
    EXPECT_EQ(w.links(), 6u);
    EXPECT_EQ(w.paths(), 9u);
    w.finish(test_nodes(), test_objects());
  }

  // Root attributes.
  EXPECT_EQ(str_attr(file, "/", "format"), "raysweep-channels");
  EXPECT_EQ(str_attr(file, "/", "schema_version"), "1.5.0");
  EXPECT_EQ(str_attr(file, "/", "store"), "full");
  EXPECT_EQ(num_attr<std::uint32_t>(file, "/", "paths_top_k", H5T_NATIVE_UINT32), 0u);
  EXPECT_EQ(str_attr(file, "/", "raysweep_version"), "0.1.0-test");
  EXPECT_EQ(str_attr(file, "/", "git_hash"), "0123456789ab");
  EXPECT_EQ(nlohmann::json::parse(str_attr(file, "/", "config")), test_header().config);
  EXPECT_EQ(nlohmann::json::parse(str_attr(file, "/", "inputs")), test_header().inputs);
  EXPECT_EQ(nlohmann::json::parse(str_attr(file, "/", "provenance")), test_header().provenance);
  EXPECT_EQ(num_attr<std::uint64_t>(file, "/", "seed", H5T_NATIVE_UINT64), 42u);
  EXPECT_EQ(num_attr<double>(file, "/", "carrier_hz", H5T_NATIVE_DOUBLE), 5.9e9);
  EXPECT_EQ(num_attr<double>(file, "/", "bandwidth_hz", H5T_NATIVE_DOUBLE), 10e6);
  EXPECT_EQ(num_attr<std::uint64_t>(file, "/", "frame_count", H5T_NATIVE_UINT64), 3u);
  EXPECT_EQ(num_attr<std::uint64_t>(file, "/", "node_count", H5T_NATIVE_UINT64), 3u);
  EXPECT_EQ(num_attr<std::uint64_t>(file, "/", "link_count", H5T_NATIVE_UINT64), 6u);
  EXPECT_EQ(num_attr<std::uint64_t>(file, "/", "path_count", H5T_NATIVE_UINT64), 9u);
  EXPECT_EQ(num_attr<std::uint8_t>(file, "/", "complete", H5T_NATIVE_UINT8), 1u);
  EXPECT_EQ(str_attr(file, "/links/gain_coherent_db", "units"), "dB");
  EXPECT_EQ(str_attr(file, "/node_states/position", "units"), "m");
  EXPECT_FALSE(str_attr(file, "/paths/a", "description").empty());

  // /frames
  EXPECT_EQ(read_ds<double>(file, "/frames/time_s", H5T_NATIVE_DOUBLE), x.time);
  EXPECT_EQ(read_ds<std::uint64_t>(file, "/frames/node_offset", H5T_NATIVE_UINT64), (std::vector<std::uint64_t>{0, 3, 6}));
  EXPECT_EQ(read_ds<std::uint32_t>(file, "/frames/node_count", H5T_NATIVE_UINT32), (std::vector<std::uint32_t>{3, 3, 2}));
  EXPECT_EQ(read_ds<std::uint64_t>(file, "/frames/link_offset", H5T_NATIVE_UINT64), (std::vector<std::uint64_t>{0, 3, 5}));
  EXPECT_EQ(read_ds<std::uint32_t>(file, "/frames/link_count", H5T_NATIVE_UINT32), (std::vector<std::uint32_t>{3, 2, 1}));

  // /node_states
  std::vector<hsize_t> dims;
  const auto node = read_ds<std::uint32_t>(file, "/node_states/node", H5T_NATIVE_UINT32);
  const auto pos = read_ds<double>(file, "/node_states/position", H5T_NATIVE_DOUBLE, &dims);
  EXPECT_EQ(dims, (std::vector<hsize_t>{8, 3}));
  const auto vel = read_ds<float>(file, "/node_states/velocity", H5T_NATIVE_FLOAT, &dims);
  EXPECT_EQ(dims, (std::vector<hsize_t>{8, 3}));
  const auto heading = read_ds<float>(file, "/node_states/heading_deg", H5T_NATIVE_FLOAT);
  ASSERT_EQ(node.size(), 8u);
  for (std::size_t i = 0; i < 8; ++i) {
    const auto& s = x.states[i];
    EXPECT_EQ(node[i], s.node);
    EXPECT_EQ(pos[3 * i + 0], s.x);
    EXPECT_EQ(pos[3 * i + 1], s.y);
    EXPECT_EQ(pos[3 * i + 2], s.z);
    EXPECT_EQ(vel[3 * i + 0], s.vx);
    EXPECT_EQ(vel[3 * i + 1], s.vy);
    EXPECT_EQ(vel[3 * i + 2], s.vz);
    EXPECT_EQ(heading[i], s.heading_deg);
  }
  EXPECT_EQ(node, (std::vector<std::uint32_t>{0, 1, 2, 0, 1, 2, 0, 2}));

  // /nodes, /objects
  EXPECT_EQ(read_strings(file, "/nodes/id"), (std::vector<std::string>{"rsu0", "veh.a", "veh.b"}));
  EXPECT_EQ(read_ds<std::uint8_t>(file, "/nodes/kind", H5T_NATIVE_UINT8), (std::vector<std::uint8_t>{1, 0, 0}));
  EXPECT_EQ(read_strings(file, "/nodes/vclass"), (std::vector<std::string>{"", "passenger", "truck"}));
  EXPECT_EQ(read_strings(file, "/nodes/vtype"), (std::vector<std::string>{"", "DEFAULT_VEHTYPE", "lorry"}));
  EXPECT_EQ(read_ds<float>(file, "/nodes/dimensions", H5T_NATIVE_FLOAT, &dims),
            (std::vector<float>{0, 0, 0, 4.5f, 1.8f, 1.5f, 12.f, 2.5f, 3.75f}));
  EXPECT_EQ(dims, (std::vector<hsize_t>{3, 3}));
  EXPECT_EQ(read_strings(file, "/objects/name"), test_objects());

  // /links
  const auto frame = read_ds<std::uint32_t>(file, "/links/frame", H5T_NATIVE_UINT32);
  const auto tx = read_ds<std::uint32_t>(file, "/links/tx", H5T_NATIVE_UINT32);
  const auto rx = read_ds<std::uint32_t>(file, "/links/rx", H5T_NATIVE_UINT32);
  const auto los = read_ds<std::uint8_t>(file, "/links/los_class", H5T_NATIVE_UINT8);
  const auto flags = read_ds<std::uint8_t>(file, "/links/flags", H5T_NATIVE_UINT8);
  const auto blockers = read_ds<std::uint16_t>(file, "/links/blocker_count", H5T_NATIVE_UINT16);
  const auto gc = read_ds<float>(file, "/links/gain_coherent_db", H5T_NATIVE_FLOAT);
  const auto gi = read_ds<float>(file, "/links/gain_incoherent_db", H5T_NATIVE_FLOAT);
  const auto fd = read_ds<double>(file, "/links/first_delay_s", H5T_NATIVE_DOUBLE);
  const auto rms = read_ds<float>(file, "/links/rms_delay_spread_s", H5T_NATIVE_FLOAT);
  const auto pc = read_ds<std::uint32_t>(file, "/links/path_count", H5T_NATIVE_UINT32);
  const auto po = read_ds<std::uint64_t>(file, "/links/path_offset", H5T_NATIVE_UINT64);
  const auto below = read_ds<std::uint32_t>(file, "/links/paths_below_threshold", H5T_NATIVE_UINT32);
  const auto zone = read_ds<std::uint8_t>(file, "/links/los_class_fresnel", H5T_NATIVE_UINT8);
  const auto clearance = read_ds<float>(file, "/links/fresnel_clearance", H5T_NATIVE_FLOAT);
  const auto vehicle_loss = read_ds<float>(file, "/links/vehicle_loss_db", H5T_NATIVE_FLOAT);
  const auto beyond = read_ds<std::uint32_t>(file, "/links/paths_beyond_top_k", H5T_NATIVE_UINT32);
  const auto diffuse = read_ds<float>(file, "/links/diffuse_gain_db", H5T_NATIVE_FLOAT);
  const auto k_factor = read_ds<float>(file, "/links/k_factor_db", H5T_NATIVE_FLOAT);
  const auto doppler_spread = read_ds<float>(file, "/links/rms_doppler_spread_hz", H5T_NATIVE_FLOAT);
  const auto aod_spread = read_ds<float>(file, "/links/aod_spread_rad", H5T_NATIVE_FLOAT);
  const auto aoa_spread = read_ds<float>(file, "/links/aoa_spread_rad", H5T_NATIVE_FLOAT);
  const auto excess = read_ds<float>(file, "/links/strongest_excess_delay_s", H5T_NATIVE_FLOAT);
  const auto s_aod = read_ds<float>(file, "/links/strongest_aod", H5T_NATIVE_FLOAT);
  const auto s_aoa = read_ds<float>(file, "/links/strongest_aoa", H5T_NATIVE_FLOAT, &dims);
  EXPECT_EQ(dims, (std::vector<hsize_t>{6, 2}));
  ASSERT_EQ(tx.size(), 6u);
  EXPECT_EQ(frame, x.link_frame);
  EXPECT_EQ(frame, (std::vector<std::uint32_t>{0, 0, 0, 1, 1, 2}));
  EXPECT_EQ(pc, (std::vector<std::uint32_t>{1, 3, 0, 1, 3, 1}));
  EXPECT_EQ(po, (std::vector<std::uint64_t>{0, 1, 4, 4, 5, 8}));
  for (std::size_t i = 0; i < 6; ++i) {
    const auto& l = x.links[i];
    EXPECT_EQ(tx[i], l.tx);
    EXPECT_EQ(rx[i], l.rx);
    EXPECT_EQ(los[i], l.los_class);
    EXPECT_EQ(flags[i], l.flags);
    EXPECT_EQ(blockers[i], l.blocker_count);
    EXPECT_EQ(gc[i], l.gain_coherent_db);
    EXPECT_EQ(gi[i], l.gain_incoherent_db);
    EXPECT_EQ(fd[i], l.first_delay_s);
    EXPECT_EQ(rms[i], l.rms_delay_spread_s);
    EXPECT_EQ(pc[i], l.path_count);
    EXPECT_EQ(po[i], x.path_offset[i]);
    EXPECT_EQ(below[i], l.paths_below_threshold);
    EXPECT_EQ(zone[i], l.los_class_fresnel);
    EXPECT_EQ(clearance[i], l.fresnel_clearance);
    EXPECT_EQ(vehicle_loss[i], l.vehicle_loss_db);
    EXPECT_EQ(beyond[i], 0u);
    EXPECT_EQ(diffuse[i], l.diffuse_gain_db);
    EXPECT_EQ(k_factor[i], l.k_factor_db);
    EXPECT_EQ(doppler_spread[i], l.rms_doppler_spread_hz);
    EXPECT_EQ(excess[i], l.strongest_excess_delay_s);
    for (int k = 0; k < 2; ++k) {
      EXPECT_EQ(aod_spread[2 * i + k], l.aod_spread[k]);
      EXPECT_EQ(aoa_spread[2 * i + k], l.aoa_spread[k]);
      EXPECT_EQ(s_aod[2 * i + k], l.strongest_aod[k]);
      EXPECT_EQ(s_aoa[2 * i + k], l.strongest_aoa[k]);
    }
  }
  EXPECT_TRUE(std::isinf(gc[2]) && gc[2] < 0);
  EXPECT_EQ(flags[2], kLinkOutOfRange);
  EXPECT_EQ(flags[3], kLinkCached);

  // /paths
  const auto a = read_complex(file, "/paths/a");
  const auto tau = read_ds<double>(file, "/paths/tau_s", H5T_NATIVE_DOUBLE);
  const auto aod = read_ds<float>(file, "/paths/aod", H5T_NATIVE_FLOAT, &dims);
  EXPECT_EQ(dims, (std::vector<hsize_t>{9, 2}));
  const auto aoa = read_ds<float>(file, "/paths/aoa", H5T_NATIVE_FLOAT);
  const auto dop = read_ds<float>(file, "/paths/doppler_hz", H5T_NATIVE_FLOAT);
  const auto ic = read_ds<std::uint8_t>(file, "/paths/interaction_count", H5T_NATIVE_UINT8);
  const auto io = read_ds<std::uint64_t>(file, "/paths/interaction_offset", H5T_NATIVE_UINT64);
  ASSERT_EQ(a.size(), 9u);
  EXPECT_EQ(ic, (std::vector<std::uint8_t>{0, 1, 2, 0, 1, 2, 0, 1, 3}));
  EXPECT_EQ(io, (std::vector<std::uint64_t>{0, 0, 1, 3, 3, 4, 6, 6, 7}));
  for (std::size_t j = 0; j < 9; ++j) {
    const auto& p = x.paths[j];
    EXPECT_EQ(a[j], p.a);
    EXPECT_EQ(tau[j], p.tau_s);
    EXPECT_EQ(aod[2 * j], p.theta_t);
    EXPECT_EQ(aod[2 * j + 1], p.phi_t);
    EXPECT_EQ(aoa[2 * j], p.theta_r);
    EXPECT_EQ(aoa[2 * j + 1], p.phi_r);
    EXPECT_EQ(dop[j], p.doppler_hz);
    EXPECT_EQ(ic[j], p.interaction_count);
    EXPECT_EQ(io[j], x.interaction_offset[j]);
  }

  // /interactions
  const auto type = read_ds<std::uint8_t>(file, "/interactions/type", H5T_NATIVE_UINT8);
  const auto object = read_ds<std::uint32_t>(file, "/interactions/object", H5T_NATIVE_UINT32);
  const auto point = read_ds<float>(file, "/interactions/point", H5T_NATIVE_FLOAT, &dims);
  EXPECT_EQ(dims, (std::vector<hsize_t>{10, 3}));
  EXPECT_EQ(object, (std::vector<std::uint32_t>{0, 1, 2, 4, 5, 0, 2, 0, 1, 2}));
  ASSERT_EQ(type.size(), 10u);
  for (std::size_t m = 0; m < 10; ++m) {
    EXPECT_EQ(type[m], x.interactions[m].type);
    EXPECT_EQ(type[m], 1 + m % 4);
    EXPECT_EQ(point[3 * m + 0], static_cast<float>(m));
    EXPECT_EQ(point[3 * m + 1], 2.f * static_cast<float>(m));
    EXPECT_EQ(point[3 * m + 2], 0.5f * static_cast<float>(m));
  }

  // /cfr
  const auto h = read_complex(file, "/cfr/h", &dims);
  EXPECT_EQ(dims, (std::vector<hsize_t>{6, kK}));
  EXPECT_EQ(h, x.cfr);
  EXPECT_EQ(h[5 * kK + 3], std::complex<float>(53.f, -1.5f));
  EXPECT_EQ(num_attr<std::uint32_t>(file, "/cfr", "subcarriers", H5T_NATIVE_UINT32), kK);
  EXPECT_EQ(num_attr<double>(file, "/cfr", "subcarrier_spacing_hz", H5T_NATIVE_DOUBLE), 156250.0);
  EXPECT_EQ(num_attr<double>(file, "/cfr", "carrier_hz", H5T_NATIVE_DOUBLE), 5.9e9);

  // Storage: chunked along the first axis, shuffle + deflate, extendible.
  {
    H5 f{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
    H5 d{H5Dopen2(f.id, "/paths/aod", H5P_DEFAULT), H5Dclose};
    H5 plist{H5Dget_create_plist(d.id), H5Pclose};
    EXPECT_EQ(H5Pget_layout(plist.id), H5D_CHUNKED);
    hsize_t chunk[2] = {0, 0};
    EXPECT_EQ(H5Pget_chunk(plist.id, 2, chunk), 2);
    EXPECT_EQ(chunk[0], 16384u);
    EXPECT_EQ(chunk[1], 2u);
    ASSERT_EQ(H5Pget_nfilters(plist.id), 2);
    EXPECT_EQ(H5Pget_filter2(plist.id, 0, nullptr, nullptr, nullptr, 0, nullptr, nullptr), H5Z_FILTER_SHUFFLE);
    EXPECT_EQ(H5Pget_filter2(plist.id, 1, nullptr, nullptr, nullptr, 0, nullptr, nullptr), H5Z_FILTER_DEFLATE);
    H5 s{H5Dget_space(d.id), H5Sclose};
    hsize_t cur[2], max[2];
    H5Sget_simple_extent_dims(s.id, cur, max);
    EXPECT_EQ(max[0], H5S_UNLIMITED);
  }

  const auto problems = validate_dataset(file.string());
  EXPECT_TRUE(problems.empty()) << joined(problems);

  const auto info = dataset_info(file.string());
  EXPECT_EQ(info["schema_version"], "1.5.0");
  EXPECT_EQ(info["store"], "full");
  EXPECT_EQ(info["raysweep_version"], "0.1.0-test");
  EXPECT_EQ(info["frames"], 3);
  EXPECT_EQ(info["time_start_s"], 0.0);
  EXPECT_EQ(info["time_end_s"], 0.2);
  EXPECT_EQ(info["nodes"], 3);
  EXPECT_EQ(info["vehicles"], 2);
  EXPECT_EQ(info["rsus"], 1);
  EXPECT_EQ(info["links"], 6);
  EXPECT_EQ(info["paths"], 9);
  EXPECT_EQ(info["interactions"], 10);
  EXPECT_EQ(info["objects"], 6);
  EXPECT_EQ(info["los_counts"]["LOS"], 2);
  EXPECT_EQ(info["los_counts"]["NLOSV"], 2);
  EXPECT_EQ(info["los_counts"]["NLOS"], 2);
  EXPECT_EQ(info["cached_links"], 1);
  EXPECT_EQ(info["out_of_range_links"], 1);
  EXPECT_DOUBLE_EQ(info["mean_paths_per_link"].get<double>(), 9.0 / 6.0);
  EXPECT_DOUBLE_EQ(info["mean_paths_per_in_range_link"].get<double>(), 9.0 / 5.0);
  EXPECT_EQ(info["has_cfr"], true);
  EXPECT_EQ(info["subcarriers"], kK);
  EXPECT_EQ(info["complete"], true);
  EXPECT_EQ(info["file_bytes"].get<std::uint64_t>(), fs::file_size(file));
  EXPECT_DOUBLE_EQ(info["bytes_per_link"].get<double>(), static_cast<double>(fs::file_size(file)) / 6.0);
  const std::string text = format_dataset_info(info);
  EXPECT_NE(text.find("frames        3"), std::string::npos) << text;
  EXPECT_NE(text.find("2 vehicles, 1 RSUs"), std::string::npos) << text;
  EXPECT_NE(text.find("NLOSV 2 (33.3 %)"), std::string::npos) << text;
}

TEST(Dataset, NoCfrGroupWithoutSubcarriers) {
  const fs::path file = tmp_dir("nocfr") / "channels.h5";
  Builder b;
  auto frames = b.frames();
  DatasetHeader h = test_header();
  h.cfr_subcarriers = 0;
  {
    DatasetWriter w(file, h);
    for (auto& f : frames) {
      f.cfr.clear();
      w.append(f);
    }
    w.finish(test_nodes(), test_objects());
  }
  H5 f{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  EXPECT_LE(H5Lexists(f.id, "cfr", H5P_DEFAULT), 0);
  EXPECT_TRUE(validate_dataset(file.string()).empty()) << joined(validate_dataset(file.string()));
  EXPECT_EQ(dataset_info(file.string())["has_cfr"], false);
}

TEST(Dataset, WriterRejectsInconsistentRecords) {
  const fs::path dir = tmp_dir("reject");
  Builder b;
  const auto good = b.frames();
  DatasetWriter w(dir / "x.h5", test_header());
  auto expect_reject = [&](FrameRecord f, const char* what) {
    EXPECT_THROW(w.append(f), std::invalid_argument) << what;
  };
  {
    auto f = good[0];
    f.links[0].path_count = 2;  // sums to 5, the frame has 4 paths
    expect_reject(f, "path count sum");
  }
  {
    auto f = good[0];
    f.paths[0].interaction_count = 1;
    expect_reject(f, "interaction count sum");
  }
  {
    auto f = good[0];
    f.cfr.pop_back();
    expect_reject(f, "cfr size");
  }
  {
    auto f = good[0];
    std::swap(f.links[0], f.links[1]);  // (0,2) before (0,1)
    expect_reject(f, "links not sorted");
  }
  {
    auto f = good[0];
    std::swap(f.links[2].tx, f.links[2].rx);
    expect_reject(f, "tx > rx");
  }
  {
    auto f = good[2];
    f.links[0].tx = 1;  // node 1 is absent from frame 2
    f.links[0].rx = 2;
    expect_reject(f, "absent node");
  }
  {
    auto f = good[0];
    std::swap(f.nodes[0], f.nodes[1]);
    expect_reject(f, "node states unsorted");
  }
  {
    auto f = good[0];
    f.links[0].los_class = 3;
    expect_reject(f, "los class");
  }
  EXPECT_EQ(w.frames(), 0u);  // nothing was appended
  w.append(good[0]);
  EXPECT_EQ(w.frames(), 1u);
  {
    auto f = good[1];
    f.time_s = -1;
    expect_reject(f, "time going backwards");
  }
  // finish() checks the tables cover every node and object used.
  EXPECT_THROW(w.finish(std::vector<NodeInfo>(2), test_objects()), std::invalid_argument);
  EXPECT_THROW(w.finish(test_nodes(), {"a", "b"}), std::invalid_argument);
  w.finish(test_nodes(), test_objects());
  EXPECT_THROW(w.append(good[1]), std::runtime_error);
  EXPECT_TRUE(validate_dataset((dir / "x.h5").string()).empty());
}

TEST(Dataset, CorruptFilesAreRejected) {
  const fs::path dir = tmp_dir("corrupt");
  const fs::path good = dir / "good.h5";
  write_test_dataset(good);
  ASSERT_TRUE(validate_dataset(good.string()).empty()) << joined(validate_dataset(good.string()));
  auto copy = [&](const std::string& name) {
    const fs::path p = dir / name;
    fs::copy_file(good, p, fs::copy_options::overwrite_existing);
    return p;
  };

  {  // (a) a LoS class outside the code table
    const fs::path p = copy("los7.h5");
    poke_u64(p, "/links/los_class", 1, 7);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/links/los_class")) << joined(problems);
  }
  {  // (b) a missing dataset
    const fs::path p = copy("notau.h5");
    {
      H5 f{H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
      ASSERT_GE(H5Ldelete(f.id, "/paths/tau_s", H5P_DEFAULT), 0);
    }
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/paths/tau_s")) << joined(problems);
  }
  {  // (b2) a column added in 1.1.0: required from 1.1.0 on, not in a 1.0.0 file
    const fs::path p = copy("nobelow.h5");
    {
      H5 f{H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
      ASSERT_GE(H5Ldelete(f.id, "/links/paths_below_threshold", H5P_DEFAULT), 0);
    }
    EXPECT_TRUE(mentions(validate_dataset(p.string()), "/links/paths_below_threshold"));
    set_str_attr(p, "schema_version", "1.0.0");
    EXPECT_TRUE(validate_dataset(p.string()).empty()) << joined(validate_dataset(p.string()));
  }
  {  // (b3) the Fresnel label, added in 1.2.0: a 1.1.0 file without it validates
    const fs::path p = copy("nofresnel.h5");
    {
      H5 f{H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
      ASSERT_GE(H5Ldelete(f.id, "/links/los_class_fresnel", H5P_DEFAULT), 0);
      ASSERT_GE(H5Ldelete(f.id, "/links/fresnel_clearance", H5P_DEFAULT), 0);
    }
    EXPECT_TRUE(mentions(validate_dataset(p.string()), "/links/los_class_fresnel"));
    set_str_attr(p, "schema_version", "1.1.0");
    EXPECT_TRUE(validate_dataset(p.string()).empty()) << joined(validate_dataset(p.string()));
  }
  {  // (b4) the vehicles' knife-edge loss, added in 1.3.0: a 1.2.0 file without it validates
    const fs::path p = copy("novehicleloss.h5");
    {
      H5 f{H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
      ASSERT_GE(H5Ldelete(f.id, "/links/vehicle_loss_db", H5P_DEFAULT), 0);
    }
    EXPECT_TRUE(mentions(validate_dataset(p.string()), "/links/vehicle_loss_db"));
    set_str_attr(p, "schema_version", "1.2.0");
    EXPECT_TRUE(validate_dataset(p.string()).empty()) << joined(validate_dataset(p.string()));
  }
  {  // (c) an unsupported major version
    const fs::path p = copy("v2.h5");
    set_str_attr(p, "schema_version", "2.0.0");
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "schema_version")) << joined(problems);
    EXPECT_TRUE(mentions(problems, "major version 2")) << joined(problems);
  }
  {  // (d) a path offset that is not the running sum of path counts
    const fs::path p = copy("offset.h5");
    poke_u64(p, "/links/path_offset", 2, 5);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/links/path_offset")) << joined(problems);
  }
  {  // (e) a truncated file
    const fs::path p = dir / "truncated.h5";
    const std::string bytes = read_bytes(good);
    write_bytes(p, bytes.substr(0, bytes.size() / 2));
    const auto problems = validate_dataset(p.string());
    ASSERT_FALSE(problems.empty());
    EXPECT_TRUE(mentions(problems, p.string())) << joined(problems);
    EXPECT_THROW(dataset_info(p.string()), InputError);
  }
  {  // (f) a file whose writer never finished
    const fs::path p = dir / "unfinished.h5";
    write_test_dataset(p, /*finish=*/false);
    EXPECT_FALSE(has_attr(p, "complete"));
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "complete")) << joined(problems);
    // The frames written so far are there and readable.
    EXPECT_EQ(read_ds<double>(p, "/frames/time_s", H5T_NATIVE_DOUBLE).size(), 3u);
    EXPECT_EQ(dataset_info(p.string())["complete"], false);
  }
  {  // more: a wrong root count, a node reference out of range, a frame index off its range
    const fs::path p = copy("more.h5");
    poke_u64(p, "/node_states/node", 7, 9);
    poke_u64(p, "/links/frame", 4, 2);
    poke_u64(p, "/interactions/type", 0, 0);
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/node_states/node")) << joined(problems);
    EXPECT_TRUE(mentions(problems, "/links/frame")) << joined(problems);
    EXPECT_TRUE(mentions(problems, "/interactions/type")) << joined(problems);
  }
  {  // not HDF5 at all, and a missing file: one problem naming the path
    const fs::path p = dir / "text.h5";
    write_bytes(p, "hello, not a dataset\n");
    auto problems = validate_dataset(p.string());
    ASSERT_EQ(problems.size(), 1u);
    EXPECT_TRUE(mentions(problems, p.string()));
    problems = validate_dataset((dir / "absent.h5").string());
    ASSERT_EQ(problems.size(), 1u);
    EXPECT_TRUE(mentions(problems, "absent.h5"));
    try {
      dataset_info((dir / "absent.h5").string());
      ADD_FAILURE() << "dataset_info accepted a missing file";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), (dir / "absent.h5").string());
    }
  }
}

// Same records, same header -> byte-identical files: object time stamps are
// disabled and the writer's sequence of HDF5 calls is a function of the input.
TEST(Dataset, DeterministicBytes) {
  const fs::path dir = tmp_dir("determinism");
  write_test_dataset(dir / "a.h5");
  write_test_dataset(dir / "b.h5");
  const std::string a = read_bytes(dir / "a.h5"), b = read_bytes(dir / "b.h5");
  ASSERT_FALSE(a.empty());
  EXPECT_EQ(a.size(), b.size());
  EXPECT_TRUE(a == b) << "files differ";
}

namespace {

// One frame of two nodes and their one link with `paths` paths (the caller
// adds them), every subcarrier's response `h`.
FrameRecord one_link_frame(double time_s, std::uint32_t paths, float gain_db, std::complex<float> h) {
  Builder b;
  FrameRecord f;
  f.time_s = time_s;
  f.nodes = {b.state(0, time_s), b.state(1, time_s)};
  LinkRecord l;
  l.tx = 0;
  l.rx = 1;
  l.path_count = paths;
  l.gain_coherent_db = l.gain_incoherent_db = gain_db;
  f.links = {l};
  f.cfr.assign(kK, h);
  return f;
}

}  // namespace

// A frame large enough that the writer compresses whole chunks itself, in
// parallel (shuffle + deflate handed to H5Dwrite_chunk): HDF5 reads every value
// back through its own filters, the chunks say both filters ran, and the bytes
// do not depend on the thread count.
TEST(Dataset, ChunksCompressedInParallelReadBackExactly) {
  const fs::path dir = tmp_dir("parallel-chunks");
  constexpr std::uint32_t kPaths = 70000, kPer = 3;  // 210,000 interactions: 2.5 MB of points
  FrameRecord f = one_link_frame(1.0, kPaths, -80.f, {0.5f, -0.25f});
  for (std::uint32_t p = 0; p < kPaths; ++p) {
    PathRecord r;
    r.a = {std::sin(0.001f * static_cast<float>(p)), 1e-6f * static_cast<float>(p % 977)};
    r.tau_s = 1e-7 + 1e-12 * p;
    r.doppler_hz = static_cast<float>(p % 301) - 150.f;
    r.interaction_count = kPer;
    f.paths.push_back(r);
    for (std::uint32_t k = 0; k < kPer; ++k) {
      InteractionRecord in;
      in.type = static_cast<std::uint8_t>(1 + (p + k) % 4);
      in.object = (p * 7 + k) % 6;
      in.x = 0.5f * static_cast<float>(p % 1000);
      in.y = -static_cast<float>(k);
      in.z = 1e-3f * static_cast<float>(p);
      f.interactions.push_back(in);
    }
  }
  auto write = [&](const fs::path& file, int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    DatasetWriter w(file, test_header());
    w.append(f);
    w.finish(test_nodes(), test_objects());
  };
  write(dir / "one.h5", 1);
  write(dir / "two.h5", 2);
  const std::string one = read_bytes(dir / "one.h5");
  EXPECT_TRUE(one == read_bytes(dir / "two.h5")) << "bytes depend on the thread count";

  const fs::path file = dir / "two.h5";
  const auto a = read_complex(file, "/paths/a");
  const auto tau = read_ds<double>(file, "/paths/tau_s", H5T_NATIVE_DOUBLE);
  const auto dop = read_ds<float>(file, "/paths/doppler_hz", H5T_NATIVE_FLOAT);
  const auto type = read_ds<std::uint8_t>(file, "/interactions/type", H5T_NATIVE_UINT8);
  const auto object = read_ds<std::uint32_t>(file, "/interactions/object", H5T_NATIVE_UINT32);
  std::vector<hsize_t> dims;
  const auto point = read_ds<float>(file, "/interactions/point", H5T_NATIVE_FLOAT, &dims);
  ASSERT_EQ(a.size(), kPaths);
  ASSERT_EQ(tau.size(), kPaths);
  ASSERT_EQ(dop.size(), kPaths);
  ASSERT_EQ(type.size(), kPaths * kPer);
  ASSERT_EQ(object.size(), kPaths * kPer);
  ASSERT_EQ(point.size(), 3u * kPaths * kPer);
  std::size_t wrong = 0;
  for (std::uint32_t p = 0; p < kPaths; ++p) {
    wrong += a[p] != f.paths[p].a || tau[p] != f.paths[p].tau_s || dop[p] != f.paths[p].doppler_hz;
    for (std::uint32_t k = 0; k < kPer; ++k) {
      const std::size_t m = p * kPer + k;
      const auto& in = f.interactions[m];
      wrong += type[m] != in.type || object[m] != in.object || point[3 * m] != in.x || point[3 * m + 1] != in.y ||
               point[3 * m + 2] != in.z;
    }
  }
  EXPECT_EQ(wrong, 0u);

  // Chunk 1 of the points (rows 16384..32767) went through both filters and shrank.
  H5 h{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  H5 d{H5Dopen2(h.id, "/interactions/point", H5P_DEFAULT), H5Dclose};
  const hsize_t offset[2] = {16384, 0};
  unsigned mask = 1;
  haddr_t addr = 0;
  hsize_t size = 0;
  ASSERT_GE(H5Dget_chunk_info_by_coord(d.id, offset, &mask, &addr, &size), 0);
  EXPECT_EQ(mask, 0u);
  EXPECT_GT(size, 0u);
  EXPECT_LT(size, 16384u * 3 * sizeof(float));
}

// A one-frame file whose writer is told the rows it will hold (a trace's
// --out X.h5): chunks of those rows rounded up to 1,024, never more than the
// schema's, and the same values as a file with the schema's chunks.
TEST(Dataset, ExpectedRowsSizeTheChunksAndChangeNoValue) {
  const fs::path dir = tmp_dir("expected-rows");
  constexpr std::uint32_t kPaths = 1500;
  FrameRecord f = one_link_frame(0.5, kPaths, -90.f, {0.25f, 0.5f});
  for (std::uint32_t p = 0; p < kPaths; ++p) {
    PathRecord r;
    r.a = {1e-5f * static_cast<float>(p % 97), -1e-6f * static_cast<float>(p)};
    r.tau_s = 2e-7 + 1e-11 * p;
    r.interaction_count = 1;
    f.paths.push_back(r);
    InteractionRecord in;
    in.type = 1;
    in.object = p % 6;
    in.x = static_cast<float>(p);
    f.interactions.push_back(in);
  }
  auto write = [&](const fs::path& file, bool sized) {
    DatasetHeader h = test_header();
    if (sized) h.expected_rows = {{"F", 1}, {"S", 2}, {"L", 1}, {"P", kPaths}, {"I", kPaths}};
    DatasetWriter w(file, h);
    w.append(f);
    w.finish(test_nodes(), test_objects());
  };
  write(dir / "schema.h5", false);
  write(dir / "sized.h5", true);
  auto chunk_rows = [](const fs::path& file, const char* ds) {
    H5 h{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
    H5 d{H5Dopen2(h.id, ds, H5P_DEFAULT), H5Dclose};
    H5 plist{H5Dget_create_plist(d.id), H5Pclose};
    hsize_t chunk[2] = {0, 0};
    H5Pget_chunk(plist.id, 2, chunk);
    return chunk[0];
  };
  EXPECT_EQ(chunk_rows(dir / "schema.h5", "/paths/tau_s"), 16384u);
  EXPECT_EQ(chunk_rows(dir / "sized.h5", "/paths/tau_s"), 2048u);
  EXPECT_EQ(chunk_rows(dir / "sized.h5", "/interactions/point"), 2048u);
  EXPECT_EQ(chunk_rows(dir / "sized.h5", "/links/tx"), 1024u);
  EXPECT_EQ(chunk_rows(dir / "sized.h5", "/node_states/position"), 1024u);
  EXPECT_EQ(chunk_rows(dir / "sized.h5", "/cfr/h"), 256u);  // the schema's is smaller
  EXPECT_TRUE(validate_dataset((dir / "sized.h5").string()).empty());
  for (const char* ds : {"/paths/tau_s", "/links/gain_coherent_db"})
    EXPECT_EQ(read_ds<double>(dir / "sized.h5", ds, H5T_NATIVE_DOUBLE),
              read_ds<double>(dir / "schema.h5", ds, H5T_NATIVE_DOUBLE))
        << ds;
  EXPECT_EQ(read_complex(dir / "sized.h5", "/paths/a"), read_complex(dir / "schema.h5", "/paths/a"));
  EXPECT_EQ(read_ds<float>(dir / "sized.h5", "/interactions/point", H5T_NATIVE_FLOAT),
            read_ds<float>(dir / "schema.h5", "/interactions/point", H5T_NATIVE_FLOAT));
  EXPECT_EQ(read_complex(dir / "sized.h5", "/cfr/h"), read_complex(dir / "schema.h5", "/cfr/h"));
}

TEST(Dataset, EmbeddedSchemaMatchesSourceFile) {
  const std::string on_disk = read_bytes(source_dir() / "schemas" / "raysweep_dataset.schema.json");
  EXPECT_EQ(dataset_schema_json(), on_disk);
  EXPECT_EQ(dataset_schema().at("schema_version"), kDatasetSchemaVersion);
  EXPECT_EQ(dataset_schema().at("format"), kDatasetFormat);
}

// ---------------------------------------------------------------------------
// Python reader.

TEST(Dataset, PythonReader) {
  if (run_command("/usr/bin/python3 -c 'import h5py, numpy'").exit_code != 0)
    GTEST_SKIP() << "/usr/bin/python3 cannot import h5py";
  const fs::path dir = tmp_dir("python");
  const fs::path file = dir / "channels.h5";
  write_test_dataset(file);
  Builder b;
  const auto frames = b.frames();
  const Flat x = flatten(frames);

  // Expected values for the script, from the records.
  auto gain = [](float g) { return std::isinf(g) ? nlohmann::json(nullptr) : nlohmann::json(g); };
  nlohmann::json e;
  e["frames"] = 3;
  e["links"] = 6;
  e["paths"] = 9;
  e["times"] = x.time;
  e["node_ids"] = {"rsu0", "veh.a", "veh.b"};
  e["node_kinds"] = {1, 0, 0};
  e["vclasses"] = {"", "passenger", "truck"};
  e["config"] = test_header().config;
  e["seed"] = 42;
  e["frame_node_counts"] = x.node_count;
  e["frame_link_counts"] = x.link_count;
  // Pair (veh.b, rsu0) = nodes (0, 2): links 1 (frame 0) and 5 (frame 2).
  nlohmann::json pair;
  pair["a"] = "veh.b";
  pair["b"] = "rsu0";
  for (std::size_t i = 0; i < x.links.size(); ++i) {
    if (x.links[i].tx != 0 || x.links[i].rx != 2) continue;
    pair["link"].push_back(i);
    pair["frame"].push_back(x.link_frame[i]);
    pair["time_s"].push_back(x.time[x.link_frame[i]]);
    pair["los_class"].push_back(x.links[i].los_class);
    pair["gain_coherent_db"].push_back(gain(x.links[i].gain_coherent_db));
    pair["path_count"].push_back(x.links[i].path_count);
    pair["first_delay_s"].push_back(x.links[i].first_delay_s);
  }
  e["pair"] = pair;
  // Paths of link 4: paths 5..7.
  nlohmann::json paths;
  paths["link"] = 4;
  for (std::size_t j = x.path_offset[4]; j < x.path_offset[4] + x.links[4].path_count; ++j) {
    const auto& p = x.paths[j];
    paths["a_re"].push_back(p.a.real());
    paths["a_im"].push_back(p.a.imag());
    paths["tau_s"].push_back(p.tau_s);
    paths["aod"].push_back({p.theta_t, p.phi_t});
    paths["doppler_hz"].push_back(p.doppler_hz);
    nlohmann::json its = nlohmann::json::array();
    for (std::uint64_t m = x.interaction_offset[j]; m < x.interaction_offset[j] + p.interaction_count; ++m)
      its.push_back({x.interactions[m].type, x.interactions[m].object,
                     {x.interactions[m].x, x.interactions[m].y, x.interactions[m].z}});
    paths["interactions"].push_back(its);
  }
  e["paths_of_link"] = paths;
  e["out_of_range_link"] = 2;
  e["cfr_link"] = 5;
  for (std::uint32_t k = 0; k < kK; ++k) {
    e["cfr_re"].push_back(x.cfr[5 * kK + k].real());
    e["cfr_im"].push_back(x.cfr[5 * kK + k].imag());
  }
  // LinkDataset: labels are the LoS classes; distance of link 0 (rsu0-veh.a in frame 0).
  for (const auto& l : x.links) e["labels"].push_back(l.los_class);
  const auto& s0 = frames[0].nodes[0];
  const auto& s1 = frames[0].nodes[1];
  e["distance_link0"] = std::sqrt((s0.x - s1.x) * (s0.x - s1.x) + (s0.y - s1.y) * (s0.y - s1.y) + (s0.z - s1.z) * (s0.z - s1.z));
  const fs::path expected = dir / "expected.json";
  raysweep::test::write_text(expected, e.dump(2));

  const std::string py = "PYTHONPATH='" + (source_dir() / "python").string() + "' /usr/bin/python3 ";
  auto r = run_command(py + "'" + (source_dir() / "tests" / "python" / "test_reader.py").string() + "' '" +
                       file.string() + "' '" + expected.string() + "' '" + (dir / "scratch").string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;

  // los_fractions.py: the overall row's label fractions are the written ones
  // (out-of-range links left out).
  const fs::path fractions = dir / "los.json";
  r = run_command(py + "'" + (source_dir() / "python" / "los_fractions.py").string() + "' '" + file.string() +
                  "' --json '" + fractions.string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  {
    double geo[3] = {0, 0, 0}, zone[3] = {0, 0, 0}, n = 0;
    for (const auto& l : x.links) {
      if (l.flags & kLinkOutOfRange) continue;
      geo[l.los_class] += 1;
      zone[l.los_class_fresnel] += 1;
      n += 1;
    }
    const nlohmann::json got = nlohmann::json::parse(raysweep::test::read_text(fractions));
    const nlohmann::json& all = got["rows"].back();
    EXPECT_EQ(all["links"], static_cast<int>(n));
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(all["geometric"][c].get<double>(), geo[c] / n, 1e-12) << c;
      EXPECT_NEAR(all["fresnel"][c].get<double>(), zone[c] / n, 1e-12) << c;
    }
  }

  const fs::path png = dir / "gain.png";
  r = run_command(py + "'" + (source_dir() / "python" / "example_dataset.py").string() + "' '" + file.string() +
                  "' --png '" + png.string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("frames        3"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("NLOSV"), std::string::npos) << r.output;
  ASSERT_TRUE(fs::exists(png));
  EXPECT_GT(fs::file_size(png), 1000u);
  EXPECT_EQ(read_bytes(png).substr(1, 3), "PNG");
}

// Splits for training (python/raysweep_dataset.py): time windows that share no
// frame and lie at least the gap apart; a split's links.
TEST(Dataset, PythonSplitsShareNoFrameAndKeepTheGap) {
  const fs::path dir = tmp_dir("python_splits");
  const fs::path file = dir / "channels.h5";
  write_test_dataset(file);
  const auto r = run_command("PYTHONPATH='" + (source_dir() / "python").string() + "' /usr/bin/python3 '" +
                             (source_dir() / "tests/python/test_splits.py").string() + "' '" + file.string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
}
