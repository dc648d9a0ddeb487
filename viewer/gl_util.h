#pragma once
// Internal to the viewer library (not installed, not for callers): the OpenGL helpers the GPU
// sources share (viewer/gpu_field.cc, gpu_models.cc, gpu_display.cc): error checks, a full-screen
// shader program, owned textures, the render-target pass and texture uploads.
//
// Everything here needs a current OpenGL 3.3 core context on the calling thread.
#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES
#endif
#include <GL/glcorearb.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

#include "viewer/gpu_relight.h"

namespace ls::viewer::gl_util {

// Throws HardwareError when GL reported an error since the last check (out of memory above all).
void check_gl(const std::string& what);

// "472 MB", "1.5 MB", "36.9 kB".
std::string mb(std::size_t bytes);

// A linked program with the full-screen vertex shader and an empty VAO.
class Program {
 public:
  Program(const char* fragment_source, const std::string& name);
  ~Program();
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
                  GLuint texture);

void set_nearest(GLenum target);

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

void check_target(const GpuSource& source, const GpuTarget& target);
// InputError unless the weights a source relights by (ViewLighting::led_irradiance_rgb, or
// field_irradiance_rgb() for a field) hold one RGB weight per LED of the source.
void check_led_weights(const GpuSource& source, const std::vector<float>& irradiance_rgb, int leds);

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

// Throws HardwareError when a width x height x layers texture is over this GPU's limits.
void check_size(int width, int height, int layers, const std::string& what);

}  // namespace ls::viewer::gl_util
