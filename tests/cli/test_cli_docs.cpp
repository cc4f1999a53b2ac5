// docs/cli.md is `raysweep help --docs`: the options of every subcommand
// from their definitions, the prose around them from pipeline/cli/prose/.
// What the prose shows must hold too: its usage lines name only options
// their subcommand has, and its TOML examples are valid configs.
#include <gtest/gtest.h>

#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "test_util.hpp"

using namespace raysweep::test;

namespace {

std::string cli_docs() {
  const auto r = run_command(std::string(RAYSWEEP_BINARY) + " help --docs 2>/dev/null");
  EXPECT_EQ(r.exit_code, 0);
  return r.output;
}

// "## `raysweep NAME`" -> the section's text; "" -> the page's head.
std::map<std::string, std::string> sections(const std::string& page) {
  std::map<std::string, std::string> out;
  const std::regex heading("^## `raysweep ([a-z0-9-]+)`$");
  std::string name, line;
  std::istringstream in(page);
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_match(line, m, heading)) name = m[1];
    out[name] += line + "\n";
  }
  return out;
}

// The options an options table lists: `--out`, `-j`, ...
std::set<std::string> table_options(const std::string& text) {
  std::set<std::string> names;
  const std::regex row("^\\| (`-[^|]*) \\|");
  const std::regex name("`(-[-a-z0-9]+)`");
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (!std::regex_search(line, m, row)) continue;
    const std::string cell = m[1];
    for (std::sregex_iterator it(cell.begin(), cell.end(), name), end; it != end; ++it) names.insert((*it)[1]);
  }
  return names;
}

// The tokens of the usage lines in a section's code blocks that look like
// options, each with the subcommand the line runs: `raysweep [GLOBAL] SUB
// ...` and the lines continuing it.
std::vector<std::pair<std::string, std::string>> usage_options(const std::string& text,
                                                              const std::set<std::string>& subcommands) {
  std::vector<std::pair<std::string, std::string>> found;
  std::string sub;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("    ", 0) != 0) {
      sub.clear();
      continue;
    }
    line = line.substr(0, line.find(" #"));
    std::vector<std::string> tokens;
    for (char& c : line)
      if (c == '[' || c == ']' || c == '(' || c == ')' || c == '|' || c == '=') c = ' ';
    std::istringstream words(line);
    for (std::string w; words >> w;) tokens.push_back(w);
    const auto raysweep = std::find(tokens.begin(), tokens.end(), "raysweep");
    auto first = tokens.begin();
    if (raysweep != tokens.end()) {
      sub.clear();
      for (first = raysweep + 1; first != tokens.end() && !subcommands.count(*first); ++first)
        if (first->front() == '-') found.emplace_back("", *first);  // a global option
      if (first == tokens.end()) continue;
      sub = *first++;
    } else if (sub.empty() || tokens.empty() || tokens.front().front() != '-') {
      sub.clear();
      continue;
    }
    for (auto it = first; it != tokens.end(); ++it)
      if (it->size() > 1 && it->front() == '-' && !std::isdigit(static_cast<unsigned char>((*it)[1])))
        found.emplace_back(sub, *it);
  }
  return found;
}

}  // namespace

TEST(CliDocs, ReferenceIsGeneratedFromTheCommands) {
  // docs/cli.md is `raysweep help --docs`; regenerate it when this fails.
  const std::string page = cli_docs();
  EXPECT_EQ(read_text(source_dir() / "docs/cli.md"), page)
      << "docs/cli.md is stale: run ./build/raysweep help --docs > docs/cli.md";
  // Every subcommand of --help has its section, with its options and a usage line.
  const auto help = run_command(std::string(RAYSWEEP_BINARY) + " --help");
  ASSERT_EQ(help.exit_code, 0);
  const auto parts = sections(page);
  std::istringstream in(help.output.substr(help.output.find("Subcommands:")));
  std::string line;
  std::getline(in, line);
  std::size_t listed = 0;
  while (std::getline(in, line) && line.size() > 2) {
    const std::string name = line.substr(2, line.find(' ', 2) - 2);
    ++listed;
    ASSERT_TRUE(parts.count(name)) << name;
    EXPECT_NE(parts.at(name).find("\n    raysweep "), std::string::npos) << name << ": no usage line";
    const auto sub_help = run_command(std::string(RAYSWEEP_BINARY) + " " + name + " --help");
    for (const auto& option : table_options(parts.at(name)))
      EXPECT_NE(sub_help.output.find(option), std::string::npos) << name << " " << option;
  }
  EXPECT_EQ(listed + 1, parts.size());  // + the page's head
}

TEST(CliDocs, UsageLinesNameOnlyTheirCommandsOptions) {
  const auto parts = sections(cli_docs());
  std::set<std::string> subcommands;
  for (const auto& [name, text] : parts)
    if (!name.empty()) subcommands.insert(name);
  const std::set<std::string> global = table_options(parts.at(""));
  EXPECT_TRUE(global.count("--threads") && global.count("-j")) << "global options table";
  std::size_t checked = 0;
  for (const auto& [name, text] : parts)
    for (const auto& [sub, option] : usage_options(text, subcommands)) {
      ++checked;
      if (sub.empty()) {
        EXPECT_TRUE(global.count(option)) << "section " << name << ": " << option << " is no global option";
        continue;
      }
      EXPECT_TRUE(table_options(parts.at(sub)).count(option))
          << "section " << name << ": raysweep " << sub << " has no option " << option;
    }
  EXPECT_GT(checked, 100u);
}

TEST(CliDocs, TomlExamplesAreValidConfigs) {
  const std::string page = cli_docs();
  const fs::path dir = scratch_dir("toml");
  const std::regex block("```toml\\n([\\s\\S]*?)```");
  std::size_t n = 0;
  for (std::sregex_iterator it(page.begin(), page.end(), block), end; it != end; ++it, ++n) {
    const fs::path file = dir / ("example" + std::to_string(n) + ".toml");
    write_text(file, (*it)[1]);
    const auto r = run_raysweep("config " + file.string());
    EXPECT_EQ(r.exit_code, 0) << (*it)[1] << r.output;
  }
  EXPECT_GE(n, 5u);
}
