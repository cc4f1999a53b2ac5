// `--set TABLE.KEY=VALUE`: a setting changed on the command line, applied to
// the parsed file before the schema checks it, so that it is checked,
// recorded and stamped exactly like the same line in the file.
#pragma once

#include <string>
#include <vector>

#include <toml++/toml.h>

namespace raysweep::pipeline {

// Each "TABLE.KEY=VALUE" (KEY may be dotted: materials.glass.eps_r) in order,
// the later winning. VALUE is a TOML value (3, 2.5, true, "text", [1, 2],
// { a = 1 }); anything that does not parse as one is taken as a string, so
// `--set radio.antenna=dipole` needs no quotes. The values' source is
// "--set TABLE.KEY" (schema::set_option). Throws ConfigError for a malformed
// option.
void apply_overrides(toml::table& root, const std::vector<std::string>& sets);

}  // namespace raysweep::pipeline
