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

 protected:
  std::string description_;
};

// Creates the context, makes it current on this thread and loads the GL entry points.
// Returns nullptr with a message naming what failed.
std::unique_ptr<GlContext> createContext(ContextKind kind, int width_px, int height_px, std::string& error);

}  // namespace ig::render
