// Camera raw files as image files: decoded whole by LibRaw on opening (raw_photo.h), linear,
// 16-bit, camera RGB. Read only: nothing writes a camera's raw format.
#include <algorithm>
#include <cstring>

#include "lightstage/errors.h"
#include "lightstage/image_file.h"
#include "lightstage/raw_photo.h"

namespace ls::image_file {
namespace {

namespace fs = std::filesystem;

class RawReader final : public Reader {
 public:
  explicit RawReader(DecodedRaw decoded) : decoded_(std::move(decoded)) {
    const RawFrame& f = decoded_.frame;
    spec_.width = f.width;
    spec_.height = f.height;
    spec_.channels = f.channels;
    spec_.format = Sample::kUInt16;
    spec_.channel_names = default_channel_names(f.channels);
    // What an importer needs to know: the codes are linear (no transfer curve to undo).
    spec_.set("lightstage:linear", 1LL);
    spec_.set("raw:camera", decoded_.camera);
    spec_.set("raw:black_level", decoded_.black_level);
    spec_.set("raw:white_level", decoded_.white_level);
    if (decoded_.exposure_s > 0) spec_.set("ExposureTime", decoded_.exposure_s);
    if (decoded_.iso > 0) spec_.set("Exif:ISOSpeedRatings", decoded_.iso);
  }

  const Spec& spec() const override { return spec_; }

  bool read_rows(int y0, int y1, Sample as, void* out) override {
    if (y0 < 0 || y1 > spec_.height || y0 > y1) {
      error_ = "rows " + std::to_string(y0) + ".." + std::to_string(y1) + " outside the image";
      return false;
    }
    const size_t first = size_t(y0) * spec_.width * spec_.channels;
    const size_t count = size_t(y1 - y0) * spec_.width * spec_.channels;
    const uint16_t* codes = decoded_.frame.pixels.data() + first;
    switch (as) {
      case Sample::kUInt16:
        std::memcpy(out, codes, count * sizeof(uint16_t));
        return true;
      case Sample::kFloat:
        for (size_t i = 0; i < count; ++i) static_cast<float*>(out)[i] = codes[i] / 65535.0f;
        return true;
      case Sample::kUInt8:
        for (size_t i = 0; i < count; ++i) {
          static_cast<uint8_t*>(out)[i] = uint8_t((codes[i] * 255u + 32767u) / 65535u);
        }
        return true;
      default:
        error_ = std::string("a raw file reads as 8-bit, 16-bit or float, not ") + sample_name(as);
        return false;
    }
  }

  std::string error() override { return std::exchange(error_, {}); }

 private:
  DecodedRaw decoded_;
  Spec spec_;
  std::string error_;
};

class RawCodecs final : public Codecs {
 public:
  std::unique_ptr<Reader> open(const fs::path& path, std::string& error) override {
    try {
      return std::make_unique<RawReader>(decode_raw_photo(path));
    } catch (const InputError& e) {
      // The caller names the file.
      const std::string prefix = path.string() + ": ";
      error = e.what();
      if (error.rfind(prefix, 0) == 0) error.erase(0, prefix.size());
      return nullptr;
    }
  }

  std::unique_ptr<Writer> create(const fs::path& named_like, const Spec&, Sink&,
                                 std::string& error) override {
    error = named_like.extension().string() +
            ": a camera raw format; lightstage reads raw files but writes none";
    return nullptr;
  }
};

}  // namespace

Codecs& raw_codecs() {
  static RawCodecs codecs;
  return codecs;
}

}  // namespace ls::image_file
