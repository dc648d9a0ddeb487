// The OpenImageIO module (lightstage_oiio.so): every format lightstage's built-in codecs leave to
// OpenImageIO (PNG, TIFF, Radiance HDR, CMYK JPEG, ...). Built as a module and loaded on first use
// (lightstage/image_file.h); it depends on no lightstage library, only on the interface's header.
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <exception>

#include "lightstage/image_file.h"

namespace ls::image_file {
namespace {

OIIO::TypeDesc type_of(Sample sample) {
  switch (sample) {
    case Sample::kUInt8:
      return OIIO::TypeDesc::UINT8;
    case Sample::kUInt16:
      return OIIO::TypeDesc::UINT16;
    case Sample::kHalf:
      return OIIO::TypeDesc::HALF;
    case Sample::kFloat:
      return OIIO::TypeDesc::FLOAT;
    case Sample::kOther:
      break;
  }
  return OIIO::TypeDesc::UNKNOWN;
}

Sample sample_of(const OIIO::TypeDesc& type) {
  switch (type.basetype) {
    case OIIO::TypeDesc::UINT8:
      return Sample::kUInt8;
    case OIIO::TypeDesc::UINT16:
      return Sample::kUInt16;
    case OIIO::TypeDesc::HALF:
      return Sample::kHalf;
    case OIIO::TypeDesc::FLOAT:
      return Sample::kFloat;
    default:
      return Sample::kOther;
  }
}

Attribute attribute_of(const OIIO::ParamValue& p) {
  const OIIO::TypeDesc type = p.type();
  Attribute a{p.name().string(), p.get_string(), type.c_str()};
  if (type == OIIO::TypeDesc::STRING || type.aggregate != OIIO::TypeDesc::SCALAR ||
      type.arraylen != 0) {
    return a;
  }
  switch (type.basetype) {
    case OIIO::TypeDesc::DOUBLE:
      a.value = p.get<double>();
      break;
    case OIIO::TypeDesc::FLOAT:
    case OIIO::TypeDesc::HALF:
      a.value = double(p.get_float());
      break;
    case OIIO::TypeDesc::UINT8:
    case OIIO::TypeDesc::INT8:
    case OIIO::TypeDesc::UINT16:
    case OIIO::TypeDesc::INT16:
    case OIIO::TypeDesc::UINT32:
    case OIIO::TypeDesc::INT32:
      a.value = (long long)p.get_int();
      break;
    case OIIO::TypeDesc::INT64:
      a.value = (long long)p.get<int64_t>();
      break;
    case OIIO::TypeDesc::UINT64:
      a.value = (long long)p.get<uint64_t>();
      break;
    default:
      break;
  }
  return a;
}

class OiioReader final : public Reader {
 public:
  explicit OiioReader(std::unique_ptr<OIIO::ImageInput> in) : in_(std::move(in)) {
    const OIIO::ImageSpec& s = in_->spec();
    spec_.width = s.width;
    spec_.height = s.height;
    spec_.channels = s.nchannels;
    spec_.format = sample_of(s.format);
    spec_.channel_names = s.channelnames;
    spec_.tile_width = s.tile_width;
    spec_.tile_height = s.tile_height;
    for (const OIIO::ParamValue& p : s.extra_attribs) spec_.attributes.push_back(attribute_of(p));
  }
  const Spec& spec() const override { return spec_; }
  bool read_rows(int y0, int y1, Sample as, void* out) override {
    const OIIO::ImageSpec& s = in_->spec();
    if (y0 == 0 && y1 == s.height) {
      return in_->read_image(0, 0, 0, s.nchannels, type_of(as), out);
    }
    return in_->read_scanlines(0, 0, s.y + y0, s.y + y1, 0, 0, s.nchannels, type_of(as), out);
  }
  std::string error() override { return in_->geterror(); }

 private:
  std::unique_ptr<OIIO::ImageInput> in_;
  Spec spec_;
};

// The encoder's bytes into the caller's sink; a failed write is kept for error(), not thrown
// through the encoder.
class SinkProxy final : public OIIO::Filesystem::IOProxy {
 public:
  explicit SinkProxy(Sink& sink) : IOProxy("", Write), sink_(sink) {}
  const char* proxytype() const override { return "lightstage-sink"; }
  size_t write(const void* buf, size_t size) override {
    const size_t written = pwrite(buf, size, m_pos);
    m_pos += int64_t(written);
    return written;
  }
  size_t pwrite(const void* buf, size_t size, int64_t offset) override {
    if (!error_.empty()) return 0;
    try {
      sink_.write_at(uint64_t(offset), buf, size);
    } catch (const std::exception& e) {
      error_ = e.what();
      return 0;
    }
    size_ = std::max(size_, uint64_t(offset) + size);
    return size;
  }
  size_t size() const override { return size_t(size_); }
  const std::string& failure() const { return error_; }

 private:
  Sink& sink_;
  uint64_t size_ = 0;
  std::string error_;
};

OIIO::ImageSpec oiio_spec(const Spec& spec) {
  OIIO::ImageSpec s(spec.width, spec.height, spec.channels, type_of(spec.format));
  if (!spec.channel_names.empty()) s.channelnames = spec.channel_names;
  s.tile_width = spec.tile_width;
  s.tile_height = spec.tile_height;
  s.tile_depth = spec.tile_width > 0 ? 1 : 0;
  for (const Attribute& a : spec.attributes) {
    if (const std::string* text = a.text()) {
      s.attribute(a.name, *text);
    } else if (const long long* i = std::get_if<long long>(&a.value)) {
      s.attribute(a.name, int(*i));
    } else if (a.type_name == "float") {
      s.attribute(a.name, float(std::get<double>(a.value)));
    } else {
      const double d = std::get<double>(a.value);
      s.attribute(a.name, OIIO::TypeDesc::DOUBLE, &d);
    }
  }
  return s;
}

class OiioWriter final : public Writer {
 public:
  OiioWriter(std::unique_ptr<OIIO::ImageOutput> out, Sink& sink, int tile_height)
      : proxy_(sink), out_(std::move(out)), tile_height_(tile_height) {}
  ~OiioWriter() override {
    if (!closed_) out_->close();
  }
  bool start(const std::string& name, const OIIO::ImageSpec& spec) {
    return out_->supports("ioproxy") && out_->set_ioproxy(&proxy_) && out_->open(name, spec);
  }
  bool write_rows(int y0, int y1, Sample from, const void* data) override {
    const OIIO::ImageSpec& s = out_->spec();
    return tile_height_ > 0 ? out_->write_tiles(0, s.width, y0, y1, 0, 1, type_of(from), data)
                            : out_->write_scanlines(y0, y1, 0, type_of(from), data);
  }
  bool close() override {
    closed_ = true;
    return out_->close() && proxy_.failure().empty();
  }
  std::string error() override {
    std::string why = proxy_.failure().empty() ? out_->geterror() : proxy_.failure();
    return why.empty() ? "unknown error" : why;
  }

 private:
  SinkProxy proxy_;
  std::unique_ptr<OIIO::ImageOutput> out_;  // Closed before the proxy goes.
  int tile_height_ = 0;
  bool closed_ = false;
};

class OiioCodecs final : public Codecs {
 public:
  std::unique_ptr<Reader> open(const std::filesystem::path& path, std::string& error) override {
    auto in = OIIO::ImageInput::open(path.string());
    if (!in) {
      error = OIIO::geterror();
      if (error.empty()) error = "unknown format";
      return nullptr;
    }
    return std::make_unique<OiioReader>(std::move(in));
  }
  std::unique_ptr<Writer> create(const std::filesystem::path& named_like, const Spec& spec,
                                 Sink& sink, std::string& error) override {
    auto out = OIIO::ImageOutput::create(named_like.string());
    if (!out) {
      error = "cannot write this format: " + OIIO::geterror();
      return nullptr;
    }
    const std::string format = out->format_name();
    auto writer = std::make_unique<OiioWriter>(std::move(out), sink, spec.tile_height);
    if (!writer->start(named_like.string(), oiio_spec(spec))) {
      error = "the " + format + " writer cannot start: " + writer->error();
      return nullptr;
    }
    return writer;
  }
};

}  // namespace
}  // namespace ls::image_file

extern "C" __attribute__((visibility("default"))) ls::image_file::Codecs* lightstage_oiio_codecs() {
  static ls::image_file::OiioCodecs codecs;
  return &codecs;
}
