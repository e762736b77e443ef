#include "lod/cells_select.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>

#if defined(__SSE2__) && !defined(IG_CELLS_NO_SIMD)
#include <emmintrin.h>
#if defined(__x86_64__)
#include <immintrin.h>
#define IG_CELLS_AVX2 1
#endif
#endif

namespace ig::lod {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;
// Per-frame flags of a cell (set members and per-cell arrays).
constexpr uint8_t kLive = 1;         // in the frustum and V > 0
constexpr uint8_t kInside = 2;       // wholly inside the frustum
constexpr uint8_t kHasChildren = 4;  // static: the cell has children
constexpr uint8_t kCosted = 8;       // per-cell arrays: mc is this frame's
constexpr float kInf = std::numeric_limits<float>::infinity();

bool finite3(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

double pixelsPerRadian(const CellView& v) { return v.viewportHeight_px / (2.0 * std::tan(0.5 * v.camera.fovY_deg * kDeg)); }

// Priority order of the greedy: larger e first, ties by smaller cell index.
bool splitLess(const auto& a, const auto& b) { return a.e < b.e || (a.e == b.e && a.cell > b.cell); }
bool mergeLess(const auto& a, const auto& b) { return a.e > b.e || (a.e == b.e && a.cell < b.cell); }


#if defined(IG_CELLS_AVX2)
[[gnu::target("avx2")]] inline __m256 broadcast8(const std::array<float, 4>& a) {
  return _mm256_broadcast_ss(a.data());
}

// Eight cells at once where the CPU has AVX2: lane for lane the same operations as the SSE2
// quads (no FMA), so the same bits. Returns how many cells it did (a multiple of 8 <= n).
[[gnu::target("avx2")]] uint32_t evalEights(const std::array<float, 4>* lanes, uint32_t n, const float* px,
                                           const float* py, const float* pz, const float* pedge, const uint32_t* pv,
                                           float* pe, uint8_t* pflags) {
  const __m256 rx = broadcast8(lanes[36]), ry = broadcast8(lanes[37]), rz = broadcast8(lanes[38]);
  const __m256 k = broadcast8(lanes[39]), near = broadcast8(lanes[40]);
  const __m256 zero = _mm256_setzero_ps(), sign = _mm256_set1_ps(-0.0f);
  const __m256 all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  static constexpr uint32_t kSpread[16] = {0x0, 0x1, 0x100, 0x101, 0x10000, 0x10001, 0x10100, 0x10101,
                                           0x1000000, 0x1000001, 0x1000100, 0x1000101, 0x1010000, 0x1010001, 0x1010100, 0x1010101};
  uint32_t q = 0;
  for (; q + 8 <= n; q += 8) {
    const __m256 ed = _mm256_loadu_ps(pedge + q);
    const __m256 x0 = _mm256_add_ps(_mm256_loadu_ps(px + q), rx);
    const __m256 y0 = _mm256_add_ps(_mm256_loadu_ps(py + q), ry);
    const __m256 z0 = _mm256_add_ps(_mm256_loadu_ps(pz + q), rz);
    const __m256 dx = _mm256_max_ps(_mm256_max_ps(x0, _mm256_xor_ps(_mm256_add_ps(x0, ed), sign)), zero);
    const __m256 dy = _mm256_max_ps(_mm256_max_ps(y0, _mm256_xor_ps(_mm256_add_ps(y0, ed), sign)), zero);
    const __m256 dz = _mm256_max_ps(_mm256_max_ps(z0, _mm256_xor_ps(_mm256_add_ps(z0, ed), sign)), zero);
    const __m256 d2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)), _mm256_mul_ps(dz, dz));
    const __m256 d = _mm256_max_ps(_mm256_sqrt_ps(d2), near);
    const __m256 e = _mm256_div_ps(_mm256_mul_ps(ed, k), d);
    __m256 out = _mm256_castsi256_ps(
        _mm256_cmpeq_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(pv + q)), _mm256_setzero_si256()));
    __m256 in = all;
    for (size_t i = 0; i < 6; ++i) {
      const __m256 t = _mm256_add_ps(_mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(broadcast8(lanes[i]), x0),
                                                                 _mm256_mul_ps(broadcast8(lanes[6 + i]), y0)),
                                                   _mm256_mul_ps(broadcast8(lanes[12 + i]), z0)),
                                     broadcast8(lanes[18 + i]));
      const __m256 hi = _mm256_add_ps(t, _mm256_mul_ps(ed, broadcast8(lanes[24 + i])));
      const __m256 lo = _mm256_add_ps(t, _mm256_mul_ps(ed, broadcast8(lanes[30 + i])));
      out = _mm256_or_ps(out, _mm256_cmp_ps(hi, zero, _CMP_LT_OQ));
      in = _mm256_and_ps(in, _mm256_cmp_ps(lo, zero, _CMP_GE_OQ));
    }
    _mm256_storeu_ps(pe + q, _mm256_andnot_ps(out, e));
    const int live = ~_mm256_movemask_ps(out) & 255, inside = _mm256_movemask_ps(in) & live;
    uint32_t f[2];
    std::memcpy(f, pflags + q, 8);
    f[0] = (f[0] & 0x04040404u) | kSpread[live & 15] * kLive | kSpread[inside & 15] * kInside;
    f[1] = (f[1] & 0x04040404u) | kSpread[live >> 4] * kLive | kSpread[inside >> 4] * kInside;
    std::memcpy(pflags + q, f, 8);
  }
  return q;
}

const bool kHasAvx2 = [] {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") != 0;
}();
#endif
}  // namespace

// Cells n (rounded up to a multiple of 4: the arrays are padded) four at a time (x, y, z: lowest
// corner relative to the root corner; edge; V): e (0 when not live) and the flags kLive and
// kInside (kHasChildren kept). Every evaluation (the set passes, single cells, evaluateCell) goes
// through this one function, so all give the same bits.
[[gnu::noinline]] void CellSelector::evalCells(const ViewConsts& v, uint32_t n, const float* px, const float* py,
                                               const float* pz, const float* pedge, const uint32_t* pv, float* pe,
                                               uint8_t* pflags) {
#if defined(__SSE2__) && !defined(IG_CELLS_NO_SIMD)
  auto lane = [&](size_t i) { return _mm_load_ps(v.lanes[i].data()); };
  const __m128 rx = lane(36), ry = lane(37), rz = lane(38), k = lane(39), near = lane(40);
  const __m128 zero = _mm_setzero_ps(), sign = _mm_set1_ps(-0.0f), all = _mm_cmpeq_ps(zero, zero);
  // Lane l -> byte l (x86 is little-endian).
  static constexpr uint32_t kSpread[16] = {0x0, 0x1, 0x100, 0x101, 0x10000, 0x10001, 0x10100, 0x10101,
                                           0x1000000, 0x1000001, 0x1000100, 0x1000101, 0x1010000, 0x1010001, 0x1010100, 0x1010101};
  uint32_t q = 0;
#if defined(IG_CELLS_AVX2)
  if (kHasAvx2 && n >= 8) q = evalEights(&v.lanes[0], n, px, py, pz, pedge, pv, pe, pflags);
#endif
  for (; q < n; q += 4) {
    const __m128 ed = _mm_loadu_ps(pedge + q);
    const __m128 x0 = _mm_add_ps(_mm_loadu_ps(px + q), rx);
    const __m128 y0 = _mm_add_ps(_mm_loadu_ps(py + q), ry);
    const __m128 z0 = _mm_add_ps(_mm_loadu_ps(pz + q), rz);
    const __m128 dx = _mm_max_ps(_mm_max_ps(x0, _mm_xor_ps(_mm_add_ps(x0, ed), sign)), zero);
    const __m128 dy = _mm_max_ps(_mm_max_ps(y0, _mm_xor_ps(_mm_add_ps(y0, ed), sign)), zero);
    const __m128 dz = _mm_max_ps(_mm_max_ps(z0, _mm_xor_ps(_mm_add_ps(z0, ed), sign)), zero);
    const __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
    const __m128 d = _mm_max_ps(_mm_sqrt_ps(d2), near);
    const __m128 e = _mm_div_ps(_mm_mul_ps(ed, k), d);
    __m128 out = _mm_castsi128_ps(
        _mm_cmpeq_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(pv + q)), _mm_setzero_si128()));
    __m128 in = all;
    for (size_t i = 0; i < 6; ++i) {
      const __m128 t = _mm_add_ps(
          _mm_add_ps(_mm_add_ps(_mm_mul_ps(lane(i), x0), _mm_mul_ps(lane(6 + i), y0)), _mm_mul_ps(lane(12 + i), z0)),
          lane(18 + i));
      out = _mm_or_ps(out, _mm_cmplt_ps(_mm_add_ps(t, _mm_mul_ps(ed, lane(24 + i))), zero));
      in = _mm_and_ps(in, _mm_cmpge_ps(_mm_add_ps(t, _mm_mul_ps(ed, lane(30 + i))), zero));
    }
    _mm_storeu_ps(pe + q, _mm_andnot_ps(out, e));
    const int live = ~_mm_movemask_ps(out) & 15, inside = _mm_movemask_ps(in) & live;
    uint32_t f;
    std::memcpy(&f, pflags + q, 4);
    f = (f & 0x04040404u) | kSpread[live] * kLive | kSpread[inside] * kInside;
    std::memcpy(pflags + q, &f, 4);
  }
#else
  for (uint32_t l = 0; l < (n + 3) / 4 * 4; ++l) {
    const float ed = pedge[l], x0 = px[l] + v.rx, y0 = py[l] + v.ry, z0 = pz[l] + v.rz;
    const float dx = std::max(std::max(x0, -(x0 + ed)), 0.0f), dy = std::max(std::max(y0, -(y0 + ed)), 0.0f),
                dz = std::max(std::max(z0, -(z0 + ed)), 0.0f);
    const float d = std::max(std::sqrt((dx * dx + dy * dy) + dz * dz), v.near);
    const float e = (ed * v.k) / d;
    bool o = pv[l] == 0, in = true;
    for (size_t i = 0; i < 6; ++i) {
      const float t = ((v.nx[i] * x0 + v.ny[i] * y0) + v.nz[i] * z0) + v.w[i];
      o = o || t + ed * v.pos[i] < 0.0f;
      in = in && t + ed * v.neg[i] >= 0.0f;
    }
    pe[l] = o ? 0.0f : e;
    pflags[l] = static_cast<uint8_t>((pflags[l] & kHasChildren) | (o ? 0 : kLive) | (!o && in ? kInside : 0));
  }
#endif
}

void CellSelector::makeConsts(const CellTree& tree, const CellView& view, ViewConsts& vc) {
  const Frustum fr = makeFrustum(view.camera);
  for (size_t i = 0; i < 6; ++i) {
    const glm::dvec4& p = fr.planes[i];
    vc.nx[i] = static_cast<float>(p.x);
    vc.ny[i] = static_cast<float>(p.y);
    vc.nz[i] = static_cast<float>(p.z);
    vc.w[i] = static_cast<float>(p.w);
    vc.pos[i] = (std::max(vc.nx[i], 0.0f) + std::max(vc.ny[i], 0.0f)) + std::max(vc.nz[i], 0.0f);
    vc.neg[i] = (std::min(vc.nx[i], 0.0f) + std::min(vc.ny[i], 0.0f)) + std::min(vc.nz[i], 0.0f);
  }
  const glm::dvec3 r = tree.info().rootMin_m - view.camera.eye_m;
  vc.rx = static_cast<float>(r.x);
  vc.ry = static_cast<float>(r.y);
  vc.rz = static_cast<float>(r.z);
  vc.k = static_cast<float>(std::ldexp(pixelsPerRadian(view), -tree.info().cellVoxelDepth));
  vc.near = static_cast<float>(view.camera.near_m);
  for (size_t i = 0; i < 6; ++i) {
    vc.lanes[i].fill(vc.nx[i]);
    vc.lanes[6 + i].fill(vc.ny[i]);
    vc.lanes[12 + i].fill(vc.nz[i]);
    vc.lanes[18 + i].fill(vc.w[i]);
    vc.lanes[24 + i].fill(vc.pos[i]);
    vc.lanes[30 + i].fill(vc.neg[i]);
  }
  vc.lanes[36].fill(vc.rx);
  vc.lanes[37].fill(vc.ry);
  vc.lanes[38].fill(vc.rz);
  vc.lanes[39].fill(vc.k);
  vc.lanes[40].fill(vc.near);
}

CellSelector::Ev CellSelector::evalOne(const CellTree& tree, const ViewConsts& vc, float edge, uint32_t c) {
  const glm::uvec3 k = tree.coord(c);
  const float x = static_cast<float>(k.x) * edge, y = static_cast<float>(k.y) * edge, z = static_cast<float>(k.z) * edge;
  const float xs[4] = {x, x, x, x}, ys[4] = {y, y, y, y}, zs[4] = {z, z, z, z}, es[4] = {edge, edge, edge, edge};
  const uint32_t v = tree.voxels(c), vs[4] = {v, v, v, v};
  const uint8_t f = tree.childCount(c) > 0 ? kHasChildren : 0;
  float e[4];
  uint8_t flags[4] = {f, f, f, f};
  evalCells(vc, 4, xs, ys, zs, es, vs, e, flags);
  return {e[0], flags[0]};
}

bool validCellView(const CellView& v) {
  const Camera& c = v.camera;
  return finite3(c.eye_m) && std::isfinite(c.heading_deg) && std::isfinite(c.pitch_deg) && std::isfinite(c.roll_deg) &&
         c.fovY_deg > 0.0 && c.fovY_deg < 180.0 && c.aspect > 0.0 && std::isfinite(c.aspect) && c.near_m > 0.0 &&
         c.far_m > c.near_m && std::isfinite(c.far_m) && validWindowShift(c) && v.viewportHeight_px > 0.0 && std::isfinite(v.viewportHeight_px) &&
         v.minVoxel_px >= 0.0 && std::isfinite(v.minVoxel_px);
}

CellEval evaluateCell(const CellTree& tree, uint32_t cell, const CellView& view) {
  CellEval out;
  if (!validCellView(view) || cell >= tree.size()) return out;
  CellSelector::ViewConsts vc;
  CellSelector::makeConsts(tree, view, vc);
  const CellSelector::Ev x =
      CellSelector::evalOne(tree, vc, static_cast<float>(tree.cellEdge_m(tree.level(cell))), cell);
  out.live = (x.flags & kLive) != 0;
  out.voxel_px = x.e;
  return out;
}

void CellSelector::CellSet::allocate(size_t capacity) {
  const size_t padded = capacity + 4;
  cell.assign(padded, 0);
  voxels.assign(padded, 0);
  mc.assign(padded, 0);
  x.assign(padded, 0.0f);
  y.assign(padded, 0.0f);
  z.assign(padded, 0.0f);
  edge.assign(padded, 0.0f);
  e.assign(padded, 0.0f);
  flags.assign(padded, 0);
  cert.assign(padded, 0);
  up.assign(padded, kNoCell);
  first.assign(padded, 0);
  n = 0;
}

CellSelector::CellSelector(const CellTree& tree, const CellSelectorConfig& config) : tree_(tree), config_(config) {
  const size_t n = tree.size();
  for (int q = 0; q < tree.levels(); ++q) edgeF_.push_back(static_cast<float>(tree.cellEdge_m(q)));
  node_.resize(n);
  size_t leaves = 0;
  for (uint32_t c = 0; c < n; ++c) {
    Node& d = node_[c];
    const float edge = edgeF_[static_cast<size_t>(tree.level(c))];
    const glm::uvec3 k = tree.coord(c);
    d.x = static_cast<float>(k.x) * edge;
    d.y = static_cast<float>(k.y) * edge;
    d.z = static_cast<float>(k.z) * edge;
    d.voxels = tree.voxels(c);
    d.firstChild = tree.firstChild(c);
    d.childCount = static_cast<uint8_t>(tree.childCount(c));
    d.level = static_cast<uint8_t>(tree.level(c));
    leaves += tree.childCount(c) == 0 ? 1 : 0;
  }
  reqStamp_.assign(n, 0);
  popStamp_.assign(n, 0);
  minBytes_ = n > 0 ? tree.bytes(0) : 0;
  for (uint32_t c = 0; c < n; ++c) minBytes_ = std::min(minBytes_, uint64_t{tree.bytes(c)});
  cut_.allocate(leaves);           // a cut never holds more cells than there are leaves
  mergeable_.allocate(n - leaves);  // nor refined cells more than inner cells
  childSum_.assign(n - leaves + 4, 0);  // the last slot: a spare (see select())
  scratch_.reserve(n);
  evicted_.reserve(leaves);
  unknownCover_.reserve(n);
  parts_[0].covers.reserve(leaves);
  if (config_.runner != nullptr) {
    // At most 2^30 (one chunk for any cut that fits in memory: ~110 bytes a cell), so that neither
    // the rounding nor the chunk counts in runPass() wrap around.
    chunkCells_ = (std::clamp(config_.chunkCells, 8u, 1u << 30) + 7u) / 8u * 8u;
    Part& p1 = parts_[1];
    p1.marks.reserve((leaves + chunkCells_ - 1) / chunkCells_ + (n - leaves + chunkCells_ - 1) / chunkCells_ + 2);
    p1.evicted.reserve(leaves);
    p1.unknown.reserve(n);
    p1.covers.reserve(std::min<size_t>(leaves, chunkCells_));
    p1.splits.reserve(leaves);
    p1.childSum.assign(childSum_.size(), 0);
    drawBuf_.resize(leaves);
  }
  splitHeap_.reserve(2 * n + 64);
  mergeHeap_.reserve(2 * n + 64);
  reset();
}

void CellSelector::reset() {
  for (Node& d : node_) d.state = kBelow;
  cut_.n = 0;
  mergeable_.n = 0;
  lastT_ = 0.0f;
  if (tree_.empty()) return;
  insert(cut_, 0, {0.0f, static_cast<uint8_t>(uint32_t{node_[0].childCount} > 0 ? kHasChildren : 0)}, 0);
  node_[0].state = kCut;
}

uint32_t CellSelector::insert(CellSet& s, uint32_t c, Ev x, uint64_t mc) {
  const uint32_t i = s.n++;
  const Node& d = node_[c];
  s.cell[i] = c;
  s.voxels[i] = d.voxels;
  s.mc[i] = static_cast<uint32_t>(mc);
  s.x[i] = d.x;
  s.y[i] = d.y;
  s.z[i] = d.z;
  s.edge[i] = edgeF_[d.level];
  s.e[i] = x.e;
  s.flags[i] = static_cast<uint8_t>(x.flags | (d.childCount > 0 ? kHasChildren : 0));
  s.cert[i] = 0;
  s.up[i] = kNoCell;
  s.first[i] = d.firstChild;
  node_[c].slot = i;
  if (&s == &mergeable_) setUp(c, i);  // its children (all in the cut) point to it
  return i;
}

void CellSelector::setUp(uint32_t p, uint32_t slot) {
  const uint32_t first = node_[p].firstChild, count = uint32_t{node_[p].childCount};
  for (uint32_t k = 0; k < count; ++k)
    if (node_[first + k].state == kCut) cut_.up[node_[first + k].slot] = slot;
}

void CellSelector::remove(CellSet& s, uint32_t c) {
  const uint32_t i = node_[c].slot, last = --s.n;
  if (&s == &mergeable_) setUp(c, kNoCell);
  // Keep this frame's evaluation of c reachable (covers, realization()); its cost too once the
  // set's costs are this frame's (not while step 2 repairs evictions: the set still holds the
  // last frame's, which the view may have changed: a cell partly outside may be wholly inside).
  node_[c].e = s.e[i];
  node_[c].flags = static_cast<uint8_t>(s.flags[i] | (costsFresh_ ? kCosted : 0));
  node_[c].mc = s.mc[i];
  node_[c].stamp = frame_;
  if (i != last) {
    s.cell[i] = s.cell[last];
    s.voxels[i] = s.voxels[last];
    s.mc[i] = s.mc[last];
    s.x[i] = s.x[last];
    s.y[i] = s.y[last];
    s.z[i] = s.z[last];
    s.edge[i] = s.edge[last];
    s.e[i] = s.e[last];
    s.flags[i] = s.flags[last];
    s.cert[i] = s.cert[last];
    s.up[i] = s.up[last];
    s.first[i] = s.first[last];
    node_[s.cell[i]].slot = i;
    if (&s == &mergeable_) setUp(s.cell[i], i);
  }
}

void CellSelector::prefetchChildren(uint32_t c) const {
  const Node* p = &node_[node_[c].firstChild];
  const uint32_t count = node_[c].childCount;
  for (uint32_t b = 0; b < count * sizeof(Node); b += 64) __builtin_prefetch(reinterpret_cast<const char*>(p) + b);
}

// One pass over a set: e and the frustum flags of every member.
void CellSelector::evaluateSet(CellSet& s) {
  evalCells(vc_, s.n, s.x.data(), s.y.data(), s.z.data(), s.edge.data(), s.voxels.data(), s.e.data(), s.flags.data());
}

// The children of c that are below the cut and not yet evaluated this frame, four at a time.
void CellSelector::evaluateChildren(uint32_t c) {
  const uint32_t first = node_[c].firstChild, count = uint32_t{node_[c].childCount};
  if (count == 0) return;
  const float edge = edgeF_[node_[first].level];
  float x[8], y[8], z[8], ed[8], e[8];
  uint32_t v[8], idx[8];
  uint8_t fl[8];
  uint32_t n = 0;
  for (uint32_t i = 0; i < count; ++i) {
    const uint32_t ch = first + i;
    if (node_[ch].state != kBelow || node_[ch].stamp == frame_) continue;
    const Node& d = node_[ch];
    x[n] = d.x;
    y[n] = d.y;
    z[n] = d.z;
    ed[n] = edge;
    v[n] = d.voxels;
    fl[n] = d.childCount > 0 ? kHasChildren : 0;
    idx[n++] = ch;
  }
  for (uint32_t i = n; i < (n + 3) / 4 * 4; ++i) {
    x[i] = y[i] = z[i] = 0.0f;
    ed[i] = edge;
    v[i] = 0;
    fl[i] = 0;
  }
  evalCells(vc_, n, x, y, z, ed, v, e, fl);
  for (uint32_t i = 0; i < n; ++i) {
    Node& d = node_[idx[i]];
    d.e = e[i];
    d.flags = fl[i];
    d.stamp = frame_;
  }
}

CellSelector::Ev CellSelector::ev(uint32_t c) {
  if (node_[c].state == kCut) return {cut_.e[node_[c].slot], cut_.flags[node_[c].slot]};
  if (node_[c].state == kMergeable) return {mergeable_.e[node_[c].slot], mergeable_.flags[node_[c].slot]};
  if (node_[c].stamp != frame_) {
    const Node& d = node_[c];
    const float edge = edgeF_[d.level];
    const float xs[4] = {d.x, d.x, d.x, d.x}, ys[4] = {d.y, d.y, d.y, d.y}, zs[4] = {d.z, d.z, d.z, d.z},
                es[4] = {edge, edge, edge, edge};
    const uint32_t vs[4] = {d.voxels, d.voxels, d.voxels, d.voxels};
    const uint8_t f = d.childCount > 0 ? kHasChildren : 0;
    float ee[4];
    uint8_t ff[4] = {f, f, f, f};
    evalCells(vc_, 4, xs, ys, zs, es, vs, ee, ff);
    const Ev x{ee[0], ff[0]};
    node_[c].e = x.e;
    node_[c].flags = x.flags;
    node_[c].stamp = frame_;
  }
  return {node_[c].e, node_[c].flags};
}

CellSelector::Ev CellSelector::evConst(uint32_t c) const {
  if (node_[c].state == kCut) return {cut_.e[node_[c].slot], cut_.flags[node_[c].slot]};
  if (node_[c].state == kMergeable) return {mergeable_.e[node_[c].slot], mergeable_.flags[node_[c].slot]};
  if (node_[c].stamp != frame_) return {0.0f, 0};
  return {node_[c].e, node_[c].flags};
}

bool CellSelector::refinable(uint32_t, Ev x) const { return (x.flags & kLive) && (x.flags & kHasChildren) && x.e > alpha_; }
bool CellSelector::drawable(uint32_t c, Ev x) const { return !(x.flags & kLive) || resident(c); }

bool CellSelector::childrenDrawable(uint32_t c) {
  const uint32_t first = node_[c].firstChild, count = uint32_t{node_[c].childCount};
  for (uint32_t i = 0; i < count; ++i)
    if (!drawable(first + i, ev(first + i))) return false;
  return true;
}

// mc(c) = min(V, sum mc(children)) for a live refinable cell cut by the frustum boundary (a cell
// wholly inside has mc = V: every descendant is live and octree images are monotone).
uint64_t CellSelector::coverCost(uint32_t c, Ev x, std::vector<uint32_t>& unknown) {
  const uint64_t v = node_[c].voxels;
  if (!(x.flags & kLive)) return 0;
  if ((x.flags & kInside) || !refinable(c, x)) return v;
  evaluateChildren(c);
  const uint32_t first = node_[c].firstChild, count = uint32_t{node_[c].childCount};
  Node* const kids = &node_[first];
  bool below = true;
  for (uint32_t i = 0; i < count; ++i) below = below && kids[i].state == kBelow;
  if (below) {
    // The usual case (c is in the cut or below it): the children's evaluation is in their nodes,
    // read once. The same steps as the general case below, in the same order.
    uint64_t sum = 0;
    bool drawableAll = true;
    for (uint32_t i = 0; i < count; ++i) {
      const uint8_t f = kids[i].flags;
      sum += (f & kInside) ? kids[i].voxels : 0;
      drawableAll = drawableAll && (!(f & kLive) || resident(first + i));
    }
    if (sum >= v) return v;
    if (!drawableAll) {
      if (unknown.size() < unknown.capacity()) unknown.push_back(c);
      return v;
    }
    uint32_t deferred = 0;
    for (uint32_t i = 0; i < count; ++i) {
      Node& d = kids[i];
      const uint8_t f = d.flags;
      if (f & kInside) continue;
      if (f & kCosted) {
        sum += d.mc;
      } else if ((f & kLive) && (f & kHasChildren) && d.e > alpha_) {
        prefetchChildren(first + i);
        deferred |= 1u << i;
      } else {
        const uint32_t mc = (f & kLive) ? d.voxels : 0;  // a live cell that is not refinable: V; outside: 0
        d.mc = mc;
        d.flags = static_cast<uint8_t>(f | kCosted);
        sum += mc;
      }
    }
    for (uint32_t i = 0; i < count && deferred != 0 && sum < v; ++i) {
      if (!((deferred >> i) & 1)) continue;
      sum += cost(first + i, unknown);
      deferred &= ~(1u << i);
    }
    return std::min(v, sum);
  }
  // Children wholly inside cost their V: when these already reach V(c), no cover is cheaper.
  uint64_t sum = 0;
  for (uint32_t i = 0; i < count; ++i)
    if (ev(first + i).flags & kInside) sum += node_[first + i].voxels;
  if (sum >= v) return v;
  if (!childrenDrawable(c)) {
    if (unknown.size() < unknown.capacity()) unknown.push_back(c);
    return v;
  }
  // The other children: plain ones first (outside: 0, not refinable: V), then those cut by the
  // frustum boundary while the sum stays below V.
  uint32_t deferred = 0;
  for (uint32_t i = 0; i < count; ++i) {
    const uint32_t ch = first + i;
    const Ev y = ev(ch);
    if (y.flags & kInside) continue;
    if ((y.flags & kLive) && refinable(ch, y) && node_[ch].state == kBelow && !costed(ch)) {
      prefetchChildren(ch);
      ++deferred;
      continue;
    }
    sum += cost(ch, unknown);
  }
  for (uint32_t i = 0; i < count && deferred > 0 && sum < v; ++i) {
    const uint32_t ch = first + i;
    const Ev y = ev(ch);
    if (!(y.flags & kInside) && (y.flags & kLive) && refinable(ch, y) && node_[ch].state == kBelow && !costed(ch)) {
      sum += cost(ch, unknown);
      --deferred;
    }
  }
  return std::min(v, sum);
}

// Certificates. A cut cell c cut by the frustum boundary usually costs V. Cells wholly inside
// the frustum cost their V whatever the cover (covers only grow inside the frustum), so with S a
// set of wholly inside children and grandchildren,
//     mc(c) >= sum over children ch of (ch in S ? V(ch) : min(V(ch), sum of V over its grandchildren in S)),
// and when that reaches V(c), mc(c) = V(c). Such an S (up to 8 boxes, chosen when c's cover was
// last computed) is kept with c; while its boxes stay wholly inside, mc(c) = V(c) without looking
// at the tree. A box code: bits 0-2 the child's octant, bits 3-5 the grandchild's, bit 6 set for
// a grandchild, bit 7 set for a live leaf (costs V: tested live on a shrunk box) rather than a
// wholly inside cell; up to 7 codes, their count in the top byte; 0: none.
uint64_t CellSelector::makeCertificate(uint32_t c) {
  struct Piece {
    uint64_t value;
    uint32_t boxes;
    uint8_t code[8];
  };
  // A child's octant in its parent, from the corners the nodes hold (no trip to the tree's
  // coordinate arrays): float(2k * e) == float(k * 2e), and float((2k + 1) * e) is larger (by
  // e / (2k + 1) >= 2^-16 of it, far above rounding), since the edges halve exactly per level.
  auto octant = [&](uint32_t parent, uint32_t cell) {
    const Node &p = node_[parent], &q = node_[cell];
    return static_cast<uint8_t>((q.x > p.x ? 1 : 0) | (q.y > p.y ? 2 : 0) | (q.z > p.z ? 4 : 0));
  };
  Piece parts[8];
  uint32_t np = 0;
  const uint32_t first = node_[c].firstChild, count = node_[c].childCount;
  for (uint32_t i = 0; i < count; ++i) {
    const uint32_t ch = first + i;
    const Ev y = ev(ch);
    Piece& p = parts[np];
    p.boxes = 0;
    p.value = 0;
    if (y.flags & kInside) {
      p.value = node_[ch].voxels;
      p.code[p.boxes++] = octant(c, ch);
    } else if ((y.flags & kLive) && node_[ch].childCount == 0) {
      p.value = node_[ch].voxels;  // a live leaf costs V
      p.code[p.boxes++] = static_cast<uint8_t>(octant(c, ch) | 0x80);
    } else if ((y.flags & kLive) && node_[ch].childCount > 0) {
      // Its wholly inside children evaluated this frame, largest first, up to V(ch).
      // One pass over the grandchildren, then the qualifying ones by V, largest first (ties: the
      // lower index first), taken until V(ch).
      const uint32_t gf = node_[ch].firstChild, gc = node_[ch].childCount;
      uint32_t pick[8], pickV[8], n = 0;
      for (uint32_t j = 0; j < gc && j < 8; ++j) {
        const Node& g = node_[gf + j];
        if (g.state == kBelow && g.stamp == frame_ && ((g.flags & kInside) || ((g.flags & kLive) && g.childCount == 0)) &&
            g.voxels > 0) {
          uint32_t k = n++;
          for (; k > 0 && pickV[k - 1] < g.voxels; --k) {
            pick[k] = pick[k - 1];
            pickV[k] = pickV[k - 1];
          }
          pick[k] = j;
          pickV[k] = g.voxels;
        }
      }
      for (uint32_t k = 0; k < n && p.value < node_[ch].voxels && p.boxes < 8; ++k) {
        const uint32_t best = pick[k];
        p.code[p.boxes++] = static_cast<uint8_t>(octant(c, ch) | (octant(ch, gf + best) << 3) | 0x40 |
                                                 ((node_[gf + best].flags & kInside) ? 0 : 0x80));
        p.value += pickV[k];
      }
      p.value = std::min<uint64_t>(p.value, node_[ch].voxels);
    }
    if (p.value > 0) ++np;
  }
  // The parts worth most per box first, until V(c).
  for (uint32_t k = 1; k < np && k < 9; ++k)
    for (uint32_t j = k; j > 0 && parts[j].value * parts[j - 1].boxes > parts[j - 1].value * parts[j].boxes; --j)
      std::swap(parts[j], parts[j - 1]);
  uint64_t sum = 0, cert = 0;
  uint32_t boxes = 0;
  for (uint32_t k = 0; k < np && sum < node_[c].voxels; ++k) {
    if (boxes + parts[k].boxes > 7) continue;
    for (uint32_t j = 0; j < parts[k].boxes; ++j) cert |= uint64_t{parts[k].code[j]} << (8 * boxes++);
    sum += parts[k].value;
  }
  return sum >= node_[c].voxels && boxes > 0 ? cert | uint64_t{boxes} << 56 : 0;
}

// Whether the certificate's boxes are still wholly inside the frustum (tested on boxes grown by
// 0.1 % of their edge, so that rounding cannot make this differ from the cells' own test; a live
// leaf's box shrunk by as much and tested live). Only against the planes that may cut the cell:
// a plane that has the whole cell inside it by a margin larger than the growth has every box of
// the certificate inside it too (the boxes lie in the cell, grown by at most 0.1 % of half its
// edge), so most checks test one or two planes, not six.
bool CellSelector::certificateHolds(const CellSet& s, uint32_t i) const {
  const uint32_t n = static_cast<uint32_t>(s.cert[i] >> 56);
  if (n == 0 || n > 7) return false;
  const float edge = s.edge[i], h = 0.5f * edge, q = 0.5f * h;
  const float cx = s.x[i] + vc_.rx, cy = s.y[i] + vc_.ry, cz = s.z[i] + vc_.rz;
  const float margin = 4e-3f * edge;
  uint32_t planes[6], np = 0;
  for (uint32_t p = 0; p < 6; ++p) {
    const float t = ((vc_.nx[p] * cx + vc_.ny[p] * cy) + vc_.nz[p] * cz) + vc_.w[p];
    if (!(t + edge * vc_.neg[p] >= margin)) planes[np++] = p;
  }
  for (uint32_t k = 0; k < n; ++k) {
    const uint32_t code = static_cast<uint32_t>(s.cert[i] >> (8 * k)) & 0xFF;
    const uint32_t o = code & 7, g = (code >> 3) & 7;
    const bool deep = (code & 0x40) != 0, leaf = (code & 0x80) != 0;
    // Wholly inside: tested grown; live (a leaf): tested shrunk.
    const float size = deep ? q : h, eps = leaf ? -1e-3f * size : 1e-3f * size;
    const float x = cx + ((o & 1) ? h : 0.0f) + (deep && (g & 1) ? q : 0.0f) - eps;
    const float y = cy + ((o & 2) ? h : 0.0f) + (deep && (g & 2) ? q : 0.0f) - eps;
    const float z = cz + ((o & 4) ? h : 0.0f) + (deep && (g & 4) ? q : 0.0f) - eps;
    const float ed = size + 2.0f * eps;
    for (uint32_t j = 0; j < np; ++j) {
      const uint32_t p = planes[j];
      const float t = ((vc_.nx[p] * x + vc_.ny[p] * y) + vc_.nz[p] * z) + vc_.w[p];
      if (!(t + ed * (leaf ? vc_.pos[p] : vc_.neg[p]) >= 0.0f)) return false;
    }
  }
  return true;
}

uint64_t CellSelector::cost(uint32_t c, std::vector<uint32_t>& unknown) {
  if (node_[c].state == kCut) return cut_.mc[node_[c].slot];
  if (node_[c].state == kMergeable) return mergeable_.mc[node_[c].slot];
  if (costed(c)) return node_[c].mc;
  const uint64_t v = coverCost(c, ev(c), unknown);
  node_[c].flags = static_cast<uint8_t>(node_[c].flags | kCosted);
  node_[c].mc = static_cast<uint32_t>(v);
  return v;
}

int64_t CellSelector::countedCost(uint32_t c) const {
  if (c >= node_.size()) return -1;
  if (node_[c].state == kCut || node_[c].state == kMergeable || costed(c)) return static_cast<int64_t>(costConst(c));
  return -1;
}

uint64_t CellSelector::costConst(uint32_t c) const {
  if (node_[c].state == kCut) return cut_.mc[node_[c].slot];
  if (node_[c].state == kMergeable) return mergeable_.mc[node_[c].slot];
  return costed(c) ? node_[c].mc : node_[c].voxels;
}

void CellSelector::maybeMergeable(uint32_t p) {
  if (p == kNoCell || node_[p].state != kRefined) return;
  const uint32_t first = node_[p].firstChild, count = uint32_t{node_[p].childCount};
  for (uint32_t i = 0; i < count; ++i)
    if (node_[first + i].state != kCut) return;
  const Ev x = ev(p);
  const uint64_t mc = coverCost(p, x);  // children in the cut: their costs are known
  insert(mergeable_, p, x, mc);
  node_[p].state = kMergeable;
}

// Eviction repair: a's subtree leaves the cut, a joins it.
void CellSelector::collapse(uint32_t a) {
  const Ev x = ev(a);
  if (node_[a].state == kMergeable) remove(mergeable_, a);
  if (node_[a].state != kCut) {
    size_t top = 0;
    scratch_.clear();
    const uint32_t first = node_[a].firstChild, count = uint32_t{node_[a].childCount};
    for (uint32_t i = 0; i < count; ++i) scratch_.push_back(first + i);
    while (top < scratch_.size()) {
      const uint32_t d = scratch_[top++];
      if (node_[d].state == kCut) remove(cut_, d);
      if (node_[d].state == kMergeable) remove(mergeable_, d);
      if (node_[d].state == kRefined || node_[d].state == kMergeable) {
        const uint32_t f = node_[d].firstChild, k = uint32_t{node_[d].childCount};
        for (uint32_t i = 0; i < k; ++i) scratch_.push_back(f + i);
      }
      node_[d].state = kBelow;
    }
    insert(cut_, a, x, 0);  // costed with the rest of the cut
    node_[a].state = kCut;
  }
  maybeMergeable(tree_.parent(a));
}

void CellSelector::pushSplit(uint32_t c, float e) {
  if (e >= splitFloor_ && splitHeap_.size() < splitHeap_.capacity()) {
    splitHeap_.push_back({e, c, node_[c].firstChild});
    std::push_heap(splitHeap_.begin(), splitHeap_.end(), splitLess<HeapEntry, HeapEntry>);
  }
}

void CellSelector::pushMerge(uint32_t p, float e) {
  if (e <= mergeCeil_ && mergeHeap_.size() < mergeHeap_.capacity()) {
    mergeHeap_.push_back({e, p});
    std::push_heap(mergeHeap_.begin(), mergeHeap_.end(), mergeLess<HeapEntry, HeapEntry>);
  }
}

bool CellSelector::splitTop(HeapEntry& top) {
  for (;;) {
    while (!splitHeap_.empty() && (node_[splitHeap_.front().cell].state != kCut || popStamp_[splitHeap_.front().cell] == frame_)) {
      std::pop_heap(splitHeap_.begin(), splitHeap_.end(), splitLess<HeapEntry, HeapEntry>);
      splitHeap_.pop_back();
    }
    if (!splitHeap_.empty() && splitHeap_.front().e >= splitFloor_) {
      top = splitHeap_.front();
      return true;
    }
    if (splitFloor_ <= 0.0f) return false;
    // Below the window: queue the next band of the cut.
    const float hi = splitFloor_;
    // (From a window at inf, the last frame's greedy having stopped at a cell of e = inf, straight
    // to 0: 0.8 * inf is inf, and the loop would never end.)
    splitFloor_ =
        splitFloor_ > 1.25f * alpha_ && splitFloor_ > 1e-30f && splitFloor_ < kInf ? 0.8f * splitFloor_ : 0.0f;
    for (uint32_t i = 0; i < cut_.n; ++i) {
      const Ev x{cut_.e[i], cut_.flags[i]};
      if (x.e >= splitFloor_ && x.e < hi && refinable(cut_.cell[i], x) && splitHeap_.size() < splitHeap_.capacity())
        splitHeap_.push_back({x.e, cut_.cell[i], cut_.first[i]});
    }
    std::make_heap(splitHeap_.begin(), splitHeap_.end(), splitLess<HeapEntry, HeapEntry>);
  }
}

bool CellSelector::mergeFront(float limit, HeapEntry& front) {
  for (;;) {
    while (!mergeHeap_.empty() && node_[mergeHeap_.front().cell].state != kMergeable) {
      std::pop_heap(mergeHeap_.begin(), mergeHeap_.end(), mergeLess<HeapEntry, HeapEntry>);
      mergeHeap_.pop_back();
    }
    if (!mergeHeap_.empty() && mergeHeap_.front().e <= mergeCeil_) {
      front = mergeHeap_.front();
      return front.e <= limit;
    }
    if (mergeCeil_ >= limit || mergeCeil_ == kInf) return false;  // none with e <= limit
    // Above the window: queue the next band of the mergeable cells.
    const float lo = mergeCeil_;
    mergeCeil_ = limit == kInf || !(mergeCeil_ > 0.0f) ? kInf : std::max(limit, 1.25f * mergeCeil_);
    for (uint32_t i = 0; i < mergeable_.n; ++i) {
      const float e = mergeable_.e[i];
      if (e > lo && e <= mergeCeil_ && mergeHeap_.size() < mergeHeap_.capacity())
        mergeHeap_.push_back({e, mergeable_.cell[i]});
    }
    std::make_heap(mergeHeap_.begin(), mergeHeap_.end(), mergeLess<HeapEntry, HeapEntry>);
  }
}

// c (cut, every child drawable and costed) -> its children.
void CellSelector::split(uint32_t c) {
  const Ev x = ev(c);
  const uint64_t own = cost(c);
  remove(cut_, c);
  node_[c].state = kRefined;
  const uint32_t first = node_[c].firstChild, count = uint32_t{node_[c].childCount};
  for (uint32_t i = 0; i < count; ++i) {
    const uint32_t ch = first + i;
    const Ev y = ev(ch);
    insert(cut_, ch, y, cost(ch));
    node_[ch].state = kCut;
    if (refinable(ch, y)) pushSplit(ch, y.e);
  }
  const uint32_t p = tree_.parent(c);
  if (p != kNoCell && node_[p].state == kMergeable) {
    remove(mergeable_, p);
    node_[p].state = kRefined;
  }
  insert(mergeable_, c, x, own);
  node_[c].state = kMergeable;
  pushMerge(c, x.e);
}

// p (mergeable) -> p in the cut, with the cost; then its parent, if that becomes mergeable and
// is drawable but not refinable (invisible or sub-pixel: minimum quality, not a greedy operation).
void CellSelector::merge(uint32_t p) {
  for (;;) {
    const uint32_t first = node_[p].firstChild, count = uint32_t{node_[p].childCount};
    uint64_t sum = 0;
    for (uint32_t i = 0; i < count; ++i) {
      sum += cost(first + i);
      remove(cut_, first + i);
      node_[first + i].state = kBelow;
    }
    const uint32_t i = node_[p].slot;
    const Ev x{mergeable_.e[i], mergeable_.flags[i]};
    const uint64_t mc = mergeable_.mc[i];
    cost_ = cost_ - sum + mc;
    remove(mergeable_, p);
    insert(cut_, p, x, mc);
    node_[p].state = kCut;
    if (refinable(p, x)) pushSplit(p, x.e);
    const uint32_t gp = tree_.parent(p);
    maybeMergeable(gp);
    if (gp == kNoCell || node_[gp].state != kMergeable) return;
    const Ev g = ev(gp);
    if (refinable(gp, g)) {
      pushMerge(gp, g.e);
      return;
    }
    if (!drawable(gp, g)) return;
    ++forcedMerges_;
    p = gp;
  }
}

bool CellSelector::request(uint32_t c) {
  if (!residency_.empty() && residency_[c] == Residency::InFlight) return true;
  // Already requested this frame, or already counted as unfetchable (W is the frame's).
  if (reqStamp_[c] == frame_) return tree_.bytes(c) <= W_;
  if (tree_.bytes(c) > W_) {
    ++unfetchable_;
    reqStamp_[c] = frame_;
    return false;
  }
  if (reqBytes_ + tree_.bytes(c) > W_ || reqCount_ >= reqOut_.size()) return false;
  reqOut_[reqCount_++] = c;
  reqStamp_[c] = frame_;
  reqBytes_ += tree_.bytes(c);
  return true;
}

void CellSelector::requestUnknownCovers() {
  for (uint32_t c : unknownCover_) {
    const uint32_t first = node_[c].firstChild, count = uint32_t{node_[c].childCount};
    for (uint32_t i = 0; i < count; ++i)
      if (!drawable(first + i, ev(first + i))) request(first + i);
  }
}

template <typename Emit>
void CellSelector::emitCover(uint32_t c, bool liveOnly, Emit&& emit) const {
  const Ev x = evConst(c);
  if (!(x.flags & kLive)) {
    if (!liveOnly) emit(c, x);
    return;
  }
  if (costConst(c) < node_[c].voxels) {
    const uint32_t first = node_[c].firstChild, count = uint32_t{node_[c].childCount};
    for (uint32_t i = 0; i < count; ++i) emitCover(first + i, liveOnly, emit);
    return;
  }
  emit(c, x);
}

size_t CellSelector::realization(std::span<uint32_t> out) const {
  size_t n = 0;
  if (tree_.empty()) return 0;
  std::array<uint32_t, 8 * kMaxCellLevels + 8> stack{};
  size_t top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const uint32_t c = stack[--top];
    if (node_[c].state == kRefined || node_[c].state == kMergeable) {
      const uint32_t first = node_[c].firstChild, count = uint32_t{node_[c].childCount};
      for (uint32_t i = count; i-- > 0;) stack[top++] = first + i;
    } else if (node_[c].state == kCut) {
      emitCover(c, false, [&](uint32_t cell, Ev) {
        if (n < out.size()) out[n] = cell;
        ++n;
      });
    }
  }
  return std::min(n, out.size());
}

// The per-frame passes. With a runner each pass is split in chunks of chunkCells_ cut cells (the
// eval pass: then chunks of the mergeable cells); worker 0 takes a prefix of the chunks in order
// and writes to the selector's own outputs, worker 1 the rest, from the back, into its Part with
// a mark per chunk; afterwards worker 1's outputs are appended in chunk order, so every list is
// the one a single pass would have made.
void CellSelector::runPass(Pass pass) {
  pass_ = pass;
  Part& p0 = parts_[0];
  p0.begin();
  if (config_.runner == nullptr) {
    switch (pass) {
      case Pass::Eval:
        evalChunk(0, p0, true);
        evaluateSet(mergeable_);
        break;
      case Pass::Cost:
        costChunk(0, cut_.n, p0, true);
        break;
      case Pass::Draw:
        drawChunk(0, cut_.n, p0);
        break;
    }
    return;
  }
  Part& p1 = parts_[1];
  p1.begin();
  const uint32_t size = chunkCells_;
  cutChunks_ = (cut_.n + size - 1) / size;
  uint32_t chunks = cutChunks_;
  if (pass == Pass::Eval) chunks += (mergeable_.n + size - 1) / size;
  if (pass == Pass::Cost) std::fill_n(p1.childSum.begin(), mergeable_.n, uint64_t{0});
  if (pass == Pass::Draw) {
    p1.out = drawBuf_.data();
    p1.cap = static_cast<uint32_t>(drawBuf_.size());
  }
  if (chunks > 0) config_.runner->forEach(chunks, &CellSelector::passChunk, this);
  // Worker 1's outputs in chunk order: its marks are in the order it took them (descending).
  const size_t m = p1.marks.size();
  for (size_t k = m; k-- > 0;) {
    const Part::Mark& a = p1.marks[k];
    const bool last = k + 1 == m;
    if (pass == Pass::Eval) {
      const uint32_t end = last ? static_cast<uint32_t>(p1.evicted.size()) : p1.marks[k + 1].evicted;
      for (uint32_t j = a.evicted; j < end; ++j) evicted_.push_back(p1.evicted[j]);
    } else if (pass == Pass::Cost) {
      const uint32_t endS = last ? static_cast<uint32_t>(p1.splits.size()) : p1.marks[k + 1].splits;
      for (uint32_t j = a.splits; j < endS; ++j) splitHeap_.push_back(p1.splits[j]);
      const uint32_t endU = last ? static_cast<uint32_t>(p1.unknown.size()) : p1.marks[k + 1].unknown;
      for (uint32_t j = a.unknown; j < endU && unknownCover_.size() < unknownCover_.capacity(); ++j)
        unknownCover_.push_back(p1.unknown[j]);
    } else {
      const uint32_t end = last ? p1.written : p1.marks[k + 1].draw;
      const uint32_t n = end - a.draw, room = p0.cap - p0.written;
      const uint32_t take = std::min(n, room);
      if (take > 0) std::memcpy(p0.out + p0.written, p1.out + a.draw, take * sizeof(CellDraw));
      p0.written += take;
      if (take < n) p0.truncated = true;
    }
  }
  if (pass == Pass::Cost) p0.cost += p1.cost;
  if (pass == Pass::Draw) {
    p0.cutCells += p1.cutCells;
    p0.drawnVoxels += p1.drawnVoxels;
    p0.maxE = std::max(p0.maxE, p1.maxE);
    p0.truncated = p0.truncated || p1.truncated;
  }
}

void CellSelector::passChunk(void* self, uint32_t chunk, uint32_t worker) {
  CellSelector& s = *static_cast<CellSelector*>(self);
  Part& part = s.parts_[worker != 0 ? 1 : 0];
  const bool mine = worker == 0;
  if (!mine) {
    part.marks.push_back({chunk, static_cast<uint32_t>(part.evicted.size()), static_cast<uint32_t>(part.splits.size()),
                          static_cast<uint32_t>(part.unknown.size()), part.written});
  }
  const uint32_t size = s.chunkCells_, begin = chunk * size;
  if (s.pass_ == Pass::Eval) {
    if (chunk < s.cutChunks_) {
      s.evalChunk(chunk, part, mine);
    } else {
      const uint32_t b = (chunk - s.cutChunks_) * size, n = std::min(s.mergeable_.n - b, size);
      CellSet& m = s.mergeable_;
      evalCells(s.vc_, n, m.x.data() + b, m.y.data() + b, m.z.data() + b, m.edge.data() + b, m.voxels.data() + b,
                m.e.data() + b, m.flags.data() + b);
    }
  } else if (s.pass_ == Pass::Cost) {
    s.costChunk(begin, std::min(s.cut_.n, begin + size), part, mine);
  } else {
    s.drawChunk(begin, std::min(s.cut_.n, begin + size), part);
  }
}

// Re-evaluation of a chunk of the cut (without a runner: all of it) and the drawn cells in it that
// stopped being resident.
void CellSelector::evalChunk(uint32_t chunk, Part& part, bool mine) {
  const uint32_t b = chunkCells_ == 0 ? 0 : chunk * chunkCells_;
  const uint32_t e = chunkCells_ == 0 ? cut_.n : std::min(cut_.n, b + chunkCells_);
  CellSet& c = cut_;
  evalCells(vc_, e - b, c.x.data() + b, c.y.data() + b, c.z.data() + b, c.edge.data() + b, c.voxels.data() + b,
            c.e.data() + b, c.flags.data() + b);
  if (residency_.empty()) return;
  std::vector<uint32_t>& out = mine ? evicted_ : part.evicted;
  for (uint32_t i = b; i < e; ++i)
    if ((c.flags[i] & kLive) && !resident(c.cell[i]) && c.cell[i] != 0) out.push_back(c.cell[i]);
}

// Costs of a range of the cut: mc of every cell (V when live), the sums of the mergeable cells'
// children, the split candidates of the heap window, then the cheapest covers of the cells cut
// by the frustum boundary whose certificate does not hold.
void CellSelector::costChunk(uint32_t begin, uint32_t end, Part& part, bool mine) {
  std::vector<HeapEntry>& splits = mine ? splitHeap_ : part.splits;
  std::vector<uint32_t>& unknown = mine ? unknownCover_ : part.unknown;
  std::vector<uint32_t>& covers = part.covers;
  uint64_t* sums = mine ? childSum_.data() : part.childSum.data();
  covers.clear();
  uint64_t total = 0;
  const uint8_t* flags = cut_.flags.data();
  const uint32_t *voxels = cut_.voxels.data(), *up = cut_.up.data(), *cells = cut_.cell.data();
  const float* es = cut_.e.data();
  uint32_t* mcs = cut_.mc.data();
  const float alpha = alpha_, floor = splitFloor_;
  // Cells without a mergeable parent add to a spare slot past the real ones (no branch).
  const uint32_t spare = static_cast<uint32_t>(childSum_.size() - 1);
  // A cell that is refinable (live, with children, e > alpha) is a split candidate of the
  // window (bit 0: e >= floor) and, when cut by the frustum boundary, needs its cheapest cover
  // unless its certificate holds (bit 1). Few cells are either: the masks come four at a time.
  auto visit = [&](uint32_t i, uint32_t want) {
    if (want & 1) splits.push_back({es[i], cells[i], cut_.first[i]});
    if ((want & 2) && (cut_.cert[i] == 0 || !certificateHolds(cut_, i))) covers.push_back(i);
  };
  uint32_t i = begin;
#if defined(__SSE2__) && !defined(IG_CELLS_NO_SIMD)
  {
    const __m128i zero = _mm_setzero_si128(), live1 = _mm_set1_epi32(kLive), kids = _mm_set1_epi32(kHasChildren),
                  inside = _mm_set1_epi32(kInside);
    const __m128 va = _mm_set1_ps(alpha), vf = _mm_set1_ps(floor);
    __m128i acc = zero;  // two 64-bit sums
    for (; i + 4 <= end; i += 4) {
      int32_t f4;
      std::memcpy(&f4, flags + i, 4);
      const __m128i f = _mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(f4), zero), zero);
      const __m128i live = _mm_cmpeq_epi32(_mm_and_si128(f, live1), live1);
      const __m128i mc = _mm_and_si128(_mm_loadu_si128(reinterpret_cast<const __m128i*>(voxels + i)), live);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(mcs + i), mc);
      acc = _mm_add_epi64(acc, _mm_add_epi64(_mm_unpacklo_epi32(mc, zero), _mm_unpackhi_epi32(mc, zero)));
      for (uint32_t k = 0; k < 4; ++k) sums[std::min(up[i + k], spare)] += mcs[i + k];
      const __m128 e = _mm_loadu_ps(es + i);
      const __m128i refinable = _mm_and_si128(_mm_and_si128(live, _mm_cmpeq_epi32(_mm_and_si128(f, kids), kids)),
                                              _mm_castps_si128(_mm_cmpgt_ps(e, va)));
      const int cand = _mm_movemask_ps(_mm_castsi128_ps(_mm_and_si128(refinable, _mm_castps_si128(_mm_cmpge_ps(e, vf)))));
      const int strad = _mm_movemask_ps(
          _mm_castsi128_ps(_mm_andnot_si128(_mm_cmpeq_epi32(_mm_and_si128(f, inside), inside), refinable)));
      if ((cand | strad) == 0) continue;
      for (uint32_t k = 0; k < 4; ++k) visit(i + k, static_cast<uint32_t>(((cand >> k) & 1) | (((strad >> k) & 1) << 1)));
    }
    uint64_t lanes[2];
    _mm_storeu_si128(reinterpret_cast<__m128i*>(lanes), acc);
    total = lanes[0] + lanes[1];
  }
#endif
  for (; i < end; ++i) {
    const uint8_t f = flags[i];
    const uint32_t mc = (f & kLive) ? voxels[i] : 0;
    mcs[i] = mc;
    total += mc;
    sums[std::min(up[i], spare)] += mc;
    if ((f & (kLive | kHasChildren)) != (kLive | kHasChildren) || !(es[i] > alpha)) continue;
    visit(i, (es[i] >= floor ? 1u : 0u) | (f & kInside ? 0u : 2u));
  }
  // The covers, each cell's node and then its children's fetched a few cells ahead (the tree walk
  // waits on memory).
  constexpr size_t kAhead = 6;
  for (size_t k = 0; k < std::min(2 * kAhead, covers.size()); ++k) __builtin_prefetch(&node_[cut_.cell[covers[k]]]);
  for (size_t k = 0; k < std::min(kAhead, covers.size()); ++k) prefetchChildren(cut_.cell[covers[k]]);
  for (size_t k = 0; k < covers.size(); ++k) {
    if (k + 2 * kAhead < covers.size()) __builtin_prefetch(&node_[cut_.cell[covers[k + 2 * kAhead]]]);
    if (k + kAhead < covers.size()) prefetchChildren(cut_.cell[covers[k + kAhead]]);
    const uint32_t j = covers[k];
    const uint64_t mc = coverCost(cut_.cell[j], {cut_.e[j], cut_.flags[j]}, unknown);
    cut_.cert[j] = mc == cut_.voxels[j] ? makeCertificate(cut_.cell[j]) : 0;
    total -= cut_.voxels[j] - mc;
    sums[std::min(cut_.up[j], spare)] -= cut_.voxels[j] - mc;
    cut_.mc[j] = static_cast<uint32_t>(mc);
  }
  part.cost += total;
}

// The drawn cells of a range of the cut, in its order (covers expanded), into part.out.
void CellSelector::drawChunk(uint32_t begin, uint32_t end, Part& part) {
  uint32_t written = part.written, cutCells = 0;
  uint64_t drawnVoxels = 0;
  float maxE = part.maxE;
  bool truncated = part.truncated;
  CellDraw* out = part.out;
  const uint32_t cap = part.cap;
  auto emit = [&](uint32_t cell, Ev x) {
    ++cutCells;
    if (!(x.flags & kLive)) return;
    drawnVoxels += node_[cell].voxels;
    maxE = std::max(maxE, x.e);
    if (written < cap) out[written++] = {cell, x.e};
    else truncated = true;
  };
  const uint8_t* flags = cut_.flags.data();
  const uint32_t *cells = cut_.cell.data(), *voxels = cut_.voxels.data(), *mcs = cut_.mc.data();
  const float* es = cut_.e.data();
  const bool rootMissing = rootMissing_;
  // One cut cell: not live (counted, not drawn), the root not arrived yet (neither), drawn as
  // its cheaper cover, or drawn itself.
  auto emitCut = [&](uint32_t k) {
    if (!(flags[k] & kLive)) {
      ++cutCells;
      return;
    }
    const uint32_t c = cells[k];
    if (c == 0 && rootMissing) return;
    if (mcs[k] < voxels[k]) {
      emitCover(c, false, emit);
      return;
    }
    ++cutCells;
    drawnVoxels += voxels[k];
    maxE = std::max(maxE, es[k]);
    if (written < cap) out[written++] = {c, es[k]};
    else truncated = true;
  };
  uint32_t i = begin;
#if defined(__SSE2__) && !defined(IG_CELLS_NO_SIMD)
  // Four cells at a time while no cover is among them (~93 % of the groups) and the root is
  // resident: the live ones are written in order, four in two stores when all are live.
  static_assert(sizeof(CellDraw) == 8 && offsetof(CellDraw, voxel_px) == 4);
  if (!rootMissing) {
    const __m128i zero = _mm_setzero_si128(), live1 = _mm_set1_epi32(kLive);
    __m128i voxelSum = zero;  // two 64-bit sums
    __m128 maxV = _mm_setzero_ps();
    for (; i + 4 <= end && written + 4 <= cap; i += 4) {
      int32_t f4;
      std::memcpy(&f4, flags + i, 4);
      const __m128i f = _mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(f4), zero), zero);
      const __m128i live = _mm_cmpeq_epi32(_mm_and_si128(f, live1), live1);
      const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(voxels + i));
      const __m128i plain = _mm_cmpeq_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(mcs + i)), v);
      const int lm = _mm_movemask_ps(_mm_castsi128_ps(live));
      if (_mm_movemask_ps(_mm_castsi128_ps(_mm_andnot_si128(plain, live))) != 0) {
        for (uint32_t k = i; k < i + 4; ++k) emitCut(k);  // a cover among them: one by one, in order
        continue;
      }
      cutCells += 4;
      const __m128 e = _mm_loadu_ps(es + i);
      const __m128i kept = _mm_and_si128(v, live);
      voxelSum = _mm_add_epi64(voxelSum, _mm_add_epi64(_mm_unpacklo_epi32(kept, zero), _mm_unpackhi_epi32(kept, zero)));
      maxV = _mm_max_ps(maxV, _mm_and_ps(e, _mm_castsi128_ps(live)));
      if (lm == 15) {
        const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(cells + i));
        _mm_storeu_si128(reinterpret_cast<__m128i*>(out + written), _mm_unpacklo_epi32(c, _mm_castps_si128(e)));
        _mm_storeu_si128(reinterpret_cast<__m128i*>(out + written + 2), _mm_unpackhi_epi32(c, _mm_castps_si128(e)));
        written += 4;
      } else {
        for (uint32_t k = 0; k < 4; ++k)
          if ((lm >> k) & 1) out[written++] = {cells[i + k], es[i + k]};
      }
    }
    uint64_t sums[2];
    float maxes[4];
    _mm_storeu_si128(reinterpret_cast<__m128i*>(sums), voxelSum);
    _mm_storeu_ps(maxes, maxV);
    drawnVoxels += sums[0] + sums[1];
    maxE = std::max(std::max(maxE, std::max(maxes[0], maxes[1])), std::max(maxes[2], maxes[3]));
  }
#endif
  for (; i < end; ++i) emitCut(i);
  part.written = written;
  part.cutCells += cutCells;
  part.drawnVoxels += drawnVoxels;
  part.maxE = maxE;
  part.truncated = truncated;
}

CellSelectStats CellSelector::select(const CellView& view, std::span<const Residency> residency,
                                     std::span<CellDraw> draw, std::span<uint32_t> requests) {
  CellSelectStats stats;
  if (!validCellView(view) || (!residency.empty() && residency.size() != tree_.size())) return stats;
  stats.valid = true;
  if (tree_.empty()) return stats;
  residency_ = residency;
  if (++frame_ == 0) {
    for (Node& d : node_) d.stamp = 0;
    std::fill(reqStamp_.begin(), reqStamp_.end(), 0u);
    std::fill(popStamp_.begin(), popStamp_.end(), 0u);
    frame_ = 1;
  }
  makeConsts(tree_, view, vc_);
  alpha_ = static_cast<float>(view.minVoxel_px);
  const uint64_t budget = view.voxelBudget;
  reqOut_ = requests;
  reqCount_ = 0;
  reqBytes_ = 0;
  W_ = view.byteBudget;
  unfetchable_ = 0;
  uint32_t ops = 0;

  // 1. Evaluate the cut and the mergeable cells (one pass each over packed arrays); collect the
  // drawn cells that stopped being resident.
  evicted_.clear();
  costsFresh_ = false;
  runPass(Pass::Eval);

  // 2. Drawn cells that stopped being resident: fall back to the nearest drawable ancestor
  // (collected first: collapsing reorders the cut).
  for (uint32_t c : evicted_) {
    if (node_[c].state != kCut) continue;  // gone with an earlier repair
    uint32_t a = tree_.parent(c);
    while (a != 0 && !drawable(a, ev(a))) a = tree_.parent(a);
    collapse(a);
  }

  // 3. Costs: mc of every cut cell, then of the mergeable cells (from their children). The
  // same pass over the cut sums each mergeable cell's children (a mergeable cell's children are
  // all in the cut and drawable: every live cut cell but the root is resident after step 2, so
  // its cheapest cover is min(V, sum of their mc); each cut cell knows its parent's slot) and
  // queues the split candidates of the heap window, around where the greedy stopped last frame
  // (the cut's evaluation is final here: forced merges below only add cells that are not
  // refinable, and the queues skip cells that left the cut).
  unknownCover_.clear();
  splitHeap_.clear();
  mergeHeap_.clear();
  splitFloor_ = 0.95f * lastT_;
  mergeCeil_ = lastT_ / 0.95f;
  std::fill_n(childSum_.begin(), mergeable_.n, uint64_t{0});
  runPass(Pass::Cost);
  costsFresh_ = true;  // the cut's; the mergeable cells' below, before any of them leaves the set
  cost_ = parts_[0].cost;
  // 4. One pass over the mergeable cells: their cost, the merge candidates of the heap window,
  // and those that became invisible or sub-pixel (merged: minimum quality).
  scratch_.clear();
  for (uint32_t i = 0; i < mergeable_.n; ++i) {
    const uint8_t f = mergeable_.flags[i];
    const float e = mergeable_.e[i];
    uint64_t mc = 0;
    if (f & kLive) {
      mc = mergeable_.voxels[i];
      if (!(f & kInside) && (f & kHasChildren) && e > alpha_)
        mc = std::min(mc, config_.runner != nullptr ? childSum_[i] + parts_[1].childSum[i] : childSum_[i]);
    }
    mergeable_.mc[i] = static_cast<uint32_t>(mc);
    if (e <= mergeCeil_) mergeHeap_.push_back({e, mergeable_.cell[i]});
    if (!refinable(mergeable_.cell[i], {e, f}) && drawable(mergeable_.cell[i], {e, f})) scratch_.push_back(mergeable_.cell[i]);
  }
  // These merges only coarsen the cut where nothing can be seen (invisible or sub-pixel cells)
  // and never raise the cost, so a stop may leave the rest to the next frames (after a jump of
  // the eye they are hundreds: ~0.2 ms). Polled as the refinement is; stopped here, nothing is
  // refined this frame.
  forcedMerges_ = 0;
  bool stopped = false;
  for (size_t k = 0; k < scratch_.size(); ++k) {
    const uint32_t p = scratch_[k];
    if (node_[p].state != kMergeable) continue;
    if (view.stop != nullptr && (forcedMerges_ + 1) % kCellStopPoll == 0 && view.stop(view.stopContext)) {
      stopped = true;
      break;
    }
    merge(p);  // cascades to parents that are not refinable either (queued as merge candidates when refinable)
    ++forcedMerges_;
  }
  if (stopped) stats.capped = stats.stopped = true;
  std::make_heap(splitHeap_.begin(), splitHeap_.end(), splitLess<HeapEntry, HeapEntry>);
  std::make_heap(mergeHeap_.begin(), mergeHeap_.end(), mergeLess<HeapEntry, HeapEntry>);
  auto doMerge = [&](uint32_t p) {
    merge(p);
    ++stats.merges;
    ++ops;
  };
  auto popMerge = [&]() {
    std::pop_heap(mergeHeap_.begin(), mergeHeap_.end(), mergeLess<HeapEntry, HeapEntry>);
    mergeHeap_.pop_back();
  };

  if (node_[0].state == kCut && !drawable(0, ev(0))) {
    // Nothing drawable yet: fetch the root.
    request(0);
    stats.feasible = false;
  } else {
    // 5. Over budget (the view came closer, cells became visible): coarsen, smallest e first.
    HeapEntry m{};
    while (cost_ > budget && mergeFront(kInf, m)) {
      popMerge();
      if (drawable(m.cell, ev(m.cell))) doMerge(m.cell);
    }
    stats.feasible = cost_ <= budget;
    if (!stats.feasible) requestUnknownCovers();  // a cheaper cover may hide below cells not resident

    // 6. Refine: largest on-screen voxel first; merge cells of lower priority to make room.
    uint64_t reserved = 0;
    HeapEntry s{};
    uint32_t examined = 0;
    while (stats.feasible && !stopped && splitTop(s)) {
      if (ops >= config_.maxOperations) {
        stats.capped = true;
        break;
      }
      if (view.stop != nullptr && ++examined % kCellStopPoll == 0 && view.stop(view.stopContext)) {
        stats.capped = stats.stopped = true;
        break;
      }
      const uint32_t c = s.cell;
      lastT_ = s.e;
      // The next candidate is one of the heap's next two entries (a blocked split pushes none):
      // fetch their nodes, children and residency while this one is examined (its children's
      // evaluation waited on them: ~35 % of a blocked split's cycles).
      for (size_t k = 1; k < 3 && k < splitHeap_.size(); ++k) {
        const HeapEntry& h = splitHeap_[k];
        const char* kids = reinterpret_cast<const char*>(&node_[h.first]);
        __builtin_prefetch(&node_[h.cell]);
        __builtin_prefetch(&popStamp_[h.cell]);
        __builtin_prefetch(kids);
        __builtin_prefetch(kids + 64);
        __builtin_prefetch(kids + 128);
        __builtin_prefetch(kids + 192);
        __builtin_prefetch(kids + 256);
        if (!residency_.empty()) __builtin_prefetch(&residency_[h.first]);
      }
      const uint32_t first = node_[c].firstChild, count = uint32_t{node_[c].childCount};
      evaluateChildren(c);
      uint64_t childCost = 0;
      bool missing = false;
      for (uint32_t i = 0; i < count; ++i) {
        const uint32_t ch = first + i;
        if (!drawable(ch, ev(ch))) {
          missing = true;
          childCost += node_[ch].voxels;
        } else {
          childCost += cost(ch);
        }
      }
      const uint64_t own = cost(c);
      const uint64_t delta = childCost > own ? childCost - own : 0;
      bool fits = cost_ + reserved + delta <= budget;
      // Every mergeable cell of lower priority than c is merged before c is given up (so that
      // the result does not depend on the last frame's cut), and while c does not fit.
      while (!fits && mergeFront(s.e, m) && mergeLess(s, m)) {
        popMerge();
        if (drawable(m.cell, ev(m.cell))) doMerge(m.cell);
        fits = cost_ + reserved + delta <= budget;
      }
      if (!fits) {
        // The largest voxel cannot shrink: balanced. Fetch the cells whose residency may reveal
        // cheaper covers of cells cut by the frustum (their cost is counted as V until then).
        requestUnknownCovers();
        break;
      }
      std::pop_heap(splitHeap_.begin(), splitHeap_.end(), splitLess<HeapEntry, HeapEntry>);
      splitHeap_.pop_back();
      popStamp_[c] = frame_;
      if (!missing) {
        split(c);
        cost_ += delta;
        ++stats.splits;
        ++ops;
        continue;
      }
      // Blocked: request the missing children (within W) and hold their voxels.
      bool all = true;
      for (uint32_t i = 0; i < count; ++i)
        if (!drawable(first + i, ev(first + i)) && !request(first + i)) all = false;
      if (all) {
        reserved += delta;
        ++stats.blockedSplits;
      } else if (reqCount_ >= reqOut_.size() || W_ - reqBytes_ < minBytes_) {
        break;  // W is spent: the next frames fetch what this cell waits for (bounds the work per frame)
      }
    }
    if (!stats.capped && stats.feasible && splitHeap_.empty() && splitFloor_ <= 0.0f) lastT_ = 0.0f;
    stats.reservedVoxels = reserved;
  }
  stats.merges += forcedMerges_;
  stats.requestedCells = reqCount_;
  stats.requestedBytes = reqBytes_;
  stats.unfetchable = unfetchable_;
  reqOut_ = {};

  // 7. Emit the realization's drawn cells.
  if (stats.feasible) {
    // Every live cut cell but the root is resident here (step 2 repaired evictions, and splits
    // and merges only make drawable cells cut cells): the root may not have arrived yet.
    rootMissing_ = !resident(0);
    Part& p0 = parts_[0];
    p0.out = draw.data();
    p0.cap = static_cast<uint32_t>(std::min<size_t>(draw.size(), 0xFFFFFFFFu));
    runPass(Pass::Draw);
    stats.drawnCells = p0.written;
    stats.cutCells = p0.cutCells;
    stats.drawnVoxels = p0.drawnVoxels;
    stats.maxVoxel_px = p0.maxE;
    stats.drawTruncated = p0.truncated;
  }
  return stats;
}

}  // namespace ig::lod
