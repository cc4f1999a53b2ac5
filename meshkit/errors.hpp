// Errors for bad input: every message names the file and the offending element
// (OSM id, XML line, mesh name) so a user can find it.
#pragma once

#include <stdexcept>
#include <string>

namespace raysweep::meshkit {

class InputError : public std::runtime_error {
 public:
  InputError(const std::string& file, const std::string& element, const std::string& what)
      : std::runtime_error(file + (element.empty() ? "" : ": " + element) + ": " + what),
        file_(file),
        element_(element) {}
  const std::string& file() const { return file_; }
  const std::string& element() const { return element_; }

 private:
  std::string file_;
  std::string element_;
};

}  // namespace raysweep::meshkit
