// A headless GL 4.5 context (EGL surfaceless on Mesa) with a Renderer of the given size, for the
// pass tests (*_gltest). Failures are test failures naming the reason.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "render/context.h"
#include "render/renderer.h"

namespace ig::test {

struct HeadlessGl {
  std::unique_ptr<render::GlContext> context;
  render::Renderer renderer;
  // `samples` > 1: an MSAA frame (render::Renderer::init).
  HeadlessGl(int width_px, int height_px, int samples = 1) {
    std::string error;
    context = render::createContext(render::ContextKind::Headless, width_px, height_px, error);
    EXPECT_TRUE(context) << error;
    EXPECT_TRUE(renderer.init(width_px, height_px, error, samples)) << error;
  }
};

}  // namespace ig::test
