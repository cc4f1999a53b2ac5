// Regression tests for what fuzzing (tests/fuzz/) found: each finding's input
// is kept in tests/fuzz/corpus/<target>/ (crash-*, leak-*, timeout-*, oom-*)
// and replayed here through the same reader as its harness, so the normal and
// the sanitizer suites check every fix; plus one test per finding that states
// the expected clear error.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>

#include "fuzz/h5_bases.hpp"
#include "generators/dataset/dataset_reader.hpp"
#include "generators/formats.hpp"
#include "generators/sinr/channel_trace.hpp"
#include "hdf5_test_util.hpp"
#include "meshkit/errors.hpp"
#include "meshkit/model_import.hpp"
#include "meshkit/osm_buildings.hpp"
#include "meshkit/ply_io.hpp"
#include "pipeline/radiomap_stage.hpp"
#include "pipeline/settings/config_error.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace raysweep;
using raysweep::test::scratch_dir;
using raysweep::test::source_dir;

namespace {

const meshkit::Projector kProject = [](double lon, double lat) { return meshkit::Vec2{lon * 7e4, lat * 1.1e5}; };

// The reader each fuzz target drives, by target name; the file name (and so
// its extension) is the one the harness gives its input.
struct Target {
  std::string file_name;
  std::function<void(const std::string&)> read;
};

const std::map<std::string, Target>& targets() {
  static const std::map<std::string, Target> t = {
      {"osm_xml", {"input.osm", [](const std::string& p) { meshkit::read_osm_buildings(p, kProject); }}},
      {"osm_pbf", {"input.osm.pbf", [](const std::string& p) { meshkit::read_osm_buildings(p, kProject); }}},
      {"off", {"input.off", [](const std::string& p) { meshkit::import_model(p, {}); }}},
      {"ply", {"input.ply",
               [](const std::string& p) {
                 // Both PLY readers, as fuzz_ply calls them; the second's error counts when the first reads.
                 try {
                   meshkit::read_ply(p);
                 } catch (const meshkit::InputError&) {
                 }
                 meshkit::import_model(p, {});
               }}},
      {"toml", {"city.toml", [](const std::string& p) { pipeline::load_settings(p); }}},
  };
  return t;
}

// Reads `path` as its target does: passes when it reads, or fails with one of
// the errors the CLI reports as bad input (exit 2) naming the file.
void expect_read_or_clear_error(const Target& target, const std::string& path) {
  const std::string name = fs::path(path).filename().string();
  try {
    target.read(path);
  } catch (const meshkit::InputError& e) {
    EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
  } catch (const pipeline::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << path << ": unexpected exception: " << e.what();
  }
}

fs::path copy_as(const fs::path& input, const fs::path& dir, const std::string& name) {
  fs::copy_file(input, dir / name, fs::copy_options::overwrite_existing);
  return dir / name;
}

fs::path corpus(const std::string& target, const std::string& file) {
  return source_dir() / "tests/fuzz/corpus" / target / file;
}

}  // namespace

// Every kept finding of every target still reads, or fails with a clear error.
TEST(FuzzRegressions, EveryKeptFindingReadsOrFailsClearly) {
  const fs::path dir = scratch_dir("replay");
  int replayed = 0;
  for (const auto& [name, target] : targets()) {
    const fs::path folder = source_dir() / "tests/fuzz/corpus" / name;
    if (!fs::is_directory(folder)) continue;
    for (const auto& e : fs::directory_iterator(folder)) {
      const std::string f = e.path().filename().string();
      if (f.rfind("crash-", 0) && f.rfind("leak-", 0) && f.rfind("timeout-", 0) && f.rfind("oom-", 0)) continue;
      SCOPED_TRACE(name + "/" + f);
      expect_read_or_clear_error(target, copy_as(e.path(), dir, target.file_name).string());
      ++replayed;
    }
  }
  EXPECT_GT(replayed, 0);
}

// A PBF block whose protobuf data ends early: protozero's end_of_buffer_exception
// (a std::exception only) escaped read_osm_buildings, and the CLI exited 1 with
// "end of buffer exception". Now an InputError naming the file (exit 2).
TEST(FuzzRegressions, OsmPbfTruncatedProtobufIsAClearError) {
  const fs::path dir = scratch_dir("pbf");
  const fs::path in = copy_as(corpus("osm_pbf", "crash-c8ebe1ffb896b056f14df59cec7ad10d5534171a"), dir, "x.osm.pbf");
  try {
    meshkit::read_osm_buildings(in.string(), kProject);
    FAIL() << "no error";
  } catch (const meshkit::InputError& e) {
    EXPECT_EQ(e.file(), in.string());
    EXPECT_NE(std::string(e.what()).find("corrupt OSM PBF data"), std::string::npos) << e.what();
  }
}

// An OSM XML attribute libosmium cannot read (visible="x"): its parser threw
// std::invalid_argument, which escaped read_osm_buildings without the file's
// name (fuzz_osm_xml). Now an InputError naming the file.
TEST(FuzzRegressions, OsmXmlUnreadableAttributeIsAClearError) {
  const fs::path dir = scratch_dir("osmvis");
  const fs::path in = copy_as(corpus("osm_xml", "crash-f5297915be573ac470b28c0409d8f9b997f829a8"), dir, "x.osm");
  EXPECT_THROW(meshkit::read_osm_buildings(in.string(), kProject), meshkit::InputError);
  const fs::path small = dir / "visible.osm";
  raysweep::test::write_text(small, "<?xml version='1.0'?>\n<osm version='0.6'>\n"
                                    " <node id='1' lat='50' lon='9' visible='maybe'/>\n</osm>\n");
  try {
    meshkit::read_osm_buildings(small.string(), kProject);
    FAIL() << "no error";
  } catch (const meshkit::InputError& e) {
    EXPECT_EQ(e.file(), small.string());
    EXPECT_NE(std::string(e.what()).find("visible"), std::string::npos) << e.what();
  }
}

// A PBF string-table entry holding a NUL byte: libosmium copies it into a way's
// tag list, whose strlen walk then steps over the list's end and reads past its
// buffer (ASan heap-buffer-overflow under TagList::find_key in fuzz_osm_pbf).
// The tag list is now checked first and the way named.
TEST(FuzzRegressions, OsmPbfTagWithNulByteIsAClearError) {
  const fs::path dir = scratch_dir("pbfnul");
  const fs::path in = copy_as(corpus("osm_pbf", "crash-151041f14f9e2c89d6ae354d8baad10eca62915d"), dir, "x.osm.pbf");
  try {
    meshkit::read_osm_buildings(in.string(), kProject);
    FAIL() << "no error";
  } catch (const meshkit::InputError& e) {
    EXPECT_EQ(e.file(), in.string());
    EXPECT_EQ(e.element().rfind("way/", 0), 0u) << e.what();
    EXPECT_NE(std::string(e.what()).find("corrupt tag list"), std::string::npos) << e.what();
  }
}

// Every failed read of a corrupt PBF leaked libosmium's file descriptor (the
// fuzzer ran out of descriptors after ~20,000 inputs). PBF is now read from
// memory; reading it again and again keeps the process's descriptors.
TEST(FuzzRegressions, CorruptPbfDoesNotLeakFileDescriptors) {
  const fs::path dir = scratch_dir("pbffd");
  const fs::path in = copy_as(corpus("osm_pbf", "crash-c8ebe1ffb896b056f14df59cec7ad10d5534171a"), dir, "x.osm.pbf");
  auto open_fds = [] {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator("/proc/self/fd")) ++n;
    return n;
  };
  EXPECT_THROW(meshkit::read_osm_buildings(in.string(), kProject), meshkit::InputError);
  const std::size_t before = open_fds();
  for (int i = 0; i < 50; ++i) EXPECT_THROW(meshkit::read_osm_buildings(in.string(), kProject), meshkit::InputError);
  EXPECT_LE(open_fds(), before);
}

// A node coordinate with a huge exponent ("13.40021e309") overflows libosmium's
// int64 scaling (a signed overflow in its header, UBSan in the fuzz build;
// meshkit/CMakeLists.txt). The reader must neither crash nor place the node at
// a coordinate it did not give: it is refused (libosmium's range check) or
// read as invalid, so it is in neither the bounds nor an outline.
TEST(FuzzRegressions, OsmCoordinateWithHugeExponentIsNotTakenAsALocation) {
  const fs::path dir = scratch_dir("osm");
  const fs::path in = dir / "x.osm";
  raysweep::test::write_text(in,
                             "<?xml version='1.0'?>\n<osm version=\"0.6\">\n"
                             "<node id=\"1\" lat=\"52.5\" lon=\"13.4\"/>"
                             "<node id=\"2\" lat=\"52.5\" lon=\"13.40021e309\"/>"
                             "<node id=\"3\" lat=\"52.5002\" lon=\"13.4002\"/>\n"
                             "<way id=\"5\"><nd ref=\"1\"/><nd ref=\"2\"/><nd ref=\"3\"/><nd ref=\"1\"/>"
                             "<tag k=\"building\" v=\"yes\"/></way>\n</osm>\n");
  try {
    const auto osm = meshkit::read_osm_buildings(in.string(), kProject);
    EXPECT_LE(osm.max_lon, 13.4002 + 1e-9);  // node 2 is not in the bounds
    for (const auto& b : osm.buildings)        // nor in an outline (a way missing a node is repaired later)
      for (const auto& ring : b.outers)
        for (const auto& p : ring) EXPECT_LE(p[0], 13.4002 * 7e4 + 1e-6);
  } catch (const meshkit::InputError& e) {
    EXPECT_EQ(e.file(), in.string());
  }
}

// An OFF data line of only a vertical tab: the layout check counted it as a
// face line (whitespace " \t\r"), then split it into no tokens and read the
// first one (UBSan: reference to null). Now blank lines by the stream's
// whitespace are skipped, and the face count no longer matches: a clear error.
TEST(FuzzRegressions, OffLineOfOnlyAVerticalTabIsBlank) {
  const fs::path dir = scratch_dir("off");
  const fs::path in = copy_as(corpus("off", "crash-f85fcb5dd5a9440990725ec4c81a51350f802732"), dir, "x.off");
  EXPECT_THROW(meshkit::import_model(in.string(), {}), meshkit::InputError);
  // The same blank line inside a valid file changes nothing.
  raysweep::test::write_text(dir / "ok.off", "OFF\n3 1 0\n\v\n0 0 0\n1 0 0\n0 1 0\n\v\n3 0 1 2\n");
  const auto m = meshkit::import_model((dir / "ok.off").string(), {1.0, "", 0});
  EXPECT_EQ(m.triangle_count(), 1u);
}

// A PLY format line whose version is not a number sent OpenMesh 9.0's PLY
// reader into an endless loop ("Unsupported keyword : format" forever, a
// timeout in fuzz_ply). check_ply_layout, run before OpenMesh, now checks the
// format line in full and names the header line.
TEST(FuzzRegressions, PlyFormatLineWithoutAVersionIsAClearError) {
  const fs::path dir = scratch_dir("ply");
  const fs::path in = copy_as(corpus("ply", "timeout-aa1d4b74d45adc035e64704779b6e2dd6852567e"), dir, "x.ply");
  try {
    meshkit::import_model(in.string(), {});
    FAIL() << "no error";
  } catch (const meshkit::InputError& e) {
    EXPECT_EQ(e.file(), in.string());
    EXPECT_EQ(e.element(), "header line 2");
  }
  const std::string body = "element vertex 0\nproperty float x\nend_header\n";
  for (const std::string format : {"format ascii", "format ascii 1.0 x", "format ascii one", "format ebcdic 1.0"}) {
    raysweep::test::write_text(dir / "f.ply", "ply\n" + format + "\n" + body);
    EXPECT_THROW(meshkit::check_ply_layout((dir / "f.ply").string()), meshkit::InputError) << format;
  }
  raysweep::test::write_text(dir / "f.ply", "ply\nformat ascii 1.0\n" + body);
  EXPECT_NO_THROW(meshkit::check_ply_layout((dir / "f.ply").string()));
}

// OFF numbers OpenMesh 9.0 cannot read (an index or colour past 2^32) failed its
// stream, and its OFF reader then looped forever (timeout in fuzz_off). The
// layout check now requires plain decimal numbers, integers within 32 bits and
// indices below the vertex count.
TEST(FuzzRegressions, OffNumbersOpenMeshCannotReadAreClearErrors) {
  const fs::path dir = scratch_dir("offnum");
  const fs::path in = copy_as(corpus("off", "timeout-640828d7c4c9204371e521b4d019d77957567c14"), dir, "x.off");
  try {
    meshkit::import_model(in.string(), {});
    FAIL() << "no error";
  } catch (const meshkit::InputError& e) {
    EXPECT_EQ(e.file(), in.string());
    EXPECT_EQ(e.element(), "face 0");
  }
  const std::string head = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n";
  for (const std::string face : {"3 0 1 3", "3 0 1 99999999999999999999", "3 0 1 2 4294967296", "3 0 1 2 0x10"}) {
    raysweep::test::write_text(dir / "f.off", head + face + "\n");
    EXPECT_THROW(meshkit::import_model((dir / "f.off").string(), {1.0, "", 0}), meshkit::InputError) << face;
  }
  raysweep::test::write_text(dir / "f.off", "OFF\n3 1 0\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n");
  EXPECT_THROW(meshkit::import_model((dir / "f.off").string(), {1.0, "", 0}), meshkit::InputError);
  raysweep::test::write_text(dir / "f.off", head + "3 0 1 2 255 0 0\n");  // a face colour is fine
  EXPECT_EQ(meshkit::import_model((dir / "f.off").string(), {1.0, "", 0}).triangle_count(), 1u);
}

// A PLY header OpenMesh reads token by token into a failed stream (magic after
// a space, then lines that are no PLY keyword) looped its reader forever
// (timeout in fuzz_ply). check_ply_layout now takes the magic as OpenMesh does
// and refuses unknown header keywords, naming the line.
TEST(FuzzRegressions, PlyHeaderWithUnknownKeywordsIsAClearError) {
  const fs::path dir = scratch_dir("plykw");
  const fs::path in = copy_as(corpus("ply", "timeout-f69a3a94bc39bacf53ca8d648be9bc8b0713cde7"), dir, "x.ply");
  try {
    meshkit::import_model(in.string(), {});
    FAIL() << "no error";
  } catch (const meshkit::InputError& e) {
    EXPECT_EQ(e.file(), in.string());
    EXPECT_EQ(e.element().rfind("header line ", 0), 0u) << e.element();
  }
  raysweep::test::write_text(dir / "k.ply", " ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nvertices 3\nend_header\n");
  EXPECT_THROW(meshkit::check_ply_layout((dir / "k.ply").string()), meshkit::InputError);
}

// A binary PLY whose magic is upper case ("PLY"), with a NUL byte in a comment
// and broken keyword lines: check_ply_layout took the magic in lower case only
// and returned without a check, and OpenMesh, which takes it in any case, looped
// (timeout in fuzz_ply). The magic is now compared as OpenMesh compares it.
TEST(FuzzRegressions, PlyUpperCaseMagicIsCheckedToo) {
  const fs::path dir = scratch_dir("plycase");
  const fs::path in = copy_as(corpus("ply", "timeout-5b27385a349d722b48299626dad7e344c963bada"), dir, "x.ply");
  try {
    meshkit::import_model(in.string(), {});
    FAIL() << "no error";
  } catch (const meshkit::InputError& e) {
    EXPECT_EQ(e.file(), in.string());
    EXPECT_EQ(e.element(), "header line 13") << e.what();  // "*ted b0"
  }
  raysweep::test::write_text(dir / "u.ply", "PLY\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\nx\n");
  EXPECT_THROW(meshkit::check_ply_layout((dir / "u.ply").string()), meshkit::InputError);
}

// An ascii PLY face line "3 4 5 7-3 4 7 6": OpenMesh read 7, then -3 as the
// next list length, and grew one face to 3 GB (out-of-memory in fuzz_ply).
// check_ply_layout now requires every ascii value to be a plain number.
TEST(FuzzRegressions, PlyAsciiValueThatIsNoNumberIsAClearError) {
  const fs::path dir = scratch_dir("plynum");
  const fs::path in = copy_as(corpus("ply", "oom-bc115edf4cab9d4d4feec139edf2a5f0d0f2a63a"), dir, "x.ply");
  try {
    meshkit::import_model(in.string(), {});
    FAIL() << "no error";
  } catch (const meshkit::InputError& e) {
    EXPECT_EQ(e.file(), in.string());
    EXPECT_EQ(e.element(), "face 2");
  }
}

// A TOML syntax error (a quote inside a key) reached load_radiomap_settings'
// own parse: toml++'s parse_error escaped, naming neither file nor line, and
// the CLI exited 1. It now goes through the common check first: a ConfigError
// with the file and line.
TEST(FuzzRegressions, TomlSyntaxErrorInRadiomapSettingsNamesFileAndLine) {
  const fs::path dir = scratch_dir("toml");
  const fs::path in = copy_as(corpus("toml", "crash-733843f089030c8d9b873013e131d3581d03168a"), dir, "c.toml");
  try {
    pipeline::load_settings(in.string());
    FAIL() << "no error";
  } catch (const pipeline::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(in.string() + ":2:"), std::string::npos) << e.what();
  }
}

namespace {

// Replaces dataset `name` of `file` by a scalar double (what a fuzzed edit did).
void make_scalar(const fs::path& file, const std::string& name) {
  raysweep::test::H5 f{H5Fopen(file.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
  ASSERT_GE(f.id, 0);
  ASSERT_GE(H5Ldelete(f.id, name.c_str(), H5P_DEFAULT), 0);
  raysweep::test::H5 sp{H5Screate(H5S_SCALAR), H5Sclose};
  raysweep::test::H5 d{H5Dcreate2(f.id, name.c_str(), H5T_NATIVE_DOUBLE, sp.id, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                       H5Dclose};
  ASSERT_GE(d.id, 0);
  const double v = 1;
  ASSERT_GE(H5Dwrite(d.id, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, &v), 0);
}

// Sets the root (or `obj`) double attribute `name` of `file`.
void set_f64_attr(const fs::path& file, const std::string& obj, const std::string& name, double v) {
  raysweep::test::H5 f{H5Fopen(file.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
  // Through the object: HDF5 1.10's H5Awrite fails on an attribute opened by
  // name from the file ("can't locate open attribute?") unless its object is open.
  raysweep::test::H5 o{H5Oopen(f.id, obj.c_str(), H5P_DEFAULT), H5Oclose};
  raysweep::test::H5 a{H5Aopen(o.id, name.c_str(), H5P_DEFAULT), H5Aclose};
  ASSERT_GE(a.id, 0);
  ASSERT_GE(H5Awrite(a.id, H5T_NATIVE_DOUBLE, &v), 0);
}

::testing::AssertionResult StartsWith(const std::string& text, const std::string& prefix) {
  if (text.rfind(prefix, 0) == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' does not start with '" << prefix << "'";
}

// Replaces the root attribute `name` of `file` by an array of `n` fixed-length strings.
void make_string_array_attr(const fs::path& file, const std::string& name, hsize_t n) {
  raysweep::test::H5 f{H5Fopen(file.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
  ASSERT_GE(H5Adelete(f.id, name.c_str()), 0);
  raysweep::test::H5 t{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(t.id, 8);
  raysweep::test::H5 sp{H5Screate_simple(1, &n, nullptr), H5Sclose};
  raysweep::test::H5 a{H5Acreate2(f.id, name.c_str(), t.id, sp.id, H5P_DEFAULT, H5P_DEFAULT), H5Aclose};
  ASSERT_GE(a.id, 0);
  const std::string data(8 * n, 'x');
  ASSERT_GE(H5Awrite(a.id, t.id, data.data()), 0);
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const meshkit::InputError& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("unexpected exception: ") + e.what();
  }
  return "no error";
}

}  // namespace

// `raysweep info` on a SINR file (or ns-3 table) whose column is a scalar:
// dataset_info's readers took dims.at(0) and std::out_of_range escaped
// ("vector::_M_range_check"). Now an InputError naming file and dataset.
TEST(FuzzRegressions, InfoOnAScalarColumnIsAClearError) {
  const fs::path dir = scratch_dir("info");
  const fs::path sinr = dir / "sinr.h5", table = dir / "table.h5";
  raysweep::fuzz::write_sinr_base(sinr.string());
  raysweep::fuzz::write_ns3_base(table.string());
  EXPECT_NO_THROW(generators::dataset_info(sinr.string()));
  make_scalar(sinr, "/prr_rats/received");
  EXPECT_TRUE(StartsWith(error_of([&] { generators::dataset_info(sinr.string()); }), sinr.string() + ": /prr_rats/received: /prr_rats/received: not an array"));
  make_scalar(table, "/frames/time_s");
  EXPECT_TRUE(StartsWith(error_of([&] { generators::dataset_info(table.string()); }), table.string() + ": /frames/time_s: /frames/time_s: not an array"));
}

// A channel dataset whose bandwidth_hz (or carrier) is not a positive number:
// ChannelTrace::load took it, so the SINR stage would compute with it and
// `raysweep ns3-table` failed in the table writer with an invalid_argument
// naming its own output. Now the reader names the dataset and the attribute;
// likewise the /cfr attributes the per-band centres come from.
TEST(FuzzRegressions, ChannelDatasetWithBadBandwidthNamesTheAttribute) {
  const fs::path dir = scratch_dir("bw");
  const fs::path file = dir / "channels.h5";
  for (const double bad : {0.0, -10e6, std::nan("")}) {
    raysweep::fuzz::write_channel_base(file.string());
    set_f64_attr(file, "/", "bandwidth_hz", bad);
    const std::string expected = file.string() + ": attribute bandwidth_hz: is not a positive number";
    EXPECT_TRUE(StartsWith(error_of([&] { generators::sinr::ChannelTrace::load(file.string()); }), expected));
    EXPECT_TRUE(StartsWith(error_of([&] { generators::build_ns3_table(file.string(), dir / "t.h5", {}, 2); }), expected));
  }
  raysweep::fuzz::write_channel_base(file.string());
  set_f64_attr(file, "/cfr", "carrier_hz", 1e30);  // the spacing vanishes in rounding: equal band centres
  EXPECT_TRUE(StartsWith(error_of([&] { generators::build_ns3_table(file.string(), dir / "t.h5", {}, 2); }),
                         file.string() + ": /cfr: carrier_hz and subcarrier_spacing_hz give band centres"));
  raysweep::fuzz::write_channel_base(file.string());
  set_f64_attr(file, "/cfr", "subcarrier_spacing_hz", -1);
  EXPECT_NE(error_of([&] { generators::build_ns3_table(file.string(), dir / "t.h5", {}, 2); })
                .find(file.string() + ": /cfr attribute subcarrier_spacing_hz"),
            std::string::npos);
}

// Two frames at the same time (a fuzzed edit of /frames/time_s): the channel
// reader takes them, and `raysweep ns3-table` failed in the table writer with
// an invalid_argument naming its own output. Now the dataset's row is named.
TEST(FuzzRegressions, Ns3TableFromFramesAtOneTimeNamesTheDatasetRow) {
  const fs::path dir = scratch_dir("frametime");
  const fs::path file = dir / "channels.h5";
  raysweep::fuzz::write_channel_base(file.string());
  EXPECT_EQ(error_of([&] { generators::build_ns3_table(file.string(), dir / "t.h5", {}, 2); }), "no error");
  {
    raysweep::test::H5 f{H5Fopen(file.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
    raysweep::test::H5 d{H5Dopen2(f.id, "/frames/time_s", H5P_DEFAULT), H5Dclose};
    ASSERT_GE(d.id, 0);
    const double t[2] = {0, 0};
    raysweep::test::H5 file_space{H5Dget_space(d.id), H5Sclose};
    const hsize_t start = 0, count = 2;
    ASSERT_GE(H5Sselect_hyperslab(file_space.id, H5S_SELECT_SET, &start, nullptr, &count, nullptr), 0);
    raysweep::test::H5 mem{H5Screate_simple(1, &count, nullptr), H5Sclose};
    ASSERT_GE(H5Dwrite(d.id, H5T_NATIVE_DOUBLE, mem.id, file_space.id, H5P_DEFAULT, t), 0);
  }
  EXPECT_TRUE(StartsWith(error_of([&] { generators::build_ns3_table(file.string(), dir / "t2.h5", {}, 2); }),
                         file.string() + ": /frames/time_s: row 1: time 0.000000 s is not after the previous frame's"));
  EXPECT_FALSE(fs::exists(dir / "t2.h5"));
}

// A /cfr subcarrier count far beyond the /cfr/h dataset's width (a fuzzed
// attribute): the reader allocated rows x subcarriers before HDF5 checked the
// selection (219 GB, ASan out-of-memory in fuzz_dataset_h5). Now every
// column read checks its selection against the dataset first, naming it.
TEST(FuzzRegressions, CfrSubcarrierCountBeyondTheDatasetIsAClearError) {
  const fs::path dir = scratch_dir("cfrwidth");
  const fs::path file = dir / "channels.h5";
  raysweep::fuzz::write_channel_base(file.string());
  set_f64_attr(file, "/cfr", "subcarriers", 4e9);
  const std::string error = error_of([&] {
    generators::DatasetReader r(file.string());
    r.frames(0, r.frame_count());
  });
  EXPECT_TRUE(StartsWith(error, file.string() + ": /cfr/h")) << error;
  EXPECT_NE(error.find("4000000000 values a row asked of a dataset of"), std::string::npos) << error;
  // The same count against /cfr/h replaced by a scalar (the rank was
  // checked only after the allocation: 68 GB).
  make_scalar(file, "/cfr/h");
  const std::string scalar = error_of([&] {
    generators::DatasetReader r(file.string());
    r.frames(0, r.frame_count());
  });
  EXPECT_TRUE(StartsWith(scalar, file.string() + ": /cfr/h")) << scalar;
  EXPECT_NE(scalar.find("not a one- or two-dimensional dataset"), std::string::npos) << scalar;
}

// A string attribute holding an array of strings: the readers passed a buffer
// for one string to H5Aread, which wrote them all (ASan: stack- and
// heap-buffer-overflow in fuzz_sinr_h5 and fuzz_ns3_table_h5). Now "not a
// single value", naming file and attribute, in every reader.
TEST(FuzzRegressions, StringAttributeArrayIsNotASingleValue) {
  const fs::path dir = scratch_dir("strattr");
  const fs::path sinr = dir / "sinr.h5", table = dir / "table.h5", channels = dir / "channels.h5";
  raysweep::fuzz::write_sinr_base(sinr.string());
  raysweep::fuzz::write_ns3_base(table.string());
  raysweep::fuzz::write_channel_base(channels.string());
  make_string_array_attr(sinr, "format", 3);
  make_string_array_attr(table, "format", 3);
  make_string_array_attr(channels, "format", 3);
  auto expect_single_value_error = [](const fs::path& f, const std::string& error) {
    EXPECT_TRUE(StartsWith(error, f.string() + ": ")) << error;
    EXPECT_NE(error.find("format: not a single value"), std::string::npos) << error;
  };
  for (const fs::path& f : {sinr, table, channels})
    expect_single_value_error(f, error_of([&] { generators::dataset_info(f.string()); }));
  expect_single_value_error(sinr, error_of([&] { generators::sinr::read_sinr_schedule(sinr.string()); }));
  expect_single_value_error(table, error_of([&] { generators::Ns3Table::load(table.string()); }));
  expect_single_value_error(channels, error_of([&] { generators::sinr::ChannelTrace::load(channels.string()); }));
}

// A link whose LoS class is no code (88): ChannelTrace::load took it, the SINR
// channel models would index by it, and `raysweep ns3-table` failed in the
// table writer naming its own output. Now the reader names /links/los_class.
TEST(FuzzRegressions, UnknownLosClassIsNamedByTheChannelReader) {
  const fs::path dir = scratch_dir("los");
  const fs::path file = dir / "channels.h5";
  raysweep::fuzz::write_channel_base(file.string());
  raysweep::test::poke<std::uint8_t>(file, "/links/los_class", 1, 88, H5T_NATIVE_UINT8);
  const std::string expected = file.string() + ": /links/los_class: row 1: unknown LoS class 88";
  EXPECT_TRUE(StartsWith(error_of([&] { generators::sinr::ChannelTrace::load(file.string()); }), expected));
  EXPECT_TRUE(StartsWith(error_of([&] { generators::build_ns3_table(file.string(), dir / "t.h5", {}, 2); }), expected));
}
