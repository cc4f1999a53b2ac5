// Scale-out end to end on the demo city: shards of a sweep
// (`run --shard`, `sweep --shard`) merged by copy are byte-identical to the
// single-process dataset, and the virtual merge reads identically (h5diff);
// the merge refuses gaps, duplicates and shards of other runs; an interrupted
// shard resumes its own blocks; `mpirun ... run --mpi` gives the same file,
// and a failing rank fails the job and is redone alone by a rerun.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <unistd.h>

#include "hdf5_test_util.hpp"
#include "test_util.hpp"

using namespace raysweep::test;
using nlohmann::json;

namespace {

fs::path demo() { return source_dir() / "datasets/demo"; }

// 30 frames in 6 blocks of 5, cheap tracer settings, one SINR model: every
// stage of `run`, in seconds.
std::string city_text() {
  return "[city]\nname = \"mini\"\nosm = \"" + (demo() / "kirchberg.osm").string() + "\"\nnet = \"" +
         (demo() / "kirchberg.net.xml").string() +
         "\"\n[traffic]\nseed = 5\nend_s = 30\nperiod_s = 2\n"
         "[sweep]\nbegin_s = 25\nend_s = 27.95\nblock_frames = 5\ncfr = \"80211p\"\n"
         "[tracer]\nrays_per_source = 1024\nmax_depth = 2\n"
         "[sinr]\nactive_vehicles = 6\nmodels = [\"ray\"]\nisolated_runs = false\n";
}

// A city folder whose shared stages and single-process dataset are built
// (once per process: ctest runs every test in its own), and that dataset.
struct City {
  fs::path dir, toml, out, reference;
};
const City& city() {
  static const City c = [] {
    City c;
    c.dir = fs::temp_directory_path() / "raysweep-tests" / ("cli_shard_city." + std::to_string(getpid()));
    fs::remove_all(c.dir);
    fs::create_directories(c.dir);
    c.toml = c.dir / "city.toml";
    c.out = c.dir / "out";
    c.reference = c.dir / "reference.h5";
    write_text(c.toml, city_text());
    auto r = run_raysweep("run " + c.toml.string() + " --out " + c.out.string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    fs::copy_file(c.out / "dataset.h5", c.reference);
    return c;
  }();
  return c;
}

std::string run_city(const std::string& opts) {
  return "run " + city().toml.string() + " --out " + city().out.string() + " " + opts;
}

// Forget the sharded and merged outputs of an earlier step (not the shared stages).
void clear_sweep_outputs() {
  fs::remove_all(city().out / "shards");
  fs::remove(city().out / "dataset.h5");
  for (const auto& e : fs::directory_iterator(city().out / ".stamps"))
    if (e.path().filename().string().rfind("sweep", 0) == 0) fs::remove(e.path());
}

std::string sweep_args(const fs::path& config) {
  const fs::path o = city().out;
  return "sweep --scene " + (o / "scene").string() + " --vehicles " + (o / "vehicles").string() + " --fcd " +
         (o / "traffic/fcd.xml.gz").string() + " --vtypes " + (o / "traffic/vtypes.add.xml").string() +
         " --config " + config.string();
}

// A coherent sweep whose frames carry the sequences of the two before and
// share their diffuse lattices (both restart with each block, the unit
// shards share).
// Store level paths with each link's 4 strongest paths: merges and resumes keep it.
void write_sweep_config(const fs::path& p, int max_depth = 2) {
  write_text(p, "[sweep]\nbegin_s = 25\nend_s = 27.95\nblock_frames = 5\ncoherence = true\n"
                "store = \"paths\"\npaths_top_k = 4\nlattice_frames = 3\ndiffuse_frames = 2\n"
                "[tracer]\nrays_per_source = 1024\nmax_depth = " +
                    std::to_string(max_depth) + "\n");
}

bool same_bytes(const fs::path& a, const fs::path& b) { return read_bytes(a) == read_bytes(b); }

}  // namespace

TEST(CliShard, RunShardsMergeIntoTheSingleProcessDatasetByteForByte) {
  const City& c = city();
  const auto ref_time = read_ds<double>(c.reference, "/frames/time_s", H5T_NATIVE_DOUBLE);
  ASSERT_EQ(ref_time.size(), 30u);
  for (int n : {1, 3, 4, 8}) {  // 8 > 6 blocks: two empty shards
    clear_sweep_outputs();
    for (int i = 0; i < n; ++i) {
      auto r = run_raysweep(run_city("--shard " + std::to_string(i) + "/" + std::to_string(n)));
      ASSERT_EQ(r.exit_code, 0) << r.output;
      EXPECT_EQ(r.output.find("sinr"), std::string::npos) << "a shard stops after its sweep\n" << r.output;
    }
    EXPECT_FALSE(fs::exists(c.out / "dataset.h5"));
    if (n == 8) {
      const fs::path empty = c.out / "shards/dataset.7-of-8.h5";
      EXPECT_EQ(json::parse(str_attr(empty, "shard"))["blocks"], json::array());
      EXPECT_EQ(run_raysweep("validate " + empty.string()).exit_code, 0);
    }
    if (n == 4) {
      // Interleaved: shard 1 of 4 holds blocks 1 and 5, frames 5..9 and 25..29.
      const fs::path s1 = c.out / "shards/dataset.1-of-4.h5";
      const json rec = json::parse(str_attr(s1, "shard"));
      EXPECT_EQ(rec["blocks"], json::array({1, 5})) << rec;
      EXPECT_EQ(rec["frames_total"], 30);
      const auto t = read_ds<double>(s1, "/frames/time_s", H5T_NATIVE_DOUBLE);
      ASSERT_EQ(t.size(), 10u);
      for (int k = 0; k < 5; ++k) {
        EXPECT_EQ(t[k], ref_time[5 + k]);
        EXPECT_EQ(t[5 + k], ref_time[25 + k]);
      }
      EXPECT_EQ(run_raysweep("validate " + s1.string()).exit_code, 0);
      auto info = run_raysweep("info --json " + s1.string());
      ASSERT_EQ(info.exit_code, 0) << info.output;
      EXPECT_EQ(json::parse(info.output)["shard"]["index"], 1) << info.output;
      EXPECT_EQ(json::parse(info.output)["frames"], 10) << info.output;
    }
    auto r = run_raysweep(run_city("--merge"));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("merged " + std::to_string(n) + " shards (6 blocks, 30 frames)"), std::string::npos)
        << r.output;
    // The SINR stage runs after the merge; keyed by the dataset's SHA-256, it
    // finds the outcomes of the single-process dataset up to date.
    EXPECT_NE(r.output.find("[5/5] sinr: up to date"), std::string::npos) << r.output;
    EXPECT_TRUE(same_bytes(c.out / "dataset.h5", c.reference)) << n << " shards";
    r = run_command("h5diff " + (c.out / "dataset.h5").string() + " " + c.reference.string());
    EXPECT_EQ(r.exit_code, 0) << n << " shards\n" << r.output;
    EXPECT_FALSE(has_attr(c.out / "dataset.h5", "shard"));
    const json merge = json::parse(read_text(c.out / "dataset.h5.merge.json"));
    EXPECT_EQ(merge["shards"].size(), static_cast<std::size_t>(n));
  }

  // The virtual merge over the 4 shards reads the same values without holding them.
  clear_sweep_outputs();
  for (int i = 0; i < 4; ++i) ASSERT_EQ(run_raysweep(run_city("--shard " + std::to_string(i) + "/4")).exit_code, 0);
  auto r = run_raysweep(run_city("--merge --virtual"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("sinr: ray"), std::string::npos) << "SINR on the virtual dataset\n" << r.output;
  EXPECT_LT(fs::file_size(c.out / "dataset.h5"), fs::file_size(c.reference) / 4);
  r = run_command("cd / && h5diff " + (c.out / "dataset.h5").string() + " " + c.reference.string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = run_command("h5dump -p -H -d /links/gain_incoherent_db " + (c.out / "dataset.h5").string());
  EXPECT_NE(r.output.find("shards/dataset.3-of-4.h5"), std::string::npos) << r.output;
  EXPECT_EQ(run_raysweep("validate " + (c.out / "dataset.h5").string()).exit_code, 0);
}

TEST(CliShard, RunShardNeedsTheSharedStagesAndTheMergeItsShards) {
  auto dir = scratch_dir("unbuilt");
  write_text(dir / "city.toml", city_text());
  auto r = run_raysweep("run " + (dir / "city.toml").string() + " --out " + (dir / "o").string() + " --shard 0/2");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--until traffic"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "o/scene"));  // a shard does not build what every shard shares
  r = run_raysweep("run " + (dir / "city.toml").string() + " --out " + (dir / "o").string() + " --until traffic");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "o/traffic/fcd.xml.gz"));
  EXPECT_FALSE(fs::exists(dir / "o/dataset.h5"));
  r = run_raysweep("run " + (dir / "city.toml").string() + " --out " + (dir / "o").string() + " --merge");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("no shard files"), std::string::npos) << r.output;
  for (const char* bad : {"--shard 2/2", "--shard 1", "--shard x/2", "--shard 0/0"}) {
    r = run_raysweep("run " + (dir / "city.toml").string() + " --out " + (dir / "o").string() + " " + bad);
    EXPECT_EQ(r.exit_code, 2) << bad << "\n" << r.output;
    EXPECT_NE(r.output.find("I/N"), std::string::npos) << bad << "\n" << r.output;
  }
}

TEST(CliShard, SweepShardsMergeByteForByteAndTheMergeRefusesBadSets) {
  auto dir = scratch_dir("sweep");
  fs::create_directories(dir / "a");
  fs::create_directories(dir / "b");
  write_sweep_config(dir / "c.toml");
  // The single-process sweep and the merge of its shards, both named m.h5.
  auto r = run_command("cd " + (dir / "a").string() + " && " + RAYSWEEP_BINARY + " -q " + sweep_args(dir / "c.toml") +
                       " --out m.h5");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (int i = 0; i < 2; ++i) {
    r = run_command("cd " + (dir / "b").string() + " && " + RAYSWEEP_BINARY + " -q " + sweep_args(dir / "c.toml") +
                    " --shard " + std::to_string(i) + "/2 --out s" + std::to_string(i) + ".h5");
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  // Shards of another sweep: other settings, another split.
  write_sweep_config(dir / "other.toml", 1);
  r = run_command("cd " + (dir / "b").string() + " && " + RAYSWEEP_BINARY + " -q " + sweep_args(dir / "other.toml") +
                  " --shard 1/2 --out other1.h5");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_command("cd " + (dir / "b").string() + " && " + RAYSWEEP_BINARY + " -q " + sweep_args(dir / "c.toml") +
                  " --shard 1/3 --out third1.h5");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  fs::copy_file(dir / "b/s1.h5", dir / "b/s1copy.h5");

  struct Case {
    std::string files, expect;
  } cases[] = {
      {"s0.h5", "missing shard(s) 1-of-2"},
      {"s0.h5 s1.h5 s1copy.h5", "given twice: s1.h5 and s1copy.h5"},
      {"s0.h5 other1.h5", "other1.h5 is not a shard of the same sweep as s0.h5: input 'config' differs"},
      {"s0.h5 third1.h5", "not of 2"},
      {"s0.h5 s1.h5 ../a/m.h5", "not a shard file"},
  };
  for (const auto& c : cases) {
    r = run_command("cd " + (dir / "b").string() + " && " + RAYSWEEP_BINARY + " merge " + c.files + " --out m.h5");
    EXPECT_EQ(r.exit_code, 2) << c.files << "\n" << r.output;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.files << "\n" << r.output;
    EXPECT_FALSE(fs::exists(dir / "b/m.h5")) << c.files;
  }
  // In any order: the merged file records the single-process command (--out m.h5).
  r = run_command("cd " + (dir / "b").string() + " && " + RAYSWEEP_BINARY + " merge s1.h5 s0.h5 --out m.h5");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(same_bytes(dir / "a/m.h5", dir / "b/m.h5"));
  r = run_command("h5diff " + (dir / "a/m.h5").string() + " " + (dir / "b/m.h5").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(str_attr(dir / "b/m.h5", "store"), "paths");
  // The virtual merge at this level reads the same values.
  fs::remove(dir / "b/m.h5");
  r = run_command("cd " + (dir / "b").string() + " && " + RAYSWEEP_BINARY + " merge s0.h5 s1.h5 --virtual --out m.h5");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_command("cd / && h5diff " + (dir / "b/m.h5").string() + " " + (dir / "a/m.h5").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(run_raysweep("validate " + (dir / "b/m.h5").string()).exit_code, 0);
}

TEST(CliShard, AnInterruptedShardResumesItsOwnBlocks) {
  auto dir = scratch_dir("resume");
  write_sweep_config(dir / "c.toml");
  const std::string cmd = std::string(RAYSWEEP_BINARY) + " -q " + sweep_args(dir / "c.toml");
  auto r = run_command("cd " + dir.string() + " && " + cmd + " --out whole.h5");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_command("cd " + dir.string() + " && " + cmd + " --shard 0/2 --out s0.h5");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // Shard 1 of 2 (blocks 1, 3, 5) killed after committing its first block...
  r = run_command("cd " + dir.string() + " && RAYSWEEP_KILL_AFTER_BLOCKS=1 " + cmd + " --shard 1/2 --out s1.h5");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_FALSE(fs::exists(dir / "s1.h5"));
  EXPECT_TRUE(fs::exists(dir / "s1.h5.parts/block_000001.bin"));
  EXPECT_FALSE(fs::exists(dir / "s1.h5.parts/block_000000.bin"));  // shard 0's block is not its work
  EXPECT_FALSE(fs::exists(dir / "s1.h5.parts/block_000003.bin"));
  // ...keeps it on --resume and traces blocks 3 and 5 only.
  r = run_command("cd " + dir.string() + " && " + std::string(RAYSWEEP_BINARY) + " " + sweep_args(dir / "c.toml") +
                  " --shard 1/2 --out s1.h5 --resume");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("swept 15 frames (1 resumed blocks)"), std::string::npos) << r.output;
  fs::create_directories(dir / "m");
  r = run_command("cd " + (dir / "m").string() + " && " + std::string(RAYSWEEP_BINARY) +
                  " merge ../s0.h5 ../s1.h5 --out whole.h5");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(same_bytes(dir / "whole.h5", dir / "m/whole.h5"));
}

TEST(CliShard, MpiRunEqualsTheSingleProcessRunAndAFailingRankFailsTheJob) {
#ifndef RAYSWEEP_HAVE_MPI
  GTEST_SKIP() << "raysweep was built without MPI (openmpi-bin and libopenmpi-dev not installed)";
#else
  const City& c = city();
  const std::string mpirun = std::string(RAYSWEEP_MPIEXEC) + " --allow-run-as-root --oversubscribe -n ";
  clear_sweep_outputs();
  auto r = run_command(mpirun + "3 " + RAYSWEEP_BINARY + " -j 1 " + run_city("--mpi"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("[rank 2/3]"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("merged 3 shards (6 blocks, 30 frames)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("dataset: " + (c.out / "dataset.h5").string()), std::string::npos) << r.output;
  EXPECT_TRUE(same_bytes(c.out / "dataset.h5", c.reference));

  // Rank 1 of 2 cannot write its shard (a folder in the way): the job fails
  // with its error, after it committed its blocks.
  clear_sweep_outputs();
  fs::create_directories(c.out / "shards/dataset.1-of-2.h5");
  r = run_command(mpirun + "2 " + RAYSWEEP_BINARY + " -j 1 " + run_city("--mpi"));
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("[rank 1/2] error"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("dataset.1-of-2.h5"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("rank 1 of 2 failed"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(c.out / "dataset.h5"));
  // The rerun redoes nothing rank 1 committed, and gives the same dataset.
  fs::remove(c.out / "shards/dataset.1-of-2.h5");
  r = run_command(mpirun + "2 " + RAYSWEEP_BINARY + " -j 1 " + run_city("--mpi --resume"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("swept 15 frames (3 resumed blocks)"), std::string::npos) << r.output;
  EXPECT_TRUE(same_bytes(c.out / "dataset.h5", c.reference));
#endif
}
