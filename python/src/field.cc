// lightstage.Field: a reflectance field file, its header (lights, noise, shape) and its values as
// NumPy arrays, read a band of rows at a time or whole.
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "capture/field_file.h"
#include "lightstage/errors.h"
#include "python/src/arrays.h"
#include "python/src/bindings.h"

namespace ls::python {

namespace {

namespace fs = std::filesystem;

// A field file opened for reading (its header read, no values), and the whole field once load()ed.
class Field {
 public:
  explicit Field(const fs::path& path)
      : path_(path), stream_(std::make_unique<capture::FieldStream>(path)) {}

  const fs::path& path() const { return path_; }
  const capture::ReflectanceField& header() const { return stream_->header(); }
  const capture::FieldStorage& storage() const { return stream_->storage(); }

  // Rows [y0, y1), read from the file into a new buffer of the library's (H x W x L x 3).
  py::array rows(int y0, int y1) {
    check_rows(y0, y1);
    auto band = std::make_shared<capture::ReflectanceField>();
    {
      py::gil_scoped_release release;
      const std::lock_guard lock(mutex_);  // One read at a time through the file's reader.
      stream_->read_rows(y0, y1, *band);
    }
    return values_view(band, "a copy of rows " + std::to_string(y0) + ".." + std::to_string(y1) +
                                 " of " + path_.string() + ", read from it");
  }

  // The whole field in memory (read once); the arrays view it and writes reach save().
  py::array values() {
    {
      py::gil_scoped_release release;
      const std::lock_guard lock(mutex_);
      if (!loaded_)
        loaded_ = std::make_shared<capture::ReflectanceField>(capture::read_field(path_));
    }
    return values_view(loaded_, "the values of " + path_.string());
  }

  // Writes the field (as load()ed and since changed through its arrays) to `out`.
  void save(const fs::path& out, const std::string& storage) {
    values();
    const capture::StorageChoice choice = capture::parse_storage_choice("storage", storage);
    py::gil_scoped_release release;
    const std::lock_guard lock(mutex_);
    capture::write_field(out, *loaded_, {}, /*tile_size=*/0,
                         capture::choose_storage(*loaded_, choice));
  }

  // Rows [y0, y1) as a field file of their own (a tile of work for another process).
  void save_rows(const fs::path& out, int y0, int y1, const std::string& storage) {
    const capture::StorageChoice choice = capture::parse_storage_choice("storage", storage);
    check_rows(y0, y1);
    if (capture::has_near_lights(header())) {
      throw InputError(path_.string() + ": save_rows: the field has near LEDs, whose directions " +
                       "depend on a pixel's place in the whole frame: it cannot be cut into bands");
    }
    py::gil_scoped_release release;
    capture::ReflectanceField band;
    {
      const std::lock_guard lock(mutex_);
      stream_->read_rows(y0, y1, band);
    }
    band.set_band(0, 0);
    capture::write_field(out, band, {}, /*tile_size=*/0, capture::choose_storage(band, choice));
  }

 private:
  void check_rows(int y0, int y1) const {
    const int height = header().height();
    if (!(0 <= y0 && y0 < y1 && y1 <= height)) {
      throw InputError(path_.string() +
                       ": rows: expected 0 <= y0 < y1 <= " + std::to_string(height) + ", got " +
                       std::to_string(y0) + ", " + std::to_string(y1));
    }
  }

  static py::array values_view(const std::shared_ptr<capture::ReflectanceField>& field,
                               const std::string& what) {
    Buffer b;
    b.owner = field;
    b.data = field->num_lights() > 0 && field->width() > 0 && field->height() > 0
                 ? field->pixel(0, 0)
                 : nullptr;
    const py::ssize_t f = sizeof(float), lights = field->num_lights();
    b.shape = {field->height(), field->width(), lights, 3};
    b.strides = {field->width() * lights * 3 * f, lights * 3 * f, 3 * f, f};
    b.what = what;
    return view(std::move(b));
  }

  fs::path path_;
  std::unique_ptr<capture::FieldStream> stream_;
  std::shared_ptr<capture::ReflectanceField> loaded_;
  std::mutex mutex_;
};

constexpr const char* kColoursDoc =
    "Each light's RGB colour in field units (L x 3): ones, since a field is stored per unit of "
    "each LED's calibrated irradiance and colour (build divides by them; an imported set is taken "
    "as white lights).";

// A field's lights as arrays (small: copied).
struct Lights {
  std::vector<capture::FieldLight> lights;
};

py::array_t<double> vectors(const std::vector<capture::FieldLight>& lights, bool positions) {
  py::array_t<double> out({py::ssize_t(lights.size()), py::ssize_t(3)});
  auto a = out.mutable_unchecked<2>();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (size_t l = 0; l < lights.size(); ++l) {
    const auto& light = lights[l];
    for (int k = 0; k < 3; ++k) {
      if (positions) {
        a(l, k) = light.position_in_stage ? (*light.position_in_stage)[k] : nan;
      } else {
        a(l, k) = light.dir_in_stage[k];
      }
    }
  }
  return out;
}

void bind_lights(py::module_& m) {
  py::class_<Lights>(m, "Lights",
                     "A field's lights, as arrays (copies: a few values per light), in the order "
                     "of the field's light axis.")
      .def("__len__", [](const Lights& l) { return l.lights.size(); })
      .def_property_readonly(
          "ids",
          [](const Lights& l) {
            std::vector<int> ids;
            for (const auto& light : l.lights) ids.push_back(light.led_id);
            return py::array_t<int>(py::ssize_t(ids.size()), ids.data());
          },
          "LED ids (L,).")
      .def_property_readonly(
          "directions", [](const Lights& l) { return vectors(l.lights, /*positions=*/false); },
          "Unit directions toward each LED, stage frame (+Y up, camera on +Z) (L x 3).")
      .def_property_readonly(
          "positions", [](const Lights& l) { return vectors(l.lights, /*positions=*/true); },
          "Near LEDs: positions in metres, stage frame; NaN rows for distant LEDs (L x 3).")
      .def_property_readonly(
          "valid",
          [](const Lights& l) {
            py::array_t<bool> out(py::ssize_t(l.lights.size()));
            for (size_t i = 0; i < l.lights.size(); ++i) out.mutable_at(i) = l.lights[i].valid;
            return out;
          },
          "False for an LED found dead or missing: its samples are zero, not data (L,).")
      .def_property_readonly(
          "saturates_at",
          [](const Lights& l) {
            py::array_t<float> out({py::ssize_t(l.lights.size()), py::ssize_t(3)});
            for (size_t i = 0; i < l.lights.size(); ++i) {
              for (int c = 0; c < 3; ++c) out.mutable_at(i, c) = l.lights[i].saturates_at[c];
            }
            return out;
          },
          "Per LED and colour, the value of a sample clipped in every exposure (inf: never) "
          "(L x 3).")
      .def_property_readonly(
          "colours",
          [](const Lights& l) {
            // Values are per unit of each LED's irradiance and colour (build divides by the
            // calibration; an import has none to divide by): every light is white in field units.
            py::array_t<double> out({py::ssize_t(l.lights.size()), py::ssize_t(3)});
            std::fill_n(out.mutable_data(), out.size(), 1.0);
            return out;
          },
          kColoursDoc);
}

void bind_noise(py::module_& m) {
  py::class_<capture::FieldNoise>(m, "FieldNoise",
                                  "Measurement noise of a field's values: variance(v) = "
                                  "read_variance + shot_variance_per_unit * max(v, 0).")
      .def_readonly("read_variance", &capture::FieldNoise::read_variance)
      .def_readonly("shot_variance_per_unit", &capture::FieldNoise::shot_variance_per_unit)
      .def_readonly("measured", &capture::FieldNoise::measured,
                    "False when nobody estimated it (imports, older files).")
      .def_readonly("method", &capture::FieldNoise::method, "How it was estimated.")
      .def("__repr__", [](const capture::FieldNoise& n) {
        return "FieldNoise(read_variance=" + std::to_string(n.read_variance) +
               ", shot_variance_per_unit=" + std::to_string(n.shot_variance_per_unit) +
               ", measured=" + (n.measured ? "True" : "False") + ")";
      });
}

}  // namespace

void bind_field(py::module_& m) {
  bind_lights(m);
  bind_noise(m);
  m.def(
      "read_image",
      [](const fs::path& path) {
        auto image = std::make_shared<Image>();
        {
          py::gil_scoped_release release;
          *image = read_image(path);
        }
        const std::vector<std::string> names = image->channel_names;
        return py::make_tuple(channel_view(image, 0, image->channels, path.string()), names);
      },
      py::arg("path"),
      "An image file as lightstage reads it (EXR, HDR, PNG, JPEG; linear float32): (H x W x C "
      "array over the library's image, the channel names in its order).");
  py::class_<Field>(m, "Field",
                    "A reflectance field file (OpenEXR, 'lightstage build' or 'import'): R(x, l), "
                    "pixel x's linear value under LED l per unit of its irradiance.")
      .def_static(
          "open", [](const fs::path& path) { return std::make_unique<Field>(path); },
          py::arg("path"), "Opens a field file: reads its header (lights, noise, size), no values.")
      .def_property_readonly("path", &Field::path)
      .def_property_readonly(
          "shape",
          [](const Field& f) {
            return py::make_tuple(f.header().height(), f.header().width(), f.header().num_lights(),
                                  3);
          },
          "(height, width, lights, 3): the shape of values().")
      .def_property_readonly("width", [](const Field& f) { return f.header().width(); })
      .def_property_readonly("height", [](const Field& f) { return f.header().height(); })
      .def_property_readonly(
          "lights", [](const Field& f) { return Lights{f.header().lights()}; },
          "The LEDs: ids, directions, positions (near LEDs), validity, saturation ceilings.")
      .def_property_readonly(
          "noise", [](const Field& f) { return f.header().noise; },
          "The measurement noise the build estimated.")
      .def_property_readonly(
          "scene_time_s", [](const Field& f) { return f.header().scene_time_s; },
          "Scene time of the capture (time-varying sessions).")
      .def_property_readonly(
          "storage", [](const Field& f) { return f.storage().half ? "half" : "float"; },
          "How the file holds the values (read as float32 either way).")
      .def("rows", &Field::rows, py::arg("y0"), py::arg("y1"),
           "Rows [y0, y1) as a float32 array (y1 - y0) x W x L x 3, read from the file without "
           "the other rows into a new buffer of the library's (the array's base; writable, a "
           "copy of the file's values).")
      .def("values", &Field::values,
           "The whole field as a float32 array H x W x L x 3 (a small field: it must fit in "
           "memory). Read once; every call returns a view of the same memory, no copy, and "
           "writes through it are seen by save().")
      .def("save", &Field::save, py::arg("path"), py::arg("storage") = "auto",
           "Writes the field as values() holds it (with any writes made through it) to a new "
           "field file. storage: auto | half | float, as 'lightstage build --storage'.")
      .def("save_rows", &Field::save_rows, py::arg("path"), py::arg("y0"), py::arg("y1"),
           py::arg("storage") = "auto",
           "Rows [y0, y1) as a field file of their own (read without the other rows): a band "
           "that another process or Dask worker can fit or relight. Refused for a field with "
           "near LEDs (their directions depend on the whole frame).")
      .def("__repr__", [](const Field& f) {
        return "<lightstage.Field " + f.path().string() + ": " +
               std::to_string(f.header().width()) + "x" + std::to_string(f.header().height()) +
               " pixels x " + std::to_string(f.header().num_lights()) + " lights>";
      });
}

}  // namespace ls::python
