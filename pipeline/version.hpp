#pragma once
// The tool's version and the git commit it was built from, for provenance.
// Defined in a file the build regenerates whenever HEAD (or whether the tree
// is modified) changes, so a record never names a stale commit.
namespace raysweep {
extern const char* const kVersion;
extern const char* const kGitHash;  // 12 hex digits, "-dirty" if built from a modified tree; "unknown" without git
}  // namespace raysweep
