#include "pipeline/json_stream.hpp"

#include <array>
#include <cmath>
#include <stdexcept>

namespace raysweep::pipeline {

void JsonStream::newline(std::size_t depth) {
  const std::size_t n = depth * static_cast<std::size_t>(indent_) + 1;
  if (pad_.size() < n) pad_ = "\n" + std::string(2 * n, ' ');
  out_.write(pad_.data(), static_cast<std::streamsize>(n));
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
  out_.put(l.empty ? '[' : ',');
  l.empty = false;
  newline(levels_.size());
}

JsonStream& JsonStream::key(std::string_view k) {
  if (levels_.empty() || !levels_.back().object) throw std::logic_error("JsonStream: a key outside an object");
  Level& l = levels_.back();
  if (l.have_key) throw std::logic_error("JsonStream: two keys in a row");
  if (!l.empty && !(l.last_key < k))
    throw std::logic_error("JsonStream: key \"" + std::string(k) + "\" after \"" + l.last_key + "\"");
  out_.put(l.empty ? '{' : ',');
  l.empty = false;
  l.have_key = true;
  l.last_key = k;
  newline(levels_.size());
  out_ << nlohmann::json(std::string(k)).dump() << ": ";
  return *this;
}

// The opening bracket waits for the first element: an empty container is "{}" or "[]".
JsonStream& JsonStream::begin_object() {
  before_value();
  levels_.push_back({true, true, false, {}});
  return *this;
}

JsonStream& JsonStream::begin_array() {
  before_value();
  levels_.push_back({false, true, false, {}});
  return *this;
}

JsonStream& JsonStream::close(bool object, char bracket) {
  if (levels_.empty() || levels_.back().object != object || levels_.back().have_key)
    throw std::logic_error("JsonStream: unbalanced close");
  const bool empty = levels_.back().empty;
  levels_.pop_back();
  if (empty) {
    out_.put(object ? '{' : '[');
  } else {
    newline(levels_.size());
  }
  out_.put(bracket);
  return *this;
}

JsonStream& JsonStream::end_object() { return close(true, '}'); }
JsonStream& JsonStream::end_array() { return close(false, ']'); }

void JsonStream::scalar(std::string_view text) {
  before_value();
  out_ << text;
}

// nlohmann's own shortest round-trip form (what dump() writes), without a json value per number.
void JsonStream::number(double v) {
  before_value();
  if (!std::isfinite(v)) {
    out_ << "null";
    return;
  }
  std::array<char, 64> buf;
  const char* end = nlohmann::detail::to_chars(buf.data(), buf.data() + buf.size(), v);
  out_.write(buf.data(), end - buf.data());
}

// A small value: dump(indent) shifted to this depth (its strings hold no raw newline).
void JsonStream::dom(const nlohmann::json& v) {
  before_value();
  const std::string text = v.dump(indent_);
  std::size_t from = 0;
  for (std::size_t nl; (nl = text.find('\n', from)) != std::string::npos; from = nl + 1) {
    out_.write(text.data() + from, static_cast<std::streamsize>(nl - from));
    newline(levels_.size());
  }
  out_.write(text.data() + from, static_cast<std::streamsize>(text.size() - from));
}

}  // namespace raysweep::pipeline
