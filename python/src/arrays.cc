#include "python/src/arrays.h"

#include <utility>

namespace ls::python {

void bind_arrays(py::module_& m) {
  py::class_<Buffer, std::shared_ptr<Buffer>>(
      m, "Buffer", py::buffer_protocol(),
      "Memory of the library (a field's values, an image, model maps) that NumPy arrays view "
      "without copying: the base of those arrays.")
      .def_buffer([](Buffer& b) {
        return py::buffer_info(b.data, sizeof(float), py::format_descriptor<float>::format(),
                               py::ssize_t(b.shape.size()), b.shape, b.strides, !b.writable);
      })
      .def_property_readonly(
          "writable", [](const Buffer& b) { return b.writable; },
          "Whether arrays over it may be written (writes are seen by the library).")
      .def_property_readonly(
          "what", [](const Buffer& b) { return b.what; }, "What the memory holds.")
      .def("__repr__", [](const Buffer& b) {
        return "<lightstage.Buffer of " + b.what + (b.writable ? "" : ", read-only") + ">";
      });
}

py::array view(Buffer buffer) {
  auto shared = std::make_shared<Buffer>(std::move(buffer));
  const py::object base = py::cast(shared);
  py::array array(py::dtype::of<float>(), shared->shape, shared->strides, shared->data, base);
  if (!shared->writable) {
    py::detail::array_proxy(array.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  }
  return array;
}

py::array channel_view(const std::shared_ptr<Image>& image, int first, int count,
                       const std::string& what) {
  Buffer b;
  b.owner = image;
  // The library owns the image; arrays may write into it (a caller that must not see writes
  // keeps its own copy).
  b.data = image->pixels.data() + first;
  const py::ssize_t f = sizeof(float);
  b.shape = {image->height, image->width};
  b.strides = {py::ssize_t(image->width) * image->channels * f, py::ssize_t(image->channels) * f};
  if (count > 1) {
    b.shape.push_back(count);
    b.strides.push_back(f);
  }
  b.what = what;
  return view(std::move(b));
}

py::array image_view(const std::shared_ptr<Image>& image, const std::string& what) {
  const int channels = image->channels;
  return channel_view(image, 0, channels, what);
}

py::dict named_views(const std::shared_ptr<Image>& image, const std::string& what) {
  const std::vector<std::string>& names = image->channel_names;
  const auto in_group = [&](size_t c, const std::string& stem) {
    return c < names.size() && names[c].rfind(stem + ".", 0) == 0;
  };
  py::dict arrays;
  for (size_t c = 0; c < names.size();) {
    const std::string& name = names[c];
    const size_t dot = name.find('.');
    const std::string stem = name.substr(0, dot);
    const std::string tail = dot == std::string::npos ? "" : name.substr(dot + 1);
    if ((tail == "x" || tail == "r") && in_group(c + 1, stem) && in_group(c + 2, stem)) {
      arrays[py::str(stem)] = channel_view(image, int(c), 3, what + ": " + stem);
      c += 3;
      continue;
    }
    std::string key = name;
    for (char& ch : key) ch = ch == '.' ? '_' : ch;
    arrays[py::str(key)] = channel_view(image, int(c), 1, what + ": " + name);
    ++c;
  }
  return arrays;
}

}  // namespace ls::python
