// Streaming XML reading (expat) of plain or gzip-compressed files, in constant
// memory, with line numbers for error messages. SUMO networks and FCD traces
// run to gigabytes, so nothing here builds a DOM.
#pragma once

#include <functional>
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

// Same, for XML held in memory (tests, embedded snippets). `label` names it in errors.
void parse_xml_string(std::string_view xml, const std::string& label, const XmlCallbacks& callbacks);

}  // namespace raysweep::meshkit
