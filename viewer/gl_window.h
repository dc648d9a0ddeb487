#pragma once
// A GLFW window with a current OpenGL 3.3 core context. Hidden windows serve offscreen work (tests,
// benchmarks, screenshots); under `xvfb-run -a -s "-screen 0 1280x720x24"` they run on llvmpipe.
#include <cstdint>
#include <string>

struct GLFWwindow;

namespace ls::viewer {

class GlWindow {
 public:
  // Throws ls::HardwareError when there is no display ("no display: glfwInit failed (...); run
  // under xvfb-run -a, or set DISPLAY") or no OpenGL 3.3 core context. Makes the context current.
  GlWindow(int width, int height, const std::string& title, bool visible);
  ~GlWindow();
  GlWindow(const GlWindow&) = delete;
  GlWindow& operator=(const GlWindow&) = delete;

  GLFWwindow* handle() const { return window_; }
  std::string renderer() const;  // GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".

  // A number for the current thread's context that no other window has had in this process (0:
  // no GlWindow's context is current). For caches of GL objects: a new window may get a destroyed
  // one's GLFWwindow address, but never its id.
  static std::uint64_t current_context_id();

 private:
  GLFWwindow* window_ = nullptr;
};

}  // namespace ls::viewer
