// kd-tree of near trees and the per-frame cull / gather / sort (paper 004, shared/SEEDS.md
// section 004, "batching"). The rule and the memory contract are in forest_kdtree.h.
#include "lod/forest_kdtree.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

namespace ig::lod {
namespace {

bool finite(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// One stable counting-sort pass over 8 bits of key(x).
template <class Key>
void countingPass(std::span<const ForestInstance> in, std::span<ForestInstance> out, Key key,
                  std::array<uint32_t, 256>* histogramOut = nullptr) {
  std::array<uint32_t, 256> count{};
  for (const ForestInstance& x : in) ++count[key(x)];
  if (histogramOut) *histogramOut = count;
  uint32_t sum = 0;
  for (uint32_t& c : count) {
    const uint32_t k = c;
    c = sum;
    sum += k;
  }
  for (const ForestInstance& x : in) out[count[key(x)]++] = x;
}

}  // namespace

bool ForestKdTree::build(std::span<const TreeInstance> trees, const ForestKdParams& p, std::string& error) {
  nodes_.clear();
  leaves_.clear();
  trees_.clear();
  source_.clear();
  depth_ = 0;
  if (!(p.leafSize_m > 0.0) || !std::isfinite(p.leafSize_m)) {
    error = "forest kd-tree: leafSize_m = " + std::to_string(p.leafSize_m) + ": must be finite and > 0";
    return false;
  }
  if (!(p.treeHeight_m >= 0.0 && p.crownRadius_m >= 0.0) || !std::isfinite(p.treeHeight_m + p.crownRadius_m)) {
    error = "forest kd-tree: treeHeight_m = " + std::to_string(p.treeHeight_m) + ", crownRadius_m = " +
            std::to_string(p.crownRadius_m) + ": must be finite and >= 0";
    return false;
  }
  if (p.modelCount < 1 || p.modelCount > 256) {
    error = "forest kd-tree: modelCount = " + std::to_string(p.modelCount) + ": outside 1..256";
    return false;
  }
  if (trees.size() >= std::numeric_limits<uint32_t>::max()) {
    error = "forest kd-tree: " + std::to_string(trees.size()) + " trees: too many";
    return false;
  }
  params_ = p;
  sphereRadius_m_ = static_cast<float>(std::sqrt(p.crownRadius_m * p.crownRadius_m + 0.25 * p.treeHeight_m * p.treeHeight_m));
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  for (size_t i = 0; i < trees.size(); ++i) {
    const TreeInstance& t = trees[i];
    if (!finite(t.base_m)) {
      error = "forest kd-tree: tree " + std::to_string(i) + " has a non-finite position";
      return false;
    }
    if (t.model >= p.modelCount) {
      error = "forest kd-tree: tree " + std::to_string(i) + " model = " + std::to_string(t.model) + ": >= modelCount " +
              std::to_string(p.modelCount);
      return false;
    }
    if (i == 0) {
      x0 = x1 = t.base_m.x;
      y0 = y1 = t.base_m.y;
    }
    x0 = std::min(x0, t.base_m.x);
    y0 = std::min(y0, t.base_m.y);
    x1 = std::max(x1, t.base_m.x);
    y1 = std::max(y1, t.base_m.y);
  }
  std::vector<uint32_t> idx(trees.size());
  for (size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<uint32_t>(i);
  trees_.reserve(trees.size());
  source_.reserve(trees.size());
  nodes_.emplace_back();
  buildNode(0, idx, trees, x0, y0, x1, y1, 0);
  return true;
}

void ForestKdTree::buildNode(uint32_t node, std::span<uint32_t> idx, std::span<const TreeInstance> trees, double x0,
                             double y0, double x1, double y1, int depth) {
  depth_ = std::max(depth_, depth);
  const double w = x1 - x0, h = y1 - y0;
  if (idx.empty() || std::max(w, h) <= params_.leafSize_m || depth >= kMaxDepth - 2) {
    ForestKdLeaf leaf;
    leaf.first = static_cast<uint32_t>(trees_.size());
    leaf.count = static_cast<uint32_t>(idx.size());
    double z0 = 0, z1 = 0;
    for (size_t k = 0; k < idx.size(); ++k) {
      const double z = trees[idx[k]].base_m.z;
      z0 = k == 0 ? z : std::min(z0, z);
      z1 = k == 0 ? z : std::max(z1, z);
    }
    leaf.region = {{x0, y0, z0}, {x1, y1, z1}};
    const glm::dvec3 ext = leaf.region.max - leaf.region.min;
    leaf.step = glm::vec3(ext / 65535.0);
    const double r = static_cast<double>(sphereRadius_m_) * (1.0 + 1e-5) + 1e-3, hh = 0.5 * params_.treeHeight_m;
    Aabb b{leaf.region.min - glm::dvec3(r, r, r - hh), leaf.region.max + glm::dvec3(r, r, r + hh)};
    if (idx.empty()) b = {glm::dvec3(0.0), glm::dvec3(0.0)};
    for (uint32_t i : idx) {
      const TreeInstance& t = trees[i];
      PackedTree pt{};
      for (int a = 0; a < 3; ++a) {
        const double e = ext[a] > 0.0 ? (t.base_m[a] - leaf.region.min[a]) / ext[a] : 0.0;
        pt.q[a] = static_cast<uint16_t>(std::clamp(std::lround(e * 65535.0), 0L, 65535L));
      }
      pt.normal[0] = static_cast<int8_t>(std::lround(std::clamp(t.normal.x, -1.0f, 1.0f) * 127.0f));
      pt.normal[1] = static_cast<int8_t>(std::lround(std::clamp(t.normal.y, -1.0f, 1.0f) * 127.0f));
      pt.rgba = t.rgba;
      pt.model = t.model;
      trees_.push_back(pt);
      source_.push_back(i);
    }
    nodes_[node].bounds = b;
    nodes_[node].isLeaf = 1;
    nodes_[node].child = static_cast<uint32_t>(leaves_.size());
    leaves_.push_back(leaf);
    return;
  }
  const int axis = w >= h ? 0 : 1;
  const double mid = axis == 0 ? 0.5 * (x0 + x1) : 0.5 * (y0 + y1);
  const auto split = std::partition(idx.begin(), idx.end(), [&](uint32_t i) { return trees[i].base_m[axis] < mid; });
  const auto nLeft = static_cast<size_t>(split - idx.begin());
  const auto child = static_cast<uint32_t>(nodes_.size());
  nodes_.emplace_back();
  nodes_.emplace_back();
  nodes_[node].child = child;
  if (axis == 0) {
    buildNode(child, idx.first(nLeft), trees, x0, y0, mid, y1, depth + 1);
    buildNode(child + 1, idx.subspan(nLeft), trees, mid, y0, x1, y1, depth + 1);
  } else {
    buildNode(child, idx.first(nLeft), trees, x0, y0, x1, mid, depth + 1);
    buildNode(child + 1, idx.subspan(nLeft), trees, x0, mid, x1, y1, depth + 1);
  }
  const bool le = nLeft == 0, re = nLeft == idx.size();
  const Aabb& a = nodes_[child].bounds;
  const Aabb& b = nodes_[child + 1].bounds;
  nodes_[node].bounds = le ? b : re ? a : Aabb{glm::min(a.min, b.min), glm::max(a.max, b.max)};
}

std::array<glm::vec4, 6> ForestKdTree::eyeRelativePlanes(const Camera& cam) {
  const Frustum fr = makeFrustum(cam);
  std::array<glm::vec4, 6> out;
  for (int i = 0; i < 6; ++i) out[static_cast<size_t>(i)] = glm::vec4(fr.planes[static_cast<size_t>(i)]);
  return out;
}

glm::vec3 ForestKdTree::decodeRelative(uint32_t i, const glm::dvec3& eye) const {
  const ForestKdLeaf& leaf = leaves_[leafOf(i)];
  const PackedTree& t = trees_[i];
  return glm::vec3(leaf.region.min - eye) + glm::vec3(t.q[0], t.q[1], t.q[2]) * leaf.step;
}

glm::dvec3 ForestKdTree::decode(uint32_t i) const {
  const ForestKdLeaf& leaf = leaves_[leafOf(i)];
  const PackedTree& t = trees_[i];
  return leaf.region.min + glm::dvec3(t.q[0], t.q[1], t.q[2]) * glm::dvec3(leaf.step);
}

uint32_t ForestKdTree::leafOf(uint32_t i) const {
  // Leaves are in tree order: the last non-empty leaf starting at or before i.
  auto it = std::upper_bound(leaves_.begin(), leaves_.end(), i, [](uint32_t v, const ForestKdLeaf& l) { return v < l.first; });
  while (it != leaves_.begin()) {
    --it;
    if (it->count > 0) break;
  }
  assert(it != leaves_.end() && i - it->first < it->count && "ForestKdTree::leafOf: tree index out of range");
  return static_cast<uint32_t>(it - leaves_.begin());
}

bool ForestKdTree::treeAccepted(const glm::vec3& rel, const std::array<glm::vec4, 6>& planes, float range_m) const {
  if (!(glm::dot(rel, rel) < range_m * range_m)) return false;
  const glm::vec3 c = rel + glm::vec3(0.0f, 0.0f, 0.5f * static_cast<float>(params_.treeHeight_m));
  for (const glm::vec4& p : planes) {
    if (p.x * c.x + p.y * c.y + p.z * c.z + p.w < -sphereRadius_m_) return false;
  }
  return true;
}

size_t ForestKdTree::select(const Camera& cam, const NearFade& fade, std::span<ForestInstance> instances,
                            std::span<ForestInstance> scratch, std::span<ForestModelRange> models,
                            ForestSelectStats* stats) const {
  assert(scratch.size() >= instances.size() && "ForestKdTree::select: scratch smaller than instances");
  assert(models.size() >= static_cast<size_t>(params_.modelCount) && "ForestKdTree::select: models span too small");
  ForestSelectStats st;
  for (ForestModelRange& m : models) m = {};
  const double range = fade.fadeOutEnd_m;
  const bool camOk = finite(cam.eye_m) && std::isfinite(cam.heading_deg + cam.pitch_deg + cam.roll_deg + cam.fovY_deg +
                                                        cam.aspect + cam.near_m + cam.far_m);
  if (!camOk || !(range > 0.0) || !std::isfinite(range) || nodes_.empty() || !(cam.far_m > cam.near_m) ||
      !(cam.near_m > 0.0) || !(cam.fovY_deg > 0.0 && cam.fovY_deg < 180.0) || !(cam.aspect > 0.0) || !validWindowShift(cam)) {
    if (stats) *stats = st;
    return 0;
  }
  const Frustum fr = makeFrustum(cam);
  std::array<glm::vec4, 6> planes;
  for (size_t i = 0; i < 6; ++i) planes[i] = glm::vec4(fr.planes[i]);
  const auto rangeF = static_cast<float>(range);
  const float invRange = 65535.0f / rangeF;
  const double cullRange = range * (1.0 + 1e-5) + 1e-3;  // float rounding margin: stay conservative
  const glm::dvec3 eye = cam.eye_m;

  std::array<uint32_t, 2 * kMaxDepth> stack;
  size_t top = 0;
  stack[top++] = 0;
  size_t n = 0;
  const size_t cap = instances.size();
  while (top > 0) {
    const ForestKdNode& node = nodes_[stack[--top]];
    ++st.nodesVisited;
    if (distanceToBox(node.bounds, eye) >= cullRange) continue;
    if (!fr.intersects({node.bounds.min - eye, node.bounds.max - eye})) continue;
    if (!node.isLeaf) {
      const double da = distanceToBox(nodes_[node.child].bounds, eye);
      const double db = distanceToBox(nodes_[node.child + 1].bounds, eye);
      // Nearer child on top: visited first, so a full output keeps the nearer trees.
      stack[top++] = da <= db ? node.child + 1 : node.child;
      stack[top++] = da <= db ? node.child : node.child + 1;
      continue;
    }
    const ForestKdLeaf& leaf = leaves_[node.child];
    if (leaf.count == 0) continue;
    ++st.leavesVisible;
    st.treesTested += leaf.count;
    const glm::vec3 origin(leaf.region.min - eye);
    for (uint32_t i = leaf.first, e = leaf.first + leaf.count; i < e; ++i) {
      const PackedTree& t = trees_[i];
      const glm::vec3 rel = origin + glm::vec3(t.q[0], t.q[1], t.q[2]) * leaf.step;
      if (!treeAccepted(rel, planes, rangeF)) continue;
      if (n == cap) {
        ++st.dropped;
        continue;
      }
      const float d = std::sqrt(glm::dot(rel, rel));
      ForestInstance& o = scratch[n++];
      o.offset_m[0] = rel.x;
      o.offset_m[1] = rel.y;
      o.offset_m[2] = rel.z;
      o.alpha = static_cast<float>(nearAlpha(fade, static_cast<double>(d)));
      o.rgba = t.rgba;
      o.tree = i;
      o.normal[0] = t.normal[0];
      o.normal[1] = t.normal[1];
      o.model = t.model;
      o.pad = 0;
      o.key = static_cast<uint16_t>(65535 - static_cast<int>(std::min(d * invRange, 65535.0f)));
      o.pad2 = 0;
    }
  }
  // Sort by (model, key) ascending: per model, far to near. LSD radix, 3 stable passes.
  const std::span<const ForestInstance> s0(scratch.data(), n);
  const std::span<ForestInstance> i0(instances.data(), n);
  std::array<uint32_t, 256> modelHist{};
  countingPass(s0, i0, [](const ForestInstance& x) { return x.key & 255u; });
  countingPass(std::span<const ForestInstance>(i0), scratch.first(n), [](const ForestInstance& x) { return x.key >> 8; });
  countingPass(s0, i0, [](const ForestInstance& x) { return static_cast<uint32_t>(x.model); }, &modelHist);
  uint32_t first = 0;
  for (int m = 0; m < params_.modelCount; ++m) {
    models[static_cast<size_t>(m)] = {first, modelHist[static_cast<size_t>(m)]};
    first += modelHist[static_cast<size_t>(m)];
  }
  st.drawn = static_cast<uint32_t>(n);
  if (stats) *stats = st;
  return n;
}

}  // namespace ig::lod
