#include "viewer/gpu_relight.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <sstream>
#include <utility>

#include "lightstage/errors.h"
#include "relight/brdf.h"
#include "relight/envmap.h"
#include "viewer/gl_window.h"

namespace ls::viewer {
namespace {

// ---------------------------------------------------------------------------------------------
// GL helpers.

const char* gl_error_name(GLenum error) {
  switch (error) {
    case GL_INVALID_ENUM:
      return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE:
      return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION:
      return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION:
      return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY:
      return "GL_OUT_OF_MEMORY";
    default:
      return "unknown GL error";
  }
}

// Throws HardwareError when GL reported an error since the last check (out of memory above all).
void check_gl(const std::string& what) {
  const GLenum error = glGetError();
  if (error == GL_NO_ERROR) return;
  while (glGetError() != GL_NO_ERROR) {
  }
  throw HardwareError("OpenGL: " + what + " failed: " + gl_error_name(error));
}

// "472 MB", "1.5 MB", "36.9 kB".
std::string mb(std::size_t bytes) {
  std::ostringstream out;
  out << std::fixed;
  if (bytes < 1000000) {
    out.precision(1);
    out << double(bytes) / 1e3 << " kB";
  } else {
    out.precision(bytes >= 10000000 ? 0 : 1);
    out << double(bytes) / 1e6 << " MB";
  }
  return out.str();
}

GLuint compile(GLenum type, const char* source, const std::string& name) {
  const GLuint shader = glCreateShader(type);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[4096] = {};
    glGetShaderInfoLog(shader, sizeof(log), nullptr, log);
    glDeleteShader(shader);
    throw HardwareError("OpenGL: compiling the " + name + " shader failed: " + log);
  }
  return shader;
}

// A full-screen triangle from gl_VertexID: no vertex buffer needed (core profile still wants a
// VAO bound).
constexpr const char* kFullScreenVertexShader = R"(#version 330 core
void main() {
  const vec2 corners[3] = vec2[3](vec2(-1.0, -1.0), vec2(3.0, -1.0), vec2(-1.0, 3.0));
  gl_Position = vec4(corners[gl_VertexID], 0.0, 1.0);
}
)";

// A linked program with the full-screen vertex shader and an empty VAO.
class Program {
 public:
  Program(const char* fragment_source, const std::string& name) {
    const GLuint vs = compile(GL_VERTEX_SHADER, kFullScreenVertexShader, name + " vertex");
    GLuint fs = 0;
    try {
      fs = compile(GL_FRAGMENT_SHADER, fragment_source, name + " fragment");
    } catch (...) {
      glDeleteShader(vs);
      throw;
    }
    program_ = glCreateProgram();
    glAttachShader(program_, vs);
    glAttachShader(program_, fs);
    glLinkProgram(program_);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = GL_FALSE;
    glGetProgramiv(program_, GL_LINK_STATUS, &ok);
    if (!ok) {
      char log[4096] = {};
      glGetProgramInfoLog(program_, sizeof(log), nullptr, log);
      glDeleteProgram(program_);
      throw HardwareError("OpenGL: linking the " + name + " shader failed: " + log);
    }
    glGenVertexArrays(1, &vao_);
  }
  ~Program() {
    glDeleteVertexArrays(1, &vao_);
    glDeleteProgram(program_);
  }
  Program(const Program&) = delete;
  Program& operator=(const Program&) = delete;

  void use() const {
    glUseProgram(program_);
    glBindVertexArray(vao_);
  }
  GLint uniform(const char* name) const { return glGetUniformLocation(program_, name); }
  // Points the named uniform block at binding point `binding`.
  void bind_block(const char* name, GLuint binding) const {
    glUniformBlockBinding(program_, glGetUniformBlockIndex(program_, name), binding);
  }
  void draw() const { glDrawArrays(GL_TRIANGLES, 0, 3); }

 private:
  GLuint program_ = 0, vao_ = 0;
};

// Binds `texture` to unit `unit` and the sampler uniform to it.
void bind_texture(const Program& program, const char* sampler, int unit, GLenum target,
                  GLuint texture) {
  glActiveTexture(GL_TEXTURE0 + unit);
  glBindTexture(target, texture);
  glUniform1i(program.uniform(sampler), unit);
}

void set_nearest(GLenum target) {
  glTexParameteri(target, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(target, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTexParameteri(target, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(target, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
}

// An owned texture name.
class Texture {
 public:
  Texture() { glGenTextures(1, &id_); }
  ~Texture() { glDeleteTextures(1, &id_); }
  Texture(const Texture&) = delete;
  Texture& operator=(const Texture&) = delete;
  GLuint id() const { return id_; }

 private:
  GLuint id_ = 0;
};

// Renders into the target with the GL state a full-screen pass needs, restoring the caller's
// framebuffer, viewport and the capabilities it turns off (ImGui leaves scissor on, e.g.).
class TargetPass {
 public:
  explicit TargetPass(const GpuTarget& target) {
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &framebuffer_);
    glGetIntegerv(GL_VIEWPORT, viewport_);
    for (int i = 0; i < kCaps; ++i) enabled_[i] = glIsEnabled(kCapList[i]);
    for (GLenum cap : kCapList) glDisable(cap);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, target.framebuffer());
    glViewport(0, 0, target.width(), target.height());
  }
  ~TargetPass() {
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(framebuffer_));
    glViewport(viewport_[0], viewport_[1], viewport_[2], viewport_[3]);
    for (int i = 0; i < kCaps; ++i) {
      if (enabled_[i]) glEnable(kCapList[i]);
    }
  }
  TargetPass(const TargetPass&) = delete;
  TargetPass& operator=(const TargetPass&) = delete;

 private:
  static constexpr int kCaps = 4;
  static constexpr GLenum kCapList[kCaps] = {GL_SCISSOR_TEST, GL_BLEND, GL_DEPTH_TEST,
                                             GL_CULL_FACE};
  GLint framebuffer_ = 0;
  GLint viewport_[4] = {};
  GLboolean enabled_[kCaps] = {};
};

void check_target(const GpuSource& source, const GpuTarget& target) {
  if (target.width() != source.width() || target.height() != source.height()) {
    throw InputError("GPU relight: target: expected " + std::to_string(source.width()) + "x" +
                     std::to_string(source.height()) + " (the " + source.name() + "'s size), got " +
                     std::to_string(target.width()) + "x" + std::to_string(target.height()));
  }
}

int max_texture_size() {
  GLint size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &size);
  return size;
}

int max_array_layers() {
  GLint layers = 0;
  glGetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &layers);
  return layers;
}

// Uploads per-pixel data stored pixel-major (`stride` floats per pixel, `layers` RGB triples at
// its start) into a W x H x layers RGB texture array, one layer per triple, image row 0 at texture
// row 0. `convert` turns each float into the stored type. Works through blocks of rows so the
// field is read once, sequentially, with a bounded staging buffer.
template <class Stored, class Convert>
void upload_layers(const float* values, int width, int height, int layers, std::size_t stride,
                   GLenum type, Convert convert) {
  const std::size_t row_texels = std::size_t(width) * layers;
  const int rows_per_block =
      std::max(1, int((std::size_t(16) << 20) / std::max<std::size_t>(1, row_texels * 3 * 4)));
  std::vector<Stored> staging;
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  for (int y0 = 0; y0 < height; y0 += rows_per_block) {
    const int rows = std::min(rows_per_block, height - y0);
    staging.resize(std::size_t(rows) * row_texels * 3);
    // staging[((layer * rows + r) * width + x) * 3 + c]: layers outermost, as glTexSubImage3D
    // reads a box.
    tbb::parallel_for(tbb::blocked_range<int>(0, rows), [&](const tbb::blocked_range<int>& rs) {
      for (int r = rs.begin(); r < rs.end(); ++r) {
        for (int x = 0; x < width; ++x) {
          const float* pixel = values + (std::size_t(y0 + r) * width + x) * stride;
          for (int l = 0; l < layers; ++l) {
            Stored* out = &staging[((std::size_t(l) * rows + r) * width + x) * 3];
            for (int c = 0; c < 3; ++c) out[c] = convert(pixel[l * 3 + c]);
          }
        }
      }
    });
    glTexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, y0, 0, width, rows, layers, GL_RGB, type,
                    staging.data());
  }
}

void check_size(int width, int height, int layers, const std::string& what) {
  const int max_size = max_texture_size(), max_layers = max_array_layers();
  if (width > max_size || height > max_size || layers > max_layers) {
    throw HardwareError("OpenGL: " + what + " is " + std::to_string(width) + "x" +
                        std::to_string(height) + "x" + std::to_string(layers) +
                        ", over this GPU's limits (" + std::to_string(max_size) + " texels, " +
                        std::to_string(max_layers) + " layers)");
  }
}

// ---------------------------------------------------------------------------------------------
// Field: R(x, l) in a buffer texture in the field's own pixel-major order (each pixel's 3L values
// padded to whole groups of 4 LEDs = 3 RGBA texels), so one pixel's samples are contiguous and a
// fetch brings 4 values; the lighting as one RGBA weight per texel of a group plus the list of
// groups with any light, in a uniform buffer. (A texture array with one RGB layer per LED, the
// first version, ran 1.5x slower on llvmpipe: 150 fetches per pixel, 1 MB apart.)

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
  radiance = vec4(sum * output_scale, 1.0);
}
)";

// Worst relative error of half storage on a sample of pixels relit under equal weights: per
// channel |sum half(s v) / s - sum v| / sum |v|, over (pixel, channel) pairs whose sum |v| is at
// least 1e-3 of the largest (darker ones are below display precision anyway).
double half_relit_error(const capture::ReflectanceField& field, float scale) {
  const std::size_t pixels = std::size_t(field.width()) * field.height();
  const std::size_t step = std::max<std::size_t>(1, pixels / 4096);
  const int lights = field.num_lights();
  std::vector<double> abs_sum, error;
  for (std::size_t i = 0; i < pixels; i += step) {
    const float* v = field.values().data() + i * lights * 3;
    for (int c = 0; c < 3; ++c) {
      double exact = 0, rounded = 0, magnitude = 0;
      for (int l = 0; l < lights; ++l) {
        const float value = v[l * 3 + c];
        exact += value;
        magnitude += std::abs(value);
        rounded += double(float(Eigen::half(value * scale))) / scale;
      }
      abs_sum.push_back(magnitude);
      error.push_back(std::abs(rounded - exact));
    }
  }
  const double largest = abs_sum.empty() ? 0 : *std::max_element(abs_sum.begin(), abs_sum.end());
  double worst = 0;
  for (std::size_t i = 0; i < abs_sum.size(); ++i) {
    if (abs_sum[i] >= 1e-3 * largest && abs_sum[i] > 0) {
      worst = std::max(worst, error[i] / abs_sum[i]);
    }
  }
  return worst;
}

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
        program_(kFieldShader, "field") {
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
    note_ = "field: " + std::to_string(lights_) + " LEDs, " + mb(bytes()) + " of " +
            (half ? "half" : "float") + " in a buffer texture" +
            (why.empty() ? "" : " (" + why + ")");
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
  std::string note() const override { return note_; }
  int width() const override { return width_; }
  int height() const override { return height_; }
  std::size_t bytes() const override {
    return std::size_t(width_) * height_ * groups_ * 12 * (half_ ? 2 : 4);
  }

  void render(const ViewLighting& lighting, GpuTarget& target) override {
    check_target(*this, target);
    if (lighting.led_irradiance_rgb.size() != std::size_t(lights_) * 3) {
      throw InputError("GPU relight: lighting: the field has " + std::to_string(lights_) +
                       " LEDs but the weights have " +
                       std::to_string(lighting.led_irradiance_rgb.size() / 3));
    }
    // Only groups of LEDs that carry light (and data) are fetched: a point light lights a few.
    std::fill(block_.begin(), block_.end(), 0.0f);
    int active = 0;
    for (int g = 0; g < groups_; ++g) {
      float* w = &block_[std::size_t(active) * 12];
      bool any = false;
      for (int j = 0; j < 12; ++j) {
        const int l = 4 * g + j / 3;
        const float e = l < lights_ && valid_[l] ? lighting.led_irradiance_rgb[l * 3 + j % 3] : 0;
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
    TargetPass pass(target);
    program_.use();
    bind_texture(program_, "field_values", 0, GL_TEXTURE_BUFFER, values_.id());
    glUniform1i(program_.uniform("active_count"), active);
    glUniform1i(program_.uniform("groups"), groups_);
    glUniform1i(program_.uniform("image_width"), width_);
    glUniform1i(program_.uniform("image_height"), height_);
    glUniform1f(program_.uniform("output_scale"), 1.0f / scale_);
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

  int width_, height_, lights_, groups_;
  bool half_;
  float scale_;  // Stored values are R * scale_ (a power of two: exact).
  std::vector<bool> valid_;
  Program program_;
  GLuint values_buffer_ = 0, lighting_ = 0;
  Texture values_;
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
    if (lighting.led_irradiance_rgb.size() != std::size_t(pca_.num_lights()) * 3) {
      throw InputError("GPU relight: lighting: the PCA field has " +
                       std::to_string(pca_.num_lights()) + " LEDs but the weights have " +
                       std::to_string(lighting.led_irradiance_rgb.size() / 3));
    }
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

// ---------------------------------------------------------------------------------------------
// Prefiltered lighting for the models (ModelShading::kPrefiltered), built on the CPU from the
// distant lights.

constexpr int kPrefilterWidth = 64, kPrefilterHeight = 32;  // Lat-long, envmap.h convention.
constexpr int kPrefilterLevels = 8;
// Beckmann m per level: the first about the lights' spacing (a 64-wide grid is 0.1 rad apart,
// the Beckmann reflection lobe is sqrt(2) m wide), then roughly x1.5 a level.
constexpr float kLevelRoughness[kPrefilterLevels] = {0.05f, 0.075f, 0.11f, 0.17f,
                                                     0.25f, 0.38f,  0.6f,  1.0f};
constexpr int kLobeAlbedoSize = 32;  // Table over cos_o and m, each 0..1 in 32 steps.

// The Beckmann reflection lobe about r as a function of c = r.w: D(h) of the half vector between
// r and w at normal incidence (tan^2(theta_h) = (1 - c) / (1 + c)) times the reflection
// Jacobian 1 / (4 cos theta_h); unnormalised. Zero where exp() is below 1e-11.
double beckmann_lobe(double c, double m) {
  const double half_cos2 = 0.5 * (1.0 + c);  // cos^2(theta_h).
  if (half_cos2 <= 1e-6) return 0.0;
  const double x = (1.0 - c) / (1.0 + c) / (m * m);
  if (x > 25.0) return 0.0;
  return std::exp(-x) / (half_cos2 * half_cos2 * std::sqrt(half_cos2));
}

// Integral of beckmann_lobe over the sphere, sr, per level.
const std::array<double, kPrefilterLevels>& lobe_integrals() {
  static const std::array<double, kPrefilterLevels> integrals = [] {
    std::array<double, kPrefilterLevels> out{};
    constexpr int kSteps = 200000;
    for (int j = 0; j < kPrefilterLevels; ++j) {
      double sum = 0;
      for (int i = 0; i < kSteps; ++i) {
        const double theta = brdf::kPi * (i + 0.5) / kSteps;
        sum += beckmann_lobe(std::cos(theta), kLevelRoughness[j]) * std::sin(theta);
      }
      out[j] = 2.0 * brdf::kPi * sum * brdf::kPi / kSteps;
    }
    return out;
  }();
  return integrals;
}

// beckmann_lobe / its integral per level, at kEntries points of r.w from cutoff (where it
// vanishes) to 1, for linear interpolation.
struct LobeTables {
  static constexpr int kEntries = 2048;
  std::array<float, kPrefilterLevels> cutoff{}, inverse_step{};
  std::array<std::array<float, kEntries>, kPrefilterLevels> values{};
};

const LobeTables& lobe_tables() {
  static const LobeTables tables = [] {
    LobeTables out;
    const std::array<double, kPrefilterLevels>& integrals = lobe_integrals();
    for (int j = 0; j < kPrefilterLevels; ++j) {
      const double m = kLevelRoughness[j], x = 25.0 * m * m;
      const double cutoff = (1 - x) / (1 + x), step = (1 - cutoff) / (LobeTables::kEntries - 1);
      out.cutoff[j] = float(cutoff);
      out.inverse_step[j] = float(1 / step);
      for (int i = 0; i < LobeTables::kEntries; ++i) {
        out.values[j][i] = float(beckmann_lobe(cutoff + i * step, m) / integrals[j]);
      }
    }
    return out;
  }();
  return tables;
}

// Real SH basis, bands 0-2 (the shader's sh_eval order).
std::array<double, 9> sh_basis(const Eigen::Vector3d& d) {
  const double x = d.x(), y = d.y(), z = d.z();
  return {0.282095,
          0.488603 * y,
          0.488603 * z,
          0.488603 * x,
          1.092548 * x * y,
          1.092548 * y * z,
          0.315392 * (3 * z * z - 1),
          1.092548 * x * z,
          0.546274 * (x * x - y * y)};
}

// Directional albedo of the lobes under unit radiance, integral of f cos_i over the hemisphere
// (1/k_s), tabulated at cos_o = (i / 31)^2 (x) and m = j / 31 (y; m >= 0.01); RGBA: r Torrance-
// Sparrow, g Phong with exponent 2/m^2 - 2 clamped to [1, 1e4] as the shader, b Oren-Nayar's
// B factor under uniform light (depends on cos_o only). Importance sampled
// on a 64 x 64 stratified grid: the Beckmann half vector for Torrance-Sparrow, cos^n about the
// mirror direction for Phong.
const std::vector<float>& lobe_albedo_table() {
  static const std::vector<float> table = [] {
    constexpr int kN = kLobeAlbedoSize, kSamples = 64;
    std::vector<float> out(std::size_t(kN) * kN * 4, 0.0f);
    tbb::parallel_for(0, kN, [&](int j) {
      const double m = std::max(0.01, double(j) / (kN - 1));
      const double exponent = std::clamp(2.0 / (m * m) - 2.0, 1.0, 1e4);
      for (int i = 0; i < kN; ++i) {
        // sqrt spacing in cos_o: the lobes' albedo changes fastest at grazing.
        const double cos_o = std::max(1e-3, std::pow(double(i) / (kN - 1), 2));
        const Eigen::Vector3d wo(std::sqrt(1 - cos_o * cos_o), 0, cos_o);
        const Eigen::Vector3d mirror(-wo.x(), 0, cos_o);
        // Orthonormal frame about the mirror direction.
        const Eigen::Vector3d t1 = Eigen::Vector3d(0, 1, 0), t2 = mirror.cross(t1).normalized();
        double ts = 0, ph = 0;
        for (int a = 0; a < kSamples; ++a) {
          const double u1 = (a + 0.5) / kSamples;
          for (int b = 0; b < kSamples; ++b) {
            const double phi = 2 * brdf::kPi * (b + 0.5) / kSamples;
            // Torrance-Sparrow: h ~ D(h) cos theta_h; pdf(wi) = D cos theta_h / (4 wo.h).
            const double tan_h = m * std::sqrt(-std::log(1 - u1));
            const double cos_h = 1 / std::sqrt(1 + tan_h * tan_h), sin_h = tan_h * cos_h;
            const Eigen::Vector3d h(sin_h * std::cos(phi), sin_h * std::sin(phi), cos_h);
            const double wo_h = wo.dot(h);
            const Eigen::Vector3d wi = 2 * wo_h * h - wo;
            if (wo_h > 0 && wi.z() > 0) {
              const double d =
                  std::exp(-tan_h * tan_h / (m * m)) / (brdf::kPi * m * m * std::pow(cos_h, 4));
              const auto g = brdf::Geometry<double>::from_local(wi, wo);
              ts += brdf::torrance_sparrow(g, m) * wi.z() * 4 * wo_h / (d * cos_h);
            }
            // Phong: wi ~ (n+1)/(2 pi) cos^n(alpha) about the mirror direction.
            const double cos_a = std::pow(u1, 1 / (exponent + 1));
            const double sin_a = std::sqrt(std::max(0.0, 1 - cos_a * cos_a));
            const Eigen::Vector3d wp =
                cos_a * mirror + sin_a * (std::cos(phi) * t1 + std::sin(phi) * t2);
            if (wp.z() > 0) {
              const auto g = brdf::Geometry<double>::from_local(wp, wo);
              const double pdf = (exponent + 1) / (2 * brdf::kPi) * std::pow(cos_a, exponent);
              if (pdf > 0) ph += brdf::phong(g, exponent) * wp.z() / pdf;
            }
          }
        }
        // Oren-Nayar's B factor, max(0, wi.wo - cos_i cos_o) / max(cos_i, cos_o), averaged over
        // wi ~ cos_i / pi (uniform light): independent of m, stored in every row.
        double on = 0;
        for (int a = 0; a < kSamples; ++a) {
          const double sin_i = std::sqrt((a + 0.5) / kSamples);
          const double cos_i = std::sqrt(1 - sin_i * sin_i);
          for (int b = 0; b < kSamples; ++b) {
            const double phi = 2 * brdf::kPi * (b + 0.5) / kSamples;
            const Eigen::Vector3d wi(sin_i * std::cos(phi), sin_i * std::sin(phi), cos_i);
            on += std::max(0.0, wi.dot(wo) - cos_i * cos_o) / std::max(cos_i, cos_o);
          }
        }
        float* texel = &out[(std::size_t(j) * kN + i) * 4];
        texel[0] = float(ts / (kSamples * kSamples));
        texel[1] = float(ph / (kSamples * kSamples));
        texel[2] = float(on / (kSamples * kSamples));
      }
    });
    return out;
  }();
  return table;
}

// FNV-1a over the lights: rebuild the prefiltered lighting only when they changed.
uint64_t fingerprint(const relight::LightingForModels& lights) {
  uint64_t hash = 1469598103934665603ull;
  auto add = [&hash](const void* data, std::size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) hash = (hash ^ p[i]) * 1099511628211ull;
  };
  const std::size_t count = lights.dirs_in_stage.size();
  add(&count, sizeof(count));
  if (count > 0) {
    add(lights.dirs_in_stage.data(), count * sizeof(Eigen::Vector3f));
    add(lights.irradiance_rgb.data(), count * sizeof(Eigen::Vector3f));
  }
  return hash;
}

struct PrefilteredLighting {
  std::array<float, 27> sh_irradiance{};  // 9 RGB coefficients of E(n), A_l folded in.
  std::vector<float> levels;  // [level][row][column] RGBA radiance, row 0 the top (zenith).
};

PrefilteredLighting prefilter(const relight::LightingForModels& lights) {
  PrefilteredLighting out;
  const std::size_t count = lights.dirs_in_stage.size();
  std::vector<Eigen::Vector3d> dirs(count), irradiance(count);
  for (std::size_t k = 0; k < count; ++k) {
    dirs[k] = lights.dirs_in_stage[k].cast<double>().normalized();
    irradiance[k] = lights.irradiance_rgb[k].cast<double>();
    if (!dirs[k].allFinite()) irradiance[k].setZero(), dirs[k] = Eigen::Vector3d(0, 0, 1);
  }
  // Irradiance SH: L_lm = sum_k E_k Y_lm(w_k) (each light a delta of irradiance E_k), times the
  // clamped cosine's A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4.
  constexpr double kBand[9] = {brdf::kPi,         2 * brdf::kPi / 3, 2 * brdf::kPi / 3,
                               2 * brdf::kPi / 3, brdf::kPi / 4,     brdf::kPi / 4,
                               brdf::kPi / 4,     brdf::kPi / 4,     brdf::kPi / 4};
  std::array<Eigen::Vector3d, 9> sh;
  sh.fill(Eigen::Vector3d::Zero());
  for (std::size_t k = 0; k < count; ++k) {
    const std::array<double, 9> y = sh_basis(dirs[k]);
    for (int i = 0; i < 9; ++i) sh[i] += irradiance[k] * y[i];
  }
  for (int i = 0; i < 9; ++i) {
    for (int c = 0; c < 3; ++c) out.sh_irradiance[i * 3 + c] = float(sh[i][c] * kBand[i]);
  }
  // Each level: sum_k E_k K(r.w_k) / integral K: the radiance of the lights seen through the lobe.
  // K / integral K is tabulated over r.w from where it vanishes to 1 (a lookup instead of exp and
  // sqrt: 3x faster), in float.
  const LobeTables& tables = lobe_tables();
  std::vector<Eigen::Vector3f> dirs_f(count), irradiance_f(count);
  for (std::size_t k = 0; k < count; ++k) {
    dirs_f[k] = dirs[k].cast<float>();
    irradiance_f[k] = irradiance[k].cast<float>();
  }
  const std::size_t level_texels = std::size_t(kPrefilterWidth) * kPrefilterHeight;
  out.levels.assign(level_texels * kPrefilterLevels * 4, 0.0f);
  tbb::parallel_for(0, kPrefilterHeight, [&](int y) {
    for (int x = 0; x < kPrefilterWidth; ++x) {
      const Eigen::Vector3f r = relight::EnvironmentMap::direction((x + 0.5) / kPrefilterWidth,
                                                                   (y + 0.5) / kPrefilterHeight)
                                    .cast<float>();
      std::array<Eigen::Vector3f, kPrefilterLevels> sum;
      sum.fill(Eigen::Vector3f::Zero());
      for (std::size_t k = 0; k < count; ++k) {
        const float c = r.dot(dirs_f[k]);
        for (int j = kPrefilterLevels - 1; j >= 0 && c > tables.cutoff[j]; --j) {
          const float t = std::min((c - tables.cutoff[j]) * tables.inverse_step[j],
                                   float(LobeTables::kEntries - 1) - 1e-3f);
          const int i = int(t);
          const float* entry = &tables.values[j][i];
          sum[j] += irradiance_f[k] * (entry[0] + (t - float(i)) * (entry[1] - entry[0]));
        }
      }
      for (int j = 0; j < kPrefilterLevels; ++j) {
        float* texel = &out.levels[(j * level_texels + std::size_t(y) * kPrefilterWidth + x) * 4];
        for (int c = 0; c < 3; ++c) texel[c] = sum[j][c];
        texel[3] = 1.0f;
      }
    }
  });
  return out;
}

// ---------------------------------------------------------------------------------------------
// Models: the maps in a 5-layer RGBA32F array, the distant lights in a uniform buffer, up to
// LIGHTS_PER_PASS per pass (more lights: further passes added by blending); the shader is
// relight/model_render.cc's shade() with relight/brdf.h's models, line for line. (Lights in a
// texture, the first version, cost two fetches per light: 1.6x slower on llvmpipe.)

// "#define LIGHTS_PER_PASS n" goes after the version line.
// With "#define PREFILTERED" too, the prefiltered shading (ModelShading::kPrefiltered): no lights,
// SH irradiance and the prefiltered radiance stack instead.
constexpr const char* kModelShader = R"(
#ifdef PREFILTERED
uniform vec3 sh_irradiance[9];       // E(n) = sum_i sh_irradiance[i] Y_i(n): A_l folded in.
uniform sampler2DArray prefiltered;  // Layer j: radiance around a direction (lat-long, envmap.h)
                                     // for Beckmann roughness level_roughness[j].
uniform sampler2D lobe_albedo;       // r: Torrance-Sparrow, g: Phong directional albedo (1/k_s),
                                     // b: Oren-Nayar's mean B factor;
                                     // s: sqrt(cos_o), t: m, 0..1 from the first to the last
                                     // texel.
uniform float level_roughness[PREFILTER_LEVELS];
uniform float lobe_albedo_size;
#else
layout(std140) uniform Lights {
  vec4 light_dir[LIGHTS_PER_PASS];         // Unit, toward the light.
  vec4 light_irradiance[LIGHTS_PER_PASS];  // RGB at normal incidence.
};
#endif
uniform sampler2DArray maps;  // 0: normal xyz, model; 1: albedo rgb, sigma; 2: ks, roughness;
                              // 3: view direction xyz; 4: flagged fallback rgb.
uniform bool first_pass;      // Flagged pixels take the fallback in the first pass only.
uniform int light_count;
uniform int image_height;
uniform bool per_pixel_view;
uniform bool has_fallback;
uniform float max_ks;
out vec4 radiance;

const float kPi = 3.14159265358979323846;

// relight/brdf.h, cos(theta_i) not inside; the callers have checked cos_i > 0 and cos_o > 0.
float oren_nayar(float cos_i, float cos_o, float cos_io, float sigma) {
  float s2 = sigma * sigma;
  float a = 1.0 - 0.5 * s2 / (s2 + 0.33);
  float b = 0.45 * s2 / (s2 + 0.09);
  float azimuthal = max(cos_io - cos_i * cos_o, 0.0);
  float cos_max = max(cos_i, cos_o);
  return (a + b * azimuthal / cos_max) * (1.0 / kPi);
}

float torrance_sparrow(float cos_i, float cos_o, float cos_io, float roughness) {
  float len2 = 2.0 + 2.0 * cos_io;
  if (!(len2 > 1e-12)) return 0.0;
  float inv_len = 1.0 / sqrt(len2);
  float cos_h = (cos_i + cos_o) * inv_len;
  float cos_oh = (1.0 + cos_io) * inv_len;
  if (!(cos_h > 0.0)) return 0.0;
  float cos_h2 = cos_h * cos_h;
  float m2 = roughness * roughness;
  float tan_h2 = (1.0 - cos_h2) / cos_h2;
  float d = exp(-tan_h2 / m2) / (kPi * m2 * cos_h2 * cos_h2);
  float g = min(1.0, min(2.0 * cos_h * cos_o / cos_oh, 2.0 * cos_h * cos_i / cos_oh));
  return d * g / (4.0 * cos_i * cos_o);
}

float phong(float cos_i, float cos_o, float cos_io, float exponent) {
  float cos_alpha = 2.0 * cos_i * cos_o - cos_io;
  if (!(cos_alpha > 0.0)) return 0.0;
  return (exponent + 2.0) * (1.0 / (2.0 * kPi)) * pow(cos_alpha, exponent);
}

#ifdef PREFILTERED
// Real SH basis, bands 0-2, in the order of sh_basis() on the CPU.
vec3 sh_eval(vec3 n) {
  vec3 e = sh_irradiance[0] * 0.282095;
  e += sh_irradiance[1] * (0.488603 * n.y) + sh_irradiance[2] * (0.488603 * n.z) +
       sh_irradiance[3] * (0.488603 * n.x);
  e += sh_irradiance[4] * (1.092548 * n.x * n.y) + sh_irradiance[5] * (1.092548 * n.y * n.z) +
       sh_irradiance[6] * (0.315392 * (3.0 * n.z * n.z - 1.0)) +
       sh_irradiance[7] * (1.092548 * n.x * n.z) +
       sh_irradiance[8] * (0.546274 * (n.x * n.x - n.y * n.y));
  return max(e, vec3(0.0));
}

// Prefiltered radiance toward direction r for Beckmann roughness m: the two bracketing levels,
// interpolated in log m (clamped to the first and last level).
vec3 prefiltered_radiance(vec3 r, float m) {
  float v = acos(clamp(r.y, -1.0, 1.0)) / kPi;
  float u = atan(r.x, -r.z) / (2.0 * kPi) + 0.5;
  int j = 0;
  while (j + 2 < PREFILTER_LEVELS && m > level_roughness[j + 1]) ++j;
  float t = clamp(log(m / level_roughness[j]) / log(level_roughness[j + 1] / level_roughness[j]),
                  0.0, 1.0);
  return mix(texture(prefiltered, vec3(u, v, float(j))).rgb,
             texture(prefiltered, vec3(u, v, float(j + 1))).rgb, t);
}

vec4 lobe_albedo_at(float cos_o, float m) {
  vec2 st = (vec2(sqrt(cos_o), m) * (lobe_albedo_size - 1.0) + 0.5) / lobe_albedo_size;
  return texture(lobe_albedo, st);
}
#endif

vec3 shade(ivec2 texel) {
  vec4 m0 = texelFetch(maps, ivec3(texel, 0), 0);
  vec4 m1 = texelFetch(maps, ivec3(texel, 1), 0);
  vec4 m2 = texelFetch(maps, ivec3(texel, 2), 0);
  int model = int(m0.w);
  if (model <= 0 || model > 4) {
    if (!has_fallback || !first_pass) return vec3(0.0);
    vec3 v = texelFetch(maps, ivec3(texel, 4), 0).rgb;
    return vec3(isinf(v.r) || isnan(v.r) ? 0.0 : v.r, isinf(v.g) || isnan(v.g) ? 0.0 : v.g,
                isinf(v.b) || isnan(v.b) ? 0.0 : v.b);
  }
  vec3 wo = per_pixel_view ? texelFetch(maps, ivec3(texel, 3), 0).xyz : vec3(0.0, 0.0, 1.0);
  float norm = length(m0.xyz);
  if (!(norm > 0.0)) return vec3(0.0);
  vec3 n = m0.xyz / norm;
  float cos_o = dot(n, wo);
  if (!(cos_o > 0.0)) return vec3(0.0);
  vec3 albedo = m1.rgb;
  float sigma = m1.a;
  float ks = min(m2.x, max_ks);
  float roughness = max(m2.y, 1e-3);
  float exponent = clamp(2.0 / (roughness * roughness) - 2.0, 1.0, 1e4);
  bool oren = model == 2;
  bool lobe = ks > 0.0 && (model == 3 || model == 4);
  vec3 diffuse = vec3(0.0), specular = vec3(0.0);
#ifdef PREFILTERED
  vec4 lobe_albedo = lobe_albedo_at(cos_o, min(roughness, 1.0));
  // Oren-Nayar: A + B times its azimuthal factor's mean under uniform light (see ModelShading).
  float s2 = sigma * sigma;
  float oren_factor = oren ? 1.0 - 0.5 * s2 / (s2 + 0.33) + 0.45 * s2 / (s2 + 0.09) * lobe_albedo.b
                           : 1.0;
  diffuse = sh_eval(n) * (oren_factor / kPi);
  if (lobe) {
    // Split sum: the radiance around the lobe's direction times the lobe's albedo. Torrance-
    // Sparrow: the dominant direction leans from the mirror direction toward the normal as the
    // lobe widens (Lagarde & de Rousiers 2014; their alpha is Beckmann's m here): measured max
    // error 0.32 -> 0.12 of the peak on the glossy scene. Phong: cos^n(alpha) about the mirror
    // direction is as wide as the Beckmann reflection lobe of m / 2 (n = 2/m^2 - 2: sigma =
    // m/sqrt(2) against sqrt(2) m).
    float lean =
        model == 3 ? (1.0 - roughness) * (sqrt(max(1.0 - roughness, 0.0)) + roughness) : 1.0;
    vec3 r = normalize(mix(n, 2.0 * cos_o * n - wo, clamp(lean, 0.0, 1.0)));
    bool phong_lobe = model == 4;
    specular = prefiltered_radiance(r, phong_lobe ? 0.5 * roughness : roughness) *
               (phong_lobe ? lobe_albedo.g : lobe_albedo.r);
  }
#else
  for (int k = 0; k < light_count; ++k) {
    vec3 wi = light_dir[k].xyz;
    float cos_i = dot(n, wi);
    if (!(cos_i > 0.0)) continue;
    vec3 e = light_irradiance[k].rgb;
    float cos_io = dot(wi, wo);
    diffuse += e * (cos_i * (oren ? oren_nayar(cos_i, cos_o, cos_io, sigma) : 1.0 / kPi));
    if (lobe) {
      float f = model == 3 ? torrance_sparrow(cos_i, cos_o, cos_io, roughness)
                           : phong(cos_i, cos_o, cos_io, exponent);
      specular += e * (f * cos_i);
    }
  }
#endif
  vec3 out_rgb = albedo * diffuse + ks * specular;
  // A lobe at grazing angles can overflow float: never let inf/NaN out (as the CPU; over several
  // passes a pass that overflows adds 0 where the CPU zeroes the whole sum).
  for (int c = 0; c < 3; ++c) {
    if (isinf(out_rgb[c]) || isnan(out_rgb[c])) out_rgb[c] = 0.0;
  }
  return out_rgb;
}

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  radiance = vec4(shade(ivec2(p.x, image_height - 1 - p.y)), 1.0);
}
)";

class ModelSource : public GpuSource {
 public:
  ModelSource(const relight::ModelMaps& model_maps, const relight::ModelRenderOptions& options,
              ModelShading shading)
      : shading_(shading),
        width_(model_maps.maps.width),
        height_(model_maps.maps.height),
        per_pixel_view_(!options.view_dir_per_pixel.empty()),
        has_fallback_(options.flagged_fallback != nullptr),
        max_ks_(std::isfinite(options.max_specular_albedo) ? options.max_specular_albedo
                                                           : std::numeric_limits<float>::max()),
        lights_per_pass_(lights_per_pass()),
        program_(("#version 330 core\n#define LIGHTS_PER_PASS " + std::to_string(lights_per_pass_) +
                  kModelShader)
                     .c_str(),
                 "models") {
    const Image& src = model_maps.maps;
    if (src.channels != relight::kMapChannelCount) {
      throw InputError("GPU relight: model maps: expected " +
                       std::to_string(int(relight::kMapChannelCount)) + " channels, got " +
                       std::to_string(src.channels));
    }
    if (per_pixel_view_ && options.view_dir_per_pixel.size() != src.num_pixels()) {
      throw InputError("model render options: view_dir_per_pixel: expected " +
                       std::to_string(src.num_pixels()) + " directions, got " +
                       std::to_string(options.view_dir_per_pixel.size()));
    }
    const Image* fallback = options.flagged_fallback;
    if (fallback != nullptr &&
        (fallback->width != width_ || fallback->height != height_ || fallback->channels < 3)) {
      throw InputError("model render options: flagged_fallback: expected a " +
                       std::to_string(width_) + "x" + std::to_string(height_) +
                       " image with >= 3 channels, got " + std::to_string(fallback->width) + "x" +
                       std::to_string(fallback->height) + "x" + std::to_string(fallback->channels));
    }
    check_size(width_, height_, kLayers, "the model maps texture");
    // Pixel-major staging, 5 RGBA texels per pixel, then one upload per layer.
    const std::size_t pixels = src.num_pixels();
    std::vector<float> layer(pixels * 4);
    glBindTexture(GL_TEXTURE_2D_ARRAY, maps_.id());
    set_nearest(GL_TEXTURE_2D_ARRAY);
    glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGBA32F, width_, height_, kLayers, 0, GL_RGBA, GL_FLOAT,
                 nullptr);
    check_gl("allocating the model maps (" + mb(bytes()) + ")");
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    for (int l = 0; l < kLayers; ++l) {
      for (std::size_t i = 0; i < pixels; ++i) {
        const float* m = &src.pixels[i * relight::kMapChannelCount];
        float* t = &layer[i * 4];
        switch (l) {
          case 0:
            t[0] = m[relight::kMapNormalX], t[1] = m[relight::kMapNormalY];
            t[2] = m[relight::kMapNormalZ], t[3] = m[relight::kMapModel];
            break;
          case 1:
            t[0] = m[relight::kMapAlbedoR], t[1] = m[relight::kMapAlbedoG];
            t[2] = m[relight::kMapAlbedoB], t[3] = m[relight::kMapSigma];
            break;
          case 2:
            t[0] = m[relight::kMapKs], t[1] = m[relight::kMapRoughness], t[2] = t[3] = 0;
            break;
          case 3: {
            const Eigen::Vector3f wo =
                per_pixel_view_ ? options.view_dir_per_pixel[i].normalized().cast<float>()
                                : Eigen::Vector3f(0, 0, 1);
            t[0] = wo.x(), t[1] = wo.y(), t[2] = wo.z(), t[3] = 0;
            break;
          }
          default:
            for (int c = 0; c < 3; ++c)
              t[c] = fallback ? fallback->pixels[i * fallback->channels + c] : 0;
            t[3] = 0;
        }
      }
      glTexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, l, width_, height_, 1, GL_RGBA, GL_FLOAT,
                      layer.data());
    }
    check_gl("uploading the model maps");
    glGenBuffers(1, &lights_);
    glBindBuffer(GL_UNIFORM_BUFFER, lights_);
    glBufferData(GL_UNIFORM_BUFFER, GLsizeiptr(lights_per_pass_) * 32, nullptr, GL_DYNAMIC_DRAW);
    glBindBuffer(GL_UNIFORM_BUFFER, 0);
    program_.use();
    program_.bind_block("Lights", 0);
    check_gl("allocating the lights");
  }
  ~ModelSource() override { glDeleteBuffers(1, &lights_); }
  ModelSource(const ModelSource&) = delete;
  ModelSource& operator=(const ModelSource&) = delete;

  std::string name() const override { return "models"; }
  std::string note() const override {
    const int passes = std::max(1, (light_count_ + lights_per_pass_ - 1) / lights_per_pass_);
    std::string how;
    if (last_prefiltered_) {
      std::ostringstream ms;
      ms.precision(1);
      ms << std::fixed << prefilter_ms_;
      how = std::to_string(light_count_) + " distant lights prefiltered (SH9 irradiance, " +
            std::to_string(kPrefilterLevels) + " roughness levels of " +
            std::to_string(kPrefilterWidth) + "x" + std::to_string(kPrefilterHeight) + ", " +
            ms.str() + " ms on the CPU)";
    } else {
      how = std::to_string(light_count_) + " distant lights" +
            (passes > 1 ? " in " + std::to_string(passes) + " passes" : "");
    }
    return "models: " + mb(bytes()) + " of maps; " + how + ", " +
           (per_pixel_view_ ? "per-pixel view directions" : "orthographic view (0, 0, 1)");
  }
  int width() const override { return width_; }
  int height() const override { return height_; }
  std::size_t bytes() const override { return std::size_t(width_) * height_ * kLayers * 16; }

  void render(const ViewLighting& lighting, GpuTarget& target) override {
    check_target(*this, target);
    const relight::LightingForModels& in = lighting.lights;
    if (in.dirs_in_stage.size() != in.irradiance_rgb.size()) {
      throw InputError("GPU relight: lighting: " + std::to_string(in.dirs_in_stage.size()) +
                       " directions but " + std::to_string(in.irradiance_rgb.size()) +
                       " irradiances");
    }
    light_count_ = int(in.dirs_in_stage.size());
    last_prefiltered_ = shading_ == ModelShading::kPrefiltered ||
                        (shading_ == ModelShading::kAuto && light_count_ > kMaxExactLights);
    if (last_prefiltered_) {
      render_prefiltered(in, target);
      return;
    }
    TargetPass pass(target);
    program_.use();
    bind_texture(program_, "maps", 0, GL_TEXTURE_2D_ARRAY, maps_.id());
    glUniform1i(program_.uniform("image_height"), height_);
    glUniform1i(program_.uniform("per_pixel_view"), per_pixel_view_);
    glUniform1i(program_.uniform("has_fallback"), has_fallback_);
    glUniform1f(program_.uniform("max_ks"), max_ks_);
    glBindBufferBase(GL_UNIFORM_BUFFER, 0, lights_);
    glBlendFunc(GL_ONE, GL_ONE);
    // At least one pass, so that no lights still draws black (or the fallback).
    for (int first = 0; first == 0 || first < light_count_; first += lights_per_pass_) {
      const int count = std::min(lights_per_pass_, light_count_ - first);
      packed_.assign(std::size_t(lights_per_pass_) * 8, 0.0f);
      for (int k = 0; k < count; ++k) {
        for (int c = 0; c < 3; ++c) {
          packed_[std::size_t(k) * 4 + c] = in.dirs_in_stage[first + k][c];
          packed_[(std::size_t(lights_per_pass_) + k) * 4 + c] = in.irradiance_rgb[first + k][c];
        }
      }
      glBindBuffer(GL_UNIFORM_BUFFER, lights_);
      glBufferSubData(GL_UNIFORM_BUFFER, 0, GLsizeiptr(packed_.size() * sizeof(float)),
                      packed_.data());
      glBindBuffer(GL_UNIFORM_BUFFER, 0);
      // Passes after the first add to what is there (float blending: no clamping).
      if (first > 0) glEnable(GL_BLEND);
      glUniform1i(program_.uniform("first_pass"), first == 0);
      glUniform1i(program_.uniform("light_count"), std::max(count, 0));
      program_.draw();
    }
    glDisable(GL_BLEND);
    check_gl("relighting the models");
  }

 private:
  static constexpr int kLayers = 5;
  // 1024 lights (32 KiB) where uniform blocks may be that large (llvmpipe, NVIDIA, AMD: 64 KiB),
  // else 512 (16 KiB, the GL 3.3 minimum).
  static int lights_per_pass() {
    GLint max_block = 0;
    glGetIntegerv(GL_MAX_UNIFORM_BLOCK_SIZE, &max_block);
    return max_block >= 32768 ? 1024 : 512;
  }
  // Prefiltered shading: the lighting rebuilt on the CPU and uploaded when the lights changed, then
  // one pass with no per-light work.
  void render_prefiltered(const relight::LightingForModels& in, GpuTarget& target) {
    if (!prefiltered_program_) {
      prefiltered_program_ = std::make_unique<Program>(
          ("#version 330 core\n#define PREFILTERED\n#define PREFILTER_LEVELS " +
           std::to_string(kPrefilterLevels) + "\n#define LIGHTS_PER_PASS 1" + kModelShader)
              .c_str(),
          "models prefiltered");
      const std::vector<float>& table = lobe_albedo_table();
      glBindTexture(GL_TEXTURE_2D, lobe_albedo_.id());
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
      glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
      glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, kLobeAlbedoSize, kLobeAlbedoSize, 0, GL_RGBA,
                   GL_FLOAT, table.data());
      glBindTexture(GL_TEXTURE_2D_ARRAY, prefiltered_.id());
      glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_S, GL_REPEAT);  // Longitude wraps.
      glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
      glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGBA32F, kPrefilterWidth, kPrefilterHeight,
                   kPrefilterLevels, 0, GL_RGBA, GL_FLOAT, nullptr);
      check_gl("allocating the prefiltered environment");
    }
    const uint64_t key = fingerprint(in);
    if (!prefiltered_key_ || *prefiltered_key_ != key) {
      const auto t0 = std::chrono::steady_clock::now();
      const PrefilteredLighting lighting = prefilter(in);
      sh_irradiance_ = lighting.sh_irradiance;
      glBindTexture(GL_TEXTURE_2D_ARRAY, prefiltered_.id());
      glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
      glTexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, kPrefilterWidth, kPrefilterHeight,
                      kPrefilterLevels, GL_RGBA, GL_FLOAT, lighting.levels.data());
      check_gl("uploading the prefiltered environment");
      prefiltered_key_ = key;
      prefilter_ms_ =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    }
    TargetPass pass(target);
    const Program& program = *prefiltered_program_;
    program.use();
    bind_texture(program, "maps", 0, GL_TEXTURE_2D_ARRAY, maps_.id());
    bind_texture(program, "prefiltered", 1, GL_TEXTURE_2D_ARRAY, prefiltered_.id());
    bind_texture(program, "lobe_albedo", 2, GL_TEXTURE_2D, lobe_albedo_.id());
    glUniform3fv(program.uniform("sh_irradiance"), 9, sh_irradiance_.data());
    glUniform1fv(program.uniform("level_roughness"), kPrefilterLevels, kLevelRoughness);
    glUniform1f(program.uniform("lobe_albedo_size"), float(kLobeAlbedoSize));
    glUniform1i(program.uniform("image_height"), height_);
    glUniform1i(program.uniform("per_pixel_view"), per_pixel_view_);
    glUniform1i(program.uniform("has_fallback"), has_fallback_);
    glUniform1f(program.uniform("max_ks"), max_ks_);
    glUniform1i(program.uniform("first_pass"), 1);
    program.draw();
    glActiveTexture(GL_TEXTURE0);
    check_gl("relighting the models (prefiltered)");
  }

  ModelShading shading_;
  int width_, height_;
  bool per_pixel_view_, has_fallback_;
  float max_ks_;
  int lights_per_pass_;
  Program program_;
  Texture maps_;
  GLuint lights_ = 0;  // Uniform buffer: LIGHTS_PER_PASS directions, then as many irradiances.
  int light_count_ = 0;
  std::vector<float> packed_;
  std::unique_ptr<Program> prefiltered_program_;
  Texture prefiltered_, lobe_albedo_;
  std::optional<uint64_t> prefiltered_key_;
  std::array<float, 27> sh_irradiance_{};
  bool last_prefiltered_ = false;
  double prefilter_ms_ = 0;
};

// ---------------------------------------------------------------------------------------------
// Display.

constexpr const char* kDisplayShader = R"(#version 330 core
uniform sampler2D image_a;
uniform sampler2D image_b;
uniform bool has_b;
uniform bool difference;
uniform float divider;   // 0..1 across the viewport.
uniform float gain;      // 2^exposure.
uniform vec4 viewport;   // x, y, width, height in window pixels.
out vec4 color;

float srgb(float v) {
  v = clamp(v, 0.0, 1.0);
  return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

void main() {
  vec2 uv = (gl_FragCoord.xy - viewport.xy) / viewport.zw;
  vec3 a = texture(image_a, uv).rgb;
  vec3 v = a;
  if (has_b && difference) {
    v = abs(a - texture(image_b, uv).rgb);
  } else if (has_b && uv.x > divider) {
    v = texture(image_b, uv).rgb;
  }
  v *= gain;
  color = vec4(srgb(v.r), srgb(v.g), srgb(v.b), 1.0);
  // The divider: a one-pixel light line.
  if (has_b && !difference && int(gl_FragCoord.x) == int(floor(viewport.x + divider * viewport.z))) {
    color = vec4(0.9, 0.9, 0.9, 1.0);
  }
}
)";

// The display program of the current context. Keyed by GlWindow's context id, not the GLFWwindow
// address: a new window can get a destroyed one's address, and with it a dead program.
Program& display_program() {
  static std::uint64_t context = 0;
  static std::unique_ptr<Program> program;
  const std::uint64_t current = GlWindow::current_context_id();
  if (!program || current != context) {
    // The old program belongs to another (perhaps destroyed) context: forget it without calling
    // GL on it. (If that context is still alive, switching back builds a new one.)
    if (program) (void)program.release();
    program = std::make_unique<Program>(kDisplayShader, "display");
    context = current;
  }
  return *program;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

GpuTarget::GpuTarget(int width, int height) : width_(width), height_(height) {
  if (width <= 0 || height <= 0) {
    throw InputError("GPU target: size: expected positive, got " + std::to_string(width) + "x" +
                     std::to_string(height));
  }
  glGenTextures(1, &texture_);
  glBindTexture(GL_TEXTURE_2D, texture_);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, width, height, 0, GL_RGBA, GL_FLOAT, nullptr);
  GLint previous = 0;
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &previous);
  glGenFramebuffers(1, &framebuffer_);
  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer_);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, texture_, 0);
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  glClearColor(0, 0, 0, 1);
  if (status == GL_FRAMEBUFFER_COMPLETE) glClear(GL_COLOR_BUFFER_BIT);
  glBindFramebuffer(GL_FRAMEBUFFER, GLuint(previous));
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    glDeleteFramebuffers(1, &framebuffer_);
    glDeleteTextures(1, &texture_);
    throw HardwareError("OpenGL: a " + std::to_string(width) + "x" + std::to_string(height) +
                        " RGBA32F render target is not supported (framebuffer status " +
                        std::to_string(status) + ")");
  }
  check_gl("creating a " + std::to_string(width) + "x" + std::to_string(height) + " render target");
}

GpuTarget::~GpuTarget() {
  glDeleteFramebuffers(1, &framebuffer_);
  glDeleteTextures(1, &texture_);
}

Image GpuTarget::read_back() const {
  std::vector<float> rgba(std::size_t(width_) * height_ * 4);
  GLint previous = 0;
  glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &previous);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer_);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadPixels(0, 0, width_, height_, GL_RGBA, GL_FLOAT, rgba.data());
  glBindFramebuffer(GL_READ_FRAMEBUFFER, GLuint(previous));
  check_gl("reading back the render target");
  Image out(width_, height_, 3);
  out.channel_names = {"R", "G", "B"};
  for (int y = 0; y < height_; ++y) {
    const float* row = &rgba[std::size_t(height_ - 1 - y) * width_ * 4];  // GL rows go up.
    for (int x = 0; x < width_; ++x) {
      for (int c = 0; c < 3; ++c) out.at(x, y, c) = row[x * 4 + c];
    }
  }
  return out;
}

std::size_t gpu_memory_budget_bytes() {
  constexpr std::size_t kDefault = std::size_t(1) << 30;
  // Extension enums (not in glcorearb.h): GL_NVX_gpu_memory_info and GL_ATI_meminfo, in KiB.
  constexpr GLenum kNvxCurrentAvailableKib = 0x9049;
  constexpr GLenum kAtiTextureFreeMemory = 0x87FC;
  GLint count = 0;
  glGetIntegerv(GL_NUM_EXTENSIONS, &count);
  bool nvx = false, ati = false;
  for (GLint i = 0; i < count; ++i) {
    const char* name = reinterpret_cast<const char*>(glGetStringi(GL_EXTENSIONS, GLuint(i)));
    if (name == nullptr) continue;
    nvx = nvx || std::strcmp(name, "GL_NVX_gpu_memory_info") == 0;
    ati = ati || std::strcmp(name, "GL_ATI_meminfo") == 0;
  }
  GLint kib[4] = {0, 0, 0, 0};
  if (nvx) {
    glGetIntegerv(kNvxCurrentAvailableKib, kib);
  } else if (ati) {
    glGetIntegerv(kAtiTextureFreeMemory, kib);
  }
  while (glGetError() != GL_NO_ERROR) {
  }
  // Three quarters of what is free: render targets, the window and other sources need the rest.
  if (kib[0] > 0) return std::size_t(kib[0]) * 1024 / 4 * 3;
  return kDefault;
}

std::unique_ptr<GpuSource> upload_field(const capture::ReflectanceField& field,
                                        std::size_t budget_bytes, FieldPrecision precision) {
  const std::size_t values = FieldSource::texels(field) * 4;  // Padded to whole LED groups.
  // Scale by a power of two so the largest |value| is 2^14: well inside half's range (65504), and
  // exact.
  float largest = 0;
  for (float v : field.values()) largest = std::max(largest, std::abs(v));
  const float scale =
      largest > 0 && std::isfinite(largest) ? std::ldexp(1.0f, 14 - std::ilogb(largest)) : 1.0f;
  std::string why;
  bool half = precision == FieldPrecision::kHalf;
  if (precision == FieldPrecision::kAuto) {
    const double error = half_relit_error(field, scale);
    half = error <= 1e-3;
    std::ostringstream out;
    out.precision(1);
    out << std::scientific << "half float's relit error " << error
        << (half ? " <= 1e-3" : " > 1e-3: float");
    // A software renderer converts half to float on every fetch: float is as fast or faster there
    // (bench_viewer, llvmpipe, 512^2 x 150: 126 against 171 ms a frame on a quiet machine, 268
    // against 262 ms under load) and exact, so it is used when it fits.
    const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
    const bool software = renderer != nullptr && (std::strstr(renderer, "llvmpipe") != nullptr ||
                                                  std::strstr(renderer, "softpipe") != nullptr);
    if (half && software && values * 4 <= budget_bytes) {
      half = false;
      out << ", but float is faster on " << renderer;
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

std::unique_ptr<GpuSource> upload_models(const relight::ModelMaps& maps,
                                         const relight::ModelRenderOptions& options,
                                         ModelShading shading) {
  return std::make_unique<ModelSource>(maps, options, shading);
}

void draw_to_screen(const GpuTarget& target, const DisplayOptions& options, int viewport_x,
                    int viewport_y, int viewport_width, int viewport_height) {
  Program& program = display_program();
  const GLboolean blend = glIsEnabled(GL_BLEND), depth = glIsEnabled(GL_DEPTH_TEST);
  glDisable(GL_BLEND);
  glDisable(GL_DEPTH_TEST);
  glViewport(viewport_x, viewport_y, viewport_width, viewport_height);
  program.use();
  bind_texture(program, "image_a", 0, GL_TEXTURE_2D, target.texture());
  bind_texture(program, "image_b", 1, GL_TEXTURE_2D,
               options.split ? options.split->texture() : target.texture());
  glUniform1i(program.uniform("has_b"), options.split != nullptr);
  glUniform1i(program.uniform("difference"), options.difference);
  glUniform1f(program.uniform("divider"), float(std::clamp(options.divider, 0.0, 1.0)));
  glUniform1f(program.uniform("gain"), float(std::exp2(options.exposure_stops)));
  glUniform4f(program.uniform("viewport"), float(viewport_x), float(viewport_y),
              float(std::max(viewport_width, 1)), float(std::max(viewport_height, 1)));
  program.draw();
  if (blend) glEnable(GL_BLEND);
  if (depth) glEnable(GL_DEPTH_TEST);
  check_gl("drawing to the screen");
}

}  // namespace ls::viewer
