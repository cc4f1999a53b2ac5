// Streaming XML reading (expat) of plain or gzip-compressed files, in constant
// memory, with line numbers for error messages. SUMO networks and FCD traces
// run to gigabytes, so nothing here builds a DOM.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

namespace raysweep::meshkit {

struct XmlStart {
  std::string_view name;
  const char** attrs;  // expat's null-terminated key/value array
  long line;
  const char* attr(std::string_view key) const;  // nullptr when absent
};

struct XmlCallbacks {
  std::function<void(const XmlStart&)> start;
  std::function<void(std::string_view name)> end;  // optional
};

// Parses `path` (gzip detected by content). Throws InputError naming the file
// and line for malformed XML, truncated archives and unreadable files. A
// callback may throw to abort; its exception propagates unchanged.
void parse_xml_file(const std::string& path, const XmlCallbacks& callbacks);

// Pull-mode parsing of a plain or gzip file: each pump() reads and parses the
// next chunk (256 KiB of uncompressed data), calling the callbacks for the
// elements it completes, so the caller decides when to read on (e.g. one FCD
// timestep at a time) and may stop early by simply not pumping again. Memory
// stays constant. Errors are the same InputErrors parse_xml_file throws; they
// surface from the pump() that meets them (or from the constructor when the
// file cannot be opened); archive errors name the last line read. A
// callback's exception propagates unchanged.
class XmlPullParser {
 public:
  XmlPullParser(const std::string& path, XmlCallbacks callbacks);
  ~XmlPullParser();
  XmlPullParser(XmlPullParser&&) noexcept;
  XmlPullParser& operator=(XmlPullParser&&) noexcept;

  // Parses on until the current chunk is used up, or a callback calls
  // suspend(). Returns false once the whole document has been parsed (the
  // final pump's callbacks have run by then); true while input remains.
  bool pump();
  // Only from inside a callback: the running pump() returns once the current
  // markup token is done (for an empty-element tag <a/> its end callback still
  // runs); the next pump() resumes with what follows. Lets a caller take one
  // record at a time. Ignored outside a callback.
  void suspend();
  // The line of the last parse event (expat's current line).
  long line() const;
  const std::string& path() const;
  bool finished() const;

  class Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Same, for XML held in memory (tests, embedded snippets). `label` names it in errors.
void parse_xml_string(std::string_view xml, const std::string& label, const XmlCallbacks& callbacks);

}  // namespace raysweep::meshkit
