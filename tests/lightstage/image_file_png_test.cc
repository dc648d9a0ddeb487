// The PNG codec against OpenImageIO 2.4, through which lightstage's PNG files and tests were read
// and written: the same values bit for bit on reading (alpha association, 8/16-bit and float
// conversions, palette, low bit depths, interlacing, gamma), the same bytes on writing, and clean
// failures on damaged files and failing sinks.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <png.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/image_file.h"

namespace ls::image_file {
Codecs& png_codecs();  // lightstage/image_file_png.cc
}  // namespace ls::image_file

namespace ls::image_file {
namespace {

namespace fs = std::filesystem;
using Byte = unsigned char;
using Bytes = std::vector<Byte>;

// A fresh directory per test, removed at its end.
class TempDir {
 public:
  TempDir() { fs::create_directories(path_); }
  ~TempDir() { fs::remove_all(path_, error_); }
  fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_ = fs::temp_directory_path() / ("lightstage-png-test-" + std::to_string(getpid()));
  std::error_code error_;
};

Spec png_spec(int width, int height, int channels, Sample format) {
  return Spec{.width = width, .height = height, .channels = channels, .format = format};
}

png_text text_chunk(const char* key, const char* text, int compression) {
  return png_text{compression, const_cast<char*>(key), const_cast<char*>(text)};
}

Bytes file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return Bytes(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void put_bytes(const fs::path& path, const Bytes& bytes) {
  std::ofstream(path, std::ios::binary).write((const char*)bytes.data(), bytes.size());
}

OIIO::TypeDesc type_of(Sample s) {
  const OIIO::TypeDesc kTypes[] = {OIIO::TypeUInt8, OIIO::TypeUInt16, OIIO::TypeHalf};
  return s < Sample::kFloat ? kTypes[int(s)] : OIIO::TypeFloat;
}

// Random codes, big-endian where 16-bit (as a PNG row holds them), with some alphas at 0 and max.
Bytes random_samples(int pixels, int channels, int bytes, bool alpha, unsigned seed) {
  std::mt19937 rng(seed);
  Bytes out(std::size_t(pixels) * channels * bytes);
  for (auto& b : out) b = std::uint8_t(rng());
  if (!alpha) return out;
  for (int p = 0; p < pixels; ++p) {
    unsigned char* a = &out[(std::size_t(p) * channels + channels - 1) * bytes];
    if (p % 5 == 0 || p % 7 == 0) std::memset(a, p % 5 == 0 ? 0xff : 0, bytes);
  }
  return out;
}

// A PNG made by libpng itself: what OIIO cannot write (palette, 1-4 bits, tRNS, interlace,
// gAMA, zTXt/iTXt).
struct PngRecipe {
  int width = 0, height = 0, color_type = PNG_COLOR_TYPE_RGB, bit_depth = 8, interlace = 0;
  double gamma = 0;  // gAMA when > 0.
  bool srgb = false, phys = false, time = false;
  std::vector<png_color> palette;
  Bytes palette_alpha;                        // tRNS of a palette.
  std::optional<png_color_16> trns;           // tRNS of grey or RGB.
  std::vector<png_text> text, trailing_text;  // trailing_text: after the image data.
  Bytes rows;                                 // height rows, packed.
};

bool encode_recipe(std::FILE* f, const PngRecipe& r, png_bytepp rows) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  if (setjmp(png_jmpbuf(png))) {  // NOLINT(cert-err52-cpp)
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_init_io(png, f);
  png_set_IHDR(png, info, r.width, r.height, r.bit_depth, r.color_type, r.interlace,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (!r.palette.empty()) png_set_PLTE(png, info, r.palette.data(), int(r.palette.size()));
  if (!r.palette_alpha.empty() || r.trns) {
    png_set_tRNS(png, info, r.palette_alpha.data(), int(r.palette_alpha.size()),
                 r.trns ? &*r.trns : nullptr);
  }
  if (r.srgb) png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  if (r.gamma > 0) png_set_gAMA(png, info, r.gamma);
  if (r.phys) png_set_pHYs(png, info, 2835, 3000, PNG_RESOLUTION_METER);
  png_time time{2021, 3, 4, 5, 6, 7};
  if (r.time) png_set_tIME(png, info, &time);
  png_set_text(png, info, r.text.data(), int(r.text.size()));
  png_write_info(png, info);
  png_write_image(png, rows);
  png_set_text(png, info, r.trailing_text.data(), int(r.trailing_text.size()));
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return true;
}

void write_recipe(const fs::path& path, const PngRecipe& r) {
  std::vector<png_bytep> rows(r.height);
  const std::size_t row_bytes = r.rows.size() / r.height;
  for (int y = 0; y < r.height; ++y) rows[y] = const_cast<png_bytep>(&r.rows[row_bytes * y]);
  std::FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_TRUE(f);
  const bool ok = encode_recipe(f, r, rows.data());
  std::fclose(f);
  ASSERT_TRUE(ok) << path;
}

// Attributes as comparable text, sorted: "name=s:text" or "name=n:number".
std::string entry(const std::string& name, const std::string* text, double number) {
  char digits[64];
  std::snprintf(digits, sizeof digits, "%.9g", number);
  return name + (text ? "=s:" + *text : std::string("=n:") + digits);
}

std::vector<std::string> attributes_of(const OIIO::ImageSpec& s) {
  std::vector<std::string> out;
  for (const OIIO::ParamValue& p : s.extra_attribs) {
    const std::string text = p.get_string();
    const bool is_text = p.type() == OIIO::TypeDesc::STRING;
    out.push_back(entry(p.name().string(), is_text ? &text : nullptr, p.get_float()));
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<std::string> attributes_of(const Spec& s) {
  std::vector<std::string> out;
  for (const Attribute& a : s.attributes) {
    out.push_back(entry(a.name, a.text(), a.is_number() ? a.number() : 0));
  }
  std::sort(out.begin(), out.end());
  return out;
}

// The file read whole by the codec is what OIIO reads: spec, attributes and values as float,
// 16-bit and 8-bit.
::testing::AssertionResult reads_as_oiio(const fs::path& path) {
  auto in = OIIO::ImageInput::open(path.string());
  if (!in) return ::testing::AssertionFailure() << "OIIO cannot open it: " << OIIO::geterror();
  std::string error;
  auto ours = png_codecs().open(path, error);
  if (!ours) return ::testing::AssertionFailure() << "cannot open it: " << error;
  const OIIO::ImageSpec& o = in->spec();
  const Spec& s = ours->spec();
  const Sample format = o.format == OIIO::TypeDesc::UINT16 ? Sample::kUInt16 : Sample::kUInt8;
  if (s.width != o.width || s.height != o.height || s.channels != o.nchannels ||
      s.format != format || s.channel_names != o.channelnames) {
    return ::testing::AssertionFailure() << "spec differs: " << s.channels << " channels, "
                                         << sample_name(s.format) << " (OIIO: " << o.format << ")";
  }
  if (attributes_of(s) != attributes_of(o)) {
    std::ostringstream msg;
    for (const auto& a : attributes_of(s)) msg << " ours " << a;
    for (const auto& a : attributes_of(o)) msg << " OIIO's " << a;
    return ::testing::AssertionFailure() << "attributes differ:" << msg.str();
  }
  for (Sample as : {Sample::kFloat, Sample::kUInt16, Sample::kUInt8}) {
    const std::size_t size = std::size_t(o.width) * o.height * o.nchannels * sample_bytes(as);
    Bytes expected(size), got(size);
    if (!in->read_image(0, 0, 0, o.nchannels, type_of(as), expected.data())) {
      return ::testing::AssertionFailure() << "OIIO cannot read it: " << in->geterror();
    }
    if (!ours->read_rows(0, s.height, as, got.data())) {
      return ::testing::AssertionFailure() << "cannot read it: " << ours->error();
    }
    const std::size_t at =
        std::mismatch(got.begin(), got.end(), expected.begin()).first - got.begin();
    if (at < size) {
      return ::testing::AssertionFailure() << sample_name(as) << " sample " << at / sample_bytes(as)
                                           << " (of " << o.nchannels << " a pixel) differs";
    }
  }
  return ::testing::AssertionSuccess();
}

// Random rows of a colour type and depth (alphas at 0 and max among them), a random palette.
PngRecipe recipe(int color_type, int bits, int interlace, unsigned seed, int width = 45,
                 int height = 19) {
  PngRecipe r;
  r.width = width, r.height = height, r.color_type = color_type, r.bit_depth = bits;
  r.interlace = interlace;
  constexpr int kChannels[] = {1, 0, 3, 1, 2, 0, 4};  // By PNG_COLOR_TYPE_*.
  const int channels = kChannels[color_type];
  const bool alpha = channels % 2 == 0;
  r.rows = bits < 8 ? random_samples(height * ((width * bits + 7) / 8), 1, 1, false, seed)
                    : random_samples(width * height, channels, bits / 8, alpha, seed);
  std::mt19937 rng(seed);
  for (int i = 0; color_type == PNG_COLOR_TYPE_PALETTE && i < (1 << bits); ++i) {
    r.palette.push_back({Byte(rng()), Byte(rng()), Byte(rng())});
  }
  return r;
}

TEST(PngFile, ReadsOiioWrittenFilesAsOiioDoes) {
  TempDir tmp;
  for (int bits : {8, 16}) {
    for (int channels = 1; channels <= 4; ++channels) {
      const std::string file =
          (tmp / ("oiio" + std::to_string(bits * 10 + channels) + ".png")).string();
      OIIO::ImageSpec spec(37, 11, channels, bits == 8 ? OIIO::TypeUInt8 : OIIO::TypeUInt16);
      spec.attribute("oiio:UnassociatedAlpha", 1);  // The codes as given, alpha partial.
      spec.attribute("lightstage:note", "a note");
      spec.attribute("Artist", "someone");
      // (Random bytes, alphas 0 and max among them: the same in either byte order.)
      Bytes codes = random_samples(37 * 11, channels, bits / 8, channels % 2 == 0, bits + channels);
      auto out = OIIO::ImageOutput::create("png");
      ASSERT_TRUE(out->open(file, spec));
      ASSERT_TRUE(out->write_image(spec.format, codes.data()));
      ASSERT_TRUE(out->close());
      EXPECT_TRUE(reads_as_oiio(file)) << bits << " bits, " << channels << " channels";
    }
  }
}

TEST(PngFile, AssociatesEveryAlphaAsOiioDoes) {
  TempDir tmp;
  PngRecipe r;  // Every 8-bit (colour, alpha) pair.
  r.width = r.height = 256;
  r.color_type = PNG_COLOR_TYPE_RGB_ALPHA;
  for (int a = 0; a < 256; ++a) {
    for (int v = 0; v < 256; ++v) r.rows.insert(r.rows.end(), {Byte(v), Byte(255 - v), 7, Byte(a)});
  }
  write_recipe(tmp / "pairs.png", r);
  EXPECT_TRUE(reads_as_oiio(tmp / "pairs.png"));
  for (int type : {PNG_COLOR_TYPE_GRAY_ALPHA, PNG_COLOR_TYPE_RGB_ALPHA}) {
    write_recipe(tmp / "16.png", recipe(type, 16, PNG_INTERLACE_NONE, 5, 256, 256));
    EXPECT_TRUE(reads_as_oiio(tmp / "16.png")) << type;
  }
}

// OIIO leaves values alone for gAMA and sRGB, but associates alpha through a gAMA's exponent.
TEST(PngFile, GammaAndSrgbChunksAsOiio) {
  TempDir tmp;
  for (int bits : {8, 16}) {
    for (double gamma : {0.0, 1 / 2.2, 0.45455, 1 / 1.8, 1.0, 0.5, -1.0}) {
      PngRecipe r = recipe(PNG_COLOR_TYPE_RGB_ALPHA, bits, 0, unsigned(bits + gamma * 100), 61, 13);
      r.gamma = gamma > 0 ? gamma : 0;
      r.srgb = gamma < 0;
      write_recipe(tmp / "g.png", r);
      EXPECT_TRUE(reads_as_oiio(tmp / "g.png")) << bits << " bits, gamma " << gamma;
    }
  }
}

TEST(PngFile, PaletteLowBitDepthsTransparencyInterlaceAndTextAsOiio) {
  TempDir tmp;
  std::vector<std::pair<std::string, PngRecipe>> cases;
  for (int interlace : {PNG_INTERLACE_NONE, PNG_INTERLACE_ADAM7}) {
    const std::string i = interlace ? " interlaced" : "";
    for (int bits : {1, 2, 4, 8}) {
      cases.emplace_back("palette " + std::to_string(bits) + i,
                         recipe(PNG_COLOR_TYPE_PALETTE, bits, interlace, bits));
      cases.emplace_back("grey " + std::to_string(bits) + i,
                         recipe(PNG_COLOR_TYPE_GRAY, bits, interlace, bits));
    }
    cases.emplace_back("palette with alpha" + i, recipe(PNG_COLOR_TYPE_PALETTE, 8, interlace, 3));
    for (int a = 0; a < 256; a += 2) cases.back().second.palette_alpha.push_back(Byte(255 - a));
    cases.emplace_back("grey with tRNS" + i, recipe(PNG_COLOR_TYPE_GRAY, 4, interlace, 4));
    cases.back().second.trns = png_color_16{0, 0, 0, 0, 5};
    cases.emplace_back("rgb16 with tRNS" + i, recipe(PNG_COLOR_TYPE_RGB, 16, interlace, 5));
    cases.back().second.trns = png_color_16{0, 0x1234, 0x5678, 0x9abc, 0};
    cases.emplace_back("rgba16" + i, recipe(PNG_COLOR_TYPE_RGB_ALPHA, 16, interlace, 6));
    cases.emplace_back("ya8" + i, recipe(PNG_COLOR_TYPE_GRAY_ALPHA, 8, interlace, 7));
  }
  PngRecipe& text = cases.emplace_back("text", recipe(PNG_COLOR_TYPE_RGB, 8, 0, 8)).second;
  text.time = text.phys = true;
  const std::pair<const char*, int> kText[] = {{"Description", PNG_TEXT_COMPRESSION_NONE},
                                               {"Author", PNG_TEXT_COMPRESSION_zTXt},
                                               {"Title", PNG_ITXT_COMPRESSION_NONE},
                                               {"lightstage:note", PNG_ITXT_COMPRESSION_zTXt},
                                               {"plain", PNG_TEXT_COMPRESSION_NONE}};
  for (const auto& [key, compression] : kText) {
    text.text.push_back(text_chunk(key, "text of the chunk, é", compression));
  }
  for (const auto& [name, r] : cases) {
    write_recipe(tmp / "c.png", r);
    EXPECT_TRUE(reads_as_oiio(tmp / "c.png")) << name;
  }
}

TEST(PngFile, BandsInAnyOrderEqualTheWholeRead) {
  TempDir tmp;
  for (int interlace : {PNG_INTERLACE_NONE, PNG_INTERLACE_ADAM7}) {
    write_recipe(tmp / "b.png", recipe(PNG_COLOR_TYPE_RGB_ALPHA, 16, interlace, 9));
    std::string error;
    auto in = png_codecs().open(tmp / "b.png", error);
    ASSERT_TRUE(in) << error;
    for (Sample as : {Sample::kFloat, Sample::kUInt8}) {
      const std::size_t row = std::size_t(45) * 4 * sample_bytes(as);
      Bytes whole(row * 19);
      ASSERT_TRUE(in->read_rows(0, 19, as, whole.data())) << in->error();
      const std::pair<int, int> kBands[] = {{0, 3},   {3, 10}, {10, 19}, {12, 13}, {0, 1},
                                            {18, 19}, {5, 6},  {4, 5},   {6, 19}};
      for (const auto& [y0, y1] : kBands) {
        Bytes band(row * (y1 - y0));
        ASSERT_TRUE(in->read_rows(y0, y1, as, band.data())) << in->error();
        EXPECT_TRUE(std::equal(band.begin(), band.end(), whole.begin() + row * y0))
            << "rows " << y0 << ".." << y1 << (interlace ? " interlaced" : "");
      }
    }
    EXPECT_EQ(in->error(), "");
  }
}

// An OIIO spec of the codec's, as lightstage's OIIO module made it.
OIIO::ImageSpec oiio_spec(const Spec& spec) {
  OIIO::ImageSpec s(spec.width, spec.height, spec.channels, type_of(spec.format));
  for (const Attribute& a : spec.attributes) {
    if (a.text()) s.attribute(a.name, *a.text());
    if (a.type_name == "int") s.attribute(a.name, int(a.number()));
  }
  return s;
}

Bytes oiio_encode(const fs::path& path, const Spec& spec, Sample from, const void* data) {
  auto out = OIIO::ImageOutput::create(path.string());
  EXPECT_TRUE(out->open(path.string(), oiio_spec(spec))) << out->geterror();
  EXPECT_TRUE(out->write_image(type_of(from), data)) << out->geterror();
  EXPECT_TRUE(out->close()) << out->geterror();
  return file_bytes(path);
}

// Written in three bands.
Bytes encode_png(const Spec& spec, Sample from, const void* data) {
  MemorySink sink;
  std::string error;
  auto out = png_codecs().create("x.png", spec, sink, error);
  EXPECT_TRUE(out) << error;
  if (!out) return {};
  const std::size_t row = std::size_t(spec.width) * spec.channels * sample_bytes(from);
  const auto* bytes = static_cast<const unsigned char*>(data);
  const int bands[] = {0, 1, spec.height / 2, spec.height};
  for (int b = 0; b < 3; ++b) {
    EXPECT_TRUE(out->write_rows(bands[b], bands[b + 1], from, bytes + row * bands[b]))
        << out->error();
  }
  EXPECT_TRUE(out->close()) << out->error();
  return sink.bytes;
}

// Samples of type `from`. Floats range past [0, 1] (NaN and infinities too), but none lies where
// OIIO's own rounding depends on its thread count (see from_float in image_file_png.cc).
Bytes samples_from(Sample from, Sample file, std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  Bytes out(n * sample_bytes(from));
  if (from != Sample::kFloat) {
    for (auto& b : out) b = Byte(rng());
    return out;
  }
  const float max = file == Sample::kUInt8 ? 255.0f : 65535.0f;
  std::uniform_real_distribution<float> value(-0.1f, 1.1f);
  for (std::size_t i = 0; i < n; ++i) {
    float x = i % 97 == 0 ? NAN : i % 89 == 0 ? INFINITY : i % 83 == 0 ? -INFINITY : value(rng);
    if (std::isfinite(x) && std::round(x * max) != std::floor(x * max + 0.5f)) x = 0.5f;
    std::memcpy(&out[i * 4], &x, 4);
  }
  return out;
}

TEST(PngFile, WritesTheBytesOiioWrites) {
  TempDir tmp;
  for (Sample format : {Sample::kUInt8, Sample::kUInt16}) {
    for (int channels = 1; channels <= 4; ++channels) {
      for (long long level : {1, 9}) {
        for (Sample from : {Sample::kUInt8, Sample::kUInt16, Sample::kFloat}) {
          Spec spec = png_spec(37, 9, channels, format);
          spec.set("png:compressionLevel", level);
          spec.set("lightstage:bit_depth", 12LL);
          spec.set("lightstage:note", "written by lightstage");
          const Bytes data =
              samples_from(from, format, std::size_t(37) * 9 * channels, channels + level);
          const Bytes ours = encode_png(spec, from, data.data());
          EXPECT_EQ(ours, oiio_encode(tmp / "oiio.png", spec, from, data.data()))
              << sample_name(format) << " file, " << channels << " channels, level " << level
              << ", from " << sample_name(from);
          put_bytes(tmp / "ours.png", ours);
          auto in = OIIO::ImageInput::open((tmp / "ours.png").string());
          ASSERT_TRUE(in) << OIIO::geterror();
          EXPECT_EQ(in->spec().get_string_attribute("lightstage:note"), "written by lightstage");
          EXPECT_EQ(in->spec().find_attribute("lightstage:bit_depth"), nullptr);  // As OIIO.
        }
      }
    }
  }
}

// Colour spaces as sRGB / gAMA chunks, alpha divided through a gamma, PNG's names for three
// attributes. (DateTime, resolution and "compression", which OIIO turned into tIME, pHYs and a
// zlib strategy, are left out: not text either.)
TEST(PngFile, WritesOiiosChunksForItsAttributes) {
  TempDir tmp;
  const char* kSpaces[] = {"sRGB", "linear", "Gamma2.2", "Gamma1.8", "GammaCorrected", "ACES"};
  for (Sample format : {Sample::kUInt8, Sample::kUInt16}) {
    for (const char* space : kSpaces) {
      for (int channels : {2, 4}) {
        Spec spec = png_spec(23, 5, channels, format);
        spec.set("oiio:ColorSpace", space);
        spec.set("Artist", "a"), spec.set("ImageDescription", "d"), spec.set("name", "t");
        Bytes data = samples_from(Sample::kUInt16, format, std::size_t(23) * 5 * channels, 3);
        auto* codes = reinterpret_cast<std::uint16_t*>(data.data());
        for (int p = 0; p < 4; ++p) {  // Past 2^32 when divided through a gamma.
          codes[std::size_t(p) * channels] = 65535;
          codes[std::size_t(p) * channels + channels - 1] = std::uint16_t(1 + 99 * p);
        }
        EXPECT_EQ(encode_png(spec, Sample::kUInt16, data.data()),
                  oiio_encode(tmp / "o.png", spec, Sample::kUInt16, data.data()))
            << space << ", " << channels << " channels, " << sample_name(format);
      }
    }
  }
  Spec spec = png_spec(3, 2, 1, Sample::kUInt8);
  spec.set("DateTime", "2024:05:06 07:08:09"), spec.set("compression", "rle");
  spec.set("ResolutionUnit", "inch"), spec.set("XResolution", 72.0, "float");
  put_bytes(tmp / "ours.png", encode_png(spec, Sample::kUInt8, Bytes(6, 9).data()));
  auto in = OIIO::ImageInput::open((tmp / "ours.png").string());
  ASSERT_TRUE(in);
  EXPECT_EQ(attributes_of(in->spec()), std::vector<std::string>{"oiio:ColorSpace=s:sRGB"});
}

TEST(PngFile, WriterRefusesWhatPngCannotHold) {
  MemorySink sink;
  std::string error;
  auto refused = [&](const Spec& spec) {
    error.clear();
    return !png_codecs().create("x.png", spec, sink, error) && !error.empty();
  };
  EXPECT_TRUE(refused(png_spec(4, 4, 5, Sample::kUInt8)));
  EXPECT_TRUE(refused(png_spec(4, 4, 3, Sample::kFloat)));
  EXPECT_TRUE(refused(png_spec(4, 4, 3, Sample::kHalf)));
  EXPECT_TRUE(refused(png_spec(0, 4, 3, Sample::kUInt8)));
  EXPECT_TRUE(refused(png_spec(2000000, 4, 3, Sample::kUInt8)));  // libpng's limit, not a crash.
  const Spec spec = png_spec(4, 4, 3, Sample::kUInt8);
  const Bytes row(std::size_t(4) * 3 * 4);
  auto out = png_codecs().create("x.png", spec, sink, error);
  EXPECT_FALSE(out->write_rows(0, 1, Sample::kHalf, row.data()));
  EXPECT_NE(out->error(), "");
  out = png_codecs().create("x.png", spec, sink, error);
  EXPECT_FALSE(out->write_rows(1, 2, Sample::kUInt8, row.data()));  // Not from the top.
  out = png_codecs().create("x.png", spec, sink, error);
  EXPECT_TRUE(out->write_rows(0, 2, Sample::kUInt8, row.data()));
  EXPECT_FALSE(out->close());  // Rows missing.
  EXPECT_NE(out->error(), "");
  EXPECT_TRUE(sink.bytes.empty());
}

// Every way out: false with a message, never a crash or a silent success.
::testing::AssertionResult fails_cleanly(const fs::path& path) {
  std::string error;
  auto in = png_codecs().open(path, error);
  if (!in && error.empty()) return ::testing::AssertionFailure() << "open failed without a message";
  if (!in) return ::testing::AssertionSuccess();
  const Spec& s = in->spec();
  Bytes pixels(std::size_t(s.width) * s.height * s.channels * 4);
  for (int attempt = 0; attempt < 2; ++attempt) {  // A second read starts again, and fails again.
    if (in->read_rows(0, s.height, Sample::kFloat, pixels.data())) {
      return ::testing::AssertionFailure() << "read it whole";
    }
    if (in->error().empty()) return ::testing::AssertionFailure() << "failed without a message";
  }
  return ::testing::AssertionSuccess();
}

// Cut anywhere, a file fails as it fails with OIIO: always before the end of its image data;
// after it, only where OIIO reads on (an interlaced file's trailing chunks).
TEST(PngFile, TruncatedFilesFailCleanlyWhereOiioFails) {
  TempDir tmp;
  for (int interlace : {PNG_INTERLACE_NONE, PNG_INTERLACE_ADAM7}) {
    PngRecipe r = recipe(PNG_COLOR_TYPE_RGB, 8, interlace, 10);
    r.trailing_text.push_back(text_chunk("after", "the image data", PNG_TEXT_COMPRESSION_NONE));
    write_recipe(tmp / "whole.png", r);
    const Bytes whole = file_bytes(tmp / "whole.png");
    ASSERT_TRUE(reads_as_oiio(tmp / "whole.png"));
    const std::size_t image_end = whole.size() - 12 - (12 + 20);  // Before tEXt and IEND.
    // Every byte near the end, fewer before.
    for (std::size_t size = 0; size < whole.size();
         size += size + 48 < whole.size() ? 1 + size / 16 : 1) {
      const fs::path cut = tmp / "cut.png";
      put_bytes(cut, Bytes(whole.begin(), whole.begin() + size));
      auto oiio = OIIO::ImageInput::create("png");  // Not every other format's reader as well.
      OIIO::ImageSpec spec;
      Bytes pixels(std::size_t(45) * 19 * 3);
      const bool oiio_reads = oiio->open(cut.string(), spec) &&
                              oiio->read_image(0, 0, 0, 3, OIIO::TypeUInt8, pixels.data());
      oiio->geterror();
      if (size < image_end || !oiio_reads) {
        EXPECT_FALSE(oiio_reads) << "OIIO read a file cut at " << size;
        EXPECT_TRUE(fails_cleanly(cut)) << "cut at " << size << " of " << whole.size();
      } else {
        EXPECT_TRUE(reads_as_oiio(cut)) << "cut at " << size << " of " << whole.size();
      }
    }
  }
}

TEST(PngFile, GarbageFailsCleanly) {
  TempDir tmp;
  const Bytes signature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  write_recipe(tmp / "good.png", recipe(PNG_COLOR_TYPE_RGB, 8, PNG_INTERLACE_NONE, 11));
  const Bytes good = file_bytes(tmp / "good.png");
  for (unsigned seed = 0; seed < 40; ++seed) {
    const Bytes noise = random_samples(300, 1, 1, false, seed);
    Bytes garbage = signature;
    garbage.insert(garbage.end(), noise.begin(), noise.end());
    put_bytes(tmp / "garbage.png", garbage);
    EXPECT_TRUE(fails_cleanly(tmp / "garbage.png")) << seed;
    // A good header, then noise in the middle of the image data.
    Bytes damaged = good;
    std::copy(noise.begin(), noise.begin() + 40, damaged.begin() + good.size() / 2);
    put_bytes(tmp / "damaged.png", damaged);
    EXPECT_TRUE(fails_cleanly(tmp / "damaged.png")) << seed;
  }
  put_bytes(tmp / "text.png", Bytes{'n', 'o', 't', ' ', 'a', ' ', 'P', 'N', 'G'});
  EXPECT_TRUE(fails_cleanly(tmp / "text.png"));
  EXPECT_TRUE(fails_cleanly(tmp / "missing.png"));
}

TEST(PngFile, ReaderRefusesOtherTypesRowsAndAFileReplaced) {
  TempDir tmp;
  write_recipe(tmp / "r.png", recipe(PNG_COLOR_TYPE_GRAY, 8, PNG_INTERLACE_NONE, 12));
  std::string error;
  auto in = png_codecs().open(tmp / "r.png", error);
  ASSERT_TRUE(in) << error;
  Bytes out(std::size_t(45) * 19 * 4);
  EXPECT_FALSE(in->read_rows(0, 1, Sample::kHalf, out.data()));
  EXPECT_NE(in->error(), "");
  EXPECT_FALSE(in->read_rows(0, 20, Sample::kFloat, out.data()));
  EXPECT_NE(in->error(), "");
  EXPECT_TRUE(in->read_rows(0, 19, Sample::kFloat, out.data())) << in->error();
  // Read again from the top, the file now of another size, then gone: failures, not overruns.
  write_recipe(tmp / "r.png", recipe(PNG_COLOR_TYPE_RGB, 8, PNG_INTERLACE_NONE, 12));
  EXPECT_FALSE(in->read_rows(0, 19, Sample::kFloat, out.data()));
  EXPECT_NE(in->error(), "");
  fs::remove(tmp / "r.png");
  EXPECT_FALSE(in->read_rows(0, 19, Sample::kFloat, out.data()));
  EXPECT_FALSE(in->read_rows(0, 19, Sample::kFloat, out.data()));  // Again: no crash.
  EXPECT_NE(in->error(), "");
}

class FullDisk final : public Sink {
 public:
  void write_at(std::uint64_t, const void*, std::size_t) override {
    throw InputError("frame.png: cannot write: No space left on device");
  }
};

TEST(PngFile, ASinkThatThrowsFailsCloseWithItsMessage) {
  FullDisk sink;
  std::string error;
  auto out = png_codecs().create("frame.png", png_spec(8, 3, 3, Sample::kUInt16), sink, error);
  ASSERT_TRUE(out) << error;
  const Bytes data(std::size_t(8) * 3 * 3 * 2, 0x40);
  ASSERT_TRUE(out->write_rows(0, 3, Sample::kUInt16, data.data())) << out->error();
  EXPECT_FALSE(out->close());
  EXPECT_EQ(out->error(), "frame.png: cannot write: No space left on device");
}

TEST(PngFile, AWriterDestroyedBeforeCloseWritesNothing) {
  MemorySink sink;
  std::string error;
  const Bytes data(std::size_t(64) * 64 * 4, 0x80);
  for (int rows : {0, 1, 32}) {
    auto out = png_codecs().create("x.png", png_spec(64, 64, 4, Sample::kUInt8), sink, error);
    ASSERT_TRUE(out) << error;
    EXPECT_TRUE(out->write_rows(0, rows, Sample::kUInt8, data.data()));
  }
  EXPECT_TRUE(sink.bytes.empty());
}

}  // namespace
}  // namespace ls::image_file
