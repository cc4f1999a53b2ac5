#include "pipeline/fcd.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string_view>
#include <unordered_set>

#include "meshkit/errors.hpp"
#include "meshkit/xml_reader.hpp"

namespace raysweep::pipeline {

using meshkit::InputError;

namespace {

constexpr double kTimeEps = 1e-9;

// A finite double spanning the whole of [first, last).
bool parse_number(const char* first, const char* last, double& out) {
  if (first == last) return false;
  const auto [ptr, ec] = std::from_chars(first, last, out);
  return ec == std::errc() && ptr == last && std::isfinite(out);
}

bool parse_number(const char* text, double& out) { return parse_number(text, text + std::strlen(text), out); }

std::string fmt_time(double t) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", t);
  return buf;
}

}  // namespace

std::optional<double> parse_fcd_time(const char* text) {
  if (!text) return std::nullopt;
  const char* end = text + std::strlen(text);
  double value = 0;
  if (!std::memchr(text, ':', static_cast<std::size_t>(end - text))) {
    if (!parse_number(text, end, value)) return std::nullopt;
    return value;
  }
  // [D:]HH:MM:SS[.fff]: up to three integer fields, then seconds.
  bool negative = false;
  const char* p = text;
  if (*p == '-') {
    negative = true;
    ++p;
  }
  long fields[3];
  int nfields = 0;
  for (;;) {
    const char* colon = static_cast<const char*>(std::memchr(p, ':', static_cast<std::size_t>(end - p)));
    if (!colon) break;
    if (nfields == 3 || colon == p) return std::nullopt;
    long v = 0;
    const auto [ptr, ec] = std::from_chars(p, colon, v);
    if (ec != std::errc() || ptr != colon || v < 0) return std::nullopt;
    fields[nfields++] = v;
    p = colon + 1;
  }
  double seconds = 0;
  if (nfields < 2 || !parse_number(p, end, seconds) || seconds < 0 || seconds >= 60) return std::nullopt;
  const long days = nfields == 3 ? fields[0] : 0;
  const long hours = fields[nfields - 2], minutes = fields[nfields - 1];
  if (minutes >= 60 || (nfields == 3 && hours >= 24)) return std::nullopt;
  value = ((static_cast<double>(days) * 24 + static_cast<double>(hours)) * 60 + static_cast<double>(minutes)) * 60 + seconds;
  return negative ? -value : value;
}

struct FcdReader::State {
  std::string path;
  FcdFilter filter;
  std::unique_ptr<meshkit::XmlPullParser> parser;

  FcdFrame current;          // being filled, or complete when frame_ready
  bool frame_ready = false;  // current is a complete kept frame
  bool done = false;         // nothing more to return
  std::exception_ptr error;  // rethrown by every next() after a failure

  int depth = 0;
  bool in_timestep = false, keep_frame = false;
  bool have_time = false, have_kept = false;
  double last_time = 0, last_kept = 0;
  std::uint64_t frames_read = 0;
  std::unordered_set<std::string> ids_in_frame;

  std::string where(long line, std::string_view element, const char* id = nullptr) const {
    std::string s = "line " + std::to_string(line) + " " + std::string(element);
    if (id) s += std::string(" ") + id;
    return s;
  }

  void on_start(const meshkit::XmlStart& e) {
    const int level = depth++;
    if (level == 0) {
      if (e.name != "fcd-export")
        throw InputError(path, where(e.line, e.name),
                         "the root element is <" + std::string(e.name) + ">, not <fcd-export> (not a SUMO FCD file?)");
      return;
    }
    if (e.name == "timestep") {
      start_timestep(e);
    } else if (e.name == "vehicle") {
      if (!in_timestep) throw InputError(path, where(e.line, e.name, e.attr("id")), "vehicle outside a <timestep>");
      if (keep_frame) add_vehicle(e);
    }
    // <person>, <container> and anything newer SUMO writes: ignored.
  }

  void on_end(std::string_view name) {
    --depth;
    if (depth == 1 && name == "timestep") {
      in_timestep = false;
      if (keep_frame) {
        frame_ready = true;
        parser->suspend();  // hand this frame out before parsing on
      }
    }
  }

  void start_timestep(const meshkit::XmlStart& e) {
    if (depth != 2) throw InputError(path, where(e.line, e.name), "<timestep> must be a child of <fcd-export>");
    const char* text = e.attr("time");
    if (!text) throw InputError(path, where(e.line, e.name), "has no time attribute");
    const std::optional<double> t = parse_fcd_time(text);
    if (!t) throw InputError(path, where(e.line, e.name), std::string("time='") + text + "' is not a finite number");
    if (have_time && !(*t > last_time))
      throw InputError(path, where(e.line, e.name),
                       "non-monotonic time: " + std::string(text) + " after " + fmt_time(last_time));
    have_time = true;
    last_time = *t;
    if (*t > filter.end_s + kTimeEps) {
      // Past the window: stop without reading the rest of the file.
      done = true;
      keep_frame = false;
      parser->suspend();
      return;
    }
    ++frames_read;
    in_timestep = true;
    keep_frame = *t >= filter.begin_s - kTimeEps && (!have_kept || *t >= last_kept + filter.step_s - kTimeEps);
    if (!keep_frame) return;
    have_kept = true;
    last_kept = *t;
    current.time_s = *t;
    current.line = e.line;
    current.vehicles.clear();
    ids_in_frame.clear();
  }

  void add_vehicle(const meshkit::XmlStart& e) {
    const char *id = nullptr, *type = nullptr, *x = nullptr, *y = nullptr, *z = nullptr, *angle = nullptr,
               *speed = nullptr, *slope = nullptr;
    for (const char** a = e.attrs; a && *a; a += 2) {
      const std::string_view key = a[0];
      const char* value = a[1];
      if (key.size() == 1) {
        if (key[0] == 'x') x = value;
        else if (key[0] == 'y') y = value;
        else if (key[0] == 'z') z = value;
      } else if (key == "id") {
        id = value;
      } else if (key == "type") {
        type = value;
      } else if (key == "angle") {
        angle = value;
      } else if (key == "speed") {
        speed = value;
      } else if (key == "slope") {
        slope = value;
      }
    }
    if (!id) throw InputError(path, where(e.line, "vehicle"), "has no id attribute");
    auto required = [&](const char* key, const char* text, double& out) {
      if (!text) throw InputError(path, where(e.line, "vehicle", id), std::string("has no ") + key + " attribute");
      if (!parse_number(text, out))
        throw InputError(path, where(e.line, "vehicle", id),
                         std::string(key) + "='" + text + "' is not a finite number");
    };
    FcdVehicle v;
    required("x", x, v.x);
    required("y", y, v.y);
    required("angle", angle, v.angle_deg);
    required("speed", speed, v.speed_mps);
    if (z) {
      required("z", z, v.z);
      v.has_z = true;
    }
    if (slope) required("slope", slope, v.slope_deg);
    if (!ids_in_frame.emplace(id).second)
      throw InputError(path, where(e.line, "vehicle", id),
                       "duplicate vehicle id in the timestep at time " + fmt_time(current.time_s));
    const char* type_id = type ? type : "DEFAULT_VEHTYPE";
    if (!filter.ids.empty() && !filter.ids.count(id)) return;
    if (!filter.types.empty() && !filter.types.count(type_id)) return;
    if (filter.area) {
      const FcdArea& a = *filter.area;
      if (!(v.x >= a.xmin && v.x <= a.xmax && v.y >= a.ymin && v.y <= a.ymax)) return;
    }
    v.id = id;
    v.type = type_id;
    v.line = e.line;
    current.vehicles.push_back(std::move(v));
  }
};

FcdReader::FcdReader(const std::string& path, FcdFilter filter) : state_(std::make_unique<State>()) {
  State* s = state_.get();
  s->path = path;
  s->filter = std::move(filter);
  if (std::isnan(s->filter.begin_s) || std::isnan(s->filter.end_s) || !std::isfinite(s->filter.step_s) ||
      s->filter.step_s < 0)
    throw std::invalid_argument("FcdFilter for " + path + ": begin/end must not be NaN and step must be >= 0");
  meshkit::XmlCallbacks callbacks;
  callbacks.start = [s](const meshkit::XmlStart& e) { s->on_start(e); };
  callbacks.end = [s](std::string_view name) { s->on_end(name); };
  s->parser = std::make_unique<meshkit::XmlPullParser>(path, std::move(callbacks));
}

FcdReader::~FcdReader() = default;
FcdReader::FcdReader(FcdReader&&) noexcept = default;
FcdReader& FcdReader::operator=(FcdReader&&) noexcept = default;

bool FcdReader::next(FcdFrame& frame) {
  State& s = *state_;
  if (s.error) std::rethrow_exception(s.error);
  try {
    while (!s.frame_ready && !s.done)
      if (!s.parser->pump()) s.done = true;
  } catch (...) {
    s.error = std::current_exception();
    s.done = true;
    s.frame_ready = false;
    throw;
  }
  if (!s.frame_ready) {
    s.parser.reset();  // closes the file early
    return false;
  }
  s.frame_ready = false;
  std::swap(frame, s.current);  // the caller's old frame becomes the next buffer
  return true;
}

const std::string& FcdReader::path() const { return state_->path; }
std::uint64_t FcdReader::frames_read() const { return state_->frames_read; }

}  // namespace raysweep::pipeline
