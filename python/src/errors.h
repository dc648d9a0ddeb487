#pragma once
// The library's errors as Python exceptions (lightstage/_errors.py): InputError (a ValueError),
// StorageError (an OSError), HardwareError (a RuntimeError), each with the message and the file
// and field it names.
#include <pybind11/pybind11.h>

#include <string>

namespace ls::python {

namespace py = pybind11;

void bind_errors(py::module_& m);

// Raises lightstage.StorageError from C++ (the error is set; throws error_already_set).
[[noreturn]] void throw_storage_error(const std::string& message, const std::string& file);

}  // namespace ls::python
