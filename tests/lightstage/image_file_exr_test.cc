// OpenEXR through OpenEXR itself (lightstage/image_file_exr.cc) against OpenImageIO 2.4, which
// read and wrote the project's EXR files before: the same channel order, attributes and values,
// bit for bit, both ways.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <half.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <tuple>

#include "lightstage/errors.h"
#include "lightstage/image_file.h"
#include "tests/support/test_support.h"

namespace ls::image_file {
namespace {

namespace fs = std::filesystem;

void save(const fs::path& path, const std::vector<unsigned char>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

// Floats of every kind a file meets: ordinary, tiny, huge (past half's range), signed zeros,
// infinities, NaN, and the values half rounding treats differently from OpenEXR's floatToHalf.
std::vector<float> test_values(std::size_t count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uniform(-4.0f, 4.0f);
  const float inf = std::numeric_limits<float>::infinity();
  const float specials[] = {0.0f,  -0.0f, 1.0f,  65504.0f, 65519.0f, 65520.0f, 1e6f, -7e4f,
                            1e-7f, 6e-8f, 3e-5f, 0.5f,     1.5f,     inf,      -inf, std::nanf("")};
  std::vector<float> values(count);
  for (std::size_t i = 0; i < count; ++i) {
    values[i] = i % 7 == 3 ? specials[(i / 7) % std::size(specials)] : uniform(rng);
  }
  return values;
}

std::vector<std::uint16_t> halves_of(const std::vector<float>& values) {
  std::vector<std::uint16_t> out(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) out[i] = half(values[i]).bits();
  return out;
}

// Bytes of `count` values of `type`, for comparing bit for bit (NaN included).
template <class T>
std::vector<unsigned char> bytes_of(const std::vector<T>& values) {
  std::vector<unsigned char> out(values.size() * sizeof(T));
  std::memcpy(out.data(), values.data(), out.size());
  return out;
}

OIIO::TypeDesc oiio_type(Sample sample) {
  return sample == Sample::kHalf     ? OIIO::TypeDesc::HALF
         : sample == Sample::kUInt16 ? OIIO::TypeDesc::UINT16
         : sample == Sample::kUInt8  ? OIIO::TypeDesc::UINT8
                                     : OIIO::TypeDesc::FLOAT;
}

// The whole image as OpenImageIO reads it, converted to `as`, with its spec.
std::vector<unsigned char> oiio_read(const fs::path& path, Sample as, OIIO::ImageSpec* spec) {
  auto in = OIIO::ImageInput::open(path.string());
  EXPECT_TRUE(in) << OIIO::geterror();
  if (!in) return {};
  if (spec) *spec = in->spec();
  const OIIO::ImageSpec& s = in->spec();
  std::vector<unsigned char> out(std::size_t(s.width) * s.height * s.nchannels * sample_bytes(as));
  EXPECT_TRUE(in->read_image(0, 0, 0, s.nchannels, oiio_type(as), out.data())) << in->geterror();
  return out;
}

std::vector<unsigned char> mine_read(Reader& in, Sample as, int y0 = 0, int y1 = -1) {
  if (y1 < 0) y1 = in.spec().height;
  std::vector<unsigned char> out(std::size_t(in.spec().width) * (y1 - y0) * in.spec().channels *
                                 sample_bytes(as));
  EXPECT_TRUE(in.read_rows(y0, y1, as, out.data())) << in.error();
  return out;
}

std::unique_ptr<Reader> mine_open(const fs::path& path) {
  std::string error;
  auto in = exr_codecs().open(path, error);
  EXPECT_TRUE(in) << error;
  return in;
}

// `pixels` of `type` in a file OpenImageIO writes as `spec` says.
void oiio_write(const fs::path& path, const OIIO::ImageSpec& spec, const OIIO::TypeDesc& type,
                const void* pixels) {
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out && out->open(path.string(), spec)) << OIIO::geterror();
  ASSERT_TRUE(out->write_image(type, pixels)) << out->geterror();
  ASSERT_TRUE(out->close());
}

// "led001.R", "led001.G", "led001.B", "led002.R", ...: a reflectance field's channels.
std::vector<std::string> led_names(int leds) {
  std::vector<std::string> names;
  for (int led = 1; led <= leds; ++led) {
    for (const char* c : {"R", "G", "B"}) {
      names.push_back("led" + std::string(led < 10 ? "00" : "0") + std::to_string(led) + "." + c);
    }
  }
  return names;
}

// Names and pixels (each channel's values its index in `names`) in the order OpenImageIO gives.
void expect_order_as_oiio(const fs::path& path, const std::vector<std::string>& names) {
  OIIO::ImageSpec spec(3, 2, int(names.size()), OIIO::TypeDesc::FLOAT);
  spec.channelnames = names;
  std::vector<float> pixels(6 * names.size());
  for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = float(i % names.size());
  oiio_write(path, spec, OIIO::TypeDesc::FLOAT, pixels.data());
  const auto in = mine_open(path);
  ASSERT_TRUE(in);
  OIIO::ImageSpec theirs;
  EXPECT_EQ(mine_read(*in, Sample::kFloat), oiio_read(path, Sample::kFloat, &theirs));
  EXPECT_EQ(in->spec().channel_names, theirs.channelnames);
}

TEST(ExrCodecs, ChannelOrderIsOpenImageIOs) {
  ls::testing::TempDir dir;
  const fs::path path = dir / "order.exr";
  const std::vector<std::pair<std::vector<std::string>, std::vector<std::string>>> cases = {
      {{"R", "G", "B"}, {"R", "G", "B"}},
      {{"A", "B", "G", "R"}, {"R", "G", "B", "A"}},
      {{"normal.Z", "albedo.B", "normal.X", "albedo.R", "normal.Y", "albedo.G"},
       {"albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z"}},
      {{"model", "Z", "b", "r", "g", "alpha"}, {"r", "g", "b", "alpha", "Z", "model"}},
      {{"P.Z", "P.X", "P.Y", "P.A"}, {"P.X", "P.Y", "P.Z", "P.A"}},
      {{"a.R", "a-b.R", "a.G", "b"}, {"b", "a-b.R", "a.R", "a.G"}},  // Layers keep their '.'.
      {{"a.x", "a.y.R", "a.z"}, {"a.x", "a.z", "a.y.R"}},  // A layer split by OpenEXR's order.
  };
  for (const auto& [names, expected] : cases) {
    expect_order_as_oiio(path, names);
    const auto in = mine_open(path);
    ASSERT_TRUE(in);
    EXPECT_EQ(in->spec().channel_names, expected);
  }
  const std::vector<std::string> leds = led_names(10);
  expect_order_as_oiio(path, {leds.rbegin(), leds.rend()});
  EXPECT_EQ(mine_open(path)->spec().channel_names, leds);

  // Random sets from the names OpenImageIO treats specially, in and out of layers.
  const char* suffixes[] = {"R", "g", "Blue",  "A",     "alpha", "X",    "Y",  "Z",
                            "x", "z", "depth", "Zback", "real",  "imag", "AR", "ba",
                            "u", "v", "red",   "RY",    "BY",    "mask", ""};
  const char* layers[] = {"", "", "n.", "a.", "a-b.", "a.b.", "a.y.", "N.", "diffuse.", "x."};
  std::mt19937 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<std::string> names;
    const int count = 1 + int(rng() % 8);
    for (int i = 0; i < count; ++i) {
      std::string name =
          std::string(layers[rng() % std::size(layers)]) + suffixes[rng() % std::size(suffixes)];
      if (name.empty() || std::find(names.begin(), names.end(), name) != names.end()) continue;
      names.push_back(name);
    }
    if (names.empty()) continue;
    SCOPED_TRACE(::testing::PrintToString(names));
    expect_order_as_oiio(path, names);
  }
}

// Our writer's file of `values` (of type `from`, interleaved rows), written `band` rows at a time.
std::vector<unsigned char> write_mine(const Spec& spec, Sample from, const void* values, int band) {
  MemorySink sink;
  std::string error;
  auto out = exr_codecs().create("x.exr", spec, sink, error);
  EXPECT_TRUE(out) << error;
  if (!out) return {};
  const std::size_t row_bytes = std::size_t(spec.width) * spec.channels * sample_bytes(from);
  for (int y = 0; y < spec.height; y += band) {
    const int y1 = std::min(spec.height, y + band);
    EXPECT_TRUE(out->write_rows(y, y1, from, static_cast<const char*>(values) + y * row_bytes))
        << out->error();
  }
  EXPECT_TRUE(out->close()) << out->error();
  return std::move(sink.bytes);
}

Spec exr_spec(int width, int height, std::vector<std::string> names, Sample format) {
  Spec spec;
  spec.width = width;
  spec.height = height;
  spec.channels = int(names.size());
  spec.channel_names = std::move(names);
  spec.format = format;
  return spec;
}

// The value of OpenImageIO's attribute `name`, of type `type`.
template <class T>
T oiio_attribute(const OIIO::ImageSpec& spec, const char* name, const OIIO::TypeDesc& type) {
  const OIIO::ParamValue* p = spec.find_attribute(name, type);
  EXPECT_TRUE(p) << name << " as " << type;
  return p ? p->get<T>() : T();
}

TEST(ExrCodecs, WrittenFilesReadTheSameThroughOpenImageIO) {
  ls::testing::TempDir dir;
  const fs::path path = dir / "mine.exr";
  const int width = 37, height = 23;
  const std::vector<std::string> names = {"R", "G", "B", "A", "mask"};
  const std::vector<float> floats = test_values(std::size_t(width) * height * names.size(), 1);
  const std::vector<std::uint16_t> halves = halves_of(floats);
  std::vector<float> widened(floats.size());
  for (std::size_t i = 0; i < floats.size(); ++i) widened[i] = float(half(floats[i]));
  for (const Sample format : {Sample::kHalf, Sample::kFloat}) {
    for (const Sample from : {Sample::kFloat, Sample::kHalf}) {
      for (const int tile : {0, 8}) {
        for (const char* compression : {"none", "zip", "zips", "rle", "piz"}) {
          SCOPED_TRACE(std::string(sample_name(format)) + " from " + sample_name(from) + ", tile " +
                       std::to_string(tile) + ", " + compression);
          Spec spec = exr_spec(width, height, names, format);
          spec.tile_width = tile;
          spec.tile_height = tile / 2;
          spec.set("compression", compression);
          spec.set("lightstage:text", "hello");
          spec.set("lightstage:double", 0.1);
          spec.set("lightstage:float", 0.25, "float");
          spec.set("lightstage:int", 42LL);
          const void* data = from == Sample::kFloat ? (const void*)floats.data() : halves.data();
          save(path, write_mine(spec, from, data, tile > 0 ? tile : 5));
          // What the file must hold: the values, as halves where the file or input is half.
          const std::vector<unsigned char> expected = format == Sample::kHalf ? bytes_of(halves)
                                                      : from == Sample::kHalf ? bytes_of(widened)
                                                                              : bytes_of(floats);
          OIIO::ImageSpec theirs;
          EXPECT_EQ(oiio_read(path, format, &theirs), expected);
          EXPECT_EQ(theirs.channelnames, names);
          EXPECT_EQ(theirs.tile_width, tile);
          EXPECT_EQ(theirs.tile_height, tile / 2);
          EXPECT_EQ(theirs.get_string_attribute("compression"), compression);
          EXPECT_EQ(theirs.get_string_attribute("lightstage:text"), "hello");
          EXPECT_EQ(oiio_attribute<double>(theirs, "lightstage:double", OIIO::TypeDesc::DOUBLE),
                    0.1);
          EXPECT_EQ(oiio_attribute<float>(theirs, "lightstage:float", OIIO::TypeDesc::FLOAT),
                    0.25f);
          EXPECT_EQ(oiio_attribute<int>(theirs, "lightstage:int", OIIO::TypeDesc::INT), 42);

          const auto in = mine_open(path);
          ASSERT_TRUE(in);
          EXPECT_EQ(mine_read(*in, format), expected);
          for (const Sample as : {Sample::kFloat, Sample::kHalf, Sample::kUInt16}) {
            EXPECT_EQ(mine_read(*in, as), oiio_read(path, as, nullptr)) << sample_name(as);
          }
          const Spec& ours = in->spec();
          EXPECT_EQ(ours.format, format);
          EXPECT_EQ(ours.channel_names, names);
          EXPECT_EQ(ours.tile_width, tile);
          for (const Attribute& written : spec.attributes) {  // Values and types.
            const Attribute* read = ours.find(written.name);
            ASSERT_TRUE(read) << written.name;
            EXPECT_EQ(read->value, written.value) << written.name;
            EXPECT_EQ(read->type_name, written.type_name) << written.name;
          }
        }
      }
    }
  }
}

// Floats into a half file round as OpenImageIO rounded them (65519 to 65504, not infinity).
TEST(ExrCodecs, FloatsBecomeTheHalvesOpenImageIOMade) {
  ls::testing::TempDir dir;
  const int width = 16, height = 12;
  const std::vector<float> floats = test_values(std::size_t(width) * height * 3, 2);
  save(dir / "mine.exr", write_mine(exr_spec(width, height, {"R", "G", "B"}, Sample::kHalf),
                                    Sample::kFloat, floats.data(), 5));
  oiio_write(dir / "theirs.exr", OIIO::ImageSpec(width, height, 3, OIIO::TypeDesc::HALF),
             OIIO::TypeDesc::FLOAT, floats.data());
  EXPECT_EQ(oiio_read(dir / "mine.exr", Sample::kHalf, nullptr),
            oiio_read(dir / "theirs.exr", Sample::kHalf, nullptr));
}

// A file OpenImageIO wrote: channels in no order, a data window off the origin, attributes of
// four types.
void write_oiio(const fs::path& path, const OIIO::TypeDesc& type, int tile, const char* compression,
                const std::vector<float>& floats) {
  OIIO::ImageSpec spec(29, 21, 9, type);
  spec.channelnames = {"Z", "B", "normal.Y", "R", "G", "normal.X", "A", "normal.Z", "id"};
  spec.x = 3;
  spec.y = -2;
  spec.tile_width = tile;
  spec.tile_height = tile / 2;
  spec.attribute("compression", compression);
  spec.attribute("note", "a note");
  const double time = 12.125;
  spec.attribute("scene_time", OIIO::TypeDesc::DOUBLE, &time);
  spec.attribute("count", 42);
  const float dir[3] = {1.0f, 2.5f, -3.0f};
  spec.attribute("dir", OIIO::TypeVector, dir);
  oiio_write(path, spec, OIIO::TypeDesc::FLOAT, floats.data());
}

TEST(ExrCodecs, OpenImageIOsFilesReadAsItReadThem) {
  ls::testing::TempDir dir;
  const fs::path path = dir / "theirs.exr";
  const std::vector<float> floats = test_values(std::size_t{29} * 21 * 9, 3);
  for (const OIIO::TypeDesc type : {OIIO::TypeDesc::HALF, OIIO::TypeDesc::FLOAT}) {
    for (const int tile : {0, 16}) {
      for (const char* compression : {"zip", "none"}) {
        SCOPED_TRACE(std::string(type.c_str()) + ", tile " + std::to_string(tile) + ", " +
                     compression);
        write_oiio(path, type, tile, compression, floats);
        OIIO::ImageSpec theirs;
        const std::vector<unsigned char> as_float = oiio_read(path, Sample::kFloat, &theirs);
        const auto in = mine_open(path);
        ASSERT_TRUE(in);
        const Spec& ours = in->spec();
        EXPECT_EQ(
            std::tie(ours.width, ours.height, ours.channels, ours.tile_width, ours.tile_height),
            std::tie(theirs.width, theirs.height, theirs.nchannels, theirs.tile_width,
                     theirs.tile_height));
        EXPECT_EQ(ours.channel_names, theirs.channelnames);
        EXPECT_EQ(ours.format, type == OIIO::TypeDesc::HALF ? Sample::kHalf : Sample::kFloat);
        EXPECT_EQ(mine_read(*in, Sample::kFloat), as_float);
        for (const Sample as : {Sample::kHalf, Sample::kUInt16, Sample::kUInt8}) {
          EXPECT_EQ(mine_read(*in, as), oiio_read(path, as, nullptr)) << sample_name(as);
        }
        const std::pair<const char*, const char*> typed[] = {{"compression", "string"},
                                                             {"note", "string"},
                                                             {"scene_time", "double"},
                                                             {"count", "int"},
                                                             {"dir", "v3f"}};
        for (const auto& [name, type] : typed) {
          const Attribute* a = ours.find(name);
          const OIIO::ParamValue* p = theirs.find_attribute(name);
          ASSERT_TRUE(a && p) << name;
          EXPECT_EQ(a->type_name, type) << name;
          if (a->text()) {
            EXPECT_EQ(*a->text(), p->get_string()) << name;
          } else if (p->type() == OIIO::TypeDesc::INT) {
            EXPECT_EQ(a->number(), p->get_int()) << name;
          } else {
            EXPECT_EQ(a->number(), p->get<double>()) << name;
          }
        }
        EXPECT_EQ(*ours.find("dir")->text(), "1, 2.5, -3");
        for (const char* layout : {"dataWindow", "channels", "lineOrder", "tiles"}) {
          EXPECT_FALSE(ours.find(layout)) << layout;
        }
      }
    }
  }
}

TEST(ExrCodecs, RowsReadInBandsEqualTheWhole) {
  ls::testing::TempDir dir;
  const fs::path path = dir / "theirs.exr";
  const std::vector<float> floats = test_values(std::size_t{29} * 21 * 9, 4);
  for (const int tile : {0, 16}) {
    write_oiio(path, OIIO::TypeDesc::HALF, tile, "zip", floats);
    const auto in = mine_open(path);
    ASSERT_TRUE(in);
    for (const Sample as : {Sample::kFloat, Sample::kHalf, Sample::kUInt16}) {
      const std::vector<unsigned char> whole = mine_read(*in, as);
      const std::size_t row_bytes = whole.size() / std::size_t(in->spec().height);
      for (const int band : {1, 3, 7, 8, 16}) {
        // Bottom band first: rows are asked in any order.
        for (int y0 = (in->spec().height - 1) / band * band; y0 >= 0; y0 -= band) {
          const int y1 = std::min(in->spec().height, y0 + band);
          const std::vector<unsigned char> rows = mine_read(*in, as, y0, y1);
          ASSERT_TRUE(std::equal(rows.begin(), rows.end(), whole.begin() + y0 * row_bytes))
              << "tile " << tile << ", " << sample_name(as) << ", rows " << y0 << ".." << y1;
        }
      }
    }
  }
}

// 32-bit unsigned channels: normalised to [0, 1] as OpenImageIO normalised them.
TEST(ExrCodecs, UnsignedChannelsConvertAsOpenImageIOConverted) {
  ls::testing::TempDir dir;
  const std::string path = (dir / "uint.exr").string();
  std::vector<std::uint32_t> values(std::size_t{13} * 7 * 2);
  std::mt19937 rng(5);
  for (std::size_t i = 0; i < values.size(); ++i) {
    values[i] = i % 5 == 0 ? std::uint32_t(-1) - std::uint32_t(i) : std::uint32_t(rng());
  }
  values[1] = 0;
  OIIO::ImageSpec spec(13, 7, 2, OIIO::TypeDesc::UINT32);
  spec.channelnames = {"id", "mask"};
  oiio_write(path, spec, OIIO::TypeDesc::UINT32, values.data());
  const auto in = mine_open(path);
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().format, Sample::kOther);
  for (const Sample as : {Sample::kFloat, Sample::kHalf, Sample::kUInt16}) {
    EXPECT_EQ(mine_read(*in, as), oiio_read(path, as, nullptr)) << sample_name(as);
  }
}

// Integer codes from floats: rounded and clamped as OpenImageIO did, at every 16-bit code's edges.
TEST(ExrCodecs, IntegerCodesRoundAsOpenImageIORoundedThem) {
  ls::testing::TempDir dir;
  std::vector<float> floats(std::size_t{256} * 520);
  for (std::size_t i = 0; i < floats.size(); ++i) {
    floats[i] = i < 131071 ? float(double(i) / 131070.0) : float(i - 131071) / 1024.0f - 1.0f;
  }
  save(dir / "codes.exr",
       write_mine(exr_spec(256, 520, {"Y"}, Sample::kFloat), Sample::kFloat, floats.data(), 520));
  const auto in = mine_open(dir / "codes.exr");
  ASSERT_TRUE(in);
  for (const Sample as : {Sample::kUInt16, Sample::kUInt8}) {
    EXPECT_EQ(mine_read(*in, as), oiio_read(dir / "codes.exr", as, nullptr)) << sample_name(as);
  }
}

TEST(ExrCodecs, TruncatedFilesFailWithAReason) {
  ls::testing::TempDir dir;
  const std::vector<float> floats = test_values(std::size_t{64} * 48 * 3, 6);
  for (const int tile : {0, 16}) {
    for (const char* compression : {"zip", "none"}) {
      Spec spec = exr_spec(64, 48, {"R", "G", "B"}, Sample::kHalf);
      spec.tile_width = spec.tile_height = tile;
      spec.set("compression", compression);
      const std::vector<unsigned char> whole = write_mine(spec, Sample::kFloat, floats.data(), 16);
      for (const double kept : {0.5, 0.9, 0.99, 0.3, 0.05}) {
        SCOPED_TRACE("tile " + std::to_string(tile) + ", " + compression + ", " +
                     std::to_string(kept) + " of the file");
        const fs::path path = dir / "cut.exr";
        save(path, {whole.begin(), whole.begin() + std::ptrdiff_t(whole.size() * kept)});
        std::string error;
        const auto in = exr_codecs().open(path, error);
        if (!in) {
          EXPECT_FALSE(error.empty());
          continue;
        }
        std::vector<float> pixels(std::size_t{64} * 48 * 3);
        EXPECT_FALSE(in->read_rows(0, 48, Sample::kFloat, pixels.data()));
        EXPECT_FALSE(in->error().empty());
        EXPECT_TRUE(in->error().empty());  // error() clears.
      }
    }
  }
  std::string error;
  EXPECT_FALSE(exr_codecs().open(dir / "missing.exr", error));
  EXPECT_FALSE(error.empty());
}

// A sink that fails: past `limit` bytes, or (rewrites) on any write before its end.
class FailingSink final : public Sink {
 public:
  explicit FailingSink(std::uint64_t limit, bool fail_rewrites = false)
      : limit_(limit), fail_rewrites_(fail_rewrites) {}
  void write_at(std::uint64_t offset, const void* data, std::size_t size) override {
    if (offset + size > limit_ || (fail_rewrites_ && offset < memory.bytes.size())) {
      throw InputError("out.exr: cannot write: No space left on device");
    }
    memory.write_at(offset, data, size);
  }
  MemorySink memory;

 private:
  std::uint64_t limit_;
  bool fail_rewrites_;
};

TEST(ExrCodecs, AFailingSinkFailsTheWriteWithItsMessage) {
  const std::vector<float> floats = test_values(std::size_t{40} * 40 * 3, 7);
  for (const int tile : {0, 16}) {
    Spec spec = exr_spec(40, 40, {"R", "G", "B"}, Sample::kFloat);
    spec.tile_width = spec.tile_height = tile;
    spec.set("compression", "none");
    const std::size_t full = write_mine(spec, Sample::kFloat, floats.data(), 16).size();
    for (const std::uint64_t limit : {std::uint64_t(0), std::uint64_t(full / 2),
                                      std::uint64_t(full - 1), std::uint64_t(full)}) {
      SCOPED_TRACE("tile " + std::to_string(tile) + ", limit " + std::to_string(limit) + " of " +
                   std::to_string(full));
      FailingSink sink(limit, /*fail_rewrites=*/limit == full);
      std::string error;
      auto out = exr_codecs().create("out.exr", spec, sink, error);
      if (!out) {
        EXPECT_NE(error.find("No space left on device"), std::string::npos) << error;
        continue;
      }
      bool wrote = true;
      for (int y = 0; y < 40 && wrote; y += 16) {
        wrote = out->write_rows(y, std::min(40, y + 16), Sample::kFloat,
                                floats.data() + std::ptrdiff_t{y} * 40 * 3);
      }
      // The offset table, rewritten last, fails only in close: OpenEXR's destructors swallow it.
      if (limit == full) {
        EXPECT_TRUE(wrote) << out->error();
      }
      EXPECT_FALSE(wrote && out->close());
      EXPECT_NE(out->error().find("No space left on device"), std::string::npos);
    }
    // Destroyed without close, after a failure: no exception.
    FailingSink sink(full / 2);
    std::string error;
    auto out = exr_codecs().create("out.exr", spec, sink, error);
    ASSERT_TRUE(out) << error;
    out->write_rows(0, 32, Sample::kFloat, floats.data());
    EXPECT_NO_THROW(out.reset());
  }
}

// A reflectance field's layout: 3 channels a LED, tiles of 16, halves, uncompressed.
TEST(ExrCodecs, FieldLikeFilesReadBackByOpenImageIO) {
  ls::testing::TempDir dir;
  const int width = 50, height = 37;
  const std::vector<std::string> names = led_names(10);
  Spec spec = exr_spec(width, height, names, Sample::kHalf);
  spec.tile_width = spec.tile_height = 16;
  spec.set("compression", "none");
  spec.set("lightstage:lights", "[]");
  spec.set("lightstage:scene_time_s", 1.5);
  const std::vector<std::uint16_t> halves =
      halves_of(test_values(std::size_t(width) * height * names.size(), 8));
  save(dir / "field.exr", write_mine(spec, Sample::kHalf, halves.data(), 16));
  OIIO::ImageSpec theirs;
  EXPECT_EQ(oiio_read(dir / "field.exr", Sample::kHalf, &theirs), bytes_of(halves));
  EXPECT_EQ(theirs.channelnames, names);
  EXPECT_EQ(theirs.tile_width, 16);
  EXPECT_EQ(theirs.tile_height, 16);
  EXPECT_EQ(theirs.get_string_attribute("compression"), "none");
  EXPECT_EQ(theirs.get_string_attribute("lightstage:lights"), "[]");
  EXPECT_EQ(oiio_attribute<double>(theirs, "lightstage:scene_time_s", OIIO::TypeDesc::DOUBLE), 1.5);
  const auto in = mine_open(dir / "field.exr");
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().channel_names, names);
  EXPECT_EQ(mine_read(*in, Sample::kHalf), bytes_of(halves));
}

TEST(ExrCodecs, CompressionsAreTheOnesOpenImageIONamed) {
  ls::testing::TempDir dir;
  const std::vector<float> floats = test_values(std::size_t{8} * 8 * 3, 9);
  for (const char* name :
       {"none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"}) {
    Spec spec = exr_spec(8, 8, {"R", "G", "B"}, Sample::kHalf);
    spec.set("compression", name);
    save(dir / "c.exr", write_mine(spec, Sample::kFloat, floats.data(), 8));
    OIIO::ImageSpec theirs;
    EXPECT_EQ(mine_read(*mine_open(dir / "c.exr"), Sample::kFloat),
              oiio_read(dir / "c.exr", Sample::kFloat, &theirs));
    EXPECT_EQ(theirs.get_string_attribute("compression"), name);
    EXPECT_EQ(*mine_open(dir / "c.exr")->spec().find("compression")->text(), name);
  }
  Spec spec = exr_spec(8, 8, {"R", "G", "B"}, Sample::kHalf);  // No compression named: zip.
  save(dir / "c.exr", write_mine(spec, Sample::kFloat, floats.data(), 8));
  EXPECT_EQ(*mine_open(dir / "c.exr")->spec().find("compression")->text(), "zip");
}

TEST(ExrCodecs, RefusesWhatItCannotWrite) {
  MemorySink sink;
  std::string error;
  auto refused = [&](const Spec& spec) {
    error.clear();
    const bool null = !exr_codecs().create("x.exr", spec, sink, error);
    return null && !error.empty();
  };
  const Spec good = exr_spec(8, 8, {"R", "G", "B"}, Sample::kFloat);
  EXPECT_TRUE(refused(exr_spec(8, 8, {"R", "G", "B"}, Sample::kUInt8)));
  Spec spec = good;
  spec.channel_names.pop_back();
  EXPECT_TRUE(refused(spec));
  EXPECT_TRUE(refused(exr_spec(8, 8, {"R", "G", "R"}, Sample::kFloat)));  // A name twice.
  spec = good;
  spec.set("compression", "lzw");
  EXPECT_TRUE(refused(spec));
  EXPECT_NE(error.find("lzw"), std::string::npos) << error;
  spec = good;
  spec.width = 0;
  EXPECT_TRUE(refused(spec));

  const std::vector<float> floats(std::size_t{8} * 8 * 3, 0.5f);
  auto out = exr_codecs().create("x.exr", good, sink, error);
  ASSERT_TRUE(out) << error;
  EXPECT_FALSE(out->write_rows(0, 4, Sample::kUInt16, floats.data()));
  EXPECT_FALSE(out->error().empty());
  EXPECT_FALSE(out->write_rows(4, 8, Sample::kFloat, floats.data()));  // Out of order.
  EXPECT_FALSE(out->error().empty());
  EXPECT_TRUE(out->error().empty());  // error() clears.
  EXPECT_TRUE(out->write_rows(0, 4, Sample::kFloat, floats.data()));
  EXPECT_FALSE(out->close());  // Rows 4.. never written.
  EXPECT_NE(out->error().find("row 4"), std::string::npos);

  Spec tiled = good;
  tiled.tile_width = tiled.tile_height = 4;
  out = exr_codecs().create("x.exr", tiled, sink, error);
  ASSERT_TRUE(out) << error;
  EXPECT_FALSE(out->write_rows(0, 3, Sample::kFloat, floats.data()));  // Not whole tiles.
  EXPECT_FALSE(out->error().empty());
  EXPECT_TRUE(out->write_rows(4, 8, Sample::kFloat, floats.data()));  // Tiles in any order.
  EXPECT_TRUE(out->write_rows(0, 4, Sample::kFloat, floats.data()));
  EXPECT_TRUE(out->close()) << out->error();
}

}  // namespace
}  // namespace ls::image_file
