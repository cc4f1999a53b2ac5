// The pipeline's store of precomputed tables (pipeline/precompute_store.hpp):
// whole files through a rename; a folder that cannot be written is only a warning.
#include <gtest/gtest.h>

#include "pipeline/precompute_store.hpp"
#include "test_util.hpp"

using namespace raysweep;
using namespace raysweep::test;

TEST(Precompute, FileStoreWritesWholeFilesAndSurvivesAnUnwritableFolder) {
  const auto dir = scratch_dir("precompute_store");
  pipeline::FilePrecomputeStore store(dir / "cache");
  EXPECT_FALSE(store.load("k1"));
  store.save("k1", "abc");
  EXPECT_EQ(store.load("k1"), "abc");
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir / "cache")) files += e.path().filename() == "k1.bin";
  EXPECT_EQ(files, 1u);
  // A folder that cannot exist: saving is a warning, loading finds nothing.
  write_text(dir / "blocker", "a file where the cache folder would be");
  pipeline::FilePrecomputeStore blocked(dir / "blocker" / "cache");
  blocked.save("k1", "abc");
  EXPECT_FALSE(blocked.load("k1"));
}
