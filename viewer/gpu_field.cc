// The field and PCA sources of viewer/gpu_relight.h: upload_field, upload_pca.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <sstream>
#include <utility>

#include "lightstage/errors.h"
#include "relight/lighting/half_relight.h"
#include "viewer/cpu_sources.h"
#include "viewer/gl_util.h"
#include "viewer/gpu_relight.h"
#include "viewer/view_lighting.h"

namespace ls::viewer {

using namespace gl_util;

namespace {

// ---------------------------------------------------------------------------------------------
// Field: R(x, l) in a buffer texture in the field's own pixel-major order (each pixel's 3L values
// padded to whole groups of 4 LEDs = 3 RGBA texels), so one pixel's samples are contiguous and a
// fetch brings 4 values; the lighting as one RGBA weight per texel of a group plus the list of
// groups with any light, in a uniform buffer. (A texture array with one RGB layer per LED instead
// runs 1.5x slower on llvmpipe: 150 fetches per pixel, 1 MB apart.)

constexpr int kMaxFieldGroups = 256;  // 1024 LEDs: 768 + 64 vec4 = 13 KiB of uniform buffer, under
                                      // the 16 KiB every GL 3.3 implementation allows.

constexpr const char* kFieldShader = R"(#version 330 core
uniform samplerBuffer field_values;  // Pixel p (row-major from the top row), group g, part k:
                                     // texel (p * groups + g) * 3 + k; values 12 g + 4 k + 0..3.
layout(std140) uniform FieldLighting {
  vec4 weights[768];                 // 3 per active group: the weight of each value it holds.
  ivec4 active_groups[64];           // Group of active group i: active_groups[i / 4][i % 4].
};
uniform int active_count;
uniform int groups;                  // Per pixel.
uniform int image_width;
uniform int image_height;
uniform float output_scale;          // Undoes the storage scale.
uniform sampler2D sources_image;     // The compact sources' light, image row 0 at
uniform int with_sources;            // texture row 0; added when with_sources != 0.
out vec4 radiance;
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  int base = ((image_height - 1 - p.y) * image_width + p.x) * groups;
  // Value 12 g + j is channel j % 3: a0 holds channels (0 1 2 0), a1 (1 2 0 1), a2 (2 0 1 2).
  vec4 a0 = vec4(0.0), a1 = vec4(0.0), a2 = vec4(0.0);
  for (int i = 0; i < active_count; ++i) {
    int texel = (base + active_groups[i >> 2][i & 3]) * 3;
    a0 += texelFetch(field_values, texel) * weights[3 * i];
    a1 += texelFetch(field_values, texel + 1) * weights[3 * i + 1];
    a2 += texelFetch(field_values, texel + 2) * weights[3 * i + 2];
  }
  vec3 sum = vec3(a0.x + a0.w + a1.z + a2.y, a0.y + a1.x + a1.w + a2.z,
                  a0.z + a1.y + a2.x + a2.w);
  vec3 sources = with_sources != 0
      ? texelFetch(sources_image, ivec2(p.x, image_height - 1 - p.y), 0).rgb : vec3(0.0);
  radiance = vec4(sum * output_scale + sources, 1.0);
}
)";

class FieldSource : public GpuSource {
 public:
  FieldSource(const capture::ReflectanceField& field, bool half, float scale,
              const std::string& why)
      : width_(field.width()),
        height_(field.height()),
        lights_(field.num_lights()),
        groups_((field.num_lights() + 3) / 4),
        half_(half),
        scale_(scale),
        program_(kFieldShader, "field"),
        sources_(field) {
    valid_.reserve(lights_);
    for (const capture::FieldLight& light : field.lights()) valid_.push_back(light.valid);
    glGenBuffers(1, &values_buffer_);
    glBindBuffer(GL_TEXTURE_BUFFER, values_buffer_);
    glBufferData(GL_TEXTURE_BUFFER, GLsizeiptr(bytes()), nullptr, GL_STATIC_DRAW);
    check_gl("allocating the field buffer (" + mb(bytes()) + ")");
    if (half) {
      upload<Eigen::half>(field, [scale](float v) { return Eigen::half(v * scale); });
    } else {
      upload<float>(field, [](float v) { return v; });
    }
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
    check_gl("uploading the field");
    glBindTexture(GL_TEXTURE_BUFFER, values_.id());
    glTexBuffer(GL_TEXTURE_BUFFER, half ? GL_RGBA16F : GL_RGBA32F, values_buffer_);
    check_gl("making the field a buffer texture");
    glGenBuffers(1, &lighting_);
    glBindBuffer(GL_UNIFORM_BUFFER, lighting_);
    glBufferData(GL_UNIFORM_BUFFER, kLightingBytes, nullptr, GL_DYNAMIC_DRAW);
    glBindBuffer(GL_UNIFORM_BUFFER, 0);
    program_.use();
    program_.bind_block("FieldLighting", 0);
    check_gl("allocating the field lighting");
    glBindTexture(GL_TEXTURE_2D, sources_texture_.id());
    set_nearest(GL_TEXTURE_2D);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, 1, 1, 0, GL_RGB, GL_FLOAT, nullptr);
    check_gl("allocating the bright sources' image");
    note_ = "field: " + std::to_string(lights_) + " LEDs, " + mb(bytes()) + " of " +
            (half ? "half" : "float") + " in a buffer texture" +
            (why.empty() ? "" : " (" + why + ")") +
            "; bright sources (a sun) computed on the CPU and added";
  }
  ~FieldSource() override {
    glDeleteBuffers(1, &lighting_);
    glDeleteBuffers(1, &values_buffer_);
  }
  FieldSource(const FieldSource&) = delete;
  FieldSource& operator=(const FieldSource&) = delete;

  // Texels (RGBA) the field takes, and whether this GPU's buffer textures and uniform buffers hold
  // it.
  static std::size_t texels(const capture::ReflectanceField& field) {
    return std::size_t(field.width()) * field.height() * ((field.num_lights() + 3) / 4) * 3;
  }
  static std::string unsupported(const capture::ReflectanceField& field) {
    GLint max_texels = 0;
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_texels);
    if (field.num_lights() > 4 * kMaxFieldGroups) {
      return "field has " + std::to_string(field.num_lights()) + " LEDs, over the " +
             std::to_string(4 * kMaxFieldGroups) + " the GPU field shader takes";
    }
    if (texels(field) > std::size_t(max_texels)) {
      return "field needs " + std::to_string(texels(field)) + " texels, over this GPU's " +
             std::to_string(max_texels) + " per buffer texture";
    }
    return "";
  }

  std::string name() const override { return "field"; }
  bool adds_bright_sources() const override { return true; }
  std::string shadows() const override { return sources_.shadows(); }
  std::string note() const override { return note_; }
  int width() const override { return width_; }
  int height() const override { return height_; }
  std::size_t bytes() const override {
    return std::size_t(width_) * height_ * groups_ * 12 * (half_ ? 2 : 4);
  }

  void render(const ViewLighting& lighting, GpuTarget& target) override {
    check_target(*this, target);
    check_led_weights(*this, lighting.field_irradiance_rgb(), lights_);
    // Only groups of LEDs that carry light (and data) are fetched: a point light lights a few.
    const std::vector<float>& irradiance = lighting.field_irradiance_rgb();
    std::fill(block_.begin(), block_.end(), 0.0f);
    int active = 0;
    for (int g = 0; g < groups_; ++g) {
      float* w = &block_[std::size_t(active) * 12];
      bool any = false;
      for (int j = 0; j < 12; ++j) {
        const int l = 4 * g + j / 3;
        const float e = l < lights_ && valid_[l] ? irradiance[l * 3 + j % 3] : 0;
        w[j] = e;
        any = any || e != 0;
      }
      if (!any) continue;
      const int32_t group = g;  // The block's int part, stored in the float array's bytes.
      std::memcpy(&block_[kWeightFloats + active], &group, sizeof(group));
      ++active;
    }
    glBindBuffer(GL_UNIFORM_BUFFER, lighting_);
    glBufferSubData(GL_UNIFORM_BUFFER, 0, kLightingBytes, block_.data());
    glBindBuffer(GL_UNIFORM_BUFFER, 0);
    glBindBufferBase(GL_UNIFORM_BUFFER, 0, lighting_);
    const bool with_sources = upload_sources(lighting);
    TargetPass pass(target);
    program_.use();
    bind_texture(program_, "field_values", 0, GL_TEXTURE_BUFFER, values_.id());
    glUniform1i(program_.uniform("active_count"), active);
    glUniform1i(program_.uniform("groups"), groups_);
    glUniform1i(program_.uniform("image_width"), width_);
    glUniform1i(program_.uniform("image_height"), height_);
    glUniform1f(program_.uniform("output_scale"), 1.0f / scale_);
    bind_texture(program_, "sources_image", 1, GL_TEXTURE_2D, sources_texture_.id());
    glUniform1i(program_.uniform("with_sources"), with_sources ? 1 : 0);
    program_.draw();
    check_gl("relighting the field");
  }

 private:
  // The uniform block: 768 vec4 weights, then 64 ivec4 group indices (std140: tightly packed).
  static constexpr int kWeightFloats = 3 * kMaxFieldGroups * 4;
  static constexpr GLsizeiptr kLightingBytes = (kWeightFloats + kMaxFieldGroups) * 4;

  // Pixel-major like the field, each pixel padded to whole groups; in slices of rows.
  template <class Stored, class Convert>
  void upload(const capture::ReflectanceField& field, Convert convert) {
    const std::size_t per_pixel = std::size_t(groups_) * 12, count = std::size_t(lights_) * 3;
    const int rows_per_slice = std::max(1, int((std::size_t(16) << 20) / (per_pixel * width_ * 4)));
    std::vector<Stored> staging;
    for (int y0 = 0; y0 < height_; y0 += rows_per_slice) {
      const int rows = std::min(rows_per_slice, height_ - y0);
      staging.assign(std::size_t(rows) * width_ * per_pixel, Stored(0.0f));
      tbb::parallel_for(tbb::blocked_range<int>(0, rows), [&](const tbb::blocked_range<int>& rs) {
        for (int r = rs.begin(); r < rs.end(); ++r) {
          for (int x = 0; x < width_; ++x) {
            const float* in = field.pixel(x, y0 + r);
            Stored* out = &staging[(std::size_t(r) * width_ + x) * per_pixel];
            for (std::size_t i = 0; i < count; ++i) out[i] = convert(in[i]);
          }
        }
      });
      glBufferSubData(GL_TEXTURE_BUFFER,
                      GLintptr(std::size_t(y0) * width_ * per_pixel * sizeof(Stored)),
                      GLsizeiptr(staging.size() * sizeof(Stored)), staging.data());
    }
  }

  // The compact sources' light computed on the CPU into the sources texture; false
  // when the lighting has none.
  bool upload_sources(const ViewLighting& lighting) {
    if (!sources_.render(lighting, sources_image_)) return false;
    glBindTexture(GL_TEXTURE_2D, sources_texture_.id());
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    if (!sources_allocated_) {
      glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, width_, height_, 0, GL_RGB, GL_FLOAT,
                   sources_image_.pixels.data());
      sources_allocated_ = true;
    } else {
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width_, height_, GL_RGB, GL_FLOAT,
                      sources_image_.pixels.data());
    }
    glBindTexture(GL_TEXTURE_2D, 0);
    check_gl("uploading the bright sources' image");
    return true;
  }

  int width_, height_, lights_, groups_;
  bool half_;
  float scale_;  // Stored values are R * scale_ (a power of two: exact).
  std::vector<bool> valid_;
  Program program_;
  GLuint values_buffer_ = 0, lighting_ = 0;
  Texture values_;
  BrightSourceLight sources_;
  Image sources_image_;
  Texture sources_texture_;  // 1 x 1 until a lighting has bright sources.
  bool sources_allocated_ = false;
  std::vector<float> block_ = std::vector<float>(kLightingBytes / 4);
  std::string note_;
};

// ---------------------------------------------------------------------------------------------
// PCA: coefficients C(x, j, c) in a k-layer float texture array, the lighting projected on each
// tile's basis (k x 3 per tile, CPU) in a k x tiles texture.

constexpr const char* kPcaShader = R"(#version 330 core
uniform sampler2DArray coefficients;  // Layer j: C(x, j) RGB.
uniform sampler2D basis_weights;      // Texel (j, tile): the lighting on basis function j.
uniform int rank;
uniform int tile_size;                // 0: one global basis.
uniform int tiles_across;
uniform int image_height;
out vec4 radiance;
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  ivec2 texel = ivec2(p.x, image_height - 1 - p.y);
  int tile = tile_size > 0 ? (texel.y / tile_size) * tiles_across + texel.x / tile_size : 0;
  vec3 sum = vec3(0.0);
  for (int j = 0; j < rank; ++j) {
    sum += texelFetch(coefficients, ivec3(texel, j), 0).rgb *
           texelFetch(basis_weights, ivec2(j, tile), 0).rgb;
  }
  radiance = vec4(sum, 1.0);
}
)";

class PcaSource : public GpuSource {
 public:
  PcaSource(relight::PcaField pca, const std::string& why)
      : pca_(std::move(pca)), program_(kPcaShader, "PCA") {
    const int k = pca_.rank(), tiles = int(pca_.num_tiles());
    check_size(pca_.width(), pca_.height(), std::max(k, 1), "the PCA coefficient texture");
    check_size(std::max(k, 1), tiles, 1, "the PCA basis weights");
    glBindTexture(GL_TEXTURE_2D_ARRAY, coefficients_.id());
    set_nearest(GL_TEXTURE_2D_ARRAY);
    glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGB32F, pca_.width(), pca_.height(), std::max(k, 1), 0,
                 GL_RGB, GL_FLOAT, nullptr);
    check_gl("allocating the PCA coefficients (" + mb(bytes()) + ")");
    if (k > 0) {
      upload_layers<float>(pca_.coefficients().data(), pca_.width(), pca_.height(), k,
                           std::size_t(k) * 3, GL_FLOAT, [](float v) { return v; });
    }
    check_gl("uploading the PCA coefficients");
    glBindTexture(GL_TEXTURE_2D, basis_weights_.id());
    set_nearest(GL_TEXTURE_2D);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, std::max(k, 1), tiles, 0, GL_RGB, GL_FLOAT, nullptr);
    check_gl("allocating the PCA basis weights");
    note_ =
        name() + ": " + mb(bytes()) + " of float coefficients in a texture array, " +
        (tiles > 1 ? std::to_string(tiles) + " tiles of " + std::to_string(pca_.tile_size()) + " px"
                   : std::string("one global basis"));
    if (!why.empty()) note_ = why + ": showing " + note_;
  }

  std::string name() const override { return "pca k=" + std::to_string(pca_.rank()); }
  std::string note() const override { return note_; }
  int width() const override { return pca_.width(); }
  int height() const override { return pca_.height(); }
  std::size_t bytes() const override {
    return std::size_t(pca_.width()) * pca_.height() * pca_.rank() * 3 * 4 +
           pca_.num_tiles() * pca_.rank() * 3 * 4;
  }

  void render(const ViewLighting& lighting, GpuTarget& target) override {
    check_target(*this, target);
    check_led_weights(*this, lighting.led_irradiance_rgb, pca_.num_lights());
    const int k = pca_.rank();
    const std::vector<float> w = pca_.project_led_weights(lighting.led_irradiance_rgb.data());
    glBindTexture(GL_TEXTURE_2D, basis_weights_.id());
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    if (k > 0) {
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, k, int(pca_.num_tiles()), GL_RGB, GL_FLOAT, w.data());
    }
    TargetPass pass(target);
    program_.use();
    bind_texture(program_, "coefficients", 0, GL_TEXTURE_2D_ARRAY, coefficients_.id());
    bind_texture(program_, "basis_weights", 1, GL_TEXTURE_2D, basis_weights_.id());
    glUniform1i(program_.uniform("rank"), k);
    glUniform1i(program_.uniform("tile_size"), pca_.tile_size());
    glUniform1i(program_.uniform("tiles_across"), pca_.tiles_across());
    glUniform1i(program_.uniform("image_height"), pca_.height());
    program_.draw();
    check_gl("relighting the PCA field");
  }

 private:
  relight::PcaField pca_;  // A copy: the bases project each frame's lighting.
  Program program_;
  Texture coefficients_, basis_weights_;
  std::string note_;
};

}  // namespace

std::unique_ptr<GpuSource> upload_field(const capture::ReflectanceField& field,
                                        std::size_t budget_bytes, FieldPrecision precision) {
  const std::size_t values = FieldSource::texels(field) * 4;  // Padded to whole LED groups.
  // Scale by a power of two so the largest |value| is 2^14: well inside half's range (65504), and
  // exact.
  const float scale = relight::half_scale(field);
  std::string why;
  bool half = precision == FieldPrecision::kHalf;
  if (precision == FieldPrecision::kAuto) {
    const double error = relight::half_relit_error(field, scale);
    half = error <= 1e-3;
    std::ostringstream out;
    out.precision(1);
    out << std::scientific << "half float's relit error " << error
        << (half ? " <= 1e-3" : " > 1e-3: float");
    // A software renderer converts half to float on every fetch: float is as fast or faster there
    // (bench_viewer, llvmpipe, 512^2 x 150: 126 against 171 ms a frame on a quiet machine, 268
    // against 262 ms under load) and exact, so it is used when it fits.
    if (half && software_renderer() && values * 4 <= budget_bytes) {
      half = false;
      out << ", but float is faster on a software renderer";
    }
    why = out.str();
  }
  const std::string unsupported = FieldSource::unsupported(field);
  if (unsupported.empty() && values * (half ? 2 : 4) <= budget_bytes) {
    return std::make_unique<FieldSource>(field, half, half ? scale : 1.0f, why);
  }
  if (unsupported.empty() && !half && precision == FieldPrecision::kAuto &&
      values * 2 <= budget_bytes) {
    // Over budget in float but fits in half.
    return std::make_unique<FieldSource>(field, true, scale, why + "; float would be over budget");
  }
  // PCA at the noise-floor rank, at most 64 and at most what the budget holds in float.
  const std::size_t bytes_per_rank = std::size_t(field.width()) * field.height() * 3 * 4;
  const std::size_t rank_budget = budget_bytes / std::max<std::size_t>(bytes_per_rank, 1);
  if (rank_budget < 1) {
    throw HardwareError("GPU relight: the field needs " + mb(values * 2) +
                        " even in half float and " + "PCA k=1 " + mb(bytes_per_rank) +
                        ", over the " + mb(budget_bytes) + " GPU budget");
  }
  relight::PcaOptions options;
  options.max_rank = int(std::min<std::size_t>(64, rank_budget));
  relight::PcaField pca = relight::PcaField::build(field, options);
  const std::string reason = !unsupported.empty()
                                 ? unsupported
                                 : "field needs " + mb(values * (half ? 2 : 4)) + ", over the " +
                                       mb(budget_bytes) + " budget";
  return std::make_unique<PcaSource>(std::move(pca), reason);
}

std::unique_ptr<GpuSource> upload_pca(const relight::PcaField& pca) {
  return std::make_unique<PcaSource>(pca, "");
}

}  // namespace ls::viewer
