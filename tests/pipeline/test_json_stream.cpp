// pipeline::JsonStream writes, without a DOM, the very text nlohmann::json's
// dump(indent) writes of the same document; keys out of order are refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>

#include "pipeline/json_stream.hpp"

using raysweep::pipeline::JsonStream;
using nlohmann::json;

namespace {

// Streams `v` value by value (objects in their sorted key order).
void stream(JsonStream& js, const json& v) {
  if (v.is_object()) {
    js.begin_object();
    for (const auto& [k, x] : v.items()) {
      js.key(k);
      stream(js, x);
    }
    js.end_object();
  } else if (v.is_array()) {
    js.begin_array();
    for (const auto& x : v) stream(js, x);
    js.end_array();
  } else if (v.is_number_float()) {
    js.value(v.get<double>());
  } else if (v.is_number_unsigned()) {
    js.value(v.get<std::uint64_t>());
  } else if (v.is_number_integer()) {
    js.value(v.get<std::int64_t>());
  } else if (v.is_boolean()) {
    js.value(v.get<bool>());
  } else {
    js.value(v);  // strings and null
  }
}

std::string streamed(const json& v, int indent) {
  std::ostringstream out;
  JsonStream js(out, indent);
  stream(js, v);
  EXPECT_TRUE(js.complete());
  return out.str();
}

// Random documents of every value kind, nesting and emptiness.
json random_value(std::mt19937_64& rng, int depth) {
  std::uniform_int_distribution<int> kind(0, depth > 3 ? 5 : 7);
  switch (kind(rng)) {
    case 0: return nullptr;
    case 1: return std::uniform_int_distribution<int>(0, 1)(rng) == 1;
    case 2: return std::uniform_int_distribution<std::int64_t>(-1000000, 1000000)(rng);
    case 3: return std::uniform_int_distribution<std::uint64_t>()(rng);
    case 4: {
      const double m = std::uniform_real_distribution<double>(-1, 1)(rng);
      return std::ldexp(m, std::uniform_int_distribution<int>(-1070, 1020)(rng));
    }
    case 5: return std::string("s\"\\\n\t\u00e9") + std::to_string(rng() % 100);
    case 6: {
      json a = json::array();
      for (int n = std::uniform_int_distribution<int>(0, 4)(rng); n > 0; --n) a.push_back(random_value(rng, depth + 1));
      return a;
    }
    default: {
      json o = json::object();
      for (int n = std::uniform_int_distribution<int>(0, 4)(rng); n > 0; --n)
        o["k" + std::to_string(rng() % 50)] = random_value(rng, depth + 1);
      return o;
    }
  }
}

}  // namespace

TEST(JsonStream, WritesWhatDumpWritesForRandomDocuments) {
  std::mt19937_64 rng(7);
  for (int i = 0; i < 300; ++i) {
    const json doc = random_value(rng, 0);
    for (int indent : {1, 2}) ASSERT_EQ(streamed(doc, indent), doc.dump(indent)) << doc.dump();
  }
}

TEST(JsonStream, NumbersAsDumpWritesThem) {
  const double inf = std::numeric_limits<double>::infinity();
  json doc = {{"a", 0.0},     {"b", -0.0},          {"c", 1e-300}, {"d", 5e-324},  {"e", 1.0 / 3},
              {"f", 1e21},    {"g", 123456789.0},   {"h", -2.5},   {"i", 1e15},    {"j", 1e16},
              {"k", 0.0001},  {"l", 0.00001},       {"m", 255u},   {"n", -7},      {"o", json::array()},
              {"p", json::object()}, {"q", std::numeric_limits<double>::max()}};
  EXPECT_EQ(streamed(doc, 1), doc.dump(1));
  // Not finite: null, as dump writes it.
  std::ostringstream out;
  JsonStream js(out, 1);
  js.begin_array().value(std::nan("")).value(inf).value(-inf).end_array();
  EXPECT_EQ(out.str(), json::array({nullptr, nullptr, nullptr}).dump(1));
}

TEST(JsonStream, RefusesKeysOutOfOrderAndUnbalancedCalls) {
  std::ostringstream out;
  JsonStream js(out);
  js.begin_object().field("b", 1);
  EXPECT_THROW(js.key("a"), std::logic_error);
  EXPECT_THROW(js.key("b"), std::logic_error);  // a repeated key
  EXPECT_THROW(js.end_array(), std::logic_error);
  js.key("c");
  EXPECT_THROW(js.end_object(), std::logic_error);  // a key without its value
  js.value(2).end_object();
  EXPECT_TRUE(js.complete());
  EXPECT_THROW(js.value(3), std::logic_error);  // a second document
  JsonStream arr(out);
  arr.begin_array();
  EXPECT_THROW(arr.key("a"), std::logic_error);
  EXPECT_FALSE(arr.complete());
}

// Keys quoted once (JsonStream::Key) write what the same keys as strings
// write, escapes and UTF-8 included, and are checked for order the same way.
TEST(JsonStream, QuotedOnceKeysWriteWhatStringKeysWrite) {
  const json doc = {{"a\"q", 1}, {"b\\\\", {{"c\t", 2.5}, {"d", {1, 2}}}}, {"h\xc3\xa9", "x"}, {"z", nullptr}};
  for (int indent : {1, 3}) {
    std::ostringstream out;
    {
      const JsonStream::Key aq("a\"q"), b("b\\\\"), c("c\t"), d("d"), he("h\xc3\xa9"), z("z");
      JsonStream js(out, indent);
      js.begin_object().field(aq, 1).key(b).begin_object().field(c, 2.5);
      js.number_array(d, std::vector<int>{1, 2}).end_object();
      js.field(he, "x").key(z).json_text("null").end_object();
    }
    EXPECT_EQ(out.str(), doc.dump(indent));
  }
  std::ostringstream out;
  JsonStream js(out);
  const JsonStream::Key a("a"), b("b");
  js.begin_object().field(b, 1);
  EXPECT_THROW(js.key(a), std::logic_error);
  EXPECT_THROW(js.key(b), std::logic_error);
  EXPECT_EQ(a.name(), "a");
}

// Elements formatted apart (as `trace` formats chunks of pairs on every core)
// and spliced in order give the bytes of writing them in place, whatever the
// split: none, every element alone, empty fragments, at any depth.
TEST(JsonStream, FragmentsSplicedGiveTheSameBytes) {
  std::mt19937_64 rng(11);
  for (int i = 0; i < 200; ++i) {
    json items = json::array();
    for (int n = std::uniform_int_distribution<int>(0, 6)(rng); n > 0; --n) items.push_back(random_value(rng, 1));
    const json doc = {{"a", 1}, {"list", {{"items", items}}}, {"z", "end"}};
    for (int indent : {1, 2}) {
      std::ostringstream out;
      JsonStream js(out, indent);
      js.begin_object().field("a", 1).key("list").begin_object().key("items").begin_array();
      std::size_t k = 0;
      do {  // n = 0: an empty fragment
        const std::size_t n = std::uniform_int_distribution<std::size_t>(0, items.size() - k)(rng);
        JsonStream part(JsonStream::Fragment{js.depth()}, indent);
        for (std::size_t e = k; e < k + n; ++e) stream(part, items[e]);
        js.splice(part.take());
        k += n;
      } while (k < items.size());
      js.end_array().end_object().field("z", "end").end_object();
      ASSERT_EQ(out.str(), doc.dump(indent)) << doc.dump();
    }
  }
}

TEST(JsonStream, FragmentsRefuseWhatWouldBreakTheDocument) {
  JsonStream part(JsonStream::Fragment{2});
  EXPECT_THROW(part.end_array(), std::logic_error);  // the array is the other stream's
  EXPECT_THROW(part.key("a"), std::logic_error);      // elements of an array, not members
  part.begin_object();
  EXPECT_THROW(part.take(), std::logic_error);  // unfinished
  part.field("a", 1).end_object();
  EXPECT_EQ(part.take().view(), "\n  {\n   \"a\": 1\n  }");
  EXPECT_THROW(JsonStream(JsonStream::Fragment{0}), std::logic_error);
  std::ostringstream out;
  JsonStream js(out);
  js.begin_object();
  EXPECT_THROW(js.splice("\n 1"), std::logic_error);  // not inside an array
  EXPECT_THROW(js.take(), std::logic_error);          // a stream's text goes to its ostream
}
