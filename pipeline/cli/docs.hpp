// docs/cli.md, generated: `raysweep help --docs` walks the CLI11
// definitions of every subcommand (pipeline/main.cpp) for its options and
// puts beside each the prose of pipeline/cli/prose/<subcommand>.md (intro.md
// for the page's head), compiled into the binary. tests/cli/test_cli_docs.cpp
// fails when docs/cli.md differs from it.
#pragma once

#include <map>
#include <string>

namespace CLI {
class App;
}

namespace raysweep::pipeline {

// The whole page: the intro, the global options, a table of the subcommands
// and one section per subcommand in the order they were added to `app`.
std::string cli_docs(const CLI::App& app);

// The fragments of pipeline/cli/prose/ by name (file name without .md);
// defined in the file the build generates from them (embed_prose.cmake).
const std::map<std::string, std::string>& cli_prose();

}  // namespace raysweep::pipeline
