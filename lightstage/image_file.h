#pragma once
// Image files through one narrow interface. The formats lightstage's own jobs live on are read and
// written by their own libraries: OpenEXR (fields, maps, relit images), libjpeg (RTI sets,
// OpenLIME planes) and libpng (frames, previews). Every other format (TIFF, Radiance HDR, ...)
// goes through OpenImageIO,
// loaded from a module (lightstage_oiio) on first use: Debian's OpenImageIO brings 260 libraries
// and 120 MiB of resident memory into a process before any work, more than an RTI set's whole
// compression needs. Row 0 is the top row of the data window.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace ls::image_file {

// A pixel value's type, in a file or in memory.
enum class Sample { kUInt8, kUInt16, kHalf, kFloat, kOther };
std::size_t sample_bytes(Sample sample);
const char* sample_name(Sample sample);  // "8-bit", "16-bit", "half float", "float", "other".
// The channel names a file gets when none are given, as OpenImageIO names them: Y for one
// channel, else R, G, B, A, channel4, channel5, ...
std::vector<std::string> default_channel_names(int channels);

// A header attribute. Numbers of any integer type read as long long, of any floating type as
// double; a value of another type (a vector, a matrix, ...) reads as its text, type_name naming
// the type (e.g. "v3f"), so that a caller can refuse it by name.
struct Attribute {
  std::string name;
  std::variant<std::string, double, long long> value;
  std::string type_name;  // "string", "double", "float", "int", ... as the file stores it.

  const std::string* text() const { return std::get_if<std::string>(&value); }
  bool is_number() const { return !std::holds_alternative<std::string>(value); }
  double number() const;  // The number (is_number() only).
};

struct Spec {
  int width = 0, height = 0, channels = 0;
  Sample format = Sample::kFloat;  // As stored (the first channel's, where they differ).
  std::vector<std::string> channel_names;
  int tile_width = 0, tile_height = 0;  // 0: scanlines.
  std::vector<Attribute> attributes;

  const Attribute* find(std::string_view name) const;
  // Adds or replaces. A writer takes what its format has: EXR "compression" ("none", "zip",
  // "rle", "piz", ...); JPEG "Compression" ("jpeg:Q") and "jpeg:subsampling" ("4:4:4"); PNG
  // "png:compressionLevel"; other names as the format's own header attributes where it has them.
  void set(std::string name, std::variant<std::string, double, long long> value,
           std::string type_name = "");
};

class Reader {
 public:
  virtual ~Reader() = default;
  virtual const Spec& spec() const = 0;
  // Rows [y0, y1), every channel, interleaved, converted to `as` (kFloat: integer codes
  // normalised to [0, 1]; kUInt16: 16-bit codes, 8-bit ones scaled by 257). False on failure,
  // with error() saying why. Rows may be asked in any order; some formats decode from the top
  // again for rows above the last ones read.
  virtual bool read_rows(int y0, int y1, Sample as, void* out) = 0;
  // What the decoder reported since the last call, failures and warnings alike (a JPEG cut short
  // is only a warning to libjpeg: "Premature end of JPEG file"); clears it.
  virtual std::string error() = 0;
};

// Where a writer's bytes go. write_at throws InputError naming the file when the bytes cannot be
// written (a full disk fails here); a writer keeps that message for its error().
class Sink {
 public:
  virtual ~Sink() = default;
  virtual void write_at(std::uint64_t offset, const void* data, std::size_t size) = 0;
};

// Bytes in memory (to be written whole, atomically, where the encoder's own writes would not all
// report a full disk).
class MemorySink final : public Sink {
 public:
  void write_at(std::uint64_t offset, const void* data, std::size_t size) override;
  std::vector<unsigned char> bytes;
};

class Writer {
 public:
  virtual ~Writer() = default;
  // Rows [y0, y1), in order from the top, every channel, interleaved, of type `from` (converted
  // to the file's). A tiled file takes whole rows of tiles (the last may be short).
  virtual bool write_rows(int y0, int y1, Sample from, const void* data) = 0;
  // Finishes the file (its offset tables, its trailer). No write after it.
  virtual bool close() = 0;
  virtual std::string error() = 0;
};

// Opens a file of any format either library reads, by its content: EXR, JPEG and PNG here, camera
// raw files (by their extension) through LibRaw, the rest through OpenImageIO. Null with `error`
// set (naming neither the file: the caller does) when it cannot be opened or its format is unknown.
std::unique_ptr<Reader> open(const std::filesystem::path& path, std::string& error);

// A writer of the format `named_like`'s extension says, into `sink`, which must outlive it. Null
// with `error` set when the format cannot be written or the spec does not suit it.
std::unique_ptr<Writer> create(const std::filesystem::path& named_like, const Spec& spec,
                               Sink& sink, std::string& error);

// The interface a codec module (and each built-in codec) gives.
class Codecs {
 public:
  virtual ~Codecs() = default;
  virtual std::unique_ptr<Reader> open(const std::filesystem::path& path, std::string& error) = 0;
  virtual std::unique_ptr<Writer> create(const std::filesystem::path& named_like, const Spec& spec,
                                         Sink& sink, std::string& error) = 0;
};

// The built-in codecs (image_file_exr.cc, image_file_jpeg.cc, image_file_png.cc).
Codecs& exr_codecs();
Codecs& jpeg_codecs();
Codecs& png_codecs();
// Camera raw files through LibRaw, chosen by extension (raw_photo.h): read only.
Codecs& raw_codecs();
// The OpenImageIO module, loaded on first use. InputError when it cannot be found or loaded.
Codecs& oiio_codecs();
// True once the module has been loaded in this process (for tests that show a job never needs it).
bool oiio_loaded();

}  // namespace ls::image_file

// The module's one entry point (lightstage_oiio.so): its codecs, alive as long as the process.
extern "C" ls::image_file::Codecs* lightstage_oiio_codecs();
