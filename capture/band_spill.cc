#include "capture/band_spill.h"

#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>

#include "capture/field_file.h"
#include "lightstage/bands.h"
#include "lightstage/errors.h"

namespace ls::capture {

int spill_band_rows(int width, int height, int num_lights, const MemoryBudget& memory) {
  const std::size_t row_bytes = ReflectanceField::bytes_for(width, 1, num_lights);
  return rows_within(memory.bytes(), 2 * row_bytes, height);
}

SpillFile::SpillFile(const std::filesystem::path& field_file, int width, int height, int num_lights,
                     int band_rows, const std::filesystem::path& kept_at)
    : width_(width),
      height_(height),
      lights_(num_lights),
      band_rows_(band_rows),
      file_(kept_at.empty() ? std::filesystem::path(field_file.string() + ".spill-" +
                                                    std::to_string(::getpid()))
                            : kept_at,
            "a field built in bands needs free space for the whole field beside it",
            kept_at.empty() ? ScratchFile::Lifetime::kTemporary : ScratchFile::Lifetime::kKept) {}

void SpillFile::count_largest(const std::vector<float>& rgb) {
  const float largest = largest_magnitude(rgb.data(), rgb.size());
  float seen = largest_.load();
  while (largest > seen && !largest_.compare_exchange_weak(seen, largest)) {
  }
}

void SpillFile::put(int light, const std::vector<float>& rgb) {
  count_largest(rgb);
  for (int b = 0; b < bands(); ++b) {
    const std::size_t count = std::size_t(band_height(b)) * width_ * 3;
    const float* rows = rgb.data() + std::size_t(band_first_row(b)) * width_ * 3;
    file_.write(rows, count, offset(b) + std::size_t(light) * count);
  }
}

void SpillFile::reread(int light, std::vector<float>& rgb) {
  rgb.resize(std::size_t(width_) * height_ * 3);
  for (int b = 0; b < bands(); ++b) {
    const std::size_t count = std::size_t(band_height(b)) * width_ * 3;
    float* rows = rgb.data() + std::size_t(band_first_row(b)) * width_ * 3;
    file_.read(rows, count, offset(b) + std::size_t(light) * count);
  }
  count_largest(rgb);
}

void SpillFile::read_band(int b, std::vector<float>& scratch, ReflectanceField& band,
                          const std::vector<int>& keep) {
  const std::size_t per_light = std::size_t(band_height(b)) * width_ * 3;
  scratch.resize(per_light * std::size_t(lights_));
  file_.read(scratch.data(), scratch.size(), offset(b));
  const std::size_t lights = keep.empty() ? std::size_t(lights_) : keep.size();
  LS_CHECK(std::size_t(band.num_lights()) == lights, "a band of another number of lights");
  if (band.width() != width_ || band.height() != band_height(b)) {
    band = ReflectanceField(width_, band_height(b), band.lights());
  }
  tbb::parallel_for(0, band_height(b), [&](int y) {
    for (int x = 0; x < width_; ++x) {
      float* out = band.pixel(x, y);
      const std::size_t at = (std::size_t(y) * width_ + x) * 3;
      for (std::size_t i = 0; i < lights; ++i) {
        const std::size_t l = keep.empty() ? i : std::size_t(keep[i]);
        std::copy_n(&scratch[l * per_light + at], 3, out + 3 * i);
      }
    }
  });
}

FieldStorage SpillFile::write_field(const std::filesystem::path& out,
                                    const ReflectanceField& header, const ExrAttributes& attributes,
                                    const ProgressFn& progress, StorageChoice choice,
                                    HalfCheck* check, const std::vector<int>& keep) {
  FieldStorage storage;
  if (choice != StorageChoice::kFloat) storage = {true, half_scale_for(largest_.load())};
  std::vector<float> scratch;
  ReflectanceField band = ReflectanceField::without_values(0, 0, header.lights());
  while (true) {
    FieldWriter writer(out, header, attributes, 0, storage);
    HalfCheck worst;       // Over the bands written.
    bool refused = false;  // Auto, and half too coarse for a band: float instead.
    for (int b = 0; b < bands(); ++b) {
      read_band(b, scratch, band, keep);
      if (storage.half) {
        copy_attributes(header, band);  // Its noise: the check holds the rounding against it.
        worst.add(check_half(band, storage.scale));
        if (check) *check = worst;
        refused = choice == StorageChoice::kAuto && !worst.passes();
      }
      if (refused) break;
      writer.write_rows(band_first_row(b), band);
      report(progress, "write", b + 1, bands());
    }
    if (!refused) {
      writer.finish();
      return storage;
    }
    storage = {};
  }
}

std::size_t SpillFile::offset(int band) const {
  return std::size_t(band_first_row(band)) * width_ * 3 * std::size_t(lights_);
}

}  // namespace ls::capture
