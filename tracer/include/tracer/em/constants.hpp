// The physical constants and the complex type of the electromagnetics
// headers (tracer/em/).
#pragma once

#include <complex>

namespace raysweep::tracer {

using cdouble = std::complex<double>;

constexpr double kSpeedOfLight = 299792458.0;    // m/s
constexpr double kVacuumPermittivity = 8.8541878128e-12;  // F/m
constexpr double kPi = 3.14159265358979323846;

}  // namespace raysweep::tracer
