#include "relight/compact/rti_io.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <system_error>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/scratch_file.h"

namespace ls::relight {

namespace {

static_assert(sizeof(float) == 4, "float32 expected");

template <class T>
std::string shortest(T value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

uint8_t quantise_byte(double v) {
  if (!(v > 0)) return 0;  // Also NaN.
  return uint8_t(std::min(255.0, std::round(v)));
}

// Reads the text header line by line; the binary data starts right after the last line read.
class HeaderReader {
 public:
  HeaderReader(const std::string& bytes, std::string name)
      : bytes_(bytes), name_(std::move(name)) {}

  // The next line without its '\n' (and '\r'); InputError naming `field` at end of data.
  std::string line(const std::string& field) {
    const size_t end = bytes_.find('\n', pos_);
    if (end == std::string::npos || end - pos_ > 4096) {
      throw InputError(name_ + ": " + field + ": expected a header line, got " +
                       (end == std::string::npos ? "end of file" : "a line over 4096 bytes"));
    }
    std::string out = bytes_.substr(pos_, end - pos_);
    pos_ = end + 1;
    if (!out.empty() && out.back() == '\r') out.pop_back();
    return out;
  }
  // Whitespace-separated tokens of lines until `count` are read (a value may not span lines).
  std::vector<std::string> tokens(int count, const std::string& field) {
    std::vector<std::string> out;
    while (int(out.size()) < count) {
      std::istringstream in(line(field));
      std::string token;
      while (in >> token) out.push_back(token);
    }
    if (int(out.size()) != count) {
      throw InputError(name_ + ": " + field + ": expected " + std::to_string(count) +
                       " values, got " + std::to_string(out.size()));
    }
    return out;
  }
  size_t pos() const { return pos_; }
  void advance(size_t n) { pos_ += n; }
  size_t remaining() const { return bytes_.size() - pos_; }
  const std::string& name() const { return name_; }

 private:
  const std::string& bytes_;
  std::string name_;
  size_t pos_ = 0;
};

long long parse_int(const std::string& token, const std::string& name, const std::string& field,
                    long long lo, long long hi) {
  long long v = 0;
  const auto r = std::from_chars(token.data(), token.data() + token.size(), v);
  if (r.ec != std::errc() || r.ptr != token.data() + token.size() || v < lo || v > hi) {
    throw InputError(name + ": " + field + ": expected an integer in " + std::to_string(lo) + ".." +
                     std::to_string(hi) + ", got \"" + token + "\"");
  }
  return v;
}

float parse_float(const std::string& token, const std::string& name, const std::string& field) {
  float v = 0;
  const auto r = std::from_chars(token.data(), token.data() + token.size(), v);
  if (r.ec != std::errc() || r.ptr != token.data() + token.size() || !std::isfinite(v)) {
    throw InputError(name + ": " + field + ": expected a finite number, got \"" + token + "\"");
  }
  return v;
}

void check_data_size(const HeaderReader& header, size_t expected) {
  if (header.remaining() != expected) {
    throw InputError(header.name() + ": data: expected " + std::to_string(expected) +
                     " bytes after the header, got " + std::to_string(header.remaining()));
  }
}

RtiFile decode_ptm(const std::string& bytes, const std::string& name) {
  HeaderReader header(bytes, name);
  const std::string version = header.line("version");
  if (version != "PTM_1.2") {
    throw InputError(name + ": version: expected PTM_1.2, got \"" + version.substr(0, 40) + "\"");
  }
  RtiFile file;
  const std::string format = header.line("format");
  if (format == "PTM_FORMAT_RGB") {
    file.format = RtiFileFormat::kPtmRgb;
  } else if (format == "PTM_FORMAT_LRGB") {
    file.format = RtiFileFormat::kPtmLrgb;
  } else {
    throw InputError(name +
                     ": format: expected PTM_FORMAT_RGB or PTM_FORMAT_LRGB (uncompressed), "
                     "got \"" +
                     format.substr(0, 40) + "\"");
  }
  const auto size = header.tokens(2, "width and height");
  file.width = int(parse_int(size[0], name, "width", 1, 65536));
  file.height = int(parse_int(size[1], name, "height", 1, 65536));
  file.terms = 6;
  const auto scales = header.tokens(6, "scale");
  const auto biases = header.tokens(6, "bias");
  for (int j = 0; j < 6; ++j) {
    file.scale.push_back(parse_float(scales[j], name, "scale[" + std::to_string(j) + "]"));
    file.bias.push_back(
        float(parse_int(biases[j], name, "bias[" + std::to_string(j) + "]", -100000, 100000)));
  }
  const size_t pixels = size_t(file.width) * file.height;
  check_data_size(header, pixels * file.bytes_per_pixel());
  file.data.resize(pixels * file.bytes_per_pixel());
  const uint8_t* in = reinterpret_cast<const uint8_t*>(bytes.data()) + header.pos();
  const int w = file.width, h = file.height;
  if (file.format == RtiFileFormat::kPtmRgb) {
    for (int c = 0; c < 3; ++c) {
      for (int r = h - 1; r >= 0; --r) {
        for (int x = 0; x < w; ++x) {
          for (int j = 0; j < 6; ++j) file.data[(size_t(r) * w + x) * 18 + c * 6 + j] = *in++;
        }
      }
    }
  } else {
    for (int part = 0; part < 2; ++part) {
      const int first = part == 0 ? 0 : 6, count = part == 0 ? 6 : 3;
      for (int r = h - 1; r >= 0; --r) {
        for (int x = 0; x < w; ++x) {
          for (int j = 0; j < count; ++j) file.data[(size_t(r) * w + x) * 9 + first + j] = *in++;
        }
      }
    }
  }
  return file;
}

RtiFile decode_hsh(const std::string& bytes, const std::string& name) {
  HeaderReader header(bytes, name);
  RtiFile file;
  file.format = RtiFileFormat::kHsh;
  std::string line = header.line("version");
  if (line.rfind("#HSH1.2", 0) != 0) {
    throw InputError(name + ": version: expected #HSH1.2, got \"" + line.substr(0, 40) + "\"");
  }
  std::string encoding;  // Another builder's file is display-referred, as its viewers show it.
  for (line = header.line("type"); !line.empty() && line[0] == '#'; line = header.line("type")) {
    constexpr char kGain[] = "#lightstage field_gain ";
    constexpr char kEncoding[] = "#lightstage encoding ";
    if (line.rfind(kEncoding, 0) == 0) {
      encoding = line.substr(sizeof(kEncoding) - 1);
      if (encoding != "sRGB" && encoding != "linear") {
        throw InputError(name + ": encoding: expected sRGB or linear, got \"" +
                         encoding.substr(0, 40) + "\"");
      }
    }
    if (line.rfind(kGain, 0) == 0) {
      const std::string token = line.substr(sizeof(kGain) - 1);
      double g = 0;
      const auto r = std::from_chars(token.data(), token.data() + token.size(), g);
      if (r.ec != std::errc() || !(g > 0) || !std::isfinite(g)) {
        throw InputError(name + ": field_gain: expected a positive number, got \"" + token + "\"");
      }
      file.field_gain = g;
    }
  }
  // No encoding line: linear values if the file gives a gain (lightstage's older files), else sRGB.
  file.srgb = encoding.empty() ? !(file.field_gain > 0) : encoding == "sRGB";
  const std::string type = line;
  if (type != "3") {
    throw InputError(name + ": type: expected 3 (HSH), got \"" + type.substr(0, 40) + "\"");
  }
  const auto size = header.tokens(3, "width height bands");
  file.width = int(parse_int(size[0], name, "width", 1, 65536));
  file.height = int(parse_int(size[1], name, "height", 1, 65536));
  parse_int(size[2], name, "bands", 3, 3);
  const auto basis = header.tokens(3, "terms basis_type element_size");
  file.terms = int(parse_int(basis[0], name, "terms", 4, 16));
  if (file.terms != 4 && file.terms != 9 && file.terms != 16) {
    throw InputError(name + ": terms: expected 4, 9 or 16 (HSH orders 2..4), got " + basis[0]);
  }
  // RTIViewer's basis types: 2 is HSH, the one basis this reader evaluates.
  if (basis[1] != "2") {
    throw InputError(name + ": basis_type: expected 2 (HSH), got \"" + basis[1].substr(0, 40) +
                     "\"");
  }
  parse_int(basis[2], name, "element_size", 1, 1);
  if (header.remaining() < 8 * size_t(file.terms)) {
    throw InputError(name + ": scale and bias: expected " + std::to_string(8 * file.terms) +
                     " bytes, got " + std::to_string(header.remaining()));
  }
  file.scale.resize(file.terms);
  file.bias.resize(file.terms);
  std::memcpy(file.scale.data(), bytes.data() + header.pos(), 4 * file.terms);
  header.advance(4 * file.terms);
  std::memcpy(file.bias.data(), bytes.data() + header.pos(), 4 * file.terms);
  header.advance(4 * file.terms);
  for (int j = 0; j < file.terms; ++j) {
    if (!std::isfinite(file.scale[j]) || !std::isfinite(file.bias[j])) {
      throw InputError(name + ": scale[" + std::to_string(j) + "]/bias: expected finite floats");
    }
  }
  const size_t pixels = size_t(file.width) * file.height;
  check_data_size(header, pixels * file.bytes_per_pixel());
  const uint8_t* in = reinterpret_cast<const uint8_t*>(bytes.data()) + header.pos();
  file.data.resize(pixels * file.bytes_per_pixel());
  // Rows top to bottom, as RTIViewer's Hsh::loadData (row j at offset j * w) and relight read them.
  std::memcpy(file.data.data(), in, file.data.size());
  return file;
}

}  // namespace

RtiQuantiser::RtiQuantiser(RtiBasis basis, bool lrgb, int width, int height)
    : basis_(basis), lrgb_(lrgb), width_(width), height_(height), terms_(rti_num_terms(basis)) {
  lo_.assign(size_t(terms_), HUGE_VAL);
  hi_.assign(size_t(terms_), -HUGE_VAL);
}

double RtiQuantiser::lrgb_magnitude(const float* color) {
  return std::max({color[0], color[1], color[2], 0.0f});
}

void RtiQuantiser::add(const float* coefs, const float* colors, size_t pixels, float max_sample) {
  max_sample_ = std::max(max_sample_, max_sample);
  const int per_pixel = lrgb_ ? terms_ : 3 * terms_;
  for (size_t p = 0; p < pixels; ++p) {
    // LRGB moves each pixel's colour magnitude into L.
    const double m = lrgb_ ? lrgb_magnitude(colors + p * 3) : 1.0;
    for (int k = 0; k < per_pixel; ++k) {
      const int j = k % terms_;
      const double v = lrgb_ ? double(coefs[p * per_pixel + k]) * m : coefs[p * per_pixel + k];
      lo_[size_t(j)] = std::min(lo_[size_t(j)], v);
      hi_[size_t(j)] = std::max(hi_[size_t(j)], v);
    }
  }
}

double RtiQuantiser::code(double v, double gain) const {
  // In the files' units: PTM 8-bit codes, HSH white = 1. Monotone in v, so the extremes of the
  // codes are the codes of the extremes (add() keeps those of v).
  return basis_ == RtiBasis::kPtm ? v * gain * 255.0 : v * gain;
}

RtiFile RtiQuantiser::header(double gain, bool srgb) const {
  if (!(gain > 0)) gain = max_sample_ > 0 ? 1.0 / max_sample_ : 1.0;
  RtiFile file;
  file.width = width_;
  file.height = height_;
  file.terms = terms_;
  file.field_gain = gain;  // Informational for .ptm: encode_rti_file cannot store it there.
  file.srgb = srgb;
  if (srgb) gain = 1.0;  // The coefficients are display units already.
  file.scale.assign(size_t(terms_), 1.0f);
  file.bias.assign(size_t(terms_), 0.0f);
  if (basis_ == RtiBasis::kPtm) {
    file.format = lrgb_ ? RtiFileFormat::kPtmLrgb : RtiFileFormat::kPtmRgb;
    for (size_t j = 0; j < 6; ++j) {
      // [min(min_j, 0), max(max_j, 0)] onto an integer bias and 0..255.
      const double lo = std::min(0.0, lo_[j] <= hi_[j] ? code(lo_[j], gain) : 0.0);
      const double hi = std::max(0.0, lo_[j] <= hi_[j] ? code(hi_[j], gain) : 0.0);
      if (hi > lo) file.scale[j] = float((hi - lo) / 255.0);
      file.bias[j] = float(std::round(-lo / file.scale[j]));
    }
    return file;
  }
  file.format = RtiFileFormat::kHsh;
  for (size_t j = 0; j < size_t(terms_); ++j) {
    double lo = code(lo_[j], gain), hi = code(hi_[j], gain);
    if (!(lo <= hi)) lo = hi = 0;
    file.bias[j] = float(lo);
    file.scale[j] = hi > lo ? float(hi - lo) : 1.0f;
  }
  return file;
}

void RtiQuantiser::quantise(const RtiFile& header, const float* coefs, const float* colors,
                            size_t pixels, uint8_t* bytes) const {
  const double gain = header.srgb ? 1.0 : header.field_gain;
  const int per_pixel = lrgb_ ? terms_ : 3 * terms_;
  for (size_t p = 0; p < pixels; ++p) {
    uint8_t* out = bytes + p * size_t(header.bytes_per_pixel());
    const float* coef = coefs + p * per_pixel;
    if (basis_ != RtiBasis::kPtm) {
      for (int k = 0; k < per_pixel; ++k) {
        const int j = k % terms_;
        const double v = coef[k] * gain;
        out[k] = quantise_byte((v - header.bias[j]) / header.scale[j] * 255.0);
      }
      continue;
    }
    const float* color = lrgb_ ? colors + p * 3 : nullptr;
    const double m = lrgb_ ? lrgb_magnitude(color) : 1.0;
    for (int k = 0; k < per_pixel; ++k) {
      const int j = k % 6;
      const double v = lrgb_ ? double(coef[k]) * m : coef[k];
      out[k] = quantise_byte(code(v, gain) / header.scale[j] + header.bias[j]);
    }
    for (int c = 0; lrgb_ && c < 3; ++c) {
      out[6 + c] = m > 0 ? quantise_byte(255.0 * color[c] / m) : 0;
    }
  }
}

RtiFile quantise(const RtiField& field, double gain) {
  RtiQuantiser quantiser(field.basis(), field.lrgb(), field.width(), field.height());
  const size_t pixels = size_t(field.width()) * field.height();
  quantiser.add(field.coefficients().data(), field.colors().data(), pixels, field.max_sample_value);
  RtiFile file = field.display_gain() > 0 ? quantiser.header(field.display_gain(), true)
                                          : quantiser.header(gain);
  file.data.resize(pixels * size_t(file.bytes_per_pixel()));
  quantiser.quantise(file, field.coefficients().data(), field.colors().data(), pixels,
                     file.data.data());
  return file;
}

RtiField dequantise(const RtiFile& file) {
  const size_t pixels = size_t(file.width) * file.height;
  const double g = file.format == RtiFileFormat::kHsh && file.field_gain > 0 && !file.srgb
                       ? file.field_gain
                       : 1.0;
  const double display_gain = !file.srgb ? 0.0 : file.field_gain > 0 ? file.field_gain : 1.0;
  if (file.format == RtiFileFormat::kHsh) {
    const int terms = file.terms;
    std::vector<float> coefs(pixels * 3 * terms);
    for (size_t i = 0; i < coefs.size(); ++i) {
      const int j = int(i % terms);
      coefs[i] = float((file.data[i] / 255.0 * file.scale[j] + file.bias[j]) / g);
    }
    const RtiBasis basis = terms == 4   ? RtiBasis::kHsh2
                           : terms == 9 ? RtiBasis::kHsh3
                                        : RtiBasis::kHsh4;
    RtiField field(basis, false, file.width, file.height, std::move(coefs));
    field.set_display_gain(display_gain);
    return field;
  }
  const bool lrgb = file.format == RtiFileFormat::kPtmLrgb;
  const int per_pixel = lrgb ? 6 : 18;
  std::vector<float> coefs(pixels * per_pixel);
  std::vector<float> colors(lrgb ? pixels * 3 : 0);
  for (size_t p = 0; p < pixels; ++p) {
    const uint8_t* in = file.data.data() + p * file.bytes_per_pixel();
    for (int k = 0; k < per_pixel; ++k) {
      const int j = k % 6;
      coefs[p * per_pixel + k] = float((in[k] - file.bias[j]) * file.scale[j] / 255.0);
    }
    for (int c = 0; lrgb && c < 3; ++c) colors[p * 3 + c] = float(in[6 + c] / 255.0);
  }
  RtiField field(RtiBasis::kPtm, lrgb, file.width, file.height, std::move(coefs),
                 std::move(colors));
  field.set_display_gain(display_gain);
  return field;
}

void encode_rti_rows(const RtiFile& header, const RtiRowFn& row, const RtiBytesFn& write) {
  const int w = header.width, h = header.height;
  const auto text = [&](const std::string& t) { write(t.data(), t.size()); };
  std::vector<uint8_t> bytes(size_t(w) * header.bytes_per_pixel());
  if (header.format == RtiFileFormat::kHsh) {
    text("#HSH1.2\n");
    if (header.field_gain > 0) text("#lightstage field_gain " + shortest(header.field_gain) + "\n");
    text(std::string("#lightstage encoding ") + (header.srgb ? "sRGB" : "linear") + "\n");
    text("3\n" + std::to_string(w) + " " + std::to_string(h) + " 3\n" +
         std::to_string(header.terms) + " 2 1\n");
    write(header.scale.data(), 4 * size_t(header.terms));
    write(header.bias.data(), 4 * size_t(header.terms));
    // Rows top to bottom (unlike .ptm): the order RTIViewer's and relight's HSH loaders read.
    for (int r = 0; r < h; ++r) {
      row(r, bytes.data());
      write(bytes.data(), bytes.size());
    }
    return;
  }
  const bool lrgb = header.format == RtiFileFormat::kPtmLrgb;
  text(std::string("PTM_1.2\n") + (lrgb ? "PTM_FORMAT_LRGB\n" : "PTM_FORMAT_RGB\n") +
       std::to_string(w) + "\n" + std::to_string(h) + "\n");
  std::string line;
  for (int j = 0; j < 6; ++j) line += shortest(header.scale[j]) + (j < 5 ? " " : "\n");
  for (int j = 0; j < 6; ++j) line += std::to_string(int(header.bias[j])) + (j < 5 ? " " : "\n");
  text(line);
  // RGB: a block per colour of 6 coefficients a pixel; LRGB: the 6 luminance coefficients, then
  // the 3 colour bytes; each block rows bottom to top.
  const int per_pixel = header.bytes_per_pixel();
  std::vector<uint8_t> block(size_t(w) * 6);
  for (int part = 0; part < (lrgb ? 2 : 3); ++part) {
    const int first = lrgb ? (part == 0 ? 0 : 6) : part * 6;
    const int count = lrgb && part == 1 ? 3 : 6;
    for (int r = h - 1; r >= 0; --r) {
      row(r, bytes.data());
      for (int x = 0; x < w; ++x) {
        std::copy_n(bytes.data() + size_t(x) * per_pixel + first, count,
                    block.data() + size_t(x) * count);
      }
      write(block.data(), size_t(w) * count);
    }
  }
}

std::string encode_rti_file(const RtiFile& file) {
  LS_CHECK(file.data.size() == size_t(file.width) * file.height * file.bytes_per_pixel(),
           "RtiFile data size");
  const size_t row_bytes = size_t(file.width) * file.bytes_per_pixel();
  std::string out;
  encode_rti_rows(
      file,
      [&](int y, uint8_t* bytes) {
        std::copy_n(file.data.data() + size_t(y) * row_bytes, row_bytes, bytes);
      },
      [&](const void* data, size_t size) { out.append(static_cast<const char*>(data), size); });
  return out;
}

RtiFile decode_rti_file(const std::string& bytes, const std::string& name) {
  if (bytes.rfind("PTM_", 0) == 0) return decode_ptm(bytes, name);
  if (bytes.rfind("#HSH", 0) == 0) return decode_hsh(bytes, name);
  throw InputError(name + ": version: expected a PTM_1.2 or #HSH1.2 header, got \"" +
                   bytes.substr(0, std::min<size_t>(bytes.find('\n'), 20)) + "\"");
}

void write_rti_file(const std::filesystem::path& path, const RtiFile& file) {
  write_file_atomic(path, encode_rti_file(file));
}

RtiFile read_rti_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot open for reading");
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return decode_rti_file(bytes, path.string());
}

namespace {

// A band's record in kept_dir: the largest sample of its fit, exactly (shortest round trip).
std::filesystem::path band_record(const std::filesystem::path& kept_dir, int first_row) {
  return kept_dir / ("band_" + std::to_string(first_row));
}
bool read_band_record(const std::filesystem::path& file, float& max_sample) {
  std::ifstream in(file);
  std::string text;
  if (!(in >> text)) return false;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), max_sample);
  return error == std::errc() && end == text.data() + text.size();
}

}  // namespace

RtiWritten write_rti_file_in_bands(const std::filesystem::path& path,
                                   const capture::ReflectanceField& header,
                                   const capture::FieldBands& bands, const RtiFitOptions& options,
                                   double gain, const std::filesystem::path& kept_dir,
                                   const RankSplit& split) {
  const RtiFitter fitter(header, options);
  const int width = header.width();
  const size_t per_pixel = size_t(fitter.coefficients_per_pixel());
  const size_t colors = options.lrgb ? 3 : 0;  // Per pixel, after a row's coefficients.
  // Through a file: the image's coefficients are never held.
  const size_t row_floats = size_t(width) * (per_pixel + colors);
  ScratchFile spill(kept_dir / "coefficients.spill",
                    "the coefficients of a field compressed in bands are spilled beside the "
                    "output: they need its size free there",
                    ScratchFile::Lifetime::kKept);
  RtiQuantiser quantiser(options.basis, options.lrgb, width, header.height());
  std::vector<float> coefs, band_colors, rows;
  RtiWritten written;
  std::vector<std::pair<int, int>> others;  // Other ranks' bands: first row, rows.
  int index = 0;
  // A band read back (an earlier run's, or another rank's: `fit` false), else fitted.
  const auto take = [&](const capture::ReflectanceField& band, bool fit) {
    const size_t pixels = size_t(band.width()) * band.height();
    coefs.assign(pixels * per_pixel, 0.0f);
    band_colors.assign(pixels * colors, 0.0f);
    rows.resize(pixels * (per_pixel + colors));
    const size_t at = size_t(band.first_row()) * row_floats;
    float max_sample = 0;
    // Each row: its coefficients, then its colours.
    const auto row = [&](int y) { return rows.data() + size_t(y) * width * (per_pixel + colors); };
    if (read_band_record(band_record(kept_dir, band.first_row()), max_sample)) {
      spill.read(rows.data(), rows.size(), at);
      for (int y = 0; y < band.height(); ++y) {
        std::copy_n(row(y), width * per_pixel, coefs.data() + size_t(y) * width * per_pixel);
        std::copy_n(row(y) + width * per_pixel, width * colors,
                    band_colors.data() + size_t(y) * width * colors);
      }
      if (fit) written.resumed_rows += band.height();
    } else if (!fit) {  // Another rank's, which it did not leave.
      throw InputError(band_record(kept_dir, band.first_row()).string() +
                       ": the band's coefficients are missing (did its rank fail?)");
    } else {
      max_sample = fitter.fit_band(band, coefs.data(), band_colors.data());
      for (int y = 0; y < band.height(); ++y) {
        std::copy_n(coefs.data() + size_t(y) * width * per_pixel, width * per_pixel, row(y));
        std::copy_n(band_colors.data() + size_t(y) * width * colors, width * colors,
                    row(y) + width * per_pixel);
      }
      spill.write(rows.data(), rows.size(), at);
      spill.sync();  // The rows are there before their record says so.
      char text[32];
      const std::to_chars_result printed = std::to_chars(text, text + sizeof text, max_sample);
      write_file_atomic(band_record(kept_dir, band.first_row()), std::string(text, printed.ptr));
    }
    quantiser.add(coefs.data(), band_colors.data(), pixels, max_sample);
  };
  bands([&](const capture::ReflectanceField& band) {
    if (split.mine(index++)) {
      take(band, true);
    } else {
      others.emplace_back(band.first_row(), band.height());
    }
  });
  if (split.split()) {
    split.barrier();  // Every rank's bands are in the spill, with their records.
    if (split.rank != 0) return written;
    spill.reopen();  // Their rows as they wrote them (a file system shared between nodes).
    for (const auto& [first_row, band_rows] : others) {
      capture::ReflectanceField shell =
          capture::ReflectanceField::without_values(width, band_rows, header.lights());
      shell.set_band(first_row, header.height());
      take(shell, false);
    }
  }
  coefs = {}, band_colors = {}, rows = {};
  const RtiFile file =
      options.srgb_gain > 0 ? quantiser.header(options.srgb_gain, true) : quantiser.header(gain);
  std::vector<float> row(row_floats);
  AtomicFileWriter out(path);
  encode_rti_rows(
      file,
      [&](int y, uint8_t* bytes) {
        spill.read(row.data(), row_floats, size_t(y) * row_floats);
        quantiser.quantise(file, row.data(), row.data() + width * per_pixel, size_t(width), bytes);
      },
      [&](const void* data, size_t size) { out.write(data, size); });
  out.commit();
  const RtiField shape(options.basis, options.lrgb, 0, 0, {}, {});
  written.name = shape.name();
  written.lights_used = fitter.lights_used();
  written.bytes_per_pixel = shape.bytes_per_pixel();
  return written;
}

}  // namespace ls::relight
