#include "meshkit/xml_reader.hpp"

#include <expat.h>
#include <zlib.h>

#include <cstring>
#include <exception>
#include <memory>

#include "meshkit/errors.hpp"

namespace raysweep::meshkit {

const char* XmlStart::attr(std::string_view key) const {
  for (const char** a = attrs; a && *a; a += 2)
    if (key == a[0]) return a[1];
  return nullptr;
}

namespace {

struct ParseState {
  const XmlCallbacks* callbacks;
  XML_Parser parser;
  std::exception_ptr error;
};

void on_start(void* user, const XML_Char* name, const XML_Char** attrs) {
  auto* s = static_cast<ParseState*>(user);
  if (s->error || !s->callbacks->start) return;
  try {
    s->callbacks->start(XmlStart{name, attrs, static_cast<long>(XML_GetCurrentLineNumber(s->parser))});
  } catch (...) {
    s->error = std::current_exception();
    XML_StopParser(s->parser, XML_FALSE);
  }
}

void on_end(void* user, const XML_Char* name) {
  auto* s = static_cast<ParseState*>(user);
  if (s->error || !s->callbacks->end) return;
  try {
    s->callbacks->end(name);
  } catch (...) {
    s->error = std::current_exception();
    XML_StopParser(s->parser, XML_FALSE);
  }
}

class Parser {
 public:
  Parser(const std::string& label, const XmlCallbacks& callbacks) : label_(label) {
    parser_ = XML_ParserCreate(nullptr);
    state_ = ParseState{&callbacks, parser_, nullptr};
    XML_SetUserData(parser_, &state_);
    XML_SetElementHandler(parser_, on_start, on_end);
  }
  ~Parser() { XML_ParserFree(parser_); }
  Parser(const Parser&) = delete;
  Parser& operator=(const Parser&) = delete;

  void feed(const char* data, int len, bool final) {
    const XML_Status status = XML_Parse(parser_, data, len, final ? XML_TRUE : XML_FALSE);
    if (state_.error) std::rethrow_exception(state_.error);
    if (status == XML_STATUS_ERROR) {
      throw InputError(label_, "line " + std::to_string(XML_GetCurrentLineNumber(parser_)),
                       std::string("malformed XML: ") + XML_ErrorString(XML_GetErrorCode(parser_)));
    }
  }

 private:
  std::string label_;
  XML_Parser parser_;
  ParseState state_;
};

}  // namespace

void parse_xml_file(const std::string& path, const XmlCallbacks& callbacks) {
  // gzread passes uncompressed files through unchanged, so one path serves both.
  gzFile file = gzopen(path.c_str(), "rb");
  if (!file) throw InputError(path, "", std::string("cannot open: ") + std::strerror(errno));
  std::unique_ptr<gzFile_s, int (*)(gzFile)> guard(file, gzclose);
  gzbuffer(file, 1 << 17);
  Parser parser(path, callbacks);
  std::unique_ptr<char[]> buf(new char[1 << 16]);
  for (;;) {
    const int n = gzread(file, buf.get(), 1 << 16);
    if (n < 0) {
      int code = 0;
      const char* msg = gzerror(file, &code);
      throw InputError(path, "", std::string("read error: ") + (msg ? msg : "unknown"));
    }
    if (n == 0) {
      int code = 0;
      gzerror(file, &code);
      // A truncated gzip stream reads as a short file; zlib flags it here.
      if (code != Z_OK && code != Z_STREAM_END && code != Z_BUF_ERROR)
        throw InputError(path, "", "truncated or corrupt compressed file");
      if (!gzdirect(file) && code == Z_BUF_ERROR)
        throw InputError(path, "", "truncated compressed file (unexpected end of gzip stream)");
      parser.feed(nullptr, 0, true);
      return;
    }
    parser.feed(buf.get(), n, false);
  }
}

void parse_xml_string(std::string_view xml, const std::string& label, const XmlCallbacks& callbacks) {
  Parser parser(label, callbacks);
  parser.feed(xml.data(), static_cast<int>(xml.size()), true);
}

}  // namespace raysweep::meshkit
