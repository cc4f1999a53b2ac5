// Provenance records: every output says which tool, version, config, inputs
// (with SHA-256) and seeds produced it. No timestamps: the same inputs give
// byte-identical records.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace raysweep::pipeline {

std::string sha256_file(const std::string& path);  // hex; throws on unreadable files
std::string sha256_text(const std::string& text);  // hex

struct InputFile {
  std::string role;  // "osm", "net", "config", ...
  std::string path;
};

// The command line as provenance records it: without the options that change no
// number in the output (--resume, -q/--quiet, -j/--threads N), so a resumed run
// or another thread count gives the same file; nor those that only split the
// work of `run` over stages, processes and machines (--until STAGE, --shard I/N,
// --merge, --mpi, --virtual), so a sharded and merged run records the command of
// the single-process run and writes the same bytes (docs/scaleout.md).
std::vector<std::string> recorded_command(const std::vector<std::string>& argv);

// Fills the identity fields every file header shares (raysweep_version, git_hash,
// config, inputs, provenance) from a provenance() record.
template <class Header>
void stamp_header(Header& h, const std::string& version, const std::string& git_hash, const nlohmann::json& config,
                  const nlohmann::json& prov) {
  h.raysweep_version = version;
  h.git_hash = git_hash;
  h.config = config;
  h.inputs = prov["inputs"];
  h.provenance = prov;
}

nlohmann::json provenance(const std::string& stage, const std::vector<InputFile>& inputs,
                          const nlohmann::json& config, const std::vector<std::string>& argv);

}  // namespace raysweep::pipeline
