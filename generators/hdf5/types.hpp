// The element types of the schemas (their `dtype`), as HDF5 memory and file
// types, and HDF5 types described in words, for the writing and the reading
// side of the HDF5 layer.
#pragma once

#include <hdf5.h>

#include <complex>
#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>

#include "generators/hdf5/handle.hpp"

namespace raysweep::generators::hdf5 {

enum class Dtype { u8, u16, u32, u64, f32, f64, c64, str };
Dtype parse_dtype(const std::string& s);  // schema dtype name; std::logic_error when unknown
std::size_t dtype_bytes(Dtype t);         // bytes of one element in memory

// Memory and file types. Predefined types are not owned; the compound and string
// types are created once per file.
class Types {
 public:
  explicit Types(const std::string& file);
  hid_t mem(Dtype t) const;
  hid_t file(Dtype t) const;
  hid_t str() const { return str_.get(); }

 private:
  Handle c64_mem_, c64_file_, str_;
};

// The Dtype of a C++ element type: complex<float> for c64, char* (one
// variable-length string) for str.
template <class T>
constexpr Dtype dtype_of() {
  if constexpr (std::is_same_v<T, std::uint8_t>) return Dtype::u8;
  else if constexpr (std::is_same_v<T, std::uint16_t>) return Dtype::u16;
  else if constexpr (std::is_same_v<T, std::uint32_t>) return Dtype::u32;
  else if constexpr (std::is_same_v<T, std::uint64_t>) return Dtype::u64;
  else if constexpr (std::is_same_v<T, float>) return Dtype::f32;
  else if constexpr (std::is_same_v<T, double>) return Dtype::f64;
  else if constexpr (std::is_same_v<T, std::complex<float>>) return Dtype::c64;
  else if constexpr (std::is_same_v<T, char*>) return Dtype::str;
  else static_assert(sizeof(T) == 0, "no HDF5 type for T");
}

// "" when the HDF5 type matches the schema dtype, else a description of the type.
std::string type_mismatch(hid_t type, const std::string& dtype);
// "unsigned 8-bit integer", "64-bit float", "variable-length string", ...
std::string describe_type(hid_t type);

}  // namespace raysweep::generators::hdf5
