// The config schema through the CLI: the provenance of `raysweep vehicles`
// records the effective config, `raysweep config FILE` prints it, and
// docs/config.md is `raysweep config --docs`.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "pipeline/settings/config_file.hpp"
#include "pipeline/settings/tables.hpp"
#include "test_util.hpp"

using namespace raysweep::pipeline;
using namespace raysweep::test;
using json = nlohmann::json;

TEST(ConfigSchema, ProvenanceRecordsTheEffectiveConfig) {
  const fs::path dir = scratch_dir("cfg");
  write_text(dir / "v.toml",
             "[vehicles]\nclasses = [\"bicycle\"]\nlod_ratios = [1.0, 0.5]\n[vehicles.class.bicycle]\nlength = 1.8\n");
  const auto r = run_raysweep("-q vehicles --no-preview --config " + (dir / "v.toml").string() + " --out " +
                              (dir / "lib").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json manifest = json::parse(read_text(dir / "lib/manifest.json"));
  const json eff = effective_config((dir / "v.toml").string());
  EXPECT_EQ(manifest["provenance"]["config"], eff["vehicles"]);
  EXPECT_EQ(manifest["provenance"]["config"]["class"]["bicycle"]["length"], 1.8);
  // `raysweep config FILE` prints the same, `raysweep config` with a bad file exits 2.
  const auto c = run_raysweep("config " + (dir / "v.toml").string());
  ASSERT_EQ(c.exit_code, 0) << c.output;
  EXPECT_EQ(json::parse(c.output)["vehicles"], eff["vehicles"]);
  write_text(dir / "bad.toml", "[vehicles]\nclases = []\n");
  const auto b = run_raysweep("config " + (dir / "bad.toml").string());
  EXPECT_EQ(b.exit_code, 2);
  EXPECT_NE(b.output.find("bad.toml:2: vehicles.clases: unknown key (did you mean 'classes'?)"), std::string::npos)
      << b.output;
}

TEST(ConfigSchema, DocsAreGeneratedFromTheSchema) {
  // docs/config.md is `raysweep config --docs`; regenerate it when this fails.
  EXPECT_EQ(read_text(source_dir() / "docs/config.md"), config_docs())
      << "docs/config.md is stale: run ./build/raysweep config --docs > docs/config.md";
  const auto r = run_command(std::string(RAYSWEEP_BINARY) + " config --docs 2>/dev/null");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.output, config_docs());
  // Every table and key has a section or a row.
  for (const auto* t : config_tables()) {
    EXPECT_NE(config_docs().find("`[" + t->name() + "]`"), std::string::npos) << t->name();
    for (const auto& k : t->docs()) {
      EXPECT_NE(config_docs().find("| `" + k.key + "` |"), std::string::npos) << t->name() << "." << k.key;
      EXPECT_FALSE(k.help.empty()) << t->name() << "." << k.key;
    }
  }
}
