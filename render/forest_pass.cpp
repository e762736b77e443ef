// Forest pass of paper 004 (Graphicon 2006; shared/SEEDS.md section 004): shell layers and fins
// far away, instanced 3D trees near, and the offline textures T and S. See forest_pass.h.
#include "render/forest_pass.h"


#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include <glm/gtc/type_ptr.hpp>
#include <glm/mat4x4.hpp>

#include "lod/forest.h"
#include "render/gl.h"
#include "render/renderer.h"
#include "render/split_offset.h"

namespace ig::render {
namespace {



// Move-only texture name (render/gl.h's GlObject has no texture kind).
class GlTexture {
 public:
  GlTexture() = default;
  explicit GlTexture(GLuint id) : id_(id) {}
  GlTexture(GlTexture&& o) noexcept : id_(std::exchange(o.id_, 0)) {}
  GlTexture& operator=(GlTexture&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = std::exchange(o.id_, 0);
    }
    return *this;
  }
  GlTexture(const GlTexture&) = delete;
  GlTexture& operator=(const GlTexture&) = delete;
  ~GlTexture() { reset(); }
  void reset() {
    if (id_) gl.DeleteTextures(1, &id_);
    id_ = 0;
  }
  GLuint id() const { return id_; }

 private:
  GLuint id_ = 0;
};

// Shared GLSL: fades, sun light, fog (the terrain pass's Koschmieder fog).
const char* kCommon = R"(
uniform vec4 uFarFade;      // fadeInStart, fadeInEnd, fadeOut, farPlane
uniform vec3 uSunDirection;
uniform vec3 uSunColor;
uniform float uAmbient;
uniform vec3 uFogColor;
uniform float uFogDensity;
float farAlpha(float d) {
  if (!(d > uFarFade.x) || d >= uFarFade.w) return 0.0;
  if (d < uFarFade.y) return (d - uFarFade.x) / (uFarFade.y - uFarFade.x);
  if (d <= uFarFade.z) return 1.0;
  return (uFarFade.w - d) / (uFarFade.w - uFarFade.z);
}
vec3 shade(vec3 albedo, vec3 n, float dist) {
  float diffuse = max(dot(n, uSunDirection), 0.0);
  vec3 lit = albedo * (uAmbient + (1.0 - uAmbient) * diffuse * uSunColor);
  return mix(uFogColor, lit, exp(-uFogDensity * dist));
}
)";

const char* kTreeVs = R"(#version 450 core
layout(location = 0) in vec3 aPosition;   // model space
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aAlbedo;
layout(location = 3) in vec4 iOffsetAlpha; // tree base - eye (metres), nearAlpha
layout(location = 4) in vec4 iTint;        // per-tree colour (Gr tint with variation)
layout(location = 5) in uint iTree;        // tree index: yaw and scale
layout(location = 6) in vec2 iNormal;      // terrain normal x, y
uniform mat4 uViewProjection;
uniform float uModelHeight;
uniform float uYawJitter;
uniform vec4 uClip0;                       // clip planes (texture baking; else 0,0,0,1)
uniform vec4 uClip1;
out vec3 vRel;
out vec3 vColor;
out vec3 vTerrainNormal;
out float vAlpha;
uint hash(uint x) {
  x ^= x >> 16; x *= 0x7feb352du; x ^= x >> 15; x *= 0x846ca68bu; x ^= x >> 16;
  return x;
}
void main() {
  // lod::treePose (lod/forest_rays.h) repeats this pose for the host's line-of-sight queries:
  // change both together.
  uint h = hash(iTree);
  float yaw = float(h & 0xffffu) * (6.2831853 / 65536.0) * uYawJitter;
  float s = 1.0 + 0.2 * uYawJitter * (float((h >> 16) & 0xffu) / 255.0 - 0.5);
  float c = cos(yaw), sn = sin(yaw);
  vec2 xy = vec2(c * aPosition.x - sn * aPosition.y, sn * aPosition.x + c * aPosition.y);
  vec3 rel = vec3(xy, aPosition.z) * s + iOffsetAlpha.xyz;
  vec3 nm = vec3(c * aNormal.x - sn * aNormal.y, sn * aNormal.x + c * aNormal.y, aNormal.z);
  // Lower parts darker (as the lower layers of T), tops brighter (sky light): sun independent,
  // so T and S bake exactly this colour.
  float k = (0.55 + 0.45 * clamp(aPosition.z / uModelHeight, 0.0, 1.0)) * (0.8 + 0.2 * nm.z);
  vColor = 2.0 * aAlbedo.rgb * iTint.rgb * k;
  vTerrainNormal = vec3(iNormal, sqrt(max(1.0 - dot(iNormal, iNormal), 0.0)));
  vAlpha = iOffsetAlpha.w;
  vRel = rel;
  gl_ClipDistance[0] = dot(vec4(rel, 1.0), uClip0);
  gl_ClipDistance[1] = dot(vec4(rel, 1.0), uClip1);
  gl_Position = uViewProjection * vec4(rel, 1.0);
}
)";

const char* kTreeFs = R"(
in vec3 vRel;
in vec3 vColor;
in vec3 vTerrainNormal;
in float vAlpha;
uniform int uBake;
out vec4 fragColor;
void main() {
  if (uBake == 1) {
    fragColor = vec4(vColor, 1.0);
    return;
  }
  fragColor = vec4(shade(vColor, normalize(vTerrainNormal), length(vRel)), vAlpha);
}
)";

const char* kLayerVs = R"(#version 450 core
layout(location = 0) in vec3 aPosition;   // terrain vertex relative to the terrain origin
layout(location = 1) in vec3 aNormal;
uniform mat4 uViewProjection;
uniform vec3 uOffset;                     // terrain origin - eye (double on the CPU) as a float
uniform vec3 uOffsetLow;                  // what the float left out (render/split_offset.h)
uniform float uLayerStep;                 // H / n
uniform int uLayerBase;                   // drawn layer of instance 0 (one draw per layer over ranges)
uniform int uLayersDrawn;                 // m <= n drawn: layer j stands for slabs [j n / m, (j + 1) n / m)
uniform int uLayerCount;                  // n (slabs of T)
uniform vec2 uMapScale;                   // 1 / map extent
uniform vec2 uMapBias;                    // (terrain origin - map origin) / extent
uniform float uTileScale;                 // 1 / tile
uniform vec2 uTileBias;                   // fract(terrain origin / tile)
out vec3 vRel;
out vec3 vNormal;
out vec2 vMapUv;
out vec3 vTileUv;
void main() {
  // Drawn layer j stands for a group of slabs, at the top one's height, with slice j of the
  // texture bound: T itself when m = n (one slab each), else T's slabs composited per group.
  int j = gl_InstanceID + uLayerBase;
  float top = float(((j + 1) * uLayerCount) / uLayersDrawn);
  precise vec3 rel = ((aPosition + uOffset) + uOffsetLow) + vec3(0.0, 0.0, top * uLayerStep);
  vRel = rel;
  vNormal = aNormal;
  vMapUv = aPosition.xy * uMapScale + uMapBias;
  vTileUv = vec3(aPosition.xy * uTileScale + uTileBias, float(j));
  gl_Position = uViewProjection * vec4(rel, 1.0);
}
)";

const char* kLayerFs = R"(
in vec3 vRel;
in vec3 vNormal;
in vec2 vMapUv;
in vec3 vTileUv;
layout(binding = 0) uniform sampler2DArray uT;
layout(binding = 1) uniform sampler2D uGr;
out vec4 fragColor;
void main() {
  // Outside the map is a glade (no forest): Gr's border cells are not repeated over the terrain.
  if (any(lessThan(vMapUv, vec2(0.0))) || any(greaterThan(vMapUv, vec2(1.0)))) discard;
  float dist = length(vRel);
  vec4 t = texture(uT, vTileUv);
  vec4 gr = texture(uGr, vMapUv);
  // a = T.a * Gr.a is the slab's coverage seen along the layer normal; a ray crossing the slab
  // at an angle travels 1 / cos longer through it (Beer-Lambert): a' = 1 - (1 - a)^(1 / cos).
  vec3 n = normalize(vNormal);
  float cosView = max(abs(dot(n, vRel)) / max(dist, 1e-6), 0.05);
  float a = (1.0 - pow(max(1.0 - t.a * gr.a, 0.0), 1.0 / cosView)) * farAlpha(dist);
  if (a < 0.5 / 255.0) discard;
  fragColor = vec4(shade(2.0 * t.rgb * gr.rgb, n, dist), a);
}
)";

const char* kFinVs = R"(#version 450 core
layout(location = 0) in vec3 aPosition;   // relative to the map origin
layout(location = 1) in vec3 aTangent;
layout(location = 2) in vec3 aUv;         // along the edge (metres), up (0..1), slice
uniform mat4 uViewProjection;
uniform vec3 uOffset;                     // map origin - eye as a float
uniform vec3 uOffsetLow;                  // what the float left out (render/split_offset.h)
uniform vec2 uMapScale;                   // 1 / map extent
uniform float uTileScale;
out vec3 vRel;
out vec3 vTangent;
out vec2 vMapUv;
out vec3 vUv;
void main() {
  precise vec3 rel = (aPosition + uOffset) + uOffsetLow;
  vRel = rel;
  vTangent = aTangent;
  vMapUv = aPosition.xy * uMapScale;
  vUv = vec3(aUv.x * uTileScale, aUv.y, aUv.z);
  gl_Position = uViewProjection * vec4(rel, 1.0);
}
)";

const char* kFinFs = R"(
in vec3 vRel;
in vec3 vTangent;
in vec2 vMapUv;
in vec3 vUv;
layout(binding = 0) uniform sampler2DArray uS;
layout(binding = 1) uniform sampler2D uGr;
out vec4 fragColor;
void main() {
  if (any(lessThan(vMapUv, vec2(0.0))) || any(greaterThan(vMapUv, vec2(1.0)))) discard;  // outside the map
  float dist = length(vRel);
  float viewA = 1.0 - abs(dot(normalize(vTangent), vRel / max(dist, 1e-6)));
  vec4 s = texture(uS, vUv);
  vec4 gr = texture(uGr, vMapUv);
  float a = s.a * gr.a * farAlpha(dist) * viewA;
  if (a < 0.5 / 255.0) discard;
  fragColor = vec4(shade(2.0 * s.rgb * gr.rgb, vec3(0.0, 0.0, 1.0), dist), a);
}
)";

GlProgram build(const char* vs, const char* fsBody, const char* what, std::string& error) {
  const std::string fs = std::string("#version 450 core\n") + kCommon + fsBody;
  GlProgram p = buildProgram(vs, fs.c_str(), error);
  if (!p) error = std::string("forest pass: ") + what + ": " + error;
  return p;
}

struct FinVertex {
  float position[3];
  float tangent[3];
  float uv[3];
};

struct ModelRange {
  GLint baseVertex = 0;
  uint32_t firstIndex = 0;
  uint32_t indexCount = 0;
  float height_m = 1.0f;
};

glm::mat4 viewProjection(const lod::Camera& c) {
  return glm::mat4(lod::projection(c) * glm::dmat4(lod::viewRotation(c)));
}

struct Locations {
  GLint viewProjection = -1, farFade = -1, sun = -1, sunColor = -1, ambient = -1, fogColor = -1, fogDensity = -1;
  void find(GLuint p) {
    viewProjection = gl.GetUniformLocation(p, "uViewProjection");
    farFade = gl.GetUniformLocation(p, "uFarFade");
    sun = gl.GetUniformLocation(p, "uSunDirection");
    sunColor = gl.GetUniformLocation(p, "uSunColor");
    ambient = gl.GetUniformLocation(p, "uAmbient");
    fogColor = gl.GetUniformLocation(p, "uFogColor");
    fogDensity = gl.GetUniformLocation(p, "uFogDensity");
  }
  void set(GLuint p, const glm::mat4& vp, const Lighting& l, const lod::FarFade& f) const {
    gl.ProgramUniformMatrix4fv(p, viewProjection, 1, GL_FALSE, glm::value_ptr(vp));
    const glm::vec4 fade(static_cast<float>(f.fadeInStart_m), static_cast<float>(f.fadeInEnd_m),
                         static_cast<float>(f.fadeOut_m), static_cast<float>(f.farPlane_m));
    gl.ProgramUniform4fv(p, farFade, 1, glm::value_ptr(fade));
    const glm::vec3 sunDir(l.sunDirection), sunRgb(l.sunColor), fog(l.fogColor);
    gl.ProgramUniform3fv(p, sun, 1, glm::value_ptr(sunDir));
    gl.ProgramUniform3fv(p, sunColor, 1, glm::value_ptr(sunRgb));
    gl.ProgramUniform1f(p, ambient, static_cast<float>(l.ambient));
    gl.ProgramUniform3fv(p, fogColor, 1, glm::value_ptr(fog));
    gl.ProgramUniform1f(p, fogDensity, l.fog ? static_cast<float>(kFogExtinction / l.fogVisibility_m) : 0.0f);
  }
};

// The 3D tree models and their program: used by the pass and by the texture baker.
// The cull state and depth mask as a draw found them, put back when it ends (the pass's
// contract, render/forest_pass.h): the draws switch culling off for two-sided cards and depth
// writes off for blended ones, and re-enabled both unconditionally.
struct CullAndDepthMaskRestore {
  GLboolean cull = GL_TRUE, depthMask = GL_TRUE;
  CullAndDepthMaskRestore() {
    gl.GetBooleanv(GL_CULL_FACE, &cull);
    gl.GetBooleanv(GL_DEPTH_WRITEMASK, &depthMask);
  }
  ~CullAndDepthMaskRestore() {
    if (cull) gl.Enable(GL_CULL_FACE);
    else gl.Disable(GL_CULL_FACE);
    gl.DepthMask(depthMask);
  }
  CullAndDepthMaskRestore(const CullAndDepthMaskRestore&) = delete;
  CullAndDepthMaskRestore& operator=(const CullAndDepthMaskRestore&) = delete;
};

struct TreeDrawer {
  GlProgram program;
  GlBuffer vertices, indices, instances;
  GlVertexArray vao;
  std::vector<ModelRange> models;
  size_t capacity = 0;
  uint64_t bytes = 0;
  Locations loc;
  GLint uModelHeight = -1, uYawJitter = -1, uClip0 = -1, uClip1 = -1, uBake = -1;

  bool init(std::span<const lod::TreeMesh> meshes, size_t maxInstances, std::string& error) {
    if (meshes.empty() || meshes.size() > 256) {
      error = "forest pass: " + std::to_string(meshes.size()) + " tree models: need 1..256";
      return false;
    }
    program = build(kTreeVs, kTreeFs, "tree program", error);
    if (!program) return false;
    const GLuint p = program.id();
    loc.find(p);
    uModelHeight = gl.GetUniformLocation(p, "uModelHeight");
    uYawJitter = gl.GetUniformLocation(p, "uYawJitter");
    uClip0 = gl.GetUniformLocation(p, "uClip0");
    uClip1 = gl.GetUniformLocation(p, "uClip1");
    uBake = gl.GetUniformLocation(p, "uBake");
    std::vector<lod::TreeVertex> v;
    std::vector<uint32_t> idx;
    for (const lod::TreeMesh& m : meshes) {
      if (!lod::validateTreeMesh(m, error)) return false;
      ModelRange r;
      r.baseVertex = static_cast<GLint>(v.size());
      r.firstIndex = static_cast<uint32_t>(idx.size());
      r.indexCount = static_cast<uint32_t>(m.indices.size());
      r.height_m = std::max(m.height_m, 0.1f);
      models.push_back(r);
      v.insert(v.end(), m.vertices.begin(), m.vertices.end());
      idx.insert(idx.end(), m.indices.begin(), m.indices.end());
    }
    capacity = std::max<size_t>(maxInstances, 1);
    GLuint ids[3];
    gl.CreateBuffers(3, ids);
    vertices = GlBuffer::wrap(ids[0]);
    indices = GlBuffer::wrap(ids[1]);
    instances = GlBuffer::wrap(ids[2]);
    const auto vb = static_cast<GLsizeiptr>(v.size() * sizeof(lod::TreeVertex));
    const auto ib = static_cast<GLsizeiptr>(idx.size() * sizeof(uint32_t));
    const auto nb = static_cast<GLsizeiptr>(capacity * sizeof(lod::ForestInstance));
    gl.NamedBufferStorage(ids[0], vb, v.data(), 0);
    gl.NamedBufferStorage(ids[1], ib, idx.data(), 0);
    gl.NamedBufferStorage(ids[2], nb, nullptr, GL_DYNAMIC_STORAGE_BIT);
    bytes = static_cast<uint64_t>(vb + ib + nb);
    GLuint a = 0;
    gl.CreateVertexArrays(1, &a);
    vao = GlVertexArray::wrap(a);
    gl.VertexArrayVertexBuffer(a, 0, ids[0], 0, sizeof(lod::TreeVertex));
    gl.VertexArrayVertexBuffer(a, 1, ids[2], 0, sizeof(lod::ForestInstance));
    gl.VertexArrayBindingDivisor(a, 1, 1);
    gl.VertexArrayElementBuffer(a, ids[1]);
    const auto attrib = [&](GLuint i, GLuint binding, GLint n, GLenum type, GLboolean norm, size_t offset) {
      gl.EnableVertexArrayAttrib(a, i);
      gl.VertexArrayAttribFormat(a, i, n, type, norm, static_cast<GLuint>(offset));
      gl.VertexArrayAttribBinding(a, i, binding);
    };
    attrib(0, 0, 3, GL_FLOAT, GL_FALSE, offsetof(lod::TreeVertex, position));
    attrib(1, 0, 3, GL_FLOAT, GL_FALSE, offsetof(lod::TreeVertex, normal));
    attrib(2, 0, 4, GL_UNSIGNED_BYTE, GL_TRUE, offsetof(lod::TreeVertex, rgba));
    attrib(3, 1, 4, GL_FLOAT, GL_FALSE, offsetof(lod::ForestInstance, offset_m));
    attrib(4, 1, 4, GL_UNSIGNED_BYTE, GL_TRUE, offsetof(lod::ForestInstance, rgba));
    gl.EnableVertexArrayAttrib(a, 5);
    gl.VertexArrayAttribIFormat(a, 5, 1, GL_UNSIGNED_INT, offsetof(lod::ForestInstance, tree));
    gl.VertexArrayAttribBinding(a, 5, 1);
    attrib(6, 1, 2, GL_BYTE, GL_TRUE, offsetof(lod::ForestInstance, normal));
    const glm::vec4 noClip(0.0f, 0.0f, 0.0f, 1.0f);
    gl.ProgramUniform4fv(p, uClip0, 1, glm::value_ptr(noClip));
    gl.ProgramUniform4fv(p, uClip1, 1, glm::value_ptr(noClip));
    gl.ProgramUniform1i(p, uBake, 0);
    gl.ProgramUniform1f(p, uYawJitter, 1.0f);
    return true;
  }

  // Uploads instances and issues instanced draws per non-empty model range: first the opaque
  // trees (alpha 1) of every model, writing depth; then the fading ones (alpha < 1: the fade
  // band, the farthest of each far-to-near range), blended and depth tested only, so that a tree
  // fading out never hides what is drawn behind it later (the shell layers and fins fading in).
  void draw(std::span<const lod::ForestInstance> inst, std::span<const lod::ForestModelRange> ranges,
            ForestDrawStats& stats) {
    const size_t n = std::min(inst.size(), capacity);
    if (n == 0) return;
    gl.NamedBufferSubData(instances.id(), 0, static_cast<GLsizeiptr>(n * sizeof(lod::ForestInstance)), inst.data());
    gl.UseProgram(program.id());
    gl.BindVertexArray(vao.id());
    const size_t nm = std::min(ranges.size(), models.size());
    std::array<uint32_t, 256> fading{};  // per model: the leading instances with alpha < 1
    bool anyFading = false;
    for (size_t m = 0; m < nm; ++m) {
      const lod::ForestModelRange& r = ranges[m];
      if (r.count == 0 || r.first >= n) continue;
      const auto count = static_cast<uint32_t>(std::min<size_t>(r.count, n - r.first));
      uint32_t f = 0;
      while (f < count && !(inst[r.first + f].alpha >= 1.0f)) ++f;
      fading[m] = f;
      anyFading = anyFading || f > 0;
    }
    const auto drawRange = [&](size_t m, uint32_t first, uint32_t count) {
      if (count == 0) return;
      const ModelRange& mr = models[m];
      gl.ProgramUniform1f(program.id(), uModelHeight, mr.height_m);
      gl.DrawElementsInstancedBaseVertexBaseInstance(
          GL_TRIANGLES, static_cast<GLsizei>(mr.indexCount), GL_UNSIGNED_INT,
          reinterpret_cast<const void*>(static_cast<uintptr_t>(mr.firstIndex) * sizeof(uint32_t)),
          static_cast<GLsizei>(count), mr.baseVertex, first);
      stats.trees += static_cast<uint64_t>(count);
      stats.triangles += static_cast<uint64_t>(count) * (mr.indexCount / 3);
      ++stats.drawCalls;
    };
    for (size_t m = 0; m < nm; ++m) {
      const lod::ForestModelRange& r = ranges[m];
      if (r.count == 0 || r.first >= n) continue;
      const auto count = static_cast<uint32_t>(std::min<size_t>(r.count, n - r.first));
      drawRange(m, r.first + fading[m], count - fading[m]);
    }
    if (anyFading) {
      gl.DepthMask(GL_FALSE);
      for (size_t m = 0; m < nm; ++m) drawRange(m, ranges[m].first, fading[m]);
      gl.DepthMask(GL_TRUE);
    }
    gl.BindVertexArray(0);
  }
};

GlTexture makeArrayTexture(const Image& img, int tileW, int layers, GLenum wrapT) {
  GLuint id = 0;
  gl.CreateTextures(GL_TEXTURE_2D_ARRAY, 1, &id);
  GlTexture t(id);
  const int h = img.height;
  const int levels = 1 + static_cast<int>(std::floor(std::log2(std::max(tileW, h))));
  gl.TextureStorage3D(id, levels, GL_RGBA8, tileW, h, layers);
  std::vector<uint8_t> layer(static_cast<size_t>(tileW) * static_cast<size_t>(h) * 4);
  for (int l = 0; l < layers; ++l) {
    // Image row 0 is the top; texture row 0 is v = 0 (bottom): flip so v grows upwards/north.
    for (int y = 0; y < h; ++y) {
      const uint8_t* src = img.rgba.data() + (static_cast<size_t>(h - 1 - y) * static_cast<size_t>(img.width) +
                                              static_cast<size_t>(l) * static_cast<size_t>(tileW)) * 4;
      std::memcpy(layer.data() + static_cast<size_t>(y) * static_cast<size_t>(tileW) * 4, src,
                  static_cast<size_t>(tileW) * 4);
    }
    gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    gl.TextureSubImage3D(id, 0, 0, 0, l, tileW, h, 1, GL_RGBA, GL_UNSIGNED_BYTE, layer.data());
  }
  gl.GenerateTextureMipmap(id);
  gl.TextureParameteri(id, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  gl.TextureParameteri(id, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  gl.TextureParameteri(id, GL_TEXTURE_WRAP_S, GL_REPEAT);
  gl.TextureParameteri(id, GL_TEXTURE_WRAP_T, static_cast<GLint>(wrapT));
  return t;
}

}  // namespace

bool validateForestTextures(const ForestTextures& t, std::string& error) {
  if (t.layerCount < 1 || t.layerCount > 32 || t.layers.height < 1 || t.layers.width != t.layers.height * t.layerCount ||
      t.layers.rgba.size() != static_cast<size_t>(t.layers.width) * static_cast<size_t>(t.layers.height) * 4) {
    error = "forest textures: layer image " + std::to_string(t.layers.width) + " x " + std::to_string(t.layers.height) +
            " with " + std::to_string(t.layerCount) + " layers: need 1..32 square layers side by side";
    return false;
  }
  if (t.finSlices < 1 || t.fins.height < 1 || t.fins.width % t.finSlices != 0 ||
      t.fins.rgba.size() != static_cast<size_t>(t.fins.width) * static_cast<size_t>(t.fins.height) * 4) {
    error = "forest textures: fin image " + std::to_string(t.fins.width) + " x " + std::to_string(t.fins.height) +
            " with " + std::to_string(t.finSlices) + " slices: width must be a multiple of the slice count";
    return false;
  }
  if (!(t.tile_m > 0.0 && std::isfinite(t.tile_m)) || !(t.height_m > 0.0 && std::isfinite(t.height_m))) {
    error = "forest textures: tile_m = " + std::to_string(t.tile_m) + ", height_m = " + std::to_string(t.height_m) +
            ": both must be finite and > 0";
    return false;
  }
  return true;
}

bool renderForestTextures(std::span<const lod::TreeMesh> models, const ForestTextureDesc& d, ForestTextures& out,
                          std::string& error) {
  if (d.layers < 1 || d.layers > 32 || d.size_px < 8 || d.size_px > 2048 || d.finSlices < 1 || d.finSlices > 16 ||
      d.supersample < 1 || d.supersample > 8 || d.treesPerTile < 1 || !(d.tile_m > 0.0) || !std::isfinite(d.tile_m) ||
      !(d.finSliceDepth_m > 0.0) || !std::isfinite(d.finSliceDepth_m)) {
    error = "forest textures: layers = " + std::to_string(d.layers) + ", size_px = " + std::to_string(d.size_px) +
            ", fin slices = " + std::to_string(d.finSlices) + ", supersample = " + std::to_string(d.supersample) +
            ", trees per tile = " + std::to_string(d.treesPerTile) + ", tile_m = " + std::to_string(d.tile_m) +
            ", fin slice depth = " + std::to_string(d.finSliceDepth_m) +
            ": need layers 1..32, size 8..2048, slices 1..16, supersample 1..8, trees >= 1, tile and slice depth "
            "finite and > 0";
    return false;
  }
  // The models are checked before the tile is planted (a model index is a hash modulo their
  // count) and must stand above the ground (H, the height of the layer stack and the fins).
  if (models.empty() || models.size() > 256) {
    error = "forest textures: " + std::to_string(models.size()) + " tree models: need 1..256";
    return false;
  }
  for (const lod::TreeMesh& m : models) {
    if (!lod::validateTreeMesh(m, error)) return false;
  }
  // Plant the tile: a jittered grid, nine copies (wrap-around) so both textures tile.
  const int g = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(d.treesPerTile))));
  std::vector<lod::ForestInstance> base;
  float top = 0.0f;
  for (const lod::TreeMesh& m : models) top = std::max(top, m.height_m);
  if (!(top > 0.0f) || !std::isfinite(top)) {
    error = "forest textures: the tallest tree model is " + std::to_string(top) + " m high: must be finite and > 0";
    return false;
  }
  for (int i = 0; i < d.treesPerTile; ++i) {
    const auto ui = static_cast<uint32_t>(i);
    const uint32_t h0 = lod::forestHash(d.seed, ui, 1), h1 = lod::forestHash(d.seed, ui, 2), h2 = lod::forestHash(d.seed, ui, 3);
    const double cx = ((i % g) + 0.5 + 0.8 * ((h0 >> 8) / 16777216.0 - 0.5)) / g * d.tile_m;
    const double cy = ((i / g) + 0.5 + 0.8 * ((h1 >> 8) / 16777216.0 - 0.5)) / g * d.tile_m;
    lod::ForestInstance t{};
    t.offset_m[0] = static_cast<float>(cx);
    t.offset_m[1] = static_cast<float>(cy);
    t.alpha = 1.0f;
    t.rgba = 0xFF808080u;  // neutral tint: 2 * albedo * 0.5
    t.tree = h2;
    t.normal[0] = t.normal[1] = 0;
    t.model = static_cast<uint8_t>(h2 % models.size());
    base.push_back(t);
  }
  const double height = static_cast<double>(top) * 1.1;  // the largest per-tree scale (1 + 0.1)
  std::vector<lod::ForestInstance> inst;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx)
      for (lod::ForestInstance t : base) {
        t.offset_m[0] += static_cast<float>(dx * d.tile_m);
        t.offset_m[1] += static_cast<float>(dy * d.tile_m);
        inst.push_back(t);
      }
  std::stable_sort(inst.begin(), inst.end(), [](const auto& a, const auto& b) { return a.model < b.model; });
  std::vector<lod::ForestModelRange> ranges(models.size());
  for (uint32_t i = 0; i < inst.size(); ++i) {
    if (ranges[inst[i].model].count == 0) ranges[inst[i].model].first = i;
    ++ranges[inst[i].model].count;
  }

  TreeDrawer drawer;
  if (!drawer.init(models, inst.size(), error)) return false;
  const GLuint p = drawer.program.id();
  gl.ProgramUniform1i(p, drawer.uBake, 1);

  // Saved state.
  GLint prevFbo = 0, prevViewport[4] = {0, 0, 0, 0}, prevDepthFunc = GL_LESS;
  gl.GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &prevFbo);
  gl.GetIntegerv(GL_VIEWPORT, prevViewport);
  gl.GetIntegerv(GL_DEPTH_FUNC, &prevDepthFunc);
  GLboolean depthTest = GL_FALSE, cull = GL_FALSE;
  gl.GetBooleanv(GL_DEPTH_TEST, &depthTest);
  gl.GetBooleanv(GL_CULL_FACE, &cull);

  const int ss = d.supersample;
  const int layerPx = d.size_px, finH = std::max(8, static_cast<int>(std::lround(d.size_px * height / d.tile_m)));
  const int W = layerPx * ss, H = std::max(layerPx, finH) * ss;
  GLuint rb[2], fbo = 0;
  gl.CreateRenderbuffers(2, rb);
  GlRenderbuffer color = GlRenderbuffer::wrap(rb[0]), depth = GlRenderbuffer::wrap(rb[1]);
  gl.NamedRenderbufferStorage(rb[0], GL_RGBA8, W, H);
  gl.NamedRenderbufferStorage(rb[1], GL_DEPTH_COMPONENT32F, W, H);
  gl.CreateFramebuffers(1, &fbo);
  GlFramebuffer target = GlFramebuffer::wrap(fbo);
  gl.NamedFramebufferRenderbuffer(fbo, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb[0]);
  gl.NamedFramebufferRenderbuffer(fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, rb[1]);
  gl.NamedFramebufferReadBuffer(fbo, GL_COLOR_ATTACHMENT0);
  if (gl.CheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
    error = "forest textures: bake framebuffer " + std::to_string(W) + " x " + std::to_string(H) + " incomplete";
    return false;
  }
  gl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
  gl.ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  gl.Enable(GL_DEPTH_TEST);
  gl.DepthFunc(GL_GREATER);
  gl.Disable(GL_CULL_FACE);  // leaf cards and open cones: both sides
  gl.Enable(GL_CLIP_DISTANCE0);
  gl.Enable(GL_CLIP_DISTANCE1);

  std::vector<uint8_t> px(static_cast<size_t>(W) * static_cast<size_t>(H) * 4);
  // Renders with `vp` (world = tree-tile coordinates) and clip planes, box-filters the w x h
  // (output pixels) lower-left region into `dst` columns [x0, x0 + w), top row first.
  const auto bake = [&](const glm::mat4& vp, const glm::vec4& c0, const glm::vec4& c1, int w, int h, Image& dst, int x0,
                        float darken) {
    gl.Viewport(0, 0, w * ss, h * ss);
    const float clear[4] = {0, 0, 0, 0}, far = 0.0f;
    gl.ClearNamedFramebufferfv(fbo, GL_COLOR, 0, clear);
    gl.ClearNamedFramebufferfv(fbo, GL_DEPTH, 0, &far);
    gl.ProgramUniformMatrix4fv(p, drawer.loc.viewProjection, 1, GL_FALSE, glm::value_ptr(vp));
    gl.ProgramUniform4fv(p, drawer.uClip0, 1, glm::value_ptr(c0));
    gl.ProgramUniform4fv(p, drawer.uClip1, 1, glm::value_ptr(c1));
    ForestDrawStats st;
    drawer.draw(inst, ranges, st);
    gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl.ReadPixels(0, 0, w * ss, h * ss, GL_RGBA, GL_UNSIGNED_BYTE, px.data());
    double sum[3] = {0, 0, 0}, covered = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        double c[4] = {0, 0, 0, 0};
        for (int sy = 0; sy < ss; ++sy)
          for (int sx = 0; sx < ss; ++sx) {
            const uint8_t* s = px.data() + (static_cast<size_t>(y * ss + sy) * static_cast<size_t>(w * ss) +
                                            static_cast<size_t>(x * ss + sx)) * 4;
                  const double a = s[3] / 255.0;
            for (int k = 0; k < 3; ++k) c[k] += s[k] * a;
            c[3] += a;
          }
        uint8_t* o = dst.rgba.data() + (static_cast<size_t>(h - 1 - y) * static_cast<size_t>(dst.width) +
                                        static_cast<size_t>(x0 + x)) * 4;
        for (int k = 0; k < 3; ++k) {
          o[k] = c[3] > 0 ? static_cast<uint8_t>(std::clamp(std::lround(c[k] / c[3] * static_cast<double>(darken)), 0L, 255L)) : 0;
          sum[k] += c[k] * static_cast<double>(darken);
        }
        covered += c[3];
        o[3] = static_cast<uint8_t>(std::lround(c[3] / (ss * ss) * 255.0));
      }
    }
    // Uncovered texels take the mean covered colour, so mipmaps do not darken edges.
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        uint8_t* o = dst.rgba.data() + (static_cast<size_t>(y) * static_cast<size_t>(dst.width) +
                                        static_cast<size_t>(x0 + x)) * 4;
        if (o[3] == 0 && covered > 0)
          for (int k = 0; k < 3; ++k) o[k] = static_cast<uint8_t>(std::clamp(std::lround(sum[k] / covered), 0L, 255L));
      }
  };

  out = {};
  out.layerCount = d.layers;
  out.finSlices = d.finSlices;
  out.tile_m = d.tile_m;
  out.height_m = height;
  out.layers.width = layerPx * d.layers;
  out.layers.height = layerPx;
  out.layers.rgba.assign(static_cast<size_t>(out.layers.width) * static_cast<size_t>(out.layers.height) * 4, 0);
  out.fins.width = layerPx * d.finSlices;
  out.fins.height = finH;
  out.fins.rgba.assign(static_cast<size_t>(out.fins.width) * static_cast<size_t>(out.fins.height) * 4, 0);

  const float T = static_cast<float>(d.tile_m), Hm = static_cast<float>(height);
  // Top view: x east, y north, depth: higher is nearer (reverse-Z, 1 at the top).
  glm::mat4 above(0.0f);
  above[0][0] = 2.0f / T;
  above[1][1] = 2.0f / T;
  above[2][2] = 1.0f / (Hm + 1.0f);
  above[3] = glm::vec4(-1.0f, -1.0f, 1.0f / (Hm + 1.0f), 1.0f);
  for (int i = 0; i < d.layers; ++i) {
    const float z0 = Hm * static_cast<float>(i) / static_cast<float>(d.layers);
    const float z1 = Hm * static_cast<float>(i + 1) / static_cast<float>(d.layers);
    // The bottom slab starts below the foot, the top one ends above the crown.
    const glm::vec4 c0(0, 0, 1, i == 0 ? 1.0f : -z0), c1(0, 0, -1, i + 1 == d.layers ? Hm + 1.0f : z1);
    bake(above, c0, c1, layerPx, layerPx, out.layers, i * layerPx, 1.0f);
  }
  // Side view looking north: x east, y up; depth: smaller north is nearer.
  for (int j = 0; j < d.finSlices; ++j) {
    const float y0 = T * static_cast<float>(j) / static_cast<float>(d.finSlices);
    const float y1 = y0 + static_cast<float>(d.finSliceDepth_m);
    glm::mat4 side(0.0f);
    side[0][0] = 2.0f / T;
    side[2][1] = 2.0f / Hm;
    side[1][2] = -1.0f / (y1 - y0 + 2.0f);
    side[3] = glm::vec4(-1.0f, -1.0f, (y1 + 1.0f) / (y1 - y0 + 2.0f), 1.0f);
    bake(side, glm::vec4(0, 1, 0, -y0), glm::vec4(0, -1, 0, y1), layerPx, finH, out.fins, j * layerPx, 1.0f);
  }

  gl.Disable(GL_CLIP_DISTANCE0);
  gl.Disable(GL_CLIP_DISTANCE1);
  gl.BindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(prevFbo));
  gl.Viewport(prevViewport[0], prevViewport[1], prevViewport[2], prevViewport[3]);
  gl.DepthFunc(static_cast<GLenum>(prevDepthFunc));
  if (!depthTest) gl.Disable(GL_DEPTH_TEST);
  if (cull) gl.Enable(GL_CULL_FACE);
  const std::string e = glErrors();
  if (!e.empty()) {
    error = "forest textures: GL errors " + e;
    return false;
  }
  return true;
}

struct ForestPass::Impl {
  ForestPassDesc desc;
  TreeDrawer trees;
  GlProgram layerProgram, finProgram;
  Locations layerLoc, finLoc;
  std::vector<GLint> layerFirsts;  // drawLayers over ranges
  std::vector<GLsizei> layerCounts;
  GLint lOffset = -1, lOffsetLow = -1, lLayerStep = -1, lLayerBase = -1, lLayersDrawn = -1, lLayerCount = -1, lMapScale = -1, lMapBias = -1, lTileScale = -1, lTileBias = -1;
  GLint fOffset = -1, fOffsetLow = -1, fMapScale = -1, fTileScale = -1;
  GlVertexArray layerVao, finVao;
  GLuint layerVaoBuffer = 0;
  GlBuffer finBuffer;
  GlTexture grTex, layerTex, finTex;
  // Fewer layers drawn (m < n): T's slabs composited in m groups, made on first use per m.
  Image layerImage;
  std::vector<GlTexture> groupTex;  // [m], empty texture until used
  uint64_t bytes = 0, finBytes = 0;
  int layerCount = 0;
  int finSlices = 1;  // the fin vertices carry a slice index and the height: baked at init
  double tile_m = 24.0, height_m = 20.0;
  glm::dvec2 mapOrigin{0.0}, mapExtent{1.0};
  std::vector<lod::FinGroup> groups;
  std::vector<GLint> firsts;
  std::vector<GLsizei> counts;
  std::vector<uint8_t> groupMarked;  // drawFins: a group named twice is drawn once (all 0 between calls)
  ForestDrawStats stats;

  const GlTexture& groupTexture(int m);  // m in [1, layerCount)
  void setTextures(const ForestTextures& t) {
    const int tw = t.layers.height;
    layerTex = makeArrayTexture(t.layers, tw, t.layerCount, GL_REPEAT);
    layerImage = t.layers;
    groupTex.clear();
    groupTex.resize(static_cast<size_t>(t.layerCount) + 1);
    finTex = makeArrayTexture(t.fins, t.fins.width / t.finSlices, t.finSlices, GL_CLAMP_TO_EDGE);
    layerCount = t.layerCount;
    finSlices = t.finSlices;
    tile_m = t.tile_m;
    height_m = t.height_m;
    bytes = trees.bytes + finBytes + static_cast<uint64_t>(t.layers.rgba.size() + t.fins.rgba.size()) * 4 / 3;
  }
};

// The n slabs of T (side by side in `t`, size x size each) in m groups, group j = slabs
// [j n / m, (j + 1) n / m): each texel the group seen from above, its slabs composited top down
// ("over": colour sum of c a times the transmittance above, alpha 1 - product of (1 - a)); a
// texel no slab covers keeps the top slab's colour at alpha 0 (filtering stays on the forest's hue).
Image compositeLayerGroups(const Image& t, int n, int m) {
  const int size = t.height;
  Image out;
  out.width = size * m;
  out.height = size;
  out.rgba.assign(static_cast<size_t>(out.width) * static_cast<size_t>(size) * 4, 0);
  for (int j = 0; j < m; ++j) {
    const int g0 = j * n / m, g1 = (j + 1) * n / m;
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size; ++x) {
        double c[3] = {0.0, 0.0, 0.0}, trans = 1.0;
        for (int s = g1 - 1; s >= g0; --s) {
          const uint8_t* p = t.rgba.data() + (static_cast<size_t>(y) * static_cast<size_t>(t.width) +
                                              static_cast<size_t>(s) * static_cast<size_t>(size) + static_cast<size_t>(x)) * 4;
          const double a = p[3] / 255.0;
          for (int k = 0; k < 3; ++k) c[k] += trans * a * p[k];
          trans *= 1.0 - a;
        }
        const double alpha = 1.0 - trans;
        const uint8_t* top = t.rgba.data() + (static_cast<size_t>(y) * static_cast<size_t>(t.width) +
                                              static_cast<size_t>(g1 - 1) * static_cast<size_t>(size) + static_cast<size_t>(x)) * 4;
        uint8_t* q = out.rgba.data() + (static_cast<size_t>(y) * static_cast<size_t>(out.width) +
                                        static_cast<size_t>(j) * static_cast<size_t>(size) + static_cast<size_t>(x)) * 4;
        for (int k = 0; k < 3; ++k)
          q[k] = alpha > 1e-6 ? static_cast<uint8_t>(std::clamp(std::lround(c[k] / alpha), 0L, 255L)) : top[k];
        q[3] = static_cast<uint8_t>(std::clamp(std::lround(alpha * 255.0), 0L, 255L));
      }
  }
  return out;
}

const GlTexture& ForestPass::Impl::groupTexture(int m) {
  GlTexture& t = groupTex[static_cast<size_t>(m)];
  if (t.id() == 0) {
    const Image img = compositeLayerGroups(layerImage, layerCount, m);
    t = makeArrayTexture(img, img.height, m, GL_REPEAT);
    bytes += static_cast<uint64_t>(img.rgba.size()) * 4 / 3;
  }
  return t;
}

ForestPass::ForestPass() = default;
ForestPass::~ForestPass() = default;

bool ForestPass::init(const ForestPassDesc& desc, const lod::ForestMap& map, const ForestTextures& textures,
                      std::span<const lod::TreeMesh> models, const lod::FinSet* fins, std::string& error) {
  if (!lod::validateForestMap(map, error) || !validateForestTextures(textures, error) ||
      !lod::validateForestFades(desc.farFade, desc.nearFade, error))
    return false;
  auto m = std::make_unique<Impl>();
  m->desc = desc;
  if (!m->trees.init(models, desc.maxInstances, error)) return false;
  gl.ProgramUniform1f(m->trees.program.id(), m->trees.uYawJitter, desc.yawJitter);
  m->layerProgram = build(kLayerVs, kLayerFs, "layer program", error);
  if (!m->layerProgram) return false;
  m->finProgram = build(kFinVs, kFinFs, "fin program", error);
  if (!m->finProgram) return false;
  const GLuint lp = m->layerProgram.id(), fp = m->finProgram.id();
  m->layerLoc.find(lp);
  m->finLoc.find(fp);
  m->lOffset = gl.GetUniformLocation(lp, "uOffset");
  m->lOffsetLow = gl.GetUniformLocation(lp, "uOffsetLow");
  m->lLayerStep = gl.GetUniformLocation(lp, "uLayerStep");
  m->lLayerBase = gl.GetUniformLocation(lp, "uLayerBase");
  m->lLayersDrawn = gl.GetUniformLocation(lp, "uLayersDrawn");
  m->lLayerCount = gl.GetUniformLocation(lp, "uLayerCount");
  m->lMapScale = gl.GetUniformLocation(lp, "uMapScale");
  m->lMapBias = gl.GetUniformLocation(lp, "uMapBias");
  m->lTileScale = gl.GetUniformLocation(lp, "uTileScale");
  m->lTileBias = gl.GetUniformLocation(lp, "uTileBias");
  m->fOffset = gl.GetUniformLocation(fp, "uOffset");
  m->fOffsetLow = gl.GetUniformLocation(fp, "uOffsetLow");
  m->fMapScale = gl.GetUniformLocation(fp, "uMapScale");
  m->fTileScale = gl.GetUniformLocation(fp, "uTileScale");

  // Gr: rgb tint, a = density (0 in glades).
  m->mapOrigin = map.origin_m;
  m->mapExtent = {map.extentEast_m(), map.extentNorth_m()};
  std::vector<uint32_t> gr(map.gr.size());
  for (size_t i = 0; i < gr.size(); ++i) {
    const uint32_t a = (map.gr[i] >> 24) == 0 ? 0u : static_cast<uint32_t>(std::lround(map.density[i] * 255.0f));
    gr[i] = (map.gr[i] & 0xFFFFFFu) | a << 24;
  }
  GLuint tex = 0;
  gl.CreateTextures(GL_TEXTURE_2D, 1, &tex);
  m->grTex = GlTexture(tex);
  const int levels = 1 + static_cast<int>(std::floor(std::log2(std::max(map.width, map.height))));
  gl.TextureStorage2D(tex, levels, GL_RGBA8, map.width, map.height);
  gl.PixelStorei(GL_UNPACK_ALIGNMENT, 4);
  gl.TextureSubImage2D(tex, 0, 0, 0, map.width, map.height, GL_RGBA, GL_UNSIGNED_BYTE, gr.data());
  gl.GenerateTextureMipmap(tex);
  gl.TextureParameteri(tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  gl.TextureParameteri(tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  gl.TextureParameteri(tex, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  gl.TextureParameteri(tex, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  m->finBytes = gr.size() * 4 * 4 / 3;

  // Layer VAO: the terrain vertex layout; the buffer is bound at draw time.
  GLuint vao = 0;
  gl.CreateVertexArrays(1, &vao);
  m->layerVao = GlVertexArray::wrap(vao);
  gl.EnableVertexArrayAttrib(vao, 0);
  gl.VertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, offsetof(lod::TerrainVertex, position));
  gl.VertexArrayAttribBinding(vao, 0, 0);
  gl.EnableVertexArrayAttrib(vao, 1);
  gl.VertexArrayAttribFormat(vao, 1, 3, GL_FLOAT, GL_FALSE, offsetof(lod::TerrainVertex, normal));
  gl.VertexArrayAttribBinding(vao, 1, 0);

  // Fins: two triangles each, positions relative to the map origin.
  if (fins && !fins->fins.empty()) {
    std::vector<FinVertex> v;
    v.reserve(fins->fins.size() * 6);
    const glm::dvec3 o(map.origin_m, 0.0);
    const double finH = textures.height_m;
    for (size_t i = 0; i < fins->fins.size(); ++i) {
      const lod::Fin& f = fins->fins[i];
      const glm::vec3 a(f.a_m - o), b(f.b_m - o), up(0.0f, 0.0f, static_cast<float>(finH));
      const float len = glm::length(glm::vec3(f.b_m - f.a_m));
      const uint32_t h = lod::forestHash(static_cast<uint32_t>(i), 17, 3);
      const float u0 = static_cast<float>((h >> 8) % 1024u) * 0.25f;
      const float slice = static_cast<float>(h % static_cast<uint32_t>(textures.finSlices));
      const auto vert = [&](const glm::vec3& p, float u, float vv) {
        FinVertex fv{};
        fv.position[0] = p.x, fv.position[1] = p.y, fv.position[2] = p.z;
        fv.tangent[0] = f.tangent.x, fv.tangent[1] = f.tangent.y, fv.tangent[2] = f.tangent.z;
        fv.uv[0] = u, fv.uv[1] = vv, fv.uv[2] = slice;
        v.push_back(fv);
      };
      vert(a, u0, 0), vert(b, u0 + len, 0), vert(b + up, u0 + len, 1);
      vert(a, u0, 0), vert(b + up, u0 + len, 1), vert(a + up, u0, 1);
    }
    GLuint id = 0;
    gl.CreateBuffers(1, &id);
    m->finBuffer = GlBuffer::wrap(id);
    const auto nb = static_cast<GLsizeiptr>(v.size() * sizeof(FinVertex));
    gl.NamedBufferStorage(id, nb, v.data(), 0);
    m->finBytes += static_cast<uint64_t>(nb);
    GLuint fv = 0;
    gl.CreateVertexArrays(1, &fv);
    m->finVao = GlVertexArray::wrap(fv);
    gl.VertexArrayVertexBuffer(fv, 0, id, 0, sizeof(FinVertex));
    for (GLuint k = 0; k < 3; ++k) {
      gl.EnableVertexArrayAttrib(fv, k);
      gl.VertexArrayAttribFormat(fv, k, 3, GL_FLOAT, GL_FALSE, static_cast<GLuint>(k * 3 * sizeof(float)));
      gl.VertexArrayAttribBinding(fv, k, 0);
    }
    m->groups = fins->groups;
    m->firsts.resize(m->groups.size());
    m->counts.resize(m->groups.size());
    m->groupMarked.assign(m->groups.size(), 0);
  }
  m->setTextures(textures);
  const std::string e = glErrors();
  if (!e.empty()) {
    error = "forest pass: GL errors during set-up " + e;
    return false;
  }
  impl_ = std::move(m);
  return true;
}

void ForestPass::drawTrees(Renderer& r, std::span<const lod::ForestInstance> instances,
                           std::span<const lod::ForestModelRange> models) {
  if (!impl_) return;
  Impl& m = *impl_;
  if (instances.empty()) return;
  m.trees.loc.set(m.trees.program.id(), viewProjection(r.camera()), r.lighting(), m.desc.farFade);
  ForestDrawStats st;
  {
    const CullAndDepthMaskRestore restore;
    gl.Disable(GL_CULL_FACE);  // leaf cards are single-sided in the models
    gl.DepthMask(GL_TRUE);     // the opaque trees write depth
    gl.Enable(GL_BLEND);
    gl.BlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
    m.trees.draw(instances, models, st);
    gl.Disable(GL_BLEND);
  }
  m.stats.trees += st.trees;
  m.stats.triangles += st.triangles;
  m.stats.drawCalls += st.drawCalls;
  r.addStats(st.triangles, st.drawCalls);
}

void ForestPass::drawLayers(Renderer& r, const glm::dvec3& origin, size_t vertexCount, int layers) {
  const size_t slots = std::min<size_t>(vertexCount / 3, std::numeric_limits<uint32_t>::max());
  const lod::TerrainDrawRange all{0, static_cast<uint32_t>(slots)};
  drawLayers(r, origin, std::span(&all, slots > 0 ? 1 : 0), layers);
}

void ForestPass::drawLayers(Renderer& r, const glm::dvec3& origin, std::span<const lod::TerrainDrawRange> ranges,
                            int layers) {
  if (!impl_) return;
  Impl& m = *impl_;
  const GLuint buffer = r.terrainMeshVertexBuffer();
  const int n = std::min(layers, m.layerCount);
  // The ranges clamped to the terrain mesh buffer (as the terrain pass clamps them): slots past
  // its end are never drawn, and no count overflows GLsizei.
  const size_t limit = r.terrainMeshVertices().size() / 3;
  if (buffer == 0 || n <= 0 || limit == 0) return;
  m.layerFirsts.clear();
  m.layerCounts.clear();
  size_t count = 0;  // vertices
  for (const lod::TerrainDrawRange& rg : ranges) {
    if (rg.count == 0 || rg.first >= limit) continue;
    const size_t c = std::min<size_t>(rg.count, limit - rg.first);
    m.layerFirsts.push_back(static_cast<GLint>(3 * static_cast<size_t>(rg.first)));
    m.layerCounts.push_back(static_cast<GLsizei>(3 * c));
    count += 3 * c;
  }
  if (count == 0) return;
  if (buffer != m.layerVaoBuffer) {
    gl.VertexArrayVertexBuffer(m.layerVao.id(), 0, buffer, 0, sizeof(lod::TerrainVertex));
    m.layerVaoBuffer = buffer;
  }
  const lod::Camera& cam = r.camera();
  const GLuint p = m.layerProgram.id();
  m.layerLoc.set(p, viewProjection(cam), r.lighting(), m.desc.farFade);
  const SplitOffset offset = splitOffset(origin - cam.eye_m);  // the mesh's origin may be ~100 km away
  gl.ProgramUniform3fv(p, m.lOffset, 1, glm::value_ptr(offset.high));
  gl.ProgramUniform3fv(p, m.lOffsetLow, 1, glm::value_ptr(offset.low));
  gl.ProgramUniform1f(p, m.lLayerStep, static_cast<float>(m.height_m / m.layerCount));
  gl.ProgramUniform1i(p, m.lLayersDrawn, n);
  gl.ProgramUniform1i(p, m.lLayerCount, m.layerCount);
  const glm::vec2 mapScale(1.0 / m.mapExtent.x, 1.0 / m.mapExtent.y);
  const glm::vec2 mapBias((origin.x - m.mapOrigin.x) / m.mapExtent.x, (origin.y - m.mapOrigin.y) / m.mapExtent.y);
  gl.ProgramUniform2fv(p, m.lMapScale, 1, glm::value_ptr(mapScale));
  gl.ProgramUniform2fv(p, m.lMapBias, 1, glm::value_ptr(mapBias));
  gl.ProgramUniform1f(p, m.lTileScale, static_cast<float>(1.0 / m.tile_m));
  const auto fract = [&](double v) { return static_cast<float>(v / m.tile_m - std::floor(v / m.tile_m)); };
  const glm::vec2 tileBias(fract(origin.x), fract(origin.y));
  gl.ProgramUniform2fv(p, m.lTileBias, 1, glm::value_ptr(tileBias));
  gl.BindTextureUnit(0, n == m.layerCount ? m.layerTex.id() : m.groupTexture(n).id());
  gl.BindTextureUnit(1, m.grTex.id());
  gl.UseProgram(p);
  gl.BindVertexArray(m.layerVao.id());
  const CullAndDepthMaskRestore restore;
  gl.Enable(GL_BLEND);
  gl.BlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  gl.DepthMask(GL_FALSE);
  gl.Disable(GL_CULL_FACE);  // seen from below inside valleys too
  if (m.layerFirsts.size() == 1) {
    gl.ProgramUniform1i(p, m.lLayerBase, 0);
    gl.DrawArraysInstanced(GL_TRIANGLES, m.layerFirsts[0], m.layerCounts[0], n);
  } else {
    // Several ranges (the terrain's chunks in view): one multi-draw a layer, bottom up as the
    // instanced draw orders them.
    for (int layer = 0; layer < n; ++layer) {
      gl.ProgramUniform1i(p, m.lLayerBase, layer);
      gl.MultiDrawArrays(GL_TRIANGLES, m.layerFirsts.data(), m.layerCounts.data(), static_cast<GLsizei>(m.layerFirsts.size()));
    }
  }
  gl.Disable(GL_BLEND);
  gl.BindVertexArray(0);
  const uint64_t tris = static_cast<uint64_t>(count / 3) * static_cast<uint64_t>(n);
  const uint32_t calls = m.layerFirsts.size() == 1 ? 1u : static_cast<uint32_t>(n);  // one multi-draw a layer
  m.stats.layers = static_cast<uint32_t>(n);
  m.stats.triangles += tris;
  m.stats.drawCalls += calls;
  r.addStats(tris, calls);
}

void ForestPass::drawFins(Renderer& r, std::span<const uint32_t> groups) {
  if (!impl_) return;
  Impl& m = *impl_;
  if (!m.finVao || groups.empty()) return;
  GLsizei k = 0;
  uint64_t fins = 0;
  // Each group at most once: firsts / counts hold one entry per group.
  for (uint32_t g : groups) {
    if (g >= m.groups.size() || m.groups[g].count == 0 || m.groupMarked[g]) continue;
    m.groupMarked[g] = 1;
    m.firsts[static_cast<size_t>(k)] = static_cast<GLint>(m.groups[g].first * 6);
    m.counts[static_cast<size_t>(k)] = static_cast<GLsizei>(m.groups[g].count * 6);
    fins += m.groups[g].count;
    ++k;
  }
  for (uint32_t g : groups) {
    if (g < m.groupMarked.size()) m.groupMarked[g] = 0;
  }
  if (k == 0) return;
  const lod::Camera& cam = r.camera();
  const GLuint p = m.finProgram.id();
  m.finLoc.set(p, viewProjection(cam), r.lighting(), m.desc.farFade);
  const SplitOffset offset = splitOffset(glm::dvec3(m.mapOrigin, 0.0) - cam.eye_m);  // a large map's may be far
  gl.ProgramUniform3fv(p, m.fOffset, 1, glm::value_ptr(offset.high));
  gl.ProgramUniform3fv(p, m.fOffsetLow, 1, glm::value_ptr(offset.low));
  const glm::vec2 mapScale(1.0 / m.mapExtent.x, 1.0 / m.mapExtent.y);
  gl.ProgramUniform2fv(p, m.fMapScale, 1, glm::value_ptr(mapScale));
  gl.ProgramUniform1f(p, m.fTileScale, static_cast<float>(1.0 / m.tile_m));
  gl.BindTextureUnit(0, m.finTex.id());
  gl.BindTextureUnit(1, m.grTex.id());
  gl.UseProgram(p);
  gl.BindVertexArray(m.finVao.id());
  {
    const CullAndDepthMaskRestore restore;
    gl.Enable(GL_BLEND);
    gl.BlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
    gl.DepthMask(GL_FALSE);
    gl.Disable(GL_CULL_FACE);  // two-sided
    gl.MultiDrawArrays(GL_TRIANGLES, m.firsts.data(), m.counts.data(), k);
    gl.Disable(GL_BLEND);
  }
  gl.BindVertexArray(0);
  m.stats.fins += fins;
  m.stats.triangles += fins * 2;
  ++m.stats.drawCalls;
  r.addStats(fins * 2, 1);
}

bool ForestPass::setTextures(const ForestTextures& textures, std::string& error) {
  if (!impl_) {
    error = "forest pass: not initialised";
    return false;
  }
  if (!validateForestTextures(textures, error)) return false;
  // The fins' vertices were made at init with its H (their height) and fin slice count (each
  // fin's slice index): other values would draw them at the wrong height or from slices that
  // are not there.
  if (textures.height_m != impl_->height_m || textures.finSlices != impl_->finSlices) {
    error = "forest textures: height_m = " + std::to_string(textures.height_m) + " with " +
            std::to_string(textures.finSlices) + " fin slices: the pass was made with " + std::to_string(impl_->height_m) +
            " m and " + std::to_string(impl_->finSlices) + " (only the layer count may change)";
    return false;
  }
  impl_->setTextures(textures);
  return true;
}

void ForestPass::prepareLayers(int layers) {
  if (impl_ && layers >= 1 && layers < impl_->layerCount) impl_->groupTexture(layers);
}

ForestDrawStats ForestPass::takeStats() {
  if (!impl_) return {};
  return std::exchange(impl_->stats, ForestDrawStats{});
}
int ForestPass::layerCount() const { return impl_ ? impl_->layerCount : 0; }
uint64_t ForestPass::bufferBytes() const { return impl_ ? impl_->bytes : 0; }
void ForestPass::setFarFade(const lod::FarFade& f) {
  if (impl_) impl_->desc.farFade = f;
}
void ForestPass::setNearFade(const lod::NearFade& f) {
  if (impl_) impl_->desc.nearFade = f;
}

}  // namespace ig::render
