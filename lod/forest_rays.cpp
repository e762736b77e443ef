#include "lod/forest_rays.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

namespace ig::lod {
namespace {

bool finite3(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// The vertex shader's hash (render/forest_pass.cpp, kTreeVs: hash(iTree)).
uint32_t shaderHash(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

constexpr double kMaxScale = 1.1, kMinScale = 0.9;  // treePose's range
constexpr double kMaxCells = 4.0e6;

glm::dvec3 baseOf(const ForestKdLeaf& leaf, const PackedTree& t) {
  return leaf.region.min + glm::dvec3(t.q[0], t.q[1], t.q[2]) * glm::dvec3(leaf.step);
}

}  // namespace

TreePose treePose(uint32_t tree, float jitter) {
  const uint32_t h = shaderHash(tree);
  // The shader's float arithmetic, in the same order.
  const float yaw = static_cast<float>(h & 0xffffu) * (6.2831853f / 65536.0f) * jitter;
  const float s = 1.0f + 0.2f * jitter * (static_cast<float>((h >> 16) & 0xffu) / 255.0f - 0.5f);
  return {static_cast<double>(yaw), static_cast<double>(s)};
}

ForestRays::ForestRays(const ForestKdTree& kd, std::span<const TreeMesh> models, float yawJitter) : jitter_(yawJitter) {
  models_.resize(models.size());
  double radius = 0.0, zLow = 0.0, zHigh = 0.0;
  for (size_t m = 0; m < models.size(); ++m) {
    const TreeMesh& mesh = models[m];
    Model& out = models_[m];
    out.mesh = MeshRays(mesh.vertices.empty() ? nullptr : mesh.vertices[0].position, mesh.vertices.size(),
                        sizeof(TreeVertex), mesh.indices);
    if (out.mesh.empty()) continue;
    out.zMin_m = std::numeric_limits<double>::infinity();
    out.zMax_m = -std::numeric_limits<double>::infinity();
    for (const TreeVertex& v : mesh.vertices) {
      out.radius_m = std::max(out.radius_m, std::hypot(static_cast<double>(v.position[0]), static_cast<double>(v.position[1])));
      out.zMin_m = std::min(out.zMin_m, static_cast<double>(v.position[2]));
      out.zMax_m = std::max(out.zMax_m, static_cast<double>(v.position[2]));
    }
    radius = std::max(radius, out.radius_m * kMaxScale);
    zLow = std::min(zLow, std::min(out.zMin_m * kMaxScale, out.zMin_m * kMinScale));
    zHigh = std::max(zHigh, out.zMax_m * kMaxScale);
  }
  const std::span<const ForestKdLeaf> leaves = kd.leaves();
  const std::span<const PackedTree> trees = kd.trees();
  if (trees.empty()) return;
  // The trees' bases and their leaves.
  leafOf_.assign(trees.size(), 0);
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  for (uint32_t l = 0; l < leaves.size(); ++l) {
    for (uint32_t i = leaves[l].first; i < leaves[l].first + leaves[l].count && i < trees.size(); ++i) {
      leafOf_[i] = l;
      const glm::dvec3 b = baseOf(leaves[l], trees[i]);
      lo = glm::min(lo, b);
      hi = glm::max(hi, b);
    }
  }
  if (!finite3(lo) || !finite3(hi)) return;
  boxMin_ = lo + glm::dvec3(-radius, -radius, zLow);
  boxMax_ = hi + glm::dvec3(radius, radius, zHigh);
  const double ex = boxMax_.x - boxMin_.x, ey = boxMax_.y - boxMin_.y;
  cell_m_ = std::max({8.0, 2.0 * radius, std::sqrt(ex * ey / kMaxCells)});
  nx_ = static_cast<uint32_t>(std::max(1.0, std::ceil(ex / cell_m_)));
  ny_ = static_cast<uint32_t>(std::max(1.0, std::ceil(ey / cell_m_)));
  // Each tree into every cell its crown box reaches (two passes: count, then fill).
  const auto cellRange = [&](const glm::dvec3& b, uint32_t& x0, uint32_t& x1, uint32_t& y0, uint32_t& y1) {
    const auto clampCell = [](double v, uint32_t n) {
      return static_cast<uint32_t>(std::clamp(std::floor(v), 0.0, static_cast<double>(n - 1)));
    };
    x0 = clampCell((b.x - radius - boxMin_.x) / cell_m_, nx_);
    x1 = clampCell((b.x + radius - boxMin_.x) / cell_m_, nx_);
    y0 = clampCell((b.y - radius - boxMin_.y) / cell_m_, ny_);
    y1 = clampCell((b.y + radius - boxMin_.y) / cell_m_, ny_);
  };
  cellStart_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<uint32_t> fill;
    if (pass == 1) {
      for (size_t c = 1; c < cellStart_.size(); ++c) cellStart_[c] += cellStart_[c - 1];
      entries_.resize(cellStart_.back());
      fill.assign(cellStart_.begin(), cellStart_.end() - 1);
    }
    for (uint32_t i = 0; i < trees.size(); ++i) {
      uint32_t x0, x1, y0, y1;
      cellRange(baseOf(leaves[leafOf_[i]], trees[i]), x0, x1, y0, y1);
      for (uint32_t y = y0; y <= y1; ++y)
        for (uint32_t x = x0; x <= x1; ++x) {
          const size_t c = static_cast<size_t>(y) * nx_ + x;
          if (pass == 0) ++cellStart_[c + 1];
          else entries_[fill[c]++] = i;
        }
    }
  }
  kd_ = &kd;
}

bool ForestRays::testTree(uint32_t i, const glm::dvec3& from, const glm::dvec3& d, double& best, TreeHit& hit,
                          RayWork& w) const {
  const PackedTree& t = kd_->trees()[i];
  ++w.nodes;  // a tree's box: counted like a node
  if (t.model >= models_.size() || models_[t.model].mesh.empty()) return false;
  const Model& model = models_[t.model];
  const glm::dvec3 base = baseOf(kd_->leaves()[leafOf_[i]], t);
  const TreePose pose = treePose(i, jitter_);
  const double r = model.radius_m * pose.scale;
  if (!segmentMeetsBox(from, d, std::min(best, 1.0), base + glm::dvec3(-r, -r, model.zMin_m * pose.scale),
                       base + glm::dvec3(r, r, model.zMax_m * pose.scale)))
    return false;
  // Into the tree's space: world = base + R(yaw) (s p), so p = R(-yaw) (world - base) / s.
  const double c = std::cos(pose.yaw_rad), sn = std::sin(pose.yaw_rad), inv = 1.0 / pose.scale;
  auto local = [&](const glm::dvec3& v) { return glm::dvec3(c * v.x + sn * v.y, -sn * v.x + c * v.y, v.z) * inv; };
  glm::dvec3 normal;
  if (!model.mesh.intersect(local(from - base), local(d), best, normal, w)) return false;
  hit.t = best;
  hit.normal = glm::dvec3(c * normal.x - sn * normal.y, sn * normal.x + c * normal.y, normal.z);
  hit.tree = i;
  return true;
}

bool ForestRays::intersect(const glm::dvec3& from_m, const glm::dvec3& to_m, TreeHit& hit, RayWork* work) const {
  if (kd_ == nullptr || !finite3(from_m) || !finite3(to_m)) return false;
  const glm::dvec3 d = to_m - from_m;
  if (!finite3(d)) return false;
  RayWork w;
  double best = std::numeric_limits<double>::infinity();
  bool found = false;
  double tIn = 0.0, tOut = 0.0;
  ++w.nodes;
  if (segmentMeetsBox(from_m, d, 1.0, boxMin_, boxMax_, tIn, tOut)) {
    // 2D DDA over the cells the ground track crosses between tIn and tOut.
    const glm::dvec3 p = from_m + d * tIn;
    const auto cellOf = [&](double v, double origin, uint32_t n) {
      return static_cast<int64_t>(std::clamp(std::floor((v - origin) / cell_m_), 0.0, static_cast<double>(n - 1)));
    };
    int64_t cx = cellOf(p.x, boxMin_.x, nx_), cy = cellOf(p.y, boxMin_.y, ny_);
    const int64_t stepX = d.x > 0.0 ? 1 : -1, stepY = d.y > 0.0 ? 1 : -1;
    const double inf = std::numeric_limits<double>::infinity();
    // Where the track crosses the next cell boundary in x and in y, and the step between crossings.
    const auto firstCross = [&](double dir, int64_t cell, double origin, double start) {
      if (dir == 0.0) return inf;
      const double edge = origin + static_cast<double>(dir > 0.0 ? cell + 1 : cell) * cell_m_;
      return (edge - start) / dir;
    };
    double tx = firstCross(d.x, cx, boxMin_.x, from_m.x), ty = firstCross(d.y, cy, boxMin_.y, from_m.y);
    const double dtx = d.x == 0.0 ? inf : cell_m_ / std::abs(d.x), dty = d.y == 0.0 ? inf : cell_m_ / std::abs(d.y);
    for (;;) {
      ++w.nodes;
      const size_t c = static_cast<size_t>(cy) * nx_ + static_cast<size_t>(cx);
      for (uint32_t k = cellStart_[c]; k < cellStart_[c + 1]; ++k)
        found = testTree(entries_[k], from_m, d, best, hit, w) || found;
      const double tExit = std::min({tx, ty, tOut});
      if (best <= tExit || tExit >= tOut) break;  // a hit in this cell, or the track leaves the box
      if (tx <= ty) {
        cx += stepX;
        tx += dtx;
      } else {
        cy += stepY;
        ty += dty;
      }
      if (cx < 0 || cy < 0 || cx >= nx_ || cy >= ny_) break;
    }
  }
  if (found) hit.point_m = from_m + d * hit.t;
  if (work) {
    work->nodes += w.nodes;
    work->triangles += w.triangles;
  }
  return found;
}

}  // namespace ig::lod
