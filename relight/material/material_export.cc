#include "relight/material/material_export.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>

#include "lightstage/errors.h"

namespace ls::relight {
namespace fs = std::filesystem;
namespace {

// The material's values as a texture: `channels` values per pixel in [0, 1] as stored (base colour
// already sRGB-encoded).
struct TextureValues {
  std::string file;
  int channels = 1;
  std::vector<float> encoded;
};

// What an 8-bit code does to one pixel's material, relative (the rule in material_export.h): the
// change of the value it stores, weighed by how much the BRDF moves with it.
using EightBitImpact =
    std::function<double(size_t pixel, const float* encoded, const float* eight)>;

float eight_bit(float v) { return std::round(std::clamp(v, 0.0f, 1.0f) * 255.0f) / 255.0f; }

int bits_needed(const GgxConversion& m, const TextureValues& t, const EightBitImpact& impact) {
  size_t counted = 0, over = 0;
  std::vector<float> eight(size_t(t.channels));
  for (size_t i = 0; i < m.error.num_pixels(); ++i) {
    if (!m.converted[i]) continue;
    const float* v = &t.encoded[i * t.channels];
    for (int c = 0; c < t.channels; ++c) eight[c] = eight_bit(v[c]);
    ++counted;
    if (impact(i, v, eight.data()) > 0.25 * std::max(double(m.error.pixels[i]), 0.005)) ++over;
  }
  return double(over) > 0.01 * double(counted) ? 16 : 8;
}

WrittenTexture write_texture(const fs::path& dir, const GgxConversion& m, const TextureValues& t,
                             const EightBitImpact& impact) {
  const int bits = bits_needed(m, t, impact);
  const float scale = bits == 16 ? 65535.0f : 255.0f;
  std::vector<uint16_t> codes(t.encoded.size());
  for (size_t i = 0; i < codes.size(); ++i) {
    codes[i] = uint16_t(std::lround(std::clamp(t.encoded[i], 0.0f, 1.0f) * scale));
  }
  write_png_codes(dir / t.file, m.width, m.height, t.channels, bits, codes.data());
  return {t.file, bits};
}

TextureValues base_color_values(const GgxConversion& m) {
  TextureValues t{"base_color.png", 3, std::vector<float>(m.base_color.pixels.size())};
  for (size_t i = 0; i < t.encoded.size(); ++i) t.encoded[i] = srgb_encode(m.base_color.pixels[i]);
  return t;
}
double base_color_impact(const GgxConversion& m, size_t i, const float* v, const float* eight) {
  double worst = 0;
  for (int c = 0; c < 3; ++c) {
    const double linear = m.base_color.pixels[i * 3 + c];
    worst = std::max(worst,
                     std::abs(srgb_decode(eight[c]) - srgb_decode(v[c])) / std::max(linear, 0.01));
  }
  return worst;
}

TextureValues normal_values(const Image& normals) {
  TextureValues t{"normal.png", 3, std::vector<float>(normals.pixels.size())};
  for (size_t i = 0; i < t.encoded.size(); ++i) t.encoded[i] = 0.5f + 0.5f * normals.pixels[i];
  return t;
}
// A normal tilted by d radians moves a diffuse response by about d, a lobe of width a by 2d / a.
double normal_impact(const GgxConversion& m, size_t i, const float* v, const float* eight) {
  const Eigen::Vector3d n(2.0 * v[0] - 1, 2.0 * v[1] - 1, 2.0 * v[2] - 1);
  const Eigen::Vector3d q(2.0 * eight[0] - 1, 2.0 * eight[1] - 1, 2.0 * eight[2] - 1);
  const double tilt = std::acos(std::clamp(n.normalized().dot(q.normalized()), -1.0, 1.0));
  const double a = std::pow(double(m.roughness.pixels[i]), 2);
  return m.strength.pixels[i] > 0 ? tilt * std::max(1.0, 2.0 / a) : tilt;
}

// glTF's metallicRoughness: roughness in G, metallic (0) in B.
TextureValues roughness_values(const GgxConversion& m, int channels, int channel) {
  TextureValues t{channels == 1 ? "roughness.png" : "metallic_roughness.png", channels,
                  std::vector<float>(m.roughness.pixels.size() * size_t(channels), 0.0f)};
  for (size_t i = 0; i < m.roughness.pixels.size(); ++i) {
    t.encoded[i * channels + channel] = m.roughness.pixels[i];
  }
  return t;
}
// D moves with a = r^2: da / a = 2 dr / r; no lobe, no effect.
EightBitImpact roughness_impact(const GgxConversion& m, int channel) {
  return [&m, channel](size_t i, const float* v, const float* eight) {
    if (!(m.strength.pixels[i] > 0)) return 0.0;
    return 2.0 * std::abs(eight[channel] - v[channel]) / std::max(double(v[channel]), 0.02);
  };
}

// KHR_materials_specular's strength is the texture's alpha; MaterialX's a grey image.
TextureValues strength_values(const GgxConversion& m, int channels) {
  TextureValues t{channels == 1 ? "specular.png" : "specular_strength.png", channels,
                  std::vector<float>(m.strength.pixels.size() * size_t(channels), 1.0f)};
  for (size_t i = 0; i < m.strength.pixels.size(); ++i) {
    t.encoded[i * channels + channels - 1] = m.strength.pixels[i];
  }
  return t;
}
EightBitImpact strength_impact(const GgxConversion& m, int channels) {
  return [&m, channels](size_t i, const float* v, const float* eight) {
    const int c = channels - 1;
    if (!(m.strength.pixels[i] > 0)) return 0.0;
    return std::abs(double(eight[c]) - v[c]) / std::max(double(v[c]), 1e-3);
  };
}

void make_dir(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw StorageError(dir.string() + ": cannot make the folder: " + ec.message());
}

// The four textures, in the order both documents index them: base colour, roughness, normal,
// strength. glTF packs the roughness in G of metallic_roughness and the strength in an alpha
// (KHR_materials_specular's); MaterialX takes grey images.
std::vector<WrittenTexture> write_textures(const fs::path& dir, const GgxConversion& m,
                                           const Image& normals, bool gltf) {
  make_dir(dir);
  const int roughness_channels = gltf ? 3 : 1, roughness_channel = gltf ? 1 : 0;
  const int strength_channels = gltf ? 4 : 1;
  return {write_texture(dir, m, base_color_values(m),
                        [&m](size_t i, const float* v, const float* e) {
                          return base_color_impact(m, i, v, e);
                        }),
          write_texture(dir, m, roughness_values(m, roughness_channels, roughness_channel),
                        roughness_impact(m, roughness_channel)),
          write_texture(
              dir, m, normal_values(normals),
              [&m](size_t i, const float* v, const float* e) { return normal_impact(m, i, v, e); }),
          write_texture(dir, m, strength_values(m, strength_channels),
                        strength_impact(m, strength_channels))};
}

// Appends `bytes` to the glTF buffer, 4-byte aligned; its bufferView index.
int add_view(std::string& buffer, nlohmann::json& views, const void* bytes, size_t size,
             int target) {
  while (buffer.size() % 4 != 0) buffer.push_back('\0');
  views.push_back(
      {{"buffer", 0}, {"byteOffset", buffer.size()}, {"byteLength", size}, {"target", target}});
  buffer.append(static_cast<const char*>(bytes), size);
  return int(views.size()) - 1;
}

constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;
constexpr int kFloat = 5126, kUnsignedInt = 5125;
constexpr int kLinear = 9729, kLinearMipmapLinear = 9987, kRepeat = 10497;

}  // namespace

MaterialExport write_gltf(const GgxConversion& m, const fs::path& dir, const std::string& name,
                          const SurfaceMesh& mesh) {
  MaterialExport out;
  out.textures = write_textures(dir, m, tangent_space_normals(m.normal, mesh), /*gltf=*/true);

  std::string buffer;
  nlohmann::json views = nlohmann::json::array();
  Eigen::Vector3f lo = mesh.positions.front(), hi = lo;
  for (const Eigen::Vector3f& p : mesh.positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const auto view_of = [&](const auto& values, int target) {
    return add_view(buffer, views, values.data(), values.size() * sizeof(values[0]), target);
  };
  const int count = int(mesh.positions.size());
  const nlohmann::json accessors =
      nlohmann::json::array({{{"bufferView", view_of(mesh.positions, kArrayBuffer)},
                              {"componentType", kFloat},
                              {"count", count},
                              {"type", "VEC3"},
                              {"min", {lo.x(), lo.y(), lo.z()}},
                              {"max", {hi.x(), hi.y(), hi.z()}}},
                             {{"bufferView", view_of(mesh.normals, kArrayBuffer)},
                              {"componentType", kFloat},
                              {"count", count},
                              {"type", "VEC3"}},
                             {{"bufferView", view_of(mesh.tangents, kArrayBuffer)},
                              {"componentType", kFloat},
                              {"count", count},
                              {"type", "VEC4"}},
                             {{"bufferView", view_of(mesh.uvs, kArrayBuffer)},
                              {"componentType", kFloat},
                              {"count", count},
                              {"type", "VEC2"}},
                             {{"bufferView", view_of(mesh.indices, kElementArrayBuffer)},
                              {"componentType", kUnsignedInt},
                              {"count", mesh.indices.size()},
                              {"type", "SCALAR"}}});

  nlohmann::json images = nlohmann::json::array(), textures = nlohmann::json::array();
  for (const WrittenTexture& t : out.textures) {
    images.push_back({{"uri", t.file}});
    textures.push_back({{"source", images.size() - 1}, {"sampler", 0}});
  }
  const double specular_color = m.f0 / kGltfDielectricF0;
  nlohmann::json gltf = {
      {"asset", {{"version", "2.0"}, {"generator", "lightstage export gltf"}}},
      {"extensionsUsed", {"KHR_materials_specular"}},
      {"scene", 0},
      {"scenes", {{{"nodes", {0}}}}},
      {"nodes", {{{"mesh", 0}, {"name", name}}}},
      {"meshes",
       {{{"name", name},
         {"primitives",
          {{{"attributes", {{"POSITION", 0}, {"NORMAL", 1}, {"TANGENT", 2}, {"TEXCOORD_0", 3}}},
            {"indices", 4},
            {"material", 0}}}}}}},
      {"materials",
       {{{"name", name},
         {"pbrMetallicRoughness",
          {{"baseColorTexture", {{"index", 0}}},
           {"metallicFactor", 0.0},
           {"roughnessFactor", 1.0},
           {"metallicRoughnessTexture", {{"index", 1}}}}},
         {"normalTexture", {{"index", 2}}},
         {"extensions",
          {{"KHR_materials_specular",
            {{"specularFactor", 1.0},
             {"specularTexture", {{"index", 3}}},
             {"specularColorFactor", {specular_color, specular_color, specular_color}}}}}}}}},
      {"samplers",
       {{{"magFilter", kLinear},
         {"minFilter", kLinearMipmapLinear},
         {"wrapS", kRepeat},
         {"wrapT", kRepeat}}}},
      {"images", images},
      {"textures", textures},
      {"buffers", {{{"uri", name + ".bin"}, {"byteLength", buffer.size()}}}},
      {"bufferViews", views},
      {"accessors", accessors},
  };
  write_file_atomic(dir / (name + ".bin"), buffer);
  out.document = dir / (name + ".gltf");
  write_file_atomic(out.document, gltf.dump(1) + "\n");
  return out;
}

MaterialExport write_materialx(const GgxConversion& m, const fs::path& dir,
                               const std::string& name) {
  MaterialExport out;
  out.textures = write_textures(dir, m, m.normal, /*gltf=*/false);
  // Standard Surface's dielectric F0 comes from its index of refraction.
  const double root = std::sqrt(m.f0);
  const double ior = (1 + root) / (1 - std::min(root, 0.999));
  std::ostringstream x;
  x.precision(6);
  x << "<?xml version=\"1.0\"?>\n"
    << "<!-- Written by lightstage export materialx: the fitted models as Standard Surface (the "
       "conversion in relight/material/ggx_conversion.h). -->\n"
    << "<materialx version=\"1.38\" colorspace=\"lin_rec709\">\n"
    << "  <nodegraph name=\"NG_" << name << "\">\n"
    << "    <image name=\"base_color_image\" type=\"color3\">\n"
    << "      <input name=\"file\" type=\"filename\" value=\"" << out.textures[0].file
    << "\" colorspace=\"srgb_texture\" />\n"
    << "    </image>\n"
    << "    <image name=\"roughness_image\" type=\"float\">\n"
    << "      <input name=\"file\" type=\"filename\" value=\"" << out.textures[1].file << "\" />\n"
    << "    </image>\n"
    << "    <image name=\"normal_image\" type=\"vector3\">\n"
    << "      <input name=\"file\" type=\"filename\" value=\"" << out.textures[2].file << "\" />\n"
    << "    </image>\n"
    << "    <normalmap name=\"normal_map\" type=\"vector3\">\n"
    << "      <input name=\"in\" type=\"vector3\" nodename=\"normal_image\" />\n"
    << "    </normalmap>\n"
    << "    <image name=\"specular_image\" type=\"float\">\n"
    << "      <input name=\"file\" type=\"filename\" value=\"" << out.textures[3].file << "\" />\n"
    << "    </image>\n"
    << "    <output name=\"base_color_out\" type=\"color3\" nodename=\"base_color_image\" />\n"
    << "    <output name=\"roughness_out\" type=\"float\" nodename=\"roughness_image\" />\n"
    << "    <output name=\"normal_out\" type=\"vector3\" nodename=\"normal_map\" />\n"
    << "    <output name=\"specular_out\" type=\"float\" nodename=\"specular_image\" />\n"
    << "  </nodegraph>\n"
    << "  <standard_surface name=\"SR_" << name << "\" type=\"surfaceshader\">\n"
    << "    <input name=\"base\" type=\"float\" value=\"1\" />\n"
    << "    <input name=\"base_color\" type=\"color3\" nodegraph=\"NG_" << name
    << "\" output=\"base_color_out\" />\n"
    << "    <input name=\"metalness\" type=\"float\" value=\"0\" />\n"
    << "    <input name=\"specular\" type=\"float\" nodegraph=\"NG_" << name
    << "\" output=\"specular_out\" />\n"
    << "    <input name=\"specular_color\" type=\"color3\" value=\"1, 1, 1\" />\n"
    << "    <input name=\"specular_roughness\" type=\"float\" nodegraph=\"NG_" << name
    << "\" output=\"roughness_out\" />\n"
    << "    <input name=\"specular_IOR\" type=\"float\" value=\"" << ior << "\" />\n"
    << "    <input name=\"normal\" type=\"vector3\" nodegraph=\"NG_" << name
    << "\" output=\"normal_out\" />\n"
    << "  </standard_surface>\n"
    << "  <surfacematerial name=\"M_" << name << "\" type=\"material\">\n"
    << "    <input name=\"surfaceshader\" type=\"surfaceshader\" nodename=\"SR_" << name
    << "\" />\n"
    << "  </surfacematerial>\n"
    << "</materialx>\n";
  out.document = dir / (name + ".mtlx");
  write_file_atomic(out.document, x.str());
  return out;
}

}  // namespace ls::relight
