// JPEG through libjpeg (image_file.h): RTI sets and OpenLIME planes without OpenImageIO. Pixels
// are those OpenImageIO 2.4 reads (libjpeg's defaults: islow DCT, fancy upsampling), to the bit.
// libjpeg reports a failure by calling error_exit, which must not return: ours longjmps back to
// guarded(), whose setjmp is set just before the call into libjpeg, so that only libjpeg's own
// frames and guarded()'s lambda (references only, nothing to destroy) are jumped over.
#include <cerrno>
#include <charconv>
#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

// After <cstdio>: jpeglib.h needs FILE and size_t.
#include <jerror.h>
#include <jpeglib.h>

#include "lightstage/image_file.h"

namespace ls::image_file {
namespace {

namespace fs = std::filesystem;

// A file cut short or corrupt can warn once per restart interval: the first few say enough.
constexpr int kMaxWarnings = 8;

// libjpeg's error manager, its failures and warnings kept as text; the codec struct's client_data
// points at it.
struct Messages {
  jpeg_error_mgr manager{};
  std::jmp_buf jump{};
  std::string text;
  int warnings = 0;

  void add(std::string_view message) noexcept {
    try {
      if (!text.empty()) text += "; ";
      text += message;
    } catch (...) {  // Out of memory: the message is lost, not the decoding.
    }
  }
  std::string take() {
    warnings = 0;
    return std::exchange(text, {});
  }
};

Messages& messages_of(j_common_ptr cinfo) { return *static_cast<Messages*>(cinfo->client_data); }

[[noreturn]] void on_failure(j_common_ptr cinfo) {
  char message[JMSG_LENGTH_MAX];
  (*cinfo->err->format_message)(cinfo, message);
  Messages& messages = messages_of(cinfo);
  messages.add(message);
  std::longjmp(messages.jump, 1);
}

// Level -1 is a warning (a file cut short: "Premature end of JPEG file", once for each buffer
// asked past the end); the others are traces.
void on_message(j_common_ptr cinfo, int level) {
  if (level >= 0) return;
  ++cinfo->err->num_warnings;
  Messages& messages = messages_of(cinfo);
  char message[JMSG_LENGTH_MAX];
  (*cinfo->err->format_message)(cinfo, message);
  if (messages.warnings >= kMaxWarnings || messages.text.find(message) != std::string::npos) return;
  ++messages.warnings;
  messages.add(message);
}

template <class Info>
void attach(Info& cinfo, Messages& messages) {
  cinfo.err = jpeg_std_error(&messages.manager);
  messages.manager.error_exit = on_failure;
  messages.manager.emit_message = on_message;
  cinfo.client_data = &messages;
}

// Runs `call`, calls into libjpeg and nothing that would need destroying (a failure jumps over
// it); false when libjpeg failed, its message in `messages`.
template <class Call>
bool guarded(Messages& messages, const Call& call) {
  if (setjmp(messages.jump) != 0) return false;
  call();
  return true;
}

// Codes as `as` (OpenImageIO's conversions: float(code) * (1 / 255.0f), code * 257).
void convert_codes(const JSAMPLE* codes, std::size_t count, Sample as, void* out) {
  if (as == Sample::kFloat) {
    constexpr float kScale = 1.0f / 255.0f;
    float* values = static_cast<float*>(out);
    for (std::size_t i = 0; i < count; ++i) values[i] = float(codes[i]) * kScale;
  } else {
    auto* values = static_cast<std::uint16_t*>(out);
    for (std::size_t i = 0; i < count; ++i) values[i] = std::uint16_t(codes[i] * 257);
  }
}

class JpegReader final : public Reader {
 public:
  explicit JpegReader(fs::path path) : path_(std::move(path)) {}
  JpegReader(const JpegReader&) = delete;
  JpegReader& operator=(const JpegReader&) = delete;
  ~JpegReader() override { stop(); }

  // Opens the file, reads its header and starts decoding from the top. False with a message, or
  // with `declined` and none for a colour space left to OpenImageIO (CMYK, YCCK).
  bool start(bool& declined);
  const Spec& spec() const override { return spec_; }
  bool read_rows(int y0, int y1, Sample as, void* out) override;
  std::string error() override { return messages_.take(); }

 private:
  void stop();
  bool decode_row(JSAMPLE* codes);

  fs::path path_;
  Spec spec_;
  Messages messages_;
  std::FILE* file_ = nullptr;
  jpeg_decompress_struct cinfo_{};  // libjpeg keeps pointers into it and into messages_.
  bool created_ = false;
  int next_row_ = 0;
  std::vector<JSAMPLE> scratch_;  // A row skipped or to convert.
};

bool JpegReader::start(bool& declined) {
  declined = false;
  file_ = std::fopen(path_.c_str(), "rb");
  if (file_ == nullptr) {
    messages_.add(std::strerror(errno));
    return false;
  }
  attach(cinfo_, messages_);
  created_ = true;  // cinfo_ is zeroed: destroying it is safe even if creating it fails.
  const bool header_read = guarded(messages_, [&] {
    jpeg_create_decompress(&cinfo_);
    jpeg_stdio_src(&cinfo_, file_);
    jpeg_read_header(&cinfo_, TRUE);
  });
  if (!header_read) return false;
  switch (cinfo_.jpeg_color_space) {
    case JCS_GRAYSCALE:
      cinfo_.out_color_space = JCS_GRAYSCALE;
      break;
    case JCS_YCbCr:
    case JCS_RGB:
      cinfo_.out_color_space = JCS_RGB;
      break;
    default:
      declined = true;
      return false;
  }
  if (!guarded(messages_, [&] { jpeg_start_decompress(&cinfo_); })) return false;
  const int width = int(cinfo_.output_width), height = int(cinfo_.output_height);
  const int channels = cinfo_.output_components;
  if (spec_.width == 0) {
    spec_.width = width;
    spec_.height = height;
    spec_.channels = channels;
    spec_.format = Sample::kUInt8;
    spec_.channel_names = default_channel_names(channels);
    scratch_.resize(std::size_t(width) * std::size_t(channels));
  } else if (width != spec_.width || height != spec_.height || channels != spec_.channels) {
    messages_.add("the file changed while it was being read");
    return false;
  }
  next_row_ = 0;
  return true;
}

void JpegReader::stop() {
  if (created_) jpeg_destroy_decompress(&cinfo_);
  created_ = false;
  cinfo_ = {};
  if (file_ != nullptr) std::fclose(file_);
  file_ = nullptr;
}

bool JpegReader::decode_row(JSAMPLE* codes) {
  JDIMENSION rows = 0;
  if (!guarded(messages_, [&] { rows = jpeg_read_scanlines(&cinfo_, &codes, 1); })) {
    stop();  // libjpeg's state is undefined after a failure: the next read starts again.
    return false;
  }
  if (rows != 1) {
    messages_.add("the decoder returned no row");
    stop();
    return false;
  }
  ++next_row_;
  return true;
}

bool JpegReader::read_rows(int y0, int y1, Sample as, void* out) {
  if (y0 < 0 || y1 > spec_.height || y0 > y1) {
    messages_.add("rows " + std::to_string(y0) + "-" + std::to_string(y1) + " are outside 0-" +
                  std::to_string(spec_.height));
    return false;
  }
  if (as != Sample::kUInt8 && as != Sample::kUInt16 && as != Sample::kFloat) {
    messages_.add("cannot convert 8-bit samples to " + std::string(sample_name(as)));
    return false;
  }
  if (y0 == y1) return true;
  if (!created_ || next_row_ > y0) {
    stop();
    bool declined = false;
    if (!start(declined)) {
      if (declined) messages_.add("the file changed while it was being read");
      return false;
    }
  }
  while (next_row_ < y0) {
    if (!decode_row(scratch_.data())) return false;
  }
  const std::size_t row_samples = scratch_.size();
  auto* bytes = static_cast<unsigned char*>(out);
  const std::size_t row_bytes = row_samples * sample_bytes(as);
  for (int y = y0; y < y1; ++y) {
    unsigned char* row = bytes + std::size_t(y - y0) * row_bytes;
    JSAMPLE* codes = as == Sample::kUInt8 ? row : scratch_.data();
    if (!decode_row(codes)) return false;
    if (as != Sample::kUInt8) convert_codes(codes, row_samples, as, row);
  }
  return true;
}

// libjpeg's output, into a buffer that grows. Standard layout: libjpeg's pointer to `manager` is
// one to the whole.
struct Destination {
  jpeg_destination_mgr manager{};
  std::vector<JOCTET>* bytes = nullptr;
};

Destination& destination_of(j_compress_ptr cinfo) {
  return *reinterpret_cast<Destination*>(cinfo->dest);
}

bool resize(std::vector<JOCTET>& bytes, std::size_t size) noexcept {
  try {
    bytes.resize(size);
    return true;
  } catch (...) {
    return false;
  }
}

// The buffer grown to `size`, libjpeg's free space from `used` on; out of memory is libjpeg's
// failure (outside the catch above: a longjmp must not leave a handler).
void grow(j_compress_ptr cinfo, std::size_t used, std::size_t size) {
  Destination& d = destination_of(cinfo);
  if (!resize(*d.bytes, size)) {
    cinfo->err->msg_code = JERR_OUT_OF_MEMORY;
    cinfo->err->msg_parm.i[0] = 0;
    (*cinfo->err->error_exit)(reinterpret_cast<j_common_ptr>(cinfo));
  }
  d.manager.next_output_byte = d.bytes->data() + used;
  d.manager.free_in_buffer = size - used;
}

void on_init_destination(j_compress_ptr cinfo) { grow(cinfo, 0, std::size_t(1) << 16); }

// Called when the buffer is full.
boolean on_full_buffer(j_compress_ptr cinfo) {
  const std::size_t used = destination_of(cinfo).bytes->size();
  grow(cinfo, used, 2 * used);
  return TRUE;
}

void on_term_destination(j_compress_ptr cinfo) {
  Destination& d = destination_of(cinfo);
  d.bytes->resize(d.bytes->size() - d.manager.free_in_buffer);
}

struct Settings {
  int quality = 95;
  int luma_h = 2, luma_v = 2;  // Luma's sampling factors (chroma's are 1): libjpeg's 4:2:0.
};

// The spec's "Compression" ("jpeg", "jpeg:Q") and "jpeg:subsampling"; false with `error` for
// values this writer cannot honour.
bool settings_of(const Spec& spec, Settings& settings, std::string& error) {
  if (const Attribute* a = spec.find("Compression")) {
    const std::string* text = a->text();
    const std::string_view prefix = "jpeg:";
    int quality = settings.quality;
    bool valid = text != nullptr && (*text == "jpeg" || text->starts_with(prefix));
    if (valid && *text != "jpeg") {
      const char* end = text->data() + text->size();
      const auto [stop, failure] = std::from_chars(text->data() + prefix.size(), end, quality);
      valid = failure == std::errc() && stop == end && quality >= 1 && quality <= 100;
    }
    if (!valid) {
      error = "JPEG compression is \"jpeg:Q\" with a quality Q from 1 to 100, not \"" +
              (text != nullptr ? *text : a->type_name) + "\"";
      return false;
    }
    settings.quality = quality;
  }
  if (const Attribute* a = spec.find("jpeg:subsampling")) {
    const std::string* text = a->text();
    const std::string value = text != nullptr ? *text : a->type_name;
    if (value == "4:4:4") {
      settings.luma_h = settings.luma_v = 1;
    } else if (value == "4:2:2") {
      settings.luma_h = 2;
      settings.luma_v = 1;
    } else if (value != "4:2:0") {
      error = "JPEG subsampling is 4:4:4, 4:2:2 or 4:2:0, not \"" + value + "\"";
      return false;
    }
  }
  return true;
}

// Rows of `from` as 8-bit codes (kFloat: clamped to [0, 1], NaN as 0, rounded).
void to_codes(const void* data, Sample from, std::size_t count, JSAMPLE* codes) {
  if (from == Sample::kUInt8) {
    std::memcpy(codes, data, count);
  } else if (from == Sample::kUInt16) {
    const auto* values = static_cast<const std::uint16_t*>(data);
    for (std::size_t i = 0; i < count; ++i)
      codes[i] = JSAMPLE((values[i] * 255u + 32767u) / 65535u);
  } else {
    const auto* values = static_cast<const float*>(data);
    for (std::size_t i = 0; i < count; ++i) {
      const float v = values[i] > 0.0f ? (values[i] < 1.0f ? values[i] : 1.0f) : 0.0f;
      codes[i] = JSAMPLE(std::lround(v * 255.0f));
    }
  }
}

class JpegWriter final : public Writer {
 public:
  explicit JpegWriter(Sink& sink) : sink_(sink) {}
  JpegWriter(const JpegWriter&) = delete;
  JpegWriter& operator=(const JpegWriter&) = delete;
  ~JpegWriter() override {
    if (created_) jpeg_destroy_compress(&cinfo_);
  }

  bool start(const Spec& spec, const Settings& settings);
  bool write_rows(int y0, int y1, Sample from, const void* data) override;
  bool close() override;
  std::string error() override { return messages_.take(); }

 private:
  Sink& sink_;
  Messages messages_;
  std::vector<JOCTET> bytes_;
  Destination destination_;
  jpeg_compress_struct cinfo_{};  // libjpeg keeps pointers into it, messages_ and destination_.
  bool created_ = false, failed_ = false, closed_ = false;
  int height_ = 0, next_row_ = 0;
  std::vector<JSAMPLE> codes_;  // One row.
};

bool JpegWriter::start(const Spec& spec, const Settings& settings) {
  attach(cinfo_, messages_);
  destination_.bytes = &bytes_;
  destination_.manager.init_destination = on_init_destination;
  destination_.manager.empty_output_buffer = on_full_buffer;
  destination_.manager.term_destination = on_term_destination;
  height_ = spec.height;
  codes_.resize(std::size_t(spec.width) * std::size_t(spec.channels));
  created_ = true;  // cinfo_ is zeroed: destroying it is safe even if creating it fails.
  return guarded(messages_, [&] {
    jpeg_create_compress(&cinfo_);
    cinfo_.dest = &destination_.manager;
    cinfo_.image_width = JDIMENSION(spec.width);
    cinfo_.image_height = JDIMENSION(spec.height);
    cinfo_.input_components = spec.channels;
    cinfo_.in_color_space = spec.channels == 1 ? JCS_GRAYSCALE : JCS_RGB;
    jpeg_set_defaults(&cinfo_);
    jpeg_set_quality(&cinfo_, settings.quality, TRUE);
    if (spec.channels == 3) {
      cinfo_.comp_info[0].h_samp_factor = settings.luma_h;
      cinfo_.comp_info[0].v_samp_factor = settings.luma_v;
    }
    jpeg_start_compress(&cinfo_, TRUE);
  });
}

bool JpegWriter::write_rows(int y0, int y1, Sample from, const void* data) {
  if (failed_ || closed_) {
    messages_.add(closed_ ? "the file is closed" : "an earlier write failed");
    return false;
  }
  if (y0 != next_row_ || y1 < y0 || y1 > height_) {
    messages_.add("rows " + std::to_string(y0) + "-" + std::to_string(y1) +
                  " written out of order: row " + std::to_string(next_row_) + " comes next");
    return false;
  }
  if (from != Sample::kUInt8 && from != Sample::kUInt16 && from != Sample::kFloat) {
    messages_.add("cannot write " + std::string(sample_name(from)) + " samples as JPEG");
    return false;
  }
  const auto* bytes = static_cast<const unsigned char*>(data);
  const std::size_t row_bytes = codes_.size() * sample_bytes(from);
  for (int y = y0; y < y1; ++y) {
    to_codes(bytes + std::size_t(y - y0) * row_bytes, from, codes_.size(), codes_.data());
    JSAMPROW row = codes_.data();
    if (!guarded(messages_, [&] { jpeg_write_scanlines(&cinfo_, &row, 1); })) {
      failed_ = true;
      return false;
    }
    ++next_row_;
  }
  return true;
}

bool JpegWriter::close() {
  if (closed_ || failed_) {
    messages_.add(closed_ ? "the file is closed" : "an earlier write failed");
    return false;
  }
  closed_ = true;
  if (next_row_ != height_) {
    messages_.add("only " + std::to_string(next_row_) + " of " + std::to_string(height_) +
                  " rows were written");
    return false;
  }
  if (!guarded(messages_, [&] { jpeg_finish_compress(&cinfo_); })) return false;
  try {
    sink_.write_at(0, bytes_.data(), bytes_.size());
  } catch (const std::exception& e) {
    messages_.add(e.what());
    return false;
  }
  bytes_ = {};
  return true;
}

class JpegCodecs final : public Codecs {
 public:
  std::unique_ptr<Reader> open(const fs::path& path, std::string& error) override {
    auto reader = std::make_unique<JpegReader>(path);
    bool declined = false;
    if (reader->start(declined)) return reader;
    error = declined ? "" : reader->error();
    return nullptr;
  }

  std::unique_ptr<Writer> create(const fs::path& /*named_like*/, const Spec& spec, Sink& sink,
                                 std::string& error) override {
    if (spec.channels != 1 && spec.channels != 3) {
      error = "JPEG holds 1 or 3 channels, not " + std::to_string(spec.channels);
      return nullptr;
    }
    if (spec.width < 1 || spec.height < 1 || spec.width > JPEG_MAX_DIMENSION ||
        spec.height > JPEG_MAX_DIMENSION) {
      error = "JPEG images are 1 to " + std::to_string(JPEG_MAX_DIMENSION) +
              " pixels a side, not " + std::to_string(spec.width) + "x" +
              std::to_string(spec.height);
      return nullptr;
    }
    if (spec.tile_width > 0 || spec.tile_height > 0) {
      error = "JPEG has no tiles";
      return nullptr;
    }
    Settings settings;
    if (!settings_of(spec, settings, error)) return nullptr;
    auto writer = std::make_unique<JpegWriter>(sink);
    if (!writer->start(spec, settings)) {
      error = "the JPEG encoder cannot start: " + writer->error();
      return nullptr;
    }
    return writer;
  }
};

}  // namespace

Codecs& jpeg_codecs() {
  static JpegCodecs codecs;
  return codecs;
}

}  // namespace ls::image_file
