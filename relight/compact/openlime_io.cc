// OpenLIME's RTI folder (relight/compact/plane_field.h): info.json as relight's
// RtiBuilder::saveJSON writes it, and the planes as JPEGs (plane_j.jpg: planes 3j, 3j+1, 3j+2 in R,
// G, B, rows top to bottom, as relight's encoders write them and OpenLIME textures them).
#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/image_file.h"
#include "lightstage/json_reader.h"
#include "lightstage/memory.h"
#include "lightstage/run_outputs.h"
#include "lightstage/scratch_file.h"
#include "relight/compact/plane_field.h"

namespace ls::relight {

namespace fs = std::filesystem;

namespace {

fs::path plane_file(const fs::path& folder, int image, const std::string& format) {
  return folder / ("plane_" + std::to_string(image) + "." + format);
}

std::vector<float> floats(const JsonReader& array, size_t count) {
  array.expect_array();
  if (array.size() != count) array.fail("an array of " + std::to_string(count) + " numbers");
  std::vector<float> out(count);
  for (size_t i = 0; i < count; ++i) out[i] = float(array[i].number());
  return out;
}

// A plane is the 8-bit image info.json's format says: a 16-bit PNG named .jpg is not one.
void require_8bit_plane(const fs::path& plane, const std::string& format) {
  std::ifstream in(plane, std::ios::binary);
  unsigned char magic[3] = {0, 0, 0};
  in.read(reinterpret_cast<char*>(magic), 3);
  const bool jpeg = magic[0] == 0xFF && magic[1] == 0xD8 && magic[2] == 0xFF;
  const bool png = magic[0] == 0x89 && magic[1] == 'P' && magic[2] == 'N';
  if (in && (format == "jpg" ? !jpeg : !png)) {
    throw InputError(plane.string() + ": expected a " + (format == "jpg" ? "JPEG" : "PNG") +
                     " (info.json's format), got " +
                     (jpeg  ? "a JPEG"
                      : png ? "a PNG"
                            : "another format"));
  }
  std::string error;
  const auto reader = image_file::open(plane, error);
  if (reader && reader->spec().format != image_file::Sample::kUInt8) {
    throw InputError(plane.string() + ": expected 8-bit planes, got " +
                     image_file::sample_name(reader->spec().format) + " samples");
  }
}

}  // namespace

PlaneField write_openlime(const fs::path& folder, const PlaneField& field,
                          const std::string& format, int jpeg_quality) {
  LS_CHECK(format == "jpg" || format == "png", "planes are jpg or png");
  RunOutputs outputs(folder);  // A write that fails leaves no planes.
  fs::create_directories(folder);
  const size_t pixels = size_t(field.width()) * field.height();
  std::vector<uint8_t> rgb(pixels * 3);
  for (int j = 0; j < field.planes / 3; ++j) {
    for (size_t i = 0; i < pixels; ++i) {
      for (int k = 0; k < 3; ++k)
        rgb[i * 3 + k] = field.codes[i * size_t(field.planes) + size_t(3 * j + k)];
    }
    outputs.add(plane_file(folder, j, format));
    write_rgb8(plane_file(folder, j, format), field.width(), field.height(), rgb.data(),
               jpeg_quality);
  }
  nlohmann::ordered_json info;
  info["width"] = field.width();
  info["height"] = field.height();
  info["format"] = format;
  info["type"] = to_string(field.interpolation);
  info["colorspace"] = "mrgb";
  if (field.interpolation == PlaneInterpolation::kRbf) {
    info["sigma"] = field.sigma;
  } else {
    info["resolution"] = field.resolution;
  }
  std::vector<double> lights;
  for (const auto& l : field.lights) lights.insert(lights.end(), {l.x(), l.y(), l.z()});
  info["lights"] = lights;
  info["nplanes"] = field.planes;
  if (format == "jpg") info["quality"] = jpeg_quality;
  info["basis"] = field.basis;
  info["materials"] = {{{"range", field.range}, {"scale", field.scale}, {"bias", field.bias}}};
  // Not OpenLIME's: how the display values relate to the field (display units per field unit).
  info["lightstage"] = {{"gain", field.gain}, {"encoding", "sRGB"}};
  outputs.add(folder / "info.json");
  write_file_atomic(folder / "info.json", info.dump() + "\n");
  outputs.keep();
  return read_openlime(folder);
}

PlaneField read_openlime(const fs::path& folder) {
  const fs::path file = folder / "info.json";
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string() + ": cannot read (an OpenLIME folder has info.json)");
  std::stringstream text;
  text << in.rdbuf();
  const nlohmann::json json = JsonReader::parse(text.str(), file.string());
  const JsonReader info(json, file.string());
  PlaneField out;
  const int width = info["width"].integer_in(1, 65536),
            height = info["height"].integer_in(1, 65536);
  out.set_size(width, height);
  const std::string type = info["type"].one_of({"rbf", "bilinear"});
  out.interpolation = type == "rbf" ? PlaneInterpolation::kRbf : PlaneInterpolation::kBilinear;
  info["colorspace"].one_of({"mrgb"});
  const std::string format = info.has("format") ? info["format"].one_of({"jpg", "png"}) : "jpg";
  out.planes = info["nplanes"].integer_in(3, 255);
  if (out.planes % 3 != 0) info["nplanes"].fail("a multiple of 3 (three planes a JPEG)");
  if (out.interpolation == PlaneInterpolation::kRbf) {
    out.sigma = info["sigma"].number_in(1e-6, 10.0);
  } else {
    out.resolution = info["resolution"].integer_in(3, 64);
  }
  const JsonReader lights = info["lights"];
  lights.expect_array();
  if (lights.size() % 3 != 0 || lights.size() == 0) lights.fail("x y z for each light");
  for (size_t i = 0; i < lights.size(); i += 3) {
    out.lights.emplace_back(lights[i].number(), lights[i + 1].number(), lights[i + 2].number());
  }
  const size_t basis_size = size_t(out.planes + 1) * size_t(out.dims()) * 3;
  const JsonReader basis = info["basis"];
  basis.expect_array();
  if (basis.size() != basis_size) basis.fail(std::to_string(basis_size) + " bytes");
  for (size_t i = 0; i < basis_size; ++i) out.basis.push_back(uint8_t(basis[i].integer_in(0, 255)));
  const JsonReader material = info["materials"][0];
  out.range = floats(material["range"], size_t(out.planes));
  out.scale = floats(material["scale"], size_t(out.planes));
  out.bias = floats(material["bias"], size_t(out.planes));
  for (int p = 0; p < out.planes; ++p) {
    // As floats (what the planes are dequantised with): 1e308 is no scale.
    if (!(out.range[size_t(p)] > 0) || !std::isfinite(out.range[size_t(p)])) {
      material["range"][size_t(p)].fail("a positive number within float range");
    }
    if (!std::isfinite(out.scale[size_t(p)])) {
      material["scale"][size_t(p)].fail("a number within float range");
    }
    if (!std::isfinite(out.bias[size_t(p)])) {
      material["bias"][size_t(p)].fail("a number within float range");
    }
  }
  out.gain = info.has("lightstage") ? info["lightstage"]["gain"].positive() : 1.0;
  out.stored_bytes = fs::file_size(file);
  const size_t pixels = size_t(width) * height;
  // The planes' codes, a plane read as floats, and a render's image: before any is made.
  require_memory(pixels * (size_t(out.planes) + std::size_t(2 * 3) * sizeof(float)),
                 file.string() + ": width, height: " + std::to_string(width) + "x" +
                     std::to_string(height) + " with " + std::to_string(out.planes) + " planes",
                 "this folder cannot be rendered on this machine");
  out.codes.resize(pixels * size_t(out.planes));
  for (int j = 0; j < out.planes / 3; ++j) {
    const fs::path plane = plane_file(folder, j, format);
    require_8bit_plane(plane, format);
    const Image image = read_image(plane);
    if (image.width != width || image.height != height || image.channels != 3) {
      throw InputError(plane.string() + ": expected a " + std::to_string(width) + "x" +
                       std::to_string(height) + " RGB image (info.json's size), got " +
                       std::to_string(image.width) + "x" + std::to_string(image.height) + "x" +
                       std::to_string(image.channels));
    }
    for (size_t i = 0; i < pixels; ++i) {
      for (int k = 0; k < 3; ++k) {
        out.codes[i * size_t(out.planes) + size_t(3 * j + k)] =
            uint8_t(std::clamp(std::lround(image.pixels[i * 3 + k] * 255.0f), 0L, 255L));
      }
    }
    out.stored_bytes += fs::file_size(plane);
  }
  return out;
}

}  // namespace ls::relight
