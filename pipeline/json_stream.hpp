// A JSON writer that streams to an ostream, with exactly the text of
// nlohmann::json's dump(indent): the same indentation, number and string
// forms, and the same key order, which the writer enforces (an object's keys
// must come in increasing byte order, as std::map sorts them). A trace's
// paths then never have to live twice in memory (once as a DOM, once as text),
// and readers that compared against the DOM's output still read the same bytes.
#pragma once

#include <charconv>
#include <cstring>
#include <memory>
#include <ostream>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <nlohmann/json.hpp>

namespace raysweep::pipeline {

class JsonStream {
 public:
  explicit JsonStream(std::ostream& out, int indent = 1) : out_(&out), indent_(indent) { grow(kFlushBytes + 4096); }
  // Elements of an array that another stream has open at `depth` (its
  // number of open objects and arrays), formatted apart, on another thread,
  // into text that the other stream's splice() takes: the bytes are those of
  // writing the elements there.
  struct Fragment {
    std::size_t depth;
  };
  explicit JsonStream(Fragment at, int indent = 1);
  ~JsonStream();  // writes what is buffered (flush() reports failures; this cannot)
  JsonStream(const JsonStream&) = delete;
  JsonStream& operator=(const JsonStream&) = delete;
  // Hands the buffered text to the stream (also done when the root value closes).
  void flush();

  JsonStream& begin_object();
  JsonStream& end_object();
  JsonStream& begin_array();
  JsonStream& end_array();
  // A key quoted once, for keys written many times (a trace's path fields).
  class Key {
   public:
    explicit Key(std::string_view name);
    std::string_view name() const { return name_; }

   private:
    friend class JsonStream;
    std::string name_;
    std::string text_;  // "name": (as key(name) writes it)
  };
  // The next value's key; std::logic_error when it does not sort after the previous key.
  JsonStream& key(std::string_view k);
  JsonStream& key(const Key& k);
  // A scalar, or a small value written as dump(indent) writes it at this depth.
  template <class T>
  JsonStream& value(const T& v) {
    if constexpr (std::is_same_v<T, bool>) {
      scalar(v ? "true" : "false");
    } else if constexpr (std::is_integral_v<T>) {
      char text[24];
      scalar(std::string_view(text, static_cast<std::size_t>(std::to_chars(text, text + sizeof text, v).ptr - text)));
    } else if constexpr (std::is_floating_point_v<T>) {
      number(static_cast<double>(v));
    } else if constexpr (std::is_same_v<T, std::string> || std::is_same_v<T, std::string_view> ||
                         std::is_same_v<T, const char*> || std::is_same_v<T, char*> ||
                         (std::is_array_v<T> && std::is_same_v<std::remove_cv_t<std::remove_extent_t<T>>, char>)) {
      string(std::string_view(v));
    } else {
      dom(nlohmann::json(v));
    }
    return *this;
  }
  // A scalar already in JSON text (a string quoted once for many uses, null).
  JsonStream& json_text(std::string_view text) {
    scalar(text);
    return *this;
  }
  template <class K, class T>
  JsonStream& field(const K& k, const T& v) {
    return key(k).value(v);
  }
  // An array of numbers.
  template <class K, class Range>
  JsonStream& number_array(const K& k, const Range& values) {
    key(k).begin_array();
    for (const auto& v : values) value(v);
    return end_array();
  }
  // True when every opened object and array is closed.
  bool complete() const { return levels_.size() == base_ && wrote_root_; }
  // Objects and arrays open now (a Fragment's depth for elements of this array).
  std::size_t depth() const { return levels_.size(); }
  // A fragment's finished text (moved, not copied).
  class Text {
   public:
    std::string_view view() const { return {data_.get(), size_}; }
    operator std::string_view() const { return view(); }

   private:
    friend class JsonStream;
    std::unique_ptr<char[]> data_;
    std::size_t size_ = 0;
  };
  // A fragment's text, once complete() (std::logic_error otherwise).
  Text take();
  // Appends a fragment's text to the open array, as its next elements.
  JsonStream& splice(std::string_view fragment);

 private:
  struct Level {
    bool object = false;
    bool empty = true;
    bool have_key = false;  // objects: a key waits for its value
    bool spliced = false;   // a fragment's array: its bracket is in the other stream
    std::string last_key;
  };
  static constexpr std::size_t kFlushBytes = 1 << 20;
  static constexpr std::size_t kFragmentBytes = 1 << 17;  // a trace's chunk of 16 pairs is about 110 kB
  std::ostream* out_ = nullptr;  // none for a fragment
  // Text not yet handed to out_ (one write per MiB, not one per token): its
  // first len_ bytes; the rest is room, so that appending a token is a copy
  // and a compare (no std::string bookkeeping per token).
  std::unique_ptr<char[]> buf_;
  std::size_t cap_ = 0, len_ = 0;
  int indent_;
  std::vector<Level> levels_;
  std::size_t base_ = 0;  // levels a fragment starts inside (and cannot close)
  bool wrote_root_ = false;
  std::string pad_;  // a newline and spaces enough for the deepest level so far
  static constexpr std::size_t kShortPad = 16;  // newlines this long or shorter are copied whole

  void before_value();
  void scalar(std::string_view text);
  void string(std::string_view s);
  void quoted(std::string_view s);  // s as dump() writes a string
  void room(std::size_t n) {
    if (cap_ - len_ < n) grow(n);
  }
  void grow(std::size_t n);
  void put(std::string_view text) {
    room(text.size());
    std::memcpy(buf_.get() + len_, text.data(), text.size());
    len_ += text.size();
    if (out_ && len_ >= kFlushBytes) flush();
  }
  void put(char c) {
    room(1);
    buf_[len_++] = c;
  }
  void number(double v);
  void open_key(std::string_view k);  // the checks and the separator before a key
  void dom(const nlohmann::json& v);
  void newline(std::size_t depth);
  JsonStream& close(bool object, char bracket);
};

}  // namespace raysweep::pipeline
