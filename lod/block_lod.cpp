#include "lod/block_lod.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace ig::lod {
namespace {

// Signed double area of a grid triangle (x, y); > 0 is counter-clockwise seen from above.
constexpr double kInf = std::numeric_limits<double>::infinity();

int64_t area2(const RoamTriangle& t) {
  return static_cast<int64_t>(t.v[1].x - t.v[0].x) * (t.v[2].y - t.v[0].y) -
         static_cast<int64_t>(t.v[2].x - t.v[0].x) * (t.v[1].y - t.v[0].y);
}

}  // namespace

BlockLod::BlockLod(std::span<const float> heights_m, int width, int height, double spacing_m,
                   const glm::dvec3& origin_m, const BlockLodConfig& config)
    : heights_m_(heights_m.data()), width_(width), height_(height), spacing_m_(spacing_m), origin_m_(origin_m),
      B_(config.blockQuads) {
  assert(width >= 2 && height >= 2 && "BlockLod: need at least 2x2 samples");
  assert(heights_m.size() >= static_cast<size_t>(width) * static_cast<size_t>(height) && "BlockLod: heights too small");
  assert(B_ >= 2 && (B_ & (B_ - 1)) == 0 && "BlockLod: blockQuads must be a power of two >= 2");
  blocksX_ = (width - 1 + B_ - 1) / B_;
  blocksY_ = (height - 1 + B_ - 1) / B_;
  levels_ = 0;
  while ((1 << levels_) <= B_) ++levels_;  // k = 0 .. log2(B)
  const size_t blocks = static_cast<size_t>(blocksX_) * static_cast<size_t>(blocksY_);
  error_m_.assign(blocks * static_cast<size_t>(levels_), 0.0f);
  zMin_m_.assign(blocks, 0.0f);
  zMax_m_.assign(blocks, 0.0f);
  level_.assign(blocks, 0);
  std::vector<RoamTriangle> scratch(2 * static_cast<size_t>(B_) * static_cast<size_t>(B_) + 8);
  // Largest |mesh - sample| over the DEM samples in triangle t (clamped onto the DEM as drawn).
  auto triangleError = [&](RoamTriangle t) {
    for (auto& v : t.v) {
      v.x = std::clamp(v.x, 0, width_ - 1);
      v.y = std::clamp(v.y, 0, height_ - 1);
    }
    const int64_t d = area2(t);
    if (d == 0) return 0.0f;
    const double z0 = heightAt(t.v[0].x, t.v[0].y), z1 = heightAt(t.v[1].x, t.v[1].y), z2 = heightAt(t.v[2].x, t.v[2].y);
    const int xl = std::min({t.v[0].x, t.v[1].x, t.v[2].x}), xh = std::max({t.v[0].x, t.v[1].x, t.v[2].x});
    const int yl = std::min({t.v[0].y, t.v[1].y, t.v[2].y}), yh = std::max({t.v[0].y, t.v[1].y, t.v[2].y});
    float e = 0.0f;
    for (int y = yl; y <= yh; ++y)
      for (int x = xl; x <= xh; ++x) {
        // Barycentric weights (times d) of (x, y): exact integers; inside or on an edge when
        // all three have the sign of d.
        const int64_t w1 = static_cast<int64_t>(x - t.v[0].x) * (t.v[2].y - t.v[0].y) -
                           static_cast<int64_t>(t.v[2].x - t.v[0].x) * (y - t.v[0].y);
        const int64_t w2 = static_cast<int64_t>(t.v[1].x - t.v[0].x) * (y - t.v[0].y) -
                           static_cast<int64_t>(x - t.v[0].x) * (t.v[1].y - t.v[0].y);
        const int64_t w0 = d - w1 - w2;
        if (d > 0 ? (w0 < 0 || w1 < 0 || w2 < 0) : (w0 > 0 || w1 > 0 || w2 > 0)) continue;
        const double z = (static_cast<double>(w0) * z0 + static_cast<double>(w1) * z1 + static_cast<double>(w2) * z2) /
                         static_cast<double>(d);
        e = std::max(e, static_cast<float>(std::abs(z - static_cast<double>(heightAt(x, y)))));
      }
    return e;
  };
  for (int by = 0; by < blocksY_; ++by) {
    for (int bx = 0; bx < blocksX_; ++bx) {
      const size_t b = static_cast<size_t>(by) * blocksX_ + bx;
      const int x0 = bx * B_, y0 = by * B_;
      float lo = heightAt(x0, y0), hi = lo;
      for (int y = 0; y <= B_; ++y)
        for (int x = 0; x <= B_; ++x) {
          lo = std::min(lo, heightAt(x0 + x, y0 + y));
          hi = std::max(hi, heightAt(x0 + x, y0 + y));
        }
      zMin_m_[b] = lo;
      zMax_m_[b] = hi;
      // Exact error of level k: every DEM sample of the block against the triangles the block
      // draws at that level with neighbours of its own level (the interior quads split along
      // x = y, the border ring zipped, vertices clamped onto the DEM as emitted), made monotone
      // in k. (On the padded grid with every quad split along x = y, the table missed the ring's
      // other diagonal and the clamped blocks at the east / north edge: up to tens of metres.)
      float prev = 0.0f;
      for (int k = 0; k < levels_; ++k) {
        const int s = 1 << k;
        float e = 0.0f;
        if (k > 0) {
          const int steps[4] = {s, s, s, s};
          const size_t n = emitBlockSteps(bx, by, s, steps, scratch);
          for (size_t i = 0; i < n; ++i) e = std::max(e, triangleError(scratch[i]));
        }
        prev = std::max(prev, e);
        error_m_[b * static_cast<size_t>(levels_) + static_cast<size_t>(k)] = prev;
      }
    }
  }
}

float BlockLod::heightAt(int x, int y) const {
  x = std::clamp(x, 0, width_ - 1);
  y = std::clamp(y, 0, height_ - 1);
  return heights_m_[static_cast<size_t>(y) * static_cast<size_t>(width_) + static_cast<size_t>(x)];
}

glm::dvec3 BlockLod::vertexPosition(int x, int y) const {
  const int cx = std::clamp(x, 0, width_ - 1), cy = std::clamp(y, 0, height_ - 1);
  return origin_m_ + glm::dvec3(cx * spacing_m_, cy * spacing_m_, static_cast<double>(heightAt(cx, cy)));
}

Aabb BlockLod::blockBox(int bx, int by) const {
  const size_t b = static_cast<size_t>(by) * blocksX_ + bx;
  const double x0 = std::min(bx * B_, width_ - 1) * spacing_m_, x1 = std::min((bx + 1) * B_, width_ - 1) * spacing_m_;
  const double y0 = std::min(by * B_, height_ - 1) * spacing_m_, y1 = std::min((by + 1) * B_, height_ - 1) * spacing_m_;
  return {{x0, y0, static_cast<double>(zMin_m_[b])}, {x1, y1, static_cast<double>(zMax_m_[b])}};
}

BlockLodStats BlockLod::update(const RoamView& view) {
  BlockLodStats st;
  const Camera& cam = view.camera;
  const glm::dvec3 eye = cam.eye_m - origin_m_;
  // A camera that is not finite cannot cull or measure distances: every block, coarsest. An
  // infinite tolerance is a valid view (any error goes: coarsest), which still culls; a NaN
  // tolerance takes the coarsest level too.
  const bool finite = std::isfinite(eye.x) && std::isfinite(eye.y) && std::isfinite(eye.z) && std::isfinite(cam.fovY_deg) &&
                      validWindowShift(cam);
  const bool refine = finite && !std::isnan(view.tolerance_px);
  Camera rel = cam;
  rel.eye_m = eye;
  const Frustum fr = makeFrustum(rel);
  const double scale = view.viewportHeight_px / (2.0 * std::tan(0.5 * cam.fovY_deg * 3.14159265358979323846 / 180.0));
  for (int by = 0; by < blocksY_; ++by) {
    for (int bx = 0; bx < blocksX_; ++bx) {
      const size_t b = static_cast<size_t>(by) * blocksX_ + bx;
      const Aabb box = blockBox(bx, by);
      if (finite && !fr.intersects({box.min - eye, box.max - eye})) {
        level_[b] = -1;
        continue;
      }
      ++st.blocksVisible;
      const double d = finite ? distanceToBox(box, eye) : 0.0;
      int k = levels_ - 1;
      if (refine) {
        while (k > 0) {
          const double e = error_m_[b * static_cast<size_t>(levels_) + static_cast<size_t>(k)];
          const double px = e <= 0.0 ? 0.0 : (d > 0.0 ? e * scale / d : kInf);
          if (px <= view.tolerance_px) break;
          --k;
        }
      }
      level_[b] = static_cast<int8_t>(k);
      const double e = error_m_[b * static_cast<size_t>(levels_) + static_cast<size_t>(k)];
      if (finite && e > 0.0) st.maxErrorPx = std::max(st.maxErrorPx, d > 0.0 ? e * scale / d : kInf);
    }
  }
  // Triangles: counted by emitting into nothing would allocate; the bound is exact enough
  // for interior quads, so count precisely with a dry run of the border rule instead.
  uint64_t n = 0;
  for (int by = 0; by < blocksY_; ++by)
    for (int bx = 0; bx < blocksX_; ++bx)
      if (level(bx, by) >= 0) n += emitBlock(bx, by, {});
  st.triangles = n;
  return st;
}

int BlockLod::edgeStep(int bx, int by, int nbx, int nby) const {
  const int own = 1 << level(bx, by);
  if (nbx < 0 || nby < 0 || nbx >= blocksX_ || nby >= blocksY_) return own;
  const int k = level(nbx, nby);
  return k < 0 ? own : std::max(own, 1 << k);  // culled neighbours draw nothing: no stitching
}

size_t BlockLod::triangleBound() const {
  size_t n = 0;
  for (int by = 0; by < blocksY_; ++by)
    for (int bx = 0; bx < blocksX_; ++bx)
      if (const int k = level(bx, by); k >= 0) {
        const size_t q = static_cast<size_t>(B_ >> k);
        n += 2 * q * q + 8;
      }
  return n;
}

size_t BlockLod::emitTriangles(std::span<RoamTriangle> out) const {
  assert(out.size() >= triangleBound() && "BlockLod::emitTriangles: output span too small");
  size_t n = 0;
  for (int by = 0; by < blocksY_; ++by)
    for (int bx = 0; bx < blocksX_; ++bx)
      if (level(bx, by) >= 0) n += emitBlock(bx, by, out.subspan(n));
  return n;
}

// Emits one block into `out` (or only counts when `out` is empty).
size_t BlockLod::emitBlock(int bx, int by, std::span<RoamTriangle> out) const {
  const int steps[4] = {edgeStep(bx, by, bx, by - 1), edgeStep(bx, by, bx + 1, by), edgeStep(bx, by, bx, by + 1),
                        edgeStep(bx, by, bx - 1, by)};
  return emitBlockSteps(bx, by, 1 << level(bx, by), steps, out);
}

size_t BlockLod::emitBlockSteps(int bx, int by, int s, const int (&edgeSteps)[4], std::span<RoamTriangle> out) const {
  const int x0 = bx * B_, y0 = by * B_;
  size_t n = 0;
  RoamTriangle* const dst = out.data();  // null when only counting
  auto emit = [&](RoamVertex a, RoamVertex b, RoamVertex c) {
    // Clamp to the DEM (zero-area triangles outside it are dropped), wind CCW.
    RoamTriangle clamped{{a, b, c}};
    for (auto& v : clamped.v) {
      v.x = std::clamp(v.x, 0, width_ - 1);
      v.y = std::clamp(v.y, 0, height_ - 1);
    }
    const int64_t a2 = area2(clamped);
    if (a2 == 0) return;
    if (dst) {
      dst[n].v[0] = a;
      dst[n].v[1] = a2 > 0 ? b : c;
      dst[n].v[2] = a2 > 0 ? c : b;
    }
    ++n;
  };
  const int q = B_ / s;  // quads per side at this level
  if (q == 1) {
    emit({x0, y0}, {x0 + B_, y0}, {x0 + B_, y0 + B_});
    emit({x0, y0}, {x0 + B_, y0 + B_}, {x0, y0 + B_});
    return n;
  }
  // Interior quads (one ring in from the block edge).
  for (int y = s; y < B_ - s; y += s)
    for (int x = s; x < B_ - s; x += s) {
      emit({x0 + x, y0 + y}, {x0 + x + s, y0 + y}, {x0 + x + s, y0 + y + s});
      emit({x0 + x, y0 + y}, {x0 + x + s, y0 + y + s}, {x0 + x, y0 + y + s});
    }
  // Border ring: per side, zip the edge (step = max(own, neighbour)) with the inner row
  // (own step, from s to B - s). The four trapezoids meet on the corner diagonals.
  struct Side {
    int ex, ey, dx, dy;  // edge start and direction (unit grid step)
    int ix, iy;          // inner row start
  };
  const Side sides[4] = {
      {x0, y0, 1, 0, x0 + s, y0 + s},                    // south (edgeSteps[0])
      {x0 + B_, y0, 0, 1, x0 + B_ - s, y0 + s},          // east
      {x0 + B_, y0 + B_, -1, 0, x0 + B_ - s, y0 + B_ - s},  // north
      {x0, y0 + B_, 0, -1, x0 + s, y0 + B_ - s},          // west
  };
  for (int side = 0; side < 4; ++side) {
    const Side& sd = sides[side];
    const int es = edgeSteps[side];
    // Positions along the side: edge vertices at 0, es, ..., B; inner at s, 2s, ..., B - s.
    int ei = 0, ii = s;
    const int innerEnd = B_ - s;
    auto edgeV = [&](int t) { return RoamVertex{sd.ex + sd.dx * t, sd.ey + sd.dy * t}; };
    auto innerV = [&](int t) { return RoamVertex{sd.ix + sd.dx * (t - s), sd.iy + sd.dy * (t - s)}; };
    while (ei < B_ || ii < innerEnd) {
      // Advance the chain whose next vertex comes first along the side (edge on ties).
      const bool advanceEdge = ii >= innerEnd || (ei < B_ && ei + es <= ii + s);
      if (advanceEdge) {
        emit(edgeV(ei), edgeV(ei + es), innerV(ii));
        ei += es;
      } else {
        emit(edgeV(ei), innerV(ii + s), innerV(ii));
        ii += s;
      }
    }
  }
  return n;
}

}  // namespace ig::lod
