#include "render/gl.h"

#include <cstdio>

namespace ig::render {

GlApi gl;

bool loadGl(GlGetProc getProc, std::string& error) {
  GlApi api;
  std::string missing;
#define IG_GL_LOAD(type, name)                                       \
  api.name = reinterpret_cast<type>(getProc("gl" #name));           \
  if (api.name == nullptr) missing += (missing.empty() ? "gl" : ", gl") + std::string(#name);
  IG_GL_FUNCTIONS(IG_GL_LOAD)
#undef IG_GL_LOAD
  if (!missing.empty()) {
    error = "OpenGL 4.5 entry points missing: " + missing;
    return false;
  }
  gl = api;
  return true;
}

std::string glErrors() {
  std::string s;
  for (int i = 0; i < 16; ++i) {
    const GLenum e = gl.GetError();
    if (e == GL_NO_ERROR) break;
    char buf[32];
    std::snprintf(buf, sizeof buf, "%s0x%04x", s.empty() ? "" : " ", e);
    s += buf;
  }
  return s;
}

void deleteGlObject(GlKind kind, GLuint id) {
  switch (kind) {
    case GlKind::Buffer: gl.DeleteBuffers(1, &id); break;
    case GlKind::VertexArray: gl.DeleteVertexArrays(1, &id); break;
    case GlKind::Program: gl.DeleteProgram(id); break;
    case GlKind::Framebuffer: gl.DeleteFramebuffers(1, &id); break;
    case GlKind::Renderbuffer: gl.DeleteRenderbuffers(1, &id); break;
  }
}

namespace {
GLuint compile(GLenum stage, const char* source, std::string& error) {
  const GLuint s = gl.CreateShader(stage);
  gl.ShaderSource(s, 1, &source, nullptr);
  gl.CompileShader(s);
  GLint ok = 0;
  gl.GetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[4096];
    gl.GetShaderInfoLog(s, sizeof log, nullptr, log);
    error = std::string(stage == GL_VERTEX_SHADER ? "vertex" : "fragment") + " shader: " + log;
    gl.DeleteShader(s);
    return 0;
  }
  return s;
}
}  // namespace

GlProgram buildProgram(const char* vertexSource, const char* fragmentSource, std::string& error) {
  const GLuint vs = compile(GL_VERTEX_SHADER, vertexSource, error);
  if (!vs) return {};
  const GLuint fs = compile(GL_FRAGMENT_SHADER, fragmentSource, error);
  if (!fs) {
    gl.DeleteShader(vs);
    return {};
  }
  GlProgram program = GlProgram::wrap(gl.CreateProgram());
  gl.AttachShader(program.id(), vs);
  gl.AttachShader(program.id(), fs);
  gl.LinkProgram(program.id());
  gl.DeleteShader(vs);
  gl.DeleteShader(fs);
  GLint ok = 0;
  gl.GetProgramiv(program.id(), GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[4096];
    gl.GetProgramInfoLog(program.id(), sizeof log, nullptr, log);
    error = std::string("program link: ") + log;
    return {};
  }
  return program;
}

}  // namespace ig::render
