// Structure-aware fuzzing of raysweep's HDF5 files. The fuzz input is not the
// file: it is a list of edits applied, through the HDF5 library, to a valid
// file written by raysweep's own writer (the base). The reader under test then
// meets every dataset and attribute with values, sizes, ranks and types it
// did not write, in a file the HDF5 library itself can parse. Raw byte
// mutation of HDF5 files would mostly exercise libhdf5's own parser, whose
// robustness against corrupt files is upstream's business (validate_dataset
// runs its checks in a child process for that reason); raysweep's readers are
// the target here.
//
// Edits (each chosen by the fuzz input): overwrite one element of a dataset
// with raw bytes (or a string for string datasets), set an attribute to raw
// bytes or a string, delete a dataset or attribute, change the extent of a
// chunked dataset, replace a dataset or attribute by one of another type,
// rank and size.
#pragma once

#if __has_include(<hdf5.h>)
#include <hdf5.h>
#else
#include <hdf5/serial/hdf5.h>
#endif

#include <fuzzer/FuzzedDataProvider.h>

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include "fuzz_common.hpp"

namespace raysweep::fuzz {

struct H5Id {
  hid_t id;
  herr_t (*close)(hid_t);
  H5Id(hid_t i, herr_t (*c)(hid_t)) : id(i), close(c) {}
  H5Id(const H5Id&) = delete;
  H5Id& operator=(const H5Id&) = delete;
  ~H5Id() {
    if (id >= 0) close(id);
  }
};

struct H5Objects {
  std::vector<std::string> datasets;                          // full paths
  std::vector<std::pair<std::string, std::string>> attributes;  // (object path, attribute name)
};

inline herr_t collect_attr(hid_t, const char* name, const H5A_info_t*, void* op) {
  auto* out = static_cast<std::pair<H5Objects*, std::string>*>(op);
  out->first->attributes.emplace_back(out->second, name);
  return 0;
}

inline herr_t collect_object(hid_t obj, const char* name, const H5O_info_t* info, void* op) {
  auto* objects = static_cast<H5Objects*>(op);
  const std::string path = std::string(name) == "." ? "/" : "/" + std::string(name);
  if (info->type == H5O_TYPE_DATASET) objects->datasets.push_back(path);
  H5Id o(H5Oopen(obj, name, H5P_DEFAULT), H5Oclose);
  if (o.id >= 0) {
    std::pair<H5Objects*, std::string> ctx{objects, path};
    hsize_t idx = 0;
    H5Aiterate2(o.id, H5_INDEX_NAME, H5_ITER_INC, &idx, collect_attr, &ctx);
  }
  return 0;
}

inline H5Objects list_objects(hid_t file) {
  H5Objects out;
  H5Ovisit(file, H5_INDEX_NAME, H5_ITER_INC, collect_object, &out);
  return out;
}

inline hid_t vlen_string_type() {
  hid_t t = H5Tcopy(H5T_C_S1);
  H5Tset_size(t, H5T_VARIABLE);
  H5Tset_cset(t, H5T_CSET_UTF8);
  return t;
}

// A type for a replacement object: one of the shapes raysweep's files use, or not.
inline hid_t pick_type(FuzzedDataProvider& in) {
  switch (in.ConsumeIntegralInRange(0, 7)) {
    case 0: return H5Tcopy(H5T_NATIVE_UINT8);
    case 1: return H5Tcopy(H5T_NATIVE_INT32);
    case 2: return H5Tcopy(H5T_NATIVE_UINT32);
    case 3: return H5Tcopy(H5T_NATIVE_UINT64);
    case 4: return H5Tcopy(H5T_NATIVE_FLOAT);
    case 5: return H5Tcopy(H5T_NATIVE_DOUBLE);
    case 6: return vlen_string_type();
    default: {
      hid_t t = H5Tcopy(H5T_C_S1);
      H5Tset_size(t, in.ConsumeIntegralInRange<std::size_t>(1, 16));
      return t;
    }
  }
}

// Writes fuzz bytes (or strings) into a whole object of `type` with `n` elements.
inline void write_values(FuzzedDataProvider& in, hid_t type, std::size_t n,
                         const std::function<herr_t(hid_t, const void*)>& write) {
  if (H5Tis_variable_str(type) > 0) {
    std::vector<std::string> s(n);
    std::vector<const char*> p(n);
    for (std::size_t i = 0; i < n; ++i) {
      s[i] = in.ConsumeRandomLengthString(64);
      p[i] = s[i].c_str();
    }
    write(type, p.data());
    return;
  }
  if (H5Tdetect_class(type, H5T_VLEN) > 0) return;  // compounds with vlen members: left alone
  const std::size_t bytes = H5Tget_size(type) * n;
  std::vector<std::uint8_t> buf = in.ConsumeBytes<std::uint8_t>(bytes);
  buf.resize(bytes, 0);
  write(type, buf.data());
}

// Applies the edits of `in` to the open file.
inline void apply_edits(hid_t file, FuzzedDataProvider& in) {
  H5Objects obj = list_objects(file);
  for (int edits = 0; edits < 16 && in.remaining_bytes() > 0; ++edits) {
    const int op = in.ConsumeIntegralInRange(0, 5);
    if (op <= 2 || op == 4) {
      if (obj.datasets.empty()) continue;
      const std::string name = obj.datasets[in.ConsumeIntegralInRange<std::size_t>(0, obj.datasets.size() - 1)];
      H5Id d(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose);
      if (d.id < 0) continue;
      H5Id space(H5Dget_space(d.id), H5Sclose);
      H5Id type(H5Dget_type(d.id), H5Tclose);
      const int rank = H5Sget_simple_extent_ndims(space.id);
      if (rank < 0 || rank > 4) continue;
      std::vector<hsize_t> dims(static_cast<std::size_t>(rank)), maxdims(dims.size());
      H5Sget_simple_extent_dims(space.id, dims.data(), maxdims.data());
      if (op == 0 || op == 1) {  // one element: raw bytes or a string
        hsize_t n = 1;
        for (auto x : dims) n *= x;
        if (n == 0) continue;
        std::vector<hsize_t> start(dims.size()), count(dims.size(), 1);
        for (std::size_t i = 0; i < dims.size(); ++i) start[i] = in.ConsumeIntegralInRange<hsize_t>(0, dims[i] - 1);
        H5Id mem(rank > 0 ? H5Screate_simple(rank, count.data(), nullptr) : H5Screate(H5S_SCALAR), H5Sclose);
        if (rank > 0) H5Sselect_hyperslab(space.id, H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr);
        write_values(in, type.id, 1, [&](hid_t t, const void* buf) {
          return H5Dwrite(d.id, t, rank > 0 ? mem.id : H5S_ALL, rank > 0 ? space.id : H5S_ALL, H5P_DEFAULT, buf);
        });
      } else if (op == 2) {  // new extent (chunked datasets only)
        if (rank == 0) continue;
        std::vector<hsize_t> nd(dims);
        const std::size_t axis = in.ConsumeIntegralInRange<std::size_t>(0, nd.size() - 1);
        nd[axis] = in.ConsumeIntegralInRange<hsize_t>(0, dims[axis] * 2 + 3);
        if (maxdims[axis] != H5S_UNLIMITED && nd[axis] > maxdims[axis]) continue;
        H5Dset_extent(d.id, nd.data());
      } else {  // delete the dataset
        H5Ldelete(file, name.c_str(), H5P_DEFAULT);
        obj.datasets.erase(std::find(obj.datasets.begin(), obj.datasets.end(), name));
      }
    } else if (op == 5) {  // replace a dataset by one of another type / rank / size
      if (obj.datasets.empty()) continue;
      const std::string name = obj.datasets[in.ConsumeIntegralInRange<std::size_t>(0, obj.datasets.size() - 1)];
      if (H5Ldelete(file, name.c_str(), H5P_DEFAULT) < 0) continue;
      H5Id type(pick_type(in), H5Tclose);
      const int rank = in.ConsumeIntegralInRange(0, 2);
      std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
      hsize_t n = 1;
      for (auto& x : dims) n *= (x = in.ConsumeIntegralInRange<hsize_t>(0, 6));
      H5Id space(rank == 0 ? H5Screate(H5S_SCALAR) : H5Screate_simple(rank, dims.data(), nullptr), H5Sclose);
      H5Id d(H5Dcreate2(file, name.c_str(), type.id, space.id, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
      if (d.id >= 0 && n > 0)
        write_values(in, type.id, n, [&](hid_t t, const void* buf) {
          return H5Dwrite(d.id, t, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf);
        });
    } else {  // op 3: an attribute: new value, deleted, or replaced by another type
      if (obj.attributes.empty()) continue;
      const std::size_t i = in.ConsumeIntegralInRange<std::size_t>(0, obj.attributes.size() - 1);
      const auto [owner, name] = obj.attributes[i];
      const int how = in.ConsumeIntegralInRange(0, 2);
      // Through the open object: HDF5 1.10 cannot write an attribute opened
      // by name from the file ("can't locate open attribute?").
      H5Id owner_obj(H5Oopen(file, owner.c_str(), H5P_DEFAULT), H5Oclose);
      if (owner_obj.id < 0) continue;
      if (how == 0) {
        H5Id a(H5Aopen(owner_obj.id, name.c_str(), H5P_DEFAULT), H5Aclose);
        if (a.id < 0) continue;
        H5Id type(H5Aget_type(a.id), H5Tclose);
        H5Id space(H5Aget_space(a.id), H5Sclose);
        const hssize_t n = H5Sget_simple_extent_npoints(space.id);
        if (n <= 0) continue;
        write_values(in, type.id, static_cast<std::size_t>(n),
                     [&](hid_t t, const void* buf) { return H5Awrite(a.id, t, buf); });
        continue;
      }
      H5Adelete(owner_obj.id, name.c_str());
      obj.attributes.erase(obj.attributes.begin() + static_cast<std::ptrdiff_t>(i));
      if (how == 1) continue;
      H5Id type(pick_type(in), H5Tclose);
      const hsize_t n = in.ConsumeIntegralInRange<hsize_t>(0, 3);
      H5Id space(n == 0 ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &n, nullptr), H5Sclose);
      H5Id a(H5Acreate2(owner_obj.id, name.c_str(), type.id, space.id, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
      if (a.id >= 0)
        write_values(in, type.id, n == 0 ? 1 : n, [&](hid_t t, const void* buf) { return H5Awrite(a.id, t, buf); });
      obj.attributes.emplace_back(owner, name);
    }
  }
}

// Copies `base` (bytes of a valid file) to scratch()/name, applies the edits
// of the fuzz input and returns the path.
inline std::string mutated_file(const std::string& name, const std::vector<std::uint8_t>& base,
                                const std::uint8_t* data, std::size_t size) {
  const std::string path = write_input(name, base.data(), base.size());
  FuzzedDataProvider in(data, size);
  H5Id f(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose);
  if (f.id < 0) finding("cannot reopen the base file " + path);
  apply_edits(f.id, in);
  return path;
}

inline std::vector<std::uint8_t> read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), {});
}

// The bytes of a base file written by `write` (h5_bases.hpp).
template <class F>
std::vector<std::uint8_t> base_bytes(const std::string& name, F&& write) {
  const std::string path = (scratch() / name).string();
  write(path);
  return read_all(path);
}

// Silences HDF5's error stack printing (every refused edit would print one).
inline void quiet_hdf5() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }

}  // namespace raysweep::fuzz
