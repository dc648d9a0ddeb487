// The extension module lightstage._lightstage; the package lightstage (__init__.py) re-exports it.
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <system_error>

#include "app/cli/register_backends.h"
#include "python/src/bindings.h"
#include "python/src/errors.h"

namespace ls::python {

namespace fs = std::filesystem;

fs::path to_path(const py::handle& object) {
  if (py::hasattr(object, "path") && !py::isinstance<py::str>(object)) {
    return to_path(object.attr("path"));
  }
  return object.cast<fs::path>();
}

fs::path to_optional_path(const py::handle& object) {
  return object.is_none() ? fs::path() : to_path(object);
}

std::vector<fs::path> to_paths(const py::handle& object) {
  if (object.is_none()) return {};
  if (py::isinstance<py::str>(object) || py::hasattr(object, "__fspath__") ||
      py::hasattr(object, "path")) {
    return {to_path(object)};
  }
  std::vector<fs::path> paths;
  for (const py::handle item : object) paths.push_back(to_path(item));
  return paths;
}

std::vector<double> to_numbers(const py::handle& object) {
  if (!py::hasattr(object, "__iter__")) return {object.cast<double>()};  // A number (NumPy's too).
  std::vector<double> numbers;
  for (const py::handle item : object) numbers.push_back(item.cast<double>());
  return numbers;
}

MemoryBudget to_memory(const py::handle& object) {
  if (object.is_none()) return {};
  return MemoryBudget::parse(py::str(object).cast<std::string>(), "--memory");
}

py::object make_result(const char* type, const py::dict& fields) {
  return py::module_::import("lightstage._results").attr(type)(**fields);
}

TempDir::TempDir() {
  std::string pattern = (fs::temp_directory_path() / "lightstage-XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr) {
    throw_storage_error("cannot make a temporary folder in " + fs::temp_directory_path().string(),
                        fs::temp_directory_path().string());
  }
  path_ = pattern;
}

TempDir::~TempDir() {
  std::error_code ignored;
  fs::remove_all(path_, ignored);
}

}  // namespace ls::python

PYBIND11_MODULE(_lightstage, m) {
  m.doc() =
      "lightstage's library: reflectance fields as NumPy arrays and the jobs of the command "
      "line. Import the package lightstage, not this module.";
  // Captures open their devices through the back-end registry: the simulated stage and hardware.
  ls::cli::register_backends();
  ls::python::bind_errors(m);
  ls::python::bind_arrays(m);
  ls::python::bind_field(m);
  ls::python::bind_jobs(m);
  ls::python::bind_more_jobs(m);
}
