#include "pipeline/json_stream.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <cmath>
#include <stdexcept>

namespace raysweep::pipeline {

JsonStream::~JsonStream() {
  try {
    flush();
  } catch (...) {  // a destructor cannot report it; the caller's stream state does
  }
}

JsonStream::JsonStream(Fragment at, int indent) : indent_(indent), base_(at.depth) {
  if (at.depth == 0) throw std::logic_error("JsonStream: a fragment inside no array");
  levels_.resize(at.depth);
  levels_.back().spliced = true;
  grow(kFragmentBytes);
  wrote_root_ = true;
}

// Uninitialised room (std::string would clear it): a trace's fragments are 110 kB each.
void JsonStream::grow(std::size_t n) {
  const std::size_t cap = std::max(2 * cap_, len_ + n + 4096);
  std::unique_ptr<char[]> bigger(new char[cap]);
  if (len_ > 0) std::memcpy(bigger.get(), buf_.get(), len_);
  buf_ = std::move(bigger);
  cap_ = cap;
}

void JsonStream::flush() {
  if (!out_) return;  // a fragment keeps its text for take()
  out_->write(buf_.get(), static_cast<std::streamsize>(len_));
  len_ = 0;
}

JsonStream::Text JsonStream::take() {
  if (out_ || !complete()) throw std::logic_error("JsonStream: take() of an unfinished fragment");
  Text text;
  text.data_ = std::move(buf_);
  text.size_ = len_;
  cap_ = len_ = 0;
  return text;
}

// A fragment's text begins with its first element's newline and holds the
// commas between its elements; the bracket or comma before it is this array's.
JsonStream& JsonStream::splice(std::string_view fragment) {
  if (levels_.empty() || levels_.back().object) throw std::logic_error("JsonStream: splice outside an array");
  if (fragment.empty()) return *this;
  Level& l = levels_.back();
  put(l.empty ? '[' : ',');
  l.empty = false;
  put(fragment);
  return *this;
}

void JsonStream::newline(std::size_t depth) {
  const std::size_t n = depth * static_cast<std::size_t>(indent_) + 1;
  if (pad_.size() < n || pad_.size() < kShortPad) {
    pad_.assign(std::max(2 * n + 1, kShortPad), ' ');
    pad_[0] = '\n';
  }
  if (n > kShortPad) return put(std::string_view(pad_.data(), n));
  // A fixed-size copy (two stores, no call) into the room, of which n count.
  room(kShortPad);
  std::memcpy(buf_.get() + len_, pad_.data(), kShortPad);
  len_ += n;
  if (out_ && len_ >= kFlushBytes) flush();
}

namespace {

// Printable ASCII without quote or backslash is its own JSON text; anything
// else (escapes, UTF-8 checks) goes through dump() itself. A table: keys and
// names are most of a trace document's strings.
constexpr std::array<bool, 256> kNeedsDump = [] {
  std::array<bool, 256> t{};
  for (int c = 0; c < 256; ++c) t[c] = c < 0x20 || c > 0x7e || c == '"' || c == '\\';
  return t;
}();

}  // namespace

void JsonStream::quoted(std::string_view s) {
  for (unsigned char c : s)
    if (kNeedsDump[c]) {
      put(nlohmann::json(std::string(s)).dump());
      return;
    }
  room(s.size() + 2);
  buf_[len_++] = '"';
  std::memcpy(buf_.get() + len_, s.data(), s.size());
  len_ += s.size();
  buf_[len_++] = '"';
  if (out_ && len_ >= kFlushBytes) flush();
}

void JsonStream::string(std::string_view s) {
  before_value();
  quoted(s);
  if (levels_.empty()) flush();
}

void JsonStream::before_value() {
  if (levels_.empty()) {
    if (wrote_root_) throw std::logic_error("JsonStream: a second root value");
    wrote_root_ = true;
    return;
  }
  Level& l = levels_.back();
  if (l.object) {
    if (!l.have_key) throw std::logic_error("JsonStream: an object value without a key");
    l.have_key = false;
    return;
  }
  if (!l.empty) put(',');
  else if (!l.spliced) put('[');
  l.empty = false;
  newline(levels_.size());
}

void JsonStream::open_key(std::string_view k) {
  if (levels_.empty() || !levels_.back().object) throw std::logic_error("JsonStream: a key outside an object");
  Level& l = levels_.back();
  if (l.have_key) throw std::logic_error("JsonStream: two keys in a row");
  if (!l.empty && !(l.last_key < k))
    throw std::logic_error("JsonStream: key \"" + std::string(k) + "\" after \"" + l.last_key + "\"");
  put(l.empty ? '{' : ',');
  l.empty = false;
  l.have_key = true;
  l.last_key = k;
  newline(levels_.size());
}

JsonStream& JsonStream::key(std::string_view k) {
  open_key(k);
  quoted(k);
  put(std::string_view(": ", 2));
  return *this;
}

JsonStream::Key::Key(std::string_view name) : name_(name), text_(nlohmann::json(name_).dump() + ": ") {}

JsonStream& JsonStream::key(const Key& k) {
  open_key(k.name_);
  put(k.text_);
  return *this;
}

// The opening bracket waits for the first element: an empty container is "{}" or "[]".
JsonStream& JsonStream::begin_object() {
  before_value();
  levels_.push_back({true, true, false, false, {}});
  return *this;
}

JsonStream& JsonStream::begin_array() {
  before_value();
  levels_.push_back({false, true, false, false, {}});
  return *this;
}

JsonStream& JsonStream::close(bool object, char bracket) {
  if (levels_.size() <= base_ || levels_.back().object != object || levels_.back().have_key)
    throw std::logic_error("JsonStream: unbalanced close");
  const bool empty = levels_.back().empty;
  levels_.pop_back();
  if (empty) {
    put(object ? '{' : '[');
  } else {
    newline(levels_.size());
  }
  put(bracket);
  if (levels_.empty()) flush();
  return *this;
}

JsonStream& JsonStream::end_object() { return close(true, '}'); }
JsonStream& JsonStream::end_array() { return close(false, ']'); }

void JsonStream::scalar(std::string_view text) {
  before_value();
  put(text);
  if (levels_.empty()) flush();  // a root scalar is the whole document
}

// nlohmann's own shortest round-trip form (what dump() writes), without a
// json value per number. (libstdc++'s std::to_chars, Ryu, costs as many
// instructions here and gives other digits for one number in 1,600.)
void JsonStream::number(double v) {
  before_value();
  if (!std::isfinite(v)) {
    put("null");
  } else {
    constexpr std::size_t kLongest = 32;  // -d.ddddddddddddddddde-308 is 25
    room(kLongest);
    char* at = buf_.get() + len_;
    len_ += static_cast<std::size_t>(nlohmann::detail::to_chars(at, at + kLongest, v) - at);
    if (out_ && len_ >= kFlushBytes) flush();
  }
  if (levels_.empty()) flush();
}

// A small value: dump(indent) shifted to this depth (its strings hold no raw newline).
void JsonStream::dom(const nlohmann::json& v) {
  before_value();
  const std::string text = v.dump(indent_);
  std::size_t from = 0;
  for (std::size_t nl; (nl = text.find('\n', from)) != std::string::npos; from = nl + 1) {
    put(std::string_view(text).substr(from, nl - from));
    newline(levels_.size());
  }
  put(std::string_view(text).substr(from));
  if (levels_.empty()) flush();
}

}  // namespace raysweep::pipeline
