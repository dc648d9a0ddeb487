#include "app/jobs/import_job.h"

#include <nlohmann/json.hpp>

#include "capture/field.h"
#include "lightstage/image.h"

namespace ls::jobs {

namespace fs = std::filesystem;

namespace {

// The light nearest the camera (+Z): the most evenly lit of the images, for the preview.
int frontal_light(const capture::ReflectanceField& field) {
  int best = 0;
  for (int l = 1; l < field.num_lights(); ++l) {
    if (field.lights()[l].dir_in_stage.z() > field.lights()[best].dir_in_stage.z()) best = l;
  }
  return best;
}

Image light_image(const capture::ReflectanceField& field, int light) {
  Image image(field.width(), field.height(), 3);
  for (int y = 0; y < field.height(); ++y) {
    for (int x = 0; x < field.width(); ++x) {
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = field.at(x, y, light, c);
    }
  }
  return image;
}

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
                            capture::OlatImportOptions options, const ProgressFn& progress) {
  ImportJobSummary summary;
  summary.format = capture::detect_olat_format(source);
  options.on_progress = [&](int done, int total) { report(progress, "import", done, total); };
  const capture::ReflectanceField field = capture::import_olat(source, options, &summary.import);
  capture::write_field(out, field, {{kOptionsAttribute, options_json(source, options)}});
  summary.lights = field.num_lights();
  summary.mebibytes = field.bytes() / 1048576.0;
  summary.preview_light = frontal_light(field);
  const Image preview = light_image(field, summary.preview_light);
  summary.preview = out;
  summary.preview.replace_extension(".preview.png");
  write_png_preview(summary.preview, preview, auto_exposure_stops(preview));
  return summary;
}

}  // namespace ls::jobs
