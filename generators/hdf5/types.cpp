// Schema element types as HDF5 types, and HDF5 types in words (see types.hpp).
#include "generators/hdf5/types.hpp"

#include <cctype>
#include <stdexcept>
#include <unordered_map>

namespace raysweep::generators::hdf5 {

Dtype parse_dtype(const std::string& s) {
  static const std::unordered_map<std::string, Dtype> m = {{"u8", Dtype::u8},   {"u16", Dtype::u16},
                                                           {"u32", Dtype::u32}, {"u64", Dtype::u64},
                                                           {"f32", Dtype::f32}, {"f64", Dtype::f64},
                                                           {"c64", Dtype::c64}, {"str", Dtype::str}};
  auto it = m.find(s);
  if (it == m.end()) throw std::logic_error("schema: unknown dtype " + s);
  return it->second;
}

std::size_t dtype_bytes(Dtype t) {
  switch (t) {
    case Dtype::u8: return 1;
    case Dtype::u16: return 2;
    case Dtype::u32: return 4;
    case Dtype::u64: return 8;
    case Dtype::f32: return 4;
    case Dtype::f64: return 8;
    case Dtype::c64: return 8;
    case Dtype::str: return sizeof(const char*);
  }
  return 0;
}

Types::Types(const std::string& file) {
  c64_mem_ = Handle(H5Tcreate(H5T_COMPOUND, 2 * sizeof(float)), H5Tclose);
  if (c64_mem_.get() < 0 || H5Tinsert(c64_mem_.get(), "r", 0, H5T_NATIVE_FLOAT) < 0 ||
      H5Tinsert(c64_mem_.get(), "i", sizeof(float), H5T_NATIVE_FLOAT) < 0)
    write_fail(file, "complex memory type", "cannot create");
  c64_file_ = Handle(H5Tcreate(H5T_COMPOUND, 8), H5Tclose);
  if (c64_file_.get() < 0 || H5Tinsert(c64_file_.get(), "r", 0, H5T_IEEE_F32LE) < 0 ||
      H5Tinsert(c64_file_.get(), "i", 4, H5T_IEEE_F32LE) < 0)
    write_fail(file, "complex file type", "cannot create");
  str_ = Handle(H5Tcopy(H5T_C_S1), H5Tclose);
  if (str_.get() < 0 || H5Tset_size(str_.get(), H5T_VARIABLE) < 0 || H5Tset_cset(str_.get(), H5T_CSET_UTF8) < 0)
    write_fail(file, "string type", "cannot create");
}

hid_t Types::mem(Dtype t) const {
  switch (t) {
    case Dtype::u8: return H5T_NATIVE_UINT8;
    case Dtype::u16: return H5T_NATIVE_UINT16;
    case Dtype::u32: return H5T_NATIVE_UINT32;
    case Dtype::u64: return H5T_NATIVE_UINT64;
    case Dtype::f32: return H5T_NATIVE_FLOAT;
    case Dtype::f64: return H5T_NATIVE_DOUBLE;
    case Dtype::c64: return c64_mem_.get();
    case Dtype::str: return str_.get();
  }
  return H5I_INVALID_HID;
}

hid_t Types::file(Dtype t) const {
  switch (t) {
    case Dtype::u8: return H5T_STD_U8LE;
    case Dtype::u16: return H5T_STD_U16LE;
    case Dtype::u32: return H5T_STD_U32LE;
    case Dtype::u64: return H5T_STD_U64LE;
    case Dtype::f32: return H5T_IEEE_F32LE;
    case Dtype::f64: return H5T_IEEE_F64LE;
    case Dtype::c64: return c64_file_.get();
    case Dtype::str: return str_.get();
  }
  return H5I_INVALID_HID;
}

std::string describe_type(hid_t type) {
  const H5T_class_t cls = H5Tget_class(type);
  const std::size_t size = H5Tget_size(type);
  switch (cls) {
    case H5T_INTEGER:
      return (H5Tget_sign(type) == H5T_SGN_NONE ? "unsigned " : "signed ") + std::to_string(8 * size) + "-bit integer";
    case H5T_FLOAT: return std::to_string(8 * size) + "-bit float";
    case H5T_STRING:
      return H5Tis_variable_str(type) > 0 ? "variable-length string" : std::to_string(size) + "-byte fixed string";
    case H5T_COMPOUND: return "compound of " + std::to_string(H5Tget_nmembers(type)) + " members";
    default: return "type class " + std::to_string(static_cast<int>(cls));
  }
}

std::string type_mismatch(hid_t type, const std::string& dtype) {
  const H5T_class_t cls = H5Tget_class(type);
  const std::size_t size = H5Tget_size(type);
  bool ok = false;
  if (dtype.size() >= 2 && dtype[0] == 'u' && std::isdigit(static_cast<unsigned char>(dtype[1]))) {
    ok = cls == H5T_INTEGER && H5Tget_sign(type) == H5T_SGN_NONE && 8 * size == std::stoul(dtype.substr(1));
  } else if (dtype == "f32" || dtype == "f64") {
    ok = cls == H5T_FLOAT && 8 * size == std::stoul(dtype.substr(1));
  } else if (dtype == "str") {
    ok = cls == H5T_STRING && H5Tis_variable_str(type) > 0;
  } else if (dtype == "c64") {
    ok = cls == H5T_COMPOUND && size == 8 && H5Tget_nmembers(type) == 2;
    for (unsigned m = 0; ok && m < 2; ++m) {
      char* name = H5Tget_member_name(type, m);
      const std::string expect = m == 0 ? "r" : "i";
      ok = name && expect == name && H5Tget_member_offset(type, m) == 4 * m;
      if (name) H5free_memory(name);
      Handle mt(H5Tget_member_type(type, m), H5Tclose);
      ok = ok && mt.valid() && H5Tget_class(mt.get()) == H5T_FLOAT && H5Tget_size(mt.get()) == 4;
    }
    if (cls == H5T_COMPOUND && !ok) return "compound other than {r: f32, i: f32}";
  }
  return ok ? std::string() : describe_type(type);
}

}  // namespace raysweep::generators::hdf5
