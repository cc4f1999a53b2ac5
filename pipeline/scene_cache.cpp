#include "pipeline/scene_cache.hpp"

#include <cstring>
#include <fstream>
#include <iterator>

#include "meshkit/gltf_io.hpp"
#include "pipeline/precompute_store.hpp"
#include "pipeline/version.hpp"
#include "tracer/precompute.hpp"

namespace raysweep::pipeline {

namespace fs = std::filesystem;

namespace {

constexpr std::uint32_t kSceneFormat = 1;
constexpr const char* kPrefix = "scene-";

class Writer {
 public:
  void u32(std::uint32_t v) { w_.push_back(v); }
  void f64(double d) {
    std::uint64_t bits;
    std::memcpy(&bits, &d, sizeof bits);
    u32(static_cast<std::uint32_t>(bits));
    u32(static_cast<std::uint32_t>(bits >> 32));
  }
  void str(const std::string& s) {
    u32(static_cast<std::uint32_t>(s.size()));
    for (std::size_t i = 0; i < s.size(); i += 4) {
      std::uint32_t word = 0;
      std::memcpy(&word, s.data() + i, std::min<std::size_t>(4, s.size() - i));
      u32(word);
    }
  }
  void u32s(const std::vector<std::uint32_t>& v) {
    u32(static_cast<std::uint32_t>(v.size()));
    w_.insert(w_.end(), v.begin(), v.end());
  }
  std::vector<std::uint32_t> take() { return std::move(w_); }

 private:
  std::vector<std::uint32_t> w_;
};

// Reads past the end or sizes beyond what is left fail the decode, never the process.
class Reader {
 public:
  explicit Reader(const std::vector<std::uint32_t>& w) : w_(w) {}
  bool ok() const { return ok_; }
  bool done() const { return at_ == w_.size(); }
  std::uint32_t u32() {
    if (at_ >= w_.size()) return fail();
    return w_[at_++];
  }
  double f64() {
    const std::uint64_t lo = u32(), hi = u32();
    const std::uint64_t bits = lo | (hi << 32);
    double d;
    std::memcpy(&d, &bits, sizeof d);
    return d;
  }
  // A count of items of `words` words each that the rest can hold.
  std::size_t count(std::size_t words) {
    const std::size_t n = u32();
    if (n * words > w_.size() - at_) return fail();
    return n;
  }
  std::string str() {
    const std::size_t n = u32();
    if ((n + 3) / 4 > w_.size() - at_) return fail(), std::string();
    std::string s(n, '\0');
    for (std::size_t i = 0; i < n; i += 4) {
      const std::uint32_t word = w_[at_++];
      std::memcpy(s.data() + i, &word, std::min<std::size_t>(4, n - i));
    }
    return s;
  }
  std::vector<std::uint32_t> u32s() {
    const std::size_t n = count(1);
    std::vector<std::uint32_t> v(w_.begin() + static_cast<std::ptrdiff_t>(at_),
                                 w_.begin() + static_cast<std::ptrdiff_t>(at_ + n));
    at_ += n;
    return v;
  }

 private:
  const std::vector<std::uint32_t>& w_;
  std::size_t at_ = 0;
  bool ok_ = true;
  std::uint32_t fail() {
    ok_ = false;
    at_ = w_.size();
    return 0;
  }
};

// What read_glb guarantees, so that a decoded scene is one it could have given.
std::optional<std::string> inconsistency(const meshkit::Scene& s) {
  for (const auto& m : s.meshes) {
    if (m.triangle_object.size() != m.triangles.size() || m.triangle_face.size() != m.triangles.size())
      return "mesh '" + m.name + "': per-triangle lists of another length";
    for (const auto& t : m.triangles)
      for (auto v : t)
        if (v >= m.vertices.size()) return "mesh '" + m.name + "': a vertex index out of range";
    for (auto o : m.triangle_object)
      if (o >= s.objects.size()) return "mesh '" + m.name + "': an object index out of range";
  }
  return std::nullopt;
}

std::string entry_key(const std::string& glb_bytes) {
  tracer::ContentKey key;
  key.add(glb_bytes).add(kVersion).add(kGitHash).add_u64(kSceneFormat);
  return kPrefix + key.hex();
}

// Other scene entries of the folder: of an older glb or another build.
void remove_other_entries(const fs::path& cache_dir, const std::string& keep) {
  std::error_code ec;
  for (fs::directory_iterator it(cache_dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(kPrefix, 0) == 0 && name != keep + ".bin") fs::remove(it->path(), ec);
  }
}

}  // namespace

std::vector<std::uint32_t> encode_scene(const meshkit::Scene& scene) {
  Writer w;
  w.u32(kSceneFormat);
  w.u32(static_cast<std::uint32_t>(scene.objects.size()));
  for (const auto& o : scene.objects) {
    w.str(o.kind);
    w.str(o.source_id);
  }
  w.u32(static_cast<std::uint32_t>(scene.meshes.size()));
  for (const auto& m : scene.meshes) {
    w.str(m.name);
    w.str(m.material);
    w.u32(static_cast<std::uint32_t>(m.vertices.size()));
    for (const auto& v : m.vertices)
      for (double c : v) w.f64(c);
    w.u32(static_cast<std::uint32_t>(m.triangles.size()));
    for (const auto& t : m.triangles)
      for (auto i : t) w.u32(i);
    w.u32s(m.triangle_object);
    w.u32s(m.triangle_face);
  }
  return w.take();
}

std::optional<meshkit::Scene> decode_scene(const std::vector<std::uint32_t>& words, std::string& why) {
  Reader r(words);
  if (r.u32() != kSceneFormat) {
    why = "another scene format";
    return std::nullopt;
  }
  meshkit::Scene s;
  s.objects.resize(r.count(2));
  for (auto& o : s.objects) {
    o.kind = r.str();
    o.source_id = r.str();
  }
  s.meshes.resize(r.count(6));
  for (auto& m : s.meshes) {
    m.name = r.str();
    m.material = r.str();
    m.vertices.resize(r.count(6));
    for (auto& v : m.vertices)
      for (double& c : v) c = r.f64();
    m.triangles.resize(r.count(3));
    for (auto& t : m.triangles)
      for (auto& i : t) i = r.u32();
    m.triangle_object = r.u32s();
    m.triangle_face = r.u32s();
    if (!r.ok()) break;
  }
  if (!r.ok() || !r.done()) {
    why = "truncated or overlong";
    return std::nullopt;
  }
  if (auto bad = inconsistency(s)) {
    why = *bad;
    return std::nullopt;
  }
  return s;
}

meshkit::Scene read_scene_glb(const fs::path& scene_dir) {
  const fs::path glb = scene_dir / "scene.glb";
  std::ifstream in(glb, std::ios::binary);
  if (!in) return meshkit::read_glb(glb.string());  // read_glb says what is wrong
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const FilePrecomputeStore store(scene_dir / "cache");
  const std::string key = entry_key(bytes);
  if (auto stored = store.load(key)) {
    std::string why;
    if (auto words = tracer::unframe_table(*stored, why))
      if (auto scene = decode_scene(*words, why)) return std::move(*scene);
    store.rejected(key, why);
  }
  meshkit::Scene scene = meshkit::read_glb(glb.string());
  store.save(key, tracer::frame_table(encode_scene(scene)));
  remove_other_entries(scene_dir / "cache", key);
  return scene;
}

}  // namespace raysweep::pipeline
