// The ns-3 lookup table through the CLI: corrupt tables named by the reader,
// `raysweep validate` and `raysweep info`; `raysweep ns3-table` writes through
// a temporary file, records provenance and refuses bad settings.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "generators/formats.hpp"
#include "generators/ns3_table/ns3_table.hpp"
#include "meshkit/errors.hpp"
#include "ns3_table_fixtures.hpp"
#include "test_util.hpp"

namespace rg = raysweep::generators;
namespace fs = std::filesystem;
using namespace raysweep::test;
using namespace raysweep::test::ns3;

TEST(Ns3Table, CorruptFilesNameFileAndElement) {
  const fs::path dir = scratch_dir("ns3_table_corrupt");
  const fs::path good = dir / "good.h5";
  rg::build_ns3_table(write_dataset(dir, true).string(), good, header(), 4);
  auto load_error = [](const fs::path& p) {
    try {
      rg::Ns3Table::load(p.string());
    } catch (const raysweep::meshkit::InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  // Missing, not HDF5, truncated.
  EXPECT_NE(load_error(dir / "missing.h5").find((dir / "missing.h5").string()), std::string::npos);
  write_text(dir / "text.h5", "not hdf5");
  EXPECT_NE(load_error(dir / "text.h5").find("not an HDF5 file"), std::string::npos);
  {
    const std::string bytes = read_text(good);
    write_text(dir / "half.h5", bytes.substr(0, bytes.size() / 2));
  }
  EXPECT_NE(load_error(dir / "half.h5").find((dir / "half.h5").string()), std::string::npos);
  EXPECT_FALSE(rg::validate_dataset((dir / "half.h5").string()).empty());
  // A channel dataset is not a table.
  const std::string e = load_error(dir / "cfr.h5");
  EXPECT_NE(e.find("attribute format"), std::string::npos) << e;
  // Through the CLI: validate says INVALID (exit 1), info fails naming the file (exit 2).
  const auto v = run_raysweep("validate " + (dir / "half.h5").string());
  EXPECT_EQ(v.exit_code, 1) << v.output;
  const auto i = run_raysweep("info " + (dir / "text.h5").string());
  EXPECT_EQ(i.exit_code, 2) << i.output;
  EXPECT_NE(i.output.find("text.h5"), std::string::npos);
}

TEST(Ns3Table, CliWritesThroughATemporaryFileAndRecordsProvenance) {
  const fs::path dir = scratch_dir("ns3_table_cli");
  const fs::path ds = write_dataset(dir, true);
  write_text(dir / "c.toml", "[ns3]\nsubcarriers_per_band = 2\n");
  const auto r = run_raysweep("-q ns3-table --channels " + ds.string() + " --out " + (dir / "t.h5").string() +
                              " --config " + (dir / "c.toml").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_FALSE(fs::exists(dir / "t.h5.tmp"));
  const rg::Ns3Table t = rg::Ns3Table::load((dir / "t.h5").string());
  EXPECT_EQ(t.bands().count(), 4u);
  EXPECT_EQ(t.provenance().value("stage", std::string()), "ns3-table");
  const auto v = run_raysweep("validate " + (dir / "t.h5").string());
  EXPECT_EQ(v.exit_code, 0) << v.output;
  // Usage and config errors: exit 2, naming the key.
  write_text(dir / "bad.toml", "[ns3]\nbands = 2\n");
  const auto b = run_raysweep("ns3-table --channels " + ds.string() + " --out " + (dir / "u.h5").string() +
                              " --config " + (dir / "bad.toml").string());
  EXPECT_EQ(b.exit_code, 2);
  EXPECT_NE(b.output.find("ns3.bands"), std::string::npos) << b.output;
  EXPECT_FALSE(fs::exists(dir / "u.h5"));
  EXPECT_EQ(run_raysweep("ns3-table --out x.h5").exit_code, 2);
}
