// PNG through libpng, read and written as OpenImageIO 2.4 did (files and tests were made through
// it): colour associated with alpha on reading and divided by it on writing, OIIO's rounding in
// every conversion, its chunks (oFFs, text, colour space) and its attribute names. libpng reports
// errors by longjmp: every call that can jump sits in a small function of its own (decode_*,
// encode_*) whose frame holds no C++ object, and callbacks keep to plain data.
#include <png.h>
#include <strings.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <type_traits>
#include <utility>

#include "lightstage/image_file.h"
#include "lightstage/image_file_png_samples.h"
#include "lightstage/text.h"

namespace ls::image_file {
namespace {

namespace fs = std::filesystem;

// What libpng's callbacks reach.
struct PngState {
  png_structp png = nullptr;
  png_infop info = nullptr;
  std::FILE* file = nullptr;                    // Reading.
  std::vector<unsigned char>* bytes = nullptr;  // Writing.
  std::string* warnings = nullptr;
  char message[256] = {};  // libpng's last error.
};

[[noreturn]] void on_error(png_structp png, png_const_charp message) {
  auto* state = static_cast<PngState*>(png_get_error_ptr(png));
  std::snprintf(state->message, sizeof state->message, "%s", message ? message : "libpng error");
  png_longjmp(png, 1);
}

void on_warning(png_structp png, png_const_charp message) {
  std::string& warnings = *static_cast<PngState*>(png_get_error_ptr(png))->warnings;
  try {  // A warning lost rather than an exception through libpng.
    warnings += (warnings.empty() ? "libpng warning: " : "; libpng warning: ") +
                std::string(message ? message : "");
  } catch (const std::exception&) {
  }
}

void read_file(png_structp png, png_bytep data, size_t size) {
  auto* state = static_cast<PngState*>(png_get_io_ptr(png));
  if (std::fread(data, 1, size, state->file) != size) {
    png_error(png, std::ferror(state->file) ? "read error" : "the file ends early (truncated?)");
  }
}

void append_bytes(png_structp png, png_bytep data, size_t size) {
  auto* state = static_cast<PngState*>(png_get_io_ptr(png));
  bool ok = true;
  try {
    state->bytes->insert(state->bytes->end(), data, data + size);
  } catch (const std::bad_alloc&) {
    ok = false;
  }
  if (!ok) png_error(png, "out of memory for the encoded file");
}

// The header and OIIO's transforms: palette to RGB, grey under 8 bits to 8, tRNS to alpha. False
// on error, libpng's message in state.message (as for every decode_* and encode_*).
bool decode_header(PngState& s) {
  if (setjmp(png_jmpbuf(s.png))) return false;  // NOLINT(cert-err52-cpp)
  png_read_info(s.png, s.info);
  png_set_expand(s.png);
  png_set_interlace_handling(s.png);
  png_read_update_info(s.png, s.info);
  return true;
}

bool decode_row(PngState& s, png_bytep row) {
  if (setjmp(png_jmpbuf(s.png))) return false;  // NOLINT(cert-err52-cpp)
  png_read_row(s.png, row, nullptr);
  return true;
}

bool decode_image(PngState& s, png_bytepp rows) {
  if (setjmp(png_jmpbuf(s.png))) return false;  // NOLINT(cert-err52-cpp)
  png_read_image(s.png, rows);
  png_read_end(s.png, nullptr);
  return true;
}

// The writer's header, as OIIO's PNG writer sets it.
struct Header {
  png_uint_32 width = 0, height = 0;
  int bit_depth = 8, color_type = 0, level = 6, filter = 0;
  bool srgb = false;
  double file_gamma = 0;  // gAMA when > 0.
  png_textp text = nullptr;
  int text_count = 0;
};

bool encode_header(PngState& s, const Header& h) {
  if (setjmp(png_jmpbuf(s.png))) return false;  // NOLINT(cert-err52-cpp)
  png_set_compression_level(s.png, h.level);
  png_set_compression_strategy(s.png, Z_DEFAULT_STRATEGY);  // OIIO's: not libpng's Z_FILTERED.
  png_set_filter(s.png, 0, h.filter);
  png_set_IHDR(s.png, s.info, h.width, h.height, h.bit_depth, h.color_type, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_oFFs(s.png, s.info, 0, 0, PNG_OFFSET_PIXEL);
  if (h.srgb) png_set_sRGB_gAMA_and_cHRM(s.png, s.info, PNG_sRGB_INTENT_ABSOLUTE);
  if (h.file_gamma > 0) png_set_gAMA(s.png, s.info, h.file_gamma);
  if (h.text_count > 0) png_set_text(s.png, s.info, h.text, h.text_count);
  png_write_info(s.png, s.info);
  return true;
}

// A row (none: the file's end).
bool encode_row(PngState& s, png_bytep row) {
  if (setjmp(png_jmpbuf(s.png))) return false;  // NOLINT(cert-err52-cpp)
  row ? png_write_row(s.png, row) : png_write_end(s.png, s.info);
  return true;
}

class PngReader final : public Reader {
 public:
  explicit PngReader(fs::path path) : path_(std::move(path)) { state_.warnings = &warnings_; }
  ~PngReader() override { release(); }
  PngReader(const PngReader&) = delete;
  PngReader& operator=(const PngReader&) = delete;

  bool start(std::string& error);
  const Spec& spec() const override { return spec_; }
  bool read_rows(int y0, int y1, Sample as, void* out) override;
  std::string error() override {
    std::string why = error_ + (error_.empty() || warnings_.empty() ? "" : "; ") + warnings_;
    error_.clear(), warnings_.clear();
    return why;
  }

 private:
  void release() {  // (libpng nulls the pointers.)
    if (state_.png) png_destroy_read_struct(&state_.png, &state_.info, nullptr);
    if (state_.file) std::fclose(state_.file);
    state_.file = nullptr;
  }
  void read_spec();
  bool fail(const std::string& why) {
    error_ = why;
    return false;
  }
  bool decode_next(unsigned char* row);
  bool rewind();
  void convert(unsigned char* row, Sample as, unsigned char* out);

  fs::path path_;
  PngState state_;
  Spec spec_;
  bool sixteen_ = false, interlaced_ = false, broken_ = false;
  float gamma_ = 1.0f;  // For the premultiplication (OIIO's "oiio:Gamma", 1 without gAMA).
  std::size_t row_bytes_ = 0;
  int next_row_ = 0;
  std::vector<unsigned char> row_, image_;  // image_: an interlaced file, decoded whole.
  std::vector<std::uint16_t> codes_;
  std::string warnings_, error_;
};

bool PngReader::start(std::string& error) {
  unsigned char signature[8];
  if (!(state_.file = std::fopen(path_.c_str(), "rb"))) {
    error = std::string("cannot open the file: ") + std::strerror(errno);
  } else if (std::fread(signature, 1, 8, state_.file) != 8 || png_sig_cmp(signature, 0, 8)) {
    error = "not a PNG file";
  } else if (!(state_.png =
                   png_create_read_struct(PNG_LIBPNG_VER_STRING, &state_, on_error, on_warning)) ||
             !(state_.info = png_create_info_struct(state_.png))) {
    error = "out of memory for libpng";
  } else {
    png_set_read_fn(state_.png, &state_, read_file);
    png_set_sig_bytes(state_.png, 8);
    if (decode_header(state_)) {
      read_spec();
      return true;
    }
    error = std::string("cannot decode the PNG header: ") + state_.message;
  }
  return false;
}

// The spec and OIIO's attributes: colour space, DateTime, text chunks (three keys renamed as OIIO
// does; XMP and raw Exif, which it decodes into other names, left out), resolution.
void PngReader::read_spec() {
  png_structp p = state_.png;
  spec_ = Spec{};
  spec_.width = int(png_get_image_width(p, state_.info));
  spec_.height = int(png_get_image_height(p, state_.info));
  spec_.channels = png_get_channels(p, state_.info);
  sixteen_ = png_get_bit_depth(p, state_.info) == 16;
  spec_.format = sixteen_ ? Sample::kUInt16 : Sample::kUInt8;
  spec_.channel_names = spec_.channels == 2 ? std::vector<std::string>{"Y", "A"}
                                            : default_channel_names(spec_.channels);
  interlaced_ = png_get_interlace_type(p, state_.info) != PNG_INTERLACE_NONE;
  row_bytes_ = png_get_rowbytes(p, state_.info);
  gamma_ = 1.0f;
  int intent = 0;
  double gamma = 0;
  if (!png_get_sRGB(p, state_.info, &intent) && png_get_gAMA(p, state_.info, &gamma) && gamma > 0) {
    // OIIO rounds to hundredths: 2.2, not 2.19998.
    gamma_ = std::round(float(100.0 * float(1.0 / gamma))) / 100.0f;
    spec_.set("oiio:Gamma", double(gamma_), "float");
    char name[32];
    std::snprintf(name, sizeof name, "Gamma%.2g", double(gamma_));
    spec_.set("oiio:ColorSpace", gamma_ == 1.0f ? "linear" : name);
  } else {
    spec_.set("oiio:ColorSpace", "sRGB");
  }
  png_timep time = nullptr;
  if (png_get_tIME(p, state_.info, &time)) {
    char date[64];
    std::snprintf(date, sizeof date, "%4d:%02d:%02d %02d:%02d:%02d", time->year, time->month,
                  time->day, time->hour, time->minute, time->second);
    spec_.set("DateTime", std::string(date));
  }
  png_textp text = nullptr;
  const int count = png_get_text(p, state_.info, &text, nullptr);
  for (int i = 0; i < count; ++i) {
    const std::string key = text[i].key;
    if (equals_ignoring_case(key, "XML:com.adobe.xmp") ||
        equals_ignoring_case(key, "Raw profile type exif"))
      continue;
    const char* name = equals_ignoring_case(key, "Description") ? "ImageDescription"
                       : equals_ignoring_case(key, "Author")    ? "Artist"
                       : equals_ignoring_case(key, "Title")     ? "DocumentName"
                                                                : text[i].key;
    spec_.set(name, std::string(text[i].text ? text[i].text : ""));
  }
  png_uint_32 res_x = 0, res_y = 0;
  int unit = 0;
  if (png_get_pHYs(p, state_.info, &res_x, &res_y, &unit)) {
    const float scale = unit == PNG_RESOLUTION_METER ? float(2.54 / 100.0) : 1.0f;
    spec_.set("ResolutionUnit", unit == PNG_RESOLUTION_METER ? "inch" : "none");
    spec_.set("XResolution", double(float(res_x) * scale), "float");
    spec_.set("YResolution", double(float(res_y) * scale), "float");
  }
  const float aspect = png_get_pixel_aspect_ratio(p, state_.info);
  if (aspect != 0 && aspect != 1) spec_.set("PixelAspectRatio", double(aspect), "float");
}

// Decodes the next row into `row` (row_bytes_), from the whole image if interlaced.
bool PngReader::decode_next(unsigned char* row) {
  if (interlaced_) {
    if (image_.empty()) {
      image_.resize(row_bytes_ * std::size_t(spec_.height));
      std::vector<png_bytep> rows(spec_.height);
      for (int y = 0; y < spec_.height; ++y) rows[y] = image_.data() + row_bytes_ * y;
      if (!decode_image(state_, rows.data())) {
        image_.clear();
        broken_ = true;
        return fail(std::string("cannot decode the PNG: ") + state_.message);
      }
    }
    std::memcpy(row, image_.data() + row_bytes_ * next_row_, row_bytes_);
  } else if (!decode_row(state_, row)) {
    broken_ = true;
    return fail(std::string("cannot decode the PNG: ") + state_.message);
  }
  ++next_row_;
  return true;
}

// Decoding is sequential: rows above the last ones decoded (or after a failure) start the file
// again from the top.
bool PngReader::rewind() {
  release();
  image_.clear();
  next_row_ = 0;
  broken_ = true;  // Until the file opens again as it was.
  const Spec before = spec_;
  std::string why;
  if (!start(why)) return fail(why);
  if (row_bytes_ != std::size_t(before.width) * before.channels * sample_bytes(before.format) ||
      spec_.height != before.height || spec_.channels != before.channels) {
    spec_ = before;  // The caller's buffers are of this size.
    return fail("the file changed while it was being read");
  }
  broken_ = false;
  return true;
}

// A decoded row's codes associated with their alpha as OIIO does, then converted.
template <class T>
void emit(T* codes, const Spec& spec, float gamma, Sample as, unsigned char* out) {
  if (spec.channels % 2 == 0) png_samples::associate(codes, spec.width, spec.channels, gamma);
  for (int i = 0; i < spec.width * spec.channels; ++i) {
    const unsigned v = codes[i];
    const bool byte = sizeof(T) == 1;
    auto* out16 = reinterpret_cast<std::uint16_t*>(out);
    if (as == Sample::kUInt8) out[i] = std::uint8_t(byte ? v : (v * 255 + 32767) / 65535);
    if (as == Sample::kUInt16) out16[i] = std::uint16_t(byte ? v * 257 : v);
    if (as == Sample::kFloat) reinterpret_cast<float*>(out)[i] = png_samples::to_float(codes[i]);
  }
}

void PngReader::convert(unsigned char* row, Sample as, unsigned char* out) {
  if (!sixteen_) return emit(row, spec_, gamma_, as, out);
  codes_.resize(std::size_t(spec_.width) * spec_.channels);
  for (std::size_t i = 0; i < codes_.size(); ++i) codes_[i] = row[2 * i] << 8 | row[2 * i + 1];
  emit(codes_.data(), spec_, gamma_, as, out);
}

bool PngReader::read_rows(int y0, int y1, Sample as, void* out) {
  if (as != Sample::kUInt8 && as != Sample::kUInt16 && as != Sample::kFloat) {
    return fail(std::string("cannot read PNG pixels as ") + sample_name(as));
  }
  if (y0 < 0 || y1 > spec_.height || y0 > y1) {
    return fail("rows " + std::to_string(y0) + ".." + std::to_string(y1) + " are outside 0.." +
                std::to_string(spec_.height));
  }
  if (y0 == y1) return true;
  try {
    if ((broken_ || y0 < next_row_) && !rewind()) return false;
    row_.resize(row_bytes_);
    while (next_row_ < y0) {
      if (!decode_next(row_.data())) return false;
    }
    const std::size_t out_row = std::size_t(spec_.width) * spec_.channels * sample_bytes(as);
    auto* dst = static_cast<unsigned char*>(out);
    for (int y = y0; y < y1; ++y, dst += out_row) {
      if (!decode_next(row_.data())) return false;
      convert(row_.data(), as, dst);
    }
  } catch (const std::bad_alloc&) {
    broken_ = true;
    return fail("out of memory decoding the PNG");
  }
  return true;
}

class PngWriter final : public Writer {
 public:
  PngWriter(const Spec& spec, Sink& sink) : spec_(spec), sink_(sink) {
    state_.bytes = &bytes_;
    state_.warnings = &warnings_;
  }
  ~PngWriter() override { release(); }
  PngWriter(const PngWriter&) = delete;
  PngWriter& operator=(const PngWriter&) = delete;

  bool start(std::string& error);
  bool write_rows(int y0, int y1, Sample from, const void* data) override;
  bool close() override;
  std::string error() override { return error_.empty() ? warnings_ : error_; }

 private:
  void release() {  // (libpng nulls the pointers.)
    if (state_.png) png_destroy_write_struct(&state_.png, &state_.info);
  }
  bool fail(const std::string& why) {
    error_ = why;
    release();
    return false;
  }
  Header header(std::vector<png_text>& text);
  template <class T>
  void encode(const unsigned char* in, Sample from, std::vector<T>& codes);  // One row.

  Spec spec_;
  Sink& sink_;
  PngState state_;
  std::vector<unsigned char> bytes_, row_;
  std::vector<std::uint16_t> codes16_;
  float gamma_ = 1.0f;  // For the division by alpha.
  bool deassociate_ = false, closed_ = false;
  int next_row_ = 0;
  std::string warnings_, error_;
};

// PNG's names for three of OIIO's attributes.
const char* png_key(const std::string& name) {
  if (equals_ignoring_case(name, "Artist")) return "Author";
  if (equals_ignoring_case(name, "DocumentName") || equals_ignoring_case(name, "name"))
    return "Title";
  if (equals_ignoring_case(name, "ImageDescription") || equals_ignoring_case(name, "description"))
    return "Description";
  return name.c_str();
}

// What OIIO's writer makes of the attributes: "png:compressionLevel" (default 6), "png:filter",
// "oiio:ColorSpace" as sRGB / gAMA chunks (and as text), every other string as a tEXt chunk.
// Other numbers (an int such as "lightstage:bit_depth") are not written, as OIIO wrote none. Left
// out, none in lightstage's files: DateTime (OIIO's tIME), the resolution (its pHYs) and
// "compression" (its zlib strategy).
Header PngWriter::header(std::vector<png_text>& text) {
  Header h;
  h.width = png_uint_32(spec_.width);
  h.height = png_uint_32(spec_.height);
  h.bit_depth = spec_.format == Sample::kUInt16 ? 16 : 8;
  constexpr int kTypes[] = {PNG_COLOR_TYPE_GRAY, PNG_COLOR_TYPE_GRAY_ALPHA, PNG_COLOR_TYPE_RGB,
                            PNG_COLOR_TYPE_RGB_ALPHA};
  h.color_type = kTypes[spec_.channels - 1];
  auto number = [&](std::string_view name, double otherwise) {
    const Attribute* a = spec_.find(name);
    return a && a->is_number() ? a->number() : otherwise;
  };
  h.level = std::clamp(int(number("png:compressionLevel", 6)), 0, 9);
  h.filter = int(number("png:filter", PNG_NO_FILTERS));
  gamma_ = float(number("oiio:Gamma", 1.0));
  deassociate_ =
      (spec_.channels == 2 || spec_.channels == 4) && number("oiio:UnassociatedAlpha", 0) == 0;
  for (const Attribute& a : spec_.attributes) {
    const std::string* value = a.text();
    const bool skipped = equals_ignoring_case(a.name, "planarconfig") ||
                         equals_ignoring_case(a.name, "compression") ||
                         equals_ignoring_case(a.name, "ResolutionUnit") ||
                         equals_ignoring_case(a.name, "DateTime");
    if (!value || a.name.empty() || skipped) continue;
    if (equals_ignoring_case(a.name, "oiio:ColorSpace")) {
      if (equals_ignoring_case(*value, "sRGB")) h.srgb = true;
      if (equals_ignoring_case(*value, "linear")) h.file_gamma = 1.0;
      if (strncasecmp(value->c_str(), "Gamma", 5) == 0) {
        std::size_t digits = 5;
        while (digits < value->size() && std::isalpha((unsigned char)(*value)[digits])) ++digits;
        const float g = std::strtof(value->c_str() + digits, nullptr);
        if (g >= 0.01f && g <= 10.0f) gamma_ = g;
        h.file_gamma = 1.0f / gamma_;
      }
    }
    png_text t{};
    t.compression = PNG_TEXT_COMPRESSION_NONE;
    t.key = const_cast<char*>(png_key(a.name));  // libpng copies both.
    t.text = const_cast<char*>(value->c_str());
    text.push_back(t);
  }
  h.text = text.empty() ? nullptr : text.data();
  h.text_count = int(text.size());
  return h;
}

bool PngWriter::start(std::string& error) {
  if (spec_.width < 1 || spec_.height < 1 || spec_.channels < 1 || spec_.channels > 4) {
    error = "PNG takes 1 to 4 channels and at least 1x1 pixels, not " +
            std::to_string(spec_.width) + "x" + std::to_string(spec_.height) + "x" +
            std::to_string(spec_.channels);
  } else if (spec_.format != Sample::kUInt8 && spec_.format != Sample::kUInt16) {
    error = std::string("PNG stores 8-bit or 16-bit samples, not ") + sample_name(spec_.format);
  } else if (!(state_.png =
                   png_create_write_struct(PNG_LIBPNG_VER_STRING, &state_, on_error, on_warning)) ||
             !(state_.info = png_create_info_struct(state_.png))) {
    error = "out of memory for libpng";
  } else {
    png_set_write_fn(state_.png, &state_, append_bytes, [](png_structp) {});
    std::vector<png_text> text;
    if (encode_header(state_, header(text))) return true;
    error = std::string("cannot encode the PNG header: ") + state_.message;
  }
  return false;
}

// A row from the caller's type to the file's codes: as OIIO, through float unless the types
// match.
template <class T>
void PngWriter::encode(const unsigned char* in, Sample from, std::vector<T>& codes) {
  for (std::size_t i = 0; i < codes.size(); ++i) {
    if (from == Sample::kFloat) {
      codes[i] = png_samples::from_float<T>(reinterpret_cast<const float*>(in)[i]);
    } else if (from == Sample::kUInt8) {
      codes[i] = std::is_same_v<T, std::uint8_t>
                     ? T(in[i])
                     : png_samples::from_float<T>(png_samples::to_float(in[i]));
    } else {
      const std::uint16_t v = reinterpret_cast<const std::uint16_t*>(in)[i];
      codes[i] = std::is_same_v<T, std::uint16_t>
                     ? T(v)
                     : png_samples::from_float<T>(png_samples::to_float(v));
    }
  }
  if (deassociate_) png_samples::deassociate(codes.data(), spec_.width, spec_.channels, gamma_);
}

bool PngWriter::write_rows(int y0, int y1, Sample from, const void* data) {
  if (closed_ || !state_.png) return fail(error_.empty() ? "the PNG writer is closed" : error_);
  if (from != Sample::kUInt8 && from != Sample::kUInt16 && from != Sample::kFloat) {
    return fail(std::string("cannot write PNG pixels from ") + sample_name(from));
  }
  if (y0 != next_row_ || y1 < y0 || y1 > spec_.height) {
    return fail("rows " + std::to_string(y0) + ".." + std::to_string(y1) +
                " are not the next ones (row " + std::to_string(next_row_) + " of " +
                std::to_string(spec_.height) + ")");
  }
  const std::size_t n = std::size_t(spec_.width) * spec_.channels;
  const std::size_t in_row = n * sample_bytes(from);
  const bool sixteen = spec_.format == Sample::kUInt16;
  try {
    row_.resize(n * (sixteen ? 2 : 1));
    codes16_.resize(sixteen ? n : 0);
    const auto* in = static_cast<const unsigned char*>(data);
    for (int y = y0; y < y1; ++y, in += in_row) {
      sixteen ? encode(in, from, codes16_) : encode(in, from, row_);
      for (std::size_t i = 0; sixteen && i < n; ++i) {  // PNG is big-endian.
        row_[2 * i] = std::uint8_t(codes16_[i] >> 8);
        row_[2 * i + 1] = std::uint8_t(codes16_[i]);
      }
      if (!encode_row(state_, row_.data())) {
        return fail(std::string("cannot encode the PNG: ") + state_.message);
      }
      ++next_row_;
    }
  } catch (const std::bad_alloc&) {
    return fail("out of memory encoding the PNG");
  }
  return true;
}

bool PngWriter::close() {
  if (closed_) return error_.empty();
  closed_ = true;
  if (!state_.png) return false;
  if (next_row_ != spec_.height) {
    return fail("the PNG was closed after " + std::to_string(next_row_) + " of its " +
                std::to_string(spec_.height) + " rows");
  }
  if (!encode_row(state_, nullptr))
    return fail(std::string("cannot end the PNG: ") + state_.message);
  release();
  try {
    sink_.write_at(0, bytes_.data(), bytes_.size());
  } catch (const std::exception& e) {
    error_ = e.what();
    return false;
  }
  std::vector<unsigned char>().swap(bytes_);
  return true;
}

class PngCodecs final : public Codecs {
 public:
  std::unique_ptr<Reader> open(const fs::path& path, std::string& error) override {
    auto reader = std::make_unique<PngReader>(path);
    return reader->start(error) ? std::move(reader) : nullptr;
  }
  std::unique_ptr<Writer> create(const fs::path&, const Spec& spec, Sink& sink,
                                 std::string& error) override {
    auto writer = std::make_unique<PngWriter>(spec, sink);
    return writer->start(error) ? std::move(writer) : nullptr;
  }
};

}  // namespace

Codecs& png_codecs() {
  static PngCodecs codecs;
  return codecs;
}

}  // namespace ls::image_file
