// Dynamic objects with the three strategies of paper 002 and the adaptive choice. See
// dynamic_pass.h.
#include "render/dynamic_pass.h"


#include <algorithm>
#include <array>
#include <limits>
#include <bit>
#include <cmath>
#include <cstring>

#include <glm/gtc/type_ptr.hpp>
#include <glm/mat4x4.hpp>

#include "render/gl.h"
#include "render/renderer.h"
#include "render/split_offset.h"

namespace ig::render {
namespace {


const char* kBoxVs = R"(#version 450 core
layout(location = 0) in vec3 aPosition;   // unit box [-1, 1]^3
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 iAxisX;      // xyz: box x axis * half size; w: centre x - origin
layout(location = 3) in vec4 iAxisY;
layout(location = 4) in vec4 iAxisZ;
layout(location = 5) in vec4 iColor;
uniform mat4 uViewProjection;             // projection * world->camera rotation
uniform vec3 uOriginOffset;               // origin - eye, computed in double, as a float
uniform vec3 uOriginOffsetLow;            // what the float left out (render/split_offset.h)
out vec3 vNormal;
out vec3 vColor;
out vec3 vEyeToPoint;
void main() {
  precise vec3 centre = (vec3(iAxisX.w, iAxisY.w, iAxisZ.w) + uOriginOffset) + uOriginOffsetLow;
  vec3 rel = centre + aPosition.x * iAxisX.xyz + aPosition.y * iAxisY.xyz + aPosition.z * iAxisZ.xyz;
  vNormal = aNormal.x * iAxisX.xyz / max(dot(iAxisX.xyz, iAxisX.xyz), 1e-30) +
            aNormal.y * iAxisY.xyz / max(dot(iAxisY.xyz, iAxisY.xyz), 1e-30) +
            aNormal.z * iAxisZ.xyz / max(dot(iAxisZ.xyz, iAxisZ.xyz), 1e-30);
  vColor = iColor.rgb;
  vEyeToPoint = rel;
  gl_Position = uViewProjection * vec4(rel, 1.0);
}
)";

const char* kBoxFs = R"(#version 450 core
in vec3 vNormal;
in vec3 vColor;
in vec3 vEyeToPoint;
uniform vec3 uSunDirection;
uniform vec3 uSunColor;
uniform float uAmbient;
uniform vec3 uFogColor;
uniform float uFogDensity;
uniform int uWork;                        // material cost: extra shading iterations
uniform float uStateTag;                  // changed between draws by the T_state calibration
out vec4 fragColor;
void main() {
  vec3 n = normalize(vNormal);
  float diffuse = max(dot(n, uSunDirection), 0.0);
  vec3 lit = vColor * (uAmbient + (1.0 - uAmbient) * diffuse * uSunColor);
  float w = 0.0;
  for (int i = 0; i < uWork; ++i) w += sin(gl_FragCoord.x * 0.013 + float(i)) * cos(gl_FragCoord.y * 0.017 - float(i));
  lit *= 1.0 + 1e-6 * w + 1e-9 * uStateTag;
  float fog = exp(-uFogDensity * length(vEyeToPoint));
  fragColor = vec4(mix(uFogColor, lit, fog), 1.0);
}
)";

const char* kQueryVs = R"(#version 450 core
layout(location = 0) in vec3 aPosition;
uniform mat4 uViewProjection;
uniform vec3 uCentre;                     // box centre - eye
uniform vec3 uHalf;
void main() { gl_Position = uViewProjection * vec4(uCentre + aPosition * uHalf, 1.0); }
)";
const char* kQueryFs = R"(#version 450 core
out vec4 fragColor;
void main() { fragColor = vec4(1.0); }
)";

struct DrawCommand {
  GLuint count, instanceCount, firstIndex, baseVertex, baseInstance;
};
static_assert(sizeof(DrawCommand) == 20);

constexpr GLsizei kBoxIndices = 36;
constexpr uint32_t kBoxTriangles = 12;

glm::mat4 viewProjection(const lod::Camera& c) {
  return glm::mat4(lod::projection(c) * glm::dmat4(lod::viewRotation(c)));
}

bool validObject(const DynamicObject& o) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(o.center_m[i]) || !std::isfinite(o.halfSize_m[i]) || o.halfSize_m[i] < 0.0) return false;
  return std::isfinite(o.yaw_deg);
}

lod::Aabb worldBox(const DynamicObject& o) {
  const double a = o.yaw_deg * 0.017453292519943295;
  const double c = std::abs(std::cos(a)), s = std::abs(std::sin(a));
  const glm::dvec3 h(c * o.halfSize_m.x + s * o.halfSize_m.y, s * o.halfSize_m.x + c * o.halfSize_m.y, o.halfSize_m.z);
  return {o.center_m - h, o.center_m + h};
}

}  // namespace

const char* strategyName(DynamicStrategy s) {
  switch (s) {
    case DynamicStrategy::PerCommand: return "percommand";
    case DynamicStrategy::Octree: return "octree";
    case DynamicStrategy::Occlusion: return "occlusion";
    case DynamicStrategy::Adaptive: return "adaptive";
  }
  return "?";
}

struct DynamicPass::Instance {
  float axisX[4], axisY[4], axisZ[4], color[4];
};

struct DynamicPass::Gpu {
  GlProgram program, queryProgram;
  GlBuffer mesh, indices, instances, commands;
  GlVertexArray vao;
  Instance* mappedInstances = nullptr;  // [0, maxObjects): per-frame stream; then node blocks
  DrawCommand* mappedCommands = nullptr;  // [0, maxObjects): per-object; then one per node
  uint32_t blockSlots = 0;
  uint32_t nodeCommands = 0;
  std::vector<Instance> cache;          // per object, written on add / set
  std::vector<GLuint> queries;
  GLuint samplesQuery[2] = {0, 0};
  bool samplesPending[2] = {false, false};
  uint64_t bytes = 0;
  GLint uVp = -1, uOrigin = -1, uOriginLow = -1, uSun = -1, uSunColor = -1, uAmbient = -1, uFogColor = -1, uFogDensity = -1,
        uWork = -1, uStateTag = -1, qVp = -1, qCentre = -1, qHalf = -1;
  ~Gpu() {
    if (!queries.empty()) gl.DeleteQueries(static_cast<GLsizei>(queries.size()), queries.data());
    if (samplesQuery[0]) gl.DeleteQueries(2, samplesQuery);
  }
};

DynamicPass::DynamicPass() = default;
DynamicPass::~DynamicPass() = default;

bool DynamicPass::init(const DynamicPassConfig& config, std::string& error) {
  if (config.maxObjects == 0 || config.maxObjects > (1u << 24)) {
    error = "dynamic pass: maxObjects = " + std::to_string(config.maxObjects) + ": out of range (1 .. 16777216)";
    return false;
  }
  // Everything is built aside and taken over only once it all succeeded: a failed init leaves
  // the pass as it was (replacing the configuration first kept the old buffers with the new
  // maxObjects, which places node commands and instance blocks beyond them).
  lod::OctreeConfig oc;
  oc.bounds = config.bounds;
  oc.maxDepth = config.octreeDepth;
  oc.maxObjects = config.maxObjects;
  oc.maxNodes = 2 * config.maxObjects + 64;
  oc.expensiveMinObjects = config.testMinObjects;
  oc.occlusionMaxAge = config.resultMaxAge;
  lod::DynamicOctree octree;
  if (!octree.init(oc)) {
    error = "dynamic pass: bad octree bounds or depth (depth " + std::to_string(config.octreeDepth) + ")";
    return false;
  }
  auto g = std::make_unique<Gpu>();
  g->program = buildProgram(kBoxVs, kBoxFs, error);
  if (!g->program) return error = "dynamic pass: " + error, false;
  g->queryProgram = buildProgram(kQueryVs, kQueryFs, error);
  if (!g->queryProgram) return error = "dynamic pass (query boxes): " + error, false;
  const GLuint p = g->program.id(), qp = g->queryProgram.id();
  g->uVp = gl.GetUniformLocation(p, "uViewProjection");
  g->uOrigin = gl.GetUniformLocation(p, "uOriginOffset");
  g->uOriginLow = gl.GetUniformLocation(p, "uOriginOffsetLow");
  g->uSun = gl.GetUniformLocation(p, "uSunDirection");
  g->uSunColor = gl.GetUniformLocation(p, "uSunColor");
  g->uAmbient = gl.GetUniformLocation(p, "uAmbient");
  g->uFogColor = gl.GetUniformLocation(p, "uFogColor");
  g->uFogDensity = gl.GetUniformLocation(p, "uFogDensity");
  g->uWork = gl.GetUniformLocation(p, "uWork");
  g->uStateTag = gl.GetUniformLocation(p, "uStateTag");
  g->qVp = gl.GetUniformLocation(qp, "uViewProjection");
  g->qCentre = gl.GetUniformLocation(qp, "uCentre");
  g->qHalf = gl.GetUniformLocation(qp, "uHalf");

  // Unit box: 24 vertices (per-face normals), 36 indices, counter-clockwise from outside.
  float verts[24 * 6];
  uint16_t idx[36];
  for (int f = 0; f < 6; ++f) {
    const int axis = f / 2;
    const float sign = (f % 2) ? 1.0f : -1.0f;
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    const float cu[4] = {-1, 1, 1, -1}, cv[4] = {-1, -1, 1, 1};
    for (int k = 0; k < 4; ++k) {
      float* o = verts + (f * 4 + k) * 6;
      o[axis] = sign;
      o[u] = cu[k];
      o[v] = sign > 0 ? cv[k] : -cv[k];
      o[3] = o[4] = o[5] = 0.0f;
      o[3 + axis] = sign;
    }
    const uint16_t b = static_cast<uint16_t>(f * 4);
    const uint16_t t[6] = {b, static_cast<uint16_t>(b + 1), static_cast<uint16_t>(b + 2), b, static_cast<uint16_t>(b + 2),
                           static_cast<uint16_t>(b + 3)};
    std::memcpy(idx + f * 6, t, sizeof t);
  }
  GLuint ids[4];
  gl.CreateBuffers(4, ids);
  g->mesh = GlBuffer::wrap(ids[0]);
  g->indices = GlBuffer::wrap(ids[1]);
  g->instances = GlBuffer::wrap(ids[2]);
  g->commands = GlBuffer::wrap(ids[3]);
  gl.NamedBufferStorage(ids[0], sizeof verts, verts, 0);
  gl.NamedBufferStorage(ids[1], sizeof idx, idx, 0);
  g->blockSlots = 2 * config.maxObjects + 1024;
  g->nodeCommands = oc.maxNodes;
  const GLbitfield flags = GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
  const auto ibytes = static_cast<GLsizeiptr>((size_t{config.maxObjects} + g->blockSlots) * sizeof(Instance));
  const auto cbytes = static_cast<GLsizeiptr>((size_t{config.maxObjects} + g->nodeCommands) * sizeof(DrawCommand));
  gl.NamedBufferStorage(ids[2], ibytes, nullptr, flags);
  gl.NamedBufferStorage(ids[3], cbytes, nullptr, flags);
  g->mappedInstances = static_cast<Instance*>(gl.MapNamedBufferRange(ids[2], 0, ibytes, flags));
  g->mappedCommands = static_cast<DrawCommand*>(gl.MapNamedBufferRange(ids[3], 0, cbytes, flags));
  if (!g->mappedInstances || !g->mappedCommands) {
    error = "dynamic pass: cannot map " + std::to_string(ibytes + cbytes) + " bytes of instance/command buffers";
    return false;
  }
  std::memset(static_cast<void*>(g->mappedCommands), 0, static_cast<size_t>(cbytes));
  g->bytes = static_cast<uint64_t>(sizeof verts + sizeof idx) + static_cast<uint64_t>(ibytes + cbytes);
  GLuint vao = 0;
  gl.CreateVertexArrays(1, &vao);
  g->vao = GlVertexArray::wrap(vao);
  gl.VertexArrayVertexBuffer(vao, 0, ids[0], 0, 6 * sizeof(float));
  gl.VertexArrayVertexBuffer(vao, 1, ids[2], 0, sizeof(Instance));
  gl.VertexArrayBindingDivisor(vao, 1, 1);
  gl.VertexArrayElementBuffer(vao, ids[1]);
  for (GLuint a = 0; a < 6; ++a) {
    gl.EnableVertexArrayAttrib(vao, a);
    const GLuint binding = a < 2 ? 0u : 1u;
    const GLuint offset = a < 2 ? a * 3 * sizeof(float) : (a - 2) * 4 * sizeof(float);
    gl.VertexArrayAttribFormat(vao, a, a < 2 ? 3 : 4, GL_FLOAT, GL_FALSE, offset);
    gl.VertexArrayAttribBinding(vao, a, binding);
  }
  g->queries.resize(config.maxQueries);
  if (config.maxQueries) gl.CreateQueries(GL_ANY_SAMPLES_PASSED_CONSERVATIVE, static_cast<GLsizei>(config.maxQueries), g->queries.data());
  gl.CreateQueries(GL_SAMPLES_PASSED, 2, g->samplesQuery);
  g->cache.resize(config.maxObjects);
  const std::string e = glErrors();
  if (!e.empty()) {
    error = "dynamic pass init: GL errors " + e;
    return false;
  }
  config_ = config;
  octree_ = std::move(octree);
  gpu_ = std::move(g);
  objects_.assign(config.maxObjects, DynamicObject{});
  alive_.assign(config.maxObjects, 0);
  idEnd_ = 0;
  freeIds_.clear();
  freeIds_.reserve(config.maxObjects);
  for (uint32_t i = config.maxObjects; i-- > 0;) freeIds_.push_back(i);
  drawList_.assign(oc.maxNodes, 0);
  testList_.assign(oc.maxNodes, 0);
  blockFirst_.assign(oc.maxNodes, kNone);
  blockCap_.assign(oc.maxNodes, 0);
  freeBlocks_.assign(32, {});
  blockTop_ = 0;
  pending_.clear();
  pending_.reserve(config.maxQueries);
  freeQueries_.assign(gpu_->queries.rbegin(), gpu_->queries.rend());
  switcher_ = lod::ModeSwitcher(config.switching);
  fits_.reset();
  return true;
}

uint64_t DynamicPass::bufferBytes() const { return gpu_ ? gpu_->bytes : 0; }

void DynamicPass::writeInstance(uint32_t id) {
  const DynamicObject& o = objects_[id];
  const double a = o.yaw_deg * 0.017453292519943295;
  const glm::dvec3 ax(std::cos(a), std::sin(a), 0.0), ay(-std::sin(a), std::cos(a), 0.0), az(0.0, 0.0, 1.0);
  const glm::dvec3 c = o.center_m - config_.origin_m;
  Instance& in = gpu_->cache[id];
  for (int i = 0; i < 3; ++i) {
    in.axisX[i] = static_cast<float>(ax[i] * o.halfSize_m.x);
    in.axisY[i] = static_cast<float>(ay[i] * o.halfSize_m.y);
    in.axisZ[i] = static_cast<float>(az[i] * o.halfSize_m.z);
  }
  in.axisX[3] = static_cast<float>(c.x);
  in.axisY[3] = static_cast<float>(c.y);
  in.axisZ[3] = static_cast<float>(c.z);
  for (int i = 0; i < 4; ++i) in.color[i] = static_cast<float>((o.rgba >> (8 * i)) & 0xffu) / 255.0f;
}

uint32_t DynamicPass::add(const DynamicObject& o) {
  if (!gpu_ || freeIds_.empty() || !validObject(o)) return kNone;
  const uint32_t id = freeIds_.back();
  if (!octree_.insert(id, worldBox(o))) return kNone;
  freeIds_.pop_back();
  objects_[id] = o;
  alive_[id] = 1;
  idEnd_ = std::max(idEnd_, id + 1);
  writeInstance(id);
  ++movedThisFrame_;
  noteChanged(o);
  return id;
}

bool DynamicPass::set(uint32_t id, const DynamicObject& o) {
  if (!gpu_ || id >= alive_.size() || !alive_[id] || !validObject(o)) return false;
  if (!octree_.move(id, worldBox(o))) return false;
  objects_[id] = o;
  writeInstance(id);
  ++movedThisFrame_;
  noteChanged(o);
  return true;
}

void DynamicPass::noteChanged(const DynamicObject& o) {
  const double radius = glm::length(o.halfSize_m);
  if (radius <= occluderRadius_) return;
  occluderRadius_ = radius;
  occluderCenter_ = o.center_m;
}

// Adaptive, every frame: an object that could hide others (seen under more than ~15 deg: an
// angular radius of 0.13 rad, a few per cent of the screen or more) was added or moved, or the
// view moved or turned since the last estimate: estimate every frame again, and in Occlusion
// mode test every candidate node for resultMaxAge frames (the hidden set is changing).
glm::dvec3 DynamicPass::watchOccluders(const lod::Camera& cam, uint64_t frame) {
  const double d = glm::length(occluderCenter_ - cam.eye_m);
  const bool occluder = occluderRadius_ > 0.0 && occluderRadius_ > 0.13 * std::max(d, occluderRadius_ * 0.5);
  occluderRadius_ = 0.0;
  // The view axis in world coordinates (the rotation's third row).
  const glm::dvec3 forward = glm::transpose(lod::viewRotation(cam))[2];
  // (Before the first estimate there is no earlier view to compare with.)
  const bool viewChanged = nextEstimate_ > 0 && (glm::length(cam.eye_m - estimateEye_) > 1.0 ||
                                                 glm::dot(forward, estimateForward_) < std::cos(glm::radians(2.0)));
  if (occluder) {
    exploreUntil_ = frame + config_.resultMaxAge;
    // A burst (every visible result expired, every candidate tested in Octree mode) at most once
    // per resultMaxAge frames: a large object that moves every frame would otherwise test every
    // node every frame; between bursts the estimate runs every frame (below) on the nodes whose
    // results have gone stale.
    if (occluderFrame_ == kNoFrame || frame >= occluderFrame_ + std::max<uint32_t>(config_.resultMaxAge, 1)) {
      occluderFrame_ = frame;
      octree_.expireVisibleResults(frame);  // they were measured without it
    }
  }
  if (occluder || viewChanged || lastNodeStats_.hiddenEstimate > 0) {
    estimateEvery_ = 1;
    nextEstimate_ = std::min(nextEstimate_, frame);
  }
  return forward;
}

bool DynamicPass::estimateNow(const lod::Camera& cam, const glm::dvec3& forward, uint64_t frame) {
  if (frame < nextEstimate_) return false;
  nextEstimate_ = frame + estimateEvery_;
  estimateEvery_ = std::min<uint32_t>(8, 2 * estimateEvery_);
  estimateEye_ = cam.eye_m;
  estimateForward_ = forward;
  return true;
}

bool DynamicPass::remove(uint32_t id) {
  if (!gpu_ || id >= alive_.size() || !alive_[id]) return false;
  octree_.remove(id);
  alive_[id] = 0;
  freeIds_.push_back(id);
  ++movedThisFrame_;
  return true;
}

void DynamicPass::clear() {
  for (uint32_t id = 0; id < idEnd_; ++id)
    if (alive_[id]) remove(id);
  freeIds_.clear();  // ids are handed out from 0 again
  for (auto i = static_cast<uint32_t>(alive_.size()); i-- > 0;) freeIds_.push_back(i);
  idEnd_ = 0;
}

void DynamicPass::setStrategy(DynamicStrategy s) {
  strategy_ = s;
  if (s == DynamicStrategy::Adaptive) switcher_ = lod::ModeSwitcher(config_.switching);
}

// Rewrites the instance block and the command of every node whose objects changed.
void DynamicPass::rebuildDirtyNodes() {
  Gpu& g = *gpu_;
  uint32_t rewritten = 0;
  const auto dirty = octree_.dirtyNodes();
  for (uint32_t n : dirty) {
    const auto& node = octree_.node(n);
    const auto count = static_cast<uint32_t>(node.objects.size());
    if (count > blockCap_[n]) {
      if (blockFirst_[n] != kNone) freeBlocks_[std::countr_zero(blockCap_[n])].push_back(blockFirst_[n]);
      const uint32_t cap = std::bit_ceil(count);
      const int cls = std::countr_zero(cap);
      if (!freeBlocks_[cls].empty()) {
        blockFirst_[n] = freeBlocks_[cls].back();
        freeBlocks_[cls].pop_back();
      } else if (blockTop_ + cap <= g.blockSlots) {
        blockFirst_[n] = blockTop_;
        blockTop_ += cap;
      } else {
        // Out of block space (fragmentation): start over, every node gets a fresh block.
        for (auto& f : freeBlocks_) f.clear();
        blockTop_ = 0;
        std::fill(blockFirst_.begin(), blockFirst_.end(), kNone);
        std::fill(blockCap_.begin(), blockCap_.end(), 0u);
        for (uint32_t m = 0; m < octree_.nodes().size(); ++m) {
          const auto c = static_cast<uint32_t>(octree_.node(m).objects.size());
          if (c == 0) continue;
          const uint32_t cm = std::bit_ceil(c);
          blockFirst_[m] = blockTop_, blockCap_[m] = cm, blockTop_ += cm;
          Instance* dst = g.mappedInstances + config_.maxObjects + blockFirst_[m];
          for (uint32_t id : octree_.node(m).objects) *dst++ = g.cache[id];
          g.mappedCommands[config_.maxObjects + m] =
              DrawCommand{static_cast<GLuint>(kBoxIndices), c, 0, 0, config_.maxObjects + blockFirst_[m]};
          rewritten += c;
        }
        break;
      }
      blockCap_[n] = cap;
    }
    Instance* dst = g.mappedInstances + config_.maxObjects + (blockFirst_[n] == kNone ? 0 : blockFirst_[n]);
    for (uint32_t id : node.objects) *dst++ = g.cache[id];
    g.mappedCommands[config_.maxObjects + n] = DrawCommand{static_cast<GLuint>(kBoxIndices), count, 0, 0,
                                                           config_.maxObjects + (blockFirst_[n] == kNone ? 0 : blockFirst_[n])};
    rewritten += count;
  }
  stats_.dirtyNodes = static_cast<uint32_t>(dirty.size());
  stats_.rerecorded += rewritten;
  octree_.clearDirty();
}

namespace {
void bindBoxState(GLuint program, GLuint vao, GLuint commands) {
  gl.UseProgram(program);
  gl.BindVertexArray(vao);
  gl.BindBuffer(GL_DRAW_INDIRECT_BUFFER, commands);
}
void unbindBoxState() {
  gl.BindBuffer(GL_DRAW_INDIRECT_BUFFER, 0);
  gl.BindVertexArray(0);
  gl.UseProgram(0);
}
}  // namespace

void DynamicPass::drawPerCommand(Renderer& r) {
  Gpu& g = *gpu_;
  const lod::Frustum frustum = lod::makeFrustum(r.camera());
  const glm::dvec3 eye = r.camera().eye_m;
  uint32_t k = 0;
  for (uint32_t id = 0; id < idEnd_; ++id) {
    if (!alive_[id]) continue;
    ++stats_.frustumTests;
    const lod::Aabb& b = octree_.boxOf(id);
    if (!frustum.intersects({b.min - eye, b.max - eye})) continue;
    g.mappedInstances[k] = g.cache[id];
    g.mappedCommands[k] = DrawCommand{static_cast<GLuint>(kBoxIndices), 1, 0, 0, k};
    ++k;
  }
  stats_.objectsDrawn = k;
  stats_.commands += k;
  stats_.draws += k;
  stats_.triangles += uint64_t{k} * kBoxTriangles;
  if (k == 0) return;
  gl.MultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_SHORT, nullptr, static_cast<GLsizei>(k), 0);
  ++stats_.submissions;
}

void DynamicPass::pollQueries() {
  size_t keep = 0;
  newlyHidden_ = 0;
  const uint32_t maxAge = config_.resultMaxAge;
  for (size_t i = 0; i < pending_.size(); ++i) {
    const Pending p = pending_[i];
    GLuint available = 0;
    gl.GetQueryObjectuiv(p.query, GL_QUERY_RESULT_AVAILABLE, &available);
    if (!available) {
      pending_[keep++] = p;
      continue;
    }
    GLuint passed = 0;
    gl.GetQueryObjectuiv(p.query, GL_QUERY_RESULT, &passed);  // available: does not wait
    const lod::DynamicOctree::Node& node = octree_.node(p.node);
    if (passed == 0 && !(node.occluded && node.resultFrame + maxAge >= p.frame)) newlyHidden_ += node.subtreeCount;
    octree_.setOcclusionResult(p.node, passed != 0, p.frame);
    freeQueries_.push_back(p.query);
    ++stats_.resultsRead;
  }
  pending_.resize(keep);
}

void DynamicPass::issueQueries(Renderer& r, uint64_t frame, uint32_t q, double budget_ns) {
  const auto candidates = std::min<uint32_t>(q, stats_.occlusionTests);
  if (candidates == 0) {
    stats_.occlusionTests = 0;
    return;
  }
  Gpu& g = *gpu_;
  const GLuint qp = g.queryProgram.id();
  const glm::mat4 vp = viewProjection(r.camera());
  // A test's cost: the query and box draw (occlusionTest_ns, calibrated on small nodes) and the
  // box's depth-only fragments; the estimator's nodes are the large ones near the root.
  const lod::Camera& cam = r.camera();
  const glm::dmat4 vpd = lod::projection(cam) * glm::dmat4(lod::viewRotation(cam));
  const lod::PerfConstants& k = config_.constants;
  double spent_ns = 0.0;
  gl.ProgramUniformMatrix4fv(qp, g.qVp, 1, GL_FALSE, glm::value_ptr(vp));
  gl.UseProgram(qp);
  gl.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  gl.DepthMask(GL_FALSE);
  uint32_t issued = 0;
  for (uint32_t i = 0; i < candidates && !freeQueries_.empty(); ++i) {
    const uint32_t n = testList_[i];
    const lod::Aabb& b = octree_.node(n).bounds;
    if (std::isfinite(budget_ns)) {
      std::array<glm::dvec3, 8> corners;
      for (int c = 0; c < 8; ++c)
        corners[static_cast<size_t>(c)] = glm::dvec3((c & 1) ? b.max.x : b.min.x, (c & 2) ? b.max.y : b.min.y, (c & 4) ? b.max.z : b.min.z) - cam.eye_m;
      const double area = lod::projectedBoxArea_px(vpd, corners, r.width(), r.height());
      const double px = area < 0.0 ? static_cast<double>(r.width()) * r.height() : area;
      spent_ns += k.occlusionTest_ns + k.depthFrag_ns * px;
      if (spent_ns > budget_ns && issued > 0) break;
    }
    // The box is grown a little: its faces lie on the faces of the node's own objects, drawn
    // before with the same planes, and with the depth test GL_GREATER a face exactly on them
    // passes no sample (a node whose objects cover its box's faces came back hidden by itself).
    // 1 mm plus 1e-5 of the distance keeps the faces in front of them past float rounding. At
    // most half the box's clearance in front of the near plane: the grown box must not be clipped
    // by it or reach the eye (its faces, culled from inside, would then pass nothing: "hidden").
    const glm::dvec3 centreD = 0.5 * (b.min + b.max) - r.camera().eye_m, halfD = 0.5 * (b.max - b.min);
    const glm::dvec3 forward = glm::transpose(lod::viewRotation(cam)) * glm::dvec3(0.0, 0.0, -1.0);
    const double nearestDepth = glm::dot(forward, centreD) - glm::dot(glm::abs(forward), halfD);
    const double margin = std::min(1e-3 + 1e-5 * (glm::length(centreD) + glm::length(halfD)),
                                   0.5 * std::max(nearestDepth - cam.near_m, 0.0));
    const glm::vec3 centre(centreD);
    const glm::vec3 half(halfD + glm::dvec3(margin));
    gl.ProgramUniform3fv(qp, g.qCentre, 1, glm::value_ptr(centre));
    gl.ProgramUniform3fv(qp, g.qHalf, 1, glm::value_ptr(half));
    const GLuint query = freeQueries_.back();
    freeQueries_.pop_back();
    gl.BeginQuery(GL_ANY_SAMPLES_PASSED_CONSERVATIVE, query);
    gl.DrawElementsBaseVertex(GL_TRIANGLES, kBoxIndices, GL_UNSIGNED_SHORT, nullptr, 0);
    gl.EndQuery(GL_ANY_SAMPLES_PASSED_CONSERVATIVE);
    pending_.push_back({query, n, frame});
    octree_.setQueryPending(n, true);
    ++issued;
  }
  gl.DepthMask(GL_TRUE);
  gl.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  stats_.occlusionTests = issued;
  stats_.triangles += uint64_t{issued} * kBoxTriangles;
}

void DynamicPass::drawNodes(Renderer& r, bool occlusion, uint64_t frame, uint32_t q, double budget_ns) {
  lod::DynamicOctree::Traversal t;
  t.frame = frame;
  t.useOcclusion = occlusion;
  t.eye_m = r.camera().eye_m;
  const auto tr = octree_.traverse(lod::makeFrustum(r.camera()), t, drawList_, testList_);
  stats_.frustumTests += tr.frustumTests;
  stats_.nodesDrawn = tr.drawn;
  stats_.objectsDrawn = static_cast<uint32_t>(tr.objectsDrawn);
  stats_.hiddenEstimate = tr.hiddenObjects;
  stats_.triangles += tr.objectsDrawn * kBoxTriangles;
  for (uint32_t i = 0; i < tr.drawn; ++i) {
    const uintptr_t offset = (size_t{config_.maxObjects} + drawList_[i]) * sizeof(DrawCommand);
    gl.MultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_SHORT, reinterpret_cast<const void*>(offset), 1, 0);
  }
  stats_.submissions += tr.drawn;
  stats_.commands += tr.drawn;  // one pre-built command per node range (all objects are boxes)
  stats_.draws += tr.drawn;
  lastNodeStats_ = stats_;
  lastTraversalFrame_ = frame;
  endSamples();  // one occlusion query target at a time
  stats_.occlusionTests = tr.candidates;  // issueQueries() turns this into the tests issued
  if (occlusion) lastRetests_ = tr.retests;
  if (q > 0) {
    issueQueries(r, frame, q, budget_ns);
  } else {
    stats_.occlusionTests = 0;
  }
}

// Adaptive starts in PerCommand mode, and its first node draw and first occlusion test would
// come at its first switch, in the middle of a run (its first fragment count is taken on this
// frame too, in draw()); on llvmpipe a first use costs ~1 ms (each
// pass's first frame does: shader variants compiled on first use). Both are used once on the
// first frame instead, leaving the image as it is: one node's objects drawn again (the same
// fragments at the same depth as their per-object draws) and one test (a real one, its result
// read as any other).
void DynamicPass::warmUp(Renderer& r, uint64_t frame) {
  uint32_t node = kNone;
  for (uint32_t n = 0; n < octree_.nodes().size() && node == kNone; ++n)
    if (!octree_.node(n).objects.empty()) node = n;
  if (node == kNone) return;  // nothing to draw yet: the next frame tries again
  warmed_ = true;
  endSamples();  // the samples query counts the frame's own fragments only
  rebuildDirtyNodes();
  const uintptr_t offset = (size_t{config_.maxObjects} + node) * sizeof(DrawCommand);
  gl.MultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_SHORT, reinterpret_cast<const void*>(offset), 1, 0);
  ++stats_.submissions;
  ++stats_.draws;
  stats_.triangles += uint64_t{static_cast<uint32_t>(octree_.node(node).objects.size())} * kBoxTriangles;
  testList_[0] = node;
  stats_.occlusionTests = 1;  // one candidate
  issueQueries(r, frame, 1, std::numeric_limits<double>::infinity());
  gl.UseProgram(gpu_->program.id());  // issueQueries leaves the query program bound
}

void DynamicPass::endSamples() {
  if (samplesActive_) gl.EndQuery(GL_SAMPLES_PASSED);
  samplesActive_ = false;
}

void DynamicPass::drawStateChanges(Renderer& r, uint32_t count) {
  if (!gpu_ || octree_.objectCount() == 0) return;
  Gpu& g = *gpu_;
  uint32_t first = 0;
  while (!alive_[first]) ++first;
  g.mappedInstances[0] = g.cache[first];
  const GLuint p = g.program.id();
  const glm::mat4 vp = viewProjection(r.camera());
  gl.ProgramUniformMatrix4fv(p, g.uVp, 1, GL_FALSE, glm::value_ptr(vp));
  const SplitOffset origin = splitOffset(config_.origin_m - r.camera().eye_m);
  gl.ProgramUniform3fv(p, g.uOrigin, 1, glm::value_ptr(origin.high));
  gl.ProgramUniform3fv(p, g.uOriginLow, 1, glm::value_ptr(origin.low));
  bindBoxState(p, g.vao.id(), g.commands.id());
  for (uint32_t i = 0; i < count; ++i) {
    gl.ProgramUniform1f(p, g.uStateTag, static_cast<float>(i & 1u));
    gl.DrawElementsInstancedBaseInstance(GL_TRIANGLES, kBoxIndices, GL_UNSIGNED_SHORT, nullptr, 1, 0);
  }
  unbindBoxState();
  r.addStats(uint64_t{count} * kBoxTriangles, count);
}

void DynamicPass::drawDepthBoxes(Renderer& r, std::span<const lod::Aabb> boxes) {
  if (!gpu_) return;
  Gpu& g = *gpu_;
  const GLuint qp = g.queryProgram.id();
  const glm::mat4 vp = viewProjection(r.camera());
  gl.ProgramUniformMatrix4fv(qp, g.qVp, 1, GL_FALSE, glm::value_ptr(vp));
  gl.UseProgram(qp);
  gl.BindVertexArray(g.vao.id());
  gl.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  gl.DepthMask(GL_FALSE);
  for (const lod::Aabb& b : boxes) {
    const glm::vec3 centre(0.5 * (b.min + b.max) - r.camera().eye_m);
    const glm::vec3 half(0.5 * (b.max - b.min));
    gl.ProgramUniform3fv(qp, g.qCentre, 1, glm::value_ptr(centre));
    gl.ProgramUniform3fv(qp, g.qHalf, 1, glm::value_ptr(half));
    gl.DrawElementsBaseVertex(GL_TRIANGLES, kBoxIndices, GL_UNSIGNED_SHORT, nullptr, 0);
  }
  gl.DepthMask(GL_TRUE);
  gl.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  gl.BindVertexArray(0);
  gl.UseProgram(0);
}

lod::DynamicMode DynamicPass::chooseMode() {
  const lod::PerfConstants& c = config_.constants;
  const double n = octree_.objectCount();
  const DynamicFrameStats& h = lastNodeStats_;
  // Objects in frustum-visible nodes (an upper bound of per-object culling). With occlusion
  // culling on, the hidden ones were not drawn: add them back, T(S) is the frame without tests.
  const bool culled = switcher_.mode() == lod::DynamicMode::Occlusion;
  const double visS = h.objectsDrawn + (culled ? static_cast<double>(h.hiddenEstimate) : 0.0);
  const double nodes = std::max<double>(h.nodesDrawn, 1.0) * (h.objectsDrawn > 0 ? visS / h.objectsDrawn : 1.0);
  const double rewritten = movedEma_ * std::max(1.0, n / std::max<double>(octree_.nonEmptyNodes(), 1.0));
  // Fragments from the samples-passed query (async), scaled with the objects drawn.
  const double frags = static_cast<double>(lastSamples_);
  lod::ModeInputs in;
  // A command costs t_c to record and T_draw in the rasterizer (each command is a draw there):
  // per-object commands pay T_draw per object, node ranges per node.
  in.bufS_ns = visS * (lod::commandCost_ns(c, visS) + c.drawRaster_ns) + c.submit_ns;
  in.fcS_ns = n * c.cull_ns;
  in.bufH_ns = std::min(rewritten, n) * c.rerecord_ns + nodes * (lod::commandCost_ns(c, nodes) + c.drawRaster_ns + c.submit_ns);
  in.fcH_ns = h.frustumTests * c.cull_ns;
  lod::PassLoad all;
  all.triangles = visS * kBoxTriangles;
  all.fragments = frags;
  // The edges, as if the objects drawn were of one size: sum sqrt(A_i) = sqrt(n sum A_i) then
  // (an upper bound for any sizes, by Cauchy-Schwarz); projecting every box would cost more.
  all.edgePx = std::sqrt(frags * visS);
  all.stateChanges = 1;
  all.rerecorded = std::min(rewritten, n);
  all.commands = nodes;
  all.submissions = nodes;
  all.frustumTests = h.frustumTests;
  in.frameAll_ns = lod::predictFrame_ns(c, all, {});
  lod::PassLoad vis = all;
  const double hidden = std::min<double>(static_cast<double>(h.hiddenEstimate), visS);
  const double keep = visS > 0 ? (visS - hidden) / visS : 1.0;
  vis.triangles *= keep;
  vis.edgePx *= keep;
  vis.commands = vis.submissions = std::max(1.0, nodes * keep);
  in.frameVisible_ns = lod::predictFrame_ns(c, vis, {});
  // T_vis(H): the tests that found the hidden objects (the estimator's), not the exploration's.
  const double q = std::max<double>(std::min(lastQ_, estimatorQ_), config_.estimatorTests);
  in.visTests_ns = q * (c.occlusionTest_ns + kBoxTriangles * c.tri_ns);
  lastInputs_ = in;
  return switcher_.update(in);
}

void DynamicPass::draw(Renderer& r, uint64_t frame) {
  stats_ = {};
  if (!gpu_) return;
  Gpu& g = *gpu_;
  movedEma_ = 0.9 * movedEma_ + 0.1 * movedThisFrame_;
  movedThisFrame_ = 0;
  // The samples-passed count of an earlier frame, if it has arrived (never waits).
  for (int i = 0; i < 2; ++i) {
    if (!g.samplesPending[i]) continue;
    GLuint available = 0;
    gl.GetQueryObjectuiv(g.samplesQuery[i], GL_QUERY_RESULT_AVAILABLE, &available);
    if (available) {
      GLuint s = 0;
      gl.GetQueryObjectuiv(g.samplesQuery[i], GL_QUERY_RESULT, &s);
      lastSamples_ = s;
      g.samplesPending[i] = false;
    }
  }
  pollQueries();
  octree_.refresh();

  lod::DynamicMode mode = lod::DynamicMode::Octree;
  uint32_t q = 0;
  bool skipQ = false;  // Octree mode between two estimates: lastQ_ keeps the estimate's q
  double estimateBudget_ns = std::numeric_limits<double>::infinity();
  switch (strategy_) {
    case DynamicStrategy::PerCommand: mode = lod::DynamicMode::PerCommand; break;
    case DynamicStrategy::Octree: mode = lod::DynamicMode::Octree; break;
    case DynamicStrategy::Occlusion: mode = lod::DynamicMode::Occlusion, q = fixedQ_; break;
    case DynamicStrategy::Adaptive: {
      const glm::dvec3 forward = watchOccluders(r.camera(), frame);
      mode = chooseMode();
      const lod::PerfConstants& c = config_.constants;
      if (mode == lod::DynamicMode::Octree || (mode == lod::DynamicMode::PerCommand && warmed_)) {
        // The estimate of hidden objects: tests worth about 5 % of the predicted frame, each
        // costed with its box's fragments (issueQueries stops there); less often while it
        // finds nothing and nothing changed that could hide objects (estimateNow). With
        // per-object commands too (after the warm-up frame): without it a pass that starts
        // there would never see what occlusion culling could save (condition (6)).
        if (frame == occluderFrame_) {
          // An object that could hide others just appeared or moved: test every candidate on
          // this frame (what the fixed occlusion strategy does every frame), so that condition
          // (6) sees next frame what it hides instead of a 5 % sample of it. T_vis(H) is still
          // costed with the estimator's usual q (estimatorQ_, chooseMode).
          q = config_.maxQueries;  // issueQueries stops at the candidates and the free queries
          estimateNow(r.camera(), forward, frame);
        } else if (estimateNow(r.camera(), forward, frame)) {
          estimateBudget_ns = 0.05 * lastInputs_.frameAll_ns;
          const double budget = estimateBudget_ns / std::max(c.occlusionTest_ns, 1.0);
          q = static_cast<uint32_t>(std::clamp(budget, static_cast<double>(config_.estimatorTests), 1024.0));
          estimatorQ_ = q;
        } else {
          q = 0;
          skipQ = true;
        }
      } else if (mode == lod::DynamicMode::Occlusion) {
        // q from (11) once the fits have three distinct q; explore around it every 4 frames.
        lod::OcclusionCoefficients k;
        const uint32_t n0 = octree_.nonEmptyNodes();
        uint32_t base = std::max<uint32_t>(config_.estimatorTests, estimatorQ_);  // enough to find them
        lod::OcclusionCosts t{c.rerecord_ns, c.submit_ns, c.tri_ns, c.occlusionTest_ns};
        if (fits_.solve(k)) base = lod::optimalQ(k, t, n0);
        const double factors[4] = {1.0, 0.5, 1.0, 2.0};
        q = static_cast<uint32_t>(std::lround(std::max(1.0, base * factors[(frame / 4) % 4])));
        // Never fewer than the re-tests of the nodes known hidden: one left out is drawn again
        // once its result is stale, and costs what the test would have saved.
        q = std::min(std::max(q, lastRetests_ + config_.estimatorTests), n0);
        // While the results still find hidden objects that were drawn (more than 2 % of those
        // drawn: a new occluder's shadow is being discovered top-down), go on testing every
        // candidate: q* is fitted for a hidden set that stays, and testing fewer would leave the
        // rest of the shadow drawn for longer.
        if (newlyHidden_ > std::max<uint64_t>(16, lastNodeStats_.objectsDrawn / 50))
          exploreUntil_ = std::max(exploreUntil_, frame + 2);
        // A new occluder: find what it hides at once. Every candidate: interior nodes with no
        // objects of their own are candidates too, so there can be more than n0.
        if (frame < exploreUntil_) q = config_.maxQueries;
      }
      break;
    }
  }
  stats_.mode = mode;
  if (!skipQ) lastQ_ = q;

  const GLuint p = g.program.id();
  const Lighting& l = r.lighting();
  const glm::mat4 vp = viewProjection(r.camera());
  gl.ProgramUniformMatrix4fv(p, g.uVp, 1, GL_FALSE, glm::value_ptr(vp));
  const SplitOffset origin = splitOffset(config_.origin_m - r.camera().eye_m);
  gl.ProgramUniform3fv(p, g.uOrigin, 1, glm::value_ptr(origin.high));
  gl.ProgramUniform3fv(p, g.uOriginLow, 1, glm::value_ptr(origin.low));
  const glm::vec3 sun(l.sunDirection), sunColor(l.sunColor), fogColor(l.fogColor);
  gl.ProgramUniform3fv(p, g.uSun, 1, glm::value_ptr(sun));
  gl.ProgramUniform3fv(p, g.uSunColor, 1, glm::value_ptr(sunColor));
  gl.ProgramUniform1f(p, g.uAmbient, static_cast<float>(l.ambient));
  gl.ProgramUniform3fv(p, g.uFogColor, 1, glm::value_ptr(fogColor));
  gl.ProgramUniform1f(p, g.uFogDensity, l.fog ? static_cast<float>(kFogExtinction / l.fogVisibility_m) : 0.0f);
  gl.ProgramUniform1i(p, g.uWork, static_cast<GLint>(config_.fragmentWork));
  bindBoxState(p, g.vao.id(), g.commands.id());
  const int sq = static_cast<int>(frame & 1u);
  // Adaptive counts the fragments every 32nd frame, and on the frame after an occluder's burst
  // (its fragments are new): counting costs the rasterizer time on every fragment (llvmpipe: 10
  // ... 16 % of a 2 ms frame of boxes), and they change slowly. And on the warm-up frame: the
  // first count costs ~0.6 ms more (see warmUp).
  const bool countNow = frame % 32 == 0 || (occluderFrame_ != kNoFrame && frame == occluderFrame_ + 1) || !warmed_;
  samplesActive_ = ((strategy_ == DynamicStrategy::Adaptive && countNow) || measureSamples_) && !g.samplesPending[sq];
  if (samplesActive_) {
    gl.BeginQuery(GL_SAMPLES_PASSED, g.samplesQuery[sq]);
    g.samplesPending[sq] = true;
  }
  if (mode == lod::DynamicMode::PerCommand) {
    drawPerCommand(r);
    // Node ranges are rebuilt in the octree modes: the dirty nodes stay marked until then. Once
    // condition (5) prefers the octree but not yet by the hysteresis margin, Adaptive keeps them
    // current, so that the switch does not pay for every change since the last octree frame.
    if (strategy_ == DynamicStrategy::Adaptive && lastInputs_.bufS_ns + lastInputs_.fcS_ns > lastInputs_.bufH_ns + lastInputs_.fcH_ns)
      rebuildDirtyNodes();
    if (strategy_ == DynamicStrategy::Adaptive && !warmed_) warmUp(r, frame);
    if (strategy_ == DynamicStrategy::Adaptive && (q > 0 || frame >= lastTraversalFrame_ + 8)) {
      // Node statistics for conditions (5) and (6), every 8 frames and with each estimate of
      // hidden objects: its tests go to the candidate nodes of this traversal, against the depth
      // of the objects just drawn, as in Octree mode.
      lod::DynamicOctree::Traversal t;
      t.frame = frame;
      t.eye_m = r.camera().eye_m;
      const auto tr = octree_.traverse(lod::makeFrustum(r.camera()), t, drawList_, testList_);
      lastNodeStats_.objectsDrawn = static_cast<uint32_t>(tr.objectsDrawn);
      lastNodeStats_.nodesDrawn = tr.drawn;
      lastNodeStats_.frustumTests = tr.frustumTests;
      lastNodeStats_.hiddenEstimate = tr.hiddenObjects;
      lastTraversalFrame_ = frame;
      stats_.hiddenEstimate = tr.hiddenObjects;
      if (q > 0) {
        endSamples();  // one occlusion query target at a time
        stats_.occlusionTests = tr.candidates;  // issueQueries() turns this into the tests issued
        issueQueries(r, frame, q, estimateBudget_ns);
      }
    }
  } else {
    rebuildDirtyNodes();
    drawNodes(r, mode == lod::DynamicMode::Occlusion, frame, q, estimateBudget_ns);
  }
  endSamples();
  unbindBoxState();
  stats_.objects = octree_.objectCount();
  stats_.queriesPending = static_cast<uint32_t>(pending_.size());
  stats_.nonEmptyNodes = octree_.nonEmptyNodes();
  if (strategy_ == DynamicStrategy::Adaptive && mode == lod::DynamicMode::Occlusion && (frame % 4) >= 2) {
    const lod::PerfConstants& c = config_.constants;
    lod::PassLoad s;
    s.triangles = static_cast<double>(stats_.triangles);
    s.fragments = static_cast<double>(lastSamples_);
    const double gpu = std::max(s.triangles * c.tri_ns, s.fragments * c.frag_ns);
    fits_.add(stats_.occlusionTests, stats_.rerecorded + stats_.occlusionTests, stats_.submissions,
              c.tri_ns > 0 ? gpu / c.tri_ns : 0.0);
  }
  if (strategy_ == DynamicStrategy::Adaptive) stats_.predicted_ns = lastInputs_.frameAll_ns;
  r.addStats(stats_.triangles, stats_.draws);
}

}  // namespace ig::render
