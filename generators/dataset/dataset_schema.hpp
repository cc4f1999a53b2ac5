// The channel dataset's schema (schemas/raysweep_dataset.schema.json),
// embedded at build time and documented in schemas/README.md, and how every
// format's library holds its embedded schema: the build generates the text and
// the two accessors of each (raysweep_embed_schema in generators/CMakeLists.txt).
// validate_dataset() and dataset_info() (generators/formats.hpp) check files
// against their schemas.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

namespace raysweep::generators {

// An embedded schema: its text, and the JSON parsed once.
struct EmbeddedSchema {
  std::string text;
  nlohmann::json json;
  explicit EmbeddedSchema(const char* t) : text(t), json(nlohmann::json::parse(text)) {}
};

// The embedded schemas/raysweep_dataset.schema.json text, and parsed.
const std::string& dataset_schema_json();
const nlohmann::json& dataset_schema();

}  // namespace raysweep::generators
