// Binary frame blocks: see frame_block.hpp for the layout.
#include "generators/sweep/frame_block.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>

#include "meshkit/errors.hpp"

namespace raysweep::generators {

namespace {

constexpr std::size_t kMagicBytes = 8;
constexpr std::uint64_t kNodeBytes = 4 + 3 * 8 + 4 * 4;                      // 44
constexpr std::uint64_t kLinkBytes = 4 + 4 + 1 + 1 + 2 + 4 + 4 + 8 + 4 + 4 + 4 + 1 + 4 + 4 +  // 49, then
                                     4 + 4 + 4 + 4 + 8 + 8 + 4 + 8 + 8;                    // 52 of summaries
constexpr std::uint64_t kPathBytes = 4 + 4 + 8 + 4 * 4 + 4 + 1;              // 37
constexpr std::uint64_t kInteractionBytes = 1 + 4 + 3 * 4;                   // 17
constexpr std::uint64_t kCfrBytes = 8;
constexpr std::uint64_t kFrameHeaderBytes = 8 + 5 * 8;
constexpr std::uint64_t kFnvOffset = 0xcbf29ce484222325ull;
constexpr std::size_t kChunk = 1 << 20;  // bytes read or hashed at a time

std::uint64_t fnv1a64(std::uint64_t h, const unsigned char* p, std::size_t n) {
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
    // A frame is millions of fields: one append each, not one per byte.
    char b[8];
    if constexpr (std::endian::native == std::endian::little) {
      std::memcpy(b, &v, sizeof b);
    } else {
      for (int i = 0; i < 8; ++i) b[i] = static_cast<char>((v >> (8 * i)) & 0xffu);
    }
    bytes.append(b, static_cast<std::size_t>(n));
  }
};

// Little-endian decoder over the next `n` bytes of a stream (starting at file
// offset `offset`), read in chunks: a block of any size is decoded with a
// bounded buffer.
class In {
 public:
  In(const std::string& file, std::istream& s, std::uint64_t offset, std::uint64_t n)
      : file_(file), s_(s), offset_(offset), n_(n) {}
  std::uint8_t u8() { return static_cast<std::uint8_t>(le(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(le(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(le(4)); }
  std::uint64_t u64() { return le(8); }
  float f32() { return std::bit_cast<float>(static_cast<std::uint32_t>(le(4))); }
  double f64() { return std::bit_cast<double>(le(8)); }
  std::uint64_t left() const { return n_ - pos_; }
  std::uint64_t pos() const { return offset_ + pos_; }
  // Checks that count records of the given size fit in what is left (before allocating).
  std::size_t count(std::uint64_t n, std::uint64_t record_bytes, const char* what) const {
    if (n > left() / record_bytes)
      throw meshkit::InputError(file_, "offset " + std::to_string(pos()),
                                "corrupt frame block: " + std::to_string(n) + " " + what + " do not fit in the file");
    return static_cast<std::size_t>(n);
  }

 private:
  std::uint64_t le(int n) {
    if (left() < static_cast<std::uint64_t>(n))
      throw meshkit::InputError(file_, "offset " + std::to_string(pos()), "truncated frame block (short read)");
    if (end_ - at_ < static_cast<std::size_t>(n)) refill();
    std::uint64_t v = 0;
    if constexpr (std::endian::native == std::endian::little) {
      std::memcpy(&v, buf_.data() + at_, static_cast<std::size_t>(n));
    } else {
      for (int i = 0; i < n; ++i) v |= std::uint64_t{buf_[at_ + i]} << (8 * i);
    }
    at_ += static_cast<std::size_t>(n);
    pos_ += static_cast<std::uint64_t>(n);
    return v;
  }
  void refill() {
    const std::size_t keep = end_ - at_;
    if (keep > 0) std::memmove(buf_.data(), buf_.data() + at_, keep);  // empty: no buffer to move (null)
    const std::uint64_t unread = left() - keep;
    const std::size_t want = static_cast<std::size_t>(std::min<std::uint64_t>(kChunk, unread));
    buf_.resize(std::max(buf_.size(), keep + want));
    s_.read(reinterpret_cast<char*>(buf_.data() + keep), static_cast<std::streamsize>(want));
    if (static_cast<std::size_t>(s_.gcount()) != want)
      throw meshkit::InputError(file_, "offset " + std::to_string(pos()), "cannot read frame block");
    at_ = 0;
    end_ = keep + want;
  }
  const std::string& file_;
  std::istream& s_;
  std::uint64_t offset_, n_, pos_ = 0;
  std::vector<unsigned char> buf_;
  std::size_t at_ = 0, end_ = 0;
};

[[noreturn]] void io_fail(const std::string& file, const std::string& what) {
  throw std::runtime_error(file + ": " + what + ": " + std::strerror(errno));
}

void encode_frame(Out& o, const FrameRecord& f) {
  o.bytes.reserve(o.bytes.size() + kFrameHeaderBytes + f.nodes.size() * kNodeBytes + f.links.size() * kLinkBytes +
                  f.paths.size() * kPathBytes + f.interactions.size() * kInteractionBytes + f.cfr.size() * kCfrBytes);
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
    o.u32(l.paths_beyond_top_k);
    o.f32(l.diffuse_gain_db);
    o.f32(l.k_factor_db);
    o.f32(l.rms_doppler_spread_hz);
    for (float v : {l.aod_spread[0], l.aod_spread[1], l.aoa_spread[0], l.aoa_spread[1]}) o.f32(v);
    o.f32(l.strongest_excess_delay_s);
    for (float v : {l.strongest_aod[0], l.strongest_aod[1], l.strongest_aoa[0], l.strongest_aoa[1]}) o.f32(v);
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

void decode_frame(In& r, FrameRecord& f) {
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
    l.paths_beyond_top_k = r.u32();
    l.diffuse_gain_db = r.f32();
    l.k_factor_db = r.f32();
    l.rms_doppler_spread_hz = r.f32();
    for (float* v : {&l.aod_spread[0], &l.aod_spread[1], &l.aoa_spread[0], &l.aoa_spread[1]}) *v = r.f32();
    l.strongest_excess_delay_s = r.f32();
    for (float* v : {&l.strongest_aod[0], &l.strongest_aod[1], &l.strongest_aoa[0], &l.strongest_aoa[1]}) *v = r.f32();
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

void write_at(int fd, const std::string& file, const std::string& bytes, std::uint64_t offset) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::pwrite(fd, bytes.data() + done, bytes.size() - done, static_cast<off_t>(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) io_fail(file, "cannot write");
    done += static_cast<std::size_t>(n);
  }
}

}  // namespace

// ---------------------------------------------------------------- writing

FrameBlockWriter::FrameBlockWriter(const std::filesystem::path& path) : path_(path), tmp_(path.string() + ".tmp") {
  fd_ = ::open(tmp_.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) io_fail(tmp_, "cannot create");
  Out o;
  o.bytes.append(kFrameBlockMagic, kMagicBytes);
  o.u64(0);  // the frame count, written by commit()
  write_at(fd_, tmp_, o.bytes, 0);
  size_ = o.bytes.size();
}

FrameBlockWriter::~FrameBlockWriter() {
  if (fd_ >= 0) {
    ::close(fd_);
    ::unlink(tmp_.c_str());
  }
}

void FrameBlockWriter::append(const FrameRecord& frame) {
  if (fd_ < 0) throw std::runtime_error(tmp_ + ": append() after commit()");
  Out o;
  encode_frame(o, frame);
  write_at(fd_, tmp_, o.bytes, size_);
  size_ += o.bytes.size();
  ++frames_;
}

void FrameBlockWriter::commit() {
  if (fd_ < 0) throw std::runtime_error(tmp_ + ": commit() twice");
  Out count;
  count.u64(frames_);
  write_at(fd_, tmp_, count.bytes, kMagicBytes);
  // The checksum covers the count, known only now: hash the file back in chunks.
  std::vector<unsigned char> buf(kChunk);
  std::uint64_t h = kFnvOffset;
  for (std::uint64_t at = 0; at < size_;) {
    const ssize_t n = ::pread(fd_, buf.data(), static_cast<std::size_t>(std::min<std::uint64_t>(kChunk, size_ - at)),
                              static_cast<off_t>(at));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) io_fail(tmp_, "cannot read back");
    h = fnv1a64(h, buf.data(), static_cast<std::size_t>(n));
    at += static_cast<std::uint64_t>(n);
  }
  Out sum;
  sum.u64(h);
  write_at(fd_, tmp_, sum.bytes, size_);
  if (::fsync(fd_) != 0) io_fail(tmp_, "cannot fsync");
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) {
    ::unlink(tmp_.c_str());
    io_fail(tmp_, "cannot close");
  }
  if (::rename(tmp_.c_str(), path_.c_str()) != 0) io_fail(path_.string(), "cannot rename " + tmp_ + " to it");
  // Make the rename itself durable.
  const std::filesystem::path dir = path_.has_parent_path() ? path_.parent_path() : std::filesystem::path(".");
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

void write_frame_block(const std::filesystem::path& path, const std::vector<FrameRecord>& frames) {
  FrameBlockWriter w(path);
  for (const auto& f : frames) w.append(f);
  w.commit();
}

// ---------------------------------------------------------------- reading

struct FrameBlockReader::Impl {
  std::string file;
  std::ifstream in;
  std::uint64_t frames = 0, done = 0;
  std::unique_ptr<In> r;
};

FrameBlockReader::FrameBlockReader(const std::filesystem::path& path) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.file = path.string();
  m.in.open(path, std::ios::binary);
  if (!m.in) throw meshkit::InputError(m.file, "", "cannot open frame block");
  m.in.seekg(0, std::ios::end);
  const auto end = m.in.tellg();
  if (end < 0) throw meshkit::InputError(m.file, "", "cannot read frame block");
  const auto size = static_cast<std::uint64_t>(end);
  m.in.seekg(0);
  char magic[kMagicBytes] = {};
  m.in.read(magic, static_cast<std::streamsize>(std::min<std::uint64_t>(size, kMagicBytes)));
  if (size < kMagicBytes || std::memcmp(magic, kFrameBlockMagic, kMagicBytes) != 0)
    throw meshkit::InputError(m.file, "magic", "not a raysweep frame block (bad magic)");
  if (size < kMagicBytes + 8 + 8) throw meshkit::InputError(m.file, "", "truncated frame block (short read)");
  // One chunked pass for the checksum.
  const std::uint64_t body = size - 8;
  m.in.seekg(0);
  std::vector<unsigned char> buf(kChunk);
  std::uint64_t h = kFnvOffset;
  for (std::uint64_t at = 0; at < body;) {
    const auto want = static_cast<std::size_t>(std::min<std::uint64_t>(kChunk, body - at));
    m.in.read(reinterpret_cast<char*>(buf.data()), static_cast<std::streamsize>(want));
    if (static_cast<std::size_t>(m.in.gcount()) != want) throw meshkit::InputError(m.file, "", "cannot read frame block");
    h = fnv1a64(h, buf.data(), want);
    at += want;
  }
  In tail(m.file, m.in, body, 8);
  if (tail.u64() != h) throw meshkit::InputError(m.file, "checksum", "corrupt or truncated frame block (checksum mismatch)");
  m.in.seekg(static_cast<std::streamoff>(kMagicBytes));
  m.r = std::make_unique<In>(m.file, m.in, kMagicBytes, body - kMagicBytes);
  m.frames = m.r->count(m.r->u64(), kFrameHeaderBytes, "frames");
}

FrameBlockReader::~FrameBlockReader() = default;

std::uint64_t FrameBlockReader::frames() const { return impl_->frames; }

bool FrameBlockReader::next(FrameRecord& frame) {
  Impl& m = *impl_;
  if (m.done == m.frames) {
    if (m.r->left() != 0)
      throw meshkit::InputError(m.file, "offset " + std::to_string(m.r->pos()),
                                "corrupt frame block: " + std::to_string(m.r->left()) + " bytes after the last frame");
    return false;
  }
  decode_frame(*m.r, frame);
  ++m.done;
  return true;
}

void verify_frame_block(const std::filesystem::path& path) {
  FrameBlockReader r(path);
  for (FrameRecord f; r.next(f);) {
  }
}

std::vector<FrameRecord> read_frame_block(const std::filesystem::path& path) {
  FrameBlockReader r(path);
  std::vector<FrameRecord> frames;
  frames.reserve(static_cast<std::size_t>(r.frames()));
  for (FrameRecord f; r.next(f);) frames.push_back(std::move(f));
  return frames;
}

}  // namespace raysweep::generators
