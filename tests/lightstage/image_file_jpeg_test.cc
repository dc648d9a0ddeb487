// JPEG through libjpeg (image_file_jpeg.cc): pixels to the bit as OpenImageIO reads them, whole
// and in bands in any order; files cut short, broken or in colour spaces left to OpenImageIO; the
// writer's settings, refusals and failing sinks.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <random>

// After <cstdio>: jpeglib.h needs FILE and size_t.
#include <jpeglib.h>

#include "lightstage/errors.h"
#include "lightstage/image_file.h"
#include "tests/support/test_support.h"

namespace ls::image_file {
namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<unsigned char>;

template <class T>
OIIO::TypeDesc oiio_type_of() {
  if constexpr (std::is_same_v<T, float>) return OIIO::TypeDesc::FLOAT;
  if constexpr (std::is_same_v<T, std::uint16_t>) return OIIO::TypeDesc::UINT16;
  return OIIO::TypeDesc::UINT8;
}

template <class T>
Sample sample_of() {
  if constexpr (std::is_same_v<T, float>) return Sample::kFloat;
  if constexpr (std::is_same_v<T, std::uint16_t>) return Sample::kUInt16;
  return Sample::kUInt8;
}

// OpenImageIO's read of the whole image (empty when it cannot read it).
template <class T>
std::vector<T> oiio_read_samples(const fs::path& path) {
  auto in = OIIO::ImageInput::open(path.string());
  EXPECT_NE(in, nullptr) << OIIO::geterror();
  if (!in) return {};
  const OIIO::ImageSpec& s = in->spec();
  std::vector<T> values(std::size_t(s.width) * s.height * s.nchannels);
  EXPECT_TRUE(in->read_image(0, 0, 0, s.nchannels, oiio_type_of<T>(), values.data()))
      << in->geterror();
  return values;
}

// Rows [y0, y1) through `reader` (empty when the read fails).
template <class T>
std::vector<T> read_rows(Reader& reader, int y0, int y1) {
  const Spec& spec = reader.spec();
  std::vector<T> values(std::size_t(spec.width) * spec.channels * (y1 - y0));
  if (!reader.read_rows(y0, y1, sample_of<T>(), values.data())) {
    ADD_FAILURE() << "rows " << y0 << "-" << y1 << ": " << reader.error();
    return {};
  }
  return values;
}

template <class T>
std::vector<T> rows_of(const std::vector<T>& whole, const Spec& spec, int y0, int y1) {
  const std::size_t row = std::size_t(spec.width) * spec.channels;
  return {whole.begin() + std::ptrdiff_t(row * y0), whole.begin() + std::ptrdiff_t(row * y1)};
}

// Equal bit for bit; the message says where they first differ.
template <class T>
::testing::AssertionResult SameBits(const std::vector<T>& actual, const std::vector<T>& expected) {
  if (actual.size() != expected.size()) {
    return ::testing::AssertionFailure()
           << actual.size() << " samples, expected " << expected.size();
  }
  for (std::size_t i = 0; i < actual.size(); ++i) {
    if (std::memcmp(&actual[i], &expected[i], sizeof(T)) != 0) {
      return ::testing::AssertionFailure()
             << "sample " << i << " is " << std::setprecision(9) << double(actual[i])
             << ", expected " << double(expected[i]);
    }
  }
  return ::testing::AssertionSuccess();
}

std::unique_ptr<Reader> open_jpeg(const fs::path& path) {
  std::string error;
  std::unique_ptr<Reader> reader = jpeg_codecs().open(path, error);
  EXPECT_NE(reader, nullptr) << error;
  return reader;
}

void write_file(const fs::path& path, const Bytes& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

Spec jpeg_spec(int width, int height, int channels) {
  Spec spec;
  spec.width = width;
  spec.height = height;
  spec.channels = channels;
  spec.format = Sample::kUInt8;
  return spec;
}

// The file `samples` make through the writer, written in bands of 5 rows (empty on failure).
template <class T>
Bytes encode_jpeg(const Spec& spec, const std::vector<T>& samples) {
  MemorySink sink;
  std::string error;
  std::unique_ptr<Writer> out = jpeg_codecs().create("x.jpg", spec, sink, error);
  EXPECT_NE(out, nullptr) << error;
  if (!out) return {};
  const std::size_t row = std::size_t(spec.width) * spec.channels;
  for (int y0 = 0; y0 < spec.height; y0 += 5) {
    const int y1 = std::min(spec.height, y0 + 5);
    EXPECT_TRUE(out->write_rows(y0, y1, sample_of<T>(), samples.data() + row * y0)) << out->error();
  }
  EXPECT_TRUE(out->close()) << out->error();
  return sink.bytes;
}

// Smooth in x and y, a different ramp in each channel.
Bytes gradient(int width, int height, int channels) {
  Bytes codes;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c) {
        const int ramp = c == 0   ? x * 255 / (width - 1)
                         : c == 1 ? y * 255 / (height - 1)
                                  : (x + y) * 255 / (width + height - 2);
        codes.push_back((unsigned char)ramp);
      }
    }
  }
  return codes;
}

Bytes noise(int width, int height, int channels) {
  std::mt19937 random(7);
  Bytes codes(std::size_t(width) * height * channels);
  for (unsigned char& code : codes) code = (unsigned char)random();
  return codes;
}

// A colour space this reader leaves to OpenImageIO, through libjpeg itself.
Bytes four_channel_jpeg(J_COLOR_SPACE space, int width, int height) {
  jpeg_compress_struct cinfo{};
  jpeg_error_mgr errors{};
  cinfo.err = jpeg_std_error(&errors);
  jpeg_create_compress(&cinfo);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&cinfo, &buffer, &size);
  cinfo.image_width = JDIMENSION(width);
  cinfo.image_height = JDIMENSION(height);
  cinfo.input_components = 4;
  cinfo.in_color_space = JCS_CMYK;
  jpeg_set_defaults(&cinfo);
  jpeg_set_colorspace(&cinfo, space);
  jpeg_start_compress(&cinfo, TRUE);
  std::vector<JSAMPLE> row(std::size_t(width) * 4, 100);
  while (cinfo.next_scanline < cinfo.image_height) {
    JSAMPROW r = row.data();
    jpeg_write_scanlines(&cinfo, &r, 1);
  }
  jpeg_finish_compress(&cinfo);
  Bytes bytes(buffer, buffer + size);
  jpeg_destroy_compress(&cinfo);
  std::free(buffer);
  return bytes;
}

std::vector<fs::path> real_images() {
  const fs::path data = ls::testing::shared_data_dir();
  std::vector<fs::path> paths;
  for (const char* name : {"rti/loewenkopf_klein/jpg/Loewenkopf_klein_0001.jpg",
                           "rti/loewenkopf_klein/jpg/Loewenkopf_klein_0120.jpg",
                           "chrome_sphere/LightProbe-1/Image_01.JPG"}) {
    if (fs::exists(data / name)) paths.push_back(data / name);
  }
  return paths;
}

TEST(JpegReader, RealImagesAreOpenImageIOsToTheBit) {
  const std::vector<fs::path> paths = real_images();
  if (paths.empty()) GTEST_SKIP() << "no shared data at " << ls::testing::shared_data_dir();
  for (const fs::path& path : paths) {
    SCOPED_TRACE(path.string());
    std::unique_ptr<Reader> in = open_jpeg(path);
    ASSERT_NE(in, nullptr);
    const Spec& spec = in->spec();
    auto oiio = OIIO::ImageInput::open(path.string());
    ASSERT_NE(oiio, nullptr);
    EXPECT_EQ(spec.width, oiio->spec().width);
    EXPECT_EQ(spec.height, oiio->spec().height);
    EXPECT_EQ(spec.channels, 3);
    EXPECT_EQ(spec.format, Sample::kUInt8);
    EXPECT_EQ(spec.channel_names, (std::vector<std::string>{"R", "G", "B"}));
    EXPECT_EQ(spec.tile_width, 0);
    EXPECT_TRUE(SameBits(read_rows<float>(*in, 0, spec.height), oiio_read_samples<float>(path)));
    EXPECT_TRUE(SameBits(read_rows<std::uint8_t>(*in, 0, spec.height),
                         oiio_read_samples<std::uint8_t>(path)));
    EXPECT_TRUE(SameBits(read_rows<std::uint16_t>(*in, 0, spec.height),
                         oiio_read_samples<std::uint16_t>(path)));
    EXPECT_EQ(in->error(), "");
  }
}

TEST(JpegReader, BandsInAnyOrderAreTheWholeImage) {
  const std::vector<fs::path> paths = real_images();
  if (paths.empty()) GTEST_SKIP() << "no shared data at " << ls::testing::shared_data_dir();
  const std::vector<float> whole = oiio_read_samples<float>(paths[0]);
  std::unique_ptr<Reader> in = open_jpeg(paths[0]);
  ASSERT_NE(in, nullptr);
  const Spec& spec = in->spec();
  ASSERT_GE(spec.height, 31);
  for (int y0 = 0; y0 < spec.height; y0 += 7) {
    const int y1 = std::min(spec.height, y0 + 7);
    EXPECT_TRUE(SameBits(read_rows<float>(*in, y0, y1), rows_of(whole, spec, y0, y1)))
        << "rows " << y0 << "-" << y1;
  }
  // Below the rows read (skipped to), above them (decoded from the top again), empty.
  for (auto [y0, y1] :
       {std::pair{20, 30}, {0, 5}, {spec.height - 3, spec.height}, {10, 12}, {11, 11}, {11, 12}}) {
    EXPECT_TRUE(SameBits(read_rows<float>(*in, y0, y1), rows_of(whole, spec, y0, y1)))
        << "rows " << y0 << "-" << y1;
  }
  EXPECT_EQ(in->error(), "");
}

TEST(JpegReader, EveryCodeConvertsAsOpenImageIOConvertsIt) {
  // Flat 8x8 blocks, one per code, survive quality 100 unchanged.
  const int width = 8 * 256, height = 8;
  Bytes codes;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) codes.push_back((unsigned char)(x / 8));
  }
  Spec spec = jpeg_spec(width, height, 1);
  spec.set("Compression", "jpeg:100");
  ls::testing::TempDir dir;
  write_file(dir / "codes.jpg", encode_jpeg(spec, codes));
  std::unique_ptr<Reader> in = open_jpeg(dir / "codes.jpg");
  ASSERT_NE(in, nullptr);
  ASSERT_TRUE(SameBits(read_rows<std::uint8_t>(*in, 0, height), codes));
  const std::vector<float> floats = read_rows<float>(*in, 0, height);
  EXPECT_TRUE(SameBits(floats, oiio_read_samples<float>(dir / "codes.jpg")));
  EXPECT_TRUE(SameBits(read_rows<std::uint16_t>(*in, 0, height),
                       oiio_read_samples<std::uint16_t>(dir / "codes.jpg")));
  for (int code = 0; code < 256; ++code) {
    EXPECT_EQ(floats[std::size_t(code) * 8], float(code) * (1.0f / 255.0f)) << code;
  }
}

TEST(JpegReader, GrayscaleIsOneChannelAsOpenImageIOReadsIt) {
  ls::testing::TempDir dir;
  const fs::path path = dir / "gray.jpg";
  const int width = 53, height = 37;
  const Bytes codes = gradient(width, height, 1);
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_NE(out, nullptr);
  ASSERT_TRUE(out->open(path.string(), OIIO::ImageSpec(width, height, 1, OIIO::TypeDesc::UINT8)));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, codes.data()));
  ASSERT_TRUE(out->close());
  std::unique_ptr<Reader> in = open_jpeg(path);
  ASSERT_NE(in, nullptr);
  EXPECT_EQ(in->spec().channels, 1);
  EXPECT_EQ(in->spec().channel_names, std::vector<std::string>{"Y"});
  EXPECT_TRUE(SameBits(read_rows<float>(*in, 0, height), oiio_read_samples<float>(path)));
  EXPECT_TRUE(SameBits(read_rows<float>(*in, 30, height),
                       rows_of(oiio_read_samples<float>(path), in->spec(), 30, height)));
}

TEST(JpegReader, AFileCutShortReadsWithPrematureEnd) {
  const Bytes whole = encode_jpeg(jpeg_spec(64, 64, 3), noise(64, 64, 3));  // Mostly scan data.
  ls::testing::TempDir dir;
  write_file(dir / "cut.jpg",
             Bytes(whole.begin(), whole.begin() + std::ptrdiff_t(whole.size() / 2)));
  std::unique_ptr<Reader> in = open_jpeg(dir / "cut.jpg");
  ASSERT_NE(in, nullptr);
  std::vector<float> values(64 * 64 * 3);
  EXPECT_TRUE(in->read_rows(0, 64, Sample::kFloat, values.data()));
  EXPECT_NE(in->error().find("Premature end"), std::string::npos);
  EXPECT_EQ(in->error(), "");  // Taken.
  // The rows before the cut are the whole file's.
  write_file(dir / "whole.jpg", whole);
  std::unique_ptr<Reader> uncut = open_jpeg(dir / "whole.jpg");
  ASSERT_NE(uncut, nullptr);
  EXPECT_TRUE(SameBits(rows_of(values, in->spec(), 0, 8), read_rows<float>(*uncut, 0, 8)));
}

TEST(JpegReader, GarbageAfterTheMagicNeverCrashes) {
  ls::testing::TempDir dir;
  std::mt19937 random(18);
  const Bytes good = encode_jpeg(jpeg_spec(40, 24, 3), gradient(40, 24, 3));
  for (int i = 0; i < 300; ++i) {
    SCOPED_TRACE(i);
    Bytes bytes;
    if (i < 150) {  // The magic, then noise.
      bytes = {0xff, 0xd8, 0xff};
      const int size = int(random() % 4000);
      for (int k = 0; k < size; ++k) bytes.push_back((unsigned char)random());
    } else {  // A good file with a few bytes changed (its header or its data).
      bytes = good;
      for (int k = 0; k < 4; ++k)
        bytes[3 + random() % (bytes.size() - 3)] = (unsigned char)random();
    }
    write_file(dir / "bad.jpg", bytes);
    std::string error;
    std::unique_ptr<Reader> in = jpeg_codecs().open(dir / "bad.jpg", error);
    if (!in) {
      EXPECT_NE(error, "");
      continue;
    }
    const Spec& spec = in->spec();
    std::vector<float> values(std::size_t(spec.width) * spec.height * spec.channels);
    if (!in->read_rows(0, spec.height, Sample::kFloat, values.data())) {
      EXPECT_NE(in->error(), "");
    }
  }
}

TEST(JpegReader, WhatIsNoJpegIsAnErrorThatNamesNoFile) {
  ls::testing::TempDir dir;
  std::ofstream(dir / "text.jpg") << "no image here";
  std::string error;
  EXPECT_EQ(jpeg_codecs().open(dir / "text.jpg", error), nullptr);
  EXPECT_NE(error, "");
  EXPECT_EQ(error.find("text.jpg"), std::string::npos) << error;
  error.clear();
  EXPECT_EQ(jpeg_codecs().open(dir / "missing.jpg", error), nullptr);
  EXPECT_NE(error, "");
}

TEST(JpegReader, CmykAndYcckAreLeftToOpenImageIO) {
  ls::testing::TempDir dir;
  for (J_COLOR_SPACE space : {JCS_CMYK, JCS_YCCK}) {
    write_file(dir / "cmyk.jpg", four_channel_jpeg(space, 16, 8));
    std::string error;
    EXPECT_EQ(jpeg_codecs().open(dir / "cmyk.jpg", error), nullptr);
    EXPECT_EQ(error, "");  // Declined, not failed.
    EXPECT_NE(OIIO::ImageInput::open((dir / "cmyk.jpg").string()), nullptr);
  }
}

TEST(JpegReader, RowsOutsideTheImageOrAnUnknownTypeFail) {
  ls::testing::TempDir dir;
  write_file(dir / "a.jpg", encode_jpeg(jpeg_spec(16, 16, 3), gradient(16, 16, 3)));
  std::unique_ptr<Reader> in = open_jpeg(dir / "a.jpg");
  ASSERT_NE(in, nullptr);
  std::vector<float> values(16 * 17 * 3);
  EXPECT_FALSE(in->read_rows(0, 17, Sample::kFloat, values.data()));
  EXPECT_NE(in->error(), "");
  EXPECT_FALSE(in->read_rows(3, 2, Sample::kFloat, values.data()));
  EXPECT_NE(in->error(), "");
  EXPECT_FALSE(in->read_rows(0, 16, Sample::kHalf, values.data()));
  EXPECT_NE(in->error().find("half float"), std::string::npos);
  EXPECT_TRUE(in->read_rows(0, 16, Sample::kFloat, values.data())) << in->error();
}

TEST(JpegWriter, RoundTripsCloselyAndQualitySizesTheFile) {
  const int width = 70, height = 45;
  const Bytes codes = gradient(width, height, 3);
  Spec best = jpeg_spec(width, height, 3);
  best.set("Compression", "jpeg:100");
  best.set("jpeg:subsampling", "4:4:4");
  ls::testing::TempDir dir;
  write_file(dir / "best.jpg", encode_jpeg(best, codes));
  std::unique_ptr<Reader> in = open_jpeg(dir / "best.jpg");
  ASSERT_NE(in, nullptr);
  const Bytes back = read_rows<std::uint8_t>(*in, 0, height);
  ASSERT_EQ(back.size(), codes.size());
  int worst = 0;
  for (std::size_t i = 0; i < codes.size(); ++i)
    worst = std::max(worst, std::abs(back[i] - codes[i]));
  EXPECT_LE(worst, 3);
  // OpenImageIO reads what the writer was told.
  auto oiio = OIIO::ImageInput::open((dir / "best.jpg").string());
  ASSERT_NE(oiio, nullptr);
  EXPECT_EQ(oiio->spec().get_string_attribute("jpeg:subsampling"), "4:4:4");
  EXPECT_TRUE(
      SameBits(read_rows<float>(*in, 0, height), oiio_read_samples<float>(dir / "best.jpg")));

  Spec fair = jpeg_spec(width, height, 3);
  fair.set("Compression", "jpeg:50");
  EXPECT_LT(encode_jpeg(fair, codes).size(), encode_jpeg(best, codes).size());
  // Unset: quality 95, 4:2:0; floats are rounded to the same codes.
  Spec usual = jpeg_spec(width, height, 3);
  usual.set("Compression", "jpeg:95");
  usual.set("jpeg:subsampling", "4:2:0");
  const Bytes plain = encode_jpeg(jpeg_spec(width, height, 3), codes);
  EXPECT_EQ(plain, encode_jpeg(usual, codes));
  std::vector<float> floats(codes.begin(), codes.end());
  for (float& f : floats) f = f / 255.0f;
  EXPECT_EQ(plain, encode_jpeg(jpeg_spec(width, height, 3), floats));
  std::vector<std::uint16_t> wide(codes.begin(), codes.end());
  for (std::uint16_t& w : wide) w = std::uint16_t(w * 257);
  EXPECT_EQ(plain, encode_jpeg(jpeg_spec(width, height, 3), wide));
  Spec half_chroma = jpeg_spec(width, height, 3);
  half_chroma.set("jpeg:subsampling", "4:2:2");
  write_file(dir / "422.jpg", encode_jpeg(half_chroma, codes));
  oiio = OIIO::ImageInput::open((dir / "422.jpg").string());
  ASSERT_NE(oiio, nullptr);
  EXPECT_EQ(oiio->spec().get_string_attribute("jpeg:subsampling"), "4:2:2");
}

TEST(JpegWriter, FloatsAreClampedAndRounded) {
  const std::vector<float> values = {-1.0f, 0.0f, 0.5f / 255, 0.49f / 255,
                                     0.5f,  1.0f, 7.0f,       std::nanf("")};
  Spec spec = jpeg_spec(int(values.size()), 1, 1);
  spec.set("Compression", "jpeg:100");
  const Bytes codes = {0, 0, 1, 0, 128, 255, 255, 0};
  EXPECT_EQ(encode_jpeg(spec, values), encode_jpeg(spec, codes));
}

TEST(JpegWriter, RefusesWhatJpegCannotHold) {
  MemorySink sink;
  std::vector<Spec> specs = {jpeg_spec(8, 8, 2), jpeg_spec(8, 8, 4), jpeg_spec(0, 8, 3),
                             jpeg_spec(70000, 8, 3)};
  for (const char* compression : {"jpeg:0", "jpeg:101", "jpeg:x", "jpeg:90x", "zip", ""}) {
    specs.push_back(jpeg_spec(8, 8, 3));
    specs.back().set("Compression", compression);
  }
  specs.push_back(jpeg_spec(8, 8, 3));
  specs.back().set("Compression", 90LL);
  specs.push_back(jpeg_spec(8, 8, 3));
  specs.back().set("jpeg:subsampling", "4:1:1");
  specs.push_back(jpeg_spec(8, 8, 3));
  specs.back().tile_width = specs.back().tile_height = 8;
  for (const Spec& spec : specs) {
    std::string error;
    EXPECT_EQ(jpeg_codecs().create("x.jpg", spec, sink, error), nullptr);
    EXPECT_NE(error, "");
  }
}

TEST(JpegWriter, AFailingSinkIsCloseFalseWithItsMessage) {
  class FullDisk final : public Sink {
   public:
    void write_at(std::uint64_t, const void*, std::size_t) override {
      throw InputError("out.jpg: no space left on device");
    }
  } sink;
  std::string error;
  std::unique_ptr<Writer> out = jpeg_codecs().create("out.jpg", jpeg_spec(16, 8, 3), sink, error);
  ASSERT_NE(out, nullptr) << error;
  const Bytes codes = gradient(16, 8, 3);
  ASSERT_TRUE(out->write_rows(0, 8, Sample::kUInt8, codes.data()));
  EXPECT_FALSE(out->close());
  EXPECT_NE(out->error().find("no space left"), std::string::npos);
}

TEST(JpegWriter, RowsOutOfOrderOrMissingFailAndAnUnclosedWriterLeaksNothing) {
  MemorySink sink;
  std::string error;
  const Bytes codes = gradient(16, 8, 3);
  std::unique_ptr<Writer> out = jpeg_codecs().create("x.jpg", jpeg_spec(16, 8, 3), sink, error);
  ASSERT_NE(out, nullptr) << error;
  EXPECT_FALSE(out->write_rows(1, 2, Sample::kUInt8, codes.data()));
  EXPECT_NE(out->error(), "");
  EXPECT_FALSE(out->write_rows(0, 1, Sample::kHalf, codes.data()));
  EXPECT_NE(out->error(), "");
  ASSERT_TRUE(out->write_rows(0, 4, Sample::kUInt8, codes.data()));
  EXPECT_FALSE(out->close());
  EXPECT_NE(out->error().find("only 4 of 8"), std::string::npos);
  EXPECT_TRUE(sink.bytes.empty());
  // Destroyed part-way, past its first buffer (the sanitizer build checks that nothing leaks).
  out = jpeg_codecs().create("x.jpg", jpeg_spec(300, 300, 3), sink, error);
  ASSERT_NE(out, nullptr) << error;
  ASSERT_TRUE(out->write_rows(0, 300, Sample::kUInt8, noise(300, 300, 3).data()));
  out.reset();
}

TEST(JpegWriter, AFileLargerThanItsFirstBufferIsWhole) {
  Spec spec = jpeg_spec(300, 300, 3);
  spec.set("Compression", "jpeg:100");
  const Bytes bytes = encode_jpeg(spec, noise(300, 300, 3));
  EXPECT_GT(bytes.size(), 2u << 16);  // Grown twice.
  ls::testing::TempDir dir;
  write_file(dir / "noise.jpg", bytes);
  std::unique_ptr<Reader> in = open_jpeg(dir / "noise.jpg");
  ASSERT_NE(in, nullptr);
  EXPECT_TRUE(SameBits(read_rows<float>(*in, 0, 300), oiio_read_samples<float>(dir / "noise.jpg")));
  EXPECT_EQ(in->error(), "");
}

}  // namespace
}  // namespace ls::image_file
