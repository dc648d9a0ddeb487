#include "capture/exr_band_reader.h"

#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfTiledInputFile.h>
#include <fcntl.h>
#include <sys/uio.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <unordered_map>

#include "capture/half_storage.h"
#include "lightstage/errors.h"

namespace ls::capture {

namespace {

// OpenEXR's file of type T (InputFile, TiledInputFile) at `name`, or InputError naming it.
template <class T>
std::unique_ptr<T> open_exr(const std::string& name) {
  try {
    return std::make_unique<T>(name.c_str());
  } catch (const std::exception& e) {
    throw InputError(name + ": cannot read reflectance field: " + e.what());
  }
}

}  // namespace

struct ExrBandReader::File {
  std::string name;
  std::unique_ptr<Imf::InputFile> in;
  // Tiled files by whole rows of tiles, straight into the buffer (InputFile would go through a
  // cache of one row of tiles: as much memory again).
  std::unique_ptr<Imf::TiledInputFile> tiled;
  std::vector<std::string>
      channels;                     // In the file's order (sorted by name, as OpenEXR keeps them).
  std::vector<int> to_pixel_index;  // Of each channel, in that order.
  int width = 0, min_x = 0, min_y = 0;
  // Uncompressed scanlines of float channels hold, per row, each channel's row in turn: read as
  // they are, without OpenEXR's per-value conversion.
  bool raw = false;
  int value_bytes = 4;    // Of the raw rows' values: float, or half (converted here).
  float value_scale = 1;  // The field's value = stored value x this (half storage's 1 / scale).
  // Uncompressed float or half scanlines: rows are chunks of a known size at the end of the file (a
  // chunk: its row as an int32, its byte count as an int32, the row's bytes), so the next band's
  // bytes can be asked of the kernel (read ahead while this band is used) and the rows read
  // straight out of the page cache, rows in parallel (pread): a stream's read copies twice, on one
  // thread. Not through a mapping: faulting its pages in and dropping them again (a pass over a
  // field larger than memory must not hold it resident) cost more than the copy.
  int raw_fd = -1;  // Open where the rows lie where chunk_offset says, else -1 (OpenEXR reads).
  std::uintmax_t file_bytes = 0;
  int height = 0;
  ~File() {
    if (raw_fd >= 0) ::close(raw_fd);
  }
  std::uintmax_t chunk_bytes() const {
    return 8 + std::uintmax_t(width) * channels.size() * std::uintmax_t(value_bytes);
  }
  std::uintmax_t chunk_offset(int y) const {
    return file_bytes - std::uintmax_t(height - y) * chunk_bytes();
  }
  // Whether `chunk` (as stored) is row y's, with its byte count.
  bool chunk_is_row(const char* chunk, int y) const {
    std::int32_t row = 0, bytes = 0;
    std::memcpy(&row, chunk, 4);  // OpenEXR is little-endian, as x86 is.
    std::memcpy(&bytes, chunk + 4, 4);
    return row == y + min_y && std::uintmax_t(bytes) + 8 == chunk_bytes();
  }
  // Row y's chunk by one read at chunk_offset: the first `bytes` of its values into `values`;
  // false where the read falls short or the chunk is not row y's (chunk_is_row).
  bool read_chunk(int y, void* values, std::size_t bytes) const {
    char header[8];
    iovec to[2] = {{header, 8}, {values, bytes}};
    return ::preadv(raw_fd, to, 2, off_t(chunk_offset(y))) == ssize_t(8 + bytes) &&
           chunk_is_row(header, y);
  }
  // Whether byte `at` of the file is in the page cache (a read that may not wait for the disk).
  bool page_cached(std::uintmax_t at) const {
    char byte = 0;
    iovec to{&byte, 1};
    return ::preadv2(raw_fd, &to, 1, off_t(at), RWF_NOWAIT) == 1;
  }
  // Starts reading rows [y0, y1) into the page cache; not where their last byte is cached already
  // (a field read again): the kernel would find so page by page, a sixth of a pass relighting them.
  void read_ahead(int y0, int y1) const {
    if (raw_fd < 0 || y0 >= y1 || page_cached(chunk_offset(y1 - 1) + chunk_bytes() - 1)) return;
    posix_fadvise(raw_fd, off_t(chunk_offset(y0)), off_t(std::uintmax_t(y1 - y0) * chunk_bytes()),
                  POSIX_FADV_WILLNEED);
  }
  int step = 1;        // Tile height (1: scanlines).
  int piece_rows = 1;  // Rows read at a time (whole tiles where the file is tiled).
  // Rows [a, b) into `planar` as [row][channel][x]; InputError naming the file and rows, or (with
  // check_finite) when a value is not finite.
  void read_piece(int a, int b, bool check_finite);
  // The same by pread: each row read and checked (halves converted), rows in parallel.
  void read_raw_piece(int a, int b, bool check_finite);
  void read_through_openexr(int a, int b);  // Raw bytes or slices.
  // Rows [a, b)'s chunks as stored into `half_chunks`, in parallel, each checked (InputError as
  // above).
  void read_half_chunks(int a, int b);
  // InputError naming the file: a row whose chunk is out of place (>= 0), or non-finite values.
  void refuse_damage(int bad_row, bool non_finite) const;
  std::vector<float> planar;      // One piece: [row][channel][x], as an uncompressed file holds it.
  std::vector<char> half_chunks;  // One piece of a half file's chunks, as stored.
};

namespace {

void scale_values(float* values, std::size_t count, float scale) {
  for (std::size_t i = 0; i < count; ++i) values[i] *= scale;
}

bool any_not_finite(const float* values, std::size_t count) {
  int not_finite = 0;
  for (std::size_t i = 0; i < count; ++i) not_finite |= int(!std::isfinite(values[i]));
  return not_finite != 0;
}

}  // namespace

ExrBandReader::ExrBandReader(const std::filesystem::path& path,
                             const std::vector<std::string>& channels,
                             const std::vector<int>& to_pixel_index, float value_scale)
    : file_(std::make_unique<File>()) {
  File& f = *file_;
  f.value_scale = value_scale;
  f.name = path.string();
  f.in = open_exr<Imf::InputFile>(f.name);
  const Imf::Header& header = f.in->header();
  std::unordered_map<std::string, int> index;
  for (size_t i = 0; i < channels.size(); ++i) index[channels[i]] = to_pixel_index[i];
  bool all_float = true, all_half = true;
  std::size_t file_channels = 0;
  for (auto c = header.channels().begin(); c != header.channels().end(); ++c) {
    ++file_channels;
    const auto found = index.find(c.name());
    if (found == index.end()) continue;  // Not the field's (channel_layout checked what is).
    f.channels.emplace_back(c.name());
    f.to_pixel_index.push_back(found->second);
    const bool whole = c.channel().xSampling == 1 && c.channel().ySampling == 1;
    all_float = all_float && c.channel().type == Imf::FLOAT && whole;
    all_half = all_half && c.channel().type == Imf::HALF && whole;
  }
  if (f.channels.size() != channels.size()) {
    throw InputError(f.name +
                     ": channels: OpenEXR and OpenImageIO disagree on the field's channels");
  }
  const Imath::Box2i window = header.dataWindow();
  f.width = window.max.x - window.min.x + 1;
  f.min_x = window.min.x;
  f.min_y = window.min.y;
  const bool uncompressed_rows = f.channels.size() == file_channels &&
                                 header.compression() == Imf::NO_COMPRESSION &&
                                 !header.hasTileDescription();
  f.raw = all_float && uncompressed_rows;
  f.value_bytes = all_half ? 2 : 4;
  f.height = window.max.y - window.min.y + 1;
  if ((all_float || all_half) && uncompressed_rows && header.lineOrder() == Imf::INCREASING_Y) {
    std::error_code error;
    f.file_bytes = std::filesystem::file_size(path, error);
    if (!error) f.raw_fd = ::open(f.name.c_str(), O_RDONLY | O_CLOEXEC);
    // The first and last rows where chunk_offset puts them, else the rows are elsewhere, behind a
    // line offset table: OpenEXR's to read.
    const bool rows_in_place =
        f.raw_fd >= 0 && f.file_bytes >= std::uintmax_t(f.height) * f.chunk_bytes() &&
        f.read_chunk(0, nullptr, 0) && f.read_chunk(f.height - 1, nullptr, 0);
    if (f.raw_fd >= 0 && !rows_in_place) {
      ::close(f.raw_fd);
      f.raw_fd = -1;
    }
  }
  constexpr std::size_t kPieceBytes = std::size_t(8) << 20;
  const std::size_t row_bytes = std::size_t(f.width) * f.channels.size() * sizeof(float);
  if (header.hasTileDescription()) {
    f.step = int(header.tileDescription().ySize);
    f.tiled = open_exr<Imf::TiledInputFile>(f.name);
  }
  f.piece_rows = std::max(f.step, int(kPieceBytes / row_bytes) / f.step * f.step);
}

ExrBandReader::~ExrBandReader() = default;

void ExrBandReader::read(int y0, int y1, float* dst) {
  File& f = *file_;
  const int num_channels = int(f.channels.size());
  const std::size_t width = std::size_t(f.width);
  const std::size_t row_values = width * num_channels;
  // At most a quarter of the band at a time (FieldStream::rows_within counts on it).
  const int piece_rows = std::max(f.step, std::min(f.piece_rows, (y1 - y0) / 4 / f.step * f.step));
  std::atomic<bool> non_finite{false};
  for (int a = y0; a < y1; a += piece_rows) {
    const int b = std::min(y1, a + piece_rows);
    f.read_piece(a, b, false);  // The transposition checks.
    // [row][channel][x] to pixel-major, a block of pixels of one row at a time (it stays in cache
    // across the channels).
    float* out = dst + std::size_t(a - y0) * row_values;
    constexpr std::size_t kBlock = 64;
    const std::size_t blocks_per_row = (width + kBlock - 1) / kBlock;
    tbb::parallel_for(std::size_t(0), std::size_t(b - a) * blocks_per_row, [&](std::size_t k) {
      const std::size_t row = k / blocks_per_row, x0 = (k % blocks_per_row) * kBlock;
      const std::size_t x1 = std::min(width, x0 + kBlock);
      const float* in_row = f.planar.data() + row * row_values;
      float* out_row = out + row * row_values;
      int not_finite = 0;
      for (int c = 0; c < num_channels; ++c) {
        const float* plane = in_row + std::size_t(c) * width;
        float* to = out_row + f.to_pixel_index[size_t(c)];
        for (std::size_t x = x0; x < x1; ++x) {
          not_finite |= int(!std::isfinite(plane[x]));
          to[x * num_channels] = plane[x];
        }
      }
      if (not_finite != 0) non_finite = true;
    });
  }
  if (non_finite) throw InputError(f.name + ": the reflectance field holds non-finite values");
  f.read_ahead(y1, std::min(f.height, y1 + (y1 - y0)));  // Bands come in order.
}

void ExrBandReader::read_planar(int y0, int y1, const PlanarVisitor& visit) {
  File& f = *file_;
  // Half rows go to the consumer as stored: converting them first would write and read again
  // twice their bytes.
  const bool halves_as_stored = f.raw_fd >= 0 && f.value_bytes == 2 && cpu_converts_halves();
  // Halves convert nothing into `planar`: a piece of as many bytes holds twice the rows (fewer
  // pauses between pieces, and rows enough to share among the cores).
  const int piece_rows = halves_as_stored ? f.piece_rows * int(sizeof(float) / 2) : f.piece_rows;
  f.read_ahead(y0, std::min(y1, y0 + piece_rows));
  for (int a = y0; a < y1; a += piece_rows) {
    const int b = std::min(y1, a + piece_rows);
    if (halves_as_stored) {
      f.read_half_chunks(a, b);
    } else {
      f.read_piece(a, b, true);
    }
    f.read_ahead(b, std::min(y1, b + piece_rows));  // While this piece is used.
    if (halves_as_stored) {
      visit(PlanarRows{nullptr, a, b - a, f.width, f.to_pixel_index, f.half_chunks.data() + 8,
                       std::size_t(f.chunk_bytes()), f.value_scale, f.name});
    } else {
      visit(PlanarRows{f.planar.data(), a, b - a, f.width, f.to_pixel_index});
    }
  }
}

void ExrBandReader::File::read_half_chunks(int a, int b) {
  const std::size_t bytes = std::size_t(chunk_bytes());
  half_chunks.resize(std::size_t(b - a) * bytes);
  std::atomic<int> bad_row{-1};
  tbb::parallel_for(a, b, [&](int y) {
    if (!read_chunk(y, half_chunks.data() + std::size_t(y - a) * bytes + 8, bytes - 8)) bad_row = y;
  });
  refuse_damage(bad_row, false);
}

void ExrBandReader::File::refuse_damage(int bad_row, bool non_finite) const {
  if (bad_row >= 0) {
    throw InputError(name + ": row " + std::to_string(bad_row) +
                     ": its chunk is not where the file's uncompressed rows put it (damaged?)");
  }
  if (non_finite) throw InputError(name + ": the reflectance field holds non-finite values");
}

void ExrBandReader::File::read_raw_piece(int a, int b, bool check_finite) {
  const std::size_t row_values = std::size_t(width) * channels.size();
  std::atomic<int> bad_row{-1};
  std::atomic<bool> non_finite{false};
  tbb::parallel_for(a, b, [&](int y) {
    float* row = planar.data() + std::size_t(y - a) * row_values;
    thread_local std::vector<char> halves;  // A half row, converted into `row`.
    if (value_bytes == 2) halves.resize(row_values * 2);
    if (!read_chunk(y, value_bytes == 2 ? static_cast<void*>(halves.data()) : row,
                    row_values * std::size_t(value_bytes))) {
      bad_row = y;
      return;
    }
    if (value_bytes == 2) {
      if (!halves_to_floats(halves.data(), row_values, value_scale, row)) non_finite = true;
    } else {
      if (value_scale != 1) scale_values(row, row_values, value_scale);
      if (check_finite && any_not_finite(row, row_values)) non_finite = true;
    }
  });
  refuse_damage(bad_row, non_finite);
}

void ExrBandReader::File::read_piece(int a, int b, bool check_finite) {
  const std::size_t row_values = std::size_t(width) * channels.size();
  planar.resize(std::size_t(b - a) * row_values);
  if (raw_fd >= 0) {
    read_raw_piece(a, b, check_finite);
    return;
  }
  read_through_openexr(a, b);
  if (!check_finite && value_scale == 1) return;
  std::atomic<bool> non_finite{false};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, planar.size(), row_values),
                    [&](const auto& r) {
                      float* values = planar.data() + r.begin();
                      if (value_scale != 1) scale_values(values, r.size(), value_scale);
                      if (check_finite && any_not_finite(values, r.size())) non_finite = true;
                    });
  if (non_finite) throw InputError(name + ": the reflectance field holds non-finite values");
}

void ExrBandReader::File::read_through_openexr(int a, int b) {
  const std::size_t row_values = std::size_t(width) * channels.size();
  const int num_channels = int(channels.size());
  try {
    if (raw) {
      for (int y = a; y < b; ++y) {
        int bytes = int(row_values * sizeof(float));
        char* row = reinterpret_cast<char*>(planar.data() + std::size_t(y - a) * row_values);
        in->rawPixelDataToBuffer(y + min_y, row, bytes);
        if (std::size_t(bytes) != row_values * sizeof(float)) {
          throw InputError(name + ": row " + std::to_string(y) + " holds " + std::to_string(bytes) +
                           " bytes, expected " + std::to_string(row_values * sizeof(float)));
        }
      }
      return;
    }
    // OpenEXR addresses pixel (x, y) of the data window at base + x * xStride + y * yStride: each
    // channel's base offset back to the window's origin.
    Imf::FrameBuffer frame;
    const std::ptrdiff_t origin =
        std::ptrdiff_t(min_x * sizeof(float)) +
        std::ptrdiff_t(a + min_y) * std::ptrdiff_t(row_values * sizeof(float));
    for (int c = 0; c < num_channels; ++c) {
      char* base =
          reinterpret_cast<char*>(planar.data() + std::size_t(c) * std::size_t(width)) - origin;
      frame.insert(channels[size_t(c)],
                   Imf::Slice(Imf::FLOAT, base, sizeof(float), row_values * sizeof(float)));
    }
    if (tiled) {
      tiled->setFrameBuffer(frame);
      tiled->readTiles(0, tiled->numXTiles(0) - 1, a / step, (b - 1) / step);
    } else {
      in->setFrameBuffer(frame);
      in->readPixels(a + min_y, b - 1 + min_y);
    }
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(name + ": reading pixels failed (rows " + std::to_string(a) + ".." +
                     std::to_string(b - 1) + "): " + e.what());
  }
}

}  // namespace ls::capture
