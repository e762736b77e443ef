// Where the GL 4.5 core context comes from. The renderer always draws into its own FBO; the
// context only decides what happens to the finished frame:
//   Headless - EGL on Mesa's surfaceless platform, falling back to EGL_EXT_platform_device.
//              No display, no window, no environment variables. Frames are read back.
//   Window   - GLFW window with the EGL context API (needs an X server, e.g. Xvfb); the FBO
//              is blitted to the window and swapped.
//   OSMesa   - Mesa's off-screen library, the last-resort fallback where EGL is unusable.
#pragma once

#include <memory>
#include <string>

namespace ig::render {

enum class ContextKind { Headless, Window, OSMesa };

// Where a Window context's window goes (ignored by the other kinds). Cabin displays: one igd per
// display, each full screen on its own monitor.
struct WindowOptions {
  // Full screen on `monitor` at that monitor's current video mode (no mode switch, no
  // decorations, cursor hidden): the rendered image is scaled to the monitor's size. false: a
  // window of the rendered size, placed at the monitor's top-left corner.
  bool fullscreen = false;
  // Index into the X server's monitors (GLFW's order: the primary monitor first). A monitor the
  // server does not have is an error that names how many it has.
  int monitor = 0;
};

class GlContext {
 public:
  virtual ~GlContext() = default;
  // e.g. "EGL surfaceless: 4.5 (Core Profile) Mesa 22.3.6, llvmpipe (LLVM 15.0.6, 256 bits)"
  const std::string& description() const { return description_; }
  virtual bool hasWindow() const { return false; }
  // Shows the colour attachment of `fbo` (window contexts); no-op when headless.
  virtual void present(unsigned fbo, int width_px, int height_px) { (void)fbo, (void)width_px, (void)height_px; }
  // True once the user closed the window.
  virtual bool closeRequested() const { return false; }
  // The window's framebuffer size in pixels (what present() scales the frame to); 0 x 0 without
  // a window.
  virtual void windowSize(int& width_px, int& height_px) const { width_px = height_px = 0; }
  // Makes this context current on the calling thread (nothing when it already is). A process
  // with several contexts (tests, benchmarks running two services side by side) must call it
  // before GL work: the GL calls of a service whose context is not current land in another
  // context, on that context's objects of the same names. false (with `error` naming the call
  // and its error, e.g. the context is current on another thread): no GL work may follow.
  virtual bool makeCurrent(std::string& error) = 0;

 protected:
  std::string description_;
};

// Creates the context, makes it current on this thread and loads the GL entry points.
// Returns nullptr with a message naming what failed.
std::unique_ptr<GlContext> createContext(ContextKind kind, int width_px, int height_px, std::string& error,
                                         const WindowOptions& window = {});

}  // namespace ig::render
