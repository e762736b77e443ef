// HDLOD, part 2: the cluster tree of paper 000 (shared/seeds/000, section 3 and appendix 2).
//
// Tree: a virtual root over the paper's three trees: the static objects, the pseudo-dynamic
// objects (both clustered by appendix 2; static clusters have f_c = 1 throughout, so only the
// spatial error counts) and a group of the dynamic objects. Each cluster c holds
// (g_c, f_c, b_c, w_c, eps_c, gamma_c):
//
// - Leaves are objects: g_c = the object's model (shared, instanced), its constant matrix
//   (static / pseudo-dynamic) or its path (dynamic); eps_c = 0; f_c = v_s.
// - Merged clusters (built bottom-up, appendix 2): g_c = the union of the children's geometry,
//   material by material (each scene model's triangles on their own, so a window 12 cm in
//   front of its facade panel never turns into panel: the colour, not only the surface, stays
//   within eps), simplified to eps(l) by BuildConfig::simplifier (lod/hdlod_simplify.h: meshoptimizer by
//   default, OpenMesh's Decimater, or the vertex clustering on a grid of cell eps(l) anchored at
//   the tree's box kept for comparison); stored in float relative to the cluster's origin (its
//   box centre, double), so huge world coordinates keep their precision.
// - eps_c = D(children -> g_c) + max over children eps_child, where D is the largest over the
//   materials of a sampled one-sided Hausdorff distance between that material's triangles: the largest distance from a sample of the children's surfaces (every
//   vertex and centroid of the triangles with three distinct corners: one with coincident corners
//   draws nothing; at most `maxHausdorffSamples`, evenly strided) to the
//   nearest point of the simplified complex (exact point-triangle distance through a BVH), and
//   with `twoSidedHausdorff` (default, the paper's D_H) also from a sample of the simplified
//   triangles back to the children's (their corners, and a barycentric grid of 4 steps per edge
//   over each triangle while the sample cap allows, else its centroid: a triangle spanning a
//   gap of the input has its corners and centroid on the input), whatever the simplifier (their
//   own error estimates are not used). The complex is g_c's
//   triangles plus, for vertex clustering only, the segments and points it made of the
//   collapsed triangles (Rossignac-Borrel): a thin column that collapses to a segment counts as
//   an error of about its thickness (what is lost on screen), not as its distance to the
//   nearest surviving triangle. `strictHausdorff` measures against g_c's triangles only. With no
//   triangle, segment or point left, D = half the diagonal of the children's box.
// - w_s (object weight) = the diagonal of the object's world box, at least 1e-6 m;
//   w_c (cluster size) = the diagonal of b_c.
// - f_c(t) = sum_s w_s v_s(t) / sum_s w_s over the leaf objects of c: a step function on
//   [0, T] (exactly 0 when no object is present, exactly 1 when all are).
// - gamma_c = max over the objects s of c of the mean of |f_c(t) - v_s(t)| over [0, T].
// - delta_c(t) = eps_c + w_c * (1 - |2 f_c(t) - 1|): the digest's form of the lost formula
//   (eps_c when all or none of the cluster is present, eps_c + w_c when half of it is, as the
//   experiments describe: clusters with f_c near 0.5 are refined).
// - Dynamic objects: one leaf each (sharing their model), under group clusters of up to
//   `dynamicGroupSize` (sorted by first appearance time, so a group is often entirely absent);
//   a group's box holds its members' swept boxes and its f_c is 1 while any member is present.
//   Groups and the virtual root are never drawn themselves.
// - Model versions (the paper's "optional parents with simplified geometry" of dynamic objects,
//   used for every leaf): each scene model with more than `modelLodMinTriangles` triangles gets
//   up to `modelLodLevels` coarser versions, simplified like merged clusters to eps = the
//   model's diagonal x 2^-(6 - k), k = 0, 1, ..., each measured like merged clusters but against
//   its drawn triangles only (a leaf draws nothing else: a part that vanished is lost whole, not
//   a segment of its thickness), then the model's box (lattices and thin parts that edge
//   collapses cannot remove). A version drops the versions before it that have no fewer
//   triangles and no smaller eps (the selection would never want them) and is kept when it has
//   at most 3/4 of the triangles of the version now before it (the box: fewer), so along the
//   list the eps rise and the triangle counts fall. Shared by every instance (static,
//   pseudo-dynamic, dynamic). A
//   leaf drawn at distance d may use the coarsest version whose eps < r d (hdlod_select.h).
// - Layout: after the build, clusters are renumbered depth-first (pre-order from the root), so
//   a traversal reads the cluster, step and matrix arrays front to back.
//
// Clustering (appendix 2), once for the static and once for the pseudo-dynamic objects:
// active = one cluster per object with at least one triangle (objects without triangles get no cluster: there is nothing to draw). For level
// l = 1, 2, ...: thresholds w(l) = W * 2^(l - L), eps(l) = w(l) * epsPerSize,
// gamma(l) = 2^(l - L) (W = the diagonal of the tree's objects' box, L = levels, 1 + log2(W / (2 x the median
// object diagonal)) by default), frozen at l = L; the active clusters are visited in Hilbert-curve
// order of their box centres; each unvisited representative gathers, nearest first, up to
// maxChildren - 1 unvisited neighbours from a uniform grid of cell w(l) over the centres, taking
// one if the union box stays within diagonal w(l) and the mean |f_rep - f_neighbour| <= gamma(l);
// a representative with no neighbour moves on to the next level unchanged. It ends with one
// root (after level L everything qualifies, so every level merges). Cost: O(n log n) per level
// (sorting), a bounded number of candidates per representative.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <functional>
#include <new>
#include <span>
#include <string>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "lod/hdlod_scene.h"
#include "lod/hdlod_simplify.h"
#include "lod/view.h"

namespace ig::lod::hdlod {

struct BuildConfig {
  int levels = 0;                     // L; 0 = from the scene (see above)
  int maxChildren = 8;                // children per merged cluster (2 ... 65535)
  double epsPerSize = 1.0 / 16.0;     // eps(l) / w(l): the simplification error target against the cluster size
  Simplifier simplifier = Simplifier::Meshoptimizer;  // parent geometry (lod/hdlod_simplify.h)
  uint32_t sloppyAboveTriangles = 64; // meshoptimizer: try the sloppy simplifier above this many triangles
  int maxHausdorffSamples = 4096;     // per merged cluster
  bool strictHausdorff = false;       // measure to the kept triangles only (see eps_c above)
  bool twoSidedHausdorff = true;      // also from the simplified triangles back to the input (the paper's D_H)
  int dynamicGroupSize = 16;          // leaves per dynamic group (2 ... 65535)
  int candidatesPerCell = 64;         // neighbour candidates examined per grid cell (bounds the work)
  int modelLodLevels = 6;             // simplified versions per scene model (then its box)
  uint32_t modelLodMinTriangles = 16; // models with at most this many triangles get none
  // Called now and then during the build with the fraction done (0..1) and the stage ("static",
  // "pseudo-dynamic", "dynamic", "model versions", "done"); may be empty. Not part of the
  // cache key.
  std::function<void(double fraction, const char* stage)> progress;
};

enum class ClusterKind : uint8_t {
  Object,   // a static or pseudo-dynamic object (leaf)
  Merged,   // simplified union of its children
  Dynamic,  // a moving object (leaf)
  Group,    // dynamic group or virtual root: never drawn
};

struct Cluster {
  Aabb box;                 // b_c, world; for a dynamic leaf: its swept box
  double size_m = 0.0;      // w_c: diagonal of b_c
  double eps_m = 0.0;       // eps_c
  double gamma = 0.0;       // gamma_c (temporal error, 0..1)
  uint32_t firstChild = 0;  // into HdlodTree::children
  uint32_t childCount = 0;
  uint32_t stepBegin = 0;   // f_c: into HdlodTree::stepTimes / stepValues
  uint32_t stepCount = 0;
  uint32_t object = ~0u;    // leaves: the scene object
  uint32_t mesh = ~0u;      // Object / Dynamic: the scene model; Merged: into HdlodTree::meshes
  uint32_t triangles = 0;   // of g_c
  uint16_t level = 0;       // 0 for leaves
  ClusterKind kind = ClusterKind::Object;
};

// Geometry of a merged cluster: world position = origin_m + position.
struct ClusterMesh {
  glm::dvec3 origin_m{0.0};
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  // Per triangle: the scene model it stands for (its material, for the renderer; merged
  // clusters are simplified per material, so it is that of the triangles it replaces; models
  // past 65535 share the last index).
  std::vector<uint16_t> materials;
};

// A coarser version of a scene model, in model space.
struct ModelLod {
  uint32_t mesh = 0;       // into HdlodTree::meshes (origin_m = 0)
  uint32_t triangles = 0;
  double eps_m = 0.0;      // measured: sampled one-sided Hausdorff distance from the model to it
};

struct BuildStats {
  uint32_t staticObjects = 0, pseudoDynamicObjects = 0, dynamicObjects = 0, emptyObjects = 0;
  uint32_t mergedClusters = 0, levels = 0;
  uint64_t leafTriangles = 0, mergedTriangles = 0;
  uint32_t modelLods = 0;  // coarser model versions made
  uint64_t hausdorffSamples = 0;
  // Over the merged clusters: D (the measured Hausdorff distance of the cluster's own
  // simplification, without the children's eps), its sum and largest value, and D / eps(l).
  uint32_t sloppyClusters = 0;  // meshoptimizer's sloppy fallback taken
  double simplifyErrorSum_m = 0.0, simplifyErrorMax_m = 0.0;
  double simplifyRelativeSum = 0.0, simplifyRelativeMax = 0.0;
};

// One cache line per cluster for the selection's traversal, derived from the tree by
// prepareSelection() (never stored in the cache). Cold caches are the selection's cost (after an
// llvmpipe frame the tree is out of the caches): the cluster record (two lines), its f_c steps
// (two) and the children indices were separate misses per visit; this record holds what a visit
// reads, siblings are adjacent (one record per entry of HdlodTree::children), a leaf's short
// step function is held inline, and a box decided within its float margin never touches the
// cluster record (see hdlod_select.cpp).
struct alignas(64) SelectRecord {
  float lo[3] = {0, 0, 0};   // b_c relative to HdlodTree::selectOrigin_m, widened outward (selectWiden*)
  float hi[3] = {0, 0, 0};
  union {
    struct {
      double eps_m, size_m;  // Merged, Group: eps_c and w_c
    } merged;
    double leafStepTimes[2];  // leaves with kInlineSteps: the times of f_c's 2nd and 3rd steps (+inf: none)
  } u = {{0.0, 0.0}};
  uint32_t first = 0;        // Merged / Group: its children's first entry in `children`; leaves: Cluster::mesh
  uint32_t stepBegin = 0;    // into HdlodTree::selectSteps
  uint32_t stepCount = 0;
  uint32_t childSteps = 0;   // the children's steps start here (adjacent: they are in record order)
  uint32_t triangles = 0;
  uint16_t count = 0;        // children
  ClusterKind kind = ClusterKind::Object;
  uint8_t flags = 0;            // kAlwaysPresent, kInlineSteps and the inline step values

  static constexpr uint8_t kAlwaysPresent = 1;  // f_c = 1 on all of [0, T]: the steps are not read
  static constexpr uint8_t kInlineSteps = 2;    // a leaf of at most 3 steps of 0 / 1: value k is bit 2 + k
};
static_assert(sizeof(SelectRecord) == 64);

// Memory for the arrays a selection walks: 64-byte aligned (a 128-byte matrix spans two lines,
// not three); 1 MiB and more also 2 MiB aligned and advised as transparent huge pages, so that
// with cold caches and TLBs (after a rendered llvmpipe frame) the traversal does not take a page
// walk for every record it visits. Freed with selectionFree().
void* selectionAllocate(size_t bytes);
void selectionFree(void* p);

template <class T>
struct CacheLineAllocator {
  using value_type = T;
  CacheLineAllocator() = default;
  template <class U>
  CacheLineAllocator(const CacheLineAllocator<U>&) {}
  T* allocate(size_t n) {
    if (n > SIZE_MAX / sizeof(T)) throw std::bad_array_new_length();
    return static_cast<T*>(selectionAllocate(n * sizeof(T)));
  }
  void deallocate(T* p, size_t) { selectionFree(p); }
  template <class U>
  bool operator==(const CacheLineAllocator<U>&) const { return true; }
};

struct HdlodTree {
  double duration_s = 1.0;
  uint32_t root = ~0u;
  std::vector<Cluster> clusters;
  std::vector<uint32_t> children;
  std::vector<double> stepTimes;     // per cluster, increasing, the first = 0
  std::vector<double> stepValues;    // f_c on [stepTimes[i], stepTimes[i + 1])
  std::vector<ClusterMesh> meshes;
  std::vector<glm::dmat4, CacheLineAllocator<glm::dmat4>> leafMatrix;  // per cluster: Object leaves' constant matrix, Merged: translate(origin)
  std::vector<uint32_t> objectCluster; // per scene object: its leaf cluster or ~0u (no triangles)
  // Per scene model m: its coarser versions are modelLods[modelLodBegin[m] .. modelLodBegin[m + 1]),
  // eps increasing (modelLodBegin has models + 1 entries).
  std::vector<uint32_t> modelLodBegin;
  std::vector<ModelLod> modelLods;
  BuildStats stats;

  // Derived by prepareSelection() (buildHdlod() and the cache loader call it): the traversal's
  // records, one per entry of `children` in the same order, then the root's; f_c as (time,
  // value) pairs in record order, for the records whose steps are not inline; the records'
  // boxes are relative to selectOrigin_m (the root box's centre) and each side is widened
  // outward by at least selectWidenMin_m and at most selectWidenMax_m.
  std::vector<SelectRecord, CacheLineAllocator<SelectRecord>> selectRecords;
  std::vector<glm::dvec2, CacheLineAllocator<glm::dvec2>> selectSteps;
  glm::dvec3 selectOrigin_m{0.0};
  double selectWidenMin_m = 0.0, selectWidenMax_m = 0.0;

  std::span<const uint32_t> childrenOf(const Cluster& c) const { return {children.data() + c.firstChild, c.childCount}; }
  std::span<const ModelLod> lodsOf(uint32_t model) const {
    if (modelLodBegin.empty() || model >= modelLodBegin.size() - 1) return {};  // also ~0u (no model)
    return {modelLods.data() + modelLodBegin[model], modelLodBegin[model + 1] - modelLodBegin[model]};
  }
};

// Derives the selection records above from the clusters. False (records cleared) when the
// clusters do not form a tree under `root` (a cluster with two parents, the root as a child, a
// reference out of range): then selectHdlod() selects nothing.
bool prepareSelection(HdlodTree& tree);

// f_c(t), t clamped to [0, T] (NaN -> 0).
double clusterPresence(const HdlodTree& tree, const Cluster& c, double t_s);
// delta_c(t) (see above).
double clusterDelta(const HdlodTree& tree, const Cluster& c, double t_s);
// Mean of |f(t) - g(t)| over [0, T] for two step functions (times start at 0, increasing).
double stepDistance(std::span<const double> timesA, std::span<const double> valuesA, std::span<const double> timesB,
                    std::span<const double> valuesB, double duration_s);

// Builds the tree. The scene must pass validateScene() (asserted). Deterministic: the same scene
// and config give the same tree.
HdlodTree buildHdlod(const Scene& scene, const BuildConfig& config = {});

// Sampled one-sided Hausdorff distance from the samples to the triangles (positions in one
// frame): the largest distance from a sample to its nearest triangle. Exposed for tests;
// +infinity when there is no triangle and at least one sample.
double sampledHausdorff(std::span<const glm::vec3> samples, std::span<const glm::vec3> positions,
                        std::span<const uint32_t> indices);

}  // namespace ig::lod::hdlod
