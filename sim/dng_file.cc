#include "sim/dng_file.h"

#include <tiffio.h>

#include <algorithm>
#include <cstring>
#include <memory>

#include "lightstage/errors.h"

namespace ls::sim {

namespace {

// libtiff writes through these into memory: a DNG is handed over as bytes, as a camera's file is.
struct MemoryFile {
  std::vector<uint8_t> bytes;
  size_t position = 0;
};

MemoryFile& file_of(thandle_t handle) { return *static_cast<MemoryFile*>(handle); }

tmsize_t read_bytes(thandle_t handle, void* data, tmsize_t size) {
  MemoryFile& f = file_of(handle);
  const size_t n = std::min(size_t(size), f.bytes.size() - std::min(f.position, f.bytes.size()));
  if (n > 0) std::memcpy(data, f.bytes.data() + f.position, n);
  f.position += n;
  return tmsize_t(n);
}

tmsize_t write_bytes(thandle_t handle, void* data, tmsize_t size) {
  MemoryFile& f = file_of(handle);
  if (f.position + size_t(size) > f.bytes.size()) f.bytes.resize(f.position + size_t(size));
  std::memcpy(f.bytes.data() + f.position, data, size_t(size));
  f.position += size_t(size);
  return size;
}

toff_t seek_to(thandle_t handle, toff_t offset, int whence) {
  MemoryFile& f = file_of(handle);
  const size_t base = whence == SEEK_CUR ? f.position : whence == SEEK_END ? f.bytes.size() : 0;
  f.position = base + size_t(offset);
  return toff_t(f.position);
}

int close_file(thandle_t) { return 0; }
toff_t size_of(thandle_t handle) { return toff_t(file_of(handle).bytes.size()); }
int no_map(thandle_t, void**, toff_t*) { return 0; }
void no_unmap(thandle_t, void*, toff_t) {}

}  // namespace

BayerImage bayer_mosaic(const RawFrame& rgb, unsigned black_level, unsigned white_level,
                        int pixel_sites) {
  if (rgb.channels != 3 || pixel_sites < 1 || pixel_sites > 2 ||
      (rgb.width * pixel_sites) % 2 != 0 || (rgb.height * pixel_sites) % 2 != 0) {
    throw InputError("bayer_mosaic: expected a 3-channel frame of even width and height, got " +
                     std::to_string(rgb.width) + "x" + std::to_string(rgb.height) + "x" +
                     std::to_string(rgb.channels));
  }
  BayerImage out;
  out.width = rgb.width * pixel_sites;
  out.height = rgb.height * pixel_sites;
  out.black_level = black_level;
  out.white_level = white_level;
  out.sites.resize(size_t(out.width) * out.height);
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      const int channel = (y % 2 == 0) ? (x % 2 == 0 ? 0 : 1) : (x % 2 == 0 ? 1 : 2);  // RGGB.
      out.sites[size_t(y) * out.width + x] = uint16_t(
          std::min<unsigned>(rgb.at(x / pixel_sites, y / pixel_sites, channel), white_level));
    }
  }
  return out;
}

std::vector<uint8_t> encode_dng(const BayerImage& image) {
  if (image.sites.size() != size_t(image.width) * image.height || image.width <= 0 ||
      image.height <= 0) {
    throw InputError("encode_dng: " + std::to_string(image.sites.size()) + " sites for " +
                     std::to_string(image.width) + "x" + std::to_string(image.height));
  }
  MemoryFile file;
  std::unique_ptr<TIFF, void (*)(TIFF*)> tif(
      TIFFClientOpen("dng", "wl", &file, read_bytes, write_bytes, seek_to, close_file, size_of,
                     no_map, no_unmap),
      &TIFFClose);
  if (!tif) throw InputError("encode_dng: libtiff could not start a file in memory");
  TIFF* t = tif.get();
  static const uint8_t kDngVersion[4] = {1, 4, 0, 0};
  static const uint16_t kCfaDims[2] = {2, 2};
  static const uint8_t kRggb[4] = {0, 1, 1, 2};
  static const float kIdentity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  static const float kNeutral[3] = {1, 1, 1};
  const float black = float(image.black_level);
  const uint32_t white = image.white_level;
  TIFFSetField(t, TIFFTAG_DNGVERSION, kDngVersion);
  TIFFSetField(t, TIFFTAG_DNGBACKWARDVERSION, kDngVersion);
  TIFFSetField(t, TIFFTAG_SUBFILETYPE, 0);
  TIFFSetField(t, TIFFTAG_IMAGEWIDTH, uint32_t(image.width));
  TIFFSetField(t, TIFFTAG_IMAGELENGTH, uint32_t(image.height));
  TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 16);
  TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
  TIFFSetField(t, TIFFTAG_COMPRESSION, COMPRESSION_NONE);
  TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_CFA);
  TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
  TIFFSetField(t, TIFFTAG_ORIENTATION, ORIENTATION_TOPLEFT);
  TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, uint32_t(image.height));
  TIFFSetField(t, TIFFTAG_MAKE, image.make.c_str());
  TIFFSetField(t, TIFFTAG_MODEL, image.model.c_str());
  TIFFSetField(t, TIFFTAG_UNIQUECAMERAMODEL, (image.make + " " + image.model).c_str());
  TIFFSetField(t, TIFFTAG_CFAREPEATPATTERNDIM, kCfaDims);
  TIFFSetField(t, TIFFTAG_CFAPATTERN, 4, kRggb);
  TIFFSetField(t, TIFFTAG_BLACKLEVEL, 1, &black);
  TIFFSetField(t, TIFFTAG_WHITELEVEL, 1, &white);
  TIFFSetField(t, TIFFTAG_COLORMATRIX1, 9, kIdentity);
  TIFFSetField(t, TIFFTAG_ASSHOTNEUTRAL, 3, kNeutral);
  TIFFSetField(t, TIFFTAG_CALIBRATIONILLUMINANT1, 21);  // D65.
  for (int y = 0; y < image.height; ++y) {
    auto* row = const_cast<uint16_t*>(image.sites.data() + size_t(y) * image.width);
    if (TIFFWriteScanline(t, row, uint32_t(y), 0) < 0) {
      throw InputError("encode_dng: libtiff could not write row " + std::to_string(y));
    }
  }
  if (!TIFFWriteDirectory(t)) throw InputError("encode_dng: libtiff could not write the directory");
  if (image.exposure_s > 0 || image.iso > 0) {
    // EXIF in its own directory, then linked from the first: how LibRaw finds shutter and ISO.
    uint64_t exif_offset = 0;
    TIFFCreateEXIFDirectory(t);
    if (image.exposure_s > 0) TIFFSetField(t, EXIFTAG_EXPOSURETIME, image.exposure_s);
    const uint16_t iso = uint16_t(std::clamp(image.iso, 0, 65535));
    if (image.iso > 0) TIFFSetField(t, EXIFTAG_ISOSPEEDRATINGS, 1, &iso);
    if (!TIFFWriteCustomDirectory(t, &exif_offset) || !TIFFSetDirectory(t, 0) ||
        !TIFFSetField(t, TIFFTAG_EXIFIFD, exif_offset) || !TIFFRewriteDirectory(t)) {
      throw InputError("encode_dng: libtiff could not write the EXIF directory");
    }
  }
  tif.reset();  // Flushes.
  return std::move(file.bytes);
}

}  // namespace ls::sim
