#include "render/renderer.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

#include <glm/gtc/type_ptr.hpp>
#include <glm/mat4x4.hpp>

#include "lod/sun.h"
#include "render/gl.h"
#include "render/split_offset.h"

namespace ig::render {
namespace {

const char* kTerrainVs = R"(#version 450 core
layout(location = 0) in vec3 aPosition;   // metres, relative to the chunk origin
layout(location = 1) in vec3 aNormal;
uniform mat4 uViewProjection;             // projection * world->camera rotation (no translation)
uniform vec3 uChunkOffset;                // chunk origin - eye, computed in double on the CPU, as float
uniform vec3 uChunkOffsetLow;             // the part of it the float left out (origin - eye - uChunkOffset)
out vec3 vEyeToPoint;
out vec3 vNormal;
out vec3 vLocal;
void main() {
  // Near the eye aPosition and uChunkOffset nearly cancel, so their sum is exact, and the low part
  // adds back what rounding the offset to float lost: a mesh whose vertices lie 100 km from its
  // origin (a DEM tile) is placed to the same fraction of a millimetre as one at its origin.
  precise vec3 rel = (aPosition + uChunkOffset) + uChunkOffsetLow;
  vEyeToPoint = rel;
  vNormal = aNormal;
  vLocal = aPosition;
  gl_Position = uViewProjection * vec4(rel, 1.0);
}
)";

// Compiled three times (detailLevel()): TERRAIN_DETAIL 2 with both noises for ground within
// kTerrainFineDetailReach_m, 1 with the 2 m noise only within kTerrainDetailReach_m, 0 beyond.
const char* kTerrainFs = R"(#version 450 core
in vec3 vEyeToPoint;
in vec3 vNormal;
in vec3 vLocal;                          // position relative to the chunk (or mesh) origin
uniform vec3 uSunDirection;
uniform vec3 uSunColor;
uniform float uAmbient;
uniform vec3 uFogColor;
uniform float uFogDensity;               // per metre; 0 = no fog
uniform float uHeightScale;
uniform float uHeightBase;               // height (relative to the origin) at the bottom of the relief
out vec4 fragColor;
uniform vec2 uDetailPhase;               // eye position mod 1024 m (computed in double)
float hash(vec2 p) { return fract(sin(dot(p, vec2(127.1, 311.7))) * 43758.5453); }
// Value noise with integer period `period` (cells), so the pattern tiles the world every
// 1024 m and stays seamless across chunk borders.
float noise(vec2 p, float period) {
  vec2 i = floor(p), f = fract(p);
  f = f * f * (3.0 - 2.0 * f);
  vec2 i0 = mod(i, period), i1 = mod(i + 1.0, period);
  return mix(mix(hash(i0), hash(vec2(i1.x, i0.y)), f.x), mix(hash(vec2(i0.x, i1.y)), hash(i1), f.x), f.y);
}
void main() {
  vec3 n = normalize(vNormal);
  float slope = 1.0 - n.z;
  float h = (vLocal.z - uHeightBase) / max(uHeightScale, 1.0);
  // Ground detail for low-level flight: 0.25 m and 2 m value noise, faded out with distance
  // before it would alias (0 from 40 m and from 400 m: kTerrainFineDetailReach_m,
  // kTerrainDetailReach_m). Each program variant has only the terms that are not 0 where it
  // draws: llvmpipe runs both sides of a branch, and the noise is a third of a frame.
  float dist = length(vEyeToPoint);
#if TERRAIN_DETAIL >= 1
  // World position mod 1024 m from the eye-relative one: precise where the noise shows (within
  // 400 m of the eye) however far the point lies from its chunk or mesh origin.
  vec2 q = vEyeToPoint.xy + uDetailPhase;
  float detail = (noise(q * 0.5, 512.0) - 0.5) * (1.0 - smoothstep(60.0, 400.0, dist));
#if TERRAIN_DETAIL >= 2
  detail = (noise(q * 4.0, 4096.0) - 0.5) * (1.0 - smoothstep(5.0, 40.0, dist)) + detail;
#endif
#else
  float detail = 0.0;
#endif
  vec3 grass = vec3(0.28, 0.40, 0.17);
  vec3 rock = vec3(0.46, 0.42, 0.37);
  vec3 snow = vec3(0.92, 0.93, 0.95);
  vec3 albedo = mix(grass, rock, smoothstep(0.12, 0.35, slope + 0.25 * h));
  albedo = mix(albedo, snow, smoothstep(0.78, 0.86, h) * (1.0 - smoothstep(0.35, 0.55, slope)));
  albedo *= 1.0 + 0.35 * detail;
  float diffuse = max(dot(n, uSunDirection), 0.0);
  vec3 lit = albedo * (uAmbient + (1.0 - uAmbient) * diffuse * uSunColor);
  float fog = exp(-uFogDensity * dist);
  fragColor = vec4(mix(uFogColor, lit, fog), 1.0);
}
)";

glm::vec3 toFloat(const glm::dvec3& v) { return glm::vec3(v); }

// The fragment shader with `#define NAME value` after its #version line.
std::string withDefine(const char* source, const char* name, int value) {
  std::string s(source);
  const size_t line = s.find('\n') + 1;
  return s.insert(line, std::string("#define ") + name + " " + std::to_string(value) + "\n");
}

// The terrain program variant for ground at least `nearest_m` from the eye: 0 beyond both noise
// terms' reach, 1 beyond the fine term's, else 2.
int detailLevel(double nearest_m) {
  return nearest_m >= kTerrainDetailReach_m ? 0 : nearest_m >= kTerrainFineDetailReach_m ? 1 : 2;
}

}  // namespace

struct Renderer::Target {
  GlFramebuffer fbo;  // drawn into (multisampled with MSAA)
  GlRenderbuffer color;
  GlRenderbuffer depth;
  GlFramebuffer resolvedFbo;  // MSAA only: the single-sample image
  GlRenderbuffer resolvedColor;
};

namespace {

bool completeFramebuffer(GLuint fbo, int width_px, int height_px, std::string& error) {
  const GLenum status = gl.CheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER);
  if (status == GL_FRAMEBUFFER_COMPLETE) return true;
  char code[16];
  std::snprintf(code, sizeof code, "0x%04x", status);
  error = "framebuffer " + std::to_string(width_px) + "x" + std::to_string(height_px) + " incomplete (status " + code + ")";
  // The GL errors of the failed set-up (a size beyond GL_MAX_RENDERBUFFER_SIZE: GL_INVALID_VALUE)
  // belong to this failure. Left queued, they failed the next init (or pass set-up) that checks
  // for errors, with a message about something else.
  if (const std::string e = glErrors(); !e.empty()) error += ", GL errors " + e;
  return false;
}

}  // namespace

// Draws terrain with the terrain program: either a static chunked grid (uploaded once), or a
// dynamic triangle list re-uploaded each frame (ROAM / block LOD output), or both.
class TerrainPass {
 public:
  bool initProgram(double heightScale_m, double heightBase_m, std::string& error) {
    for (int detail = 0; detail < 3; ++detail) {
      Program& g = programs_[detail];
      g.program = buildProgram(kTerrainVs, withDefine(kTerrainFs, "TERRAIN_DETAIL", detail).c_str(), error);
      if (!g.program) {
        error = "terrain pass: " + error;
        return false;
      }
      const GLuint p = g.program.id();
      g.uViewProjection = gl.GetUniformLocation(p, "uViewProjection");
      g.uChunkOffset = gl.GetUniformLocation(p, "uChunkOffset");
      g.uChunkOffsetLow = gl.GetUniformLocation(p, "uChunkOffsetLow");
      g.uSunDirection = gl.GetUniformLocation(p, "uSunDirection");
      g.uSunColor = gl.GetUniformLocation(p, "uSunColor");
      g.uAmbient = gl.GetUniformLocation(p, "uAmbient");
      g.uFogColor = gl.GetUniformLocation(p, "uFogColor");
      g.uFogDensity = gl.GetUniformLocation(p, "uFogDensity");
      g.uHeightScale = gl.GetUniformLocation(p, "uHeightScale");
      g.uHeightBase = gl.GetUniformLocation(p, "uHeightBase");
      g.uDetailPhase = gl.GetUniformLocation(p, "uDetailPhase");
    }
    heightScale_ = static_cast<float>(heightScale_m);
    heightBase_ = static_cast<float>(heightBase_m);
    return true;
  }

  bool initStatic(const lod::TerrainGrid& grid, std::string& error) {
    if (!initProgram(grid.desc().heights.heightScale_m, 0.0, error)) return false;
    const auto vertices = grid.vertices();
    const auto indices = grid.indices();
    GLuint ids[2];
    gl.CreateBuffers(2, ids);
    vertexBuffer_ = GlBuffer::wrap(ids[0]);
    indexBuffer_ = GlBuffer::wrap(ids[1]);
    const auto vbytes = static_cast<GLsizeiptr>(vertices.size_bytes());
    const auto ibytes = static_cast<GLsizeiptr>(indices.size_bytes());
    gl.NamedBufferStorage(vertexBuffer_.id(), vbytes, vertices.data(), 0);
    gl.NamedBufferStorage(indexBuffer_.id(), ibytes, indices.data(), 0);
    bytes_ += static_cast<uint64_t>(vbytes + ibytes);
    vertexArray_ = makeVertexArray(vertexBuffer_.id());
    gl.VertexArrayElementBuffer(vertexArray_.id(), indexBuffer_.id());
    chunks_.assign(grid.chunks().begin(), grid.chunks().end());
    return true;
  }

  bool initDynamic(size_t capacityVertices, double heightScale_m, double heightBase_m, std::string& error) {
    // A buffer of no bytes, or more than GLsizeiptr holds, is a GL_INVALID_VALUE (and the map
    // then fails): refused here, naming the value.
    const std::string capacity = "terrain mesh: a vertex buffer of " + std::to_string(capacityVertices) + " vertices";
    if (capacityVertices == 0) {
      error = capacity + ": the capacity must be at least one vertex";
      return false;
    }
    if (capacityVertices > static_cast<size_t>(PTRDIFF_MAX) / sizeof(lod::TerrainVertex)) {
      error = capacity + ": more bytes than a GL buffer can have";
      return false;
    }
    if (!programs_[0].program && !initProgram(heightScale_m, heightBase_m, error)) return false;
    GLuint id = 0;
    gl.CreateBuffers(1, &id);
    dynamicBuffer_ = GlBuffer::wrap(id);
    const auto bytes = static_cast<GLsizeiptr>(capacityVertices * sizeof(lod::TerrainVertex));
    // Persistently mapped and coherent: the CPU writes changed triangles straight into the
    // buffer. Safe without fences because every frame ends with glFinish.
    const GLbitfield flags = GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
    gl.NamedBufferStorage(id, bytes, nullptr, flags);
    void* mapped = gl.MapNamedBufferRange(id, 0, bytes, flags);
    if (!mapped) {
      error = capacity + " (" + std::to_string(bytes) + " bytes) cannot be allocated and mapped persistently";
      // The GL errors of the failed storage / map (GL_OUT_OF_MEMORY) belong to this failure: left
      // queued, the next unrelated check reported them as its own.
      if (const std::string e = glErrors(); !e.empty()) error += " (GL errors " + e + ")";
      dynamicBuffer_ = GlBuffer{};
      return false;
    }
    mapped_ = std::span(static_cast<lod::TerrainVertex*>(mapped), capacityVertices);
    bytes_ += static_cast<uint64_t>(bytes);
    dynamicArray_ = makeVertexArray(id);
    return true;
  }

  std::span<lod::TerrainVertex> mapped() const { return mapped_; }

  // Chunks in the given order, each with the program variant for its distance from the eye.
  void draw(const lod::Camera& camera, const Lighting& lighting, std::span<const uint32_t> chunkIndices,
            RenderStats& stats) {
    gl.BindVertexArray(vertexArray_.id());
    if (!chunks_.empty()) warmUp([&] {
      const lod::TerrainChunk& c = chunks_.front();
      gl.DrawElementsBaseVertex(GL_TRIANGLES, 3, GL_UNSIGNED_INT,
                                reinterpret_cast<const void*>(static_cast<uintptr_t>(c.firstIndex) * sizeof(uint32_t)),
                                static_cast<GLint>(c.firstVertex));
    });
    int current = -1;
    GLuint p = 0;
    for (uint32_t i : chunkIndices) {
      const lod::TerrainChunk& c = chunks_[i];
      const int detail = detailLevel(lod::distanceToBox(c.bounds, camera.eye_m));
      if (detail != current) {
        p = begin(camera, lighting, detail);
        current = detail;
      }
      setOrigin(p, c.origin_m, camera);
      gl.DrawElementsBaseVertex(GL_TRIANGLES, static_cast<GLsizei>(c.indexCount), GL_UNSIGNED_INT,
                                reinterpret_cast<const void*>(static_cast<uintptr_t>(c.firstIndex) * sizeof(uint32_t)),
                                static_cast<GLint>(c.firstVertex));
      stats.triangles += c.indexCount / 3;
      ++stats.drawCalls;
    }
    gl.BindVertexArray(0);
  }

  // Draws the first `count` vertices of the mapped buffer as a triangle list, with the program
  // variant for `nearest_m` (a lower bound on the distance from the eye to every vertex).
  void drawDynamic(const lod::Camera& camera, const Lighting& lighting, const glm::dvec3& origin_m, size_t count,
                   double nearest_m, RenderStats& stats) {
    const size_t n = std::min(count, mapped_.size()) / 3 * 3;
    if (n == 0) return;
    gl.BindVertexArray(dynamicArray_.id());
    warmUp([] { gl.DrawArrays(GL_TRIANGLES, 0, 3); });
    const GLuint p = begin(camera, lighting, detailLevel(nearest_m));
    setOrigin(p, origin_m, camera);
    gl.DrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(n));
    gl.BindVertexArray(0);
    stats.triangles += n / 3;
    ++stats.drawCalls;
  }

  // Ranges of triangle slots (lod/terrain_chunks.h): one multi-draw for the far ranges, one with
  // the detail for `nearest_m` (a lower bound on their distance) for the near ones
  // (TerrainDrawRange::near).
  void drawDynamicRanges(const lod::Camera& camera, const Lighting& lighting, const glm::dvec3& origin_m,
                         std::span<const lod::TerrainDrawRange> ranges, double nearest_m, RenderStats& stats) {
    const size_t limit = mapped_.size() / 3;
    if (limit > 0) {
      gl.BindVertexArray(dynamicArray_.id());
      warmUp([] { gl.DrawArrays(GL_TRIANGLES, 0, 3); });
    }
    for (uint32_t detail = 0; detail < 2; ++detail) {
      firsts_.clear();
      counts_.clear();
      size_t triangles = 0;
      for (const lod::TerrainDrawRange& r : ranges) {
        if (r.count == 0 || r.first >= limit || (r.near != 0 ? 1u : 0u) != detail) continue;
        const size_t n = std::min<size_t>(r.count, limit - r.first);
        firsts_.push_back(static_cast<GLint>(3 * static_cast<size_t>(r.first)));
        counts_.push_back(static_cast<GLsizei>(3 * n));
        triangles += n;
      }
      if (firsts_.empty()) continue;
      const GLuint p = begin(camera, lighting, detail == 0 ? 0 : std::max(1, detailLevel(nearest_m)));
      setOrigin(p, origin_m, camera);
      gl.BindVertexArray(dynamicArray_.id());
      gl.MultiDrawArrays(GL_TRIANGLES, firsts_.data(), counts_.data(), static_cast<GLsizei>(firsts_.size()));
      gl.BindVertexArray(0);
      stats.triangles += triangles;
      ++stats.drawCalls;
    }
  }

  uint64_t bytes() const { return bytes_; }
  unsigned vertexBufferId() const { return dynamicBuffer_.id() ? dynamicBuffer_.id() : vertexBuffer_.id(); }
  bool hasStatic() const { return static_cast<bool>(vertexArray_); }
  bool hasDynamic() const { return static_cast<bool>(dynamicArray_); }

 private:
  static GlVertexArray makeVertexArray(GLuint buffer) {
    GLuint vao = 0;
    gl.CreateVertexArrays(1, &vao);
    gl.VertexArrayVertexBuffer(vao, 0, buffer, 0, sizeof(lod::TerrainVertex));
    gl.EnableVertexArrayAttrib(vao, 0);
    gl.VertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, offsetof(lod::TerrainVertex, position));
    gl.VertexArrayAttribBinding(vao, 0, 0);
    gl.EnableVertexArrayAttrib(vao, 1);
    gl.VertexArrayAttribFormat(vao, 1, 3, GL_FLOAT, GL_FALSE, offsetof(lod::TerrainVertex, normal));
    gl.VertexArrayAttribBinding(vao, 1, 0);
    return GlVertexArray::wrap(vao);
  }

  // llvmpipe compiles a program's fragment code for the pipeline state at its first draw (~10 ms
  // here): the pass's first draw also draws one triangle, wholly clipped (every vertex at w = -1),
  // with each variant, so that none of them stalls a later frame (when the eye first comes near
  // the ground). `draw3` draws three vertices with the bound vertex array.
  template <typename Draw3>
  void warmUp(Draw3&& draw3) {
    if (warmed_) return;
    warmed_ = true;
    glm::mat4 clipped(0.0f);
    clipped[3][3] = -1.0f;
    for (const Program& g : programs_) {
      gl.ProgramUniformMatrix4fv(g.program.id(), g.uViewProjection, 1, GL_FALSE, glm::value_ptr(clipped));
      gl.UseProgram(g.program.id());
      draw3();
    }
  }

  // Per-draw uniforms shared by both paths; binds and returns the program variant (0: no ground
  // detail, 1: the 2 m noise, 2: both).
  GLuint begin(const lod::Camera& camera, const Lighting& lighting, int detail) {
    const Program& g = programs_[detail];
    const GLuint p = g.program.id();
    current_ = &g;
    const glm::mat4 viewProjection(lod::projection(camera) *
                                   glm::dmat4(lod::viewRotation(camera)));
    gl.ProgramUniformMatrix4fv(p, g.uViewProjection, 1, GL_FALSE, glm::value_ptr(viewProjection));
    const glm::vec3 sun = toFloat(lighting.sunDirection), sunColor = toFloat(lighting.sunColor);
    const glm::vec3 fogColor = toFloat(lighting.fogColor);
    gl.ProgramUniform3fv(p, g.uSunDirection, 1, glm::value_ptr(sun));
    gl.ProgramUniform3fv(p, g.uSunColor, 1, glm::value_ptr(sunColor));
    gl.ProgramUniform1f(p, g.uAmbient, static_cast<float>(lighting.ambient));
    gl.ProgramUniform3fv(p, g.uFogColor, 1, glm::value_ptr(fogColor));
    // Koschmieder: 2 % contrast at the visibility distance.
    gl.ProgramUniform1f(p, g.uFogDensity, lighting.fog ? static_cast<float>(kFogExtinction / lighting.fogVisibility_m) : 0.0f);
    gl.ProgramUniform1f(p, g.uHeightScale, heightScale_);
    gl.ProgramUniform1f(p, g.uHeightBase, heightBase_);
    const glm::vec2 phase(std::fmod(std::fmod(camera.eye_m.x, 1024.0) + 1024.0, 1024.0),
                          std::fmod(std::fmod(camera.eye_m.y, 1024.0) + 1024.0, 1024.0));
    gl.ProgramUniform2fv(p, g.uDetailPhase, 1, glm::value_ptr(phase));
    gl.UseProgram(p);
    return p;
  }

  // Camera-relative placement: origin - eye in double, sent as a float and the float of what
  // that float left out (render/split_offset.h; the program begin() bound).
  void setOrigin(GLuint p, const glm::dvec3& origin_m, const lod::Camera& camera) const {
    const SplitOffset o = splitOffset(origin_m - camera.eye_m);
    gl.ProgramUniform3fv(p, current_->uChunkOffset, 1, glm::value_ptr(o.high));
    gl.ProgramUniform3fv(p, current_->uChunkOffsetLow, 1, glm::value_ptr(o.low));
  }

  struct Program {
    GlProgram program;
    GLint uViewProjection = -1, uChunkOffset = -1, uChunkOffsetLow = -1, uSunDirection = -1, uSunColor = -1, uAmbient = -1, uFogColor = -1,
          uFogDensity = -1, uHeightScale = -1, uHeightBase = -1, uDetailPhase = -1;
  };

  std::vector<GLint> firsts_;    // drawDynamicRanges: grown once, reused
  std::vector<GLsizei> counts_;
  Program programs_[3];              // by detailLevel()
  const Program* current_ = nullptr;  // the variant begin() bound
  GlBuffer vertexBuffer_, indexBuffer_, dynamicBuffer_;
  GlVertexArray vertexArray_, dynamicArray_;
  std::span<lod::TerrainVertex> mapped_;
  std::vector<lod::TerrainChunk> chunks_;
  uint64_t bytes_ = 0;
  float heightScale_ = 1.0f;
  float heightBase_ = 0.0f;
  bool warmed_ = false;  // warmUp() done
};

Renderer::Renderer() = default;
Renderer::~Renderer() = default;

bool Renderer::init(int width_px, int height_px, std::string& error, int samples) {
  GLint maxSamples = 1;
  gl.GetIntegerv(GL_MAX_SAMPLES, &maxSamples);
  if (samples != 1 && samples != 2 && samples != 4 && samples != 8) {
    error = "msaa " + std::to_string(samples) + ": samples per pixel must be 1, 2, 4 or 8";
    return false;
  }
  if (samples > maxSamples) {
    error = "msaa " + std::to_string(samples) + ": this GL allows at most " + std::to_string(maxSamples) + " samples per pixel";
    return false;
  }
  auto t = std::make_unique<Target>();
  GLuint rb[2];
  gl.CreateRenderbuffers(2, rb);
  t->color = GlRenderbuffer::wrap(rb[0]);
  t->depth = GlRenderbuffer::wrap(rb[1]);
  if (samples > 1) {
    gl.NamedRenderbufferStorageMultisample(rb[0], samples, GL_RGBA8, width_px, height_px);
    gl.NamedRenderbufferStorageMultisample(rb[1], samples, GL_DEPTH_COMPONENT32F, width_px, height_px);
  } else {
    gl.NamedRenderbufferStorage(rb[0], GL_RGBA8, width_px, height_px);
    gl.NamedRenderbufferStorage(rb[1], GL_DEPTH_COMPONENT32F, width_px, height_px);
  }
  GLuint fbo = 0;
  gl.CreateFramebuffers(1, &fbo);
  t->fbo = GlFramebuffer::wrap(fbo);
  gl.NamedFramebufferRenderbuffer(fbo, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb[0]);
  gl.NamedFramebufferRenderbuffer(fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, rb[1]);
  gl.NamedFramebufferReadBuffer(fbo, GL_COLOR_ATTACHMENT0);
  if (!completeFramebuffer(fbo, width_px, height_px, error)) return false;
  if (samples > 1) {
    GLuint color = 0, resolved = 0;
    gl.CreateRenderbuffers(1, &color);
    t->resolvedColor = GlRenderbuffer::wrap(color);
    gl.NamedRenderbufferStorage(color, GL_RGBA8, width_px, height_px);
    gl.CreateFramebuffers(1, &resolved);
    t->resolvedFbo = GlFramebuffer::wrap(resolved);
    gl.NamedFramebufferRenderbuffer(resolved, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color);
    gl.NamedFramebufferReadBuffer(resolved, GL_COLOR_ATTACHMENT0);
    if (!completeFramebuffer(resolved, width_px, height_px, error)) return false;
  }
  // Reverse-Z: clip depth in [0, 1], far = 0, near = 1.
  gl.ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  gl.Enable(GL_DEPTH_TEST);
  gl.DepthFunc(GL_GREATER);
  gl.Enable(GL_CULL_FACE);
  gl.CullFace(GL_BACK);
  gl.FrontFace(GL_CCW);
  const std::string e = glErrors();
  if (!e.empty()) {
    error = "renderer init: GL errors " + e;
    return false;
  }
  target_ = std::move(t);
  width_ = width_px;
  height_ = height_px;
  samples_ = samples;
  resolved_ = true;
  return true;
}

bool Renderer::addTerrain(const lod::TerrainGrid& grid, std::string& error) {
  auto pass = std::make_unique<TerrainPass>();
  if (!pass->initStatic(grid, error)) return false;
  terrain_ = std::move(pass);
  return true;
}

bool Renderer::addTerrainMesh(size_t capacityVertices, double heightScale_m, std::string& error, double heightBase_m) {
  auto pass = std::make_unique<TerrainPass>();
  if (!pass->initDynamic(capacityVertices, heightScale_m, heightBase_m, error)) return false;
  terrainMesh_ = std::move(pass);
  return true;
}

std::span<lod::TerrainVertex> Renderer::terrainMeshVertices() const {
  return terrainMesh_ ? terrainMesh_->mapped() : std::span<lod::TerrainVertex>{};
}

void Renderer::drawTerrainMesh(const glm::dvec3& origin_m, size_t vertexCount, double nearest_m) {
  if (terrainMesh_) terrainMesh_->drawDynamic(camera_, lighting_, origin_m, vertexCount, nearest_m, stats_);
}

void Renderer::drawTerrainMeshRanges(const glm::dvec3& origin_m, std::span<const lod::TerrainDrawRange> ranges,
                                     double nearest_m) {
  if (terrainMesh_) terrainMesh_->drawDynamicRanges(camera_, lighting_, origin_m, ranges, nearest_m, stats_);
}

void Renderer::drawTerrainMesh(const glm::dvec3& origin_m, std::span<const lod::TerrainVertex> vertices) {
  const auto dst = terrainMeshVertices();
  const size_t n = std::min(vertices.size(), dst.size());
  std::copy_n(vertices.begin(), n, dst.begin());
  drawTerrainMesh(origin_m, n);
}

void Renderer::beginFrame(const lod::Camera& camera, const Lighting& lighting) {
  const auto finite = [](double v) { return std::isfinite(v); };
  const lod::Camera& c = camera;
  if (finite(c.eye_m.x) && finite(c.eye_m.y) && finite(c.eye_m.z) && finite(c.heading_deg) && finite(c.pitch_deg) &&
      finite(c.roll_deg) && c.fovY_deg > 0.0 && c.fovY_deg < 180.0 && c.aspect > 0.0 && finite(c.aspect) &&
      c.near_m > 0.0 && c.far_m > c.near_m && finite(c.far_m) && lod::validWindowShift(c)) {
    camera_ = camera;
  } else {
    char text[384];
    std::snprintf(text, sizeof text,
                  "beginFrame: camera refused (eye %g %g %g, heading %g, pitch %g, roll %g deg, fov %g deg, aspect %g, "
                  "near %g m, far %g m, window shift %g %g: need finite values, fov in (0, 180), aspect > 0, 0 < near < far, "
                  "|shift| <= 500): "
                  "the last good camera is drawn",
                  c.eye_m.x, c.eye_m.y, c.eye_m.z, c.heading_deg, c.pitch_deg, c.roll_deg, c.fovY_deg, c.aspect, c.near_m,
                  c.far_m, c.shiftX, c.shiftY);
    cameraError_ = text;
  }
  lighting_ = lighting;
  stats_ = {};
  stats_.passes = passCount();
  resolved_ = samples_ == 1;
  const GLuint fbo = target_->fbo.id();
  gl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
  gl.Viewport(0, 0, width_, height_);
  const glm::vec4 sky(glm::vec3(lighting.fogColor), 1.0f);
  gl.ClearNamedFramebufferfv(fbo, GL_COLOR, 0, glm::value_ptr(sky));
  const float farDepth = 0.0f;
  gl.ClearNamedFramebufferfv(fbo, GL_DEPTH, 0, &farDepth);
}

void Renderer::drawTerrain(std::span<const uint32_t> chunkIndices) {
  if (terrain_) terrain_->draw(camera_, lighting_, chunkIndices, stats_);
}

RenderStats Renderer::endFrame() { return stats_; }

void Renderer::finish() { gl.Finish(); }

void Renderer::readPixels(Image& out) {
  out.width = width_;
  out.height = height_;
  out.rgba.resize(static_cast<size_t>(width_) * static_cast<size_t>(height_) * 4);
  gl.BindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer());
  gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl.ReadPixels(0, 0, width_, height_, GL_RGBA, GL_UNSIGNED_BYTE, out.rgba.data());
  // GL's row 0 is the bottom; images store the top row first.
  const size_t pitch = static_cast<size_t>(width_) * 4;
  for (int y = 0; y < height_ / 2; ++y) {
    uint8_t* a = out.rgba.data() + static_cast<size_t>(y) * pitch;
    uint8_t* b = out.rgba.data() + static_cast<size_t>(height_ - 1 - y) * pitch;
    std::swap_ranges(a, a + pitch, b);
  }
}

void Renderer::resolve() {
  if (resolved_ || !target_) return;
  gl.BlitNamedFramebuffer(target_->fbo.id(), target_->resolvedFbo.id(), 0, 0, width_, height_, 0, 0, width_, height_,
                          GL_COLOR_BUFFER_BIT, GL_NEAREST);
  resolved_ = true;
}

unsigned Renderer::framebuffer() {
  if (!target_) return 0;
  if (samples_ == 1) return target_->fbo.id();
  resolve();
  return target_->resolvedFbo.id();
}

unsigned Renderer::terrainMeshVertexBuffer() const { return terrainMesh_ ? terrainMesh_->vertexBufferId() : 0; }

uint64_t Renderer::bufferBytes() const {
  return (terrain_ ? terrain_->bytes() : 0) + (terrainMesh_ ? terrainMesh_->bytes() : 0);
}

std::string Renderer::errors() const {
  std::string e = glErrors();
  if (!cameraError_.empty()) {
    e = e.empty() ? cameraError_ : cameraError_ + "; " + e;
    cameraError_.clear();
  }
  return e;
}

Lighting daylight(const Lighting& full, double elevation_deg) {
  const double day = lod::sunlightFraction(elevation_deg);
  Lighting l = full;
  l.sunColor = full.sunColor * day;
  l.ambient = full.ambient * ambientScale(day);
  l.fogColor = full.fogColor * (0.08 + 0.92 * day);
  l.daylight = day;
  return l;
}

}  // namespace ig::render
