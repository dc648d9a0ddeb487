#include "capture/field_file.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <new>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <unordered_map>

#include "capture/exr_band_reader.h"
#include "lightstage/bands.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/image_file.h"
#include "lightstage/memory.h"

namespace ls::capture {
namespace {

constexpr const char* kLightsAttribute = "lightstage:lights";
constexpr const char* kSceneTimeAttribute = "lightstage:scene_time_s";
constexpr const char* kNoiseAttribute = "lightstage:noise";
constexpr const char* kViewAttribute = "lightstage:view";
const char kChannelSuffix[3] = {'R', 'G', 'B'};

std::string channel_name(int led_id, int c) {
  char text[32];
  std::snprintf(text, sizeof(text), "led%03d.%c", led_id, kChannelSuffix[c]);
  return text;
}

}  // namespace

namespace {

using image_file::Sample;

image_file::Spec field_spec(const std::string& name, const ReflectanceField& field,
                            const ExrAttributes& attributes, int tile_size, FieldStorage storage) {
  if (field.width() <= 0 || field.height() <= 0 || field.num_lights() <= 0) {
    throw InputError(name + ": cannot write an empty reflectance field");
  }
  const int num_channels = 3 * field.num_lights();
  image_file::Spec spec;
  spec.width = field.width();
  spec.height = field.height();
  spec.channels = num_channels;
  spec.format = storage.half ? Sample::kHalf : Sample::kFloat;
  nlohmann::json lights = nlohmann::json::array();
  for (const FieldLight& light : field.lights()) {
    for (int c = 0; c < 3; ++c) spec.channel_names.push_back(channel_name(light.led_id, c));
    nlohmann::json entry = {
        {"id", light.led_id},
        {"dir", {light.dir_in_stage.x(), light.dir_in_stage.y(), light.dir_in_stage.z()}},
        {"valid", light.valid}};
    // JSON has no infinity: a light that never saturates simply has no key.
    if (light.saturates_at.allFinite()) {
      entry["saturates_at"] = {light.saturates_at.x(), light.saturates_at.y(),
                               light.saturates_at.z()};
    }
    if (light.position_in_stage) {
      const Eigen::Vector3d& p = *light.position_in_stage;
      entry["position"] = {p.x(), p.y(), p.z()};
    }
    lights.push_back(entry);
  }
  spec.set(kLightsAttribute, lights.dump());
  spec.set(kSceneTimeAttribute, field.scene_time_s);
  if (field.noise.measured) {
    const nlohmann::json noise = {{"read_variance", field.noise.read_variance},
                                  {"shot_variance_per_unit", field.noise.shot_variance_per_unit},
                                  {"method", field.noise.method}};
    spec.set(kNoiseAttribute, noise.dump());
  }
  if (field.view) {
    const FieldView& v = *field.view;
    const nlohmann::json view = {{"fov_y_deg", v.fov_y_deg},
                                 {"camera_distance_m", v.camera_distance_m},
                                 {"ortho_height_m", v.ortho_height_m},
                                 {"reference_z_m", v.reference_z_m}};
    spec.set(kViewAttribute, view.dump());
  }
  for (const auto& [key, value] : attributes) spec.set(key, value);
  if (storage.half) spec.set(kStorageAttribute, storage.to_json());
  // Uncompressed: ExrBandReader reads its rows as raw bytes, without OpenEXR's conversion value by
  // value. Relighting the 512x512 sim field (151 LEDs, 475 MB): 1034 MiB/s of file uncompressed
  // against 338 MiB/s with RLE, which saves nothing on noisy values (the demo field, with invalid
  // LEDs and a black background: 92 against 119 MB). Older RLE fields still read, more slowly.
  spec.set("compression", "none");
  spec.tile_width = spec.tile_height = std::max(0, tile_size);
  return spec;
}

}  // namespace

struct FieldWriter::File {
  explicit File(const std::filesystem::path& path) : name(path.string()), file(path) {}
  std::string name;
  AtomicFileWriter file;                    // Atomic: nothing at the path until finish().
  std::unique_ptr<image_file::Writer> out;  // Gone before the file goes.
  int tile_size = 0;
  FieldStorage storage;
  std::vector<std::uint16_t> halves;  // Rows converted for writing (half storage).

  // A StorageError when the file refused a write (a full disk), else an InputError.
  [[noreturn]] void fail(const std::string& what) const {
    if (file.failed()) throw StorageError(name + ": " + what);
    throw InputError(name + ": " + what);
  }
};

FieldWriter::FieldWriter(const std::filesystem::path& path, const ReflectanceField& header,
                         const ExrAttributes& attributes, int tile_size, FieldStorage storage)
    : width_(header.width()), height_(header.height()) {
  const image_file::Spec spec = field_spec(path.string(), header, attributes, tile_size, storage);
  file_ = std::make_unique<File>(path);
  File& f = *file_;
  f.tile_size = tile_size;
  f.storage = storage;
  std::string error;
  f.out = image_file::create("field.exr", spec, f.file, error);  // EXR, whatever the name.
  if (!f.out) f.fail("cannot open for writing: " + error);
}

FieldWriter::~FieldWriter() = default;

void FieldWriter::write_rows(int y0, const ReflectanceField& band) {
  File& f = *file_;
  const int y1 = y0 + band.height();
  if (band.width() != width_ || y0 != next_row_ || y1 > height_ ||
      (f.tile_size > 0 && y1 < height_ && band.height() % f.tile_size != 0)) {
    throw std::logic_error(f.name +
                           ": FieldWriter::write_rows: rows out of order or not whole tiles");
  }
  bool ok = true;
  if (f.storage.half) {
    // Whole tile rows, else pieces of about 8 MiB of halves.
    const std::size_t row_values = std::size_t(width_) * 3 * band.num_lights();
    const int piece = f.tile_size > 0
                          ? band.height()
                          : int(std::max<std::size_t>(1, (std::size_t(4) << 20) / row_values));
    for (int a = 0; a < band.height() && ok; a += piece) {
      const int b = std::min(band.height(), a + piece);
      f.halves.resize(std::size_t(b - a) * row_values);
      floats_to_halves(band.pixel(0, a), f.halves.size(), f.storage.scale, f.halves.data());
      ok = f.out->write_rows(y0 + a, y0 + b, Sample::kHalf, f.halves.data());
    }
  } else {
    ok = f.out->write_rows(y0, y1, Sample::kFloat, band.values().data());
  }
  if (!ok) {
    f.fail("writing the reflectance field failed (rows " + std::to_string(y0) + ".." +
           std::to_string(y1 - 1) + "): " + f.out->error());
  }
  next_row_ = y1;
}

void FieldWriter::finish() {
  File& f = *file_;
  if (next_row_ != height_) {
    throw std::logic_error(f.name + ": FieldWriter::finish before every row was written");
  }
  if (!f.out->close()) f.fail("writing the reflectance field failed: " + f.out->error());
  f.out.reset();
  f.file.commit();
}

FieldStorage choose_storage(const ReflectanceField& field, StorageChoice choice, HalfCheck* check) {
  if (choice == StorageChoice::kFloat) return {};
  const float scale = half_scale(field);
  const HalfCheck half = check_half(field, scale);
  if (check) *check = half;
  if (choice == StorageChoice::kAuto && !half.passes()) return {};
  return {true, scale};
}

void write_field(const std::filesystem::path& path, const ReflectanceField& field,
                 const ExrAttributes& attributes, int tile_size, FieldStorage storage) {
  FieldWriter writer(path, field, attributes, tile_size, storage);
  writer.write_rows(0, field);
  writer.finish();
}

namespace {

std::vector<FieldLight> parse_lights(const std::string& name, const std::string& text) {
  std::vector<FieldLight> lights;
  try {
    const nlohmann::json j = nlohmann::json::parse(text);
    if (!j.is_array()) throw InputError("expected an array");
    for (size_t i = 0; i < j.size(); ++i) {
      const nlohmann::json& e = j[i];
      const auto& dir = e.at("dir");
      if (!dir.is_array() || dir.size() != 3) throw InputError("dir must be [x, y, z]");
      FieldLight light;
      // Checked, not cast: a huge id would wrap to another LED's channel name.
      const nlohmann::json& id = e.at("id");
      if (!id.is_number_integer() || id.get<long long>() < 0 ||
          id.get<long long>() > std::numeric_limits<int>::max()) {
        throw InputError("id must be an integer in [0, " +
                         std::to_string(std::numeric_limits<int>::max()) + "], got " + id.dump());
      }
      light.led_id = id.get<int>();
      light.dir_in_stage = {dir[0].get<double>(), dir[1].get<double>(), dir[2].get<double>()};
      light.valid = e.at("valid").get<bool>();
      // norm() finite, not only the components: near the largest double they overflow it, and
      // the direction normalised later would be 0. (A NaN component makes it NaN.)
      const double norm = light.dir_in_stage.norm();
      if (!(norm > 0 && std::isfinite(norm))) {
        throw InputError("dir must be a finite, non-zero direction");
      }
      if (e.contains("saturates_at")) {
        const auto& sat = e.at("saturates_at");
        if (!sat.is_array() || sat.size() != 3) throw InputError("saturates_at must be [r, g, b]");
        light.saturates_at = {sat[0].get<float>(), sat[1].get<float>(), sat[2].get<float>()};
        if (!(light.saturates_at.array() > 0).all() || !light.saturates_at.allFinite()) {
          throw InputError("saturates_at must be finite and positive");
        }
      }
      if (e.contains("position")) {
        const auto& p = e.at("position");
        if (!p.is_array() || p.size() != 3) throw InputError("position must be [x, y, z]");
        light.position_in_stage =
            Eigen::Vector3d(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
        if (!light.position_in_stage->allFinite() || !(light.position_in_stage->norm() > 0)) {
          throw InputError("position must be finite and away from the stage centre");
        }
      }
      lights.push_back(light);
    }
  } catch (const std::exception& e) {
    throw InputError(
        name + ": attribute '" + std::string(kLightsAttribute) +
        "': expected a JSON array of {id, dir: [x, y, z], valid, saturates_at?: [r, g, b], "
        "position?: [x, y, z]}: " +
        e.what());
  }
  return lights;
}

// The EXR library may return channels in another order than written (it sorts them by name):
// file channel i goes to layout index result[i] (light-major, RGB innermost).
std::vector<int> channel_layout(const std::string& name, const image_file::Spec& spec,
                                const std::vector<FieldLight>& lights) {
  const int num_lights = int(lights.size());
  const int num_channels = spec.channels;
  if (num_lights == 0 || num_channels != 3 * num_lights) {
    throw InputError(name + ": expected " + std::to_string(3 * num_lights) + " channels (3 per " +
                     "LED for " + std::to_string(num_lights) + " LEDs), found " +
                     std::to_string(num_channels));
  }
  std::unordered_map<std::string, int> layout_index;
  for (int l = 0; l < num_lights; ++l) {
    for (int c = 0; c < 3; ++c) {
      if (!layout_index.emplace(channel_name(lights[l].led_id, c), 3 * l + c).second) {
        throw InputError(name + ": LED id " + std::to_string(lights[l].led_id) +
                         " appears twice in '" + kLightsAttribute + "'");
      }
    }
  }
  std::vector<int> file_to_layout(num_channels);
  std::vector<bool> seen(num_channels, false);
  for (int i = 0; i < num_channels; ++i) {
    const std::string& channel = spec.channel_names[i];
    auto it = layout_index.find(channel);
    if (it == layout_index.end()) {
      throw InputError(name + ": unknown channel '" + channel +
                       "' (expected ledNNN.R/G/B for the " + "LEDs in '" + kLightsAttribute + "')");
    }
    if (seen[it->second]) throw InputError(name + ": channel '" + channel + "' appears twice");
    seen[it->second] = true;
    file_to_layout[i] = it->second;
  }
  return file_to_layout;
}

// The scene time, seconds: a number of any numeric EXR type (a time written by another tool as an
// int or a float reads as that number); anything else is refused by name, never taken as 0.
double scene_time_of(const std::string& name, const image_file::Attribute& t) {
  const double seconds = t.is_number() ? t.number() : std::numeric_limits<double>::quiet_NaN();
  if (!std::isfinite(seconds)) {
    const std::string value = t.is_number() ? std::to_string(seconds) : *t.text();
    throw InputError(name + ": attribute '" + kSceneTimeAttribute +
                     "': expected a finite number of seconds, got " + t.type_name + " " + value);
  }
  return seconds;
}

// An attribute's text: a string as stored, a number as text (for a message that names it).
std::string text_of(const image_file::Attribute& a) {
  return a.text() != nullptr ? *a.text() : std::to_string(a.number());
}

// The optional attributes: scene time, measured noise, view.
void read_field_attributes(const std::string& name, const image_file::Spec& spec,
                           ReflectanceField& field) {
  if (const image_file::Attribute* t = spec.find(kSceneTimeAttribute)) {
    field.scene_time_s = scene_time_of(name, *t);
  }
  if (const image_file::Attribute* noise = spec.find(kNoiseAttribute)) {
    try {
      const nlohmann::json j = nlohmann::json::parse(text_of(*noise));
      field.noise.read_variance = j.at("read_variance").get<double>();
      field.noise.shot_variance_per_unit = j.at("shot_variance_per_unit").get<double>();
      field.noise.method = j.value("method", std::string());
      if (!std::isfinite(field.noise.read_variance) || field.noise.read_variance < 0 ||
          !std::isfinite(field.noise.shot_variance_per_unit) ||
          field.noise.shot_variance_per_unit < 0) {
        throw InputError("variances must be finite and non-negative");
      }
      field.noise.measured = true;
    } catch (const std::exception& e) {
      throw InputError(name + ": attribute '" + std::string(kNoiseAttribute) +
                       "': expected {read_variance, shot_variance_per_unit, method}: " + e.what());
    }
  }
  if (const image_file::Attribute* view = spec.find(kViewAttribute)) {
    try {
      const nlohmann::json j = nlohmann::json::parse(text_of(*view));
      FieldView v;
      v.fov_y_deg = j.at("fov_y_deg").get<double>();
      v.camera_distance_m = j.at("camera_distance_m").get<double>();
      v.ortho_height_m = j.at("ortho_height_m").get<double>();
      v.reference_z_m = j.at("reference_z_m").get<double>();
      if (!std::isfinite(v.fov_y_deg) || v.fov_y_deg < 0 || v.fov_y_deg >= 180 ||
          !(v.camera_distance_m > 0) || !std::isfinite(v.camera_distance_m) ||
          !(v.ortho_height_m > 0) || !std::isfinite(v.ortho_height_m) ||
          !std::isfinite(v.reference_z_m)) {
        throw InputError("fov_y_deg in [0, 180), positive finite distances, finite reference_z_m");
      }
      field.view = v;
    } catch (const std::exception& e) {
      throw InputError(name + ": attribute '" + std::string(kViewAttribute) +
                       "': expected {fov_y_deg, camera_distance_m, ortho_height_m, "
                       "reference_z_m}: " +
                       e.what());
    }
  }
}

}  // namespace

struct FieldStream::File {
  std::string name;
  image_file::Spec spec;  // The header as read.
  std::unique_ptr<ExrBandReader> pixels;
};

FieldStream::FieldStream(const std::filesystem::path& path) : file_(std::make_unique<File>()) {
  File& f = *file_;
  f.name = path.string();
  std::string error;
  const auto in = image_file::open(path, error);
  if (!in) throw InputError(f.name + ": cannot read reflectance field: " + error);
  f.spec = in->spec();
  const image_file::Spec& spec = f.spec;
  const image_file::Attribute* lights_param = spec.find(kLightsAttribute);
  if (lights_param == nullptr || lights_param->text() == nullptr) {
    throw InputError(f.name + ": not a reflectance field: missing string attribute '" +
                     std::string(kLightsAttribute) + "'");
  }
  std::vector<FieldLight> lights = parse_lights(f.name, *lights_param->text());
  if (const image_file::Attribute* storage = spec.find(kStorageAttribute);
      storage != nullptr && storage->text() != nullptr) {
    storage_ = FieldStorage::parse(f.name, *storage->text());
  }
  f.pixels = std::make_unique<ExrBandReader>(
      path, spec.channel_names, channel_layout(f.name, spec, lights), 1.0f / storage_.scale);
  header_ = ReflectanceField::without_values(spec.width, spec.height, std::move(lights));
  header_.source = f.name;
  read_field_attributes(f.name, spec, header_);
}

FieldStream::~FieldStream() = default;

int FieldStream::rows_within(std::size_t bytes) const {
  const image_file::Spec& spec = file_->spec;
  const std::size_t row_bytes = std::size_t(width()) * spec.channels * sizeof(float);
  // The band and the reader's buffer (a quarter of it at most: ExrBandReader).
  return ls::rows_within(bytes / 5 * 4, row_bytes, height(), spec.tile_height);
}

int FieldStream::row_alignment() const { return std::max(1, file_->spec.tile_height); }

int FieldStream::band_rows(const MemoryBudget& budget) const { return rows_within(budget.bytes()); }

FieldBands FieldStream::bands(int rows) {
  return bands_of([this](int y0, int y1, ReflectanceField& band) { read_rows(y0, y1, band); },
                  height(), rows);
}

void FieldStream::read_rows_into(int y0, int y1, float* dst) { file_->pixels->read(y0, y1, dst); }

void FieldStream::read_rows_planar(int y0, int y1, const PlanarVisitor& visit) {
  LS_CHECK(0 <= y0 && y0 < y1 && y1 <= height(), "rows out of the field");
  file_->pixels->read_planar(y0, y1, visit);
}

void FieldStream::read_rows(int y0, int y1, ReflectanceField& band) {
  shape_band(header_, y0, y1, band);
  read_rows_into(y0, y1, band.pixel(0, 0));
}

ReflectanceField read_field(const std::filesystem::path& path) {
  FieldStream stream(path);
  ReflectanceField field(stream.width(), stream.height(), stream.header().lights());
  copy_attributes(stream.header(), field);
  // In bands, so that a large field's permutation needs a bounded buffer, not a second field.
  const int rows = stream.rows_within(std::size_t(512) << 20);
  for (int y0 = 0; y0 < field.height(); y0 += rows) {
    stream.read_rows_into(y0, std::min(field.height(), y0 + rows), field.pixel(0, y0));
  }
  return field;
}

}  // namespace ls::capture
