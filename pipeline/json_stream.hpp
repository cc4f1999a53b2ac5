// A JSON writer that streams to an ostream, with exactly the text of
// nlohmann::json's dump(indent): the same indentation, number and string
// forms, and the same key order, which the writer enforces (an object's keys
// must come in increasing byte order, as std::map sorts them). A trace's
// paths then never have to live twice in memory (once as a DOM, once as text),
// and readers that compared against the DOM's output still read the same bytes.
#pragma once

#include <ostream>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <nlohmann/json.hpp>

namespace raysweep::pipeline {

class JsonStream {
 public:
  explicit JsonStream(std::ostream& out, int indent = 1) : out_(out), indent_(indent) {}

  JsonStream& begin_object();
  JsonStream& end_object();
  JsonStream& begin_array();
  JsonStream& end_array();
  // The next value's key; std::logic_error when it does not sort after the previous key.
  JsonStream& key(std::string_view k);
  // A scalar, or a small value written as dump(indent) writes it at this depth.
  template <class T>
  JsonStream& value(const T& v) {
    if constexpr (std::is_same_v<T, bool>) scalar(v ? "true" : "false");
    else if constexpr (std::is_integral_v<T>) scalar(std::to_string(v));
    else if constexpr (std::is_floating_point_v<T>) number(static_cast<double>(v));
    else dom(nlohmann::json(v));
    return *this;
  }
  template <class T>
  JsonStream& field(std::string_view k, const T& v) {
    return key(k).value(v);
  }
  // An array of numbers.
  template <class Range>
  JsonStream& number_array(std::string_view k, const Range& values) {
    key(k).begin_array();
    for (const auto& v : values) value(v);
    return end_array();
  }
  // True when every opened object and array is closed.
  bool complete() const { return levels_.empty() && wrote_root_; }

 private:
  struct Level {
    bool object = false;
    bool empty = true;
    bool have_key = false;  // objects: a key waits for its value
    std::string last_key;
  };
  std::ostream& out_;
  int indent_;
  std::vector<Level> levels_;
  bool wrote_root_ = false;
  std::string pad_;  // a newline and spaces enough for the deepest level so far

  void before_value();
  void scalar(std::string_view text);
  void number(double v);
  void dom(const nlohmann::json& v);
  void newline(std::size_t depth);
  JsonStream& close(bool object, char bracket);
};

}  // namespace raysweep::pipeline
