#include "capture/olat_import.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>

#include "capture/olat_images.h"
#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "lightstage/raw_photo.h"

namespace ls::capture {
namespace {

namespace fs = std::filesystem;

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
  const std::optional<Eigen::Vector3d> unit = unit_vector(v);
  if (!unit) {
    throw InputError(at + ": light direction: expected a finite non-zero vector x y z, got " +
                     vector_text(v));
  }
  return *unit;
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

// Whether `path` is a file; false, not a throw, where the system cannot say (a name longer than
// the file system allows, as a listed image's can be).
bool is_file(const fs::path& path) {
  std::error_code error;
  return fs::is_regular_file(path, error);
}

// Finds a listed image: as written; with Windows backslashes as '/'; else by its file name in the
// list's folder or below (RTI sets are often moved from the capturing machine, absolute paths and
// all). Counts what it had to do, for one note per set rather than one per line.
class ImageFinder {
 public:
  explicit ImageFinder(fs::path folder) : folder_(std::move(folder)) {}

  fs::path find(const std::string& written, const std::string& at) {
    fs::path direct = resolve(written);
    if (is_file(direct)) return direct;
    std::string slashes = written;
    std::replace(slashes.begin(), slashes.end(), '\\', '/');
    if (slashes != written) {
      fs::path converted = resolve(slashes);
      if (is_file(converted)) {
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
                     std::to_string(found.size()) +
                     " (or a DiLiGenT folder: filenames.txt and light_directions.txt)");
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

TransferCurve default_transfer(OlatFormat format) {
  return format == OlatFormat::kDiligent ? TransferCurve::kLinear : TransferCurve::kSrgb;
}

const char* to_string(TransferCurve curve) {
  switch (curve) {
    case TransferCurve::kSrgb:
      return "srgb";
    case TransferCurve::kGamma:
      return "gamma";
    case TransferCurve::kLinear:
      return "linear";
  }
  return "?";
}

std::string OlatImportOptions::validate() const {
  if (!(gamma > 0 && gamma <= 10)) {
    return "gamma: expected a number in (0, 10], got " + std::to_string(gamma);
  }
  if (max_size < 0)
    return "max_size: expected 0 (keep) or a positive size, got " + std::to_string(max_size);
  if (!std::isfinite(scene_time_s)) return "scene_time_s: expected a finite number of seconds";
  if (!stage_file.empty() && !spheres.outlines.empty()) {
    return "stage_file and spheres: expected one source of the lights' places, got both";
  }
  return "";
}

OlatFormat detect_olat_format(const fs::path& source) {
  if (!fs::exists(source)) throw InputError(source.string() + ": not found");
  if (fs::is_directory(source)) {
    const bool names = is_file(source / "filenames.txt");
    const bool dirs = is_file(source / "light_directions.txt");
    if (names && dirs) return OlatFormat::kDiligent;
    if (names || dirs) {  // Half a DiLiGenT folder: say what the other half is.
      throw InputError(source.string() + ": a DiLiGenT folder needs " +
                       (names ? "light_directions.txt" : "filenames.txt") + " beside its " +
                       (names ? "filenames.txt" : "light_directions.txt") +
                       " (one line per image)");
    }
    lp_in_folder(source);  // Throws unless there is exactly one.
    return OlatFormat::kRtiLp;
  }
  if (has_extension(source, ".lp")) return OlatFormat::kRtiLp;
  throw InputError(source.string() +
                   ": expected an .lp file, a folder with one, or a DiLiGenT folder "
                   "(filenames.txt, light_directions.txt, light_intensities.txt, mask.png)");
}

namespace {

OlatImageSet read_rti_lp_set(const fs::path& lp_path, const OlatImportOptions& options) {
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
                     printable(lines[0].text) + "'");
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

  OlatImageSet job;
  job.format = OlatFormat::kRtiLp;
  job.source = lp_file;
  job.transfer = options.transfer.value_or(default_transfer(job.format));
  ImageFinder finder(lp_file.parent_path());
  std::vector<double> norms;
  // One light per image and per direction: a repeated one is a copying slip that would weigh one
  // light twice (or give one image two directions).
  std::map<fs::path, std::string> image_lines;
  std::map<std::array<long long, 3>, std::string> direction_lines;
  for (int i = 1; i <= count; ++i) {
    const TextLine& line = lines[i];
    const std::string at = where(lp_file, line.number);
    const std::vector<Token> tokens = tokenize(line.text);
    if (tokens.size() < 4) {
      throw InputError(at + ": light: expected 'image x y z', got '" + printable(line.text) + "'");
    }
    const std::size_t first_number = tokens.size() - 3;
    const Eigen::Vector3d raw = parse_triple(tokens, first_number, at, "light direction");
    // The image path is everything before the numbers (it may contain spaces).
    std::string written = line.text.substr(0, tokens[first_number].begin);
    written.erase(written.find_last_not_of(" \t") + 1);
    written.erase(0, written.find_first_not_of(" \t"));
    OlatLight entry;
    entry.where = at;
    // .lp: x right, y up in the image, z toward the camera = stage +X, +Y, +Z (identity).
    entry.dir_in_stage = unit_direction(raw, at);
    if (entry.dir_in_stage.z() < 0) {
      throw InputError(at +
                       ": light direction: expected a light on the camera's side of the "
                       "object (z >= 0, toward the camera), got " +
                       vector_text(raw) + ", behind it");
    }
    entry.image = finder.find(written, at);
    if (const auto [it, added] = image_lines.emplace(entry.image, at); !added) {
      throw InputError(at + ": image: " + written + " is listed already, at " + it->second +
                       " (each image is one light's)");
    }
    std::array<long long, 3> key;
    for (int c = 0; c < 3; ++c) key[size_t(c)] = std::llround(entry.dir_in_stage(c) * 1e7);
    if (const auto [it, added] = direction_lines.emplace(key, at); !added) {
      throw InputError(at + ": light direction: " + vector_text(raw) +
                       " is the direction of the light at " + it->second +
                       " already (each light has a direction of its own)");
    }
    norms.push_back(raw.norm());
    job.lights.push_back(std::move(entry));
  }
  finder.add_notes(name, &job.notes);
  note_direction_norms(norms, name, &job.notes);
  // Camera raw files decode to linear sensor values (raw_photo.h): nothing to undo. A set that
  // mixes them with JPEGs would be undone by one curve for both.
  const auto raw_count =
      std::count_if(job.lights.begin(), job.lights.end(),
                    [](const OlatLight& l) { return is_raw_photo_name(l.image); });
  if (raw_count > 0 && raw_count < std::ptrdiff_t(job.lights.size())) {
    throw InputError(name + ": image: " + std::to_string(raw_count) + " of the " +
                     std::to_string(job.lights.size()) +
                     " images are camera raw files and the others are not: one set, one kind "
                     "(convert them alike)");
  }
  if (raw_count > 0 && !options.transfer) job.transfer = TransferCurve::kLinear;
  return job;
}

OlatImageSet read_diligent_set(const fs::path& folder, const OlatImportOptions& options) {
  if (!fs::is_directory(folder)) throw InputError(folder.string() + ": not a folder");
  const fs::path names_file = folder / "filenames.txt";
  const fs::path dirs_file = folder / "light_directions.txt";
  const fs::path intensities_file = folder / "light_intensities.txt";
  const fs::path mask_file = folder / "mask.png";
  for (const fs::path& required : {names_file, dirs_file}) {
    if (!is_file(required)) throw InputError(required.string() + ": not found");
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

  OlatImageSet job;
  job.format = OlatFormat::kDiligent;
  job.source = folder;
  job.transfer = options.transfer.value_or(default_transfer(job.format));
  std::vector<double> norms;
  for (int i = 0; i < n; ++i) {
    OlatLight entry;
    entry.where = where(names_file, names[i].number);
    std::string image = names[i].text;
    image.erase(image.find_last_not_of(" \t") + 1);
    image.erase(0, image.find_first_not_of(" \t"));
    entry.image = folder / image;
    if (!is_file(entry.image)) {
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
  if (is_file(intensities_file)) {
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
    job.warnings.push_back(intensities_file.string() +
                           ": not found; every light taken as intensity 1 (white, equal)");
  }

  // Mask: non-zero = object (DiLiGenT's mask.png is 0 / 255). Pixels outside get zero samples,
  // which the normals mark kNoSignal and the fits skip, counted apart from the flagged.
  if (is_file(mask_file)) {
    read_mask(mask_file, job);
  } else {
    job.notes.push_back(mask_file.string() + ": not found; every pixel used");
  }
  return job;
}

OlatImageSet read_set(const fs::path& source, const OlatImportOptions& options) {
  return detect_olat_format(source) == OlatFormat::kDiligent ? read_diligent_set(source, options)
                                                             : read_rti_lp_set(source, options);
}

}  // namespace

ReflectanceField import_rti_lp(const fs::path& lp_file, const OlatImportOptions& options,
                               OlatImportSummary* summary) {
  return import_images(read_rti_lp_set(lp_file, options), options, summary);
}

ReflectanceField import_diligent(const fs::path& folder, const OlatImportOptions& options,
                                 OlatImportSummary* summary) {
  return import_images(read_diligent_set(folder, options), options, summary);
}

ReflectanceField import_olat(const fs::path& source, const OlatImportOptions& options,
                             OlatImportSummary* summary) {
  return import_images(read_set(source, options), options, summary);
}

ReflectanceField olat_header(const fs::path& source, const OlatImportOptions& options) {
  return images_header(read_set(source, options), options);
}

std::unique_ptr<OlatBands> OlatBands::open(const fs::path& source,
                                           const OlatImportOptions& options) {
  return open_olat_bands(read_set(source, options), options);
}

std::uintmax_t olat_image_bytes(const fs::path& source) {
  std::uintmax_t bytes = 0;
  for (const OlatLight& light : read_set(source, {}).lights) bytes += fs::file_size(light.image);
  return bytes;
}

int import_olat_to_file(const fs::path& source, const OlatImportOptions& options,
                        const fs::path& out, const ExrAttributes& attributes,
                        const MemoryBudget& memory, const LightImageFn& on_light,
                        OlatImportSummary* summary, const RankSplit& split) {
  return import_images_to_file(read_set(source, options), options, out, attributes, memory,
                               on_light, summary, split);
}

}  // namespace ls::capture
