#include "lightstage/raw_photo.h"

#include <libraw/libraw.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <memory>
#include <set>

#include "lightstage/errors.h"

namespace ls {

namespace {

// The sensor site's black level, DN: the common level, the CFA colour's and the repeating
// pattern's (DNG BlackLevel with BlackLevelRepeatDim), however LibRaw split it.
unsigned black_at(const libraw_colordata_t& color, int row, int col, int cfa_color) {
  unsigned black = color.black + color.cblack[cfa_color];
  const unsigned pattern_rows = color.cblack[4];
  const unsigned pattern_cols = color.cblack[5];
  if (pattern_rows > 0 && pattern_cols > 0) {
    black += color.cblack[6 + (unsigned(row) % pattern_rows) * pattern_cols +
                          unsigned(col) % pattern_cols];
  }
  return black;
}

int channel_of(int cfa_color) { return cfa_color == 3 ? 1 : cfa_color; }  // Second green: G.

struct Decoder {
  std::unique_ptr<LibRaw> raw = std::make_unique<LibRaw>();
  std::string name;
  unsigned white_level = 0;  // Sensor DN, as unpacked (dcraw_process lowers color.maximum).

  [[noreturn]] void fail(const std::string& what, int code) const {
    throw InputError(name + ": " + what + ": " + libraw_strerror(code));
  }

  void check(int code, const std::string& what) const {
    if (code != LIBRAW_SUCCESS) fail(what, code);
  }

  // What every path sets before opening: linear camera RGB, nothing chosen per image.
  void set_linear_params() {
    libraw_output_params_t& p = raw->imgdata.params;
    p.output_bps = 16;
    p.gamm[0] = p.gamm[1] = 1.0;
    p.no_auto_bright = 1;
    p.use_auto_wb = 0;
    p.use_camera_wb = 0;
    p.use_camera_matrix = 0;
    p.output_color = 0;  // Raw camera colour: no matrix toward sRGB.
    std::fill(std::begin(p.user_mul), std::end(p.user_mul), 1.0f);
    p.highlight = 0;              // Clip; clipped sites are censored below.
    p.adjust_maximum_thr = 0.0f;  // The white level as the file says, not guessed from the data.
    p.user_flip = 0;              // Sensor orientation: frames of a dome share it.
    p.user_qual = 3;              // AHD.
  }

  DecodedRaw decode(const RawDecodeOptions& options) {
    for (const double m : options.white_balance) {
      if (!(m > 0.0) || !std::isfinite(m)) {
        throw InputError(name + ": white_balance: expected three positive multipliers");
      }
    }
    check(raw->unpack(), "unpacking the raw data");
    const libraw_data_t& d = raw->imgdata;
    DecodedRaw out;
    out.camera = std::string(d.idata.make) + " " + d.idata.model;
    out.exposure_s = d.other.shutter;
    out.iso = d.other.iso_speed;
    white_level = d.color.maximum;
    out.white_level = white_level;
    double black_sum = 0;
    for (int c = 0; c < 4; ++c) black_sum += black_at(d.color, 0, 0, c);
    out.black_level = black_sum / 4;
    if (white_level <= out.black_level) {
      throw InputError(name + ": white level " + std::to_string(white_level) +
                       " is not above the black level " + std::to_string(out.black_level));
    }
    if (options.mode == RawDecodeOptions::Mode::kBin2x2) {
      bin(options, out);
    } else {
      demosaic(options, out);
    }
    return out;
  }

  bool is_bayer() const {
    return raw->imgdata.rawdata.raw_image != nullptr && raw->imgdata.idata.filters >= 1000;
  }

  uint16_t raw_site(int row, int col) const {
    const libraw_data_t& d = raw->imgdata;
    const size_t pitch = d.sizes.raw_pitch / 2;
    return d.rawdata
        .raw_image[size_t(row + d.sizes.top_margin) * pitch + col + d.sizes.left_margin];
  }

  void bin(const RawDecodeOptions& options, DecodedRaw& out) {
    if (!is_bayer()) {
      throw InputError(name + ": binning 2x2 needs a Bayer sensor; this file's (" + out.camera +
                       ") is not one: decode it with demosaicing");
    }
    const libraw_data_t& d = raw->imgdata;
    RawFrame& f = out.frame;
    f.width = d.sizes.width / 2;
    f.height = d.sizes.height / 2;
    f.channels = 3;
    f.bit_depth = 16;
    f.pixels.assign(size_t(f.width) * f.height * 3, 0);
    for (int by = 0; by < f.height; ++by) {
      for (int bx = 0; bx < f.width; ++bx) {
        double sum[3] = {0, 0, 0};
        int count[3] = {0, 0, 0};
        bool clipped[3] = {false, false, false};
        for (int dy = 0; dy < 2; ++dy) {
          for (int dx = 0; dx < 2; ++dx) {
            const int row = 2 * by + dy, col = 2 * bx + dx;
            const int cfa = raw->COLOR(row, col);
            const int ch = channel_of(cfa);
            const uint16_t value = raw_site(row, col);
            const double black = black_at(d.color, row, col, cfa);
            clipped[ch] = clipped[ch] || value >= white_level;
            sum[ch] += std::max(0.0, (value - black) / (white_level - black));
            ++count[ch];
          }
        }
        uint16_t* px = &f.pixels[(size_t(by) * f.width + bx) * 3];
        for (int c = 0; c < 3; ++c) {
          if (count[c] == 0) {
            throw InputError(name + ": binning 2x2: the CFA pattern has no " +
                             std::string(c == 0   ? "red"
                                         : c == 1 ? "green"
                                                  : "blue") +
                             " site in a 2x2 block");
          }
          px[c] = encode(sum[c] / count[c] * options.white_balance[size_t(c)], clipped[c], c, out);
        }
      }
    }
  }

  // A value in [0, 1] of the white level to 16 bits; clipped (or pushed past 1) reads 65535.
  static uint16_t encode(double value, bool clipped, int channel, DecodedRaw& out) {
    if (clipped || value >= 1.0) {
      ++out.saturated_pixels[size_t(channel)];
      return 65535;
    }
    return uint16_t(std::lround(std::min(value * 65535.0, 65534.0)));
  }

  void demosaic(const RawDecodeOptions& options, DecodedRaw& out) {
    check(raw->dcraw_process(), "demosaicing");
    int code = LIBRAW_SUCCESS;
    std::unique_ptr<libraw_processed_image_t, void (*)(libraw_processed_image_t*)> image(
        raw->dcraw_make_mem_image(&code), &LibRaw::dcraw_clear_mem);
    if (!image) fail("making the decoded image", code);
    if (image->type != LIBRAW_IMAGE_BITMAP || image->colors != 3 || image->bits != 16) {
      throw InputError(name + ": LibRaw decoded " + std::to_string(image->colors) +
                       " channels of " + std::to_string(image->bits) + " bits; expected 3 of 16");
    }
    RawFrame& f = out.frame;
    f.width = image->width;
    f.height = image->height;
    f.channels = 3;
    f.bit_depth = 16;
    f.pixels.resize(size_t(f.width) * f.height * 3);
    const auto* decoded = reinterpret_cast<const uint16_t*>(image->data);
    const std::vector<uint8_t> clipped = clipped_near_sites(f.width, f.height);
    for (size_t i = 0; i < f.pixels.size(); ++i) {
      const int c = int(i % 3);
      f.pixels[i] = encode(decoded[i] / 65535.0 * options.white_balance[size_t(c)],
                           (clipped[i / 3] >> c & 1) != 0, c, out);
    }
  }

  // Per output pixel, bit c set when a clipped site of channel c lies within the 5x5 neighbourhood
  // AHD interpolates from: its value there is not the scene's.
  std::vector<uint8_t> clipped_near_sites(int width, int height) const {
    std::vector<uint8_t> mask(size_t(width) * height, 0);
    if (!is_bayer()) return mask;
    const libraw_data_t& d = raw->imgdata;
    if (d.sizes.width != width || d.sizes.height != height) return mask;
    constexpr int kReach = 2;
    for (int row = 0; row < height; ++row) {
      for (int col = 0; col < width; ++col) {
        if (raw_site(row, col) < white_level) continue;
        const int bit = 1 << channel_of(raw->COLOR(row, col));
        for (int y = std::max(0, row - kReach); y <= std::min(height - 1, row + kReach); ++y) {
          for (int x = std::max(0, col - kReach); x <= std::min(width - 1, col + kReach); ++x) {
            mask[size_t(y) * width + x] |= uint8_t(bit);
          }
        }
      }
    }
    return mask;
  }
};

}  // namespace

bool is_raw_photo_name(const std::filesystem::path& path) {
  static const std::set<std::string> kExtensions = {
      ".dng", ".cr2", ".cr3", ".crw", ".nef", ".nrw", ".arw", ".srf", ".sr2", ".raf", ".orf",
      ".rw2", ".pef", ".srw", ".3fr", ".iiq", ".erf", ".kdc", ".mos", ".mrw", ".x3f"};
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return kExtensions.count(ext) > 0;
}

DecodedRaw decode_raw_photo(const std::filesystem::path& path, const RawDecodeOptions& options) {
  Decoder decoder;
  decoder.name = path.string();
  decoder.set_linear_params();
  decoder.check(decoder.raw->open_file(path.c_str()), "opening it as a raw photograph");
  return decoder.decode(options);
}

DecodedRaw decode_raw_photo(const std::vector<std::uint8_t>& bytes, const std::string& source_name,
                            const RawDecodeOptions& options) {
  Decoder decoder;
  decoder.name = source_name;
  decoder.set_linear_params();
  // LibRaw reads the buffer without writing it (its API takes void*).
  decoder.check(decoder.raw->open_buffer(const_cast<std::uint8_t*>(bytes.data()), bytes.size()),
                "opening it as a raw photograph");
  return decoder.decode(options);
}

const char* to_string(RawDecodeOptions::Mode mode) {
  return mode == RawDecodeOptions::Mode::kBin2x2 ? "bin2x2" : "demosaic";
}

}  // namespace ls
