#include "meshkit/xml_reader.hpp"

#include <expat.h>
#include <zlib.h>

#include <cerrno>
#include <cstring>
#include <new>
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
  bool in_callback = false;
};

struct InCallback {
  explicit InCallback(ParseState* s) : s_(s) { s_->in_callback = true; }
  ~InCallback() { s_->in_callback = false; }
  ParseState* s_;
};

void on_start(void* user, const XML_Char* name, const XML_Char** attrs) {
  auto* s = static_cast<ParseState*>(user);
  if (s->error || !s->callbacks->start) return;
  InCallback guard(s);
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
  InCallback guard(s);
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
    if (!parser_) throw std::bad_alloc();
    state_ = ParseState{&callbacks, parser_, nullptr};
    XML_SetUserData(parser_, &state_);
    XML_SetElementHandler(parser_, on_start, on_end);
  }
  ~Parser() { XML_ParserFree(parser_); }
  Parser(const Parser&) = delete;
  Parser& operator=(const Parser&) = delete;

  // XML_STATUS_OK or XML_STATUS_SUSPENDED; throws for errors.
  XML_Status feed(const char* data, int len, bool final) {
    return check(XML_Parse(parser_, data, len, final ? XML_TRUE : XML_FALSE));
  }
  XML_Status resume() { return check(XML_ResumeParser(parser_)); }

  // Suspends a running parse; only has an effect from inside a callback.
  void suspend() {
    if (state_.in_callback && !state_.error) XML_StopParser(parser_, XML_TRUE);
  }
  long line() const { return static_cast<long>(XML_GetCurrentLineNumber(parser_)); }

 private:
  XML_Status check(XML_Status status) {
    if (state_.error) std::rethrow_exception(state_.error);
    if (status == XML_STATUS_ERROR) {
      throw InputError(label_, "line " + std::to_string(XML_GetCurrentLineNumber(parser_)),
                       std::string("malformed XML: ") + XML_ErrorString(XML_GetErrorCode(parser_)));
    }
    return status;
  }

  std::string label_;
  XML_Parser parser_;
  ParseState state_;
};

constexpr int kChunk = 1 << 18;  // uncompressed bytes per pump()

}  // namespace

class XmlPullParser::Impl {
 public:
  // Borrows `callbacks`, which must outlive the Impl (parse_xml_file).
  Impl(const std::string& path, const XmlCallbacks* callbacks) : path_(path) { open(callbacks); }
  // Owns a copy (XmlPullParser).
  Impl(const std::string& path, XmlCallbacks&& callbacks) : path_(path), owned_(std::move(callbacks)) { open(&owned_); }
  ~Impl() {
    if (file_) gzclose(file_);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  bool pump() {
    if (finished_) return false;
    XML_Status status;
    if (suspended_) {
      suspended_ = false;
      status = parser_->resume();
    } else {
      const int n = gzread(file_, buf_.get(), kChunk);
      if (n < 0) {
        int code = 0;
        const char* msg = gzerror(file_, &code);
        throw InputError(path_, data_end(), std::string("read error: ") + (msg ? msg : "unknown"));
      }
      if (n == 0) {
        int code = 0;
        gzerror(file_, &code);
        // A truncated gzip stream reads as a short file; zlib flags it here.
        if (code != Z_OK && code != Z_STREAM_END && code != Z_BUF_ERROR)
          throw InputError(path_, data_end(), "truncated or corrupt compressed file");
        if (!gzdirect(file_) && code == Z_BUF_ERROR)
          throw InputError(path_, data_end(), "truncated compressed file (unexpected end of gzip stream)");
        eof_ = true;
        status = parser_->feed(nullptr, 0, true);
      } else {
        count_newlines(buf_.get(), n);
        status = parser_->feed(buf_.get(), n, false);
      }
    }
    if (status == XML_STATUS_SUSPENDED) {
      suspended_ = true;
    } else if (eof_) {
      finished_ = true;
      gzclose(file_);
      file_ = nullptr;
    }
    return !finished_;
  }

  void suspend() { parser_->suspend(); }
  long line() const { return parser_->line(); }
  const std::string& path() const { return path_; }
  bool finished() const { return finished_; }

 private:
  void open(const XmlCallbacks* callbacks) {
    // gzread passes uncompressed files through unchanged, so one path serves both.
    errno = 0;
    file_ = gzopen(path_.c_str(), "rb");
    if (!file_) throw InputError(path_, "", std::string("cannot open: ") + std::strerror(errno ? errno : ENOENT));
    gzbuffer(file_, 1 << 17);
    buf_.reset(new char[kChunk]);
    parser_ = std::make_unique<Parser>(path_, *callbacks);
  }
  void count_newlines(const char* p, int n) {
    const char* end = p + n;
    while ((p = static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p))))) {
      ++newlines_;
      ++p;
    }
  }
  // Where the readable data ends (for archive errors, which expat never sees).
  std::string data_end() const { return "line " + std::to_string(newlines_ + 1); }

  std::string path_;
  XmlCallbacks owned_;
  gzFile file_ = nullptr;
  std::unique_ptr<char[]> buf_;
  std::unique_ptr<Parser> parser_;
  long newlines_ = 0;
  bool suspended_ = false, eof_ = false, finished_ = false;
};

XmlPullParser::XmlPullParser(const std::string& path, XmlCallbacks callbacks)
    : impl_(std::make_unique<Impl>(path, std::move(callbacks))) {}
XmlPullParser::~XmlPullParser() = default;
XmlPullParser::XmlPullParser(XmlPullParser&&) noexcept = default;
XmlPullParser& XmlPullParser::operator=(XmlPullParser&&) noexcept = default;
bool XmlPullParser::pump() { return impl_->pump(); }
void XmlPullParser::suspend() { impl_->suspend(); }
long XmlPullParser::line() const { return impl_->line(); }
const std::string& XmlPullParser::path() const { return impl_->path(); }
bool XmlPullParser::finished() const { return impl_->finished(); }

void parse_xml_file(const std::string& path, const XmlCallbacks& callbacks) {
  XmlPullParser::Impl parser(path, &callbacks);
  while (parser.pump()) {
  }
}

void parse_xml_string(std::string_view xml, const std::string& label, const XmlCallbacks& callbacks) {
  Parser parser(label, callbacks);
  parser.feed(xml.data(), static_cast<int>(xml.size()), true);
}

}  // namespace raysweep::meshkit
