// Hierarchical-cells point splats (paper 003). See cells_pass.h.
#include "render/cells_pass.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <vector>

#include <glm/gtc/type_ptr.hpp>
#include <glm/mat4x4.hpp>

#include "lod/view.h"
#include "render/gl.h"
#include "render/renderer.h"
#include "render/split_offset.h"

namespace ig::render {
namespace {

const char* kSplatVs = R"(#version 450 core
layout(location = 0) in vec3 aPosition;   // voxel centre relative to the tree's rootMin
layout(location = 1) in vec4 aColor;      // RGB8 (a: unused, the level's byte)
layout(location = 2) in uint aLevel;      // voxel level q + d
uniform mat4 uViewProjection;             // projection * world->camera rotation
uniform vec3 uRootOffset;                 // rootMin - eye, computed in double, as a float
uniform vec3 uRootOffsetLow;              // what the float left out (render/split_offset.h)
uniform float uRootEdge;                  // m
uniform float uPxPerM;                    // pointScale * viewport height / (2 tan(fovY / 2))
uniform vec2 uPointRange;                 // smallest, largest point side (px)
uniform vec2 uTanHalf;                    // tan of the half field of view across, up
uniform vec2 uWindowShift;                // the window centre's tangents (lod::Camera shiftX, shiftY)
out vec3 vColor;
out vec3 vEyeToPoint;
uniform vec2 uViewport;                   // px
void main() {
  precise vec3 rel = (aPosition + uRootOffset) + uRootOffsetLow;
  vec4 clip = uViewProjection * vec4(rel, 1.0);
  float edge = uRootEdge * exp2(-float(aLevel));
  // Off the view axis a step of one voxel edge in any direction moves the projected centre by
  // up to sqrt(1 + t^2) times the face-on footprint along an axis (t: the centre's offset / depth
  // along it), so neighbouring voxels of a surface seen obliquely towards the frame's sides are
  // that far apart: the side grows with it (1 at the centre, 1.24 at the side of a 45 deg 16:9 view).
  vec2 t = clip.w > 0.0 ? clip.xy / clip.w * uTanHalf + uWindowShift : vec2(0.0);
  float offAxis = sqrt(1.0 + max(t.x * t.x, t.y * t.y));
  float size = clamp(edge * uPxPerM * offAxis / max(clip.w, 1e-6), uPointRange.x, uPointRange.y);
  // A point whose centre is outside the view is discarded even where its square reaches into
  // the viewport, which leaves a border of up to half a point uncovered. Centres less than half
  // a point outside the sides are moved onto the edge (the square then reaches at most half a
  // point past its place, at the frame's border only).
  if (clip.w > 0.0) {
    vec2 ndc = clip.xy / clip.w;
    if (all(lessThan(abs(ndc), vec2(1.0) + size / uViewport))) clip.xy = clamp(ndc, -0.99999, 0.99999) * clip.w;
  }
  gl_Position = clip;
  gl_PointSize = size;
  vColor = aColor.rgb;
  vEyeToPoint = rel;
}
)";

const char* kSplatFs = R"(#version 450 core
in vec3 vColor;
in vec3 vEyeToPoint;
uniform vec3 uFogColor;
uniform float uFogDensity;
uniform float uLight;                     // the time of day's factor on the daylight-baked colour
out vec4 fragColor;
void main() {
  float fog = exp(-uFogDensity * length(vEyeToPoint));
  fragColor = vec4(mix(uFogColor, vColor * uLight, fog), 1.0);
}
)";

constexpr uint32_t kNone = 0xFFFFFFFFu;

// Buddy allocator over `units` granules: blocks of 2^k granules, aligned to their size, split on
// allocation and merged with their buddy on release. An arena that is not a power of two is cut
// into aligned power-of-two chunks (largest first) that never merge with each other. Fixed
// arrays (10 bytes a granule) sized once; no allocation afterwards.
class Buddy {
 public:
  void init(uint32_t units) {
    units_ = units;
    maxOrder_ = units ? std::bit_width(units) - 1 : 0;
    order_.assign(units, -1);
    free_.assign(units, 0);
    next_.assign(units, kNone);
    prev_.assign(units, kNone);
    head_.assign(static_cast<size_t>(maxOrder_) + 1, kNone);
    used_ = 0;
    uint32_t off = 0;
    for (int k = maxOrder_; k >= 0; --k) {
      const uint32_t size = 1u << k;
      while (off + size <= units) {
        push(off, k);
        off += size;
      }
    }
  }
  // Start granule of a block of at least n granules, or kNone.
  uint32_t allocate(uint32_t n) {
    if (n == 0 || n > units_) return kNone;
    const int k = std::bit_width(n - 1);
    if (k > maxOrder_) return kNone;
    int j = k;
    while (j <= maxOrder_ && head_[static_cast<size_t>(j)] == kNone) ++j;
    if (j > maxOrder_) return kNone;
    const uint32_t off = head_[static_cast<size_t>(j)];
    unlink(off);
    while (j > k) {
      --j;
      push(off + (1u << j), j);
    }
    order_[off] = static_cast<int8_t>(k);
    free_[off] = 0;
    used_ += 1u << k;
    return off;
  }
  void release(uint32_t off) {
    int k = order_[off];
    used_ -= 1u << k;
    while (k < maxOrder_) {
      const uint32_t buddy = off ^ (1u << k);
      if (uint64_t{buddy} + (1u << k) > units_ || !free_[buddy] || order_[buddy] != k) break;
      unlink(buddy);
      order_[std::max(off, buddy)] = -1;
      off = std::min(off, buddy);
      ++k;
    }
    push(off, k);
  }
  uint32_t blockUnits(uint32_t off) const { return 1u << order_[off]; }
  uint32_t largestBlockUnits() const { return units_ ? 1u << maxOrder_ : 0; }
  uint64_t usedUnits() const { return used_; }

 private:
  void push(uint32_t off, int k) {
    order_[off] = static_cast<int8_t>(k);
    free_[off] = 1;
    const uint32_t h = head_[static_cast<size_t>(k)];
    next_[off] = h;
    prev_[off] = kNone;
    if (h != kNone) prev_[h] = off;
    head_[static_cast<size_t>(k)] = off;
  }
  void unlink(uint32_t off) {
    const auto k = static_cast<size_t>(order_[off]);
    if (prev_[off] != kNone) next_[prev_[off]] = next_[off];
    else head_[k] = next_[off];
    if (next_[off] != kNone) prev_[next_[off]] = prev_[off];
    free_[off] = 0;
  }

  uint32_t units_ = 0;
  int maxOrder_ = 0;
  std::vector<int8_t> order_;   // per granule: the order of the block starting here, -1 if none
  std::vector<uint8_t> free_;   // per granule: the block starting here is free
  std::vector<uint32_t> next_, prev_, head_;
  uint64_t used_ = 0;
};

struct GpuPoint {
  float pos[3];
  uint8_t rgbl[4];  // R, G, B, voxel level
};
static_assert(sizeof(GpuPoint) == CellsPass::kPointBytes);

}  // namespace

struct CellsPass::Impl {
  const lod::CellTree* tree = nullptr;
  CellsPassConfig config;
  GlProgram program;
  GlBuffer arena;
  GlVertexArray vao;
  GpuPoint* mapped = nullptr;
  uint64_t arenaBytes = 0;
  float maxPoint_px = 64.0f;
  Buddy buddy;
  std::vector<uint32_t> block;   // per cell: first granule, kNone when not resident
  std::vector<uint32_t> count;   // per cell: points
  std::vector<uint8_t> isResident;
  std::vector<GLint> firsts;     // per draw (sized to the tree)
  std::vector<GLsizei> counts;
  GLint uViewport = -1, uVp = -1, uRootOffset = -1, uRootOffsetLow = -1, uLight = -1, uRootEdge = -1, uPxPerM = -1, uPointRange = -1, uTanHalf = -1, uWindowShift = -1, uFogColor = -1, uFogDensity = -1;
};

CellsPass::CellsPass() = default;
CellsPass::~CellsPass() = default;

bool CellsPass::init(const lod::CellTree& tree, const CellsPassConfig& config, std::string& error) {
  impl_.reset();
  stats_ = {};
  constexpr uint64_t kUnitBytes = uint64_t{kUnitPoints} * kPointBytes;
  // At most 2^31 points: glMultiDrawArrays takes each cell's first point as a GLint.
  if (config.arenaBytes < 4096 || config.arenaBytes > (uint64_t{1} << 31) * kPointBytes) {
    error = "cells pass: arenaBytes = " + std::to_string(config.arenaBytes) +
            ": allowed range 4096 .. 2^35 (2^31 points, GL's largest first vertex)";
    return false;
  }
  if (!(config.pointScale > 0.0f) || !std::isfinite(config.pointScale)) {
    error = "cells pass: pointScale = " + std::to_string(config.pointScale) + ": must be finite and > 0";
    return false;
  }
  if (!(config.minPoint_px >= 1.0f) || !std::isfinite(config.minPoint_px)) {
    error = "cells pass: minPoint_px = " + std::to_string(config.minPoint_px) + ": must be finite and >= 1";
    return false;
  }
  if (tree.empty()) {
    error = "cells pass: the cell tree is empty";
    return false;
  }
  auto g = std::make_unique<Impl>();
  g->tree = &tree;
  g->config = config;
  g->program = buildProgram(kSplatVs, kSplatFs, error);
  if (!g->program) return error = "cells pass: " + error, false;
  const GLuint p = g->program.id();
  g->uVp = gl.GetUniformLocation(p, "uViewProjection");
  g->uViewport = gl.GetUniformLocation(p, "uViewport");
  g->uRootOffset = gl.GetUniformLocation(p, "uRootOffset");
  g->uRootOffsetLow = gl.GetUniformLocation(p, "uRootOffsetLow");
  g->uLight = gl.GetUniformLocation(p, "uLight");
  g->uRootEdge = gl.GetUniformLocation(p, "uRootEdge");
  g->uPxPerM = gl.GetUniformLocation(p, "uPxPerM");
  g->uPointRange = gl.GetUniformLocation(p, "uPointRange");
  g->uTanHalf = gl.GetUniformLocation(p, "uTanHalf");
  g->uWindowShift = gl.GetUniformLocation(p, "uWindowShift");
  g->uFogColor = gl.GetUniformLocation(p, "uFogColor");
  g->uFogDensity = gl.GetUniformLocation(p, "uFogDensity");
  GLint range[2] = {1, 64};
  gl.GetIntegerv(GL_POINT_SIZE_RANGE, range);
  g->maxPoint_px = static_cast<float>(std::max(range[1], 1));

  const uint32_t units = static_cast<uint32_t>(config.arenaBytes / kUnitBytes);
  g->arenaBytes = uint64_t{units} * kUnitBytes;
  GLuint buf = 0;
  gl.CreateBuffers(1, &buf);
  g->arena = GlBuffer::wrap(buf);
  const GLbitfield flags = GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
  gl.NamedBufferStorage(buf, static_cast<GLsizeiptr>(g->arenaBytes), nullptr, flags);
  g->mapped = static_cast<GpuPoint*>(gl.MapNamedBufferRange(buf, 0, static_cast<GLsizeiptr>(g->arenaBytes), flags));
  if (!g->mapped) {
    error = "cells pass: cannot map an arena of " + std::to_string(g->arenaBytes) + " bytes: " + glErrors();
    return false;
  }
  GLuint vao = 0;
  gl.CreateVertexArrays(1, &vao);
  g->vao = GlVertexArray::wrap(vao);
  gl.VertexArrayVertexBuffer(vao, 0, buf, 0, sizeof(GpuPoint));
  gl.EnableVertexArrayAttrib(vao, 0);
  gl.VertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
  gl.VertexArrayAttribBinding(vao, 0, 0);
  gl.EnableVertexArrayAttrib(vao, 1);
  gl.VertexArrayAttribFormat(vao, 1, 4, GL_UNSIGNED_BYTE, GL_TRUE, 12);
  gl.VertexArrayAttribBinding(vao, 1, 0);
  gl.EnableVertexArrayAttrib(vao, 2);
  gl.VertexArrayAttribIFormat(vao, 2, 1, GL_UNSIGNED_BYTE, 15);
  gl.VertexArrayAttribBinding(vao, 2, 0);
  const std::string e = glErrors();
  if (!e.empty()) {
    error = "cells pass init: GL errors " + e;
    return false;
  }
  g->buddy.init(units);
  const size_t n = tree.size();
  g->block.assign(n, kNone);
  g->count.assign(n, 0);
  g->isResident.assign(n, 0);
  g->firsts.assign(n, 0);
  g->counts.assign(n, 0);
  impl_ = std::move(g);
  return true;
}

bool CellsPass::upload(uint32_t cell, std::span<const lod::CellPoint> points) {
  if (!impl_ || cell >= impl_->block.size()) return false;
  Impl& g = *impl_;
  evict(cell);
  if (points.empty()) {
    g.isResident[cell] = 1;
    return true;
  }
  if (points.size() > uint64_t{kNone}) return false;
  const auto n = static_cast<uint32_t>(points.size());
  const uint32_t b = g.buddy.allocate((n + kUnitPoints - 1) / kUnitPoints);
  if (b == kNone) return false;
  const int level = g.tree->level(cell) + g.tree->info().cellVoxelDepth;
  GpuPoint* dst = g.mapped + size_t{b} * kUnitPoints;
  for (uint32_t i = 0; i < n; ++i) {
    const lod::CellPoint& s = points[i];
    GpuPoint& d = dst[i];
    d.pos[0] = s.pos.x;
    d.pos[1] = s.pos.y;
    d.pos[2] = s.pos.z;
    d.rgbl[0] = static_cast<uint8_t>(s.rgba);
    d.rgbl[1] = static_cast<uint8_t>(s.rgba >> 8);
    d.rgbl[2] = static_cast<uint8_t>(s.rgba >> 16);
    d.rgbl[3] = static_cast<uint8_t>(level);
  }
  g.block[cell] = b;
  g.count[cell] = n;
  g.isResident[cell] = 1;
  return true;
}

void CellsPass::evict(uint32_t cell) {
  if (!impl_ || cell >= impl_->block.size()) return;
  Impl& g = *impl_;
  if (g.block[cell] != kNone) g.buddy.release(g.block[cell]);
  g.block[cell] = kNone;
  g.count[cell] = 0;
  g.isResident[cell] = 0;
}

void CellsPass::evictAll() {
  if (!impl_) return;
  for (uint32_t c = 0; c < impl_->block.size(); ++c)
    if (impl_->isResident[c]) evict(c);
}

bool CellsPass::resident(uint32_t cell) const {
  return impl_ && cell < impl_->isResident.size() && impl_->isResident[cell] != 0;
}

uint64_t CellsPass::bytesUsed() const {
  return impl_ ? impl_->buddy.usedUnits() * kUnitPoints * kPointBytes : 0;
}
uint64_t CellsPass::largestCellPoints() const {
  return impl_ ? uint64_t{impl_->buddy.largestBlockUnits()} * kUnitPoints : 0;
}
uint64_t CellsPass::capacityBytes() const { return impl_ ? impl_->arenaBytes : 0; }
uint64_t CellsPass::bufferBytes() const { return impl_ ? impl_->arenaBytes : 0; }

void CellsPass::draw(Renderer& renderer, std::span<const lod::CellDraw> cells) {
  stats_ = {};
  if (!impl_) return;
  Impl& g = *impl_;
  GLsizei k = 0;
  const auto cap = static_cast<GLsizei>(g.firsts.size());
  for (const lod::CellDraw& d : cells) {
    if (d.cell >= g.block.size() || !g.isResident[d.cell]) {
      ++stats_.notResident;
      continue;
    }
    if (g.count[d.cell] == 0 || k >= cap) continue;
    g.firsts[static_cast<size_t>(k)] = static_cast<GLint>(g.block[d.cell] * kUnitPoints);
    g.counts[static_cast<size_t>(k)] = static_cast<GLsizei>(g.count[d.cell]);
    ++k;
    ++stats_.drawnCells;
    stats_.drawnPoints += g.count[d.cell];
  }
  if (k == 0) return;

  const lod::Camera& cam = renderer.camera();
  const glm::mat4 vp(lod::projection(cam) *
                     glm::dmat4(lod::viewRotation(cam)));
  const SplitOffset rootOffset = splitOffset(g.tree->info().rootMin_m - cam.eye_m);
  const double tanHalf = std::tan(0.5 * cam.fovY_deg * 3.14159265358979323846 / 180.0);
  const double pxPerM = renderer.height() / (2.0 * tanHalf);
  const Lighting& l = renderer.lighting();
  const glm::vec3 fogColor(l.fogColor);
  const GLuint p = g.program.id();
  gl.ProgramUniformMatrix4fv(p, g.uVp, 1, GL_FALSE, glm::value_ptr(vp));
  gl.ProgramUniform3fv(p, g.uRootOffset, 1, glm::value_ptr(rootOffset.high));
  gl.ProgramUniform3fv(p, g.uRootOffsetLow, 1, glm::value_ptr(rootOffset.low));
  gl.ProgramUniform1f(p, g.uRootEdge, static_cast<float>(g.tree->info().rootEdge_m));
  gl.ProgramUniform1f(p, g.uPxPerM, static_cast<float>(pxPerM) * g.config.pointScale);
  const float range[2] = {g.config.minPoint_px, std::max(g.maxPoint_px, g.config.minPoint_px)};
  gl.ProgramUniform2fv(p, g.uPointRange, 1, range);
  const float tanHalfXY[2] = {static_cast<float>(tanHalf * cam.aspect), static_cast<float>(tanHalf)};
  gl.ProgramUniform2fv(p, g.uTanHalf, 1, tanHalfXY);
  const float windowShift[2] = {static_cast<float>(cam.shiftX), static_cast<float>(cam.shiftY)};
  gl.ProgramUniform2fv(p, g.uWindowShift, 1, windowShift);
  const float viewport[2] = {static_cast<float>(renderer.width()), static_cast<float>(renderer.height())};
  gl.ProgramUniform2fv(p, g.uViewport, 1, viewport);
  gl.ProgramUniform3fv(p, g.uFogColor, 1, glm::value_ptr(fogColor));
  gl.ProgramUniform1f(p, g.uFogDensity, l.fog ? static_cast<float>(kFogExtinction / l.fogVisibility_m) : 0.0f);
  // The colours are baked in daylight, 0.3 ambient + 0.7 sun (igtool cells-build): each part
  // dimmed as the frame's (render::daylight): 1 by day (the image unchanged), 0.045 at night.
  const double day = std::clamp(l.daylight, 0.0, 1.0);
  gl.ProgramUniform1f(p, g.uLight, static_cast<float>(0.3 * ambientScale(day) + 0.7 * day));

  GLboolean pointSizeWasOn = GL_FALSE;
  gl.GetBooleanv(GL_PROGRAM_POINT_SIZE, &pointSizeWasOn);
  if (!pointSizeWasOn) gl.Enable(GL_PROGRAM_POINT_SIZE);
  gl.UseProgram(p);
  gl.BindVertexArray(g.vao.id());
  gl.MultiDrawArrays(GL_POINTS, g.firsts.data(), g.counts.data(), k);
  gl.BindVertexArray(0);
  gl.UseProgram(0);
  if (!pointSizeWasOn) gl.Disable(GL_PROGRAM_POINT_SIZE);
  stats_.drawCalls = 1;
  renderer.addStats(0, 1);
}

}  // namespace ig::render
