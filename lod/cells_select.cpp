#include "lod/cells_select.h"

#include <algorithm>
#include <cmath>

namespace ig::lod {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;
constexpr uint8_t kAllPlanes = 0x3F;
constexpr uint8_t kLiveBit = 0x80;

bool finite3(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Frustum test of the eye-relative box [lo, hi] against the planes in `mask`. Returns false when
// the box is outside one plane; clears from `mask` the planes the box is wholly inside.
bool frustumTest(const std::array<glm::dvec4, 6>& planes, const glm::dvec3& lo, const glm::dvec3& hi, uint8_t& mask) {
  for (int i = 0; i < 6; ++i) {
    if (!(mask & (1u << i))) continue;
    const glm::dvec4& p = planes[static_cast<size_t>(i)];
    const double far = p.x * (p.x >= 0 ? hi.x : lo.x) + p.y * (p.y >= 0 ? hi.y : lo.y) + p.z * (p.z >= 0 ? hi.z : lo.z) + p.w;
    if (far < 0.0) return false;
    const double near = p.x * (p.x >= 0 ? lo.x : hi.x) + p.y * (p.y >= 0 ? lo.y : hi.y) + p.z * (p.z >= 0 ? lo.z : hi.z) + p.w;
    if (near >= 0.0) mask = static_cast<uint8_t>(mask & ~(1u << i));
  }
  return true;
}

// e(c): the voxel's on-screen size, from the eye-relative box.
float voxelPx(const glm::dvec3& lo, const glm::dvec3& hi, double voxelEdge_m, double pxPerM, double near_m) {
  const double dx = std::max({lo.x, -hi.x, 0.0}), dy = std::max({lo.y, -hi.y, 0.0}), dz = std::max({lo.z, -hi.z, 0.0});
  const double d = std::sqrt(dx * dx + dy * dy + dz * dz);
  return static_cast<float>(voxelEdge_m * pxPerM / std::max(d, near_m));
}

double pixelsPerRadian(const CellView& v) { return v.viewportHeight_px / (2.0 * std::tan(0.5 * v.camera.fovY_deg * kDeg)); }

}  // namespace

bool validCellView(const CellView& v) {
  const Camera& c = v.camera;
  return finite3(c.eye_m) && std::isfinite(c.heading_deg) && std::isfinite(c.pitch_deg) && std::isfinite(c.roll_deg) &&
         c.fovY_deg > 0.0 && c.fovY_deg < 180.0 && c.aspect > 0.0 && std::isfinite(c.aspect) && c.near_m > 0.0 &&
         c.far_m > c.near_m && std::isfinite(c.far_m) && v.viewportHeight_px > 0.0 && std::isfinite(v.viewportHeight_px) &&
         v.minVoxel_px >= 0.0 && std::isfinite(v.minVoxel_px);
}

CellEval evaluateCell(const CellTree& tree, uint32_t cell, const CellView& view) {
  CellEval out;
  if (!validCellView(view) || cell >= tree.size()) return out;
  const Frustum fr = makeFrustum(view.camera);
  const double edge = tree.cellEdge_m(tree.level(cell));
  const glm::dvec3 lo = (tree.info().rootMin_m - view.camera.eye_m) + glm::dvec3(tree.coord(cell)) * edge;
  const glm::dvec3 hi = lo + glm::dvec3(edge);
  uint8_t mask = kAllPlanes;
  out.live = !tree.isEmpty(cell) && frustumTest(fr.planes, lo, hi, mask);
  if (out.live)
    out.voxel_px = voxelPx(lo, hi, tree.voxelEdge_m(tree.level(cell)), pixelsPerRadian(view), view.camera.near_m);
  return out;
}

CellSelector::CellSelector(const CellTree& tree, const CellSelectorConfig& config) : tree_(tree), config_(config) {
  const size_t n = tree.size();
  state_.assign(n, kBelow);
  flags_.assign(n, 0);
  evalStamp_.assign(n, 0);
  costStamp_.assign(n, 0);
  e_.assign(n, 0.0f);
  mc_.assign(n, 0);
  cutList_.reserve(n);
  unknownCover_.reserve(n);
  reqStamp_.assign(n, 0);
  splitHeap_.reserve(2 * n + 64);
  mergeHeap_.reserve(2 * n + 64);
  reset();
}

void CellSelector::reset() {
  std::fill(state_.begin(), state_.end(), kBelow);
  if (!state_.empty()) state_[0] = kCut;
}

void CellSelector::evaluate(uint32_t c, uint8_t parentMask) {
  if (evalStamp_[c] == frame_) return;
  evalStamp_[c] = frame_;
  const int level = tree_.level(c);
  const double edge = tree_.cellEdge_m(level);
  const glm::dvec3 lo = rootRel_ + glm::dvec3(tree_.coord(c)) * edge;
  const glm::dvec3 hi = lo + glm::dvec3(edge);
  uint8_t mask = parentMask;
  const bool isLive = !tree_.isEmpty(c) && frustumTest(planes_, lo, hi, mask);
  flags_[c] = static_cast<uint8_t>(mask | (isLive ? kLiveBit : 0));
  e_[c] = isLive ? voxelPx(lo, hi, tree_.voxelEdge_m(level), pxPerM_, near_m_) : 0.0f;
}

void CellSelector::evaluateChildren(uint32_t c) {
  const uint32_t first = tree_.firstChild(c), count = tree_.childCount(c);
  const uint8_t mask = live(c) ? static_cast<uint8_t>(flags_[c] & kAllPlanes) : kAllPlanes;
  for (uint32_t i = 0; i < count; ++i) evaluate(first + i, mask);
}

bool CellSelector::childrenDrawable(uint32_t c) const {
  const uint32_t first = tree_.firstChild(c), count = tree_.childCount(c);
  for (uint32_t i = 0; i < count; ++i)
    if (!drawable(first + i)) return false;
  return true;
}

uint64_t CellSelector::cost(uint32_t c) {
  if (costStamp_[c] == frame_) return mc_[c];
  uint64_t v = live(c) ? tree_.voxels(c) : 0;
  // Wholly inside the frustum: every descendant is live and octree images are monotone, so no
  // cover is cheaper than the cell itself.
  if (live(c) && (flags_[c] & kAllPlanes) != 0 && refinable(c)) {
    evaluateChildren(c);
    if (!childrenDrawable(c)) {
      if (unknownCover_.size() < unknownCover_.capacity()) unknownCover_.push_back(c);
    } else {
      uint64_t sum = 0;
      const uint32_t first = tree_.firstChild(c), count = tree_.childCount(c);
      for (uint32_t i = 0; i < count && sum < v; ++i) sum += cost(first + i);
      v = std::min(v, sum);
    }
  }
  costStamp_[c] = frame_;
  mc_[c] = v;
  return v;
}

void CellSelector::collapse(uint32_t c) {
  if (state_[c] == kRefined) {
    const uint32_t first = tree_.firstChild(c), count = tree_.childCount(c);
    for (uint32_t i = 0; i < count; ++i) {
      collapse(first + i);
      state_[first + i] = kBelow;
    }
  }
  state_[c] = kCut;
}

bool CellSelector::pushSplit(uint32_t c) {
  if (splitHeap_.size() == splitHeap_.capacity()) return false;
  splitHeap_.push_back({e_[c], c});
  std::push_heap(splitHeap_.begin(), splitHeap_.end(), [](const HeapEntry& a, const HeapEntry& b) { return a.e < b.e; });
  return true;
}

bool CellSelector::pushMerge(uint32_t p) {
  if (mergeHeap_.size() == mergeHeap_.capacity()) return false;
  mergeHeap_.push_back({e_[p], p});
  std::push_heap(mergeHeap_.begin(), mergeHeap_.end(), [](const HeapEntry& a, const HeapEntry& b) { return a.e > b.e; });
  return true;
}

bool CellSelector::mergeCandidate(uint32_t p) const {
  if (state_[p] != kRefined) return false;
  const uint32_t first = tree_.firstChild(p), count = tree_.childCount(p);
  for (uint32_t i = 0; i < count; ++i)
    if (state_[first + i] != kCut) return false;
  return true;
}

uint64_t CellSelector::mergeSaving(uint32_t p) {
  uint64_t sum = 0;
  const uint32_t first = tree_.firstChild(p), count = tree_.childCount(p);
  for (uint32_t i = 0; i < count; ++i) sum += cost(first + i);
  const uint64_t own = cost(p);
  return sum > own ? sum - own : 0;
}

void CellSelector::merge(uint32_t p) {
  const uint32_t first = tree_.firstChild(p), count = tree_.childCount(p);
  for (uint32_t i = 0; i < count; ++i) state_[first + i] = kBelow;
  state_[p] = kCut;
}

// Walks the cut from the root: evaluates cells, merges invisible and sub-pixel refined cells,
// sums the cost and fills the queues. Returns false when a drawn cell was no longer resident and
// the cut was repaired (walk again).
bool CellSelector::walkCut() {
  cutList_.clear();
  splitHeap_.clear();
  mergeHeap_.clear();
  cost_ = 0;
  bool repaired = false;
  size_t top = 0;
  stack_[top++] = 0;
  evaluate(0, kAllPlanes);
  while (top > 0) {
    const uint32_t c = stack_[--top];
    if (state_[c] == kRefined) {
      if ((!live(c) || e_[c] <= alpha_) && drawable(c)) {
        collapse(c);  // invisible or already sub-pixel: minimum quality
        ++forcedMerges_;
      } else {
        evaluateChildren(c);
        const uint32_t first = tree_.firstChild(c), count = tree_.childCount(c);
        for (uint32_t i = 0; i < count; ++i) stack_[top++] = first + i;
        continue;
      }
    }
    if (state_[c] != kCut) continue;
    if (!drawable(c) && c != 0) {
      // Evicted: fall back to the nearest drawable ancestor (the root if none).
      uint32_t a = tree_.parent(c);
      while (a != 0 && !drawable(a)) a = tree_.parent(a);
      collapse(a);
      repaired = true;
      continue;
    }
    cutList_.push_back(c);
    cost_ += cost(c);
    if (refinable(c)) splitHeap_.push_back({e_[c], c});  // heapified once after the walk
  }
  if (repaired) return false;
  for (uint32_t c : cutList_) {
    const uint32_t p = tree_.parent(c);
    if (p != kNoCell && c == tree_.firstChild(p) && mergeCandidate(p)) mergeHeap_.push_back({e_[p], p});
  }
  return true;
}

template <typename Emit>
void CellSelector::emitCover(uint32_t c, bool liveOnly, Emit&& emit) const {
  if (!live(c)) {
    if (!liveOnly) emit(c);
    return;
  }
  if (costStamp_[c] == frame_ && mc_[c] < tree_.voxels(c)) {
    const uint32_t first = tree_.firstChild(c), count = tree_.childCount(c);
    for (uint32_t i = 0; i < count; ++i) emitCover(first + i, liveOnly, emit);
    return;
  }
  emit(c);
}

size_t CellSelector::realization(std::span<uint32_t> out) const {
  size_t n = 0;
  if (tree_.empty()) return 0;
  std::array<uint32_t, 8 * kMaxCellLevels + 8> stack{};
  size_t top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const uint32_t c = stack[--top];
    if (state_[c] == kRefined) {
      const uint32_t first = tree_.firstChild(c), count = tree_.childCount(c);
      for (uint32_t i = count; i-- > 0;) stack[top++] = first + i;
    } else if (state_[c] == kCut) {
      emitCover(c, false, [&](uint32_t cell) {
        if (n < out.size()) out[n] = cell;
        ++n;
      });
    }
  }
  return std::min(n, out.size());
}

bool CellSelector::request(uint32_t c) {
  if (!residency_.empty() && residency_[c] == Residency::InFlight) return true;
  if (reqStamp_[c] == frame_) return true;  // already requested this frame
  if (tree_.bytes(c) > W_) {
    ++unfetchable_;
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
    const uint32_t first = tree_.firstChild(c), count = tree_.childCount(c);
    for (uint32_t i = 0; i < count; ++i)
      if (!drawable(first + i)) request(first + i);
  }
}

CellSelectStats CellSelector::select(const CellView& view, std::span<const Residency> residency,
                                     std::span<CellDraw> draw, std::span<uint32_t> requests) {
  CellSelectStats stats;
  if (!validCellView(view) || (!residency.empty() && residency.size() != tree_.size())) return stats;
  stats.valid = true;
  if (tree_.empty()) return stats;
  residency_ = residency;
  if (++frame_ == 0) {
    std::fill(evalStamp_.begin(), evalStamp_.end(), 0u);
    std::fill(costStamp_.begin(), costStamp_.end(), 0u);
    std::fill(reqStamp_.begin(), reqStamp_.end(), 0u);
    frame_ = 1;
  }
  planes_ = makeFrustum(view.camera).planes;
  rootRel_ = tree_.info().rootMin_m - view.camera.eye_m;
  pxPerM_ = pixelsPerRadian(view);
  near_m_ = view.camera.near_m;
  alpha_ = static_cast<float>(view.minVoxel_px);
  const uint64_t budget = view.voxelBudget, W = view.byteBudget;
  uint32_t ops = 0;

  forcedMerges_ = 0;
  unknownCover_.clear();
  while (!walkCut()) {
  }
  stats.merges = forcedMerges_;

  reqOut_ = requests;
  reqCount_ = 0;
  reqBytes_ = 0;
  W_ = W;
  unfetchable_ = 0;

  const auto splitLess = [](const HeapEntry& a, const HeapEntry& b) { return a.e < b.e; };
  const auto mergeLess = [](const HeapEntry& a, const HeapEntry& b) { return a.e > b.e; };
  auto popMerge = [&]() {
    std::pop_heap(mergeHeap_.begin(), mergeHeap_.end(), mergeLess);
    const uint32_t p = mergeHeap_.back().cell;
    mergeHeap_.pop_back();
    return p;
  };
  auto doMerge = [&](uint32_t p, uint64_t saving) {
    merge(p);
    cost_ -= saving;
    ++stats.merges;
    ++ops;
    if (refinable(p) && !pushSplit(p)) stats.capped = true;
    const uint32_t gp = tree_.parent(p);
    if (gp != kNoCell && mergeCandidate(gp) && !pushMerge(gp)) stats.capped = true;
  };

  if (state_[0] == kCut && !drawable(0)) {
    // Nothing drawable yet: fetch the root.
    request(0);
    stats.feasible = false;
  } else {
    std::make_heap(splitHeap_.begin(), splitHeap_.end(), splitLess);
    std::make_heap(mergeHeap_.begin(), mergeHeap_.end(), mergeLess);
    // Over budget (the view came closer, cells became visible): coarsen, smallest e first.
    while (cost_ > budget && !mergeHeap_.empty()) {
      const uint32_t p = popMerge();
      if (!mergeCandidate(p) || !drawable(p)) continue;
      doMerge(p, mergeSaving(p));
    }
    stats.feasible = cost_ <= budget;
    if (!stats.feasible) requestUnknownCovers();  // a cheaper cover may hide below cells not resident

    // Refine: largest on-screen voxel first.
    uint64_t reserved = 0;
    while (stats.feasible && !splitHeap_.empty()) {
      if (ops >= config_.maxOperations) {
        stats.capped = true;
        break;
      }
      std::pop_heap(splitHeap_.begin(), splitHeap_.end(), splitLess);
      const uint32_t c = splitHeap_.back().cell;
      splitHeap_.pop_back();
      if (state_[c] != kCut) continue;
      evaluateChildren(c);
      const uint32_t first = tree_.firstChild(c), count = tree_.childCount(c);
      uint64_t childCost = 0;
      bool missing = false;
      for (uint32_t i = 0; i < count; ++i) {
        const uint32_t ch = first + i;
        if (!drawable(ch)) {
          missing = true;
          childCost += tree_.voxels(ch);
        } else {
          childCost += cost(ch);
        }
      }
      const uint64_t own = cost(c);
      const uint64_t delta = childCost > own ? childCost - own : 0;
      // Make room by merging cells whose voxels are smaller on screen than c's.
      while (cost_ + reserved + delta > budget && !mergeHeap_.empty() && mergeHeap_.front().e < e_[c]) {
        const uint32_t p = popMerge();
        if (!mergeCandidate(p) || !drawable(p)) continue;
        const uint64_t saving = mergeSaving(p);
        if (saving > 0) doMerge(p, saving);
      }
      if (cost_ + reserved + delta > budget) {
        // The largest voxel cannot shrink: balanced. Fetch the cells whose residency may reveal
        // cheaper covers of cells cut by the frustum (their cost is counted as V until then).
        requestUnknownCovers();
        break;
      }
      if (!missing) {
        state_[c] = kRefined;
        for (uint32_t i = 0; i < count; ++i) {
          state_[first + i] = kCut;
          if (refinable(first + i) && !pushSplit(first + i)) stats.capped = true;
        }
        if (!pushMerge(c)) stats.capped = true;
        cost_ += delta;
        ++stats.splits;
        ++ops;
        continue;
      }
      // Blocked: request the missing children (within W) and hold their voxels.
      bool all = true;
      for (uint32_t i = 0; i < count; ++i)
        if (!drawable(first + i) && !request(first + i)) all = false;
      if (all) {
        reserved += delta;
        ++stats.blockedSplits;
      }
    }
    stats.reservedVoxels = reserved;
  }
  stats.requestedCells = reqCount_;
  stats.requestedBytes = reqBytes_;
  stats.unfetchable = unfetchable_;
  reqOut_ = {};

  // Emit the realization's drawn cells.
  if (stats.feasible) {
    size_t top = 0;
    stack_[top++] = 0;
    uint32_t written = 0;
    while (top > 0) {
      const uint32_t c = stack_[--top];
      if (state_[c] == kRefined) {
        const uint32_t first = tree_.firstChild(c), count = tree_.childCount(c);
        for (uint32_t i = count; i-- > 0;) stack_[top++] = first + i;
        continue;
      }
      if (state_[c] != kCut) continue;
      if (!drawable(c)) continue;  // the root, not yet arrived
      emitCover(c, false, [&](uint32_t cell) {
        ++stats.cutCells;
        if (!live(cell)) return;
        stats.drawnVoxels += tree_.voxels(cell);
        stats.maxVoxel_px = std::max(stats.maxVoxel_px, e_[cell]);
        if (written < draw.size()) draw[written++] = {cell, e_[cell]};
        else stats.drawTruncated = true;
      });
    }
    stats.drawnCells = written;
  }
  return stats;
}

}  // namespace ig::lod
