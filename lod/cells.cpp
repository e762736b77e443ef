#include "lod/cells.h"

#include <cmath>
#include <cstdio>

namespace ig::lod {

void CellTree::clear() {
  info_ = {};
  for (auto* v : {&parent_, &firstChild_, &voxels_, &bytes_, &levelBegin_}) v->clear();
  for (auto* v : {&childCount_, &level_, &flags_}) v->clear();
  for (auto* v : {&x_, &y_, &z_}) v->clear();
  cellEdge_m_.clear();
  voxelEdge_m_.clear();
}

bool CellTree::build(const CellTreeInfo& info, std::span<const CellDesc> cells, std::string& error) {
  clear();
  char msg[256];
  auto fail = [&](const char* text) {
    error = text;
    clear();
    return false;
  };
  if (!std::isfinite(info.rootMin_m.x) || !std::isfinite(info.rootMin_m.y) || !std::isfinite(info.rootMin_m.z))
    return fail("cell tree: rootMin_m is not finite");
  if (!(info.rootEdge_m > 0.0) || !std::isfinite(info.rootEdge_m)) {
    std::snprintf(msg, sizeof msg, "cell tree: rootEdge_m = %g: must be finite and > 0", info.rootEdge_m);
    return fail(msg);
  }
  if (info.cellVoxelDepth < 0 || info.cellVoxelDepth > 20) {
    std::snprintf(msg, sizeof msg, "cell tree: cellVoxelDepth = %d: allowed range 0..20", info.cellVoxelDepth);
    return fail(msg);
  }
  if (cells.empty()) return fail("cell tree: no cells (the root is required)");
  if (cells.size() >= kNoCell) return fail("cell tree: too many cells");
  if (cells[0].parent != kNoCell) return fail("cell tree: cell 0 (the root) must have parent kNoCell");

  const size_t n = cells.size();
  parent_.resize(n);
  firstChild_.assign(n, kNoCell);
  voxels_.resize(n);
  bytes_.resize(n);
  childCount_.assign(n, 0);
  level_.resize(n);
  flags_.resize(n);
  x_.resize(n);
  y_.resize(n);
  z_.resize(n);
  levelBegin_.push_back(0);
  std::vector<uint64_t> childVoxels(n, 0);

  for (size_t i = 0; i < n; ++i) {
    const CellDesc& d = cells[i];
    parent_[i] = d.parent;
    voxels_[i] = d.voxels;
    bytes_[i] = d.bytes;
    flags_[i] = d.voxels == 0 ? kCellEmpty : 0;
    if (i == 0) {
      level_[0] = 0;
      x_[0] = y_[0] = z_[0] = 0;
      continue;
    }
    const uint32_t p = d.parent;
    if (p == kNoCell || p >= i) {
      std::snprintf(msg, sizeof msg, "cell tree: cell %zu: parent = %u: must be an earlier cell", i, p);
      return fail(msg);
    }
    if (d.octant > 7) {
      std::snprintf(msg, sizeof msg, "cell tree: cell %zu: octant = %u: allowed range 0..7", i, d.octant);
      return fail(msg);
    }
    const int lvl = level_[p] + 1;
    if (lvl >= kMaxCellLevels) {
      std::snprintf(msg, sizeof msg, "cell tree: cell %zu: level %d: at most %d levels", i, lvl, kMaxCellLevels);
      return fail(msg);
    }
    if (i > 1 && p < parent_[i - 1]) {
      std::snprintf(msg, sizeof msg, "cell tree: cell %zu: parent %u after a child of cell %u: not breadth-first", i,
                    p, parent_[i - 1]);
      return fail(msg);
    }
    if (firstChild_[p] == kNoCell) {
      firstChild_[p] = static_cast<uint32_t>(i);
    } else if (d.octant <= cells[i - 1].octant) {
      std::snprintf(msg, sizeof msg, "cell tree: cell %zu: octant %u after octant %u of the same parent %u", i,
                    d.octant, cells[i - 1].octant, p);
      return fail(msg);
    }
    ++childCount_[p];
    level_[i] = static_cast<uint8_t>(lvl);
    if (lvl > level_[i - 1]) levelBegin_.push_back(static_cast<uint32_t>(i));
    x_[i] = static_cast<uint16_t>(x_[p] * 2 + (d.octant & 1));
    y_[i] = static_cast<uint16_t>(y_[p] * 2 + ((d.octant >> 1) & 1));
    z_[i] = static_cast<uint16_t>(z_[p] * 2 + ((d.octant >> 2) & 1));
    childVoxels[p] += d.voxels;
    if (d.voxels > 0 && voxels_[p] == 0) {
      std::snprintf(msg, sizeof msg, "cell tree: cell %zu: V = %u inside an empty parent %u (octree images are monotone)",
                    i, d.voxels, p);
      return fail(msg);
    }
  }
  levelBegin_.push_back(static_cast<uint32_t>(n));
  for (size_t i = 0; i < n; ++i) {
    if (childCount_[i] > 0 && childVoxels[i] < voxels_[i]) {
      std::snprintf(msg, sizeof msg,
                    "cell tree: cell %zu: V = %u but its children hold %llu voxels (must be >= V: octree images are "
                    "monotone)",
                    i, voxels_[i], static_cast<unsigned long long>(childVoxels[i]));
      return fail(msg);
    }
  }
  info_ = info;
  const int L = levels();
  cellEdge_m_.resize(static_cast<size_t>(L));
  voxelEdge_m_.resize(static_cast<size_t>(L));
  for (int q = 0; q < L; ++q) {
    cellEdge_m_[static_cast<size_t>(q)] = std::ldexp(info.rootEdge_m, -q);
    voxelEdge_m_[static_cast<size_t>(q)] = std::ldexp(info.rootEdge_m, -(q + info.cellVoxelDepth));
  }
  error.clear();
  return true;
}

Aabb CellTree::box(uint32_t c) const {
  const double e = cellEdge_m_[level_[c]];
  Aabb b;
  b.min = info_.rootMin_m + glm::dvec3(x_[c], y_[c], z_[c]) * e;
  b.max = b.min + glm::dvec3(e);
  return b;
}

uint64_t CellTree::totalVoxels(int level) const {
  uint64_t s = 0;
  for (uint32_t c = levelBegin(level); c < levelBegin(level + 1); ++c) s += voxels_[c];
  return s;
}

uint64_t CellTree::totalBytes() const {
  uint64_t s = 0;
  for (uint32_t b : bytes_) s += b;
  return s;
}

}  // namespace ig::lod
