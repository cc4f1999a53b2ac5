// Display colours for radio materials, shared by the glTF and Mitsuba writers
// so a scene looks the same in a viewer and in Sionna's preview. They carry no
// electromagnetic meaning.
#pragma once

#include <array>
#include <string_view>

namespace raysweep::meshkit {

// Linear RGB in [0, 1]; a neutral grey for names it does not know.
std::array<double, 3> material_display_color(std::string_view material);

}  // namespace raysweep::meshkit
