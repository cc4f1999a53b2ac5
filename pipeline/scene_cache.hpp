// A scene folder's scene.glb as decoded meshes, kept in the folder's cache/
// (precompute_store.hpp) so that tinygltf parses a scene once, not in every
// process: on the ring road's 112 meshes that parse is 5 ms of a 0.18 s
// `trace`. The entry is named by the glb's bytes and this build of raysweep
// (the decoder's rules), framed with a checksum, and checked on load (every
// index in range, every per-triangle list as long as the triangles); what
// does not load, check or decode is rebuilt from the glb with a warning,
// never trusted. Entries of other glb contents or builds are removed when a
// new one is stored: a folder holds one scene.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "meshkit/scene.hpp"

namespace raysweep::pipeline {

// `scene_dir`/scene.glb, through `scene_dir`/cache/.
meshkit::Scene read_scene_glb(const std::filesystem::path& scene_dir);

// The cache entry's payload (tracer::frame_table words) and back; decode
// gives nullopt, with why, for words that are not a consistent scene.
std::vector<std::uint32_t> encode_scene(const meshkit::Scene& scene);
std::optional<meshkit::Scene> decode_scene(const std::vector<std::uint32_t>& words, std::string& why);

}  // namespace raysweep::pipeline
