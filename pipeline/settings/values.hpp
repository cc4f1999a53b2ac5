// Value types the schema tables share (tables*.cpp): paths relative to the
// file, material names, Draco bits, boxes; and FIELD, the binding of a key to
// a member of the settings struct.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "pipeline/settings/schema.hpp"

// A field of the bound struct, for reading (Cfg&) and writing (const Cfg&) alike.
#define FIELD(member) [](auto& c) -> auto& { return c.member; }

namespace raysweep::pipeline::schema {

std::string joined(const std::vector<std::string>& names);
// A name out of `names`, or an error saying which names there are.
std::string unknown(const std::string& what, const std::string& s, const std::vector<std::string>& names);
// A path, relative to the config file's folder unless absolute.
Value<std::string> path();
Value<std::string> itu_material();
std::vector<std::string> radio_material_names();
// P.2040 or custom (plastic, rubber, ...): what vehicle parts may be made of.
Value<std::string> radio_material();
// 0 keeps positions exact; below 8 bits Draco's grid is coarser than a wavelength.
Value<int> draco_bits();

template <class Box>
Value<Box> box(Value<Box> v) {
  return checked(std::move(v), std::function<bool(const Box&)>([](const Box& b) { return b[0] < b[2] && b[1] < b[3]; }),
                 "[xmin, ymin, xmax, ymax] with xmin < xmax and ymin < ymax", "xmin < xmax, ymin < ymax");
}

}  // namespace raysweep::pipeline::schema
