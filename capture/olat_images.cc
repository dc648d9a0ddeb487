#include "capture/olat_images.h"

#include <OpenImageIO/imageio.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <opencv2/imgproc.hpp>

#include "lightstage/errors.h"

namespace ls::capture {
namespace {

namespace fs = std::filesystem;

struct ImageHeader {
  int width = 0, height = 0, channels = 0;
  OIIO::TypeDesc format;
};

std::unique_ptr<OIIO::ImageInput> open_image(const fs::path& path, const std::string& at) {
  auto in = OIIO::ImageInput::open(path.string());
  if (!in) {
    throw InputError(at + ": image: cannot read " + path.string() + ": " + OIIO::geterror());
  }
  return in;
}

ImageHeader header_of(const OIIO::ImageInput& in) {
  const OIIO::ImageSpec& spec = in.spec();
  return {spec.width, spec.height, spec.nchannels, spec.format};
}

bool is_integer_format(OIIO::TypeDesc format) {
  return format.basetype == OIIO::TypeDesc::UINT8 || format.basetype == OIIO::TypeDesc::UINT16;
}

std::string pixel_format_text(const ImageHeader& h) {
  const std::string depth = h.format.basetype == OIIO::TypeDesc::UINT8    ? "8-bit"
                            : h.format.basetype == OIIO::TypeDesc::UINT16 ? "16-bit"
                            : h.format.basetype == OIIO::TypeDesc::HALF   ? "half float"
                            : h.format.basetype == OIIO::TypeDesc::FLOAT  ? "float"
                                                                          : h.format.c_str();
  const std::string layout = h.channels == 1   ? "grey"
                             : h.channels == 2 ? "grey+alpha"
                             : h.channels == 3 ? "RGB"
                                               : "RGBA";
  return depth + " " + layout;
}

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

// Code (normalised to [0, 1]) -> linear value, tabulated per code for 8- and 16-bit files.
class Linearizer {
 public:
  Linearizer(TransferCurve curve, double gamma) : curve_(curve), gamma_(gamma) {
    for (int bits : {8, 16}) {
      const int max_code = (1 << bits) - 1;
      std::vector<float>& table = bits == 8 ? table8_ : table16_;
      table.resize(max_code + 1);
      for (int code = 0; code <= max_code; ++code)
        table[code] = float(apply(double(code) / max_code));
    }
  }
  const std::vector<float>* table(OIIO::TypeDesc format) const {
    if (format.basetype == OIIO::TypeDesc::UINT8) return &table8_;
    if (format.basetype == OIIO::TypeDesc::UINT16) return &table16_;
    return nullptr;  // Float files are linear already.
  }

 private:
  double apply(double v) const {
    switch (curve_) {
      case TransferCurve::kSrgb:
        return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
      case TransferCurve::kGamma:
        return std::pow(v, gamma_);
      case TransferCurve::kLinear:
        break;
    }
    return v;
  }
  TransferCurve curve_;
  double gamma_;
  std::vector<float> table8_, table16_;
};

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

// Reads one light's image as linear RGB at the field's size, with the mask and the light's
// intensity applied, into the field. Returns the number of saturated samples (inside the mask).
long long import_image(const OlatImageSet& job, int light, const ImageHeader& first,
                       const Linearizer& linearizer, const OlatImportOptions& options,
                       ReflectanceField& field) {
  const OlatLight& entry = job.lights[light];
  const auto in = open_image(entry.image, entry.where);
  const ImageHeader h = header_of(*in);
  if (h.width != first.width || h.height != first.height) {
    throw InputError(entry.where + ": image size: expected " +
                     size_text(first.width, first.height) + " like " + job.lights[0].where + " (" +
                     job.lights[0].image.string() + "), got " + size_text(h.width, h.height) +
                     " (" + entry.image.string() + ")");
  }
  std::vector<float> raw(std::size_t(h.width) * h.height * h.channels);
  if (!in->read_image(0, 0, 0, h.channels, OIIO::TypeDesc::FLOAT, raw.data())) {
    throw InputError(entry.where + ": image: cannot decode " + entry.image.string() + ": " +
                     in->geterror());
  }
  const std::size_t pixels = std::size_t(h.width) * h.height;
  const bool integer = is_integer_format(h.format);
  const std::vector<float>* table = linearizer.table(h.format);
  const int max_code = h.format.basetype == OIIO::TypeDesc::UINT8 ? 255 : 65535;
  cv::Mat rgb(h.height, h.width, CV_32FC3);
  cv::Mat saturated(h.height, h.width, CV_32FC3, cv::Scalar::all(0));
  auto* out = rgb.ptr<float>();
  auto* sat = saturated.ptr<float>();
  long long saturated_count = 0;
  for (std::size_t p = 0; p < pixels; ++p) {
    const bool inside = job.mask.empty() || job.mask[p] > 0;
    for (int c = 0; c < 3; ++c) {
      // Grey files feed all three channels; alpha and extra channels are ignored.
      const int source_channel = h.channels < 3 ? 0 : c;
      float v = raw[p * h.channels + source_channel];
      if (!std::isfinite(v)) {
        throw InputError(entry.where + ": image: " + entry.image.string() +
                         " has a non-finite value at pixel (" + std::to_string(p % h.width) + ", " +
                         std::to_string(p / h.width) + ")");
      }
      if (integer) {
        const int code = std::clamp(int(std::lround(v * max_code)), 0, max_code);
        if (code == max_code && inside) {
          sat[p * 3 + c] = 1.0f;
          ++saturated_count;
        }
        v = (*table)[code];
      }
      if (!inside || (options.zero_saturated && sat[p * 3 + c] > 0)) v = 0.0f;
      out[p * 3 + c] = std::max(v, 0.0f);
    }
  }
  if (field.width() != h.width || field.height() != h.height) {
    const cv::Size size(field.width(), field.height());
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
    rgb = small;
  }
  const float* values = rgb.ptr<float>();
  const Eigen::Vector3f inverse_intensity = entry.intensity_rgb.cwiseInverse();
  // An integer file clips at its largest code: after the transfer curve and the intensity that is
  // this light's ceiling. (A field pixel averaged from clipped and unclipped image pixels lies
  // below it and is not caught.) Float files carry no ceiling.
  if (integer) {
    field.lights()[light].saturates_at = (*table)[max_code] * inverse_intensity;
  }
  for (int y = 0; y < field.height(); ++y) {
    for (int x = 0; x < field.width(); ++x) {
      const float* v = values + (std::size_t(y) * field.width() + x) * 3;
      float* sample = field.pixel(x, y) + light * 3;
      for (int c = 0; c < 3; ++c) sample[c] = v[c] * inverse_intensity[c];
    }
  }
  return saturated_count;
}

}  // namespace

ReflectanceField import_images(OlatImageSet job, const OlatImportOptions& options,
                               OlatImportSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  if (const std::string error = options.validate(); !error.empty()) {
    throw InputError(job.source.string() + ": " + error);
  }
  if (job.lights.empty()) throw InputError(job.source.string() + ": no lights listed");
  ImageHeader first;
  {
    const auto in = open_image(job.lights[0].image, job.lights[0].where);
    first = header_of(*in);
  }
  if (!job.mask.empty() && (job.mask_width != first.width || job.mask_height != first.height)) {
    throw InputError(job.mask_name + ": size: expected " + size_text(first.width, first.height) +
                     " like the images, got " + size_text(job.mask_width, job.mask_height));
  }
  const auto [width, height] = target_size(first.width, first.height, options.max_size);
  const int n = int(job.lights.size());
  require_memory(ReflectanceField::bytes_for(width, height, n),
                 job.source.string() + ": reflectance field " + size_text(width, height) +
                     " with " + std::to_string(n) + " lights");
  std::vector<FieldLight> lights;
  for (int l = 0; l < n; ++l) lights.push_back({l, job.lights[l].dir_in_stage, true});
  ReflectanceField field(width, height, std::move(lights));
  field.source = job.source.string();

  const Linearizer linearizer(job.transfer, options.gamma);
  std::atomic<long long> saturated{0};
  std::atomic<int> done{0};
  std::mutex progress_mutex;
  tbb::parallel_for(0, n, [&](int l) {
    saturated += import_image(job, l, first, linearizer, options, field);
    const int finished = ++done;
    if (options.on_progress) {
      const std::lock_guard<std::mutex> lock(progress_mutex);
      options.on_progress(finished, n);
    }
  });

  if (summary) {
    OlatImportSummary& s = *summary;
    s = OlatImportSummary{};
    s.format = job.format;
    s.source = job.source;
    s.images = n;
    s.source_width = first.width;
    s.source_height = first.height;
    s.width = width;
    s.height = height;
    s.pixel_format = pixel_format_text(first);
    s.transfer_undone = is_integer_format(first.format) ? transfer_text(job.transfer, options.gamma)
                                                        : "none (float images are linear)";
    s.min_dir_z = 1.0;
    s.max_dir_z = -1.0;
    for (const OlatLight& e : job.lights) {
      s.min_dir_z = std::min(s.min_dir_z, e.dir_in_stage.z());
      s.max_dir_z = std::max(s.max_dir_z, e.dir_in_stage.z());
    }
    s.saturated_samples = saturated.load();
    const std::size_t inside = job.mask.empty()
                                   ? std::size_t(first.width) * first.height
                                   : std::size_t(std::count_if(job.mask.begin(), job.mask.end(),
                                                               [](float m) { return m > 0; }));
    s.masked_out_pixels = int(std::size_t(first.width) * first.height - inside);
    s.saturated_fraction = inside > 0 ? double(s.saturated_samples) / (double(inside) * 3 * n) : 0;
    s.intensities_divided = job.format == OlatFormat::kDiligent;
    s.notes = std::move(job.notes);
    if (s.saturated_samples > 0) {
      s.notes.push_back(
          std::to_string(s.saturated_samples) + " samples at the maximum code (saturated): " +
          (options.zero_saturated ? "set to 0, so the normals and fits leave them out as shadowed"
                                  : "kept as lower bounds, which the normals and fits leave out "
                                    "as censored (FieldLight::saturates_at)"));
    }
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return field;
}

void read_mask(const fs::path& mask_file, OlatImageSet& job) {
  const auto in = open_image(mask_file, mask_file.string());
  const ImageHeader h = header_of(*in);
  std::vector<float> raw(std::size_t(h.width) * h.height * h.channels);
  if (!in->read_image(0, 0, 0, h.channels, OIIO::TypeDesc::FLOAT, raw.data())) {
    throw InputError(mask_file.string() + ": cannot decode: " + in->geterror());
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
