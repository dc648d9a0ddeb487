#include "capture/olat_images.h"

#include <OpenImageIO/imageio.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <tuple>

#include "capture/band_spill.h"
#include "capture/field_file.h"
#include "capture/image_consistency.h"
#include "capture/olat_pixels.h"
#include "lightstage/bands.h"
#include "lightstage/checkpoint_dir.h"
#include "lightstage/errors.h"
#include "lightstage/run_outputs.h"

namespace ls::capture {
namespace {

namespace fs = std::filesystem;

std::string pixel_format_text(const ImageHeader& h) {
  const std::string depth = image_file::sample_name(h.format);
  const std::string layout = h.channels == 1   ? "grey"
                             : h.channels == 2 ? "grey+alpha"
                             : h.channels == 3 ? "RGB"
                                               : "RGBA";
  return depth + " " + layout;
}

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

std::string transfer_text(TransferCurve curve, double gamma) {
  switch (curve) {
    case TransferCurve::kSrgb:
      return "sRGB curve";
    case TransferCurve::kGamma: {
      char text[32];
      std::snprintf(text, sizeof(text), "gamma %g", gamma);
      return text;
    }
    case TransferCurve::kLinear:
      break;
  }
  return "none (linear)";
}

// Field size for a source size and --max-size (area downsizing keeps the aspect ratio).
std::pair<int, int> target_size(int width, int height, int max_size) {
  if (max_size <= 0 || std::max(width, height) <= max_size) return {width, height};
  const double scale = double(max_size) / std::max(width, height);
  return {std::max(1, int(std::lround(width * scale))),
          std::max(1, int(std::lround(height * scale)))};
}

// Light `light`'s image read, linearised, masked, resized to width x height and divided by its
// intensity into rgb (width * height * 3, field units); its ceiling into `field_light`. Returns
// the saturated samples.
long long import_image(const OlatImageSet& job, int light, const ImageHeader& first,
                       const Linearizer& linearizer, const OlatImportOptions& options, int width,
                       int height, FieldLight& field_light, std::vector<float>& rgb_out) {
  const OlatLight& entry = job.lights[light];
  const auto in = open_olat_image(entry.image, entry.where);
  const ImageHeader h = header_of(*in);
  check_like_first(first, job.lights[0].where, job.lights[0].image, h, entry.where, entry.image);
  const bool integer = is_integer_format(h.format);
  const Eigen::Vector3f inverse_intensity = entry.intensity_rgb.cwiseInverse();
  // An integer file clips at its largest code: after the transfer curve and the intensity that is
  // this light's ceiling. (A field pixel averaged from clipped and unclipped image pixels lies
  // below it and is not caught.) Float files carry no ceiling.
  if (integer) field_light.saturates_at = linearizer.ceiling(h.format) * inverse_intensity;
  // The image's linear values, decoded a band of rows at a time: straight into the field's values
  // at the image's own size (one copy held per thread, not four: a 12-megapixel set's import held
  // 0.6 GB per image being read), else into the full image the field's size is resized from.
  const bool resize = width != h.width || height != h.height;
  cv::Mat rgb, saturated;
  if (resize) {
    rgb.create(h.height, h.width, CV_32FC3);
    if (options.zero_saturated)
      saturated = cv::Mat(h.height, h.width, CV_32FC3, cv::Scalar::all(0));
  } else {
    rgb_out.resize(std::size_t(width) * height * 3);
  }
  float* linear = resize ? rgb.ptr<float>() : rgb_out.data();
  constexpr int kBandRows = 64;
  std::vector<float> raw(std::size_t(h.width) * kBandRows * h.channels);
  long long saturated_count = 0;
  for (int y0 = 0; y0 < h.height; y0 += kBandRows) {
    const int y1 = std::min(h.height, y0 + kBandRows);
    if (!in->read_rows(y0, y1, image_file::Sample::kFloat, raw.data())) {
      throw InputError(entry.where + ": image: cannot decode " + entry.image.string() + ": " +
                       in->error());
    }
    const std::size_t first_pixel = std::size_t(y0) * h.width;
    saturated_count +=
        linearise_pixels(raw.data(), h, std::size_t(y1 - y0) * h.width, first_pixel,
                         job.mask.empty() ? nullptr : job.mask.data() + first_pixel, linearizer,
                         options.zero_saturated, linear + 3 * first_pixel,
                         saturated.empty() ? nullptr : saturated.ptr<float>() + 3 * first_pixel,
                         entry.where, entry.image);
  }
  check_decoded(*in, entry.where, entry.image);
  if (resize) {
    const cv::Size size(width, height);
    cv::Mat small;
    cv::resize(rgb, small, size, 0, 0, cv::INTER_AREA);
    if (!job.mask.empty()) {
      // Normalised convolution: average over the object's part of each output pixel only, so the
      // border does not darken; pixels mostly outside the mask stay 0.
      const cv::Mat mask(h.height, h.width, CV_32F, const_cast<float*>(job.mask.data()));
      cv::Mat coverage;
      cv::resize(mask, coverage, size, 0, 0, cv::INTER_AREA);
      for (int y = 0; y < size.height; ++y) {
        for (int x = 0; x < size.width; ++x) {
          const float w = coverage.at<float>(y, x);
          cv::Vec3f& v = small.at<cv::Vec3f>(y, x);
          v = w >= 0.5f ? v / w : cv::Vec3f(0, 0, 0);
        }
      }
    }
    if (options.zero_saturated) {
      cv::Mat small_saturated;
      cv::resize(saturated, small_saturated, size, 0, 0, cv::INTER_AREA);
      for (int i = 0; i < size.area() * 3; ++i) {
        if (small_saturated.ptr<float>()[i] > 0) small.ptr<float>()[i] = 0.0f;
      }
    }
    const float* values = small.ptr<float>();
    rgb_out.assign(values, values + std::size_t(width) * height * 3);
  }
  for (std::size_t p = 0; p < rgb_out.size(); p += 3) {
    for (int c = 0; c < 3; ++c) rgb_out[p + c] *= inverse_intensity[c];
  }
  if (entry.position_in_stage && job.view) {
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        const auto gain = float(near_light_gain(*job.view, width, height, x, y,
                                                *entry.position_in_stage, entry.falloff_from_m));
        float* v = rgb_out.data() + (std::size_t(y) * width + x) * 3;
        for (int c = 0; c < 3; ++c) v[c] *= gain;
      }
    }
  }
  return saturated_count;
}

// One import: the set checked and sized (the first image's header), then every light's image
// read (in parallel) and handed to a sink in field units.
class SetImport {
 public:
  using LightSink = std::function<void(int light, const std::vector<float>& rgb)>;
  // A light an earlier run (or another rank) kept: its image into rgb and its counts restored
  // (not given to the sink: it is where the sink would put it), or false (read from its file).
  using KeptLight = std::function<bool(int light, std::vector<float>& rgb, long long& saturated)>;
  // After a light's image went to the sink (not for kept ones): what a record of it holds.
  using LightDone = std::function<void(int light, long long saturated)>;

  // place_lights: the lights placed as the options say (place_olat_lights: spheres read from
  // every image, or a stage); false (a header): as listed.
  SetImport(OlatImageSet job, const OlatImportOptions& options, bool place_lights = true)
      : start_(std::chrono::steady_clock::now()), job_(std::move(job)), options_(options) {
    if (const std::string error = options.validate(); !error.empty()) {
      throw InputError(job_.source.string() + ": " + error);
    }
    if (job_.lights.empty()) throw InputError(job_.source.string() + ": no lights listed");
    {
      const auto in = open_olat_image(job_.lights[0].image, job_.lights[0].where);
      first_ = header_of(*in);
    }
    if (!job_.mask.empty() &&
        (job_.mask_width != first_.width || job_.mask_height != first_.height)) {
      throw InputError(job_.mask_name + ": size: expected " +
                       size_text(first_.width, first_.height) + " like the images, got " +
                       size_text(job_.mask_width, job_.mask_height));
    }
    if (const std::string error = options.spheres.validate(first_.width, first_.height);
        !error.empty()) {
      throw InputError(job_.source.string() + ": " + error);
    }
    std::tie(width_, height_) = target_size(first_.width, first_.height, options.max_size);
    if (place_lights) place_olat_lights(job_, options, first_);
    std::vector<FieldLight> lights;
    lights.reserve(job_.lights.size());
    for (int l = 0; l < num_lights(); ++l) {
      const OlatLight& light = job_.lights[size_t(l)];
      lights.push_back({l, light.dir_in_stage, true});
      lights.back().position_in_stage = light.position_in_stage;
    }
    header_ = ReflectanceField::without_values(width_, height_, std::move(lights));
    header_.view = job_.view;
    header_.source = job_.source.string();
    header_.scene_time_s = options.scene_time_s;
  }

  int num_lights() const { return int(job_.lights.size()); }
  const fs::path& source() const { return job_.source; }
  // What an import's result depends on beyond the source file and options: every image's (and
  // the mask's) size and time, and the lights' intensities (a rewritten image is read again).
  nlohmann::json identity() const {
    nlohmann::json images = nlohmann::json::array();
    const auto file = [](const fs::path& path) {
      std::error_code size_error, time_error;
      const auto size = fs::file_size(path, size_error);
      const auto time = fs::last_write_time(path, time_error).time_since_epoch().count();
      return nlohmann::json{path.string(), size_error ? 0 : size, time_error ? 0 : time};
    };
    for (const OlatLight& light : job_.lights) {
      images.push_back({file(light.image), light.intensity_rgb.x(), light.intensity_rgb.y(),
                        light.intensity_rgb.z()});
    }
    if (!job_.mask_name.empty()) images.push_back(file(job_.mask_name));
    return images;
  }
  const ReflectanceField& header() const { return header_; }
  std::string what() const {
    return job_.source.string() + ": reflectance field " + size_text(width_, height_) + " with " +
           std::to_string(num_lights()) + " lights";
  }

  // Every light's image to `sink` (from worker threads, one light at a time each); with `mine`,
  // only the lights it takes; `kept` and `done`: see their types.
  void read_images(const LightSink& sink, const std::function<bool(int)>& mine = {},
                   const KeptLight& kept = {}, const LightDone& done_with = {}) {
    const Linearizer linearizer(job_.transfer, options_.gamma);
    int n = 0;
    for (int l = 0; l < num_lights(); ++l) n += !mine || mine(l);
    ProgressCount done(options_.progress, "import", n);
    tbb::parallel_for(0, num_lights(), [&](int l) {
      if (mine && !mine(l)) return;
      std::vector<float> rgb;
      long long saturated = 0;
      if (kept && kept(l, rgb, saturated)) {
        saturated_ += saturated;  // Already where the sink would put it.
      } else {
        saturated = import_image(job_, l, first_, linearizer, options_, width_, height_,
                                 header_.lights()[size_t(l)], rgb);
        saturated_ += saturated;
        // Cancelled by another light's failure (or a stop): its image may be incomplete.
        if (tbb::is_current_task_group_canceling()) return;
        sink(l, rgb);
        if (done_with) done_with(l, saturated);
      }
      done.finished_one();
    });
  }
  // Light l's saturation ceiling (as reading its image set it), and setting it back (a kept light).
  FieldLight& light(int l) { return header_.lights()[size_t(l)]; }

  // The images as the consistency check sees them (options.keep_all: none), to be filled by
  // the sink; then the lights to keep (empty: every light), the stack clipped by the check.
  std::optional<ConsistencyStack> consistency_stack() const {
    if (options_.keep_all) return std::nullopt;
    std::vector<Eigen::Vector3d> dirs;
    for (const OlatLight& light : job_.lights) dirs.push_back(light.dir_in_stage.normalized());
    return ConsistencyStack(width_, height_, std::move(dirs));
  }
  std::vector<int> consistent_lights(std::optional<ConsistencyStack>& stack) {
    if (!stack) {
      consistency_ = "not checked (--keep-all)";
      return {};
    }
    const ConsistencyReport report = check_image_consistency(*stack);
    if (!report.not_checked.empty()) {
      consistency_ = "not checked: " + report.not_checked;
      return {};
    }
    const std::vector<int> flagged = report.flagged();
    for (int l : flagged) {
      const OlatLight& light = job_.lights[size_t(l)];
      inconsistent_.push_back(light.image.filename().string() + " (" + light.where +
                              "): " + report.images[size_t(l)].reason);
    }
    consistency_ = std::to_string(num_lights()) + " images checked against what the others predict";
    if (flagged.empty()) return {};
    const bool leave_out = options_.leave_out_inconsistent;
    consistency_ += ": " + std::to_string(flagged.size()) + (leave_out ? " left out" : " kept");
    if (!leave_out) return {};
    left_out_lights_ = flagged;
    std::vector<int> keep;
    for (int l = 0; l < num_lights(); ++l) {
      if (!report.images[size_t(l)].flagged) keep.push_back(l);
    }
    return keep;
  }

  void summarise(OlatImportSummary* summary) {
    if (!summary) return;
    OlatImportSummary& s = *summary;
    s = OlatImportSummary{};
    s.light_placement = job_.placement.description;
    s.listed_direction_error_median_deg = job_.placement.listed_error_median_deg;
    s.listed_direction_error_max_deg = job_.placement.listed_error_max_deg;
    s.inconsistent = inconsistent_;
    s.left_out_lights = left_out_lights_;
    s.consistency = consistency_;
    s.format = job_.format;
    s.source = job_.source;
    s.images = num_lights();
    s.source_width = first_.width;
    s.source_height = first_.height;
    s.width = width_;
    s.height = height_;
    s.pixel_format = pixel_format_text(first_);
    s.transfer_undone = is_integer_format(first_.format)
                            ? transfer_text(job_.transfer, options_.gamma)
                            : "none (float images are linear)";
    s.min_dir_z = 1.0;
    s.max_dir_z = -1.0;
    for (const OlatLight& e : job_.lights) {
      s.min_dir_z = std::min(s.min_dir_z, e.dir_in_stage.z());
      s.max_dir_z = std::max(s.max_dir_z, e.dir_in_stage.z());
    }
    s.saturated_samples = saturated_.load();
    const std::size_t all = std::size_t(first_.width) * first_.height;
    const std::size_t inside = job_.mask.empty()
                                   ? all
                                   : std::size_t(std::count_if(job_.mask.begin(), job_.mask.end(),
                                                               [](float m) { return m > 0; }));
    s.masked_out_pixels = int(all - inside);
    s.saturated_fraction =
        inside > 0 ? double(s.saturated_samples) / (double(inside) * 3 * num_lights()) : 0;
    s.intensities_divided = job_.format == OlatFormat::kDiligent && job_.warnings.empty();
    s.notes = std::move(job_.notes);
    s.warnings = std::move(job_.warnings);
    if (s.saturated_samples > 0) {
      s.notes.push_back(
          std::to_string(s.saturated_samples) + " samples at the maximum code (saturated): " +
          (options_.zero_saturated ? "set to 0, so the normals and fits leave them out as shadowed"
                                   : "kept as lower bounds, which the normals and fits leave out "
                                     "as censored (FieldLight::saturates_at)"));
    }
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
  OlatImageSet job_;
  const OlatImportOptions& options_;
  ImageHeader first_;
  int width_ = 0, height_ = 0;
  ReflectanceField header_;  // Lights (with their ceilings once read); no values.
  std::atomic<long long> saturated_{0};
  std::vector<std::string> inconsistent_;  // Of consistent_lights.
  std::vector<int> left_out_lights_;
  std::string consistency_;
};

// The field in memory (refused when it does not fit), without the images the consistency check
// leaves out.
ReflectanceField read_whole(SetImport& set, const LightImageFn& on_light) {
  const ReflectanceField& header = set.header();
  require_memory(ReflectanceField::bytes_for(header.width(), header.height(), set.num_lights()),
                 set.what(), "use --max-size, or --memory to import in bands");
  ReflectanceField field(header.width(), header.height(), header.lights());
  std::optional<ConsistencyStack> stack = set.consistency_stack();
  set.read_images([&](int l, const std::vector<float>& rgb) {
    if (on_light) on_light(l, header.lights()[size_t(l)].dir_in_stage, rgb);
    if (stack) stack->add(l, rgb);
    field.set_light_image(l, rgb);
  });
  field.lights() = header.lights();  // With the ceilings the images gave.
  copy_attributes(header, field);
  const std::vector<int> keep = set.consistent_lights(stack);
  if (keep.empty()) return field;
  return select_lights(field, keep);
}

}  // namespace

ReflectanceField images_header(OlatImageSet job, const OlatImportOptions& options) {
  return SetImport(std::move(job), options, /*place_lights=*/false).header();
}

ReflectanceField import_images(OlatImageSet job, const OlatImportOptions& options,
                               OlatImportSummary* summary) {
  SetImport set(std::move(job), options);
  ReflectanceField field = read_whole(set, {});
  set.summarise(summary);
  return field;
}

int import_images_to_file(OlatImageSet job, const OlatImportOptions& options, const fs::path& out,
                          const ExrAttributes& attributes, const MemoryBudget& memory,
                          const LightImageFn& on_light, OlatImportSummary* summary,
                          const RankSplit& split) {
  refuse_output_over_input(out, job.source);
  for (const OlatLight& light : job.lights) refuse_output_over_input(out, light.image);
  SetImport set(std::move(job), options);
  const ReflectanceField& header = set.header();
  int rows = spill_band_rows(header.width(), header.height(), set.num_lights(), memory);
  std::atomic<int> resumed{0};
  const StorageChoice choice = options.storage;
  FieldStorage storage;
  HalfCheck check;
  if (rows >= header.height() && !split.split()) {
    const ReflectanceField field = read_whole(set, on_light);
    storage = choose_storage(field, choice, &check);
    write_field(out, field, attributes, 0, storage);
  } else {
    // The spill and a record per light (its saturated samples and ceiling, written once its
    // image is durable) are kept in OUT.partial/ until the field is written: a killed import
    // resumes from the lights it read, and under MPI each rank reads its share of them.
    nlohmann::json identity = nlohmann::json::object();
    for (const auto& [key, value] : attributes) identity[key] = value;
    identity["images"] = set.identity();
    const CheckpointDir checkpoint(out, input_identity(set.source(), identity.dump()));
    const int band_rows = agreed_band_rows(checkpoint, rows, split);
    SpillFile spill(out, header.width(), header.height(), set.num_lights(), band_rows,
                    checkpoint.dir() / "lights.spill");
    std::optional<ConsistencyStack> stack = set.consistency_stack();
    constexpr const char* kMagic = "lightstage import light 1";
    const auto record = [&](int l) { return checkpoint.dir() / ("light_" + std::to_string(l)); };
    const auto kept = [&](int l, std::vector<float>& rgb, long long& saturated) {
      std::array<float, 3> ceiling{};
      const bool read = read_record(record(l), kMagic, [&](const nlohmann::json& info) {
        saturated = info.at("saturated").get<long long>();
        return std::optional<std::vector<RecordTarget>>{
            {{ceiling.data(), ceiling.size() * sizeof(float)}}};
      });
      if (!read) return false;
      set.light(l).saturates_at = Eigen::Vector3f(ceiling[0], ceiling[1], ceiling[2]);
      spill.reread(l, rgb);
      if (on_light) on_light(l, header.lights()[size_t(l)].dir_in_stage, rgb);
      if (stack) stack->add(l, rgb);
      ++resumed;
      return true;
    };
    const auto done = [&](int l, long long saturated) {
      spill.sync();  // The image is there before its record says so.
      const Eigen::Vector3f& ceiling = set.light(l).saturates_at;
      write_record(record(l), kMagic, {{"saturated", saturated}},
                   {{ceiling.data(), 3 * sizeof(float)}});
    };
    const auto sink = [&](int l, const std::vector<float>& rgb) {
      if (on_light) on_light(l, header.lights()[size_t(l)].dir_in_stage, rgb);
      if (stack) stack->add(l, rgb);
      spill.put(l, rgb);
    };
    set.read_images(
        sink, [&](int l) { return split.mine(l); }, kept, done);
    if (split.split()) {
      split.barrier();  // Every rank's lights are in the spill, with their records.
      if (split.rank != 0) return band_rows;
      spill.reopen();  // Their images as they wrote them (a file system shared between nodes).
      // The other ranks' lights, from their records (read here where one is missing).
      const int own = resumed.load();
      set.read_images(
          sink, [&](int l) { return !split.mine(l); }, kept, done);
      resumed = own;
    }
    const std::vector<int> keep = set.consistent_lights(stack);
    storage = spill.write_field(out, keep.empty() ? header : select_lights(header, keep),
                                attributes, {}, choice, &check, keep);
    checkpoint.remove();
    rows = band_rows;
  }
  set.summarise(summary);
  if (summary) {
    summary->resumed_lights = resumed.load();
    summary->storage = storage;
    if (choice != StorageChoice::kFloat) summary->half_check = check;
  }
  return rows;
}

void read_mask(const fs::path& mask_file, OlatImageSet& job) {
  const auto in = open_olat_image(mask_file, mask_file.string());
  const ImageHeader h = header_of(*in);
  std::vector<float> raw(std::size_t(h.width) * h.height * h.channels);
  if (!in->read_rows(0, h.height, image_file::Sample::kFloat, raw.data())) {
    throw InputError(mask_file.string() + ": cannot decode: " + in->error());
  }
  job.mask.resize(std::size_t(h.width) * h.height);
  for (std::size_t p = 0; p < job.mask.size(); ++p) {
    float m = 0;
    for (int c = 0; c < std::min(h.channels, 3); ++c) m = std::max(m, raw[p * h.channels + c]);
    job.mask[p] = m >= 0.5f ? 1.0f : 0.0f;
  }
  job.mask_width = h.width;
  job.mask_height = h.height;
  job.mask_name = mask_file.string();
}

}  // namespace ls::capture
