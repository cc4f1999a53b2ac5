// Streaming reader for SUMO floating car data (--fcd-output), plain or gzip.
// City runs produce gigabytes, so frames are pulled one timestep at a time in
// constant memory: only the current frame is held.
//
// FCD: <fcd-export> <timestep time="0.00"> <vehicle id x y [z] angle type speed
// pos lane [slope] .../> <person .../> </timestep> ... </fcd-export>. x, y are
// the front-bumper centre in network coordinates (lon/lat with
// --fcd-output.geo, which this reader cannot tell apart), angle is degrees
// clockwise from north.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace raysweep::pipeline {

struct FcdVehicle {
  std::string id, type;  // type: "DEFAULT_VEHTYPE" when the file gives none
  double x = 0, y = 0, z = 0;
  bool has_z = false;
  double angle_deg = 0, speed_mps = 0, slope_deg = 0;  // slope 0 when absent
  long line = 0;
};

struct FcdFrame {
  double time_s = 0;
  long line = 0;  // of the <timestep> element
  std::vector<FcdVehicle> vehicles;
};

struct FcdArea {
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;
};

struct FcdFilter {
  double begin_s = -std::numeric_limits<double>::infinity();  // inclusive
  double end_s = std::numeric_limits<double>::infinity();     // inclusive; reading stops past it
  // Keep a frame only when time >= last kept time + step_s - 1e-9 (0 keeps every frame).
  double step_s = 0;
  std::set<std::string> ids, types;  // empty = all
  std::optional<FcdArea> area;       // keep vehicles whose (x, y) lies inside (edges included)
};

// Pulls the frames of an FCD file. Throws meshkit::InputError naming the file,
// "line N" and the element for: an unreadable file, a root that is not
// <fcd-export>, timestep times that are missing, not numbers or not strictly
// increasing, a duplicate vehicle id within a timestep, a vehicle without
// id/x/y/angle/speed, non-numeric or non-finite (NaN, Inf) numbers, and
// malformed or truncated XML or gzip. Timesteps outside the time window or
// dropped by the step are skipped without looking at their vehicles; every
// vehicle of a kept timestep is validated, also those the id/type/area
// filters then drop. <person> and <container> elements are ignored.
class FcdReader {
 public:
  explicit FcdReader(const std::string& path, FcdFilter filter = {});
  ~FcdReader();
  FcdReader(FcdReader&&) noexcept;
  FcdReader& operator=(FcdReader&&) noexcept;

  // The next kept frame, its vehicles filtered; false at the end of the file
  // or once a timestep after filter.end_s appears (the rest is not read).
  // Frames with no vehicle left after filtering are still returned. After an
  // error every later call throws the same error again.
  bool next(FcdFrame& frame);

  const std::string& path() const;
  // Timesteps seen so far, kept or not (not counting one past end_s that ended reading).
  std::uint64_t frames_read() const;

  struct State;

 private:
  std::unique_ptr<State> state_;
};

// Parses an FCD time: seconds ("12.50") or SUMO's human-readable
// [D:]HH:MM:SS[.fff] (--human-readable-time). std::nullopt when neither or not finite.
std::optional<double> parse_fcd_time(const char* text);

}  // namespace raysweep::pipeline
