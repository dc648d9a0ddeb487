#include "lightstage/image_file.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <fstream>

#include "lightstage/errors.h"
#include "lightstage/module.h"
#include "lightstage/raw_photo.h"

namespace ls::image_file {

namespace fs = std::filesystem;

std::size_t sample_bytes(Sample sample) {
  switch (sample) {
    case Sample::kUInt8:
      return 1;
    case Sample::kUInt16:
    case Sample::kHalf:
      return 2;
    case Sample::kFloat:
      return 4;
    case Sample::kOther:
      break;
  }
  return 0;
}

const char* sample_name(Sample sample) {
  switch (sample) {
    case Sample::kUInt8:
      return "8-bit";
    case Sample::kUInt16:
      return "16-bit";
    case Sample::kHalf:
      return "half float";
    case Sample::kFloat:
      return "float";
    case Sample::kOther:
      break;
  }
  return "other";
}

std::vector<std::string> default_channel_names(int channels) {
  if (channels == 1) return {"Y"};
  std::vector<std::string> names;
  names.reserve(size_t(std::max(channels, 0)));
  for (int c = 0; c < channels; ++c) {
    names.push_back(c < 4 ? std::string(1, "RGBA"[c]) : "channel" + std::to_string(c));
  }
  return names;
}

double Attribute::number() const {
  if (const double* d = std::get_if<double>(&value)) return *d;
  return double(std::get<long long>(value));
}

const Attribute* Spec::find(std::string_view name) const {
  for (const Attribute& a : attributes) {
    if (a.name == name) return &a;
  }
  return nullptr;
}

void Spec::set(std::string name, std::variant<std::string, double, long long> value,
               std::string type_name) {
  if (type_name.empty()) {
    type_name = std::holds_alternative<std::string>(value) ? "string"
                : std::holds_alternative<double>(value)    ? "double"
                                                           : "int";
  }
  Attribute a{std::move(name), std::move(value), std::move(type_name)};
  for (Attribute& existing : attributes) {
    if (existing.name == a.name) {
      existing = std::move(a);
      return;
    }
  }
  attributes.push_back(std::move(a));
}

void MemorySink::write_at(std::uint64_t offset, const void* data, std::size_t size) {
  if (bytes.size() < offset + size) bytes.resize(offset + size);
  std::memcpy(bytes.data() + offset, data, size);
}

namespace {

enum class Kind { kExr, kJpeg, kPng, kOther };

// By the first bytes, as both libraries' own readers check them.
Kind kind_of_content(const fs::path& path) {
  unsigned char magic[4] = {};
  std::ifstream file(path, std::ios::binary);
  file.read(reinterpret_cast<char*>(magic), sizeof magic);
  if (file.gcount() == 4 && magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 &&
      magic[3] == 0x01) {
    return Kind::kExr;
  }
  if (file.gcount() >= 3 && magic[0] == 0xff && magic[1] == 0xd8 && magic[2] == 0xff) {
    return Kind::kJpeg;
  }
  if (file.gcount() == 4 && magic[0] == 0x89 && magic[1] == 'P' && magic[2] == 'N' &&
      magic[3] == 'G') {
    return Kind::kPng;
  }
  return Kind::kOther;
}

Codecs& built_in(Kind kind) {
  return kind == Kind::kExr ? exr_codecs() : kind == Kind::kJpeg ? jpeg_codecs() : png_codecs();
}

Kind kind_of_name(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  if (ext == ".exr") return Kind::kExr;
  if (ext == ".jpg" || ext == ".jpeg") return Kind::kJpeg;
  if (ext == ".png") return Kind::kPng;
  return Kind::kOther;
}

}  // namespace

std::unique_ptr<Reader> open(const fs::path& path, std::string& error) {
  error.clear();
  // Most raw formats are TIFF inside: the extension tells them from a TIFF.
  if (is_raw_photo_name(path)) return raw_codecs().open(path, error);
  const Kind kind = kind_of_content(path);
  if (kind != Kind::kOther) {
    std::unique_ptr<Reader> reader = built_in(kind).open(path, error);
    // Null without a message: a file of this format that the built-in reader leaves to
    // OpenImageIO (a CMYK JPEG).
    if (reader || !error.empty()) return reader;
  }
  return oiio_codecs().open(path, error);
}

std::unique_ptr<Writer> create(const fs::path& named_like, const Spec& spec, Sink& sink,
                               std::string& error) {
  error.clear();
  if (is_raw_photo_name(named_like)) return raw_codecs().create(named_like, spec, sink, error);
  const Kind kind = kind_of_name(named_like);
  if (kind != Kind::kOther) return built_in(kind).create(named_like, spec, sink, error);
  return oiio_codecs().create(named_like, spec, sink, error);
}

Codecs& oiio_codecs() {
  using Entry = Codecs* (*)();
  static Codecs* codecs =
      reinterpret_cast<Entry>(module_symbol("lightstage_oiio", "lightstage_oiio_codecs"))();
  return *codecs;
}

bool oiio_loaded() { return module_loaded("lightstage_oiio"); }

}  // namespace ls::image_file
