#include "viewer/gl_util.h"

#include <sstream>

#include "lightstage/errors.h"

namespace ls::viewer::gl_util {
namespace {

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

}  // namespace

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

Program::Program(const char* fragment_source, const std::string& name) {
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

Program::~Program() {
  glDeleteVertexArrays(1, &vao_);
  glDeleteProgram(program_);
}

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

void check_target(const GpuSource& source, const GpuTarget& target) {
  if (target.width() != source.width() || target.height() != source.height()) {
    throw InputError("GPU relight: target: expected " + std::to_string(source.width()) + "x" +
                     std::to_string(source.height()) + " (the " + source.name() + "'s size), got " +
                     std::to_string(target.width()) + "x" + std::to_string(target.height()));
  }
}

void check_led_weights(const GpuSource& source, const std::vector<float>& irradiance_rgb,
                       int leds) {
  if (irradiance_rgb.size() != std::size_t(leds) * 3) {
    throw InputError("GPU relight: lighting: the " + source.name() + " has " +
                     std::to_string(leds) + " LEDs but the weights have " +
                     std::to_string(irradiance_rgb.size() / 3));
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

}  // namespace ls::viewer::gl_util
