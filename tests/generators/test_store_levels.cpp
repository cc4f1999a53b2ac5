// Dataset store levels (schemas/README.md, "Store levels"): every level
// validates and reads back with the same link columns and CFR; paths_top_k
// keeps each link's strongest paths; the validator holds a file to its level;
// files written before the levels still validate and read; a stage that
// reads more than a file holds refuses it and writes nothing.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "dataset_fixtures.hpp"
#include "generators/dataset/dataset_reader.hpp"
#include "generators/dataset/dataset_writer.hpp"
#include "generators/dataset/store_level.hpp"
#include "generators/formats.hpp"
#include "generators/hdf5/checked_file.hpp"
#include "generators/ns3_table/ns3_table.hpp"
#include "hdf5_test_util.hpp"
#include "meshkit/errors.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace raysweep::generators;
using namespace raysweep::generators::fixtures;
using raysweep::test::H5;
using raysweep::test::read_bytes;
using raysweep::test::set_str_attr;

namespace {

constexpr StoreLevel kLevels[] = {StoreLevel::links, StoreLevel::cfr, StoreLevel::paths, StoreLevel::full};

fs::path write_level(const fs::path& dir, StoreLevel level, std::uint32_t top_k = 0) {
  const fs::path file = dir / (std::string(store_level_name(level)) + std::to_string(top_k) + ".h5");
  DatasetHeader h = test_header();
  h.store = level;
  h.paths_top_k = top_k;
  Builder b;
  DatasetWriter w(file, h);
  for (const auto& f : b.frames()) w.append(f);
  w.finish(test_nodes(), test_objects());
  return file;
}

void expect_same_path(const PathRecord& p, const PathRecord& q) {
  EXPECT_EQ(p.a, q.a);
  EXPECT_EQ(p.tau_s, q.tau_s);
  EXPECT_EQ(std::vector<float>({p.theta_t, p.phi_t, p.theta_r, p.phi_r, p.doppler_hz}),
            std::vector<float>({q.theta_t, q.phi_t, q.theta_r, q.phi_r, q.doppler_hz}));
  EXPECT_EQ(p.interaction_count, q.interaction_count);
}

bool mentions(const std::vector<std::string>& problems, const std::string& what) {
  for (const auto& p : problems)
    if (p.find(what) != std::string::npos) return true;
  return false;
}

std::string joined(const std::vector<std::string>& problems) {
  std::string s;
  for (const auto& p : problems) s += "  " + p + "\n";
  return s;
}

bool has(const fs::path& file, const std::string& object) {
  hdf5::CheckedFile f(file.string());
  f.open();
  return f.exists(object);
}

}  // namespace

TEST(StoreLevels, EachLevelValidatesAndReadsBackTheSameLinksAndCfr) {
  const fs::path dir = tmp_dir("store_levels");
  Builder b;
  const auto in = b.frames();
  for (StoreLevel level : kLevels) {
    SCOPED_TRACE(store_level_name(level));
    const fs::path file = write_level(dir, level);
    const auto problems = validate_dataset(file.string());
    EXPECT_TRUE(problems.empty()) << joined(problems);
    // What is stored, and what not.
    EXPECT_EQ(has(file, "/cfr/h"), level >= StoreLevel::cfr);
    EXPECT_EQ(has(file, "/paths"), level >= StoreLevel::paths);
    EXPECT_EQ(has(file, "/links/path_offset"), level >= StoreLevel::paths);
    EXPECT_EQ(has(file, "/interactions/type"), level >= StoreLevel::paths);
    EXPECT_EQ(has(file, "/interactions/point"), level >= StoreLevel::full);
    const auto info = dataset_info(file.string());
    EXPECT_EQ(info["store"], store_level_name(level));
    EXPECT_EQ(info["paths"], 9);  // the links' path counts, stored or not
    EXPECT_EQ(info["paths_stored"], level >= StoreLevel::paths);
    EXPECT_NE(format_dataset_info(info).find(std::string("store         ") + store_level_name(level)), std::string::npos);

    DatasetReader r(file);
    EXPECT_EQ(r.header().store, level);
    const auto out = r.frames(0, r.frame_count());
    ASSERT_EQ(out.size(), in.size());
    for (std::size_t f = 0; f < in.size(); ++f) {
      ASSERT_EQ(out[f].links.size(), in[f].links.size());
      for (std::size_t i = 0; i < in[f].links.size(); ++i) {
        expect_same_link_columns(out[f].links[i], in[f].links[i]);
        EXPECT_EQ(out[f].links[i].path_count, in[f].links[i].path_count);
      }
      EXPECT_EQ(out[f].cfr, level >= StoreLevel::cfr ? in[f].cfr : std::vector<std::complex<float>>{});
      ASSERT_EQ(out[f].paths.size(), level >= StoreLevel::paths ? in[f].paths.size() : 0u);
      for (std::size_t p = 0; p < out[f].paths.size(); ++p) expect_same_path(out[f].paths[p], in[f].paths[p]);
      ASSERT_EQ(out[f].interactions.size(), level >= StoreLevel::paths ? in[f].interactions.size() : 0u);
      for (std::size_t m = 0; m < out[f].interactions.size(); ++m) {
        const auto &x = out[f].interactions[m], &y = in[f].interactions[m];
        EXPECT_EQ(x.type, y.type);
        EXPECT_EQ(x.object, y.object);
        if (level == StoreLevel::full)
          EXPECT_EQ(std::vector<float>({x.x, x.y, x.z}), std::vector<float>({y.x, y.y, y.z}));
        else
          EXPECT_TRUE(std::isnan(x.x) && std::isnan(x.y) && std::isnan(x.z));
      }
    }

    // Read back and written again at its level (merge, resume): the same bytes.
    const fs::path again = dir / (std::string("again_") + store_level_name(level) + ".h5");
    {
      DatasetHeader h = r.header();
      DatasetWriter w(again, h);
      for (const auto& f : out) w.append(f);
      w.finish(r.nodes(), r.objects());
    }
    EXPECT_EQ(read_bytes(again), read_bytes(file));
  }
}

TEST(StoreLevels, TopKKeepsEachLinksStrongestPathsInDelayOrder) {
  const fs::path dir = tmp_dir("store_top_k");
  Builder b;
  const auto in = b.frames();
  const fs::path file = write_level(dir, StoreLevel::paths, 2);
  const auto problems = validate_dataset(file.string());
  EXPECT_TRUE(problems.empty()) << joined(problems);
  DatasetReader r(file);
  EXPECT_EQ(r.header().paths_top_k, 2u);
  const auto out = r.frames(0, r.frame_count());
  // The fixture's later paths are the stronger (|a| grows with the path's index):
  // of three paths a link keeps its second and third.
  for (std::size_t f = 0; f < in.size(); ++f) {
    std::size_t p_in = 0, p_out = 0;
    for (std::size_t i = 0; i < in[f].links.size(); ++i) {
      const auto &x = in[f].links[i], &y = out[f].links[i];
      expect_same_link_columns(y, x);
      const std::uint32_t kept = std::min<std::uint32_t>(x.path_count, 2);
      EXPECT_EQ(y.path_count, kept);
      EXPECT_EQ(y.paths_beyond_top_k, x.path_count - kept);
      for (std::uint32_t j = x.path_count - kept; j < x.path_count; ++j)
        expect_same_path(out[f].paths[p_out++], in[f].paths[p_in + j]);
      p_in += x.path_count;
    }
    EXPECT_EQ(out[f].cfr, in[f].cfr);  // computed from every path: untouched
  }
  EXPECT_EQ(dataset_info(file.string())["paths"], 7);
  // Interactions follow their paths: the second path of link (0, 2) had objects 1, 2.
  ASSERT_EQ(out[0].interactions.size(), 2u);
  EXPECT_EQ(out[0].interactions[0].object, 1u);
  EXPECT_EQ(out[0].interactions[1].object, 2u);
}

TEST(StoreLevels, ReductionKeepsTheFirstOfEqualPowersAndIsIdempotent) {
  FrameRecord f;
  f.nodes = {{0}, {1}};
  LinkRecord l;
  l.tx = 0, l.rx = 1, l.path_count = 3;
  f.links = {l};
  for (int j = 0; j < 3; ++j) {
    PathRecord p;
    p.a = j == 1 ? std::complex<float>(0, 1) : std::complex<float>(1, 0);  // equal powers
    p.tau_s = 1e-6 * (j + 1);
    f.paths.push_back(p);
  }
  reduce_frame(f, StoreLevel::full, 1);
  ASSERT_EQ(f.paths.size(), 1u);
  EXPECT_EQ(f.paths[0].tau_s, 1e-6);
  EXPECT_EQ(f.links[0].path_count, 1u);
  EXPECT_EQ(f.links[0].paths_beyond_top_k, 2u);
  const FrameRecord once = f;
  reduce_frame(f, StoreLevel::full, 1);
  EXPECT_EQ(f.links[0].paths_beyond_top_k, 2u);
  EXPECT_EQ(f.paths.size(), once.paths.size());
  EXPECT_THROW(parse_store_level("everything"), std::invalid_argument);
  EXPECT_EQ(parse_store_level("cfr"), StoreLevel::cfr);
}

TEST(StoreLevels, TheValidatorHoldsAFileToItsLevel) {
  const fs::path dir = tmp_dir("store_validator");
  {  // Paths in a file that says it stores up to the CFR.
    const fs::path p = write_level(dir, StoreLevel::full);
    set_str_attr(p, "store", "cfr");
    const auto problems = validate_dataset(p.string());
    EXPECT_TRUE(mentions(problems, "/paths: present, but the file's store level cfr")) << joined(problems);
    EXPECT_TRUE(mentions(problems, "/interactions: present")) << joined(problems);
  }
  {  // A paths-level file without its interactions.
    const fs::path p = write_level(dir, StoreLevel::paths);
    {
      H5 f{H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
      ASSERT_GE(H5Ldelete(f.id, "/interactions", H5P_DEFAULT), 0);
    }
    EXPECT_TRUE(mentions(validate_dataset(p.string()), "/interactions: group missing"));
  }
  {  // A level that does not exist.
    const fs::path p = write_level(dir, StoreLevel::links);
    set_str_attr(p, "store", "some");
    EXPECT_TRUE(mentions(validate_dataset(p.string()), "attribute store is \"some\""));
    EXPECT_THROW(DatasetReader{p}, raysweep::meshkit::InputError);
  }
}

TEST(StoreLevels, FilesWrittenBeforeTheLevelsValidateAndRead) {
  const fs::path dir = tmp_dir("store_old");
  const fs::path p = write_level(dir, StoreLevel::full);
  {
    H5 f{H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
    for (const char* c : {"paths_beyond_top_k", "diffuse_gain_db", "k_factor_db", "rms_doppler_spread_hz",
                          "aod_spread_rad", "aoa_spread_rad", "strongest_excess_delay_s", "strongest_aod",
                          "strongest_aoa"})
      ASSERT_GE(H5Ldelete(f.id, (std::string("/links/") + c).c_str(), H5P_DEFAULT), 0);
    ASSERT_GE(H5Adelete(f.id, "store"), 0);
    ASSERT_GE(H5Adelete(f.id, "paths_top_k"), 0);
  }
  EXPECT_TRUE(mentions(validate_dataset(p.string()), "/links/k_factor_db"));
  set_str_attr(p, "schema_version", "1.3.0");
  const auto problems = validate_dataset(p.string());
  EXPECT_TRUE(problems.empty()) << joined(problems);
  DatasetReader r(p);
  EXPECT_EQ(r.header().store, StoreLevel::full);
  const auto out = r.frames(0, r.frame_count());
  EXPECT_EQ(out[0].paths.size(), 4u);
  EXPECT_TRUE(std::isinf(out[0].links[0].k_factor_db) && out[0].links[0].k_factor_db < 0);
  EXPECT_EQ(dataset_info(p.string())["store"], "full");
}

TEST(StoreLevels, AStageThatReadsMoreRefusesNamingTheLevelAndWritesNothing) {
  const fs::path dir = tmp_dir("store_refuse");
  const fs::path links = write_level(dir, StoreLevel::links);
  const fs::path table = dir / "table.h5";
  Ns3TableHeader header;
  header.raysweep_version = "0.1.0-test";
  header.git_hash = "0123456789ab";
  try {
    build_ns3_table(links.string(), table, header, 0);
    ADD_FAILURE() << "no error";
  } catch (const raysweep::meshkit::InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(links.string()), std::string::npos) << what;
    EXPECT_NE(what.find("stores level links but ns3-table reads level cfr"), std::string::npos) << what;
    EXPECT_NE(what.find("store = \"cfr\""), std::string::npos) << what;
  }
  EXPECT_FALSE(fs::exists(table));
  // From the cfr level up it builds.
  build_ns3_table(write_level(dir, StoreLevel::cfr).string(), table, header, 2);
  EXPECT_TRUE(fs::exists(table));
}

TEST(StoreLevels, PythonReaderReadsEveryLevel) {
  const fs::path dir = tmp_dir("store_python");
  std::string args;
  for (StoreLevel level : kLevels) args += " '" + write_level(dir, level).string() + "'";
  args += " '" + write_level(dir, StoreLevel::paths, 2).string() + "'";
  const auto r = raysweep::test::run_command("PYTHONPATH='" + (raysweep::test::source_dir() / "python").string() +
                                             "' /usr/bin/python3 '" +
                                             (raysweep::test::source_dir() / "tests/python/test_reader_levels.py").string() +
                                             "'" + args);
  EXPECT_EQ(r.exit_code, 0) << r.output;
}
