#include "viewer/gl_window.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>
// glcorearb.h first: GLFW must not pull in the legacy <GL/gl.h>.
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <map>
#include <mutex>

#include "lightstage/errors.h"

namespace ls::viewer {
namespace {

// The last GLFW error, for the HardwareError messages (GLFW reports through a callback).
std::mutex error_mutex;
std::string last_glfw_error;

void record_glfw_error(int code, const char* description) {
  std::lock_guard lock(error_mutex);
  last_glfw_error = "GLFW error " + std::to_string(code) + ": " + (description ? description : "");
}

std::string take_glfw_error() {
  std::lock_guard lock(error_mutex);
  std::string message = last_glfw_error.empty() ? "no GLFW error reported" : last_glfw_error;
  last_glfw_error.clear();
  return message;
}

// GLFW is process-wide: initialised by the first window, terminated with the last.
int live_windows = 0;
// Live windows and their ids (GL is used from one thread).
std::map<GLFWwindow*, std::uint64_t> window_ids;
std::uint64_t next_window_id = 1;

}  // namespace

GlWindow::GlWindow(int width, int height, const std::string& title, bool visible) {
  glfwSetErrorCallback(record_glfw_error);
  if (live_windows == 0 && !glfwInit()) {
    throw HardwareError("no display: glfwInit failed (" + take_glfw_error() +
                        "); run under xvfb-run -a, or set DISPLAY");
  }
  ++live_windows;
  glfwDefaultWindowHints();
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_VISIBLE, visible ? GLFW_TRUE : GLFW_FALSE);
  window_ = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
  if (!window_) {
    std::string error = take_glfw_error();
    if (--live_windows == 0) glfwTerminate();
    throw HardwareError("no OpenGL 3.3 core context: glfwCreateWindow failed (" + error +
                        "); the viewer needs OpenGL 3.3 (Mesa's llvmpipe provides it)");
  }
  window_ids[window_] = next_window_id++;
  glfwMakeContextCurrent(window_);
}

GlWindow::~GlWindow() {
  window_ids.erase(window_);
  if (window_) glfwDestroyWindow(window_);
  if (--live_windows == 0) glfwTerminate();
}

std::uint64_t GlWindow::current_context_id() {
  const auto it = window_ids.find(glfwGetCurrentContext());
  return it == window_ids.end() ? 0 : it->second;
}

std::string GlWindow::renderer() const {
  const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  return renderer ? renderer : "unknown";
}

}  // namespace ls::viewer
