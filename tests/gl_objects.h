// GL object names alive in the current context, for tests that check a subsystem the scene does
// not use creates nothing (the test links EGL for eglGetProcAddress).
#pragma once

#include <EGL/egl.h>
#include <GL/glcorearb.h>

#include <gtest/gtest.h>

namespace ig::test {

// How many of the names 1 ... upTo `isFunction` ("glIsTexture", "glIsBuffer", ...) says exist.
inline int liveGlObjects(const char* isFunction, GLuint upTo) {
  using IsObject = GLboolean (*)(GLuint);
  const auto isObject = reinterpret_cast<IsObject>(eglGetProcAddress(isFunction));
  EXPECT_NE(isObject, nullptr) << isFunction;
  if (isObject == nullptr) return -1;
  int n = 0;
  for (GLuint id = 1; id <= upTo; ++id) n += isObject(id) ? 1 : 0;
  return n;
}

}  // namespace ig::test
