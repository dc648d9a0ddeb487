#include "capture/olat_import.h"

#include <OpenImageIO/imageio.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "lightstage/errors.h"

namespace ls::capture {
namespace {

namespace fs = std::filesystem;

// One light of an OLAT set, as its files describe it.
struct LightEntry {
  fs::path image;
  Eigen::Vector3d dir_in_stage{0, 0, 1};
  Eigen::Vector3f intensity_rgb{1, 1, 1};  // Divided out of the pixel values.
  std::string where;                       // "FILE:LINE" of the line that names the image.
};

struct ImportJob {
  OlatFormat format = OlatFormat::kRtiLp;
  fs::path source;
  std::vector<LightEntry> lights;
  TransferCurve transfer = TransferCurve::kSrgb;
  std::vector<float> mask;  // Empty, or 1/0 per pixel at the images' size (1 = object).
  int mask_width = 0, mask_height = 0;
  std::string mask_name;
  std::vector<std::string> notes;
};

// A text file split into lines (CR stripped), numbered from 1.
struct TextLine {
  int number = 0;
  std::string text;
};

std::vector<TextLine> read_lines(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot open file");
  std::vector<TextLine> lines;
  std::string text;
  for (int number = 1; std::getline(in, text); ++number) {
    if (!text.empty() && text.back() == '\r') text.pop_back();
    lines.push_back({number, text});
  }
  return lines;
}

bool is_blank(const std::string& text) {
  return std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isspace(c); });
}

struct Token {
  std::string_view text;
  std::size_t begin = 0;  // Offset in the line.
};

std::vector<Token> tokenize(const std::string& line) {
  std::vector<Token> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const std::size_t begin = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > begin) tokens.push_back({std::string_view(line).substr(begin, i - begin), begin});
  }
  return tokens;
}

std::optional<double> parse_number(std::string_view text) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  double value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return value;
}

std::string vector_text(const Eigen::Vector3d& v) {
  char text[96];
  std::snprintf(text, sizeof(text), "(%g, %g, %g)", v.x(), v.y(), v.z());
  return text;
}

std::string where(const fs::path& file, int line) {
  return file.string() + ":" + std::to_string(line);
}

// Three numbers from tokens [first, first + 3); InputError naming file, line and field otherwise.
Eigen::Vector3d parse_triple(const std::vector<Token>& tokens, std::size_t first,
                             const std::string& at, const std::string& field) {
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) {
    const std::optional<double> value = parse_number(tokens[first + i].text);
    if (!value) {
      throw InputError(at + ": " + field + ": expected a number, got '" +
                       std::string(tokens[first + i].text) + "'");
    }
    v[i] = *value;
  }
  return v;
}

// Unit direction toward the light; rejects NaN, infinite and zero vectors.
Eigen::Vector3d unit_direction(const Eigen::Vector3d& v, const std::string& at) {
  if (!v.allFinite() || v.norm() < 1e-9) {
    throw InputError(at + ": light direction: expected a finite non-zero vector x y z, got " +
                     vector_text(v));
  }
  return v.normalized();
}

// Notes when directions were not unit length (they are normalised either way).
void note_direction_norms(const std::vector<double>& norms, const std::string& file,
                          std::vector<std::string>* notes) {
  if (norms.empty()) return;
  const auto [lo, hi] = std::minmax_element(norms.begin(), norms.end());
  if (*hi - 1.0 > 1e-3 || 1.0 - *lo > 1e-3) {
    char text[160];
    std::snprintf(text, sizeof(text), "light directions had norms %.4g..%.4g; normalised", *lo,
                  *hi);
    notes->push_back(file + ": " + text);
  }
}

// Finds a listed image: as written; with Windows backslashes as '/'; else by its file name in the
// list's folder or below (RTI sets are often moved from the capturing machine, absolute paths and
// all). Counts what it had to do, for one note per set rather than one per line.
class ImageFinder {
 public:
  explicit ImageFinder(fs::path folder) : folder_(std::move(folder)) {}

  fs::path find(const std::string& written, const std::string& at) {
    const fs::path direct = resolve(written);
    if (fs::is_regular_file(direct)) return direct;
    std::string slashes = written;
    std::replace(slashes.begin(), slashes.end(), '\\', '/');
    if (slashes != written) {
      const fs::path converted = resolve(slashes);
      if (fs::is_regular_file(converted)) {
        ++converted_backslashes_;
        return converted;
      }
    }
    const std::string name = fs::path(slashes).filename().string();
    const auto& index = name_index();
    const auto range = index.equal_range(name);
    const long matches = std::distance(range.first, range.second);
    if (matches == 0) {
      throw InputError(at + ": image: '" + written + "' not found (nor a file named '" + name +
                       "' in " + folder_.string() + " or its subfolders)");
    }
    if (matches > 1) {
      throw InputError(at + ": image: '" + written + "' not found, and its file name '" + name +
                       "' is ambiguous: " + range.first->second.string() + " and " +
                       std::next(range.first)->second.string());
    }
    if (found_by_name_++ == 0)
      first_by_name_ = "'" + written + "' -> " + range.first->second.string();
    return range.first->second;
  }

  void add_notes(const std::string& file, std::vector<std::string>* notes) const {
    if (converted_backslashes_ > 0) {
      notes->push_back(file + ": " + std::to_string(converted_backslashes_) +
                       " image paths had Windows backslashes; read them as '/'");
    }
    if (found_by_name_ > 0) {
      notes->push_back(file + ": " + std::to_string(found_by_name_) +
                       " image paths did not exist as written; used the file of the same name in " +
                       folder_.string() + " or its subfolders (e.g. " + first_by_name_ + ")");
    }
  }

 private:
  fs::path resolve(const std::string& written) const {
    const fs::path p(written);
    return p.is_absolute() ? p : folder_ / p;
  }

  const std::multimap<std::string, fs::path>& name_index() {
    if (!indexed_) {
      std::error_code ec;
      for (fs::recursive_directory_iterator it(folder_, ec), end; !ec && it != end;
           it.increment(ec)) {
        if (it->is_regular_file(ec)) index_.emplace(it->path().filename().string(), it->path());
      }
      indexed_ = true;
    }
    return index_;
  }

  fs::path folder_;
  bool indexed_ = false;
  std::multimap<std::string, fs::path> index_;
  int converted_backslashes_ = 0;
  int found_by_name_ = 0;
  std::string first_by_name_;
};

// --- Pixels
// ---------------------------------------------------------------------------------------

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
long long import_image(const ImportJob& job, int light, const ImageHeader& first,
                       const Linearizer& linearizer, const OlatImportOptions& options,
                       ReflectanceField& field) {
  const LightEntry& entry = job.lights[light];
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

ReflectanceField import_job(ImportJob job, const OlatImportOptions& options,
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
    for (const LightEntry& e : job.lights) {
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
                                  : "kept as lower bounds (the fits cannot mark them; see "
                                    "capture/olat_import.h)"));
    }
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return field;
}

bool has_extension(const fs::path& path, const std::string& lower_extension) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return ext == lower_extension;
}

// The folder's only .lp file.
fs::path lp_in_folder(const fs::path& folder) {
  std::vector<fs::path> found;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    if (entry.is_regular_file() && has_extension(entry.path(), ".lp"))
      found.push_back(entry.path());
  }
  if (found.size() != 1) {
    throw InputError(folder.string() + ": expected exactly one .lp file in the folder, found " +
                     std::to_string(found.size()));
  }
  return found[0];
}

std::vector<TextLine> non_blank(const std::vector<TextLine>& lines) {
  std::vector<TextLine> out;
  for (const TextLine& line : lines) {
    if (!is_blank(line.text)) out.push_back(line);
  }
  return out;
}

}  // namespace

const char* to_string(OlatFormat format) {
  return format == OlatFormat::kDiligent ? "DiLiGenT folder" : "RTI .lp file";
}

std::string OlatImportOptions::validate() const {
  if (!(gamma > 0 && gamma <= 10)) {
    return "gamma: expected a number in (0, 10], got " + std::to_string(gamma);
  }
  if (max_size < 0)
    return "max_size: expected 0 (keep) or a positive size, got " + std::to_string(max_size);
  return "";
}

OlatFormat detect_olat_format(const fs::path& source) {
  if (!fs::exists(source)) throw InputError(source.string() + ": not found");
  if (fs::is_directory(source)) {
    if (fs::is_regular_file(source / "filenames.txt") &&
        fs::is_regular_file(source / "light_directions.txt")) {
      return OlatFormat::kDiligent;
    }
    lp_in_folder(source);  // Throws unless there is exactly one.
    return OlatFormat::kRtiLp;
  }
  if (has_extension(source, ".lp")) return OlatFormat::kRtiLp;
  throw InputError(source.string() +
                   ": expected an .lp file, a folder with one, or a DiLiGenT folder "
                   "(filenames.txt, light_directions.txt, light_intensities.txt, mask.png)");
}

ReflectanceField import_rti_lp(const fs::path& lp_path, const OlatImportOptions& options,
                               OlatImportSummary* summary) {
  if (!fs::exists(lp_path)) throw InputError(lp_path.string() + ": not found");
  const fs::path lp_file = fs::is_directory(lp_path) ? lp_in_folder(lp_path) : lp_path;
  const std::string name = lp_file.string();
  const std::vector<TextLine> lines = non_blank(read_lines(lp_file));
  if (lines.empty())
    throw InputError(name + ": count: expected the number of lights, got an empty file");

  const std::vector<Token> count_tokens = tokenize(lines[0].text);
  const std::optional<double> count_value =
      count_tokens.size() == 1 ? parse_number(count_tokens[0].text) : std::nullopt;
  if (!count_value || *count_value < 1 || *count_value != std::floor(*count_value) ||
      *count_value > 1e6) {
    throw InputError(where(lp_file, lines[0].number) +
                     ": count: expected the number of lights (a positive integer), got '" +
                     lines[0].text + "'");
  }
  const int count = int(*count_value);
  const int listed = int(lines.size()) - 1;
  if (listed > count) {
    throw InputError(where(lp_file, lines[count + 1].number) + ": count: line " +
                     std::to_string(lines[0].number) + " says " + std::to_string(count) +
                     " lights, but the file lists " + std::to_string(listed));
  }
  if (listed < count) {
    throw InputError(where(lp_file, lines[0].number) + ": count: says " + std::to_string(count) +
                     " lights, but the file lists only " + std::to_string(listed));
  }

  ImportJob job;
  job.format = OlatFormat::kRtiLp;
  job.source = lp_file;
  job.transfer = options.transfer.value_or(TransferCurve::kSrgb);
  ImageFinder finder(lp_file.parent_path());
  std::vector<double> norms;
  for (int i = 1; i <= count; ++i) {
    const TextLine& line = lines[i];
    const std::string at = where(lp_file, line.number);
    const std::vector<Token> tokens = tokenize(line.text);
    if (tokens.size() < 4) {
      throw InputError(at + ": light: expected 'image x y z', got '" + line.text + "'");
    }
    const std::size_t first_number = tokens.size() - 3;
    const Eigen::Vector3d raw = parse_triple(tokens, first_number, at, "light direction");
    // The image path is everything before the numbers (it may contain spaces).
    std::string written = line.text.substr(0, tokens[first_number].begin);
    written.erase(written.find_last_not_of(" \t") + 1);
    written.erase(0, written.find_first_not_of(" \t"));
    LightEntry entry;
    entry.where = at;
    // .lp: x right, y up in the image, z toward the camera = stage +X, +Y, +Z (identity).
    entry.dir_in_stage = unit_direction(raw, at);
    entry.image = finder.find(written, at);
    norms.push_back(raw.norm());
    job.lights.push_back(std::move(entry));
  }
  finder.add_notes(name, &job.notes);
  note_direction_norms(norms, name, &job.notes);
  return import_job(std::move(job), options, summary);
}

ReflectanceField import_diligent(const fs::path& folder, const OlatImportOptions& options,
                                 OlatImportSummary* summary) {
  if (!fs::is_directory(folder)) throw InputError(folder.string() + ": not a folder");
  const fs::path names_file = folder / "filenames.txt";
  const fs::path dirs_file = folder / "light_directions.txt";
  const fs::path intensities_file = folder / "light_intensities.txt";
  const fs::path mask_file = folder / "mask.png";
  for (const fs::path& required : {names_file, dirs_file}) {
    if (!fs::is_regular_file(required)) throw InputError(required.string() + ": not found");
  }
  const std::vector<TextLine> names = non_blank(read_lines(names_file));
  const std::vector<TextLine> dirs = non_blank(read_lines(dirs_file));
  if (names.empty()) throw InputError(names_file.string() + ": expected one image name per line");
  const int n = int(names.size());
  auto check_count = [&](const fs::path& file, const std::vector<TextLine>& lines) {
    if (int(lines.size()) != n) {
      throw InputError(file.string() + ": count: expected " + std::to_string(n) +
                       " lines like filenames.txt, got " + std::to_string(lines.size()));
    }
  };
  check_count(dirs_file, dirs);

  ImportJob job;
  job.format = OlatFormat::kDiligent;
  job.source = folder;
  job.transfer = options.transfer.value_or(TransferCurve::kLinear);
  std::vector<double> norms;
  for (int i = 0; i < n; ++i) {
    LightEntry entry;
    entry.where = where(names_file, names[i].number);
    std::string image = names[i].text;
    image.erase(image.find_last_not_of(" \t") + 1);
    image.erase(0, image.find_first_not_of(" \t"));
    entry.image = folder / image;
    if (!fs::is_regular_file(entry.image)) {
      throw InputError(entry.where + ": image: '" + image + "' not found in " + folder.string());
    }
    const std::string at = where(dirs_file, dirs[i].number);
    const std::vector<Token> tokens = tokenize(dirs[i].text);
    if (tokens.size() != 3) {
      throw InputError(at + ": light direction: expected 3 numbers x y z, got " +
                       std::to_string(tokens.size()));
    }
    const Eigen::Vector3d raw = parse_triple(tokens, 0, at, "light direction");
    // DiLiGenT: x right, y up in the image, z toward the camera = stage +X, +Y, +Z (identity).
    entry.dir_in_stage = unit_direction(raw, at);
    norms.push_back(raw.norm());
    job.lights.push_back(std::move(entry));
  }
  note_direction_norms(norms, dirs_file.string(), &job.notes);

  // Intensities: one RGB per light (DiLiGenT calibrated each LED's brightness and colour); the
  // images are divided by them per channel so every light counts as unit irradiance.
  if (fs::is_regular_file(intensities_file)) {
    const std::vector<TextLine> intensities = non_blank(read_lines(intensities_file));
    check_count(intensities_file, intensities);
    for (int i = 0; i < n; ++i) {
      const std::string at = where(intensities_file, intensities[i].number);
      const std::vector<Token> tokens = tokenize(intensities[i].text);
      if (tokens.size() != 3) {
        throw InputError(at + ": light intensity: expected 3 numbers r g b, got " +
                         std::to_string(tokens.size()));
      }
      const Eigen::Vector3d rgb = parse_triple(tokens, 0, at, "light intensity");
      if (!rgb.allFinite() || rgb.minCoeff() <= 0) {
        throw InputError(at + ": light intensity: expected three positive numbers r g b, got " +
                         vector_text(rgb));
      }
      job.lights[i].intensity_rgb = rgb.cast<float>();
    }
  } else {
    job.notes.push_back(intensities_file.string() +
                        ": not found; every light taken as intensity 1");
  }

  // Mask: non-zero = object (DiLiGenT's mask.png is 0 / 255). Pixels outside get zero samples,
  // which the normals flag as kAllShadowed and the fits skip.
  if (fs::is_regular_file(mask_file)) {
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
  } else {
    job.notes.push_back(mask_file.string() + ": not found; every pixel used");
  }
  return import_job(std::move(job), options, summary);
}

ReflectanceField import_olat(const fs::path& source, const OlatImportOptions& options,
                             OlatImportSummary* summary) {
  return detect_olat_format(source) == OlatFormat::kDiligent
             ? import_diligent(source, options, summary)
             : import_rti_lp(source, options, summary);
}

}  // namespace ls::capture
