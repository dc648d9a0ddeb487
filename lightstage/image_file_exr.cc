// OpenEXR files read and written with OpenEXR itself (lightstage/image_file.h), as OpenImageIO 2.4
// read and wrote them before: the same channel order and attributes (image_file_exr_header.h), the
// same values bit for bit. OpenImageIO's conversions are kept where OpenEXR's own differ or are
// missing: floats become halves by rounding (OpenEXR's floatToHalf makes every float above 65504
// infinite), 32-bit unsigned channels read as floats are normalised to [0, 1], and a file's type
// is written from the other (OpenEXR writes only the type a channel has).
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfThreading.h>
#include <ImfTiledOutputFile.h>
#include <half.h>

#include <algorithm>
#include <climits>
#include <exception>
#include <thread>
#include <utility>

#include "lightstage/errors.h"
#include "lightstage/image_file.h"
#include "lightstage/image_file_exr_header.h"

namespace ls::image_file {
namespace {

// OpenImageIO decoded EXR with every hardware thread (its "exr_threads" default); so do we, unless
// the process has set OpenEXR's pool itself.
int exr_threads() {
  static const bool started = [] {
    if (Imf::globalThreadCount() <= 0) {
      Imf::setGlobalThreadCount(int(std::max(1u, std::thread::hardware_concurrency())));
    }
    return true;
  }();
  (void)started;
  return Imf::globalThreadCount();
}

// Rows converted at a time through a scratch buffer (a band's values may be large).
constexpr std::size_t kScratchBytes = std::size_t(4) << 20;

// Whole tiles (tile_rows > 0) of about kScratchBytes.
int rows_per_piece(std::size_t row_bytes, int tile_rows) {
  const int step = std::max(1, tile_rows);
  return std::max(step, int(kScratchBytes / std::max<std::size_t>(1, row_bytes)) / step * step);
}

// A frame buffer of `rows` rows from `origin`, the channels of `names` interleaved at `first`.
Imf::FrameBuffer frame_of(const std::vector<std::string>& names, Imf::PixelType type, int width,
                          const Imath::V2i& origin, int rows, const char* first) {
  const std::size_t value_bytes = type == Imf::HALF ? 2 : 4;
  const std::size_t x_stride = value_bytes * names.size();
  Imf::FrameBuffer frame;
  for (std::size_t c = 0; c < names.size(); ++c) {
    frame.insert(names[c], Imf::Slice::Make(type, first + c * value_bytes, origin, width, rows,
                                            x_stride, x_stride * std::size_t(width)));
  }
  return frame;
}

// ---- Conversions, as OpenImageIO made them -----------------------------------------------------

// A float to an integer code of `max` (65535, 255): scaled, rounded half away from zero, clamped;
// NaN to 0.
template <class T>
T to_code(float v, float max) {
  float s = v * max;
  s += s < 0 ? -0.5f : 0.5f;
  if (!(s > 0)) return 0;
  return s >= max ? T(max) : T(s);
}

void convert_floats(const float* in, std::size_t count, Sample as, void* out) {
  switch (as) {
    case Sample::kHalf:
      for (std::size_t i = 0; i < count; ++i) static_cast<half*>(out)[i] = half(in[i]);
      break;
    case Sample::kUInt16:
      for (std::size_t i = 0; i < count; ++i) {
        static_cast<std::uint16_t*>(out)[i] = to_code<std::uint16_t>(in[i], 65535.0f);
      }
      break;
    case Sample::kUInt8:
      for (std::size_t i = 0; i < count; ++i) {
        static_cast<std::uint8_t*>(out)[i] = to_code<std::uint8_t>(in[i], 255.0f);
      }
      break;
    default:
      std::copy(in, in + count, static_cast<float*>(out));
  }
}

// ---- Reading ----------------------------------------------------------------------------------

class ExrReader final : public Reader {
 public:
  // Null with `error` set when OpenEXR cannot open it or OpenImageIO would not have read it.
  static std::unique_ptr<ExrReader> open(const std::filesystem::path& path, std::string& error);

  const Spec& spec() const override { return spec_; }
  bool read_rows(int y0, int y1, Sample as, void* out) override;
  std::string error() override { return std::exchange(error_, {}); }

 private:
  // Rows [y0, y1) as `type` (FLOAT or HALF slices; OpenEXR converts), interleaved into `out`;
  // unsigned channels' floats normalised to [0, 1] as OpenImageIO normalised them.
  void read_slices(int y0, int y1, Imf::PixelType type, char* out);

  std::unique_ptr<Imf::InputFile> in_;
  Spec spec_;
  std::vector<Imf::PixelType> types_;  // Of each channel, in spec_'s order.
  Imath::V2i origin_;                  // The data window's top left.
  std::vector<float> scratch_;
  std::string error_;
};

std::unique_ptr<ExrReader> ExrReader::open(const std::filesystem::path& path, std::string& error) {
  auto reader = std::make_unique<ExrReader>();
  try {
    reader->in_ = std::make_unique<Imf::InputFile>(path.c_str(), exr_threads());
    const Imf::Header& header = reader->in_->header();
    Spec& spec = reader->spec_;
    const Imath::Box2i window = header.dataWindow();
    reader->origin_ = window.min;
    spec.width = window.max.x - window.min.x + 1;
    spec.height = window.max.y - window.min.y + 1;
    for (const ExrChannel& c : exr_channels_in_oiio_order(header.channels())) {
      const Imf::Channel& channel = header.channels()[c.name];
      if (channel.xSampling != 1 || channel.ySampling != 1) {
        error = "channel '" + c.name + "' is subsampled (" + std::to_string(channel.xSampling) +
                "x" + std::to_string(channel.ySampling) + "): not supported";
        return nullptr;
      }
      spec.channel_names.push_back(c.name);
      reader->types_.push_back(c.type);
    }
    spec.channels = int(spec.channel_names.size());
    if (spec.channels == 0) {
      error = "no channels";
      return nullptr;
    }
    spec.format = reader->types_[0] == Imf::HALF    ? Sample::kHalf
                  : reader->types_[0] == Imf::FLOAT ? Sample::kFloat
                                                    : Sample::kOther;
    if (header.hasTileDescription()) {
      spec.tile_width = int(header.tileDescription().xSize);
      spec.tile_height = int(header.tileDescription().ySize);
    }
    spec.attributes = exr_attributes(header);
  } catch (const std::exception& e) {
    error = e.what();
    return nullptr;
  }
  return reader;
}

void ExrReader::read_slices(int y0, int y1, Imf::PixelType type, char* out) {
  in_->setFrameBuffer(
      frame_of(spec_.channel_names, type, spec_.width, {origin_.x, origin_.y + y0}, y1 - y0, out));
  in_->readPixels(origin_.y + y0, origin_.y + y1 - 1);
  if (type != Imf::FLOAT) return;
  const float scale = 1.0f / float(UINT_MAX);  // OpenImageIO's normalisation of unsigned values.
  const std::size_t values = std::size_t(y1 - y0) * std::size_t(spec_.width) * types_.size();
  for (std::size_t c = 0; c < types_.size(); ++c) {
    if (types_[c] != Imf::UINT) continue;
    float* floats = reinterpret_cast<float*>(out);
    for (std::size_t i = c; i < values; i += types_.size()) floats[i] *= scale;
  }
}

bool ExrReader::read_rows(int y0, int y1, Sample as, void* out) {
  if (y0 < 0 || y1 > spec_.height || y0 > y1) {
    error_ = "rows " + std::to_string(y0) + ".." + std::to_string(y1) +
             " are outside the image's " + std::to_string(spec_.height);
    return false;
  }
  if (as != Sample::kFloat && as != Sample::kHalf && as != Sample::kUInt16 &&
      as != Sample::kUInt8) {
    error_ = std::string("cannot read EXR pixels as ") + sample_name(as);
    return false;
  }
  if (y0 == y1) return true;
  const std::size_t row_values = std::size_t(spec_.width) * std::size_t(spec_.channels);
  const bool all_half =
      std::all_of(types_.begin(), types_.end(), [](Imf::PixelType t) { return t == Imf::HALF; });
  try {
    if (as == Sample::kFloat) {
      read_slices(y0, y1, Imf::FLOAT, static_cast<char*>(out));
    } else if (as == Sample::kHalf && all_half) {
      read_slices(y0, y1, Imf::HALF, static_cast<char*>(out));  // As stored: no conversion.
    } else {
      // Through floats, a piece at a time, as OpenImageIO converted.
      const int piece = rows_per_piece(row_values * sizeof(float), spec_.tile_height);
      for (int a = y0; a < y1; a += piece) {
        const int b = std::min(y1, a + piece);
        scratch_.resize(std::size_t(b - a) * row_values);
        read_slices(a, b, Imf::FLOAT, reinterpret_cast<char*>(scratch_.data()));
        convert_floats(
            scratch_.data(), scratch_.size(), as,
            static_cast<char*>(out) + std::size_t(a - y0) * row_values * sample_bytes(as));
      }
      scratch_ = {};
    }
  } catch (const std::exception& e) {
    error_ = e.what();
    return false;
  }
  return true;
}

// ---- Writing ----------------------------------------------------------------------------------

// OpenEXR's bytes into the caller's sink. The sink's failure is kept: OpenEXR's destructors, which
// write the offset tables, swallow exceptions. After one, nothing more is written.
class SinkStream final : public Imf::OStream {
 public:
  SinkStream(const std::string& name, Sink& sink) : Imf::OStream(name.c_str()), sink_(sink) {}
  void write(const char c[], int n) override {
    if (!failure_.empty()) throw InputError(failure_);
    try {
      sink_.write_at(position_, c, std::size_t(n));
    } catch (const std::exception& e) {
      failure_ = *e.what() != 0 ? e.what() : "cannot write";
      throw;
    }
    position_ += std::uint64_t(n);
  }
  std::uint64_t tellp() override { return position_; }
  void seekp(std::uint64_t position) override { position_ = position; }
  const std::string& failure() const { return failure_; }

 private:
  Sink& sink_;
  std::uint64_t position_ = 0;
  std::string failure_;
};

class ExrWriter final : public Writer {
 public:
  ExrWriter(const std::string& name, const Spec& spec, Sink& sink)
      : stream_(name, sink), spec_(spec), rows_done_(std::size_t(spec.height), false) {}
  ~ExrWriter() override { finish(); }
  // Writes the header; false with error() set when OpenEXR refuses it or the sink fails.
  bool start(const Imf::Header& header) try {
    if (spec_.tile_width > 0) {
      tiles_ = std::make_unique<Imf::TiledOutputFile>(stream_, header, exr_threads());
    } else {
      scanlines_ = std::make_unique<Imf::OutputFile>(stream_, header, exr_threads());
    }
    return true;
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  bool write_rows(int y0, int y1, Sample from, const void* data) override;
  bool close() override;
  std::string error() override { return std::exchange(error_, {}); }

 private:
  // Rows [y0, y1) of `type` at `data` (interleaved) to the file.
  void write_slices(int y0, int y1, Imf::PixelType type, const char* data);
  // The file's end (its offset table); never throws.
  void finish() noexcept;
  bool fail(const std::string& why) {
    error_ = stream_.failure().empty() ? why : stream_.failure();
    if (error_.empty()) error_ = "unknown OpenEXR error";
    return false;
  }

  SinkStream stream_;
  Spec spec_;
  std::unique_ptr<Imf::OutputFile> scanlines_;  // One of these two.
  std::unique_ptr<Imf::TiledOutputFile> tiles_;
  std::vector<bool> rows_done_;
  std::vector<char> converted_;  // Rows converted to the file's type.
  bool failed_ = false, closed_ = false;
  std::string error_;
};

void ExrWriter::write_slices(int y0, int y1, Imf::PixelType type, const char* data) {
  const Imf::FrameBuffer frame =
      frame_of(spec_.channel_names, type, spec_.width, {0, y0}, y1 - y0, data);
  if (tiles_) {
    tiles_->setFrameBuffer(frame);
    tiles_->writeTiles(0, tiles_->numXTiles() - 1, y0 / spec_.tile_height,
                       (y1 - 1) / spec_.tile_height);
  } else {
    scanlines_->setFrameBuffer(frame);
    scanlines_->writePixels(y1 - y0);
  }
  std::fill(rows_done_.begin() + y0, rows_done_.begin() + y1, true);
}

bool ExrWriter::write_rows(int y0, int y1, Sample from, const void* data) {
  if (failed_ || closed_) return fail(closed_ ? "written after close" : "an earlier write failed");
  if (from != Sample::kFloat && from != Sample::kHalf) {
    return fail(std::string("cannot write EXR pixels from ") + sample_name(from) + " values");
  }
  const std::string rows = "rows " + std::to_string(y0) + ".." + std::to_string(y1);
  if (y0 < 0 || y1 > spec_.height || y0 >= y1) return fail(rows + ": outside the image");
  const int th = spec_.tile_height;
  if (tiles_ && (y0 % th != 0 || (y1 % th != 0 && y1 != spec_.height))) {
    return fail(rows + ": not whole rows of " + std::to_string(th) + "-row tiles");
  }
  if (scanlines_ && y0 != scanlines_->currentScanLine()) {
    return fail(rows + ": out of order (next: " + std::to_string(scanlines_->currentScanLine()) +
                ")");
  }
  try {
    const auto* bytes = static_cast<const char*>(data);
    const Imf::PixelType type = spec_.format == Sample::kHalf ? Imf::HALF : Imf::FLOAT;
    if (from == spec_.format) {
      write_slices(y0, y1, type, bytes);
      return true;
    }
    // OpenEXR writes only the file's own type: converted here (floats rounded to halves as
    // OpenImageIO rounded them), a piece at a time.
    const std::size_t row_values = std::size_t(spec_.width) * std::size_t(spec_.channels);
    const std::size_t in_bytes = sample_bytes(from), out_bytes = sample_bytes(spec_.format);
    const int piece = rows_per_piece(row_values * out_bytes, th);
    for (int a = y0; a < y1; a += piece) {
      const int b = std::min(y1, a + piece);
      const std::size_t count = std::size_t(b - a) * row_values;
      const char* in = bytes + std::size_t(a - y0) * row_values * in_bytes;
      converted_.resize(count * out_bytes);
      if (from == Sample::kFloat) {
        convert_floats(reinterpret_cast<const float*>(in), count, Sample::kHalf, converted_.data());
      } else {
        const auto* halves = reinterpret_cast<const half*>(in);
        auto* floats = reinterpret_cast<float*>(converted_.data());
        for (std::size_t i = 0; i < count; ++i) floats[i] = float(halves[i]);
      }
      write_slices(a, b, type, converted_.data());
    }
    converted_ = {};
  } catch (const std::exception& e) {
    failed_ = true;
    return fail(e.what());
  }
  return true;
}

void ExrWriter::finish() noexcept {
  try {
    scanlines_.reset();
    tiles_.reset();
  } catch (...) {  // Not expected: OpenEXR's destructors catch their own.
    failed_ = true;
  }
}

bool ExrWriter::close() {
  if (closed_) return fail("closed twice");
  closed_ = true;
  const auto missing = std::find(rows_done_.begin(), rows_done_.end(), false);
  finish();
  if (failed_ || !stream_.failure().empty()) return fail("cannot finish the file");
  if (missing != rows_done_.end()) {
    return fail("closed before row " + std::to_string(missing - rows_done_.begin()) +
                " was written");
  }
  return true;
}

// Why OpenEXR cannot write `spec` as it is; empty when it can.
std::string refusal(const Spec& spec) {
  const auto size = [&] {
    return std::to_string(spec.width) + "x" + std::to_string(spec.height) + "x" +
           std::to_string(spec.channels);
  };
  if (spec.width <= 0 || spec.height <= 0 || spec.channels <= 0) return "an EXR of " + size();
  if (spec.format != Sample::kHalf && spec.format != Sample::kFloat) {
    return std::string("EXR stores half or float values, not ") + sample_name(spec.format);
  }
  if (int(spec.channel_names.size()) != spec.channels) {
    return std::to_string(spec.channel_names.size()) + " channel names for " + size();
  }
  if (spec.tile_width > 0 && spec.tile_height <= 0) return "tiles without a height";
  return {};
}

class ExrCodecs final : public Codecs {
 public:
  std::unique_ptr<Reader> open(const std::filesystem::path& path, std::string& error) override {
    return ExrReader::open(path, error);
  }
  std::unique_ptr<Writer> create(const std::filesystem::path& named_like, const Spec& spec,
                                 Sink& sink, std::string& error) override;
};

std::unique_ptr<Writer> ExrCodecs::create(const std::filesystem::path& named_like, const Spec& spec,
                                          Sink& sink, std::string& error) {
  error = refusal(spec);
  if (!error.empty()) return nullptr;
  auto writer = std::make_unique<ExrWriter>(named_like.string(), spec, sink);
  try {
    Imf::Header header(spec.width, spec.height);
    const Imf::PixelType type = spec.format == Sample::kHalf ? Imf::HALF : Imf::FLOAT;
    for (const std::string& name : spec.channel_names) {
      if (header.channels().findChannel(name) != nullptr) {
        error = "channel '" + name + "' named twice";
        return nullptr;
      }
      header.channels().insert(name, Imf::Channel(type));
    }
    if (spec.tile_width > 0) {
      header.setTileDescription(Imf::TileDescription(spec.tile_width, spec.tile_height));
    }
    error = set_exr_attributes(spec, header);
    if (!error.empty()) return nullptr;
    if (!writer->start(header)) {
      error = writer->error();
      return nullptr;
    }
  } catch (const std::exception& e) {  // A name or value OpenEXR refuses.
    error = e.what();
    return nullptr;
  }
  return writer;
}

}  // namespace

Codecs& exr_codecs() {
  static ExrCodecs codecs;
  return codecs;
}

}  // namespace ls::image_file
