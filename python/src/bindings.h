#pragma once
// The pieces of the extension module lightstage._lightstage, one file per concept, and what the
// jobs' bindings share.
#include <pybind11/pybind11.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "lightstage/memory.h"

namespace ls::python {

namespace py = pybind11;

void bind_arrays(py::module_& m);
void bind_field(py::module_& m);
void bind_jobs(py::module_& m);       // build, relight, fit
void bind_more_jobs(py::module_& m);  // capture, compress, render, import_set, normals

// A path from a str, an os.PathLike or a lightstage.Field (its file).
std::filesystem::path to_path(const py::handle& object);
// None: an empty path.
std::filesystem::path to_optional_path(const py::handle& object);
// One path or a sequence of them.
std::vector<std::filesystem::path> to_paths(const py::handle& object);
// One number or a sequence of them.
std::vector<double> to_numbers(const py::handle& object);
// None: unset; a size as --memory takes it ("512M", "2GiB") or a number of bytes; refused with
// the CLI's messages.
MemoryBudget to_memory(const py::handle& object);

// A result type of lightstage/_results.py made from keywords.
py::object make_result(const char* type, const py::dict& fields);

// A folder of its own under the temporary directory, removed (with what is in it) when destroyed:
// where a job writes when the caller wants arrays, not files.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace ls::python
