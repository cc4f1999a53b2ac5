#include "tracer/precompute.hpp"

#include <cstring>

namespace raysweep::tracer {

namespace {

constexpr char kMagic[4] = {'R', 'S', 'P', 'C'};
constexpr std::uint32_t kFormat = 1;
constexpr std::size_t kHeader = 4 + 4 + 8 + 8;

std::uint64_t fnv(const void* data, std::size_t n, std::uint64_t h) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
  return h;
}

template <class T>
void put(std::string& out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.append(b, sizeof(T));
}

template <class T>
T get(const std::string& in, std::size_t at) {
  T v;
  std::memcpy(&v, in.data() + at, sizeof(T));
  return v;
}

}  // namespace

ContentKey& ContentKey::add(const void* data, std::size_t bytes) {
  a_ = fnv(data, bytes, a_);
  // The second stream starts each call from a seed mixed with the call's length, so the two differ.
  b_ = fnv(data, bytes, b_ ^ (bytes * 0x9e3779b97f4a7c15ull));
  return *this;
}

std::string ContentKey::hex() const {
  static const char* digits = "0123456789abcdef";
  std::string s;
  for (std::uint64_t w : {a_, b_})
    for (int k = 60; k >= 0; k -= 4) s.push_back(digits[(w >> k) & 0xf]);
  return s;
}

std::string frame_table(const std::vector<std::uint32_t>& words) {
  std::string out(kMagic, 4);
  put<std::uint32_t>(out, kFormat);
  put<std::uint64_t>(out, words.size() * 4);
  put<std::uint64_t>(out, fnv(words.data(), words.size() * 4, 0xcbf29ce484222325ull));
  out.append(reinterpret_cast<const char*>(words.data()), words.size() * 4);
  return out;
}

std::optional<std::vector<std::uint32_t>> unframe_table(const std::string& bytes, std::string& why) {
  if (bytes.size() < kHeader || std::memcmp(bytes.data(), kMagic, 4) != 0) {
    why = "not a raysweep table";
    return std::nullopt;
  }
  if (get<std::uint32_t>(bytes, 4) != kFormat) {
    why = "format " + std::to_string(get<std::uint32_t>(bytes, 4)) + ", expected " + std::to_string(kFormat);
    return std::nullopt;
  }
  const auto length = get<std::uint64_t>(bytes, 8);
  if (length % 4 != 0 || length != bytes.size() - kHeader) {
    why = "truncated or padded: " + std::to_string(bytes.size() - kHeader) + " payload bytes, header says " +
          std::to_string(length);
    return std::nullopt;
  }
  std::vector<std::uint32_t> words(length / 4);
  std::memcpy(words.data(), bytes.data() + kHeader, length);
  if (fnv(words.data(), length, 0xcbf29ce484222325ull) != get<std::uint64_t>(bytes, 16)) {
    why = "checksum mismatch";
    return std::nullopt;
  }
  return words;
}

}  // namespace raysweep::tracer
