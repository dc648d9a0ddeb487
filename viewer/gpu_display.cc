// Render targets and display of viewer/gpu_relight.h: GpuTarget, gpu_memory_budget_bytes,
// draw_to_screen.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>

#include "lightstage/errors.h"
#include "viewer/gl_util.h"
#include "viewer/gl_window.h"
#include "viewer/gpu_relight.h"

namespace ls::viewer {

using namespace gl_util;

namespace {

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

void GpuTarget::upload(const Image& image) {
  if (image.width != width_ || image.height != height_ || image.channels < 1) {
    throw InputError("uploading a " + std::to_string(image.width) + "x" +
                     std::to_string(image.height) + " image into a " + std::to_string(width_) +
                     "x" + std::to_string(height_) + " render target");
  }
  std::vector<float> rgba(std::size_t(width_) * height_ * 4, 1.0f);
  for (int y = 0; y < height_; ++y) {
    const int gl_row = height_ - 1 - y;  // GL's row 0 is the bottom.
    for (int x = 0; x < width_; ++x) {
      for (int c = 0; c < 3; ++c)
        rgba[(std::size_t(gl_row) * width_ + x) * 4 + c] =
            image.at(x, y, std::min(c, image.channels - 1));
    }
  }
  glBindTexture(GL_TEXTURE_2D, texture_);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width_, height_, GL_RGBA, GL_FLOAT, rgba.data());
  glBindTexture(GL_TEXTURE_2D, 0);
  check_gl("uploading an image into the render target");
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
