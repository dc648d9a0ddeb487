#include "lightstage/image_file_exr_header.h"

#include <ImfBoxAttribute.h>
#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfCompressionAttribute.h>
#include <ImfDoubleAttribute.h>
#include <ImfFloatAttribute.h>
#include <ImfFloatVectorAttribute.h>
#include <ImfHeader.h>
#include <ImfIntAttribute.h>
#include <ImfMatrixAttribute.h>
#include <ImfRationalAttribute.h>
#include <ImfStringAttribute.h>
#include <ImfVecAttribute.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <climits>
#include <cstdio>
#include <string_view>
#include <utility>

#include "lightstage/text.h"

namespace ls::image_file {
namespace {

// The position of `suffix` among the space-separated `names`, ignoring case; 10000 when absent.
int index_in(std::string_view suffix, std::string_view names) {
  int i = 0;
  for (std::size_t at = 0; at < names.size(); ++i) {
    const std::size_t end = std::min(names.find(' ', at), names.size());
    if (equals_ignoring_case(suffix, names.substr(at, end - at))) return i;
    at = end + 1;
  }
  return 10000;
}

struct OrderedChannel {
  std::string name;
  std::size_t layer_size = 0;  // The layer: the name up to its last '.', the dot included.
  int rank = 0;
  Imf::PixelType type = Imf::HALF;

  std::string_view layer() const { return std::string_view(name).substr(0, layer_size); }
  std::string_view suffix() const { return std::string_view(name).substr(layer_size); }
};

// OpenImageIO's names of OpenEXR's compressions, in the order of Imf::Compression.
constexpr std::array<const char*, 10> kCompressions = {"none",  "rle", "zips", "zip",  "piz",
                                                       "pxr24", "b44", "b44a", "dwaa", "dwab"};

// The header's layout, which Spec says otherwise (or not at all): not attributes to a caller.
bool structural(std::string_view name) {
  for (const char* s : {"channels", "dataWindow", "displayWindow", "lineOrder", "pixelAspectRatio",
                        "screenWindowCenter", "screenWindowWidth", "tiles", "type", "version",
                        "chunkCount", "maxSamplesPerPixel"}) {
    if (name == s) return true;
  }
  return false;
}

template <class T>
std::string joined(const T* values, std::size_t count) {
  std::string text;
  for (std::size_t i = 0; i < count; ++i) {
    char number[32];
    std::snprintf(number, sizeof number, "%g", double(values[i]));
    text += (i == 0 ? "" : ", ") + std::string(number);
  }
  return text;
}

// An attribute of type A, an Imath vector, box or matrix of T, as its numbers in a row.
template <class A, class T>
bool join_numbers(const Imf::Attribute& attr, std::string& text) {
  const auto* a = dynamic_cast<const A*>(&attr);
  if (a) text = joined(reinterpret_cast<const T*>(&a->value()), sizeof(a->value()) / sizeof(T));
  return a != nullptr;
}

// An attribute of another type as OpenImageIO's get_string wrote it ("1, 2.5, 3"); empty for types
// without numbers (timecode, keycode, preview, ...).
std::string text_of(const Imf::Attribute& attr) {
  std::string text;
  using namespace Imf;
  (void)(join_numbers<V2iAttribute, int>(attr, text) ||
         join_numbers<V2fAttribute, float>(attr, text) ||
         join_numbers<V2dAttribute, double>(attr, text) ||
         join_numbers<V3iAttribute, int>(attr, text) ||
         join_numbers<V3fAttribute, float>(attr, text) ||
         join_numbers<V3dAttribute, double>(attr, text) ||
         join_numbers<Box2iAttribute, int>(attr, text) ||
         join_numbers<Box2fAttribute, float>(attr, text) ||
         join_numbers<M33fAttribute, float>(attr, text) ||
         join_numbers<M33dAttribute, double>(attr, text) ||
         join_numbers<M44fAttribute, float>(attr, text) ||
         join_numbers<M44dAttribute, double>(attr, text));
  if (auto* a = dynamic_cast<const FloatVectorAttribute*>(&attr)) {
    text = joined(a->value().data(), a->value().size());
  } else if (auto* a = dynamic_cast<const RationalAttribute*>(&attr)) {
    text = std::to_string(a->value().n) + "/" + std::to_string(a->value().d);
  }
  return text;
}

// "zip", "dwaa:45", ... into the header; false for a name OpenImageIO did not know.
bool set_compression(std::string_view text, Imf::Header& header) {
  const std::size_t colon = text.find(':');
  const std::string_view name = text.substr(0, colon);
  const auto found = std::find(kCompressions.begin(), kCompressions.end(), name);
  if (found == kCompressions.end()) return false;
  const auto compression = Imf::Compression(found - kCompressions.begin());
  header.compression() = compression;
  if (colon == std::string_view::npos) return true;
  const std::string_view level = text.substr(colon + 1);
  int value = 0;
  const auto [end, ec] = std::from_chars(level.data(), level.data() + level.size(), value);
  if (ec != std::errc() || end != level.data() + level.size()) return false;
  if (compression == Imf::ZIP_COMPRESSION || compression == Imf::ZIPS_COMPRESSION) {
    header.zipCompressionLevel() = value;
  } else if (compression == Imf::DWAA_COMPRESSION || compression == Imf::DWAB_COMPRESSION) {
    header.dwaCompressionLevel() = float(value);
  }
  return true;
}

}  // namespace

std::vector<ExrChannel> exr_channels_in_oiio_order(const Imf::ChannelList& list) {
  std::vector<OrderedChannel> channels;
  for (auto c = list.begin(); c != list.end(); ++c) {
    const std::string name = c.name();
    const std::size_t dot = name.find_last_of('.');
    channels.push_back({name, dot == std::string::npos ? 0 : dot + 1, 0, c.channel().type});
  }
  // OpenEXR sorts by whole name, which can split a layer ("a.x", "a.y.R", "a.z").
  std::stable_sort(
      channels.begin(), channels.end(),
      [](const OrderedChannel& a, const OrderedChannel& b) { return a.layer() < b.layer(); });
  for (std::size_t begin = 0; begin < channels.size();) {
    std::size_t end = begin + 1;
    while (end < channels.size() && channels[end].layer() == channels[begin].layer()) ++end;
    auto has = [&](const char* suffix) {
      return std::any_of(
          channels.begin() + begin, channels.begin() + end,
          [&](const OrderedChannel& c) { return equals_ignoring_case(c.suffix(), suffix); });
    };
    const bool xyz = has("X") && (has("Y") || has("Z"));
    for (std::size_t i = begin; i < end; ++i) {
      channels[i].rank = index_in(
          channels[i].suffix(),
          xyz ? "R Red G Green B Blue X Y Z real imag A Alpha AR RA AG GA AB BA Depth Zback"
              : "R Red G Green B Blue Y real imag A Alpha AR RA AG GA AB BA Z Depth Zback");
    }
    begin = end;
  }
  std::sort(channels.begin(), channels.end(), [](const OrderedChannel& a, const OrderedChannel& b) {
    if (a.layer() != b.layer()) return a.layer() < b.layer();
    if (a.rank != b.rank) return a.rank < b.rank;
    return a.suffix() < b.suffix();
  });
  std::vector<ExrChannel> out;
  out.reserve(channels.size());
  for (OrderedChannel& c : channels) out.push_back({std::move(c.name), c.type});
  return out;
}

std::vector<Attribute> exr_attributes(const Imf::Header& header) {
  std::vector<Attribute> out;
  for (auto it = header.begin(); it != header.end(); ++it) {
    const std::string name = it.name();
    const Imf::Attribute& attr = it.attribute();
    if (structural(name)) continue;
    if (auto* a = dynamic_cast<const Imf::CompressionAttribute*>(&attr)) {
      if (std::size_t(a->value()) < kCompressions.size()) {
        out.push_back({name, std::string(kCompressions[a->value()]), "string"});
      }
    } else if (auto* s = dynamic_cast<const Imf::StringAttribute*>(&attr)) {
      out.push_back({name, s->value(), "string"});
    } else if (auto* i = dynamic_cast<const Imf::IntAttribute*>(&attr)) {
      out.push_back({name, (long long)i->value(), "int"});
    } else if (auto* f = dynamic_cast<const Imf::FloatAttribute*>(&attr)) {
      out.push_back({name, double(f->value()), "float"});
    } else if (auto* d = dynamic_cast<const Imf::DoubleAttribute*>(&attr)) {
      out.push_back({name, d->value(), "double"});
    } else {
      out.push_back({name, text_of(attr), attr.typeName()});
    }
  }
  return out;
}

std::string set_exr_attributes(const Spec& spec, Imf::Header& header) {
  std::string compression = "zip";  // OpenImageIO's default.
  for (const Attribute& a : spec.attributes) {
    if (a.name == "compression") {
      if (const std::string* text = a.text()) compression = *text;
      continue;
    }
    if (const std::string* text = a.text()) {
      header.insert(a.name, Imf::StringAttribute(*text));
    } else if (const long long* i = std::get_if<long long>(&a.value)) {
      if (*i < INT_MIN || *i > INT_MAX) {
        return "attribute '" + a.name + "': " + std::to_string(*i) + " is beyond a 32-bit int";
      }
      header.insert(a.name, Imf::IntAttribute(int(*i)));
    } else if (a.type_name == "float") {
      header.insert(a.name, Imf::FloatAttribute(float(std::get<double>(a.value))));
    } else {
      header.insert(a.name, Imf::DoubleAttribute(std::get<double>(a.value)));
    }
  }
  if (!set_compression(compression, header)) {
    return "unknown EXR compression '" + compression +
           "' (none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab)";
  }
  return {};
}

}  // namespace ls::image_file
