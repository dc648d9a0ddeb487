#include "relight/compact/rti_io.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

#include "lightstage/errors.h"
#include "lightstage/image.h"

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
  for (line = header.line("type"); !line.empty() && line[0] == '#'; line = header.line("type")) {
    constexpr char kGain[] = "#lightstage field_gain ";
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

RtiFile quantise(const RtiField& field, double gain) {
  if (!(gain > 0)) gain = field.max_sample_value > 0 ? 1.0 / field.max_sample_value : 1.0;
  RtiFile file;
  file.width = field.width();
  file.height = field.height();
  file.terms = field.num_terms();
  const size_t pixels = size_t(file.width) * file.height;
  const int terms = file.terms;
  const auto& coefs = field.coefficients();
  if (field.basis() == RtiBasis::kPtm) {
    file.format = field.lrgb() ? RtiFileFormat::kPtmLrgb : RtiFileFormat::kPtmRgb;
    // Coefficients in 8-bit code units; LRGB moves each pixel's colour magnitude into L.
    const int per_pixel = field.lrgb() ? 6 : 18;
    std::vector<double> code(pixels * per_pixel);
    std::vector<uint8_t> color_bytes(field.lrgb() ? pixels * 3 : 0);
    for (size_t p = 0; p < pixels; ++p) {
      if (!field.lrgb()) {
        for (int k = 0; k < 18; ++k) code[p * 18 + k] = coefs[p * 18 + k] * gain * 255.0;
        continue;
      }
      const float* color = field.colors().data() + p * 3;
      const double m = std::max({color[0], color[1], color[2], 0.0f});
      for (int c = 0; c < 3; ++c)
        color_bytes[p * 3 + c] = m > 0 ? quantise_byte(255.0 * color[c] / m) : 0;
      for (int j = 0; j < 6; ++j) code[p * 6 + j] = coefs[p * 6 + j] * m * gain * 255.0;
    }
    file.scale.assign(6, 1.0f);
    file.bias.assign(6, 0.0f);
    for (int j = 0; j < 6; ++j) {
      double lo = 0, hi = 0;
      for (size_t i = j; i < code.size(); i += 6) {
        lo = std::min(lo, code[i]);
        hi = std::max(hi, code[i]);
      }
      if (hi > lo) file.scale[j] = float((hi - lo) / 255.0);
      file.bias[j] = float(std::round(-lo / file.scale[j]));
    }
    file.data.resize(pixels * file.bytes_per_pixel());
    for (size_t p = 0; p < pixels; ++p) {
      uint8_t* out = file.data.data() + p * file.bytes_per_pixel();
      for (int k = 0; k < per_pixel; ++k) {
        const int j = k % 6;
        out[k] = quantise_byte(code[p * per_pixel + k] / file.scale[j] + file.bias[j]);
      }
      if (field.lrgb()) std::copy_n(color_bytes.data() + p * 3, 3, out + 6);
    }
    file.field_gain = gain;  // Informational: encode_rti_file cannot store it in a .ptm.
    return file;
  }
  file.format = RtiFileFormat::kHsh;
  file.scale.assign(terms, 1.0f);
  file.bias.assign(terms, 0.0f);
  for (int j = 0; j < terms; ++j) {
    double lo = HUGE_VAL, hi = -HUGE_VAL;
    for (size_t p = 0; p < pixels; ++p) {
      for (int c = 0; c < 3; ++c) {
        const double v = coefs[p * 3 * terms + c * terms + j] * gain;
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
    }
    if (!(lo <= hi)) lo = hi = 0;
    file.bias[j] = float(lo);
    file.scale[j] = hi > lo ? float(hi - lo) : 1.0f;
  }
  file.data.resize(pixels * 3 * terms);
  for (size_t p = 0; p < pixels; ++p) {
    for (int k = 0; k < 3 * terms; ++k) {
      const int j = k % terms;
      const double v = coefs[p * 3 * terms + k] * gain;
      file.data[p * 3 * terms + k] = quantise_byte((v - file.bias[j]) / file.scale[j] * 255.0);
    }
  }
  file.field_gain = gain;
  return file;
}

RtiField dequantise(const RtiFile& file) {
  const size_t pixels = size_t(file.width) * file.height;
  const double g =
      file.format == RtiFileFormat::kHsh && file.field_gain > 0 ? file.field_gain : 1.0;
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
    return RtiField(basis, false, file.width, file.height, std::move(coefs));
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
  return RtiField(RtiBasis::kPtm, lrgb, file.width, file.height, std::move(coefs),
                  std::move(colors));
}

std::string encode_rti_file(const RtiFile& file) {
  const int w = file.width, h = file.height;
  LS_CHECK(file.data.size() == size_t(w) * h * file.bytes_per_pixel(), "RtiFile data size");
  std::string out;
  if (file.format == RtiFileFormat::kHsh) {
    out += "#HSH1.2\n";
    if (file.field_gain > 0) out += "#lightstage field_gain " + shortest(file.field_gain) + "\n";
    out += "3\n" + std::to_string(w) + " " + std::to_string(h) + " 3\n" +
           std::to_string(file.terms) + " 2 1\n";
    out.append(reinterpret_cast<const char*>(file.scale.data()), 4 * file.terms);
    out.append(reinterpret_cast<const char*>(file.bias.data()), 4 * file.terms);
    // Rows top to bottom (unlike .ptm): the order RTIViewer's and relight's HSH loaders read.
    out.append(reinterpret_cast<const char*>(file.data.data()), file.data.size());
    return out;
  }
  const bool lrgb = file.format == RtiFileFormat::kPtmLrgb;
  out += std::string("PTM_1.2\n") + (lrgb ? "PTM_FORMAT_LRGB\n" : "PTM_FORMAT_RGB\n") +
         std::to_string(w) + "\n" + std::to_string(h) + "\n";
  for (int j = 0; j < 6; ++j) out += shortest(file.scale[j]) + (j < 5 ? " " : "\n");
  for (int j = 0; j < 6; ++j) out += std::to_string(int(file.bias[j])) + (j < 5 ? " " : "\n");
  if (!lrgb) {
    for (int c = 0; c < 3; ++c) {
      for (int r = h - 1; r >= 0; --r) {
        for (int x = 0; x < w; ++x) {
          out.append(
              reinterpret_cast<const char*>(file.data.data()) + (size_t(r) * w + x) * 18 + c * 6,
              6);
        }
      }
    }
  } else {
    for (int part = 0; part < 2; ++part) {
      for (int r = h - 1; r >= 0; --r) {
        for (int x = 0; x < w; ++x) {
          out.append(reinterpret_cast<const char*>(file.data.data()) + (size_t(r) * w + x) * 9 +
                         (part == 0 ? 0 : 6),
                     part == 0 ? 6 : 3);
        }
      }
    }
  }
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

}  // namespace ls::relight
