#include "python/src/errors.h"

#include <exception>
#include <filesystem>
#include <string>

#include "lightstage/errors.h"

namespace ls::python {

namespace {

// Sets the Python error `name` of lightstage._errors, made from `args`.
template <typename... Args>
void set_error(const char* name, Args&&... args) {
  const py::object cls = py::module_::import("lightstage._errors").attr(name);
  const py::object error = cls(std::forward<Args>(args)...);
  PyErr_SetObject(cls.ptr(), error.ptr());
}

}  // namespace

void throw_storage_error(const std::string& message, const std::string& file) {
  set_error("StorageError", message, py::arg("file") = file);
  throw py::error_already_set();
}

void bind_errors(py::module_& /*m*/) {
  // pybind11's translator type takes the exception_ptr by value.
  // NOLINTNEXTLINE(performance-unnecessary-value-param)
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const StorageError& e) {
      // An output that cannot be written: the message names the path first.
      set_error("StorageError", e.what());
    } catch (const InputError& e) {
      set_error("InputError", e.what());
    } catch (const HardwareError& e) {
      set_error("HardwareError", e.what());
    } catch (const std::filesystem::filesystem_error& e) {
      // Storage: a path that cannot be created, written or read (disk full, permissions).
      set_error("StorageError", e.what(), py::arg("file") = e.path1().string(),
                py::arg("errno") = e.code().value());
    }
  });
}

}  // namespace ls::python
