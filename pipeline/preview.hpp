// PNG previews of stage outputs, drawn by the matplotlib scripts in python/
// (Debian's /usr/bin/python3). A missing interpreter or module costs the
// picture, never the stage: callers warn and go on.
#pragma once

#include <string>
#include <vector>

namespace raysweep::pipeline {

// Runs python/<script> with `args`; true when it exited 0. Output goes to the log.
bool run_python_script(const std::string& script, const std::vector<std::string>& args);

}  // namespace raysweep::pipeline
