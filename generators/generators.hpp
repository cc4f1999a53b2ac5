// generators: turn traced frames into datasets. Filled by the sweep and SINR issues.
#pragma once
#include "tracer/tracer.hpp"
