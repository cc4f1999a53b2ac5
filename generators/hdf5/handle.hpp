// HDF5 plumbing shared by the writing (column_file.hpp) and the reading
// (checked_file.hpp) side of the HDF5 layer: owned handles, the error stack
// as text, a scope that keeps HDF5 from printing errors itself.
#pragma once

#include <hdf5.h>

#include <stdexcept>
#include <string>

namespace raysweep::generators::hdf5 {

using Closer = herr_t (*)(hid_t);

class Handle {
 public:
  Handle() = default;
  Handle(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  Handle(Handle&& o) noexcept : id_(o.id_), closer_(o.closer_) { o.id_ = H5I_INVALID_HID; }
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = o.id_;
      closer_ = o.closer_;
      o.id_ = H5I_INVALID_HID;
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { reset(); }
  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  void reset() noexcept {
    if (id_ >= 0 && closer_) closer_(id_);
    id_ = H5I_INVALID_HID;
  }
  // Closes and reports failure (a failed close of a dataset or file can lose data).
  herr_t close() noexcept {
    herr_t r = 0;
    if (id_ >= 0 && closer_) r = closer_(id_);
    id_ = H5I_INVALID_HID;
    return r;
  }

 private:
  hid_t id_ = H5I_INVALID_HID;
  Closer closer_ = nullptr;
};

// The most specific message on HDF5's error stack ("" when empty); clears the stack.
inline std::string hdf5_error_text() {
  std::string text;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_UPWARD,
      [](unsigned n, const H5E_error2_t* err, void* data) -> herr_t {
        auto* s = static_cast<std::string*>(data);
        if (n < 2 && err && err->desc && *err->desc) {
          if (!s->empty()) *s += "; ";
          *s += err->desc;
        }
        return 0;
      },
      &text);
  H5Eclear2(H5E_DEFAULT);
  return text;
}

// Drops what HDF5 left on its error stack.
inline void clear_errors() { H5Eclear2(H5E_DEFAULT); }

// Throws std::runtime_error "HDF5 <file>: <object>: <what> (<HDF5 error>)".
[[noreturn]] inline void write_fail(const std::string& file, const std::string& object, const std::string& what) {
  std::string msg = "HDF5 " + file + ": " + object + ": " + what;
  const std::string h5 = hdf5_error_text();
  if (!h5.empty()) msg += " (" + h5 + ")";
  throw std::runtime_error(msg);
}

// Silences HDF5's automatic error printing for the scope (errors become exceptions).
class QuietHdf5 {
 public:
  QuietHdf5() {
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~QuietHdf5() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }
  QuietHdf5(const QuietHdf5&) = delete;
  QuietHdf5& operator=(const QuietHdf5&) = delete;

 private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

}  // namespace raysweep::generators::hdf5
