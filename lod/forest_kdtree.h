// Near forest (paper 004, shared/SEEDS.md section 004): the trees batched in a kd-tree, and the
// per-frame selection of 3D trees to draw.
//
// Build (start-up, O(n log n)): the forest's ground rectangle is split at the midpoint of its
// longer side while that side is longer than leafSize_m (default 256 m); a region with no
// trees becomes an empty leaf at once. So every leaf is empty or its sides lie in
// (leafSize_m / 2, leafSize_m] (for a forest whose sides are above leafSize_m, and down to the
// depth cap kMaxDepth: a leafSize_m so small that splitting would go deeper keeps larger leaves) and it holds
// every tree inside it (as many as fit: there is no count limit but 2^32). Trees are stored in
// leaf order, 16 bytes each (PackedTree): the position relative to the leaf's box quantised to
// 16 bits per axis (about 4 mm for a 256 m leaf), the normal as two signed bytes (nz >= 0
// rebuilt), the colour RGBA8 and the model index. Nodes keep a tight box of their trees grown
// by the largest model's crown radius and height.
//
// Selection rule (per frame, for one camera): a tree is drawn if
//   - its distance d = |base - eye| is below near.fadeOutEnd_m (nearAlpha(d) > 0), and
//   - its bounding sphere (centre base + (0, 0, height/2), radius sqrt(crown^2 + (height/2)^2)
//     of the largest model) intersects the frustum (all six planes, the camera's far plane too).
// Both tests run on the decoded eye-relative position in float (treeAccepted below), so a brute
// force over all trees with the same predicate gives exactly the same set. Nodes are culled
// against the frustum and against the near range (distanceToBox >= fadeOutEnd) first; that
// test is conservative (it never drops a tree the rule accepts; tested).
// Output: the drawn trees grouped per model (one instanced draw each, in model order), and in
// each group sorted far to near (LSD radix sort on a 16-bit distance key, stable: equal keys
// keep kd order), each with its alpha nearAlpha(d) and its position relative to the eye in
// float (camera-relative rendering). A NaN or infinite camera selects nothing.
//
// Memory: select() writes into caller buffers and does not allocate. If `instances` is too
// small, the nearer subtrees (visited first) are kept and `dropped` counts the rest.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "lod/forest.h"
#include "lod/view.h"

namespace ig::lod {

struct ForestKdParams {
  double leafSize_m = 256.0;     // largest leaf side
  double treeHeight_m = 25.0;    // of the tallest model (node boxes and the per-tree sphere)
  double crownRadius_m = 4.0;    // of the widest model
  int modelCount = 2;            // 1..256; trees with a larger index are rejected by build()
};

struct PackedTree {
  uint16_t q[3];     // position in the leaf box: min + q * step
  int8_t normal[2];  // nx, ny * 127; nz = sqrt(1 - nx^2 - ny^2)
  uint32_t rgba;
  uint8_t model;
  uint8_t pad[3];
};
static_assert(sizeof(PackedTree) == 16);

struct ForestKdNode {
  Aabb bounds;         // tight box of the subtree's trees (grown by crown and height), ENU
  uint32_t child = 0;  // inner: index of the first child (the second is child + 1); leaf: leaf index
  uint32_t isLeaf = 0;
};

struct ForestKdLeaf {
  Aabb region;          // the leaf's ground rectangle (x, y) and its trees' base z range
  glm::vec3 step{0.0f};  // quantisation step per axis (region extent / 65535)
  uint32_t first = 0;   // into trees()
  uint32_t count = 0;
};

// One tree to draw (instance data).
struct ForestInstance {
  float offset_m[3];  // tree base minus eye (ENU, float: camera-relative)
  float alpha;        // nearAlpha(d)
  uint32_t rgba;
  uint32_t tree;      // index into ForestKdTree::trees() (and sourceIndex())
  int8_t normal[2];
  uint8_t model;
  uint8_t pad;
  uint16_t key;       // distance key (internal: 65535 = farthest)
  uint16_t pad2;
};

struct ForestModelRange {
  uint32_t first = 0;  // into the instances span
  uint32_t count = 0;
};

struct ForestSelectStats {
  uint32_t nodesVisited = 0;
  uint32_t leavesVisible = 0;
  uint32_t treesTested = 0;
  uint32_t drawn = 0;
  uint32_t dropped = 0;  // accepted but no room in `instances`
};

class ForestKdTree {
 public:
  // Builds the tree. Returns false with `error` for bad parameters or a tree with a NaN
  // position or a model index >= modelCount. `trees` may be empty (one empty leaf).
  bool build(std::span<const TreeInstance> trees, const ForestKdParams& params, std::string& error);

  // Selection (rule above). `instances` holds the output grouped per model; `scratch` must be
  // at least as large as `instances`; `models` needs params.modelCount entries. Returns the
  // number of instances written. No allocation.
  size_t select(const Camera& cam, const NearFade& fade, std::span<ForestInstance> instances,
                std::span<ForestInstance> scratch, std::span<ForestModelRange> models,
                ForestSelectStats* stats = nullptr) const;

  // The per-tree rule on the decoded eye-relative position (see the header comment).
  bool treeAccepted(const glm::vec3& rel, const std::array<glm::vec4, 6>& planes, float range_m) const;
  // Eye-relative float frustum planes for treeAccepted.
  static std::array<glm::vec4, 6> eyeRelativePlanes(const Camera& cam);
  // Decoded base position of packed tree i relative to `eye` (as select() computes it).
  glm::vec3 decodeRelative(uint32_t i, const glm::dvec3& eye) const;
  glm::dvec3 decode(uint32_t i) const;

  std::span<const ForestKdNode> nodes() const { return nodes_; }
  std::span<const ForestKdLeaf> leaves() const { return leaves_; }
  std::span<const PackedTree> trees() const { return trees_; }
  // Index in the build input of packed tree i.
  std::span<const uint32_t> sourceIndex() const { return source_; }
  uint32_t leafOf(uint32_t packedTree) const;  // linear search over leaves (tests)
  const ForestKdParams& params() const { return params_; }
  int depth() const { return depth_; }

  static constexpr int kMaxDepth = 64;

 private:
  void buildNode(uint32_t node, std::span<uint32_t> idx, std::span<const TreeInstance> trees, double x0, double y0,
                 double x1, double y1, int depth);
  float sphereRadius_m_ = 0.0f;

  ForestKdParams params_;
  std::vector<ForestKdNode> nodes_;
  std::vector<ForestKdLeaf> leaves_;
  std::vector<PackedTree> trees_;
  std::vector<uint32_t> source_;
  int depth_ = 0;
};

}  // namespace ig::lod
