// Binary frame blocks: see frame_block.hpp for the layout.
#include "generators/frame_block.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>

#include "meshkit/errors.hpp"

namespace raysweep::generators {

namespace {

constexpr std::size_t kMagicBytes = 8;
constexpr std::uint64_t kNodeBytes = 4 + 3 * 8 + 4 * 4;                      // 44
constexpr std::uint64_t kLinkBytes = 4 + 4 + 1 + 1 + 2 + 4 + 4 + 8 + 4 + 4 + 4 + 1 + 4 + 4;  // 49
constexpr std::uint64_t kPathBytes = 4 + 4 + 8 + 4 * 4 + 4 + 1;              // 37
constexpr std::uint64_t kInteractionBytes = 1 + 4 + 3 * 4;                   // 17
constexpr std::uint64_t kCfrBytes = 8;
constexpr std::uint64_t kFrameHeaderBytes = 8 + 5 * 8;

std::uint64_t fnv1a64(const unsigned char* p, std::size_t n) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (std::size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ull;
  }
  return h;
}

// Little-endian encoder (independent of the host's byte order).
class Out {
 public:
  std::string bytes;
  void u8(std::uint8_t v) { bytes.push_back(static_cast<char>(v)); }
  void u16(std::uint16_t v) { le(v, 2); }
  void u32(std::uint32_t v) { le(v, 4); }
  void u64(std::uint64_t v) { le(v, 8); }
  void f32(float v) { le(std::bit_cast<std::uint32_t>(v), 4); }
  void f64(double v) { le(std::bit_cast<std::uint64_t>(v), 8); }

 private:
  void le(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i) bytes.push_back(static_cast<char>((v >> (8 * i)) & 0xffu));
  }
};

class In {
 public:
  In(const std::string& file, const unsigned char* p, std::size_t n) : file_(file), p_(p), n_(n) {}
  std::uint8_t u8() { return static_cast<std::uint8_t>(le(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(le(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(le(4)); }
  std::uint64_t u64() { return le(8); }
  float f32() { return std::bit_cast<float>(static_cast<std::uint32_t>(le(4))); }
  double f64() { return std::bit_cast<double>(le(8)); }
  std::size_t left() const { return n_ - pos_; }
  std::size_t pos() const { return pos_; }
  // Checks that count records of the given size fit in what is left (before allocating).
  std::size_t count(std::uint64_t n, std::uint64_t record_bytes, const char* what) const {
    if (n > left() / record_bytes)
      throw meshkit::InputError(file_, "offset " + std::to_string(pos_),
                                "corrupt frame block: " + std::to_string(n) + " " + what + " do not fit in the file");
    return static_cast<std::size_t>(n);
  }

 private:
  std::uint64_t le(int n) {
    if (left() < static_cast<std::size_t>(n))
      throw meshkit::InputError(file_, "offset " + std::to_string(pos_), "truncated frame block (short read)");
    std::uint64_t v = 0;
    for (int i = 0; i < n; ++i) v |= std::uint64_t{p_[pos_ + i]} << (8 * i);
    pos_ += static_cast<std::size_t>(n);
    return v;
  }
  const std::string& file_;
  const unsigned char* p_;
  std::size_t n_;
  std::size_t pos_ = 0;
};

[[noreturn]] void io_fail(const std::string& file, const std::string& what) {
  throw std::runtime_error(file + ": " + what + ": " + std::strerror(errno));
}

}  // namespace

void write_frame_block(const std::filesystem::path& path, const std::vector<FrameRecord>& frames) {
  Out o;
  o.bytes.append(kFrameBlockMagic, kMagicBytes);
  o.u64(frames.size());
  for (const auto& f : frames) {
    o.f64(f.time_s);
    o.u64(f.nodes.size());
    o.u64(f.links.size());
    o.u64(f.paths.size());
    o.u64(f.interactions.size());
    o.u64(f.cfr.size());
    for (const auto& s : f.nodes) {
      o.u32(s.node);
      o.f64(s.x), o.f64(s.y), o.f64(s.z);
      o.f32(s.vx), o.f32(s.vy), o.f32(s.vz);
      o.f32(s.heading_deg);
    }
    for (const auto& l : f.links) {
      o.u32(l.tx), o.u32(l.rx);
      o.u8(l.los_class), o.u8(l.flags), o.u16(l.blocker_count);
      o.f32(l.gain_coherent_db), o.f32(l.gain_incoherent_db);
      o.f64(l.first_delay_s);
      o.f32(l.rms_delay_spread_s);
      o.u32(l.path_count);
      o.u32(l.paths_below_threshold);
      o.u8(l.los_class_fresnel);
      o.f32(l.fresnel_clearance);
      o.f32(l.vehicle_loss_db);
    }
    for (const auto& p : f.paths) {
      o.f32(p.a.real()), o.f32(p.a.imag());
      o.f64(p.tau_s);
      o.f32(p.theta_t), o.f32(p.phi_t), o.f32(p.theta_r), o.f32(p.phi_r);
      o.f32(p.doppler_hz);
      o.u8(p.interaction_count);
    }
    for (const auto& it : f.interactions) {
      o.u8(it.type);
      o.u32(it.object);
      o.f32(it.x), o.f32(it.y), o.f32(it.z);
    }
    for (const auto& c : f.cfr) o.f32(c.real()), o.f32(c.imag());
  }
  o.u64(fnv1a64(reinterpret_cast<const unsigned char*>(o.bytes.data()), o.bytes.size()));

  const std::string file = path.string();
  const std::string tmp = file + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) io_fail(tmp, "cannot create");
  std::size_t done = 0;
  while (done < o.bytes.size()) {
    const ssize_t n = ::write(fd, o.bytes.data() + done, o.bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int e = errno;
      ::close(fd);
      ::unlink(tmp.c_str());
      errno = e;
      io_fail(tmp, "cannot write");
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const int e = errno;
    ::close(fd);
    ::unlink(tmp.c_str());
    errno = e;
    io_fail(tmp, "cannot fsync");
  }
  if (::close(fd) != 0) io_fail(tmp, "cannot close");
  if (::rename(tmp.c_str(), file.c_str()) != 0) io_fail(file, "cannot rename " + tmp + " to it");
  // Make the rename itself durable.
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

std::vector<FrameRecord> read_frame_block(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw meshkit::InputError(file, "", "cannot open frame block");
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw meshkit::InputError(file, "", "cannot read frame block");
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  if (bytes.size() < kMagicBytes || std::memcmp(p, kFrameBlockMagic, kMagicBytes) != 0)
    throw meshkit::InputError(file, "magic", "not a raysweep frame block (bad magic)");
  if (bytes.size() < kMagicBytes + 8 + 8) throw meshkit::InputError(file, "", "truncated frame block (short read)");
  const std::size_t body = bytes.size() - 8;
  In tail(file, p + body, 8);
  const std::uint64_t stored = tail.u64();
  if (stored != fnv1a64(p, body))
    throw meshkit::InputError(file, "checksum", "corrupt or truncated frame block (checksum mismatch)");

  In r(file, p + kMagicBytes, body - kMagicBytes);
  std::vector<FrameRecord> frames(r.count(r.u64(), kFrameHeaderBytes, "frames"));
  for (auto& f : frames) {
    f.time_s = r.f64();
    const std::uint64_t n_nodes = r.u64(), n_links = r.u64(), n_paths = r.u64(), n_inter = r.u64(), n_cfr = r.u64();
    f.nodes.resize(r.count(n_nodes, kNodeBytes, "node states"));
    for (auto& s : f.nodes) {
      s.node = r.u32();
      s.x = r.f64(), s.y = r.f64(), s.z = r.f64();
      s.vx = r.f32(), s.vy = r.f32(), s.vz = r.f32();
      s.heading_deg = r.f32();
    }
    f.links.resize(r.count(n_links, kLinkBytes, "links"));
    for (auto& l : f.links) {
      l.tx = r.u32(), l.rx = r.u32();
      l.los_class = r.u8(), l.flags = r.u8(), l.blocker_count = r.u16();
      l.gain_coherent_db = r.f32(), l.gain_incoherent_db = r.f32();
      l.first_delay_s = r.f64();
      l.rms_delay_spread_s = r.f32();
      l.path_count = r.u32();
      l.paths_below_threshold = r.u32();
      l.los_class_fresnel = r.u8();
      l.fresnel_clearance = r.f32();
      l.vehicle_loss_db = r.f32();
    }
    f.paths.resize(r.count(n_paths, kPathBytes, "paths"));
    for (auto& q : f.paths) {
      const float re = r.f32(), im = r.f32();
      q.a = {re, im};
      q.tau_s = r.f64();
      q.theta_t = r.f32(), q.phi_t = r.f32(), q.theta_r = r.f32(), q.phi_r = r.f32();
      q.doppler_hz = r.f32();
      q.interaction_count = r.u8();
    }
    f.interactions.resize(r.count(n_inter, kInteractionBytes, "interactions"));
    for (auto& it : f.interactions) {
      it.type = r.u8();
      it.object = r.u32();
      it.x = r.f32(), it.y = r.f32(), it.z = r.f32();
    }
    f.cfr.resize(r.count(n_cfr, kCfrBytes, "cfr values"));
    for (auto& c : f.cfr) {
      const float re = r.f32(), im = r.f32();
      c = {re, im};
    }
  }
  if (r.left() != 0)
    throw meshkit::InputError(file, "offset " + std::to_string(kMagicBytes + r.pos()),
                              "corrupt frame block: " + std::to_string(r.left()) + " bytes after the last frame");
  return frames;
}

}  // namespace raysweep::generators
