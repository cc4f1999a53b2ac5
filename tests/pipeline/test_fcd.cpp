// SUMO FCD streaming reader (pipeline/fcd) and vType -> vehicle class mapping
// (pipeline/vtypes): exact values, filters, errors with file and line,
// constant memory on a multi-million-line gzip trace, a real scenario's vTypes.
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <chrono>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "meshkit/errors.hpp"
#include "meshkit/sumo_net.hpp"
#include "meshkit/xml_reader.hpp"
#include "pipeline/fcd.hpp"
#include "pipeline/vtypes.hpp"
#include "test_util.hpp"

using namespace raysweep;
using pipeline::FcdFilter;
using pipeline::FcdFrame;
using pipeline::FcdReader;
using pipeline::VTypeMap;
namespace fs = std::filesystem;

namespace {

// Per process and test: ctest runs the tests of this file in parallel processes.
fs::path temp_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  fs::path p = fs::temp_directory_path() / "raysweep-tests" /
               ("fcd." + std::string(info->test_suite_name()) + "." + info->name() + "." + std::to_string(getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

struct TempDir {
  fs::path path = temp_dir();
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

void write_gzip(const fs::path& p, const std::string& text, const char* mode = "wb6") {
  gzFile f = gzopen(p.c_str(), mode);
  ASSERT_NE(f, nullptr);
  ASSERT_EQ(gzwrite(f, text.data(), static_cast<unsigned>(text.size())), static_cast<int>(text.size()));
  ASSERT_EQ(gzclose(f), Z_OK);
}

std::vector<FcdFrame> read_all(const fs::path& p, FcdFilter filter = {}) {
  FcdReader r(p.string(), std::move(filter));
  std::vector<FcdFrame> frames;
  FcdFrame f;
  while (r.next(f)) frames.push_back(f);
  return frames;
}

// The message of the InputError reading `p` throws ("" when none).
std::string read_error(const fs::path& p, FcdFilter filter = {}) {
  try {
    read_all(p, std::move(filter));
  } catch (const meshkit::InputError& e) {
    return e.what();
  }
  return "";
}

long vm_rss_kib() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

// Lines 1-14, known by construction.
const char* kSmallFcd =
    R"(<?xml version="1.0" encoding="UTF-8"?>
<fcd-export xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://sumo.dlr.de/xsd/fcd_file.xsd">
    <timestep time="0.00">
        <vehicle id="veh0" x="100.50" y="200.25" z="1.50" angle="90.00" type="car" speed="13.89" pos="5.10" lane="e1_0" slope="-2.50"/>
        <vehicle id="veh1" x="-3.00" y="4.00" angle="359.99" speed="0.00" pos="1.00" lane="e2_0"/>
        <person id="ped0" x="1.00" y="2.00" angle="0.00" speed="1.20" pos="0.00" edge="e1" slope="0.00"/>
    </timestep>
    <timestep time="0.10">
        <vehicle id="veh0" x="101.89" y="200.25" z="1.45" angle="90.00" type="car" speed="13.90" pos="6.49" lane="e1_0" slope="-2.40"/>
        <container id="c0" x="7.00" y="8.00" angle="0.00" speed="0.00" pos="0.00" edge="e3"/>
    </timestep>
    <timestep time="0.20"/>
    <timestep time="1:02:03.50"><vehicle id="bike" x="1e3" y="-2.5E1" angle="180" type="DEFAULT_BIKETYPE" speed="4"/></timestep>
</fcd-export>
)";

void check_small(const std::vector<FcdFrame>& frames) {
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_EQ(frames[0].time_s, 0.0);
  EXPECT_EQ(frames[0].line, 3);
  ASSERT_EQ(frames[0].vehicles.size(), 2u);  // the person is not a vehicle
  const auto& a = frames[0].vehicles[0];
  EXPECT_EQ(a.id, "veh0");
  EXPECT_EQ(a.type, "car");
  EXPECT_EQ(a.x, 100.5);
  EXPECT_EQ(a.y, 200.25);
  EXPECT_TRUE(a.has_z);
  EXPECT_EQ(a.z, 1.5);
  EXPECT_EQ(a.angle_deg, 90.0);
  EXPECT_EQ(a.speed_mps, 13.89);
  EXPECT_EQ(a.slope_deg, -2.5);
  EXPECT_EQ(a.line, 4);
  const auto& b = frames[0].vehicles[1];
  EXPECT_EQ(b.id, "veh1");
  EXPECT_EQ(b.type, "DEFAULT_VEHTYPE");
  EXPECT_EQ(b.x, -3.0);
  EXPECT_EQ(b.y, 4.0);
  EXPECT_FALSE(b.has_z);
  EXPECT_EQ(b.z, 0.0);
  EXPECT_EQ(b.angle_deg, 359.99);
  EXPECT_EQ(b.speed_mps, 0.0);
  EXPECT_EQ(b.slope_deg, 0.0);
  EXPECT_EQ(b.line, 5);

  EXPECT_EQ(frames[1].time_s, 0.1);
  EXPECT_EQ(frames[1].line, 8);
  ASSERT_EQ(frames[1].vehicles.size(), 1u);  // the container is not a vehicle
  EXPECT_EQ(frames[1].vehicles[0].id, "veh0");
  EXPECT_EQ(frames[1].vehicles[0].x, 101.89);
  EXPECT_EQ(frames[1].vehicles[0].z, 1.45);
  EXPECT_EQ(frames[1].vehicles[0].speed_mps, 13.9);
  EXPECT_EQ(frames[1].vehicles[0].slope_deg, -2.4);

  EXPECT_EQ(frames[2].time_s, 0.2);
  EXPECT_EQ(frames[2].line, 12);
  EXPECT_TRUE(frames[2].vehicles.empty());

  // --human-readable-time: 1 h 2 min 3.5 s.
  EXPECT_EQ(frames[3].time_s, 3723.5);
  ASSERT_EQ(frames[3].vehicles.size(), 1u);
  EXPECT_EQ(frames[3].vehicles[0].x, 1000.0);
  EXPECT_EQ(frames[3].vehicles[0].y, -25.0);
  EXPECT_EQ(frames[3].vehicles[0].type, "DEFAULT_BIKETYPE");
  EXPECT_EQ(frames[3].vehicles[0].line, 13);
}

// 0.1 s trace, times 0.00 .. 10.00 (101 frames): "a" (car) at x = frame index,
// y = 0; "b" (truck) at (-i, 100); "c" (car) parked at (25, 2).
std::string filter_fcd() {
  std::string s = "<fcd-export>\n";
  char buf[256];
  for (int i = 0; i <= 100; ++i) {
    std::snprintf(buf, sizeof buf, "  <timestep time=\"%d.%02d\">\n", i / 10, (i % 10) * 10);
    s += buf;
    std::snprintf(buf, sizeof buf,
                  "    <vehicle id=\"a\" x=\"%d.00\" y=\"0.00\" angle=\"90.00\" type=\"car\" speed=\"10.00\"/>\n", i);
    s += buf;
    std::snprintf(buf, sizeof buf,
                  "    <vehicle id=\"b\" x=\"%d.00\" y=\"100.00\" angle=\"270.00\" type=\"truck\" speed=\"10.00\"/>\n", -i);
    s += buf;
    s += "    <vehicle id=\"c\" x=\"25.00\" y=\"2.00\" angle=\"0.00\" type=\"car\" speed=\"0.00\"/>\n";
    s += "  </timestep>\n";
  }
  return s + "</fcd-export>\n";
}

}  // namespace

TEST(FcdReader, ReadsPlainFrameByFrame) {
  TempDir dir;
  const fs::path p = dir.path / "small.fcd.xml";
  test::write_text(p, kSmallFcd);
  check_small(read_all(p));

  FcdReader r(p.string());
  EXPECT_EQ(r.path(), p.string());
  FcdFrame f;
  ASSERT_TRUE(r.next(f));
  EXPECT_EQ(r.frames_read(), 1u);  // pulled one timestep at a time
  ASSERT_TRUE(r.next(f));
  EXPECT_EQ(r.frames_read(), 2u);
  ASSERT_TRUE(r.next(f));
  ASSERT_TRUE(r.next(f));
  EXPECT_FALSE(r.next(f));
  EXPECT_FALSE(r.next(f));
  EXPECT_EQ(r.frames_read(), 4u);
}

TEST(FcdReader, ReadsGzipLikePlain) {
  TempDir dir;
  const fs::path p = dir.path / "small.fcd.xml.gz";
  write_gzip(p, kSmallFcd);
  check_small(read_all(p));
}

TEST(FcdReader, EmptyExportHasNoFrames) {
  TempDir dir;
  const fs::path p = dir.path / "empty.xml";
  test::write_text(p, "<fcd-export/>\n");
  FcdReader r(p.string());
  FcdFrame f;
  EXPECT_FALSE(r.next(f));
  EXPECT_EQ(r.frames_read(), 0u);
}

TEST(FcdFilter, TimeWindowInclusiveAndStopsEarly) {
  TempDir dir;
  const fs::path p = dir.path / "f.xml";
  test::write_text(p, filter_fcd());
  FcdFilter filter;
  filter.begin_s = 2.0;
  filter.end_s = 3.0;
  FcdReader r(p.string(), filter);
  FcdFrame f;
  std::vector<double> times;
  while (r.next(f)) {
    times.push_back(f.time_s);
    EXPECT_EQ(f.vehicles.size(), 3u);
  }
  ASSERT_EQ(times.size(), 11u);
  for (int k = 0; k <= 10; ++k) EXPECT_EQ(times[k], (20 + k) / 10.0);
  EXPECT_EQ(r.frames_read(), 31u);  // 0.0 .. 3.0; 3.1 ended the reading
}

TEST(FcdFilter, StopsWithoutReadingPastTheEnd) {
  TempDir dir;
  const fs::path p = dir.path / "tail.xml";
  // After t = 2 the file is broken three ways: NaN, duplicate id, no closing tags.
  test::write_text(p,
                   "<fcd-export>\n"
                   "<timestep time=\"0\"><vehicle id=\"a\" x=\"0\" y=\"0\" angle=\"0\" speed=\"1\"/></timestep>\n"
                   "<timestep time=\"1\"><vehicle id=\"a\" x=\"1\" y=\"0\" angle=\"0\" speed=\"1\"/></timestep>\n"
                   "<timestep time=\"2\"><vehicle id=\"a\" x=\"2\" y=\"0\" angle=\"0\" speed=\"1\"/></timestep>\n"
                   "<timestep time=\"3\"><vehicle id=\"a\" x=\"nan\" y=\"0\" angle=\"0\" speed=\"1\"/>"
                   "<vehicle id=\"a\" x=\"3\" y=\"0\" angle=\"0\" speed=\"1\"/>\n");
  FcdFilter filter;
  filter.end_s = 2.0;
  const auto frames = read_all(p, filter);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[2].vehicles.at(0).x, 2.0);
  EXPECT_NE(read_error(p), "");  // without the window it does fail
}

TEST(FcdFilter, StepOnTenthSecondTrace) {
  TempDir dir;
  const fs::path p = dir.path / "f.xml";
  test::write_text(p, filter_fcd());
  {
    FcdFilter filter;
    filter.step_s = 0.5;
    FcdReader r(p.string(), filter);
    FcdFrame f;
    std::vector<double> times;
    while (r.next(f)) times.push_back(f.time_s);
    ASSERT_EQ(times.size(), 21u);  // every 5th of 101 frames
    for (int k = 0; k <= 20; ++k) EXPECT_EQ(times[k], (5 * k) / 10.0);
    EXPECT_EQ(r.frames_read(), 101u);
  }
  {
    // 0.3 s: sums of 0.1-steps would drift (0.1 + 0.2 != 0.3); kept times must not.
    FcdFilter filter;
    filter.step_s = 0.3;
    const auto frames = read_all(p, filter);
    ASSERT_EQ(frames.size(), 34u);  // 0.0, 0.3, ..., 9.9
    for (int k = 0; k < 34; ++k) EXPECT_EQ(frames[k].time_s, (3 * k) / 10.0);
  }
  {
    FcdFilter filter;
    filter.step_s = 1.0;
    filter.begin_s = 2.5;
    filter.end_s = 5.0;
    const auto frames = read_all(p, filter);
    ASSERT_EQ(frames.size(), 3u);  // 2.5, 3.5, 4.5
    EXPECT_EQ(frames[0].time_s, 2.5);
    EXPECT_EQ(frames[1].time_s, 3.5);
    EXPECT_EQ(frames[2].time_s, 4.5);
  }
}

TEST(FcdFilter, IdsTypesArea) {
  TempDir dir;
  const fs::path p = dir.path / "f.xml.gz";
  write_gzip(p, filter_fcd());
  {
    FcdFilter filter;
    filter.ids = {"b"};
    const auto frames = read_all(p, filter);
    ASSERT_EQ(frames.size(), 101u);
    for (std::size_t i = 0; i < frames.size(); ++i) {
      ASSERT_EQ(frames[i].vehicles.size(), 1u);
      EXPECT_EQ(frames[i].vehicles[0].id, "b");
      EXPECT_EQ(frames[i].vehicles[0].x, -static_cast<double>(i));
    }
  }
  {
    FcdFilter filter;
    filter.types = {"car"};
    for (const auto& f : read_all(p, filter)) {
      ASSERT_EQ(f.vehicles.size(), 2u);
      EXPECT_EQ(f.vehicles[0].id, "a");
      EXPECT_EQ(f.vehicles[1].id, "c");
    }
  }
  {
    // "a" is inside for frames 20..30 (x = 20..30, edges included), "c" always, "b" never.
    FcdFilter filter;
    filter.area = pipeline::FcdArea{20.0, 0.0, 30.0, 5.0};
    const auto frames = read_all(p, filter);
    ASSERT_EQ(frames.size(), 101u);
    for (int i = 0; i <= 100; ++i) {
      const auto& v = frames[i].vehicles;
      if (i >= 20 && i <= 30) {
        ASSERT_EQ(v.size(), 2u) << "frame " << i;
        EXPECT_EQ(v[0].id, "a");
        EXPECT_EQ(v[0].x, static_cast<double>(i));
        EXPECT_EQ(v[1].id, "c");
      } else {
        ASSERT_EQ(v.size(), 1u) << "frame " << i;
        EXPECT_EQ(v[0].id, "c");
      }
    }
  }
  {
    // Nothing left after filtering: frames still come (time goes on).
    FcdFilter filter;
    filter.ids = {"nobody"};
    const auto frames = read_all(p, filter);
    ASSERT_EQ(frames.size(), 101u);
    EXPECT_EQ(frames.back().time_s, 10.0);
    for (const auto& f : frames) EXPECT_TRUE(f.vehicles.empty());
  }
}

namespace {

// "line <n>" not followed by another digit.
bool names_line(const std::string& msg, long n) {
  const std::string key = "line " + std::to_string(n);
  for (auto at = msg.find(key); at != std::string::npos; at = msg.find(key, at + 1)) {
    const auto after = at + key.size();
    if (after == msg.size() || !std::isdigit(static_cast<unsigned char>(msg[after]))) return true;
  }
  return false;
}

// Writes `text` and expects an InputError naming the file, "line <line>" and `what`.
void expect_error(const fs::path& p, const std::string& text, long line, const std::string& what) {
  test::write_text(p, text);
  const std::string msg = read_error(p);
  EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
  EXPECT_TRUE(names_line(msg, line)) << "expected line " << line << ": " << msg;
  EXPECT_NE(msg.find(what), std::string::npos) << msg;
}

const std::string kHead = "<?xml version=\"1.0\"?>\n<fcd-export>\n";
const std::string kVeh0 = "<vehicle id=\"v0\" x=\"1\" y=\"2\" angle=\"3\" speed=\"4\"/>\n";

}  // namespace

TEST(FcdErrors, NamedWithFileAndLine) {
  TempDir dir;
  expect_error(dir.path / "mono.xml",
               kHead + "<timestep time=\"0.00\">\n" + kVeh0 + "</timestep>\n<timestep time=\"1.00\">\n</timestep>\n" +
                   "<timestep time=\"1.00\">\n" + kVeh0 + "</timestep>\n</fcd-export>\n",
               8, "non-monotonic time");
  expect_error(dir.path / "back.xml",
               kHead + "<timestep time=\"5\"/>\n<timestep time=\"4.5\"/>\n</fcd-export>\n", 4, "non-monotonic time");
  expect_error(dir.path / "dup.xml",
               kHead + "<timestep time=\"0\">\n" + kVeh0 +
                   "<vehicle id=\"v1\" x=\"1\" y=\"2\" angle=\"3\" speed=\"4\"/>\n" + kVeh0 + "</timestep>\n</fcd-export>\n",
               6, "duplicate vehicle id");
  expect_error(dir.path / "nox.xml",
               kHead + "<timestep time=\"0\">\n" + kVeh0 + kVeh0.substr(0, 16) + kVeh0.substr(22) +
                   "</timestep>\n</fcd-export>\n",
               5, "has no x attribute");
  expect_error(dir.path / "noid.xml",
               kHead + "<timestep time=\"0\">\n<vehicle x=\"1\" y=\"2\" angle=\"3\" speed=\"4\"/>\n</timestep>\n</fcd-export>\n",
               4, "has no id");
  expect_error(dir.path / "nan.xml",
               kHead + "<timestep time=\"0\">\n" + kVeh0 + "</timestep>\n<timestep time=\"1\">\n" +
                   "<vehicle id=\"v0\" x=\"1\" y=\"2\" angle=\"3\" speed=\"nan\"/>\n</timestep>\n</fcd-export>\n",
               7, "speed='nan'");
  expect_error(dir.path / "inf.xml",
               kHead + "<timestep time=\"0\">\n<vehicle id=\"v0\" x=\"1\" y=\"inf\" angle=\"3\" speed=\"4\"/>\n</timestep>\n</fcd-export>\n",
               4, "y='inf'");
  expect_error(dir.path / "text.xml",
               kHead + "<timestep time=\"0\">\n<vehicle id=\"v0\" x=\"1\" y=\"2\" angle=\"north\" speed=\"4\"/>\n</timestep>\n</fcd-export>\n",
               4, "angle='north' is not a finite number");
  expect_error(dir.path / "time.xml", kHead + "<timestep time=\"soon\"/>\n</fcd-export>\n", 3, "time='soon'");
  expect_error(dir.path / "root.xml",
               "<?xml version=\"1.0\"?>\n<routes>\n<vehicle id=\"v0\" depart=\"0\"/>\n</routes>\n", 2, "not <fcd-export>");
  // Truncated XML: the data ends on line 5 (no final newline).
  expect_error(dir.path / "cut.xml", kHead + "<timestep time=\"0\">\n" + kVeh0 + "</timestep>", 5, "malformed XML");
}

TEST(FcdErrors, CutXmlKeepsEarlierFramesAndRepeats) {
  TempDir dir;
  const fs::path p = dir.path / "cut.xml";
  test::write_text(p, kHead + "<timestep time=\"0\">\n" + kVeh0 + "</timestep>\n<timestep time=\"1\">\n" + kVeh0);
  FcdReader r(p.string());
  FcdFrame f;
  ASSERT_TRUE(r.next(f));  // the complete frame comes first
  EXPECT_EQ(f.time_s, 0.0);
  EXPECT_THROW(r.next(f), meshkit::InputError);
  EXPECT_THROW(r.next(f), meshkit::InputError);  // and stays failed
}

TEST(FcdErrors, TruncatedGzip) {
  TempDir dir;
  const fs::path whole = dir.path / "whole.xml.gz", cut = dir.path / "cut.xml.gz";
  // Varied numbers so that the compressed size grows with the text.
  std::string text = "<fcd-export>\n";
  char buf[200];
  for (int t = 0; t < 400; ++t) {
    std::snprintf(buf, sizeof buf, "<timestep time=\"%d\">\n", t);
    text += buf;
    for (int v = 0; v < 10; ++v) {
      std::snprintf(buf, sizeof buf, "<vehicle id=\"v%d\" x=\"%.3f\" y=\"%.3f\" angle=\"%.2f\" speed=\"%.2f\"/>\n", v,
                    std::sin(t * 0.37 + v) * 1000, std::cos(t * 0.11 + v) * 1000, std::fmod(t * 7.3 + v * 13, 360.0),
                    std::fabs(std::sin(t + v)) * 30);
      text += buf;
    }
    text += "</timestep>\n";
  }
  text += "</fcd-export>\n";
  write_gzip(whole, text);
  EXPECT_EQ(read_all(whole).size(), 400u);

  const std::string bytes = test::read_text(whole);
  test::write_text(cut, bytes.substr(0, bytes.size() / 2));
  // What zlib itself recovers from the cut archive: the readable data ends on line `lines`.
  long lines = 1;
  {
    gzFile g = gzopen(cut.c_str(), "rb");
    ASSERT_NE(g, nullptr);
    int n;
    while ((n = gzread(g, buf, sizeof buf)) > 0) lines += static_cast<long>(std::count(buf, buf + n, '\n'));
    gzclose(g);
  }
  ASSERT_GT(lines, 100);
  ASSERT_LT(lines, static_cast<long>(std::count(text.begin(), text.end(), '\n')));

  FcdReader r(cut.string());
  FcdFrame f;
  std::size_t frames = 0;
  std::string msg;
  try {
    while (r.next(f)) ++frames;
  } catch (const meshkit::InputError& e) {
    msg = e.what();
  }
  EXPECT_GT(frames, 10u);  // the frames before the cut come first
  EXPECT_NE(msg.find(cut.string()), std::string::npos) << msg;
  EXPECT_TRUE(names_line(msg, lines)) << "expected line " << lines << ": " << msg;
  EXPECT_NE(msg.find("truncated"), std::string::npos) << msg;
}

TEST(FcdErrors, MissingFile) {
  TempDir dir;
  const fs::path p = dir.path / "nope.xml";
  try {
    FcdReader r(p.string());
    FAIL() << "no error";
  } catch (const meshkit::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("nope.xml"), std::string::npos);
  }
}

TEST(XmlPullParser, SuspendGivesOneElementPerPump) {
  TempDir dir;
  const fs::path p = dir.path / "a.xml";
  test::write_text(p, "<r>\n<a n=\"1\"/>\n<a n=\"2\"/>\n<a n=\"3\"/>\n</r>\n");
  std::vector<std::string> seen;
  meshkit::XmlPullParser* self = nullptr;
  meshkit::XmlCallbacks cb;
  cb.start = [&](const meshkit::XmlStart& e) {
    if (e.name != "a") return;
    seen.push_back(e.attr("n"));
    self->suspend();
  };
  meshkit::XmlPullParser parser(p.string(), cb);
  self = &parser;
  parser.suspend();  // outside a callback: no effect
  EXPECT_TRUE(parser.pump());
  EXPECT_EQ(seen, std::vector<std::string>({"1"}));
  EXPECT_EQ(parser.line(), 2);
  EXPECT_TRUE(parser.pump());
  EXPECT_EQ(seen.size(), 2u);
  EXPECT_TRUE(parser.pump());
  EXPECT_EQ(seen.size(), 3u);
  while (parser.pump()) {
  }
  EXPECT_TRUE(parser.finished());
  EXPECT_EQ(seen.size(), 3u);

  // parse_xml_file still reads everything in one call.
  std::size_t count = 0;
  meshkit::XmlCallbacks all;
  all.start = [&](const meshkit::XmlStart& e) { count += e.name == "a"; };
  meshkit::parse_xml_file(p.string(), all);
  EXPECT_EQ(count, 3u);
}

TEST(FcdMemory, MillionsOfLinesInFlatMemory) {
  TempDir dir;
  const fs::path p = dir.path / "big.fcd.xml.gz";
  constexpr int kSteps = 20000, kVehicles = 100;
  const auto t0 = std::chrono::steady_clock::now();
  std::uint64_t raw_bytes = 0;
  {
    // Streamed out one timestep at a time.
    gzFile g = gzopen(p.c_str(), "wb1");
    ASSERT_NE(g, nullptr);
    std::string block;
    char buf[256];
    const std::string head = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<fcd-export>\n";
    gzwrite(g, head.data(), static_cast<unsigned>(head.size()));
    raw_bytes += head.size();
    for (int t = 0; t < kSteps; ++t) {
      block.clear();
      std::snprintf(buf, sizeof buf, "    <timestep time=\"%d.%d0\">\n", t / 10, t % 10);
      block += buf;
      for (int v = 0; v < kVehicles; ++v) {
        const int n = std::snprintf(
            buf, sizeof buf,
            "        <vehicle id=\"veh%d\" x=\"%d.%02d\" y=\"%d.%02d\" angle=\"%d.%02d\" type=\"passenger%d\" "
            "speed=\"%d.%02d\" pos=\"%d.%02d\" lane=\"edge%d_0\" slope=\"0.00\"/>\n",
            v, (t + v * 37) % 5000, v % 100, (t * 3 + v) % 4000, t % 100, (t + v) % 360, v % 100, v % 4, v % 30,
            t % 100, t % 500, v, v % 50);
        block.append(buf, static_cast<std::size_t>(n));
      }
      block += "    </timestep>\n";
      ASSERT_EQ(gzwrite(g, block.data(), static_cast<unsigned>(block.size())), static_cast<int>(block.size()));
      raw_bytes += block.size();
    }
    const std::string tail = "</fcd-export>\n";
    gzwrite(g, tail.data(), static_cast<unsigned>(tail.size()));
    raw_bytes += tail.size();
    ASSERT_EQ(gzclose(g), Z_OK);
  }
  const auto t1 = std::chrono::steady_clock::now();
  const double gz_bytes = static_cast<double>(fs::file_size(p));

  const long rss0 = vm_rss_kib();
  ASSERT_GT(rss0, 0);
  long peak = rss0;
  std::uint64_t frames = 0, vehicles = 0;
  double last_time = -1, checksum = 0;
  {
    FcdReader r(p.string());
    FcdFrame f;
    while (r.next(f)) {
      ASSERT_EQ(f.vehicles.size(), static_cast<std::size_t>(kVehicles));
      vehicles += f.vehicles.size();
      checksum += f.vehicles[7].x;
      last_time = f.time_s;
      if (++frames % 1000 == 0) peak = std::max(peak, vm_rss_kib());
    }
    peak = std::max(peak, vm_rss_kib());
    EXPECT_EQ(r.frames_read(), static_cast<std::uint64_t>(kSteps));
  }
  const auto t2 = std::chrono::steady_clock::now();
  EXPECT_EQ(frames, static_cast<std::uint64_t>(kSteps));
  EXPECT_EQ(vehicles, static_cast<std::uint64_t>(kSteps) * kVehicles);
  EXPECT_EQ(last_time, (kSteps - 1) / 10.0);
  // veh7's x, summed over frames as written: (t + 259) % 5000 + 0.07.
  double expected = 0;
  for (int t = 0; t < kSteps; ++t) expected += ((t + 7 * 37) % 5000) + 0.07;
  EXPECT_NEAR(checksum, expected, 1e-6 * expected);

  const double growth_mb = static_cast<double>(peak - rss0) / 1024.0;
  EXPECT_LT(growth_mb, 20.0);
  const double write_s = std::chrono::duration<double>(t1 - t0).count();
  const double read_s = std::chrono::duration<double>(t2 - t1).count();
  std::printf(
      "[ fcd ] %llu vehicle lines, %.1f MB XML, %.1f MB gzip: written in %.2f s, read in %.2f s = %.2f M lines/s, "
      "%.1f MB/s XML, %.1f MB/s gzip; RSS growth %.2f MB\n",
      static_cast<unsigned long long>(vehicles), static_cast<double>(raw_bytes) / 1e6, gz_bytes / 1e6, write_s, read_s,
      static_cast<double>(vehicles) / read_s / 1e6, static_cast<double>(raw_bytes) / 1e6 / read_s, gz_bytes / 1e6 / read_s,
      growth_mb);
  RecordProperty("read_seconds", std::to_string(read_s));
  RecordProperty("rss_growth_mb", std::to_string(growth_mb));
}

namespace {

void expect_type(const VTypeMap& m, const std::string& id, const std::string& vclass, double l, double w, double h,
                 bool known = true) {
  const auto r = m.resolve(id);
  ASSERT_TRUE(r.has_value()) << id;
  EXPECT_EQ(r->vtype, id);
  EXPECT_EQ(r->vclass, vclass) << id;
  EXPECT_DOUBLE_EQ(r->length_m, l) << id;
  EXPECT_DOUBLE_EQ(r->width_m, w) << id;
  EXPECT_DOUBLE_EQ(r->height_m, h) << id;
  EXPECT_EQ(r->known, known) << id;
}

}  // namespace

TEST(VTypeMap, BuiltinsWithoutFiles) {
  VTypeMap m;
  EXPECT_EQ(m.size(), 0u);
  // SUMO's defaults: passenger 5 x 1.8 x 1.5, bicycle 1.6 x 0.65 x 1.7.
  expect_type(m, "DEFAULT_VEHTYPE", "passenger", 5.0, 1.8, 1.5);
  expect_type(m, "DEFAULT_BIKETYPE", "bicycle", 1.6, 0.65, 1.7);
  expect_type(m, "DEFAULT_TAXITYPE", "taxi", 5.0, 1.8, 1.5);
  EXPECT_FALSE(m.resolve("DEFAULT_PEDTYPE").has_value());
  EXPECT_FALSE(m.resolve("DEFAULT_RAILTYPE").has_value());
  EXPECT_FALSE(m.resolve("DEFAULT_CONTAINERTYPE").has_value());
  expect_type(m, "mystery", "passenger", 5.0, 1.8, 1.5, false);
}

TEST(VTypeMap, RouteFilesThroughSumocfg) {
  TempDir dir;
  fs::create_directories(dir.path / "scenario" / "routes");
  test::write_text(dir.path / "scenario" / "routes" / "demand.rou.xml", R"(<routes>
    <vType id="lkw" vClass="truck" length="10"/>
    <vType id="plain" accel="2.6"/>
    <vTypeDistribution id="mix">
        <vType id="small" vClass="passenger" length="4.2" width="1.7" probability="0.5"/>
        <vType id="van" vClass="delivery" height="2.5" probability="0.5"/>
    </vTypeDistribution>
    <vType id="walker" vClass="pedestrian"/>
    <vType id="tram1" vClass="tram"/>
    <vType id="police" vClass="authority"/>
    <vehicle id="v0" type="lkw" depart="0"><route edges="a b"/></vehicle>
</routes>
)");
  test::write_text(dir.path / "scenario" / "types.add.xml",
                   "<additional>\n  <vType id=\"DEFAULT_VEHTYPE\" vClass=\"truck\" height=\"3\"/>\n"
                   "  <vType id=\"lkw\" vClass=\"truck\" length=\"10\"/>\n</additional>\n");
  const fs::path cfg = dir.path / "scenario" / "run.sumocfg";
  test::write_text(cfg, R"(<configuration>
    <input>
        <net-file value="net.net.xml"/>
        <route-files value="routes/demand.rou.xml"/>
        <additional-files value=" types.add.xml , "/>
    </input>
</configuration>
)");

  const auto inputs = pipeline::sumocfg_inputs(cfg.string());
  ASSERT_EQ(inputs.size(), 2u);
  EXPECT_EQ(inputs[0].key, "route-files");
  EXPECT_EQ(fs::path(inputs[0].path), dir.path / "scenario" / "routes" / "demand.rou.xml");
  EXPECT_EQ(inputs[1].key, "additional-files");
  EXPECT_EQ(inputs[1].line, 5);

  VTypeMap m;
  m.add_sumocfg(cfg.string());
  EXPECT_EQ(m.size(), 8u);  // the identical "lkw" again adds nothing
  expect_type(m, "lkw", "truck", 10.0, 2.4, 2.4);            // given length, class width/height
  expect_type(m, "plain", "passenger", 5.0, 1.8, 1.5);       // no vClass: passenger
  expect_type(m, "small", "passenger", 4.2, 1.7, 1.5);       // distribution member
  expect_type(m, "van", "delivery", 6.5, 2.16, 2.5);         // distribution member
  expect_type(m, "police", "passenger", 5.0, 1.8, 1.5);      // authority: car-like
  expect_type(m, "DEFAULT_VEHTYPE", "truck", 7.1, 2.4, 3.0);  // the file's redefinition wins
  EXPECT_FALSE(m.resolve("walker").has_value());
  EXPECT_FALSE(m.resolve("tram1").has_value());
  expect_type(m, "mix", "passenger", 5.0, 1.8, 1.5, false);  // a distribution id is not a vType
  expect_type(m, "unknown", "passenger", 5.0, 1.8, 1.5, false);

  // Conflicting redefinition.
  test::write_text(dir.path / "scenario" / "clash.xml", "<routes>\n<vType id=\"lkw\" vClass=\"bus\"/>\n</routes>\n");
  try {
    m.add_file((dir.path / "scenario" / "clash.xml").string());
    FAIL() << "no error";
  } catch (const meshkit::InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("clash.xml"), std::string::npos) << msg;
    EXPECT_NE(msg.find("line 2"), std::string::npos) << msg;
    EXPECT_NE(msg.find("demand.rou.xml"), std::string::npos) << msg;
  }

  // A cfg naming a missing route file.
  const fs::path bad = dir.path / "scenario" / "bad.sumocfg";
  test::write_text(bad, "<configuration>\n<input>\n<route-files value=\"routes/demand.rou.xml,gone.rou.xml\"/>\n"
                        "</input>\n</configuration>\n");
  VTypeMap m2;
  try {
    m2.add_sumocfg(bad.string());
    FAIL() << "no error";
  } catch (const meshkit::InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(bad.string()), std::string::npos) << msg;
    EXPECT_NE(msg.find("route-files"), std::string::npos) << msg;
    EXPECT_NE(msg.find("gone.rou.xml"), std::string::npos) << msg;
    EXPECT_NE(msg.find("line 3"), std::string::npos) << msg;
  }
  EXPECT_EQ(m2.size(), 0u);  // nothing half-loaded
}

TEST(VTypeMap, BadHersfeldScenario) {
  const fs::path folder = test::shared_data() / "dlr-sumo-scenarios-badhersfeld";
  if (!fs::is_directory(folder)) GTEST_SKIP() << folder << " is absent";
  fs::path cfg;
  for (const auto& e : fs::directory_iterator(folder))
    if (e.path().extension() == ".sumocfg") cfg = e.path();
  if (cfg.empty()) GTEST_SKIP() << "no .sumocfg in " << folder;

  // The snapshot lacks some of the cfg's files (its NOTICE.md says so): take
  // those present, here or under their file name in the folder, plus the
  // folder's route files.
  VTypeMap m;
  std::set<fs::path> files;
  bool missing = false;
  for (const auto& in : pipeline::sumocfg_inputs(cfg.string())) {
    fs::path p = in.path;
    if (!fs::exists(p)) p = folder / fs::path(in.path).filename();
    if (!fs::exists(p)) {
      missing = true;
      continue;
    }
    files.insert(p);
  }
  for (const auto& e : fs::directory_iterator(folder))
    if (e.path().string().ends_with(".rou.xml")) files.insert(e.path());
  if (missing) {
    VTypeMap whole;
    EXPECT_THROW(whole.add_sumocfg(cfg.string()), meshkit::InputError);
  }
  std::vector<meshkit::SumoVType> vtypes;
  for (const auto& f : files) {
    m.add_file(f.string());
    for (auto& t : meshkit::read_sumo_vtypes(f.string())) vtypes.push_back(t);
  }
  ASSERT_GE(vtypes.size(), 20u);
  EXPECT_EQ(m.size(), vtypes.size());  // ids are unique across the files

  const std::set<std::string> not_modelled = {"pedestrian", "rail", "rail_urban", "rail_electric", "tram", "ship",
                                              "subway", "cable_car"};
  for (const auto& t : vtypes) {
    const auto r = m.resolve(t.id);
    if (not_modelled.count(t.vclass)) {
      EXPECT_FALSE(r.has_value()) << t.id << " (" << t.vclass << ")";
      continue;
    }
    ASSERT_TRUE(r.has_value()) << t.id << " (" << t.vclass << ")";
    EXPECT_TRUE(r->known) << t.id;
    EXPECT_GT(r->length_m, 0) << t.id;
    EXPECT_GT(r->width_m, 0) << t.id;
    EXPECT_GT(r->height_m, 0) << t.id;
  }
  // Spot checks against the files' vClass attributes.
  expect_type(m, "passenger2a", "passenger", 5.0, 1.8, 1.5);  // a vTypeDistribution member
  expect_type(m, "trailer", "trailer", 16.5, 2.55, 4.0);      // the truck demand's type
  expect_type(m, "bus", "bus", 12.0, 2.5, 3.4);               // the GTFS buses' type
  expect_type(m, "uber", "taxi", 5.0, 1.8, 1.5);
  expect_type(m, "army", "passenger", 5.0, 1.8, 1.5);
  EXPECT_FALSE(m.resolve("pedestrian").has_value());
  EXPECT_FALSE(m.resolve("train").has_value());
  EXPECT_FALSE(m.resolve("tram").has_value());
  // Every vehicle of the route files has a type that resolves.
  for (const auto& f : files) {
    if (!f.string().ends_with(".rou.xml")) continue;
    meshkit::XmlCallbacks cb;
    std::size_t vehicles = 0;
    cb.start = [&](const meshkit::XmlStart& e) {
      if (e.name != "vehicle" && e.name != "trip") return;
      ++vehicles;
      const char* type = e.attr("type");
      const auto r = m.resolve(type ? type : "DEFAULT_VEHTYPE");
      ASSERT_TRUE(r.has_value());
      EXPECT_TRUE(r->known) << (type ? type : "DEFAULT_VEHTYPE");
    };
    meshkit::parse_xml_file(f.string(), cb);
    EXPECT_GT(vehicles, 0u) << f;
  }
}
