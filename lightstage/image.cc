#include "lightstage/image.h"

#include <fcntl.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>

#include "lightstage/errors.h"
#include "lightstage/image_file.h"
#include "lightstage/memory.h"

namespace ls {

namespace fs = std::filesystem;

Image::Image(int w, int h, int c, float fill)
    : width(w), height(h), channels(c), pixels(size_t(w) * h * c, fill) {}

namespace {

// A temporary sibling of `path` that keeps its extension (the format is picked from it).
fs::path temp_sibling(const fs::path& path) {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  return path.parent_path() / (path.stem().string() + ".tmp" + std::to_string(getpid()) + "-" +
                               std::to_string(rng() % 1000000) + path.extension().string());
}

// Returns 0 or the errno of the failed open or fsync (a full disk can first show here).
int fsync_path(const fs::path& path, bool directory) {
  const int fd = ::open(path.c_str(), directory ? O_RDONLY | O_DIRECTORY : O_RDONLY);
  if (fd < 0) return errno;
  const int result = ::fsync(fd) == 0 ? 0 : errno;
  ::close(fd);
  return result;
}

// Renames tmp over path after making tmp durable; removes tmp on failure.
void commit_temp(const fs::path& tmp, const fs::path& path) {
  std::error_code ec;
  if (const int error = fsync_path(tmp, false); error != 0) {
    fs::remove(tmp, ec);
    throw StorageError(path.string() +
                       ": cannot make the file durable (fsync): " + std::strerror(error));
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    const bool folder = fs::is_directory(path);
    const std::string why = folder ? "it is a folder" : ec.message();
    fs::remove(tmp, ec);
    if (folder) throw InputError(path.string() + ": cannot write the file there: " + why);
    throw StorageError(path.string() + ": cannot write the file there: " + why);
  }
  fsync_path(path.parent_path().empty() ? fs::path(".") : path.parent_path(), true);
}

}  // namespace

AtomicFileWriter::AtomicFileWriter(const fs::path& path) : path_(path), temp_(temp_sibling(path)) {
  fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    throw StorageError(path.string() + ": cannot create file: " + std::strerror(errno));
  }
}

AtomicFileWriter::~AtomicFileWriter() {
  if (fd_ < 0) return;
  ::close(fd_);
  std::error_code ec;
  fs::remove(temp_, ec);
}

void AtomicFileWriter::write(const void* data, size_t size) {
  LS_CHECK(fd_ >= 0, "AtomicFileWriter::write after commit");
  const char* bytes = static_cast<const char*>(data);
  for (size_t done = 0; done < size;) {
    const ssize_t n = ::write(fd_, bytes + done, size - done);
    if (n > 0) {
      done += size_t(n);
    } else if (n < 0 && errno != EINTR) {
      fail(errno);
    }
  }
}

void AtomicFileWriter::write_at(uint64_t offset, const void* data, size_t size) {
  LS_CHECK(fd_ >= 0, "AtomicFileWriter::write_at after commit");
  const char* bytes = static_cast<const char*>(data);
  for (size_t done = 0; done < size;) {
    const ssize_t n = ::pwrite(fd_, bytes + done, size - done, off_t(offset + done));
    if (n > 0) {
      done += size_t(n);
    } else if (n < 0 && errno != EINTR) {
      fail(errno);
    }
  }
}

void AtomicFileWriter::commit() {
  LS_CHECK(fd_ >= 0, "AtomicFileWriter::commit twice");
  int error = ::fsync(fd_) != 0 ? errno : 0;
  if (::close(fd_) != 0 && error == 0) error = errno;
  fd_ = -1;
  if (error != 0) {
    std::error_code ec;
    fs::remove(temp_, ec);
    fail(error);
  }
  try {
    commit_temp(temp_, path_);
  } catch (const StorageError&) {
    failed_ = true;
    throw;
  }
}

void AtomicFileWriter::fail(int error) {
  failed_ = true;
  throw StorageError(path_.string() + ": cannot write: " + std::strerror(error));
}

namespace {

// Writes bytes to a new file, checking every write and the fsync (a full disk fails here, not
// silently later), then renames it over path.
void write_bytes_atomic(const fs::path& path, const void* data, size_t size) {
  AtomicFileWriter writer(path);
  writer.write(data, size);
  writer.commit();
}

using image_file::Sample;

// Encodes in memory, the format from path's extension: an encoder's own file writes do not all
// report a full disk, so the bytes are written by write_bytes_atomic.
std::vector<unsigned char> encode(const fs::path& path, const image_file::Spec& spec,
                                  Sample in_type, const void* data) {
  image_file::MemorySink memory;
  std::string error;
  const auto out = image_file::create(path, spec, memory, error);
  if (!out) throw InputError(path.string() + ": " + error);
  if (!out->write_rows(0, spec.height, in_type, data) || !out->close()) {
    throw InputError(path.string() + ": encoding failed: " + out->error());
  }
  return std::move(memory.bytes);
}

image_file::Spec spec_of(int width, int height, int channels, Sample format) {
  image_file::Spec spec;
  spec.width = width;
  spec.height = height;
  spec.channels = channels;
  spec.format = format;
  spec.channel_names = image_file::default_channel_names(channels);
  return spec;
}

// An output file, its folder created when missing.
void write_encoded(const fs::path& path, const image_file::Spec& spec, Sample in_type,
                   const void* data) {
  if (!path.parent_path().empty()) {
    std::error_code ec;
    fs::create_directories(path.parent_path(), ec);
  }
  const std::vector<unsigned char> encoded = encode(path, spec, in_type, data);
  write_bytes_atomic(path, encoded.data(), encoded.size());
}

}  // namespace

void write_rgb8(const fs::path& path, int width, int height, const uint8_t* rgb, int jpeg_quality) {
  image_file::Spec spec = spec_of(width, height, 3, Sample::kUInt8);
  if (path.extension() == ".jpg" || path.extension() == ".jpeg") {
    spec.set("Compression", "jpeg:" + std::to_string(std::clamp(jpeg_quality, 1, 100)));
    spec.set("jpeg:subsampling", "4:4:4");
  }
  write_encoded(path, spec, Sample::kUInt8, rgb);
}

void write_png_codes(const fs::path& path, int width, int height, int channels, int bits,
                     const uint16_t* codes) {
  LS_CHECK(bits == 8 || bits == 16, "PNG codes of " + std::to_string(bits) + " bits");
  if (bits == 16) {
    write_encoded(path, spec_of(width, height, channels, Sample::kUInt16), Sample::kUInt16, codes);
    return;
  }
  std::vector<uint8_t> bytes(size_t(width) * height * channels);
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = uint8_t(std::min<uint16_t>(codes[i], 255));
  write_encoded(path, spec_of(width, height, channels, Sample::kUInt8), Sample::kUInt8,
                bytes.data());
}

float srgb_encode(float linear) {
  if (!(linear > 0.0f)) return 0.0f;  // Also NaN.
  linear = std::min(linear, 1.0f);
  return linear <= 0.0031308f ? 12.92f * linear : 1.055f * std::pow(linear, 1.0f / 2.4f) - 0.055f;
}

float srgb_decode(float encoded) {
  if (!(encoded > 0.0f)) return 0.0f;  // Also NaN.
  encoded = std::min(encoded, 1.0f);
  return encoded <= 0.04045f ? encoded / 12.92f : std::pow((encoded + 0.055f) / 1.055f, 2.4f);
}

namespace {

// The image at `path` opened, its size checked against the memory its `value_bytes` values would
// take (a damaged or hostile header can claim gigabytes in a few bytes): InputError naming it.
std::unique_ptr<image_file::Reader> open_image(const fs::path& path, std::size_t value_bytes,
                                               const char* values) {
  if (!fs::exists(path)) throw InputError(path.string() + ": file not found");
  std::string error;
  auto in = image_file::open(path, error);
  if (!in) throw InputError(path.string() + ": cannot read image: " + error);
  const image_file::Spec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.channels <= 0) {
    throw InputError(path.string() + ": image has no pixels");
  }
  require_memory(std::size_t(spec.width) * spec.height * spec.channels * value_bytes,
                 path.string() + ": the image's " + std::to_string(spec.width) + "x" +
                     std::to_string(spec.height) + "x" + std::to_string(spec.channels) + " " +
                     values + " pixels",
                 "is its header damaged?");
  return in;
}

// Reads every row of `in` (opened from `path`) as `as` into `out`.
void read_all_rows(image_file::Reader& in, const fs::path& path, Sample as, void* out) {
  if (!in.read_rows(0, in.spec().height, as, out)) {
    throw InputError(path.string() +
                     ": cannot read pixels (truncated or corrupt file?): " + in.error());
  }
}

}  // namespace

Image read_image(const fs::path& path) {
  const auto in = open_image(path, sizeof(float), "float");
  const image_file::Spec& spec = in->spec();
  Image image(spec.width, spec.height, spec.channels);
  image.channel_names = spec.channel_names;
  read_all_rows(*in, path, Sample::kFloat, image.pixels.data());
  return image;
}

ImageCodes read_image_codes(const fs::path& path) {
  const auto in = open_image(path, 1, "8-bit");
  const image_file::Spec& spec = in->spec();
  ImageCodes image{spec.width, spec.height, spec.channels, {}};
  image.codes.resize(std::size_t(spec.width) * spec.height * spec.channels);
  read_all_rows(*in, path, Sample::kUInt8, image.codes.data());
  return image;
}

namespace {

// write_exr's header: float, zip, the channel names (else R,G,B,A / Y).
image_file::Spec exr_spec(int width, int height, int channels,
                          const std::vector<std::string>& channel_names,
                          const ExrAttributes& attributes) {
  image_file::Spec spec = spec_of(width, height, channels, Sample::kFloat);
  if (!channel_names.empty()) {
    LS_CHECK(int(channel_names.size()) == channels, "channel names mismatch");
    spec.channel_names = channel_names;
  }
  spec.set("compression", "zip");
  for (const auto& [name, value] : attributes) spec.set(name, value);
  return spec;
}

// A preview's 8-bit sRGB values: RGB from the first three channels, else grey from the first.
int preview_channels(int channels) { return channels >= 3 ? 3 : 1; }
void encode_preview(const Image& image, double exposure_stops, std::vector<uint8_t>& bytes) {
  const int out_channels = preview_channels(image.channels);
  const float scale = float(std::exp2(exposure_stops));
  bytes.resize(image.num_pixels() * size_t(out_channels));
  for (size_t i = 0; i < image.num_pixels(); ++i) {
    for (int c = 0; c < out_channels; ++c) {
      const float v = image.pixels[i * size_t(image.channels) + size_t(c)] * scale;
      bytes[i * size_t(out_channels) + size_t(c)] =
          uint8_t(std::lround(255.0f * srgb_encode(std::isfinite(v) ? v : 0)));
    }
  }
}

}  // namespace

struct ImageRowWriter::Output {
  explicit Output(const fs::path& p) : path(p), file(p) {}
  fs::path path;
  AtomicFileWriter file;
  std::unique_ptr<image_file::Writer> out;  // Gone before the file goes.
  bool png = false;
  int width = 0, height = 0, channels = 0, next_row = 0;
  std::vector<uint8_t> bytes;

  // A write the file refused (a full disk) is a StorageError; the encoder's own, an InputError.
  [[noreturn]] void fail(const std::string& what) const {
    const std::string message = path.string() + ": " + what + ": " + out->error();
    if (file.failed()) throw StorageError(message);
    throw InputError(message);
  }
};

ImageRowWriter::ImageRowWriter(const fs::path& path, int width, int height, int channels,
                               const std::vector<std::string>& channel_names,
                               const ExrAttributes& attributes) {
  if (!path.parent_path().empty()) {
    std::error_code ec;
    fs::create_directories(path.parent_path(), ec);
  }
  output_ = std::make_unique<Output>(path);
  Output& o = *output_;
  o.png = path.extension() == ".png";
  o.width = width, o.height = height, o.channels = channels;
  image_file::Spec spec;
  if (o.png) {
    spec = spec_of(width, height, preview_channels(channels), Sample::kUInt8);
    spec.set("png:compressionLevel", 1LL);  // Previews: a job's last step, not its archive.
  } else {
    spec = exr_spec(width, height, channels, channel_names, attributes);
  }
  std::string error;
  o.out = image_file::create(path, spec, o.file, error);
  if (!o.out) {
    const std::string message = path.string() + ": cannot start writing: " + error;
    if (o.file.failed()) throw StorageError(message);
    throw InputError(message);
  }
}

ImageRowWriter::~ImageRowWriter() = default;

void ImageRowWriter::write_rows(const Image& rows, double exposure_stops) {
  Output& o = *output_;
  LS_CHECK(rows.width == o.width && rows.channels == o.channels &&
               rows.pixels.size() == rows.num_pixels() * size_t(rows.channels) &&
               o.next_row + rows.height <= o.height,
           o.path.string() + ": ImageRowWriter::write_rows: rows of another shape");
  const int y1 = o.next_row + rows.height;
  bool ok;
  if (o.png) {
    encode_preview(rows, exposure_stops, o.bytes);
    ok = o.out->write_rows(o.next_row, y1, Sample::kUInt8, o.bytes.data());
  } else {
    ok = o.out->write_rows(o.next_row, y1, Sample::kFloat, rows.pixels.data());
  }
  if (!ok) o.fail("cannot write rows " + std::to_string(o.next_row) + ".." + std::to_string(y1));
  o.next_row = y1;
}

void ImageRowWriter::commit() {
  Output& o = *output_;
  LS_CHECK(o.next_row == o.height, o.path.string() + ": ImageRowWriter::commit before every row");
  if (!o.out->close()) o.fail("encoding failed");
  o.out.reset();
  o.file.commit();
}

const fs::path& ImageRowWriter::path() const { return output_->path; }

void write_rows_beside(ImageRowWriter& file, const Image& first, const Image& extra,
                       int extra_channels) {
  if (extra_channels == 0) {
    file.write_rows(first);
    return;
  }
  constexpr int kChunkRows = 64;
  Image rows;
  for (int y = 0; y < first.height; y += kChunkRows) {
    const int height = std::min(kChunkRows, first.height - y);
    if (rows.height != height) rows = Image(first.width, height, first.channels + extra_channels);
    const size_t offset = size_t(y) * size_t(first.width);
    for (size_t i = 0; i < rows.num_pixels(); ++i) {
      float* out = &rows.pixels[i * size_t(rows.channels)];
      std::copy_n(&first.pixels[(offset + i) * size_t(first.channels)], first.channels, out);
      if (!extra.pixels.empty()) {
        std::copy_n(&extra.pixels[(offset + i) * size_t(extra_channels)], extra_channels,
                    out + first.channels);
      }
    }
    file.write_rows(rows);
  }
}

void commit_together(const std::vector<ImageRowWriter*>& writers) {
  size_t committed = 0;
  try {
    for (; committed < writers.size(); ++committed) writers[committed]->commit();
  } catch (...) {
    std::error_code ignored;
    for (size_t i = 0; i < committed; ++i) fs::remove(writers[i]->path(), ignored);
    throw;
  }
}

void write_exr(const fs::path& path, const Image& image, ExrPixelType type,
               const ExrAttributes& attributes) {
  LS_CHECK(image.pixels.size() == image.num_pixels() * image.channels, "image size mismatch");
  if (type == ExrPixelType::kFloat) {
    ImageRowWriter writer(path, image.width, image.height, image.channels, image.channel_names,
                          attributes);
    writer.write_rows(image);
    writer.commit();
    return;
  }
  image_file::Spec spec =
      exr_spec(image.width, image.height, image.channels, image.channel_names, attributes);
  spec.format = Sample::kHalf;
  write_encoded(path, spec, Sample::kFloat, image.pixels.data());
}

double auto_exposure_stops(const Image& image, double percentile) {
  std::vector<float> lum;
  lum.reserve(image.num_pixels());
  for (size_t i = 0; i < image.num_pixels(); ++i) {
    const float* p = &image.pixels[i * image.channels];
    const float y = image.channels >= 3 ? luminance(p) : p[0];
    if (std::isfinite(y) && y > 0) lum.push_back(y);
  }
  if (lum.empty()) return 0.0;
  const size_t k = std::min(lum.size() - 1, size_t(percentile * lum.size()));
  std::nth_element(lum.begin(), lum.begin() + k, lum.end());
  return -std::log2(std::max(lum[k], 1e-12f) / 0.9f);
}

void write_png_preview(const fs::path& path, const Image& image, double exposure_stops) {
  ImageRowWriter writer(path, image.width, image.height, image.channels);
  writer.write_rows(image, exposure_stops);
  writer.commit();
}

StoredFile write_raw_frame(const fs::path& path, const RawFrame& frame) {
  LS_CHECK(frame.bit_depth >= 1 && frame.bit_depth <= 16, "bit depth out of range");
  // Stored MSB-aligned (as most cameras do), so the PNG looks right in any viewer.
  const int shift = 16 - frame.bit_depth;
  std::vector<uint16_t> aligned(frame.pixels.size());
  for (size_t i = 0; i < aligned.size(); ++i) aligned[i] = uint16_t(frame.pixels[i] << shift);
  image_file::Spec spec = spec_of(frame.width, frame.height, frame.channels, Sample::kUInt16);
  spec.set("png:compressionLevel", 1LL);  // Fast: capture must not wait on the encoder.
  spec.set("lightstage:bit_depth", (long long)frame.bit_depth);
  // The frame's folder is not created: a session folder deleted or unmounted mid-capture must
  // stop the capture, not be recreated half empty.
  const std::vector<unsigned char> encoded = encode(path, spec, Sample::kUInt16, aligned.data());
  write_bytes_atomic(path, encoded.data(), encoded.size());
  return {encoded.size(), crc32_of(encoded.data(), encoded.size())};
}

uint32_t crc32_of(const void* data, size_t size) {
  uLong crc = ::crc32(0L, Z_NULL, 0);
  const auto* bytes = static_cast<const Bytef*>(data);
  // zlib takes at most a uInt per call.
  for (size_t done = 0; done < size;) {
    const uInt n = uInt(std::min<size_t>(size - done, 1u << 30));
    crc = ::crc32(crc, bytes + done, n);
    done += n;
  }
  return uint32_t(crc);
}

RawFrame read_raw_frame(const fs::path& path, int bit_depth) {
  if (!fs::exists(path)) throw InputError(path.string() + ": frame file not found");
  std::string error;
  const auto in = image_file::open(path, error);
  if (!in) throw InputError(path.string() + ": cannot read frame: " + error);
  const image_file::Spec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.channels <= 0) {
    throw InputError(path.string() + ": frame has no pixels");
  }
  // Checked before it is allocated, as read_image does: a damaged header can claim gigabytes.
  require_memory(std::size_t(spec.width) * spec.height * spec.channels * sizeof(uint16_t),
                 path.string() + ": the frame's " + std::to_string(spec.width) + "x" +
                     std::to_string(spec.height) + "x" + std::to_string(spec.channels) + " pixels",
                 "is its header damaged?");
  RawFrame frame;
  frame.width = spec.width;
  frame.height = spec.height;
  frame.channels = spec.channels;
  frame.bit_depth = bit_depth;
  frame.pixels.resize(size_t(spec.width) * spec.height * spec.channels);
  if (!in->read_rows(0, spec.height, Sample::kUInt16, frame.pixels.data())) {
    throw InputError(path.string() + ": cannot read frame pixels (truncated?): " + in->error());
  }
  const int shift = 16 - bit_depth;
  for (auto& v : frame.pixels) v = uint16_t(v >> shift);
  return frame;
}

void write_file_atomic(const fs::path& path, const std::string& contents) {
  write_bytes_atomic(path, contents.data(), contents.size());
}

void write_file_atomic(const fs::path& path, const void* data, size_t size) {
  write_bytes_atomic(path, data, size);
}

}  // namespace ls
