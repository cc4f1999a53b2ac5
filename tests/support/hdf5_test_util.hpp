// HDF5 C API helpers shared by the tests: reading back and corrupting files.
#pragma once

#include <gtest/gtest.h>

#if __has_include(<hdf5.h>)
#include <hdf5.h>
#else
#include <hdf5/serial/hdf5.h>  // Debian's serial HDF5 (the test target has no HDF5 include path)
#endif

#include <complex>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "test_util.hpp"

namespace raysweep::test {

// Owns an HDF5 id and closes it with `close` (ids < 0 are left alone).
struct H5 {
  hid_t id;
  herr_t (*close)(hid_t);
  ~H5() {
    if (id >= 0) close(id);
  }
};

// Reads a whole dataset as `memtype`; its dimensions go to `dims_out` when given.
template <class T>
std::vector<T> read_ds(const fs::path& file, const std::string& name, hid_t memtype,
                       std::vector<hsize_t>* dims_out = nullptr) {
  H5 f{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  EXPECT_GE(f.id, 0) << file;
  H5 d{H5Dopen2(f.id, name.c_str(), H5P_DEFAULT), H5Dclose};
  EXPECT_GE(d.id, 0) << name;
  H5 s{H5Dget_space(d.id), H5Sclose};
  std::vector<hsize_t> dims(static_cast<std::size_t>(H5Sget_simple_extent_ndims(s.id)));
  H5Sget_simple_extent_dims(s.id, dims.data(), nullptr);
  hsize_t n = 1;
  for (auto x : dims) n *= x;
  std::vector<T> out(n);
  if (n) {
    EXPECT_GE(H5Dread(d.id, memtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()), 0) << name;
  }
  if (dims_out) *dims_out = dims;
  return out;
}

// Reads a dataset of {r, i} float compounds.
inline std::vector<std::complex<float>> read_complex(const fs::path& file, const std::string& name,
                                                     std::vector<hsize_t>* dims = nullptr) {
  H5 t{H5Tcreate(H5T_COMPOUND, sizeof(std::complex<float>)), H5Tclose};
  H5Tinsert(t.id, "r", 0, H5T_NATIVE_FLOAT);
  H5Tinsert(t.id, "i", sizeof(float), H5T_NATIVE_FLOAT);
  return read_ds<std::complex<float>>(file, name, t.id, dims);
}

// Reads a dataset of variable-length UTF-8 strings.
inline std::vector<std::string> read_strings(const fs::path& file, const std::string& name) {
  H5 t{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(t.id, H5T_VARIABLE);
  H5Tset_cset(t.id, H5T_CSET_UTF8);
  auto ptrs = read_ds<char*>(file, name, t.id);
  std::vector<std::string> out;
  for (char* p : ptrs) {
    out.emplace_back(p ? p : "");
    H5free_memory(p);
  }
  return out;
}

// String attribute `name` of object `obj` ("/" for the root group).
inline std::string str_attr(const fs::path& file, const std::string& obj, const std::string& name) {
  H5 f{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  H5 a{H5Aopen_by_name(f.id, obj.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose};
  EXPECT_GE(a.id, 0) << obj << " " << name;
  H5 t{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(t.id, H5T_VARIABLE);
  H5Tset_cset(t.id, H5T_CSET_UTF8);
  char* p = nullptr;
  EXPECT_GE(H5Aread(a.id, t.id, &p), 0);
  std::string s = p ? p : "";
  H5free_memory(p);
  return s;
}

// String attribute `name` of the root group.
inline std::string str_attr(const fs::path& file, const std::string& name) { return str_attr(file, "/", name); }

// Numeric attribute `name` of object `obj` ("/" for the root group), read as `memtype`.
template <class T>
T num_attr(const fs::path& file, const std::string& obj, const std::string& name, hid_t memtype) {
  H5 f{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  H5 a{H5Aopen_by_name(f.id, obj.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose};
  EXPECT_GE(a.id, 0) << obj << " " << name;
  T v{};
  EXPECT_GE(H5Aread(a.id, memtype, &v), 0);
  return v;
}

// Numeric attribute `name` of the root group, read as `memtype`.
template <class T>
T num_attr(const fs::path& file, const std::string& name, hid_t memtype) {
  return num_attr<T>(file, "/", name, memtype);
}

// Whether the root group has attribute `name`.
inline bool has_attr(const fs::path& file, const std::string& name) {
  H5 f{H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose};
  return H5Aexists(f.id, name.c_str()) > 0;
}

// Overwrites element `row` of a dataset with a value of the given memory type.
template <class T>
void poke(const fs::path& file, const std::string& name, hsize_t row, T value, hid_t memtype) {
  H5 f{H5Fopen(file.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
  ASSERT_GE(f.id, 0);
  H5 d{H5Dopen2(f.id, name.c_str(), H5P_DEFAULT), H5Dclose};
  ASSERT_GE(d.id, 0);
  H5 fs_{H5Dget_space(d.id), H5Sclose};
  const hsize_t count = 1;
  ASSERT_GE(H5Sselect_hyperslab(fs_.id, H5S_SELECT_SET, &row, nullptr, &count, nullptr), 0);
  H5 ms{H5Screate_simple(1, &count, nullptr), H5Sclose};
  ASSERT_GE(H5Dwrite(d.id, memtype, ms.id, fs_.id, H5P_DEFAULT, &value), 0);
}
inline void poke_u64(const fs::path& file, const std::string& name, hsize_t row, std::uint64_t v) {
  poke(file, name, row, v, H5T_NATIVE_UINT64);
}
inline void poke_f64(const fs::path& file, const std::string& name, hsize_t row, double v) {
  poke(file, name, row, v, H5T_NATIVE_DOUBLE);
}

// Replaces the root group's attribute `name` with a variable-length UTF-8 string.
inline void set_str_attr(const fs::path& file, const std::string& name, const std::string& value) {
  H5 f{H5Fopen(file.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose};
  ASSERT_GE(f.id, 0);
  ASSERT_GE(H5Adelete(f.id, name.c_str()), 0);
  H5 t{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(t.id, H5T_VARIABLE);
  H5Tset_cset(t.id, H5T_CSET_UTF8);
  H5 s{H5Screate(H5S_SCALAR), H5Sclose};
  H5 a{H5Acreate2(f.id, name.c_str(), t.id, s.id, H5P_DEFAULT, H5P_DEFAULT), H5Aclose};
  ASSERT_GE(a.id, 0);
  const char* p = value.c_str();
  ASSERT_GE(H5Awrite(a.id, t.id, &p), 0);
}

// The whole file as bytes.
inline std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace raysweep::test
