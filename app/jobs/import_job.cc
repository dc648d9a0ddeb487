#include "app/jobs/import_job.h"

#include <mutex>
#include <nlohmann/json.hpp>

#include "capture/field.h"
#include "lightstage/image.h"

namespace ls::jobs {

namespace fs = std::filesystem;

namespace {

std::string options_json(const fs::path& source, const capture::OlatImportOptions& options) {
  nlohmann::json j;
  j["source"] = source.string();
  if (options.transfer) j["transfer"] = int(*options.transfer);
  j["gamma"] = options.gamma;
  j["max_size"] = options.max_size;
  j["drop_saturated"] = options.zero_saturated;
  return j.dump();
}

}  // namespace

ImportJobSummary import_set(const fs::path& source, const fs::path& out,
                            capture::OlatImportOptions options, std::size_t memory_bytes,
                            const ProgressFn& progress) {
  ImportJobSummary summary;
  summary.format = capture::detect_olat_format(source);
  options.on_progress = [&](int done, int total) { report(progress, "import", done, total); };
  // The preview: the light nearest the camera (+Z), the most evenly lit of the images (the first
  // of equals), kept as the images are read.
  std::mutex preview_mutex;
  double preview_z = -2;
  std::vector<float> preview_rgb;
  const auto keep_frontal = [&](int light, const Eigen::Vector3d& dir,
                                const std::vector<float>& rgb) {
    const std::lock_guard lock(preview_mutex);
    if (dir.z() > preview_z || (dir.z() == preview_z && light < summary.preview_light)) {
      preview_z = dir.z();
      summary.preview_light = light;
      preview_rgb = rgb;
    }
  };
  summary.band_rows = capture::import_olat_to_file(
      source, options, out, {{kOptionsAttribute, options_json(source, options)}}, memory_bytes,
      keep_frontal, &summary.import);
  summary.lights = summary.import.images;
  summary.mebibytes = capture::ReflectanceField::bytes_for(summary.import.width,
                                                           summary.import.height, summary.lights) /
                      1048576.0;
  Image preview(summary.import.width, summary.import.height, 3);
  preview.pixels = std::move(preview_rgb);
  summary.preview = out;
  summary.preview.replace_extension(".preview.png");
  write_png_preview(summary.preview, preview, auto_exposure_stops(preview));
  return summary;
}

}  // namespace ls::jobs
