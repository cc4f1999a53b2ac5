// Checking and summarising channel dataset files against the schema
// (schemas/raysweep_dataset.schema.json, embedded at build time; documented in
// schemas/README.md).
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace raysweep::generators {

// The embedded schemas/raysweep_dataset.schema.json text, and parsed.
const std::string& dataset_schema_json();
const nlohmann::json& dataset_schema();

// Checks a file against the schema: every group, dataset and attribute present with
// the right dtype class, size and rank, units/description attributes present; shapes
// consistent (symbolic dims F, S, N, L, P, I, O, K agree across datasets and with the
// root count attributes); offsets equal to the running sum of their counts and ending
// at the totals; codes within their tables, no unknown flag bits; references in range
// (node < N, object < O, frame < F); tx < rx; links of a frame sorted, between nodes
// present in the frame, and in the frame's /links row range; out-of-range links without
// paths, links without paths with gains -inf; schema major version supported; complete == 1.
// Returns the problems, each naming the dataset or attribute (empty: valid). Never
// throws for a corrupt file: an unreadable or non-HDF5 file is one problem naming the path.
// The checks run in a forked child process, so a file corrupt enough to crash the HDF5
// library is reported as a problem too instead of taking the caller down.
std::vector<std::string> validate_dataset(const std::string& path);

// A JSON summary of a dataset: format, schema_version, raysweep_version, git_hash,
// complete, frames, time_start_s, time_end_s, nodes, vehicles, rsus, links, paths,
// interactions, objects, los_counts {LOS, NLOSV, NLOS}, mean_paths_per_link,
// mean_paths_per_in_range_link (paths / links not flagged out of range), cached_links,
// out_of_range_links, file, file_bytes, bytes_per_link (file bytes / links, a link being
// one pair in one frame), has_cfr, subcarriers, carrier_hz, bandwidth_hz. Works on
// unfinished files (complete false, node table counts 0). Throws meshkit::InputError
// naming the file (and the dataset) when the file cannot be read. Unlike
// validate_dataset() it runs in this process: use it on files that validate.
nlohmann::json dataset_info(const std::string& path);

// Human-readable multi-line text of dataset_info() for `raysweep info`.
std::string format_dataset_info(const nlohmann::json& info);

}  // namespace raysweep::generators
