// The models source of viewer/gpu_relight.h: upload_models, exact and prefiltered shading.
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <sstream>

#include "lightstage/errors.h"
#include "viewer/gl_util.h"
#include "viewer/gpu_prefilter.h"
#include "viewer/gpu_relight.h"

namespace ls::viewer {

using namespace gl_util;
using namespace model_prefilter;

namespace {

// ---------------------------------------------------------------------------------------------
// Models: the maps in a 5-layer RGBA32F array, the distant lights in a uniform buffer, up to
// LIGHTS_PER_PASS per pass (more lights: further passes added by blending); the shader is
// relight/fit/model_render.cc's shade() with physics/brdf.h's models, line for line, and
// the same shadows (each light takes its nearest LED's). The prefiltered shading has no shadows:
// its lighting is one environment for every pixel.
// (Lights in a texture instead cost two fetches per light: 1.6x slower on llvmpipe.)

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
  vec4 light_dir[LIGHTS_PER_PASS];         // Unit, toward the light; w: its nearest LED.
  vec4 light_irradiance[LIGHTS_PER_PASS];  // RGB at normal incidence.
};
// The fit's LED shadows (relight/fit/fit_shadows.h): layer w holds LEDs 8w .. 8w+7, 3 bits each,
// as an integer-valued float.
uniform sampler2DArray shadow_words;
uniform bool has_shadows;

// The share of light k that reaches the pixel.
float lit_share(ivec2 texel, int k) {
  if (!has_shadows) return 1.0;
  int led = int(light_dir[k].w);
  uint word = uint(texelFetch(shadow_words, ivec3(texel, led / 8), 0).r);
  return 1.0 - float((word >> uint(3 * (led % 8))) & 7u) / 7.0;
}
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

// physics/brdf.h, cos(theta_i) not inside; the callers have checked cos_i > 0 and cos_o > 0.
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
    vec3 e = light_irradiance[k].rgb * lit_share(texel, k);
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
    upload_shadows(model_maps.shadows);
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
  std::size_t bytes() const override {
    return std::size_t(width_) * height_ * kLayers * 16 + shadow_bytes_;
  }

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
    const std::vector<int> nearest_led =
        shadow_leds_.empty() ? std::vector<int>{}
                             : relight::nearest_leds(shadow_leds_, in.dirs_in_stage);
    bind_texture(program_, "shadow_words", 1, GL_TEXTURE_2D_ARRAY, shadow_words_.id());
    glUniform1i(program_.uniform("has_shadows"), !shadow_leds_.empty());
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
        if (!nearest_led.empty()) packed_[std::size_t(k) * 4 + 3] = float(nearest_led[first + k]);
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
    glActiveTexture(GL_TEXTURE0);
    check_gl("relighting the models");
  }

 private:
  // One R32F layer per shadow word (a 1x1 layer of 0 when there are none, so the sampler is
  // complete); the LEDs' directions kept for the lights' nearest LEDs.
  void upload_shadows(const relight::FitShadows& shadows) {
    if (!shadows.empty()) {
      if (shadows.words.width != width_ || shadows.words.height != height_) {
        throw InputError("GPU relight: model maps: the shadows are " +
                         std::to_string(shadows.words.width) + "x" +
                         std::to_string(shadows.words.height) + ", the maps " +
                         std::to_string(width_) + "x" + std::to_string(height_));
      }
      shadow_leds_ = shadows.led_dirs_in_stage;
    }
    const int layers = std::max(1, shadows.words.channels);
    const int w = shadows.empty() ? 1 : width_, h = shadows.empty() ? 1 : height_;
    check_size(w, h, layers, "the shadows texture");
    glBindTexture(GL_TEXTURE_2D_ARRAY, shadow_words_.id());
    set_nearest(GL_TEXTURE_2D_ARRAY);
    glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_R32F, w, h, layers, 0, GL_RED, GL_FLOAT, nullptr);
    std::vector<float> layer(std::size_t(w) * h, 0.0f);
    for (int l = 0; l < layers; ++l) {
      for (std::size_t i = 0; !shadows.empty() && i < layer.size(); ++i) {
        layer[i] = shadows.words.pixels[i * std::size_t(shadows.words.channels) + std::size_t(l)];
      }
      glTexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, l, w, h, 1, GL_RED, GL_FLOAT, layer.data());
    }
    check_gl("uploading the shadows");
    shadow_bytes_ = shadows.empty() ? 0 : std::size_t(width_) * height_ * layers * 4;
  }

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
  Texture maps_, shadow_words_;
  std::vector<Eigen::Vector3f> shadow_leds_;  // Empty: no shadows.
  std::size_t shadow_bytes_ = 0;
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

}  // namespace

std::unique_ptr<GpuSource> upload_models(const relight::ModelMaps& maps,
                                         const relight::ModelRenderOptions& options,
                                         ModelShading shading) {
  return std::make_unique<ModelSource>(maps, options, shading);
}

}  // namespace ls::viewer
