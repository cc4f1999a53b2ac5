// Checking and summarising raysweep files against their schemas, embedded at
// build time and documented in schemas/README.md: channel datasets (format
// raysweep-channels, schemas/raysweep_dataset.schema.json), SINR outcome files
// (format raysweep-sinr, schemas/raysweep_sinr.schema.json) and ns-3 lookup tables
// (format raysweep-ns3-table, schemas/raysweep_ns3_table.schema.json) and context-feature
// files (format raysweep-features, schemas/raysweep_features.schema.json). The root
// attribute `format` says which. Each format's library has its schema, its checks
// beyond it and its summary (generators/dataset, sinr, ns3_table, sweep).
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace raysweep::generators {

// Checks a file against the schema of its `format` (a missing or unknown format is
// one problem naming the file and the format). Both formats: every group, dataset
// and attribute present with the right dtype class, size and rank, units/description
// attributes present; shapes consistent (symbolic dims agree across datasets and
// with the root count attributes); offsets equal to the running sum of their counts and ending
// at the totals; codes within their tables, no unknown flag bits; references in range;
// schema major version supported; complete == 1. Channel datasets: tx < rx; links of a
// frame sorted, between nodes present in the frame, and in the frame's /links row
// range; out-of-range links without paths, links without paths with gains -inf. SINR
// files: transmissions sorted by start, durations > 0, bands f_lo < f_hi, RAT not
// none; receptions strictly sorted by (transmission, rx), rx != tx, agreeing with their
// transmission (tx, rat, packet, attempt, time); interferers equal to the counted
// overlap rows, which never name the reception's own transmission; PRR in [0, 1] equal
// to received / packets (NaN when packets = 0), received <= packets.
// Returns the problems, each naming the dataset or attribute (empty: valid). Never
// throws for a corrupt file: an unreadable or non-HDF5 file is one problem naming the path.
// The checks run in a forked child process, so a file corrupt enough to crash the HDF5
// library is reported as a problem too instead of taking the caller down.
std::vector<std::string> validate_dataset(const std::string& path);

// A JSON summary of a file. Channel dataset: format, schema_version,
// raysweep_version, git_hash, complete, frames, time_start_s, time_end_s, nodes,
// vehicles, rsus, links, paths, interactions, objects, los_counts {LOS, NLOSV, NLOS},
// mean_paths_per_link, mean_paths_per_in_range_link (paths / links not flagged out of
// range), cached_links, out_of_range_links, file, file_bytes, bytes_per_link (file bytes / links, a link being
// one pair in one frame), has_cfr, subcarriers, carrier_hz, bandwidth_hz, and shard (the
// parsed `shard` attribute, shard files only). SINR file:
// format, schema_version, raysweep_version, git_hash, complete, channel_model,
// los_from_ray, carrier_hz, sinr_threshold_db, sensitivity_dbm, gain_threshold_db,
// time_start_s, time_end_s, nodes, transmissions, receptions, interferers (overlap
// rows), decoded (receptions decoded), prr_links (rows), prr {RAT name: {packets,
// received, prr (null when packets = 0)}} from /prr_rats, file, file_bytes. Works on
// unfinished files (complete false, node and PRR table counts 0). Throws
// meshkit::InputError naming the file (and the dataset) when the file cannot be read
// or its format is unknown. Unlike
// validate_dataset() it runs in this process: use it on files that validate.
nlohmann::json dataset_info(const std::string& path);

// Human-readable multi-line text of dataset_info() for `raysweep info`.
std::string format_dataset_info(const nlohmann::json& info);

}  // namespace raysweep::generators
