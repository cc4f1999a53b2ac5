// PNG previews of stage outputs, drawn by the matplotlib scripts in python/
// (Debian's /usr/bin/python3). A missing interpreter or module costs the
// picture, never the stage: callers warn and go on.
#pragma once

#include <string>
#include <vector>

namespace raysweep::pipeline {

// Runs python/<script> with `args`; true when it exited 0. Output goes to the log.
bool run_python_script(const std::string& script, const std::vector<std::string>& args);

// Runs `python3 -m module args` with python/ on PYTHONPATH and the output
// shown; its exit status (127 when the interpreter cannot start).
int run_python_module(const std::string& module, const std::vector<std::string>& args);

}  // namespace raysweep::pipeline
