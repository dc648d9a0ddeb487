#pragma once
// NumPy arrays over the library's memory, without copying: a Buffer keeps the library object that
// owns the floats alive and exports them through the buffer protocol; every array made here has
// that Buffer as its base, so the memory lives as long as any array (or view of one) does.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <string>
#include <vector>

#include "lightstage/image.h"

namespace ls::python {

namespace py = pybind11;

struct Buffer {
  std::shared_ptr<const void> owner;  // The library object the floats belong to.
  float* data = nullptr;
  std::vector<py::ssize_t> shape, strides;  // Strides in bytes.
  bool writable = true;
  std::string what;  // What the memory is ("field values", "model maps"), for repr.
};

void bind_arrays(py::module_& m);

// An array over `buffer` (its base is the Buffer object); read-only unless buffer.writable.
py::array view(Buffer buffer);

// An image (H x W x C, or H x W for one channel) over the image `owner` holds.
py::array image_view(const std::shared_ptr<Image>& image, const std::string& what);

// Channels [first, first + count) of an interleaved image as an H x W x count array (H x W for
// one channel), viewing the image's memory.
py::array channel_view(const std::shared_ptr<Image>& image, int first, int count,
                       const std::string& what);

// Every channel of an image with named channels (its channel_names, in the image's order): a group
// NAME.x/y/z or NAME.r/g/b as H x W x 3, any other channel as H x W under its name with '.' as
// '_', each viewing the image's memory.
py::dict named_views(const std::shared_ptr<Image>& image, const std::string& what);

}  // namespace ls::python
