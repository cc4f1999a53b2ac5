// The error of a bad config file or setting.
#pragma once

#include <stdexcept>

namespace raysweep::pipeline {

// Thrown for config errors; the message names file, key and line.
struct ConfigError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace raysweep::pipeline
