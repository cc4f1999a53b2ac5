#include "tracer/tracer.hpp"

#include <embree3/rtcore.h>

namespace raysweep::tracer {
std::string embree_version() {
  RTCDevice device = rtcNewDevice(nullptr);
  const long v = rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION);
  rtcReleaseDevice(device);
  return std::to_string(v / 10000) + "." + std::to_string((v / 100) % 100) + "." + std::to_string(v % 100);
}
}  // namespace raysweep::tracer
