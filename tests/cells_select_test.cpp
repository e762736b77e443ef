// lod/cells_select: the budgeted realization of hierarchical cells.
//  - optimality: on random trees of up to 4 levels and random views (partly outside the frustum,
//    camera inside, pre-selection on and off) the greedy's largest on-screen voxel equals the
//    brute-force minimum over every realization of the pre-selected tree within the voxel budget,
//    from scratch and incrementally along a camera path;
//  - validity: every root-to-leaf path crosses exactly one realization cell;
//  - budgets: drawn voxels <= voxel budget, requested bytes <= W, only resident cells drawn, only
//    absent cells requested, while streaming with residency, evictions and an operation cap;
//  - quality never gets worse while the viewer stands still and cells stream in, and reaches the
//    all-resident optimum;
//  - every cost the selector counted in a frame is that frame's cheapest cover, also after eviction
//    repairs in a frame whose view moved;
//  - pre-selection, empty cells, camera inside the root box, NaN view, huge coordinates, root not
//    yet resident, cells larger than W, no allocation in select().
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <new>
#include <random>
#include <string>
#include <vector>

#include "lod/cells.h"
#include "ig/cells_deadline.h"
#include "ig/clock.h"
#include "lod/cells_select.h"
#include "cells_random_tree.h"
#include "test_scale.h"

// Counts heap allocations while armed (no allocation in select()).
#include "alloc_counter.h"

using namespace ig::lod;
using namespace ig::lod::testing_trees;

namespace {

CellView randomView(std::mt19937& rng, const CellTree& t) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  CellView v;
  const double e = t.info().rootEdge_m;
  const double spread = u(rng) < 0.3 ? 0.5 : 2.0;  // sometimes inside or next to the root box
  v.camera.eye_m = t.info().rootMin_m + e * glm::dvec3(0.5 + spread * (u(rng) - 0.5), 0.5 + spread * (u(rng) - 0.5),
                                                       0.5 + spread * (u(rng) - 0.5));
  v.camera.heading_deg = 360.0 * u(rng);
  v.camera.pitch_deg = -80.0 + 160.0 * u(rng);
  v.camera.roll_deg = -30.0 + 60.0 * u(rng);
  v.camera.fovY_deg = 20.0 + 70.0 * u(rng);
  v.camera.aspect = 0.8 + u(rng);
  v.camera.near_m = 0.01 * e;
  v.camera.far_m = u(rng) < 0.2 ? 1.5 * e : 100.0 * e;
  v.viewportHeight_px = 30.0 + 1500.0 * u(rng);
  const double alphas[] = {0.0, 0.5, 1.0, 4.0, 20.0};
  v.minVoxel_px = alphas[rng() % 5];
  uint64_t total = 0;
  for (uint32_t c = 0; c < t.size(); ++c)
    if (t.childCount(c) == 0) total += t.voxels(c);
  // Mostly between the root alone and every leaf, sometimes below the root (infeasible unless a
  // cover of partly visible cells is cheaper).
  const double root = t.voxels(0);
  v.voxelBudget = static_cast<uint64_t>(u(rng) < 0.1 ? u(rng) * root : root + u(rng) * 1.1 * (static_cast<double>(total) - root));
  v.byteBudget = 1u << 30;
  return v;
}

// Brute force: every realization of the pre-selected subtree of c as (largest e, cost).
struct Cut {
  float maxE;
  uint64_t cost;
};
std::vector<Cut> allCuts(const CellTree& t, const CellView& v, uint32_t c) {
  const CellEval ev = evaluateCell(t, c, v);
  std::vector<Cut> out = {{ev.live ? ev.voxel_px : 0.0f, ev.live ? t.voxels(c) : 0}};
  if (!ev.live || t.childCount(c) == 0 || !(ev.voxel_px > static_cast<float>(v.minVoxel_px))) return out;
  std::vector<Cut> combos = {{0.0f, 0}};
  for (uint32_t i = 0; i < t.childCount(c); ++i) {
    const std::vector<Cut> sub = allCuts(t, v, t.firstChild(c) + i);
    std::vector<Cut> next;
    next.reserve(combos.size() * sub.size());
    for (const Cut& a : combos)
      for (const Cut& b : sub) next.push_back({std::max(a.maxE, b.maxE), a.cost + b.cost});
    combos.swap(next);
  }
  out.insert(out.end(), combos.begin(), combos.end());
  return out;
}

size_t countCuts(const CellTree& t, uint32_t c) {  // upper bound without pre-selection
  if (t.childCount(c) == 0) return 1;
  double prod = 1.0;
  for (uint32_t i = 0; i < t.childCount(c); ++i) prod *= static_cast<double>(countCuts(t, t.firstChild(c) + i));
  return static_cast<size_t>(std::min(prod + 1.0, 1e12));
}

// Every root-to-leaf path crosses exactly one realization cell.
void expectValidRealization(const CellTree& t, const CellSelector& sel) {
  std::vector<uint32_t> cut(t.size() + 1);
  const size_t n = sel.realization(cut);
  ASSERT_LE(n, t.size());
  std::vector<int> in(t.size(), 0);
  for (size_t i = 0; i < n; ++i) {
    ASSERT_LT(cut[i], t.size());
    ++in[cut[i]];
  }
  for (uint32_t c = 0; c < t.size(); ++c) {
    ASSERT_LE(in[c], 1) << "cell " << c << " twice";
    if (t.childCount(c) != 0) continue;
    int crossings = 0;
    for (uint32_t a = c; a != kNoCell; a = t.parent(a)) crossings += in[a];
    ASSERT_EQ(crossings, 1) << "path to leaf " << c;
  }
}

struct Frame {
  std::vector<CellDraw> draw;
  std::vector<uint32_t> requests;
  CellSelectStats stats;
};
Frame runSelect(CellSelector& sel, const CellTree& t, const CellView& v, std::span<const Residency> res = {}) {
  Frame f;
  f.draw.resize(t.size());
  f.requests.resize(t.size());
  f.stats = sel.select(v, res, f.draw, f.requests);
  f.draw.resize(f.stats.drawnCells);
  f.requests.resize(f.stats.requestedCells);
  return f;
}

std::vector<uint32_t> sortedCells(std::span<const CellDraw> draws) {
  std::vector<uint32_t> cells;
  for (const CellDraw& d : draws) cells.push_back(d.cell);
  std::sort(cells.begin(), cells.end());
  return cells;
}

// One frame of the incremental selector `sel` against a fresh selector for the same view: the
// same feasibility, largest voxel, voxel count and set of drawn cells, and a valid realization.
// `f` is the incremental frame.
void expectSameAsFresh(const CellTree& t, CellSelector& sel, const CellView& v, const std::string& what, Frame& f) {
  f = runSelect(sel, t, v);
  CellSelector fresh(t);
  const Frame g = runSelect(fresh, t, v);
  ASSERT_TRUE(f.stats.valid && g.stats.valid) << what;
  ASSERT_EQ(f.stats.feasible, g.stats.feasible) << what;
  EXPECT_EQ(f.stats.maxVoxel_px, g.stats.maxVoxel_px) << what;
  EXPECT_EQ(f.stats.drawnVoxels, g.stats.drawnVoxels) << what;
  ASSERT_EQ(sortedCells(f.draw), sortedCells(g.draw)) << what;
  expectValidRealization(t, sel);
  EXPECT_EQ(f.stats.cutCells, g.stats.cutCells) << what;
}

void expectOptimal(const CellTree& t, const CellView& v, const CellSelectStats& s, const std::string& what) {
  const std::vector<Cut> cuts = allCuts(t, v, 0);
  bool feasible = false;
  float best = std::numeric_limits<float>::infinity();
  for (const Cut& c : cuts)
    if (c.cost <= v.voxelBudget) {
      feasible = true;
      best = std::min(best, c.maxE);
    }
  ASSERT_TRUE(s.valid) << what;
  ASSERT_EQ(s.feasible, feasible) << what;
  if (feasible) {
    EXPECT_EQ(s.maxVoxel_px, best) << what << " (" << cuts.size() << " realizations)";
  }
  EXPECT_LE(s.drawnVoxels, v.voxelBudget) << what;
}

TEST(CellSelect, GreedyEqualsBruteForceOnRandomTrees) {
  std::mt19937 rng(2024);
  int compared = 0, bigCases = 0, refinedCases = 0, refinedPastMax = 0;
  for (int trial = 0; trial < 1000; ++trial) {
    TreeSpec spec;
    spec.levels = 2 + trial % 3;  // 2..4 levels
    spec.maxChildren = spec.levels == 4 ? 4 : 8;
    spec.leafEarly = 0.03;
    spec.minChildren = 2;
    const CellTree t = randomTree(rng, spec);
    ASSERT_LE(countCuts(t, 0), 2000000u);
    for (int k = 0; k < 4; ++k) {
      CellView v = randomView(rng, t);
      if (k == 0) v.minVoxel_px = 0.0;
      CellSelector fresh(t);
      const Frame f = runSelect(fresh, t, v);
      expectOptimal(t, v, f.stats, "trial " + std::to_string(trial) + " view " + std::to_string(k));
      if (allCuts(t, v, 0).size() > 100) ++bigCases;
      if (f.stats.splits >= 3) ++refinedCases;
      for (const CellDraw& d : f.draw)
        if (d.cell != 0 && evaluateCell(t, t.parent(d.cell), v).voxel_px < f.stats.maxVoxel_px) {
          ++refinedPastMax;
          break;
        }
      expectValidRealization(t, fresh);
      uint64_t vox = 0;
      for (const CellDraw& d : f.draw) vox += t.voxels(d.cell);
      EXPECT_EQ(vox, f.stats.drawnVoxels);
      ++compared;
    }
  }
  EXPECT_EQ(compared, 4000);
  // The cases are not trivial: many realizations, partly visible cells, binding budgets.
  EXPECT_GT(bigCases, 100);      // > 100 realizations after pre-selection and culling
  EXPECT_GT(refinedCases, 750);  // at least 3 splits
  // Cells drawn below a parent whose voxel is already smaller than the realization's largest:
  // cheaper covers of cells cut by the frustum, or budget left once the largest voxel is a leaf.
  EXPECT_GT(refinedPastMax, 250);
}

TEST(CellSelect, IncrementalEqualsBruteForceAlongAPath) {
  std::mt19937 rng(77);
  for (int trial = 0; trial < 60; ++trial) {
    TreeSpec spec;
    spec.levels = 4;
    spec.maxChildren = 4;
    const CellTree t = randomTree(rng, spec);
    CellSelector sel(t);
    CellView v = randomView(rng, t);
    for (int frame = 0; frame < 25; ++frame) {
      // Mostly small moves, sometimes a jump, budget and pre-selection changes.
      if (frame % 8 == 7) {
        v = randomView(rng, t);
      } else {
        v.camera.eye_m += glm::dvec3(0.3, -0.2, 0.1) * (static_cast<double>(rng() % 5) - 2.0);
        v.camera.heading_deg += 7.0;
        v.voxelBudget = v.voxelBudget * (90 + rng() % 21) / 100;
      }
      const Frame f = runSelect(sel, t, v);
      const std::string what = "trial " + std::to_string(trial) + " frame " + std::to_string(frame);
      expectOptimal(t, v, f.stats, what);
      expectValidRealization(t, sel);
      CellSelector fresh(t);
      EXPECT_EQ(runSelect(fresh, t, v).stats.maxVoxel_px, f.stats.maxVoxel_px) << what;
    }
  }
}

// The selection does not depend on history: along camera paths over deeper random trees (small
// moves, turns, budget and pre-selection changes, jumps), the incremental selector (which keeps
// its cut, its certificates and its queue windows from frame to frame) draws exactly the cells a
// fresh selector draws from the root, with the same largest on-screen voxel.
TEST(CellSelect, IncrementalDrawsTheSameCellsAsFromScratch) {
  std::mt19937 rng(99);
  int frames = 0, differentCuts = 0, invisible = 0;
  for (int trial = 0; trial < 24; ++trial) {
    TreeSpec spec;
    spec.levels = 6 + trial % 2;
    spec.minChildren = 2;
    spec.maxChildren = 5;
    spec.leafEarly = 0.05;
    spec.rootEdge_m = 64.0;
    const CellTree t = randomTree(rng, spec);
    CellSelector sel(t);
    CellView v = randomView(rng, t);
    v.camera.far_m = 1000.0;
    v.camera.eye_m = {32.0, -20.0, 30.0};
    v.camera.heading_deg = 10.0;
    v.camera.pitch_deg = -20.0;
    v.minVoxel_px = trial % 3 == 0 ? 0.0 : 1.0;
    uint64_t total = 0;
    for (uint32_t c = 0; c < t.size(); ++c)
      if (t.childCount(c) == 0) total += t.voxels(c);
    v.voxelBudget = total / 4 + 10;
    std::vector<uint32_t> last;
    for (int frame = 0; frame < 40; ++frame) {
      if (frame % 13 == 12) {
        std::uniform_real_distribution<double> u(0.0, 1.0);
        v.camera.eye_m = {64.0 * u(rng), -10.0 - 30.0 * u(rng), 10.0 + 50.0 * u(rng)};  // a jump
      } else {
        v.camera.eye_m += glm::dvec3(0.4, 0.9, -0.2);
        v.camera.heading_deg += 1.5 * std::sin(frame * 0.3);
        v.camera.pitch_deg += 0.3;
      }
      if (frame % 7 == 3) v.voxelBudget = v.voxelBudget * (70 + rng() % 61) / 100;
      if (frame % 11 == 5) v.minVoxel_px = v.minVoxel_px > 0.0 ? 0.0 : 2.0;
      const std::string what = "trial " + std::to_string(trial) + " frame " + std::to_string(frame);
      Frame f;
      expectSameAsFresh(t, sel, v, what, f);
      for (size_t i = 0; i < f.draw.size(); ++i)
        EXPECT_EQ(f.draw[i].voxel_px, evaluateCell(t, f.draw[i].cell, v).voxel_px) << what;
      const std::vector<uint32_t> a = sortedCells(f.draw);
      if (a != last) ++differentCuts;
      last = a;
      if (f.stats.cutCells > f.stats.drawnCells) ++invisible;
      ++frames;
    }
  }
  EXPECT_EQ(frames, 24 * 40);
  EXPECT_GT(differentCuts, 24 * 40 / 2);  // the cut changes along the path
  EXPECT_GT(invisible, 24 * 40 / 2);      // cells outside the frustum are part of the realization
}

// The same over deep, thin trees (16 levels: 16-bit cell coordinates) with an edge that is not a
// power of two, far from the origin: certificates locate children by comparing the corners the
// selector keeps in float, which must hold down to the finest level.
TEST(CellSelect, IncrementalEqualsFromScratchOnDeepTrees) {
  std::mt19937 rng(7);
  int frames = 0, deep = 0;
  for (int trial = 0; trial < 4; ++trial) {
    TreeSpec spec;
    spec.levels = kMaxCellLevels;
    spec.minChildren = 1;
    spec.maxChildren = 2;
    spec.leafEarly = 0.02;
    spec.empty = 0.1;
    spec.rootEdge_m = 100.3 + trial;
    spec.rootMin_m = {-3.0e4, 5.0e3 + trial, 17.25};
    const CellTree t = randomTree(rng, spec);
    CellSelector sel(t);
    CellView v;
    v.camera.far_m = 1000.0;
    v.camera.near_m = 0.01;
    v.camera.fovY_deg = 50.0;
    v.minVoxel_px = 0.5;
    uint64_t total = 0;
    for (uint32_t c = 0; c < t.size(); ++c)
      if (t.childCount(c) == 0) total += t.voxels(c);
    v.voxelBudget = total / 3 + 10;
    // Start at a leaf's corner (deep cells around the eye), then drift and turn.
    uint32_t c = 0;
    while (t.childCount(c) > 0) c = t.firstChild(c);
    v.camera.eye_m = t.info().rootMin_m + glm::dvec3(t.coord(c)) * t.cellEdge_m(t.level(c)) + glm::dvec3(1e-3);
    for (int frame = 0; frame < 30; ++frame) {
      v.camera.eye_m += glm::dvec3(0.002, 0.001, -0.0005) * static_cast<double>(frame);
      v.camera.heading_deg = 9.0 * frame;
      v.camera.pitch_deg = -30.0 + 2.0 * frame;
      const std::string what = "trial " + std::to_string(trial) + " frame " + std::to_string(frame);
      Frame f;
      expectSameAsFresh(t, sel, v, what, f);
      int deepest = 0;
      for (const CellDraw& d : f.draw) deepest = std::max(deepest, t.level(d.cell));
      if (deepest >= 12) ++deep;
      ++frames;
    }
  }
  EXPECT_EQ(frames, 4 * 30);
  EXPECT_GT(deep, 4 * 30 / 4);  // the selection reaches the deep levels
}

TEST(CellSelect, PreSelectionDropsCellsFinerThanThePixel) {
  std::mt19937 rng(5);
  TreeSpec spec;
  spec.levels = 7;
  spec.maxChildren = 3;
  spec.leafEarly = 0.0;
  spec.empty = 0.0;
  const CellTree t = randomTree(rng, spec);
  CellView v;
  v.camera.eye_m = {4.0, -30.0, 4.0};  // looking north at the root box from 30 m
  v.camera.fovY_deg = 60.0;
  v.viewportHeight_px = 400.0;
  v.voxelBudget = std::numeric_limits<uint64_t>::max();
  v.minVoxel_px = 1.0;
  CellSelector sel(t);
  const Frame f = runSelect(sel, t, v);
  ASSERT_GT(f.draw.size(), 1u);
  for (const CellDraw& d : f.draw) {
    // Never finer than needed: the parent's voxels were still larger than a pixel ...
    EXPECT_GT(evaluateCell(t, t.parent(d.cell), v).voxel_px, 1.0f) << d.cell;
    // ... and refined as far as useful: sub-pixel or a leaf.
    EXPECT_TRUE(d.voxel_px <= 1.0f || t.childCount(d.cell) == 0) << d.cell;
  }
  // Without pre-selection the unlimited budget draws the leaves.
  v.minVoxel_px = 0.0;
  CellSelector all(t);
  const Frame g = runSelect(all, t, v);
  for (const CellDraw& d : g.draw) EXPECT_EQ(t.childCount(d.cell), 0u);
  EXPECT_GT(g.stats.drawnVoxels, f.stats.drawnVoxels);
  // Moving away merges what became sub-pixel.
  v.minVoxel_px = 1.0;
  v.camera.eye_m.y = -300.0;
  const Frame far = runSelect(sel, t, v);
  EXPECT_LT(far.stats.drawnVoxels, f.stats.drawnVoxels);
  EXPECT_GT(far.stats.merges + 0u, 0u);
  for (const CellDraw& d : far.draw) EXPECT_GT(evaluateCell(t, t.parent(d.cell), v).voxel_px, 1.0f);
  expectValidRealization(t, sel);
}

TEST(CellSelect, InvisibleCellsStayAtMinimumQuality) {
  std::mt19937 rng(9);
  TreeSpec spec;
  spec.levels = 5;
  spec.maxChildren = 8;
  spec.leafEarly = 0.0;
  spec.empty = 0.0;
  const CellTree t = randomTree(rng, spec);
  CellView v;
  v.camera.eye_m = {4.0, -10.0, 4.0};
  v.camera.heading_deg = 180.0;  // looking away from the box
  v.minVoxel_px = 0.0;
  v.voxelBudget = std::numeric_limits<uint64_t>::max();
  CellSelector sel(t);
  Frame f = runSelect(sel, t, v);
  EXPECT_EQ(f.draw.size(), 0u);
  EXPECT_EQ(f.stats.drawnVoxels, 0u);
  EXPECT_EQ(f.stats.splits, 0u);
  expectValidRealization(t, sel);
  // Turn towards it: refined to leaves. Turn away again: merged back to the root.
  v.camera.heading_deg = 0.0;
  f = runSelect(sel, t, v);
  EXPECT_GT(f.stats.splits, 0u);
  v.camera.heading_deg = 180.0;
  f = runSelect(sel, t, v);
  std::vector<uint32_t> cut(t.size());
  EXPECT_EQ(sel.realization(cut), 1u);
  EXPECT_EQ(cut[0], 0u);
}

TEST(CellSelect, EmptyCellsAreNeverDrawnOrRefined) {
  // Root with an empty half: octants 0..3 hold voxels, 4..7 are empty subtrees.
  std::vector<CellDesc> cells = {{kNoCell, 0, 40, 100}};
  for (uint8_t o = 0; o < 8; ++o) cells.push_back({0, o, o < 4 ? 10u : 0u, 16});
  for (uint32_t p = 1; p <= 8; ++p)
    for (uint8_t o = 0; o < 8; ++o) cells.push_back({p, o, p <= 4 ? 3u : 0u, 16});
  CellTree t;
  std::string err;
  CellTreeInfo info;
  info.rootEdge_m = 8.0;
  ASSERT_TRUE(t.build(info, cells, err)) << err;
  CellView v;
  v.camera.eye_m = {4.0, 4.0, 6.0};  // inside the empty upper half, looking down
  v.camera.pitch_deg = -89.0;
  v.minVoxel_px = 0.0;
  v.voxelBudget = 1000;
  CellSelector sel(t);
  const Frame f = runSelect(sel, t, v);
  ASSERT_TRUE(f.stats.feasible);
  for (const CellDraw& d : f.draw) EXPECT_FALSE(t.isEmpty(d.cell));
  EXPECT_GT(f.draw.size(), 0u);
  expectValidRealization(t, sel);
  expectOptimal(t, v, f.stats, "empty half");
  // An all-empty tree draws nothing and stays at the root.
  std::vector<CellDesc> none = {{kNoCell, 0, 0, 16}, {0, 0, 0, 16}, {0, 5, 0, 16}};
  CellTree e;
  ASSERT_TRUE(e.build(info, none, err)) << err;
  CellSelector se(e);
  const Frame g = runSelect(se, e, v);
  EXPECT_TRUE(g.stats.valid);
  EXPECT_EQ(g.draw.size(), 0u);
  EXPECT_EQ(g.stats.splits, 0u);
}

TEST(CellSelect, CameraInsideTheRootBoxRefinesAroundTheEye) {
  std::mt19937 rng(13);
  TreeSpec spec;
  spec.levels = 5;
  spec.maxChildren = 8;
  spec.leafEarly = 0.0;
  spec.empty = 0.0;
  const CellTree t = randomTree(rng, spec);
  // The eye at the centre of some finest cell, looking along +y.
  const uint32_t leaf = t.levelBegin(4) + (t.levelBegin(5) - t.levelBegin(4)) / 2;
  const Aabb b = t.box(leaf);
  CellView v;
  v.camera.eye_m = 0.5 * (b.min + b.max);
  v.minVoxel_px = 1.0;
  v.voxelBudget = 400;
  CellSelector sel(t);
  const Frame f = runSelect(sel, t, v);
  ASSERT_TRUE(f.stats.feasible);
  EXPECT_TRUE(std::any_of(f.draw.begin(), f.draw.end(), [&](const CellDraw& d) { return d.cell == leaf; }))
      << "the cell around the eye is drawn at the finest level";
  expectValidRealization(t, sel);
  EXPECT_LE(f.stats.drawnVoxels, 400u);
}

TEST(CellSelect, NanAndBadViewsChangeNothing) {
  std::mt19937 rng(21);
  TreeSpec spec;
  spec.levels = 4;
  const CellTree t = randomTree(rng, spec);
  CellView v = randomView(rng, t);
  v.voxelBudget = 1000;
  v.camera.eye_m = {4.0, -6.0, 4.0};
  v.camera.heading_deg = 0.0;
  v.camera.pitch_deg = 0.0;
  v.camera.far_m = 1000.0;
  CellSelector sel(t);
  const Frame a = runSelect(sel, t, v);
  CellView offAxis = v;  // an off-axis window (a display channel's) is a valid view
  offAxis.camera.shiftX = 0.4;
  EXPECT_TRUE(validCellView(offAxis));
  for (int bad = 0; bad < 8; ++bad) {
    CellView b = v;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    switch (bad) {
      case 0: b.camera.eye_m.x = nan; break;
      case 1: b.camera.heading_deg = nan; break;
      case 2: b.camera.fovY_deg = 0.0; break;
      case 3: b.camera.near_m = 0.0; break;
      case 4: b.camera.far_m = b.camera.near_m; break;
      case 5: b.viewportHeight_px = nan; break;
      case 6: b.minVoxel_px = -1.0; break;
      case 7: b.camera.shiftY = nan; break;
    }
    const Frame f = runSelect(sel, t, b);
    EXPECT_FALSE(f.stats.valid) << bad;
    EXPECT_EQ(f.draw.size(), 0u) << bad;
  }
  // Residency of the wrong size is refused too.
  std::vector<Residency> shortRes(t.size() - 1, Residency::Resident);
  EXPECT_FALSE(runSelect(sel, t, v, shortRes).stats.valid);
  const Frame again = runSelect(sel, t, v);
  ASSERT_EQ(again.draw.size(), a.draw.size());
  for (size_t i = 0; i < a.draw.size(); ++i) EXPECT_EQ(again.draw[i].cell, a.draw[i].cell);
  EXPECT_EQ(again.stats.splits + again.stats.merges, 0u);
}

TEST(CellSelect, HugeCoordinatesSelectTheSameCells) {
  std::mt19937 rngA(31), rngB(31);
  TreeSpec spec;
  spec.levels = 5;
  spec.maxChildren = 5;
  const CellTree a = randomTree(rngA, spec);
  spec.rootMin_m = {6.4e6, -3.3e6, 1.0e7};
  const CellTree b = randomTree(rngB, spec);
  std::mt19937 rv(4);
  for (int k = 0; k < 20; ++k) {
    CellView va = randomView(rv, a);
    CellView vb = va;
    vb.camera.eye_m += spec.rootMin_m;
    CellSelector sa(a), sb(b);
    const Frame fa = runSelect(sa, a, va), fb = runSelect(sb, b, vb);
    ASSERT_EQ(fa.draw.size(), fb.draw.size()) << k;
    for (size_t i = 0; i < fa.draw.size(); ++i) {
      EXPECT_EQ(fa.draw[i].cell, fb.draw[i].cell);
      EXPECT_NEAR(fa.draw[i].voxel_px, fb.draw[i].voxel_px, 1e-4f * fa.draw[i].voxel_px);
    }
    expectOptimal(b, vb, fb.stats, "huge " + std::to_string(k));
  }
}

// Streams cells into a residency table: requested cells arrive `latency` frames later.
struct Streamer {
  std::vector<Residency> res;
  std::vector<int> arrival;
  int latency = 1;
  explicit Streamer(size_t n) : res(n, Residency::Absent), arrival(n, -1) {}
  void request(std::span<const uint32_t> cells, int frame) {
    for (uint32_t c : cells) {
      EXPECT_EQ(res[c], Residency::Absent) << "cell " << c << " requested twice";
      res[c] = Residency::InFlight;
      arrival[c] = frame + latency;
    }
  }
  size_t inFlight() const { return static_cast<size_t>(std::count(res.begin(), res.end(), Residency::InFlight)); }
  void deliver(int frame) {
    for (size_t c = 0; c < res.size(); ++c)
      if (res[c] == Residency::InFlight && arrival[c] <= frame) res[c] = Residency::Resident;
  }
};

void expectFrameWithinBudgets(const CellTree& t, const CellView& v, const Frame& f, const Streamer& s) {
  EXPECT_TRUE(f.stats.valid);
  EXPECT_LE(f.stats.drawnVoxels, v.voxelBudget);
  EXPECT_LE(f.stats.drawnVoxels + f.stats.reservedVoxels, v.voxelBudget);
  EXPECT_LE(f.stats.requestedBytes, v.byteBudget);
  uint64_t bytes = 0;
  for (uint32_t c : f.requests) {
    bytes += t.bytes(c);
    EXPECT_EQ(s.res[c], Residency::Absent) << "requested a cell that is resident or in flight";
  }
  EXPECT_EQ(bytes, f.stats.requestedBytes);
  for (const CellDraw& d : f.draw) EXPECT_EQ(s.res[d.cell], Residency::Resident) << "drew a missing cell";
}

TEST(CellSelect, StreamingKeepsBudgetsAndQualityNeverDropsWhileStill) {
  std::mt19937 rng(41);
  int settled = 0;
  for (int trial = 0; trial < 12; ++trial) {
    TreeSpec spec;
    spec.levels = 6;
    spec.maxChildren = 6;
    spec.leafEarly = 0.05;
    const CellTree t = randomTree(rng, spec);
    CellView v = randomView(rng, t);
    v.camera.eye_m = {4.0 + trial % 3, -5.0, 3.0};
    v.camera.heading_deg = 0.0;
    v.camera.pitch_deg = 10.0;
    v.camera.far_m = 1000.0;
    v.minVoxel_px = 0.5;
    v.voxelBudget = t.voxels(0) * static_cast<uint64_t>(trial) / 2 + 50;  // trial 0: the root does not fit
    uint32_t largest = 0;
    for (uint32_t c = 0; c < t.size(); ++c) largest = std::max(largest, t.bytes(c));
    v.byteBudget = largest + 100 * static_cast<uint64_t>(trial % 4);
    Streamer s(t.size());
    s.latency = 1 + trial % 3;
    CellSelector sel(t);
    float last = std::numeric_limits<float>::infinity();
    int frame = 0;
    for (; frame < 400; ++frame) {
      s.deliver(frame);
      const Frame f = runSelect(sel, t, v, s.res);
      expectFrameWithinBudgets(t, v, f, s);
      if (!f.draw.empty()) {
        EXPECT_LE(f.stats.maxVoxel_px, last) << "trial " << trial << " frame " << frame;
        last = f.stats.maxVoxel_px;
      }
      expectValidRealization(t, sel);
      s.request(f.requests, frame);
      if (f.requests.empty() && f.stats.blockedSplits == 0 && s.inFlight() == 0) break;
    }
    ASSERT_LT(frame, 400) << "streaming did not settle";
    // Settled: the same quality as with everything resident.
    CellSelector all(t);
    const Frame a = runSelect(all, t, v);
    if (std::isinf(last)) {
      EXPECT_FALSE(a.stats.feasible) << "trial " << trial;
    } else {
      EXPECT_EQ(a.stats.maxVoxel_px, last) << "trial " << trial;
      ++settled;
    }
  }
  EXPECT_GE(settled, 10);
}

TEST(CellSelect, StreamingAlongAPathWithEvictionsAndAnOperationCap) {
  std::mt19937 rng(43);
  TreeSpec spec;
  spec.levels = 7;
  spec.maxChildren = 5;
  spec.leafEarly = 0.05;
  spec.rootEdge_m = 64.0;
  const CellTree t = randomTree(rng, spec);
  for (uint32_t cap : {1u << 30, 3u}) {
    CellSelectorConfig cfg;
    cfg.maxOperations = cap;
    CellSelector sel(t, cfg);
    Streamer s(t.size());
    CellView v;
    v.camera.far_m = 10000.0;
    v.voxelBudget = 3000;
    // A small channel, but never below the largest cell (a root larger than W was never fetched,
    // nothing was drawn, and every check below passed on empty frames; a child larger than W
    // blocks its parent's split for ever).
    uint32_t largest = 0;
    for (uint32_t c = 0; c < t.size(); ++c) largest = std::max(largest, t.bytes(c));
    v.byteBudget = std::max<uint32_t>(2000, largest);
    v.minVoxel_px = 1.0;
    int drawnFrames = 0, refinedFrames = 0;
    for (int frame = 0; frame < 300; ++frame) {
      const double a = frame * 0.02;
      v.camera.eye_m = frame == 150 ? glm::dvec3(60.0, 60.0, 70.0)  // teleport
                                    : glm::dvec3(32.0 + 50.0 * std::cos(a), 32.0 + 50.0 * std::sin(a), 40.0);
      v.camera.heading_deg = 270.0 - a * 57.29578;  // roughly towards the centre
      v.camera.pitch_deg = -20.0;
      s.deliver(frame);
      if (frame % 17 == 5) {
        // Evict a third of the resident cells (never the root).
        for (uint32_t c = 1; c < t.size(); c += 3)
          if (s.res[c] == Residency::Resident) s.res[c] = Residency::Absent;
      }
      const Frame f = runSelect(sel, t, v, s.res);
      expectFrameWithinBudgets(t, v, f, s);
      if (cap < 100) {
        // The cap holds back splits; merges that keep the voxel budget are never held back.
        EXPECT_LE(f.stats.splits, cap);
        if (f.stats.capped) {
          EXPECT_GE(f.stats.splits + f.stats.merges, cap);
        }
      }
      expectValidRealization(t, sel);
      s.request(f.requests, frame);
      drawnFrames += f.draw.empty() ? 0 : 1;
      refinedFrames += f.draw.size() > 1 ? 1 : 0;
    }
    EXPECT_GT(drawnFrames, 250) << "cap " << cap;
    EXPECT_GT(refinedFrames, 200) << "cap " << cap;
  }
}

TEST(CellSelect, RootNotResidentAndCellsLargerThanW) {
  std::mt19937 rng(51);
  TreeSpec spec;
  spec.levels = 4;
  spec.maxChildren = 8;
  spec.empty = 0.0;
  spec.leafEarly = 0.0;
  const CellTree t = randomTree(rng, spec);
  CellView v;
  v.camera.eye_m = {4.0, -8.0, 4.0};
  v.minVoxel_px = 0.0;
  v.voxelBudget = 1u << 20;
  v.byteBudget = t.bytes(0);
  Streamer s(t.size());
  CellSelector sel(t);
  Frame f = runSelect(sel, t, v, s.res);
  EXPECT_TRUE(f.stats.valid);
  EXPECT_EQ(f.draw.size(), 0u);
  ASSERT_EQ(f.requests.size(), 1u);
  EXPECT_EQ(f.requests[0], 0u);
  s.request(f.requests, 0);
  // In flight: not requested again, nothing drawn yet.
  f = runSelect(sel, t, v, s.res);
  EXPECT_EQ(f.requests.size(), 0u);
  EXPECT_EQ(f.draw.size(), 0u);
  s.deliver(1);
  f = runSelect(sel, t, v, s.res);
  ASSERT_EQ(f.draw.size(), 1u);
  EXPECT_EQ(f.draw[0].cell, 0u);
  // W smaller than every child: nothing can be requested, the root stays.
  v.byteBudget = 10;
  f = runSelect(sel, t, v, s.res);
  EXPECT_EQ(f.requests.size(), 0u);
  EXPECT_GT(f.stats.unfetchable, 0u);
  ASSERT_EQ(f.draw.size(), 1u);
  // A root larger than the voxel budget: infeasible, nothing drawn.
  v.byteBudget = 1u << 20;
  v.voxelBudget = t.voxels(0) - 1;
  f = runSelect(sel, t, v, s.res);
  EXPECT_FALSE(f.stats.feasible);
  EXPECT_EQ(f.draw.size(), 0u);
  EXPECT_EQ(f.stats.drawnVoxels, 0u);
}

// A ChunkRunner on one thread that keeps the contract (worker 0 takes chunks from the front in
// order, worker 1 from the back) but interleaves the two workers' calls in a chosen way, so that
// anything in the selection that depended on the order of calls, or on which worker ran a chunk,
// would show. mode 0: alternate; 1: worker 0 takes all; 2: worker 1 takes all; 3: random split,
// random interleaving.
class InterleavedRunner final : public ChunkRunner {
 public:
  explicit InterleavedRunner(int mode, uint32_t seed = 1) : mode_(mode), rng_(seed) {}
  void forEach(uint32_t chunks, ChunkFn fn, void* ctx) override {
    uint32_t front = 0, back = chunks;
    const uint32_t split = mode_ == 1 ? chunks : mode_ == 2 ? 0 : mode_ == 0 ? (chunks + 1) / 2 : static_cast<uint32_t>(rng_() % (chunks + 1));
    bool turn = false;
    while (front < split || back > split) {
      const bool one = mode_ == 3 ? (rng_() & 1) != 0 : turn;
      turn = !turn;
      if ((one && back > split) || front >= split) {
        fn(ctx, --back, 1);
        ++workerOne;
      } else {
        fn(ctx, front++, 0);
      }
    }
    ++passes;
  }
  uint64_t passes = 0, workerOne = 0;

 private:
  int mode_;
  std::mt19937 rng_;
};

TEST(CellSelect, SelectDoesNotAllocate) {
  // On one pass, and in chunks (an interleaving runner: worker 1's lists and marks too).
  for (const bool chunked : {false, true}) {
    std::mt19937 rng(61);
    TreeSpec spec;
    spec.levels = 7;
    spec.maxChildren = 6;
    spec.rootEdge_m = 64.0;
    const CellTree t = randomTree(rng, spec);
    InterleavedRunner runner(3, 9);
    CellSelectorConfig cfg;
    if (chunked) {
      cfg.runner = &runner;
      cfg.chunkCells = 8;
    }
    CellSelector sel(t, cfg);
    Streamer s(t.size());
    std::vector<CellDraw> draw(sel.drawBound());
    std::vector<uint32_t> req(t.size());
    CellView v;
    v.voxelBudget = 5000;
    v.byteBudget = 3000;
    long allocs = 0;
    for (int frame = 0; frame < 100; ++frame) {
      v.camera.eye_m = {32.0 + 40.0 * std::cos(frame * 0.05), -30.0 + frame * 0.5, 40.0};
      v.camera.pitch_deg = -25.0;
      s.deliver(frame);
      if (chunked && frame % 13 == 4) {  // evictions: the eviction lists of both workers
        for (uint32_t c = 1; c < t.size(); c += 4)
          if (s.res[c] == Residency::Resident) s.res[c] = Residency::Absent;
      }
      gAllocs = 0;
      gCountAllocs = true;
      const CellSelectStats st = sel.select(v, s.res, draw, req);
      gCountAllocs = false;
      allocs += gAllocs.load();
      EXPECT_TRUE(st.valid);
      s.request(std::span<const uint32_t>(req.data(), st.requestedCells), frame);
    }
    EXPECT_EQ(allocs, 0) << (chunked ? "chunked" : "one pass");
    if (chunked) {
      EXPECT_GT(runner.workerOne, 0u);
    }
  }
}

// Everything a frame produced, exactly: stats, the draw list in order (bits of voxel_px too) and
// the requests in order.
void expectSameFrame(const Frame& a, const Frame& b, const std::string& what) {
  ASSERT_EQ(a.stats.valid, b.stats.valid) << what;
  ASSERT_EQ(a.stats.feasible, b.stats.feasible) << what;
  EXPECT_EQ(a.stats.drawTruncated, b.stats.drawTruncated) << what;
  EXPECT_EQ(a.stats.capped, b.stats.capped) << what;
  EXPECT_EQ(a.stats.cutCells, b.stats.cutCells) << what;
  EXPECT_EQ(a.stats.drawnVoxels, b.stats.drawnVoxels) << what;
  EXPECT_EQ(a.stats.reservedVoxels, b.stats.reservedVoxels) << what;
  EXPECT_EQ(a.stats.maxVoxel_px, b.stats.maxVoxel_px) << what;
  EXPECT_EQ(a.stats.requestedBytes, b.stats.requestedBytes) << what;
  EXPECT_EQ(a.stats.blockedSplits, b.stats.blockedSplits) << what;
  EXPECT_EQ(a.stats.unfetchable, b.stats.unfetchable) << what;
  EXPECT_EQ(a.stats.splits, b.stats.splits) << what;
  EXPECT_EQ(a.stats.merges, b.stats.merges) << what;
  ASSERT_EQ(a.draw.size(), b.draw.size()) << what;
  for (size_t i = 0; i < a.draw.size(); ++i) {
    ASSERT_EQ(a.draw[i].cell, b.draw[i].cell) << what << " draw " << i;
    ASSERT_EQ(std::bit_cast<uint32_t>(a.draw[i].voxel_px), std::bit_cast<uint32_t>(b.draw[i].voxel_px)) << what;
  }
  ASSERT_EQ(a.requests, b.requests) << what;
}

// CellView::stop (igd's deadline for the cells phase): the refinement ends at the first poll
// that says so, the cut stays valid and within the budgets, a stop that never fires changes
// nothing, and once the stops end the next frame is the selection from scratch again.
struct StopAfter {
  int polls = 0;
  int stopAt = 1;  // the poll that first returns true (<= 0: never)
  static bool poll(void* self) {
    auto* s = static_cast<StopAfter*>(self);
    return ++s->polls >= s->stopAt && s->stopAt > 0;
  }
};

// A random 7-level tree (64 m root) and a view of it that needs many splits.
CellTree stopTree(uint32_t seed) {
  std::mt19937 rng(seed);
  TreeSpec spec;
  spec.levels = 7;
  spec.maxChildren = 6;
  spec.leafEarly = 0.05;
  spec.rootEdge_m = 64.0;
  return randomTree(rng, spec);
}
CellView stopView() {
  CellView v;
  v.camera.far_m = 10000.0;
  v.camera.eye_m = {20.0, -30.0, 40.0};
  v.camera.heading_deg = 20.0;
  v.camera.pitch_deg = -25.0;
  v.minVoxel_px = 0.5;
  v.voxelBudget = 20000;
  v.byteBudget = 1 << 30;
  return v;
}

TEST(CellSelect, AStopEndsTheRefinementThereAndTheNextFramesCatchUp) {
  const CellTree t = stopTree(61);
  CellView v = stopView();
  CellSelector plain(t);
  const Frame full = runSelect(plain, t, v);
  ASSERT_TRUE(full.stats.feasible);
  ASSERT_GT(full.stats.splits, 4 * kCellStopPoll) << "the view must need many splits";

  // Stopped at the first poll, five frames in a row: at most kCellStopPoll - 1 candidates each.
  CellSelector sel(t);
  StopAfter stop;
  v.stop = &StopAfter::poll;
  v.stopContext = &stop;
  float last = std::numeric_limits<float>::infinity();
  for (int frame = 0; frame < 5; ++frame) {
    stop = {};
    const Frame f = runSelect(sel, t, v);
    EXPECT_TRUE(f.stats.valid && f.stats.feasible);
    EXPECT_TRUE(f.stats.stopped) << "frame " << frame;
    EXPECT_TRUE(f.stats.capped) << "frame " << frame;
    EXPECT_EQ(stop.polls, 1) << "frame " << frame;
    EXPECT_LT(f.stats.splits + f.stats.blockedSplits, kCellStopPoll) << "frame " << frame;
    EXPECT_LE(f.stats.drawnVoxels, v.voxelBudget);
    EXPECT_LE(f.stats.maxVoxel_px, last) << "quality dropped while the view stood still, frame " << frame;
    if (frame == 0) {
      EXPECT_NE(sortedCells(f.draw), sortedCells(full.draw)) << "the stop cut nothing short";
    }
    last = f.stats.maxVoxel_px;
    expectValidRealization(t, sel);
  }
  // The stops end: the next frame is the selection from scratch.
  v.stop = nullptr;
  Frame f;
  expectSameAsFresh(t, sel, v, "after the stops", f);
  EXPECT_EQ(f.stats.maxVoxel_px, full.stats.maxVoxel_px);
  EXPECT_FALSE(f.stats.stopped);

  // A stop that is polled but never fires chooses exactly as no stop, along a path.
  CellSelector polled(t), unpolled(t);
  StopAfter never;
  never.stopAt = 0;
  for (int frame = 0; frame < 20; ++frame) {
    v.camera.eye_m += glm::dvec3(0.5, 0.3, -0.4);
    v.camera.heading_deg += 3.0;
    CellView w = v;
    w.stop = &StopAfter::poll;
    w.stopContext = &never;
    const Frame a = runSelect(polled, t, w), b = runSelect(unpolled, t, v);
    expectSameFrame(a, b, "never-firing stop, frame " + std::to_string(frame));
    EXPECT_FALSE(a.stats.stopped);
  }
  EXPECT_GT(never.polls, 0);
}

// After a jump of the eye, hundreds of refined cells can leave the view at once; merging them
// back (they cost nothing and cannot be seen) is polled too, so a stop can end the frame there:
// the frame refines nothing, stays valid and within the budget, and the later frames merge the
// rest and come back to the selection from scratch.
TEST(CellSelect, AStopCanEndTheMergesOfCellsThatLeftTheView) {
  const CellTree t = stopTree(64);
  CellView v = stopView();
  CellView turned = v;
  turned.camera.heading_deg += 180.0;
  // How many cells the turn merges back without a stop.
  CellSelector plain(t);
  runSelect(plain, t, v);
  const Frame after = runSelect(plain, t, turned);
  ASSERT_GT(after.stats.merges, 3 * kCellStopPoll) << "the turn must merge many cells back";

  CellSelector sel(t);
  runSelect(sel, t, v);
  StopAfter stop;  // fires at the first poll: after kCellStopPoll - 1 merges
  CellView w = turned;
  w.stop = &StopAfter::poll;
  w.stopContext = &stop;
  const Frame f = runSelect(sel, t, w);
  EXPECT_TRUE(f.stats.stopped);
  EXPECT_TRUE(f.stats.capped);
  EXPECT_EQ(stop.polls, 1);
  EXPECT_EQ(f.stats.splits + f.stats.blockedSplits, 0u) << "stopped before the refinement";
  EXPECT_LT(f.stats.merges, after.stats.merges);
  EXPECT_LE(f.stats.drawnVoxels, w.voxelBudget);
  EXPECT_TRUE(f.stats.feasible);
  expectValidRealization(t, sel);
  EXPECT_GT(f.stats.cutCells, after.stats.cutCells) << "the rest of the merges must be left to later frames";

  // Stopped at every first poll, the frames go on merging and then refining, never over budget.
  int frames = 0;
  for (; frames < 100; ++frames) {
    stop = {};
    const Frame g = runSelect(sel, t, w);
    EXPECT_LE(g.stats.drawnVoxels, w.voxelBudget);
    expectValidRealization(t, sel);
    if (!g.stats.stopped) break;
  }
  EXPECT_LT(frames, 100) << "the stopped frames never caught up";
  Frame g;
  expectSameAsFresh(t, sel, turned, "after the stopped merges", g);
  EXPECT_EQ(g.stats.maxVoxel_px, after.stats.maxVoxel_px);
}

// igd's cells phase budget (ig/cells_deadline.h, header-only): a stop at the budget on the
// caller's clock; what a stopped call spends after its stop is learned and taken off the next
// deadlines, so that the whole call ends near the budget.
class CountingClock final : public ig::Clock {
 public:
  int64_t now_ns() const override {
    ++reads;
    return now += 10'000;  // 10 us a reading: every poll of the deadline moves time on
  }
  void sleepUntil_ns(int64_t) override {}
  mutable int64_t now = 0, reads = 0;
};

TEST(CellSelectDeadline, LearnsTheTimeAfterAStopAndTakesItOffTheNextDeadlines) {
  const CellTree t = stopTree(63);
  CellView v = stopView();
  CountingClock clock;
  ig::CellSelectDeadline deadline;
  int64_t polls[2] = {0, 0};
  for (int frame = 0; frame < 2; ++frame) {
    CellSelector sel(t);  // from scratch: a long refinement every time
    deadline.arm(v, clock, clock.now_ns(), 0.05);
    ASSERT_NE(v.stop, nullptr);
    const int64_t before = clock.reads;
    const Frame f = runSelect(sel, t, v);
    polls[frame] = clock.reads - before;
    deadline.done(v);
    EXPECT_EQ(v.stop, nullptr);
    EXPECT_TRUE(f.stats.stopped) << "frame " << frame;
    expectValidRealization(t, sel);
  }
  // Frame 0: the deadline 50 us on fires at the 5th poll, done() reads once: 10 us after the
  // stop. Frame 1: 40 us of room, one poll fewer.
  EXPECT_EQ(polls[0], 5);
  EXPECT_NEAR(deadline.afterStop_ms(), 0.01, 1e-9);
  EXPECT_EQ(polls[1], 4);
  // No budget (0, negative, NaN): no stop.
  for (double b : {0.0, -1.0, std::nan("")}) {
    deadline.arm(v, clock, clock.now_ns(), b);
    EXPECT_EQ(v.stop, nullptr) << b;
  }
}

// A call whose refinement ends before its deadline teaches the time after its last poll too, so
// that the first call that is stopped already leaves room for what follows its stop.
TEST(CellSelectDeadline, LearnsFromCallsThatWereNotStopped) {
  const CellTree t = stopTree(63);
  CellView v = stopView();
  CountingClock clock;
  ig::CellSelectDeadline deadline;
  {
    CellSelector sel(t);
    deadline.arm(v, clock, clock.now_ns(), 1000.0);  // never reached
    const int64_t before = clock.reads;
    const Frame f = runSelect(sel, t, v);
    ASSERT_GT(clock.reads - before, 1) << "the refinement must have polled";
    deadline.done(v);
    EXPECT_FALSE(f.stats.stopped);
  }
  // done() read the clock once after the last poll: 10 us.
  EXPECT_NEAR(deadline.afterStop_ms(), 0.01, 1e-9);
  // A call that never polls (the same view again: nothing to refine) teaches nothing.
  {
    CellSelector sel(t);
    runSelect(sel, t, v);
    deadline.arm(v, clock, clock.now_ns(), 1000.0);
    const int64_t before = clock.reads;
    const Frame f = runSelect(sel, t, v);
    ASSERT_EQ(clock.reads, before) << "a converged frame must not poll";
    clock.now += 1'000'000;  // 1 ms later
    deadline.done(v);
  }
  EXPECT_NEAR(deadline.afterStop_ms(), 0.01, 1e-9);
}

// Streaming with a stop in every frame (a machine too slow for the budget): the budgets hold,
// quality never drops while the view stands still, and it still reaches full quality.
TEST(CellSelect, StreamingUnderAStopEveryFrameReachesFullQuality) {
  const CellTree t = stopTree(62);
  CellView v = stopView();
  Streamer s(t.size());
  s.latency = 2;
  CellSelector sel(t);
  StopAfter stop;
  v.stop = &StopAfter::poll;
  v.stopContext = &stop;
  float last = std::numeric_limits<float>::infinity();
  int frame = 0, stopped = 0;
  for (; frame < 2000; ++frame) {
    s.deliver(frame);
    stop = {};
    const Frame f = runSelect(sel, t, v, s.res);
    expectFrameWithinBudgets(t, v, f, s);
    EXPECT_LT(f.stats.splits + f.stats.blockedSplits, kCellStopPoll);
    stopped += f.stats.stopped ? 1 : 0;
    if (!f.draw.empty()) {
      EXPECT_LE(f.stats.maxVoxel_px, last) << "frame " << frame;
      last = f.stats.maxVoxel_px;
    }
    expectValidRealization(t, sel);
    s.request(f.requests, frame);
    if (!f.stats.stopped && f.requests.empty() && f.stats.blockedSplits == 0 && s.inFlight() == 0) break;
  }
  ASSERT_LT(frame, 2000) << "streaming under stops did not settle";
  EXPECT_GT(stopped, 5) << "the stops must have cut the refinement short";
  CellSelector all(t);
  const Frame a = runSelect(all, t, v);
  ASSERT_TRUE(a.stats.feasible);
  EXPECT_EQ(a.stats.maxVoxel_px, last);
}

TEST(CellSelect, ChunkedPassesChooseExactlyAsOnePass) {
  // Streaming along a path with a teleport, evictions and an operation cap, then everything
  // resident; small chunks, so that every pass has many; each runner mode against one pass.
  std::mt19937 rng(71);
  TreeSpec spec;
  spec.levels = 7;
  spec.maxChildren = 5;
  spec.leafEarly = 0.05;
  spec.rootEdge_m = 64.0;
  const CellTree t = randomTree(rng, spec);
  ASSERT_GT(t.size(), 500u);
  for (int mode = 0; mode < 4; ++mode) {
    for (uint32_t cap : {1u << 30, 7u}) {
      InterleavedRunner runner(mode, 5u + static_cast<uint32_t>(mode));
      CellSelectorConfig one, chunked;
      one.maxOperations = chunked.maxOperations = cap;
      chunked.runner = &runner;
      chunked.chunkCells = 8;
      CellSelector a(t, one), b(t, chunked);
      Streamer s(t.size());
      CellView v;
      v.camera.far_m = 10000.0;
      v.voxelBudget = 3000;
      v.byteBudget = 2000;
      v.minVoxel_px = 1.0;
      for (int frame = 0; frame < 260; ++frame) {
        const std::string what = "mode " + std::to_string(mode) + " cap " + std::to_string(cap) + " frame " +
                                 std::to_string(frame);
        const double r = frame * 0.02;
        v.camera.eye_m = frame == 120 ? glm::dvec3(60.0, 60.0, 70.0)  // teleport
                                      : glm::dvec3(32.0 + 50.0 * std::cos(r), 32.0 + 50.0 * std::sin(r), 40.0);
        v.camera.heading_deg = 270.0 - r * 57.29578;
        v.camera.pitch_deg = -20.0;
        s.deliver(frame);
        if (frame % 17 == 5) {
          for (uint32_t c = 1; c < t.size(); c += 3)
            if (s.res[c] == Residency::Resident) s.res[c] = Residency::Absent;
        }
        const bool resident = frame >= 200;  // the last frames: everything resident (no residency table)
        const std::span<const Residency> res = resident ? std::span<const Residency>() : s.res;
        const Frame fa = runSelect(a, t, v, res), fb = runSelect(b, t, v, res);
        expectSameFrame(fa, fb, what);
        if (::testing::Test::HasFatalFailure()) return;
        if (!resident) s.request(fa.requests, frame);
        // A draw span too small: the same first entries, truncated alike.
        if (frame % 50 == 7 && cap > 100 && fa.draw.size() > 4) {
          std::vector<CellDraw> da(fa.draw.size() / 2), db(da.size());
          std::vector<uint32_t> ra(t.size()), rb(t.size());
          CellSelectorConfig one2 = one, chunked2 = chunked;  // from the root: no cap
          one2.maxOperations = chunked2.maxOperations = CellSelectorConfig{}.maxOperations;
          CellSelector a2(t, one2), b2(t, chunked2);
          const CellSelectStats sa = a2.select(v, {}, da, ra), sb = b2.select(v, {}, db, rb);
          EXPECT_TRUE(sa.drawTruncated) << what;
          EXPECT_EQ(sb.drawTruncated, sa.drawTruncated) << what;
          EXPECT_EQ(sb.drawnCells, sa.drawnCells) << what;
          for (size_t i = 0; i < da.size(); ++i) ASSERT_EQ(db[i].cell, da[i].cell) << what;
        }
      }
      EXPECT_GT(runner.passes, 500u);
      if (mode != 1) {
        EXPECT_GT(runner.workerOne, 0u);
      } else {
        EXPECT_EQ(runner.workerOne, 0u);
      }
    }
  }
}

// The cheapest cover of c, from scratch: 0 outside the frustum; V if c is not refinable or a live
// child of it is not resident; else the least of V and its children's covers (V when c is wholly
// inside: covers only grow there).
int64_t referenceCost(const CellTree& t, const CellView& v, std::span<const Residency> res, uint32_t c) {
  const CellEval e = evaluateCell(t, c, v);
  if (!e.live) return 0;
  const int64_t own = t.voxels(c);
  if (t.childCount(c) == 0 || !(e.voxel_px > static_cast<float>(v.minVoxel_px))) return own;
  int64_t sum = 0;
  for (uint32_t i = 0; i < t.childCount(c); ++i) {
    const uint32_t ch = t.firstChild(c) + i;
    if (evaluateCell(t, ch, v).live && res[ch] != Residency::Resident) return own;
  }
  for (uint32_t i = 0; i < t.childCount(c) && sum < own; ++i) sum += referenceCost(t, v, res, t.firstChild(c) + i);
  return std::min(own, sum);
}

// Drawn cells that stop being resident collapse to an ancestor before this frame's costs are
// known: a cell collapsed away must not carry last frame's cheapest cover into this frame (a
// cell partly outside the frustum last frame may be wholly inside now and cost more: a blocked
// split would hold too few voxels, and the split made when its cells arrive would take them
// from cells refined meanwhile). The view moves, and in the same frame some drawn cells are
// evicted; then it stands still while the cells stream in: the quality never drops from that
// frame on, and the budgets hold.
TEST(CellSelect, EvictionRepairChargesThisFramesCosts) {
  std::mt19937 rng(83);
  int held = 0;
  long costed = 0;
  // 8 trials (3 under the sanitizers, where this was the slowest test at 21 s: test_scale.h).
  const int trials = ig::test::trials(8, 3);
  for (int trial = 0; trial < trials; ++trial) {
    TreeSpec spec;
    spec.levels = 6;
    spec.minChildren = 3;
    spec.maxChildren = 8;
    spec.leafEarly = 0.02;
    spec.empty = 0.02;
    spec.rootEdge_m = 64.0;
    const CellTree t = randomTree(rng, spec);
    CellSelector sel(t);
    Streamer s(t.size());
    s.latency = 1 + trial % 2;
    CellView v;
    v.camera.far_m = 10000.0;
    v.camera.fovY_deg = 40.0;
    v.minVoxel_px = 0.5;
    v.voxelBudget = t.voxels(0) * static_cast<uint64_t>(2 + trial % 5);
    uint32_t largest = 0;
    for (uint32_t c = 0; c < t.size(); ++c) largest = std::max(largest, t.bytes(c));
    v.byteBudget = static_cast<uint64_t>(largest) * static_cast<uint64_t>(4 + trial % 3);
    std::vector<uint32_t> drawn;
    float last = std::numeric_limits<float>::infinity();
    for (int frame = 0; frame < 240; ++frame) {
      const std::string what = "trial " + std::to_string(trial) + " frame " + std::to_string(frame);
      const int step = frame / 12;  // a new view every 12 frames
      const bool moved = frame % 12 == 0;
      v.camera.eye_m = glm::dvec3(32.0, -30.0 + 2.0 * step, 20.0);
      v.camera.heading_deg = 60.0 * std::sin(0.7 * step + trial);  // a pan to and fro
      v.camera.pitch_deg = -15.0;
      s.deliver(frame);
      if (moved && step > 2) {
        for (uint32_t c : drawn)
          if (c != 0 && rng() % 3 == 0) s.res[c] = Residency::Absent;
      }
      const Frame f = runSelect(sel, t, v, s.res);
      expectFrameWithinBudgets(t, v, f, s);
      if (moved) last = std::numeric_limits<float>::infinity();
      if (!f.draw.empty()) {
        ASSERT_LE(f.stats.maxVoxel_px, last) << what << ": the quality dropped while the view stood still";
        last = f.stats.maxVoxel_px;
        held += moved ? 0 : 1;
      }
      expectValidRealization(t, sel);
      for (uint32_t c = 0; c < t.size(); ++c) {
        const int64_t counted = sel.countedCost(c);
        if (counted < 0) continue;
        ASSERT_EQ(counted, referenceCost(t, v, s.res, c)) << what << " cell " << c;
        ++costed;
      }
      s.request(f.requests, frame);
      drawn.clear();
      for (const CellDraw& d : f.draw) drawn.push_back(d.cell);
    }
  }
  EXPECT_GT(held, 1500 * trials / 8) << trials << " trials";
  EXPECT_GT(costed, 700000L * trials / 8) << trials << " trials";
}

}  // namespace

namespace {
// Random frames on random trees (one cell up to 6 levels, huge coordinates): random view changes
// (small moves, teleports, camera inside the root box, near below float's range, tiny and huge
// fov), random voxel budget (0 and 1 too), W (0 too) and alpha changes, cells arriving out of
// order (cells never requested too), random evictions (mostly keeping the ancestors of drawn
// cells, sometimes not), operation caps, stops, sometimes everything resident. Every frame: a
// valid realization, both budgets, only resident live cells drawn with this frame's e, only
// absent cells requested, every counted cost this frame's cheapest cover, the same frame with
// chunked passes (and with a residency table of Resident cells as with none), the quality never
// worse while nothing changes but arrivals, and with everything resident the same cells as a
// selection from scratch (and the brute-force optimum on small trees).
void checkFrame(const CellTree& t, const CellView& v, const Frame& f, std::span<const Residency> res,
                const std::string& what) {
  ASSERT_TRUE(f.stats.valid) << what;
  EXPECT_LE(f.stats.drawnVoxels, v.voxelBudget) << what;
  EXPECT_LE(f.stats.drawnVoxels + f.stats.reservedVoxels, v.voxelBudget) << what;
  EXPECT_LE(f.stats.requestedBytes, v.byteBudget) << what;
  uint64_t bytes = 0, voxels = 0;
  float maxE = 0.0f;
  for (uint32_t c : f.requests) {
    ASSERT_LT(c, t.size()) << what;
    bytes += t.bytes(c);
    if (!res.empty()) {
      EXPECT_EQ(res[c], Residency::Absent) << what << " requested " << c;
    }
  }
  EXPECT_EQ(bytes, f.stats.requestedBytes) << what;
  for (const CellDraw& d : f.draw) {
    ASSERT_LT(d.cell, t.size()) << what;
    if (!res.empty()) {
      EXPECT_EQ(res[d.cell], Residency::Resident) << what << " drew missing " << d.cell;
    }
    const CellEval e = evaluateCell(t, d.cell, v);
    EXPECT_TRUE(e.live) << what << " drew a cell that is not live " << d.cell;
    EXPECT_EQ(e.voxel_px, d.voxel_px) << what << " cell " << d.cell;
    voxels += t.voxels(d.cell);
    maxE = std::max(maxE, d.voxel_px);
  }
  EXPECT_EQ(voxels, f.stats.drawnVoxels) << what;
  EXPECT_EQ(maxE, f.stats.maxVoxel_px) << what;
}
}  // namespace

TEST(CellSelect, RandomFramesKeepEveryContract) {
  std::mt19937 rng(2027);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  long frames = 0, optimal = 0;
  for (int trial = 0; trial < 120; ++trial) {
    TreeSpec spec;
    spec.levels = 1 + trial % 6;
    spec.minChildren = 1;
    spec.maxChildren = 2 + trial % 7;
    spec.leafEarly = 0.1;
    spec.empty = 0.15;
    spec.rootEdge_m = trial % 5 == 4 ? 4096.0 : 16.0;
    if (trial % 7 == 6) spec.rootMin_m = glm::dvec3(1.0e7, -2.0e6, 1.0e5);
    const CellTree t = randomTree(rng, spec);
    const bool small = countCuts(t, 0) < 20000;
    InterleavedRunner runner(3, 11u + static_cast<uint32_t>(trial));
    CellSelectorConfig one, chunked;
    const bool capped = trial % 4 == 1;
    one.maxOperations = chunked.maxOperations = capped ? 1u + static_cast<uint32_t>(rng() % 5) : one.maxOperations;
    chunked.runner = &runner;
    chunked.chunkCells = 8;
    CellSelector a(t, one), b(t, chunked);
    std::vector<Residency> res(t.size(), Residency::Absent);
    std::vector<uint32_t> drawn;
    CellView v = randomView(rng, t);
    uint32_t largest = 0;
    for (uint32_t c = 0; c < t.size(); ++c) largest = std::max(largest, t.bytes(c));
    v.byteBudget = largest * 2;
    float last = std::numeric_limits<float>::infinity();
    bool prevEverything = false;
    for (int frame = 0; frame < 120; ++frame) {
      const std::string what = "trial " + std::to_string(trial) + " frame " + std::to_string(frame);
      bool still = !prevEverything;
      const double r = u(rng);
      if (r < 0.08) {
        const CellView n = randomView(rng, t);
        v.camera = n.camera;
        v.viewportHeight_px = n.viewportHeight_px;
        if (u(rng) < 0.1) v.camera.near_m = 1e-300;  // 0 in float: e = inf around the eye
        if (u(rng) < 0.05) v.camera.fovY_deg = 1e-3;
        if (u(rng) < 0.05) v.camera.fovY_deg = 179.0;
        still = false;
      } else if (r < 0.2) {
        v.camera.eye_m += t.info().rootEdge_m * 0.05 * glm::dvec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
        v.camera.heading_deg += 10.0 * (u(rng) - 0.5);
        still = false;
      }
      if (u(rng) < 0.15) {
        const CellView n = randomView(rng, t);
        const uint64_t choices[] = {0, 1, n.voxelBudget, n.voxelBudget / 2, 1u << 30};
        const uint64_t nb = choices[rng() % 5];
        still = still && nb == v.voxelBudget;
        v.voxelBudget = nb;
      }
      if (u(rng) < 0.1) {
        const uint64_t ws[] = {0, 1, largest / 2, largest, uint64_t{largest} * 4, 1u << 30};
        const uint64_t nw = ws[rng() % 6];
        v.byteBudget = nw;
      }
      if (u(rng) < 0.05) {
        const double alphas[] = {0.0, 0.5, 1.0, 4.0};
        v.minVoxel_px = alphas[rng() % 4];
        still = false;
      }
      // Arrivals, out of order; sometimes cells never requested (children before parents).
      for (uint32_t c = 0; c < t.size(); ++c)
        if (res[c] == Residency::InFlight && u(rng) < 0.4) res[c] = Residency::Resident;
      if (u(rng) < 0.03)
        for (uint32_t c = 0; c < t.size(); ++c)
          if (res[c] == Residency::Absent && u(rng) < 0.2) res[c] = Residency::Resident;
      // Evictions.
      if (u(rng) < 0.1) {
        std::vector<bool> keep(t.size(), false);
        // Mostly as the cache does (ancestors of drawn cells stay); sometimes anything.
        if (u(rng) < 0.7)
          for (uint32_t c : drawn)
            for (uint32_t p = t.parent(c); p != kNoCell; p = t.parent(p)) keep[p] = true;
        for (uint32_t c = 0; c < t.size(); ++c)
          if (!keep[c] && res[c] == Residency::Resident && u(rng) < 0.3) res[c] = Residency::Absent;
        still = false;
      }
      const bool everything = (trial % 3 == 0 && frame > 60) || (frame % 40 == 39);
      const std::span<const Residency> rs = everything ? std::span<const Residency>() : std::span<const Residency>(res);
      // With everything resident: no table for one, a table of Resident for the other.
      const std::vector<Residency> allResident(t.size(), Residency::Resident);
      // Sometimes a stop (a deadline) ends the refinement after 1 ... 3 polls.
      StopAfter sa, sb;
      const bool stopped = u(rng) < 0.2;
      sa.stopAt = sb.stopAt = 1 + static_cast<int>(rng() % 3);
      v.stop = stopped ? &StopAfter::poll : nullptr;
      v.stopContext = &sa;
      const Frame fa = runSelect(a, t, v, rs);
      v.stopContext = &sb;
      const Frame fb = runSelect(b, t, v, everything ? std::span<const Residency>(allResident) : rs);
      v.stop = nullptr;
      ++frames;
      expectSameFrame(fa, fb, what + " (chunked)");
      checkFrame(t, v, fa, rs, what);
      expectValidRealization(t, a);
      expectValidRealization(t, b);
      if (::testing::Test::HasFatalFailure()) return;
      {
        // Every cost counted is this frame's cheapest cover.
        const std::span<const Residency> rr =
            everything ? std::span<const Residency>(allResident) : std::span<const Residency>(res);
        for (uint32_t c = 0; c < t.size(); ++c) {
          const int64_t counted = a.countedCost(c);
          if (counted < 0) continue;
          ASSERT_EQ(counted, referenceCost(t, v, rr, c)) << what << " cell " << c;
        }
      }
      if (everything && !capped && !stopped) {
        CellSelector fresh(t);
        const Frame g = runSelect(fresh, t, v);
        ASSERT_EQ(fa.stats.feasible, g.stats.feasible) << what;
        EXPECT_EQ(fa.stats.maxVoxel_px, g.stats.maxVoxel_px) << what;
        ASSERT_EQ(sortedCells(fa.draw), sortedCells(g.draw)) << what << " (vs from scratch)";
        if (small) {
          expectOptimal(t, v, fa.stats, what);
          ++optimal;
        }
        still = false;
      }
      if (everything) still = false;
      if (still && !fa.draw.empty()) {
        EXPECT_LE(fa.stats.maxVoxel_px, last) << what << ": quality dropped while still";
      }
      last = fa.draw.empty() ? std::numeric_limits<float>::infinity() : fa.stats.maxVoxel_px;
      if (::testing::Test::HasFatalFailure()) return;
      prevEverything = everything;
      if (!everything)
        for (uint32_t c : fa.requests) res[c] = Residency::InFlight;
      drawn.clear();
      for (const CellDraw& d : fa.draw) drawn.push_back(d.cell);
    }
  }
  EXPECT_GT(frames, 14000);
  EXPECT_GT(optimal, 300);
}

// A valid view whose near distance is below float's range (or a fov so small, or a viewport so
// tall, that the pixels per radian overflow a float) gives the cells around the eye e = inf. When
// the greedy stops at such a cell, the next frame's heap window starts at inf; a larger budget
// then empties the heap and the window was "lowered" from inf to 0.8 * inf = inf for ever: the
// frame never returned.
TEST(CellSelect, InfiniteOnScreenVoxelsDoNotHangTheNextFrame) {
  std::mt19937 rng(5);
  TreeSpec spec;
  spec.levels = 4;
  spec.minChildren = 8;
  spec.maxChildren = 8;
  spec.empty = 0.0;
  spec.leafEarly = 0.0;
  const CellTree t = randomTree(rng, spec);
  CellSelector sel(t);
  CellView v;
  v.camera.eye_m = {4.1, 4.2, 4.3};  // inside the root box
  v.camera.near_m = 1e-300;          // valid (> 0), but 0 in float: the cells around the eye have e = inf
  v.camera.fovY_deg = 90.0;
  v.camera.far_m = 1000.0;
  v.minVoxel_px = 1.0;
  v.voxelBudget = t.voxels(0);  // the root only: the greedy stops at the root (e = inf)
  Frame f = runSelect(sel, t, v);
  ASSERT_TRUE(f.stats.valid);
  ASSERT_TRUE(f.stats.feasible);
  ASSERT_EQ(f.stats.splits, 0u);
  ASSERT_TRUE(std::isinf(f.stats.maxVoxel_px));
  v.voxelBudget = 1u << 30;  // everything fits: the greedy runs past the cells of e = inf
  f = runSelect(sel, t, v);
  EXPECT_TRUE(f.stats.valid);
  EXPECT_TRUE(f.stats.feasible);
  EXPECT_GT(f.stats.splits, 8u);
  expectValidRealization(t, sel);
  CellSelector fresh(t);
  const Frame g = runSelect(fresh, t, v);
  EXPECT_EQ(sortedCells(f.draw), sortedCells(g.draw));
}

// CellSelectorConfig::chunkCells is rounded up to a multiple of 8 and divides the cut: a very large
// value (a caller asking for "one chunk") wrapped around: 0xFFFFFFF9 and above rounded to 0 (a
// division by zero), and near the top the chunk count (cut + size - 1) / size wrapped to 0, so
// no pass ran: nothing evaluated, nothing drawn.
TEST(CellSelect, HugeChunkSizesRunOneChunk) {
  std::mt19937 rng(91);
  TreeSpec spec;
  spec.levels = 5;
  spec.minChildren = 4;
  spec.maxChildren = 8;
  spec.empty = 0.0;
  spec.leafEarly = 0.0;
  const CellTree t = randomTree(rng, spec);
  CellView v;
  v.camera.eye_m = {4.0, -12.0, 6.0};
  v.camera.pitch_deg = -10.0;
  v.camera.far_m = 1000.0;
  v.minVoxel_px = 0.0;
  v.voxelBudget = 1u << 30;
  for (const uint32_t size : {0xFFFFFFF0u, 0xFFFFFFFFu}) {
    InterleavedRunner runner(0);
    CellSelectorConfig cfg;
    cfg.runner = &runner;
    cfg.chunkCells = size;
    CellSelector plain(t), sel(t, cfg);
    for (int frame = 0; frame < 2; ++frame) {
      const Frame ref = runSelect(plain, t, v), f = runSelect(sel, t, v);
      ASSERT_GT(ref.stats.cutCells, 64u);
      expectSameFrame(ref, f, "chunkCells " + std::to_string(size) + " frame " + std::to_string(frame));
      v.camera.heading_deg += 2.0;
    }
  }
}

// CellSelectStats::unfetchable counts the wanted cells larger than W. A cell was counted once per
// attempt to request it: a blocked split of its parent, then again when the greedy stopped and
// the children of cells with an unknown cover were requested.
TEST(CellSelect, UnfetchableCellsAreCountedOnce) {
  // Root [0, 8]^3; cell 1 = octant 0 ([0, 4]^3), cell 2 = octant 1 ([4, 8] x [0, 4]^2). Cell 1's
  // children: octant 0 (outside the view) and octant 7 (in view, larger than W, not resident);
  // cell 2's children: octants 4 and 6.
  std::vector<CellDesc> cells = {{kNoCell, 0, 100, 10}, {0, 0, 50, 10}, {0, 1, 60, 10},
                                 {1, 0, 30, 10},        {1, 7, 30, 5000}, {2, 4, 40, 10}, {2, 6, 40, 10}};
  CellTree t;
  std::string err;
  CellTreeInfo info;
  info.rootEdge_m = 8.0;
  info.cellVoxelDepth = 2;
  ASSERT_TRUE(t.build(info, cells, err)) << err;
  CellView v;
  v.camera.eye_m = {3.5, -6.0, 3.5};
  v.camera.fovY_deg = 20.0;
  v.camera.far_m = 1000.0;
  v.minVoxel_px = 0.0;
  v.voxelBudget = 120;
  v.byteBudget = 1000;
  ASSERT_TRUE(evaluateCell(t, 4, v).live);
  ASSERT_FALSE(evaluateCell(t, 3, v).live);
  std::vector<Residency> res(t.size(), Residency::Resident);
  res[4] = Residency::Absent;
  CellSelector sel(t);
  const Frame f = runSelect(sel, t, v, res);
  ASSERT_TRUE(f.stats.feasible);
  EXPECT_EQ(f.stats.splits, 1u);  // the root; then cell 1 waits for a cell it can never get, cell 2 does not fit
  EXPECT_EQ(f.stats.requestedCells, 0u);
  EXPECT_EQ(f.stats.unfetchable, 1u);
}

