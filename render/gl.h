// OpenGL 4.5 core entry points, loaded at run time from whichever context API created the
// context (EGL, GLFW or OSMesa), so the same renderer runs on all three. Plus move-only RAII
// handles for GL objects. Only render/ includes this file.
#pragma once

#include <GL/glcorearb.h>

#include <string>
#include <utility>

namespace ig::render {

// glcorearb.h of this Mesa version has no pointer types for glDrawArrays and glDeleteTextures.
using PFNIGDRAWARRAYSPROC = void(APIENTRYP)(GLenum mode, GLint first, GLsizei count);
using PFNIGDELETETEXTURESPROC = void(APIENTRYP)(GLsizei n, const GLuint* textures);

// X-macro list: (pointer type, name without the "gl" prefix).
#define IG_GL_FUNCTIONS(X)                                                                            \
  X(PFNGLGETSTRINGPROC, GetString)                                                                    \
  X(PFNGLGETERRORPROC, GetError)                                                                      \
  X(PFNGLGETINTEGERVPROC, GetIntegerv)                                                                \
  X(PFNGLENABLEPROC, Enable)                                                                          \
  X(PFNGLDISABLEPROC, Disable)                                                                        \
  X(PFNGLVIEWPORTPROC, Viewport)                                                                      \
  X(PFNGLDEPTHFUNCPROC, DepthFunc)                                                                    \
  X(PFNGLDEPTHMASKPROC, DepthMask)                                                                    \
  X(PFNGLCLIPCONTROLPROC, ClipControl)                                                                \
  X(PFNGLCULLFACEPROC, CullFace)                                                                      \
  X(PFNGLFRONTFACEPROC, FrontFace)                                                                    \
  X(PFNGLFINISHPROC, Finish)                                                                          \
  X(PFNGLREADPIXELSPROC, ReadPixels)                                                                  \
  X(PFNGLPIXELSTOREIPROC, PixelStorei)                                                                \
  X(PFNGLCREATEBUFFERSPROC, CreateBuffers)                                                            \
  X(PFNGLDELETEBUFFERSPROC, DeleteBuffers)                                                            \
  X(PFNGLNAMEDBUFFERSTORAGEPROC, NamedBufferStorage)                                                  \
  X(PFNGLCREATEVERTEXARRAYSPROC, CreateVertexArrays)                                                  \
  X(PFNGLDELETEVERTEXARRAYSPROC, DeleteVertexArrays)                                                  \
  X(PFNGLBINDVERTEXARRAYPROC, BindVertexArray)                                                        \
  X(PFNGLVERTEXARRAYVERTEXBUFFERPROC, VertexArrayVertexBuffer)                                        \
  X(PFNGLVERTEXARRAYELEMENTBUFFERPROC, VertexArrayElementBuffer)                                      \
  X(PFNGLENABLEVERTEXARRAYATTRIBPROC, EnableVertexArrayAttrib)                                        \
  X(PFNGLVERTEXARRAYATTRIBFORMATPROC, VertexArrayAttribFormat)                                        \
  X(PFNGLVERTEXARRAYATTRIBBINDINGPROC, VertexArrayAttribBinding)                                      \
  X(PFNGLCREATESHADERPROC, CreateShader)                                                              \
  X(PFNGLSHADERSOURCEPROC, ShaderSource)                                                              \
  X(PFNGLCOMPILESHADERPROC, CompileShader)                                                            \
  X(PFNGLGETSHADERIVPROC, GetShaderiv)                                                                \
  X(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog)                                                      \
  X(PFNGLDELETESHADERPROC, DeleteShader)                                                              \
  X(PFNGLCREATEPROGRAMPROC, CreateProgram)                                                            \
  X(PFNGLATTACHSHADERPROC, AttachShader)                                                              \
  X(PFNGLLINKPROGRAMPROC, LinkProgram)                                                                \
  X(PFNGLGETPROGRAMIVPROC, GetProgramiv)                                                              \
  X(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog)                                                    \
  X(PFNGLDELETEPROGRAMPROC, DeleteProgram)                                                            \
  X(PFNGLUSEPROGRAMPROC, UseProgram)                                                                  \
  X(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation)                                                  \
  X(PFNGLPROGRAMUNIFORMMATRIX4FVPROC, ProgramUniformMatrix4fv)                                        \
  X(PFNGLPROGRAMUNIFORM2FVPROC, ProgramUniform2fv)                                                    \
  X(PFNGLPROGRAMUNIFORM3FVPROC, ProgramUniform3fv)                                                    \
  X(PFNGLPROGRAMUNIFORM1FPROC, ProgramUniform1f)                                                      \
  X(PFNGLCREATEFRAMEBUFFERSPROC, CreateFramebuffers)                                                  \
  X(PFNGLDELETEFRAMEBUFFERSPROC, DeleteFramebuffers)                                                  \
  X(PFNGLBINDFRAMEBUFFERPROC, BindFramebuffer)                                                        \
  X(PFNGLNAMEDFRAMEBUFFERRENDERBUFFERPROC, NamedFramebufferRenderbuffer)                              \
  X(PFNGLCHECKNAMEDFRAMEBUFFERSTATUSPROC, CheckNamedFramebufferStatus)                                \
  X(PFNGLNAMEDFRAMEBUFFERREADBUFFERPROC, NamedFramebufferReadBuffer)                                  \
  X(PFNGLCLEARNAMEDFRAMEBUFFERFVPROC, ClearNamedFramebufferfv)                                        \
  X(PFNGLCREATERENDERBUFFERSPROC, CreateRenderbuffers)                                                \
  X(PFNGLDELETERENDERBUFFERSPROC, DeleteRenderbuffers)                                                \
  X(PFNGLNAMEDRENDERBUFFERSTORAGEPROC, NamedRenderbufferStorage)                                      \
  X(PFNGLNAMEDRENDERBUFFERSTORAGEMULTISAMPLEPROC, NamedRenderbufferStorageMultisample)                \
  X(PFNGLBLITNAMEDFRAMEBUFFERPROC, BlitNamedFramebuffer)                                              \
  X(PFNGLDRAWELEMENTSBASEVERTEXPROC, DrawElementsBaseVertex)                                          \
  X(PFNIGDRAWARRAYSPROC, DrawArrays)                                                                    \
  X(PFNGLNAMEDBUFFERSUBDATAPROC, NamedBufferSubData)                                                  \
  X(PFNGLMAPNAMEDBUFFERRANGEPROC, MapNamedBufferRange)                                               \
  X(PFNGLMULTIDRAWELEMENTSINDIRECTPROC, MultiDrawElementsIndirect)                                   \
  X(PFNGLDRAWELEMENTSINSTANCEDBASEINSTANCEPROC, DrawElementsInstancedBaseInstance)                   \
  X(PFNGLVERTEXARRAYBINDINGDIVISORPROC, VertexArrayBindingDivisor)                                   \
  X(PFNGLBINDBUFFERPROC, BindBuffer)                                                                 \
  X(PFNGLCREATEQUERIESPROC, CreateQueries)                                                           \
  X(PFNGLDELETEQUERIESPROC, DeleteQueries)                                                           \
  X(PFNGLBEGINQUERYPROC, BeginQuery)                                                                 \
  X(PFNGLENDQUERYPROC, EndQuery)                                                                     \
  X(PFNGLGETQUERYOBJECTUIVPROC, GetQueryObjectuiv)                                                   \
  X(PFNGLCOLORMASKPROC, ColorMask)                                                                   \
  X(PFNGLPROGRAMUNIFORM1IPROC, ProgramUniform1i)                                                     \
  X(PFNGLBLENDFUNCSEPARATEPROC, BlendFuncSeparate)                                                   \
  X(PFNGLMULTIDRAWARRAYSPROC, MultiDrawArrays)                                                       \
  X(PFNGLDRAWARRAYSINSTANCEDPROC, DrawArraysInstanced)                                               \
  X(PFNGLDRAWELEMENTSINSTANCEDBASEVERTEXBASEINSTANCEPROC, DrawElementsInstancedBaseVertexBaseInstance) \
  X(PFNGLPROGRAMUNIFORM4FVPROC, ProgramUniform4fv)                                                   \
  X(PFNGLCREATETEXTURESPROC, CreateTextures)                                                         \
  X(PFNIGDELETETEXTURESPROC, DeleteTextures)                                                         \
  X(PFNGLTEXTURESTORAGE2DPROC, TextureStorage2D)                                                     \
  X(PFNGLTEXTURESTORAGE3DPROC, TextureStorage3D)                                                     \
  X(PFNGLTEXTURESUBIMAGE2DPROC, TextureSubImage2D)                                                   \
  X(PFNGLTEXTURESUBIMAGE3DPROC, TextureSubImage3D)                                                   \
  X(PFNGLTEXTUREPARAMETERIPROC, TextureParameteri)                                                   \
  X(PFNGLGENERATETEXTUREMIPMAPPROC, GenerateTextureMipmap)                                           \
  X(PFNGLBINDTEXTUREUNITPROC, BindTextureUnit)                                                       \
  X(PFNGLVERTEXARRAYATTRIBIFORMATPROC, VertexArrayAttribIFormat)                                     \
  X(PFNGLGETBOOLEANVPROC, GetBooleanv)                                                               \
  X(PFNGLBINDBUFFERBASEPROC, BindBufferBase)

struct GlApi {
#define IG_GL_DECLARE(type, name) type name = nullptr;
  IG_GL_FUNCTIONS(IG_GL_DECLARE)
#undef IG_GL_DECLARE
};

// The process-wide table; filled by loadGl() once a context is current.
extern GlApi gl;

using GlGetProc = void* (*)(const char* name);
// Loads every entry point. Returns false and names the missing ones in `error`.
bool loadGl(GlGetProc getProc, std::string& error);
// Returns "" or a description of the pending GL errors (drains the error queue).
std::string glErrors();

enum class GlKind { Buffer, VertexArray, Program, Framebuffer, Renderbuffer };
void deleteGlObject(GlKind kind, GLuint id);

// Move-only owner of one GL object name. Default-constructed = no object (usable before a
// context exists); wrap() adopts a name, release() gives it up without deleting.
template <GlKind K>
class GlObject {
 public:
  GlObject() = default;
  static GlObject wrap(GLuint id) {
    GlObject o;
    o.id_ = id;
    return o;
  }
  GlObject(const GlObject&) = delete;
  GlObject& operator=(const GlObject&) = delete;
  GlObject(GlObject&& o) noexcept : id_(std::exchange(o.id_, 0)) {}
  GlObject& operator=(GlObject&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = std::exchange(o.id_, 0);
    }
    return *this;
  }
  ~GlObject() { reset(); }
  GLuint id() const { return id_; }
  explicit operator bool() const { return id_ != 0; }
  GLuint release() { return std::exchange(id_, 0); }
  void reset() {
    if (id_ != 0) deleteGlObject(K, std::exchange(id_, 0));
  }

 private:
  GLuint id_ = 0;
};

using GlBuffer = GlObject<GlKind::Buffer>;
using GlVertexArray = GlObject<GlKind::VertexArray>;
using GlProgram = GlObject<GlKind::Program>;
using GlFramebuffer = GlObject<GlKind::Framebuffer>;
using GlRenderbuffer = GlObject<GlKind::Renderbuffer>;

// Compiles and links a vertex + fragment program. Returns an empty handle and the info log
// in `error` on failure.
GlProgram buildProgram(const char* vertexSource, const char* fragmentSource, std::string& error);

}  // namespace ig::render
