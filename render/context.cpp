#include "render/context.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/osmesa.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <cstdio>
#include <map>
#include <mutex>
#include <vector>

#include "render/gl.h"

namespace ig::render {
namespace {

std::string eglErrorText(const char* what) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s failed (EGL error 0x%04x)", what, eglGetError());
  return buf;
}

void* eglProc(const char* name) { return reinterpret_cast<void*>(eglGetProcAddress(name)); }
void* osmesaProc(const char* name) { return reinterpret_cast<void*>(OSMesaGetProcAddress(name)); }
void* glfwProc(const char* name) { return reinterpret_cast<void*>(glfwGetProcAddress(name)); }

std::string glDescription() {
  return std::string(reinterpret_cast<const char*>(gl.GetString(GL_VERSION))) + ", " +
         reinterpret_cast<const char*>(gl.GetString(GL_RENDERER));
}

// EGL displays are per process: every surfaceless context of the process gets the same
// EGLDisplay, and eglInitialize / eglTerminate do not count. The display is initialised with the
// first context made on it and terminated with the last one that goes: terminating it with the
// first released every other context on it (their GL calls then did nothing: black frames, no
// GL error).
// (Never destroyed: a context held in a static object may go after this file's statics.)
struct DisplayUsers {
  std::mutex mutex;
  std::map<EGLDisplay, int> count;
};
DisplayUsers& displayUsers() {
  static auto* users = new DisplayUsers;
  return *users;
}

bool acquireDisplay(EGLDisplay display) {
  DisplayUsers& d = displayUsers();
  std::lock_guard<std::mutex> lock(d.mutex);
  int& users = d.count[display];
  if (users == 0) {
    EGLint major = 0, minor = 0;
    if (!eglInitialize(display, &major, &minor)) {
      d.count.erase(display);
      return false;
    }
  }
  ++users;
  return true;
}

void releaseDisplay(EGLDisplay display) {
  DisplayUsers& d = displayUsers();
  std::lock_guard<std::mutex> lock(d.mutex);
  const auto it = d.count.find(display);
  if (it != d.count.end() && --it->second > 0) return;
  if (it != d.count.end()) d.count.erase(it);
  eglTerminate(display);
}

class EglHeadlessContext final : public GlContext {
 public:
  bool makeCurrent(std::string& error) override {
    if (eglGetCurrentContext() == context_) return true;
    if (eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_)) return true;
    error = eglErrorText("eglMakeCurrent");
    return false;
  }
  ~EglHeadlessContext() override {
    if (display_ != EGL_NO_DISPLAY) {
      // Only this context is released: the thread may have a later one current.
      if (eglGetCurrentContext() == context_) eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      if (context_ != EGL_NO_CONTEXT) eglDestroyContext(display_, context_);
      releaseDisplay(display_);
    }
  }

  bool init(std::string& error) {
    auto getPlatformDisplay =
        reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
    if (!getPlatformDisplay) {
      error = "EGL: eglGetPlatformDisplayEXT not available";
      return false;
    }
    std::string surfacelessError;
    if (tryDisplay(getPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr),
                   "EGL surfaceless", surfacelessError))
      return true;
    // Fallback: the first EGL device that gives a GL 4.5 core context.
    auto queryDevices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    std::string deviceError = "EGL_EXT_device_enumeration not available";
    if (queryDevices) {
      EGLDeviceEXT devices[8];
      EGLint count = 0;
      queryDevices(8, devices, &count);
      for (EGLint i = 0; i < count; ++i) {
        if (tryDisplay(getPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr),
                       "EGL device " + std::to_string(i), deviceError))
          return true;
      }
      if (count == 0) deviceError = "no EGL devices";
    }
    error = "headless EGL: surfaceless: " + surfacelessError + "; device: " + deviceError;
    return false;
  }

 private:
  bool tryDisplay(EGLDisplay display, const std::string& label, std::string& error) {
    if (display == EGL_NO_DISPLAY) {
      error = eglErrorText("eglGetPlatformDisplay");
      return false;
    }
    if (!acquireDisplay(display)) {
      error = eglErrorText("eglInitialize");
      return false;
    }
    if (!eglBindAPI(EGL_OPENGL_API)) {
      error = eglErrorText("eglBindAPI(EGL_OPENGL_API)");
      releaseDisplay(display);
      return false;
    }
    const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                              EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    EGLContext context = eglCreateContext(display, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attribs);
    if (context == EGL_NO_CONTEXT) {
      error = eglErrorText("eglCreateContext(GL 4.5 core)");
      releaseDisplay(display);
      return false;
    }
    if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
      error = eglErrorText("eglMakeCurrent(no surface)");
      eglDestroyContext(display, context);
      releaseDisplay(display);
      return false;
    }
    if (!loadGl(eglProc, error)) {
      eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      eglDestroyContext(display, context);
      releaseDisplay(display);
      return false;
    }
    display_ = display;
    context_ = context;
    description_ = label + ": " + glDescription();
    return true;
  }

  EGLDisplay display_ = EGL_NO_DISPLAY;
  EGLContext context_ = EGL_NO_CONTEXT;
};

class OSMesaHeadlessContext final : public GlContext {
 public:
  bool makeCurrent(std::string& error) override {
    if (OSMesaGetCurrentContext() == context_) return true;
    if (OSMesaMakeCurrent(context_, buffer_.data(), GL_UNSIGNED_BYTE, 4, 4)) return true;
    error = "OSMesa: OSMesaMakeCurrent failed";
    return false;
  }
  ~OSMesaHeadlessContext() override {
    if (context_) OSMesaDestroyContext(context_);
  }
  bool init(std::string& error) {
    const int attribs[] = {OSMESA_FORMAT, OSMESA_RGBA, OSMESA_DEPTH_BITS, 0, OSMESA_PROFILE,
                           OSMESA_CORE_PROFILE, OSMESA_CONTEXT_MAJOR_VERSION, 4,
                           OSMESA_CONTEXT_MINOR_VERSION, 5, 0};
    context_ = OSMesaCreateContextAttribs(attribs, nullptr);
    if (!context_) {
      error = "OSMesa: OSMesaCreateContextAttribs(GL 4.5 core) failed";
      return false;
    }
    // The renderer draws into its own FBO; OSMesa only needs a tiny default buffer.
    if (!OSMesaMakeCurrent(context_, buffer_.data(), GL_UNSIGNED_BYTE, 4, 4)) {
      error = "OSMesa: OSMesaMakeCurrent failed";
      return false;
    }
    if (!loadGl(osmesaProc, error)) return false;
    description_ = "OSMesa: " + glDescription();
    return true;
  }

 private:
  OSMesaContext context_ = nullptr;
  std::vector<unsigned char> buffer_ = std::vector<unsigned char>(4 * 4 * 4);
};

// GLFW is initialised once per process, and glfwTerminate() destroys every window and context
// it made: like the EGL display above, it is initialised with the first window context and
// terminated with the last one that goes. Terminating it with the first destroyed the windows
// and contexts of the others (their GL calls then did nothing: black frames, no GL error).
// (Never destroyed, as displayUsers().)
struct GlfwUsers {
  std::mutex mutex;
  int count = 0;
};
GlfwUsers& glfwUsers() {
  static auto* users = new GlfwUsers;
  return *users;
}

bool acquireGlfw() {
  GlfwUsers& g = glfwUsers();
  std::lock_guard<std::mutex> lock(g.mutex);
  if (g.count == 0) {
    glfwSetErrorCallback([](int code, const char* text) { std::fprintf(stderr, "glfw: error %d: %s\n", code, text); });
    if (!glfwInit()) return false;
  }
  ++g.count;
  return true;
}

void releaseGlfw() {
  GlfwUsers& g = glfwUsers();
  std::lock_guard<std::mutex> lock(g.mutex);
  if (g.count > 0 && --g.count == 0) glfwTerminate();
}

class GlfwWindowContext final : public GlContext {
 public:
  bool makeCurrent(std::string& error) override {
    if (!window_) {
      error = "window: no window to make current";
      return false;
    }
    if (glfwGetCurrentContext() != window_) glfwMakeContextCurrent(window_);
    if (glfwGetCurrentContext() == window_) return true;
    error = "window: glfwMakeContextCurrent failed";
    return false;
  }
  ~GlfwWindowContext() override {
    if (window_) glfwDestroyWindow(window_);
    if (initialised_) releaseGlfw();
  }
  bool init(int width_px, int height_px, const WindowOptions& options, std::string& error) {
    if (!acquireGlfw()) {
      error = "window: glfwInit failed (no X display? set DISPLAY or run under Xvfb)";
      return false;
    }
    initialised_ = true;
    int monitors = 0;
    GLFWmonitor** list = glfwGetMonitors(&monitors);
    if (options.monitor < 0 || options.monitor >= monitors || list == nullptr) {
      error = "window: output.monitor = " + std::to_string(options.monitor) + ", but the X server has " +
              std::to_string(monitors) + " monitor" + (monitors == 1 ? "" : "s") +
              (monitors > 0 ? " (0 ..= " + std::to_string(monitors - 1) + ")" : "");
      return false;
    }
    GLFWmonitor* monitor = list[options.monitor];
    glfwDefaultWindowHints();  // hints are global: nothing of an earlier window's carries over
    const GLFWvidmode* mode = glfwGetVideoMode(monitor);
    if (mode == nullptr) {
      error = "window: monitor " + std::to_string(options.monitor) + " reports no video mode";
      return false;
    }
    glfwWindowHint(GLFW_CONTEXT_CREATION_API, GLFW_EGL_CONTEXT_API);
    glfwWindowHint(GLFW_CLIENT_API, GLFW_OPENGL_API);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
    std::string where;
    if (options.fullscreen) {
      // The monitor's own mode: no mode switch (a cabin display keeps its timing).
      glfwWindowHint(GLFW_RED_BITS, mode->redBits);
      glfwWindowHint(GLFW_GREEN_BITS, mode->greenBits);
      glfwWindowHint(GLFW_BLUE_BITS, mode->blueBits);
      glfwWindowHint(GLFW_REFRESH_RATE, mode->refreshRate);
      window_ = glfwCreateWindow(mode->width, mode->height, "igd", monitor, nullptr);
      where = "full screen " + std::to_string(mode->width) + "x" + std::to_string(mode->height) + " on monitor " +
              std::to_string(options.monitor);
    } else {
      window_ = glfwCreateWindow(width_px, height_px, "igd", nullptr, nullptr);
      int x = 0, y = 0;
      glfwGetMonitorPos(monitor, &x, &y);
      if (window_) glfwSetWindowPos(window_, x, y);
      where = std::to_string(width_px) + "x" + std::to_string(height_px) + " on monitor " +
              std::to_string(options.monitor);
    }
    const char* name = glfwGetMonitorName(monitor);
    if (name != nullptr) where += std::string(" (") + name + ")";
    if (!window_) {
      error = "window: glfwCreateWindow(" + where + ", GL 4.5 core via EGL) failed";
      return false;
    }
    if (options.fullscreen) glfwSetInputMode(window_, GLFW_CURSOR, GLFW_CURSOR_HIDDEN);
    glfwMakeContextCurrent(window_);
    glfwSwapInterval(0);  // the frame loop paces itself with absolute deadlines
    if (!loadGl(glfwProc, error)) return false;
    description_ = "GLFW window " + where + " (EGL): " + glDescription();
    return true;
  }
  bool hasWindow() const override { return true; }
  void present(unsigned fbo, int width_px, int height_px) override {
    int w = 0, h = 0;
    glfwGetFramebufferSize(window_, &w, &h);
    gl.BlitNamedFramebuffer(fbo, 0, 0, 0, width_px, height_px, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_LINEAR);
    glfwSwapBuffers(window_);
    glfwPollEvents();
  }
  bool closeRequested() const override { return glfwWindowShouldClose(window_) != 0; }
  void windowSize(int& width_px, int& height_px) const override { glfwGetFramebufferSize(window_, &width_px, &height_px); }

 private:
  bool initialised_ = false;
  GLFWwindow* window_ = nullptr;
};

}  // namespace

std::unique_ptr<GlContext> createContext(ContextKind kind, int width_px, int height_px, std::string& error,
                                         const WindowOptions& window) {
  switch (kind) {
    case ContextKind::Headless: {
      auto c = std::make_unique<EglHeadlessContext>();
      if (c->init(error)) return c;
      return nullptr;
    }
    case ContextKind::OSMesa: {
      auto c = std::make_unique<OSMesaHeadlessContext>();
      if (c->init(error)) return c;
      return nullptr;
    }
    case ContextKind::Window: {
      auto c = std::make_unique<GlfwWindowContext>();
      if (c->init(width_px, height_px, window, error)) return c;
      return nullptr;
    }
  }
  error = "unknown context kind";
  return nullptr;
}

}  // namespace ig::render
