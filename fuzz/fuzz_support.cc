#include "fuzz/fuzz_support.h"

#include <OpenImageIO/imageio.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>

namespace ls::fuzz {

namespace fs = std::filesystem;

namespace {

constexpr std::string_view kSeparator = "\n--\n";
constexpr int kMaxSide = 32;
constexpr int kMaxTile = 16;
constexpr int kMaxChannels = 96;
constexpr int kMaxOrigin = 64;
constexpr const char* kSceneTimeAttribute = "lightstage:scene_time_s";

void remove_work_dir() {
  std::error_code ignored;
  fs::remove_all(work_dir(), ignored);
}

// The integer at `token`, clamped to [lo, hi]; `fallback` when it is not one.
int clamped_int(const std::string& token, int lo, int hi, int fallback) {
  char* end = nullptr;
  const long value = std::strtol(token.c_str(), &end, 10);
  if (token.empty() || end == token.c_str()) return fallback;
  return int(std::clamp<long>(value, lo, hi));
}

std::vector<std::string> split_on(const std::string& text, char separator) {
  std::vector<std::string> out;
  std::string item;
  std::istringstream in(text);
  while (std::getline(in, item, separator)) out.push_back(item);
  return out;
}

std::vector<std::string> words(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string word; in >> word;) out.push_back(word);
  return out;
}

bool writable_attribute(const std::string& name) {
  return name.rfind("lightstage:", 0) == 0 || name == "compression";
}

// The header line of a description: size, tiling, pixel type, data window origin.
OIIO::ImageSpec spec_from(const std::string& header, int channels) {
  const std::vector<std::string> w = words(header);
  auto word = [&](size_t i) { return i < w.size() ? w[i] : std::string(); };
  const bool half = word(3) == "half";
  OIIO::ImageSpec spec(clamped_int(word(0), 1, kMaxSide, 1), clamped_int(word(1), 1, kMaxSide, 1),
                       channels, half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT);
  const int tile = clamped_int(word(2), 0, kMaxTile, 0);
  spec.tile_width = spec.tile_height = tile;
  spec.x = clamped_int(word(4), -kMaxOrigin, kMaxOrigin, 0);
  spec.y = clamped_int(word(5), -kMaxOrigin, kMaxOrigin, 0);
  spec.full_x = spec.x;
  spec.full_y = spec.y;
  return spec;
}

}  // namespace

const fs::path& work_dir() {
  static const fs::path dir = [] {
    const char* tmp = std::getenv("TMPDIR");
    fs::path path = fs::path(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") /
                    ("lightstage-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(path);
    OIIO::attribute("threads", 1);
    OIIO::attribute("exr_threads", 1);
    return path;
  }();
  static const int cleanup_registered = std::atexit(remove_work_dir);
  static const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  (void)cleanup_registered;
  return dir;
}

bool verbose() {
  static const bool on = std::getenv("LIGHTSTAGE_FUZZ_VERBOSE") != nullptr;
  return on;
}

fs::path write_file(const std::string& name, std::string_view bytes) {
  fs::path path = work_dir() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), std::streamsize(bytes.size()));
  return path;
}

std::vector<std::string> split_parts(std::string_view text) {
  std::vector<std::string> parts;
  for (;;) {
    const size_t at = text.find(kSeparator);
    parts.emplace_back(text.substr(0, at));
    if (at == std::string_view::npos) return parts;
    text.remove_prefix(at + kSeparator.size());
  }
}

std::string join_parts(const std::vector<std::string>& parts) {
  std::string out;
  for (size_t i = 0; i < parts.size(); ++i) {
    if (i > 0) out += kSeparator;
    out += parts[i];
  }
  return out;
}

bool write_described_exr(std::string_view description, const fs::path& path) {
  const std::vector<std::string> parts = split_parts(description);
  if (parts.size() < 2) return false;
  const std::vector<std::string> names = split_on(parts[1], ',');
  const std::set<std::string> distinct(names.begin(), names.end());
  if (names.empty() || int(names.size()) > kMaxChannels || distinct.size() != names.size() ||
      distinct.count("") > 0) {
    return false;
  }
  OIIO::ImageSpec spec = spec_from(parts[0], int(names.size()));
  spec.channelnames = names;
  for (size_t i = 3; i < parts.size(); ++i) {
    const size_t equals = parts[i].find('=');
    const std::string name = parts[i].substr(0, equals);
    if (equals == std::string::npos || !writable_attribute(name)) continue;
    const std::string value = parts[i].substr(equals + 1);
    char* end = nullptr;
    const double number = std::strtod(value.c_str(), &end);
    if (name == kSceneTimeAttribute && !value.empty() && *end == '\0') {
      spec.attribute(name, OIIO::TypeDesc::DOUBLE, &number);
    } else {
      spec.attribute(name, value);
    }
  }
  std::vector<float> values;
  for (const std::string& word : words(parts.size() > 2 ? parts[2] : "")) {
    values.push_back(std::strtof(word.c_str(), nullptr));
  }
  if (values.empty()) values.push_back(0.0f);
  std::vector<float> pixels(size_t(spec.width) * spec.height * spec.nchannels);
  for (size_t i = 0; i < pixels.size(); ++i) pixels[i] = values[i % values.size()];
  bool written = false;
  try {
    std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(path.string());
    written = out && out->open(path.string(), spec) &&
              out->write_image(OIIO::TypeDesc::FLOAT, pixels.data()) && out->close();
  } catch (const std::exception&) {  // OpenEXR's own refusals (e.g. a name ending in '.').
    written = false;
  }
  (void)OIIO::geterror();  // Clears the message of a refused description.
  return written;
}

std::string describe_exr(const fs::path& path) {
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path.string());
  if (!in) throw InputError(path.string() + ": cannot describe: " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  std::vector<std::string> parts;
  parts.push_back(std::to_string(spec.width) + " " + std::to_string(spec.height) + " " +
                  std::to_string(spec.tile_width) + " " +
                  (spec.format == OIIO::TypeDesc::HALF ? "half" : "float") + " " +
                  std::to_string(spec.x) + " " + std::to_string(spec.y));
  std::string names;
  for (const std::string& name : spec.channelnames) names += (names.empty() ? "" : ",") + name;
  parts.push_back(names);
  std::vector<float> pixels(size_t(spec.width) * spec.height * spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, pixels.data())) {
    throw InputError(path.string() + ": cannot describe: " + in->geterror());
  }
  std::string values;
  char number[32];
  for (const float v : pixels) {
    std::snprintf(number, sizeof number, "%.9g ", double(v));
    values += number;
  }
  parts.push_back(values);
  for (const OIIO::ParamValue& p : spec.extra_attribs) {
    const std::string name = p.name().string();
    if (!writable_attribute(name)) continue;
    parts.push_back(
        name + "=" +
        (p.type() == OIIO::TypeDesc::STRING ? p.get_string() : p.get_string(/*maxsize=*/1)));
  }
  return join_parts(parts);
}

}  // namespace ls::fuzz
