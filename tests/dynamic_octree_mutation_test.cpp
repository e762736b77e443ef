// Single-reference octree (lod/dynamic_octree.h), from a mutation-testing pass over
// lod/dynamic_octree.cpp: each test pins one documented detail that perfmodel_test.cpp and
// hard_cases_test.cpp leave open (a mutant of it passed every test there):
//   - init(): maxDepth 20 is the deepest allowed, bounds empty along any axis are refused;
//   - placement: boxes touching a cell's mid plane from one side go down into that side, boxes
//     reaching out of the root stay in it, no node deeper than maxDepth, no more than maxNodes;
//   - bookkeeping: each dirty node once, the count of non-empty nodes;
//   - expensive nodes: own objects >= factor * average per non-empty node, and at least
//     expensiveMinObjects (both ends exact);
//   - traversal: only non-empty nodes drawn and tested, candidates with exactly
//     expensiveMinObjects below them, results exactly occlusionMaxAge frames old still hold,
//     no box test (and no skipping) for a box around the eye or behind the near plane, no
//     re-test while a query is in flight, a hidden subtree wholly in view counted without
//     walking it, one partly in view counted by the octants in view (none emptied walked), an
//     empty tree tested not at all;
//   - results: one of the same frame replaces the last one; expireVisibleResults never moves
//     the validity frame back; clearOcclusion() ends queries in flight too.
// One test found a deviation from dynamic_octree.h, fixed with it: BoundsAreTightForBoxesBeyondOneE300.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "lod/dynamic_octree.h"
#include "lod/view.h"
#include "octree_fixtures.h"

using namespace ig::lod;

namespace {

using ig::lod::test::cube;
using ig::lod::test::wideCamera;

// 256 m root cube at the origin.
OctreeConfig rootConfig(uint32_t maxDepth, uint32_t maxAge = 8) { return ig::lod::test::octreeConfig(maxDepth, maxAge); }

bool holds(std::span<const uint32_t> list, uint32_t count, uint32_t n) {
  return std::find(list.begin(), list.begin() + count, n) != list.begin() + count;
}

// A cluster of `count` small boxes around `centre` (all in one leaf of a depth-5 tree).
void insertCluster(DynamicOctree& t, uint32_t& id, glm::dvec3 centre, uint32_t count) {
  for (uint32_t i = 0; i < count; ++i, ++id)
    ASSERT_TRUE(t.insert(id, cube(centre + glm::dvec3(0.1 * (i % 5), 0.1 * (i / 5 % 5), 0.1 * (i / 25)), 0.05)));
}

}  // namespace

// init() refuses "empty ... bounds, maxDepth > 20": empty along z alone, and depth 21; takes 20.
TEST(DynamicOctree, InitTakesDepthTwentyAndRefusesBoundsEmptyAlongAnyAxis) {
  DynamicOctree t;
  OctreeConfig c = rootConfig(20);
  EXPECT_TRUE(t.init(c));
  c.maxDepth = 21;
  EXPECT_FALSE(t.init(c));
  c.maxDepth = 4;
  for (int axis = 0; axis < 3; ++axis) {
    c.bounds = cube(glm::dvec3(0.0), 1.0);
    c.bounds.max[axis] = c.bounds.min[axis];
    EXPECT_FALSE(t.init(c)) << "flat along axis " << axis;
  }
  c.bounds = cube(glm::dvec3(0.0), 1.0);
  c.maxNodes = 0;
  EXPECT_FALSE(t.init(c));  // like maxObjects = 0: nothing could be stored
}

// "The deepest one whose cell contains the object's box whole": cells are closed, so a box that
// touches a cell's mid plane from one side lies in that side's octant and goes down into it, to
// maxDepth (cells 4 m wide at depth 6), not kept in the parent as if it straddled.
TEST(DynamicOctree, ABoxTouchingAMidPlaneGoesDownIntoItsSide) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(6)));
  const Aabb above{glm::dvec3(0.0), glm::dvec3(1.0)};   // min on every mid plane of its cells
  const Aabb below{glm::dvec3(-1.0), glm::dvec3(0.0)};  // max on the root's mid planes
  ASSERT_TRUE(t.insert(0, above));
  ASSERT_TRUE(t.insert(1, below));
  for (uint32_t id : {0u, 1u}) {
    const DynamicOctree::Node& n = t.node(t.nodeOf(id));
    EXPECT_EQ(n.depth, 6u) << id;
    EXPECT_TRUE(n.cell.contains(t.boxOf(id).min) && n.cell.contains(t.boxOf(id).max)) << id;
  }
  EXPECT_TRUE(t.checkInvariant());
}

// "Objects outside the root cell stay in the root": also a box that is in one octant on every
// axis but reaches out of the root, and one wholly outside it.
TEST(DynamicOctree, ABoxReachingOutOfTheRootStaysInTheRoot) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(6)));
  ASSERT_TRUE(t.insert(0, {glm::dvec3(100.0), glm::dvec3(200.0)}));
  ASSERT_TRUE(t.insert(1, cube(glm::dvec3(1e6), 1.0)));
  EXPECT_EQ(t.nodeOf(0), 0u);
  EXPECT_EQ(t.nodeOf(1), 0u);
  EXPECT_EQ(t.nodes().size(), 1u);  // no octant created for them
}

// Root = depth 0: no node is deeper than maxDepth, and no more than maxNodes nodes exist.
TEST(DynamicOctree, NoNodeBelowMaxDepthAndNoMoreThanMaxNodes) {
  for (uint32_t maxDepth : {0u, 1u, 3u}) {
    DynamicOctree t;
    ASSERT_TRUE(t.init(rootConfig(maxDepth)));
    ASSERT_TRUE(t.insert(0, cube(glm::dvec3(37.3, -81.1, 5.7), 0.01)));
    uint32_t deepest = 0;
    for (const DynamicOctree::Node& n : t.nodes()) deepest = std::max(deepest, n.depth);
    EXPECT_EQ(deepest, maxDepth);
    EXPECT_EQ(t.node(t.nodeOf(0)).depth, maxDepth);
  }
  OctreeConfig c = rootConfig(6);
  c.maxNodes = 5;
  DynamicOctree t;
  ASSERT_TRUE(t.init(c));
  for (uint32_t id = 0; id < 64; ++id)
    ASSERT_TRUE(t.insert(id, cube(glm::dvec3(-120.0 + 3.7 * id, 100.0 - 3.1 * id, -60.0 + 1.9 * id), 0.01)));
  EXPECT_EQ(t.nodes().size(), 5u);
  EXPECT_TRUE(t.checkInvariant());
}

// dirtyNodes(): "each once", however often a node is touched before clearDirty(); and
// nonEmptyNodes() counts the nodes holding objects through inserts, moves and removes.
TEST(DynamicOctree, DirtyNodesAreListedOnceAndNonEmptyNodesAreCounted) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(4)));
  const glm::dvec3 a(40.0, 40.0, 40.0), b(-40.0, -40.0, -40.0);
  ASSERT_TRUE(t.insert(0, cube(a, 0.5)));
  ASSERT_TRUE(t.insert(1, cube(a + glm::dvec3(0.5), 0.5)));
  EXPECT_EQ(t.dirtyNodes().size(), 1u);
  EXPECT_EQ(t.nonEmptyNodes(), 1u);
  t.refresh();
  t.clearDirty();
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(t.move(0, cube(a + glm::dvec3(0.1 * i), 0.5)));  // same node
  EXPECT_EQ(t.dirtyNodes().size(), 1u);
  ASSERT_TRUE(t.insert(2, cube(b, 0.5)));
  EXPECT_EQ(t.nonEmptyNodes(), 2u);
  ASSERT_TRUE(t.move(1, cube(b + glm::dvec3(0.5), 0.5)));  // into 2's node
  ASSERT_TRUE(t.move(0, cube(b - glm::dvec3(0.5), 0.5)));  // the first node is empty now
  EXPECT_EQ(t.dirtyNodes().size(), 2u);
  EXPECT_EQ(t.nonEmptyNodes(), 1u);
  ASSERT_TRUE(t.remove(0));
  ASSERT_TRUE(t.remove(1));
  ASSERT_TRUE(t.remove(2));
  EXPECT_EQ(t.nonEmptyNodes(), 0u);
  EXPECT_EQ(t.objectCount(), 0u);
}

namespace {

// Ten non-empty leaves of a depth-2 tree (64 m cells): nine with one object, one with `big`.
// Returns that leaf.
uint32_t tenLeaves(DynamicOctree& t, uint32_t big) {
  uint32_t id = 0;
  const double centres[4] = {-96.0, -32.0, 32.0, 96.0};
  for (int i = 0; i < 9; ++i) {
    EXPECT_TRUE(t.insert(id++, cube({centres[i % 4], centres[(i / 4) % 4], centres[i % 3]}, 1.0)));
  }
  for (uint32_t i = 0; i < big; ++i) EXPECT_TRUE(t.insert(id++, cube({96.0 - 0.1 * i, 96.0, 96.0}, 0.01)));
  t.refresh();
  EXPECT_EQ(t.nonEmptyNodes(), 10u);
  return t.nodeOf(id - 1);
}

}  // namespace

// "Expensive: own objects >= factor * average per non-empty node" (the average over the nodes
// holding objects, not over every node of the tree), "and at least expensiveMinObjects".
TEST(DynamicOctree, TheExpensiveThresholdIsExact) {
  OctreeConfig c = rootConfig(2);
  c.expensiveFactor = 4.0;
  c.expensiveMinObjects = 1;
  {
    DynamicOctree t;  // 15 objects in 10 nodes: average 1.5, threshold exactly 6
    ASSERT_TRUE(t.init(c));
    const uint32_t leaf = tenLeaves(t, 6);
    EXPECT_TRUE(t.node(leaf).expensive);
    EXPECT_TRUE(t.node(t.node(leaf).parent).expensive);  // propagated upwards
  }
  {
    DynamicOctree t;  // 14 objects: threshold 5.6, 5 is not expensive
    ASSERT_TRUE(t.init(c));
    const uint32_t leaf = tenLeaves(t, 5);
    ASSERT_GT(t.nodes().size(), 12u);  // empty inner nodes: they do not lower the average
    EXPECT_FALSE(t.node(leaf).expensive);
    for (const DynamicOctree::Node& n : t.nodes()) EXPECT_FALSE(n.expensive);
  }
  {
    c.expensiveFactor = 1.0;
    c.expensiveMinObjects = 8;
    DynamicOctree t;  // 7 objects: above 1 x the average, below the minimum
    ASSERT_TRUE(t.init(c));
    const uint32_t leaf = tenLeaves(t, 7);
    EXPECT_FALSE(t.node(leaf).expensive);
    for (const DynamicOctree::Node& n : t.nodes()) EXPECT_FALSE(n.expensive);
  }
}

// "Writes the non-empty visible nodes to draw ... then the other non-empty nodes with at least
// expensiveMinObjects objects below them": inner nodes without objects of their own are neither
// drawn nor (unless expensive) tested; a leaf with exactly expensiveMinObjects objects is tested.
TEST(DynamicOctree, OnlyNonEmptyNodesAreDrawnAndTestedFromExactlyTheMinimum) {
  DynamicOctree t;
  OctreeConfig c = rootConfig(5);
  c.expensiveFactor = 1000.0;  // no expensive nodes
  c.expensiveMinObjects = 8;
  ASSERT_TRUE(t.init(c));
  uint32_t id = 0;
  insertCluster(t, id, {30.0, 60.0, 5.0}, 8);
  const uint32_t eight = t.nodeOf(0);
  insertCluster(t, id, {-30.0, 60.0, 5.0}, 7);
  const uint32_t seven = t.nodeOf(8);
  t.refresh();
  ASSERT_NE(eight, seven);
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 10;
  const auto r = t.traverse(makeFrustum(wideCamera()), tr, draw, test);
  EXPECT_EQ(r.drawn, 2u);
  EXPECT_EQ(r.objectsDrawn, 15u);
  for (uint32_t i = 0; i < r.drawn; ++i) EXPECT_FALSE(t.node(draw[i]).objects.empty());
  EXPECT_EQ(r.candidates, 1u);
  EXPECT_TRUE(holds(test, r.candidates, eight));
  EXPECT_FALSE(holds(test, r.candidates, seven));
}

// Results "older than occlusionMaxAge frames" are ignored: one exactly that old still holds (a
// hidden node stays skipped, a visible one stays out of the tests), one frame later it does not.
TEST(DynamicOctree, AResultExactlyOcclusionMaxAgeFramesOldStillHolds) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(5, 4)));
  uint32_t id = 0;
  insertCluster(t, id, {30.0, 60.0, 5.0}, 20);
  const uint32_t hidden = t.nodeOf(0);
  insertCluster(t, id, {-30.0, 60.0, 5.0}, 20);
  const uint32_t visible = t.nodeOf(20);
  t.refresh();
  const Frustum f = makeFrustum(wideCamera());
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.useOcclusion = true;
  t.setOcclusionResult(hidden, false, 10);
  t.setOcclusionResult(visible, true, 10);
  tr.frame = 14;  // 4 frames old
  auto r = t.traverse(f, tr, draw, test);
  EXPECT_FALSE(holds(draw, r.drawn, hidden));
  EXPECT_EQ(r.hiddenObjects, 20u);
  EXPECT_FALSE(holds(test, r.candidates, visible));
  tr.frame = 15;  // 5 frames old: ignored
  r = t.traverse(f, tr, draw, test);
  EXPECT_TRUE(holds(draw, r.drawn, hidden));
  EXPECT_EQ(r.hiddenObjects, 0u);
  EXPECT_TRUE(holds(test, r.candidates, visible));
}

// "Nodes whose box contains the eye or reaches behind the near plane" are not tested, whichever
// corner is behind it: here the eye is just inside the max corner of a leaf's box, looking
// towards its min corner (down and south-west), so only that one corner is behind the eye.
TEST(DynamicOctree, ABoxBehindTheNearPlaneAtItsMaxCornerIsNotTested) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(5)));
  uint32_t id = 0;
  for (int i = 0; i < 27; ++i, ++id)  // a 2 m cube of boxes in one 8 m leaf
    ASSERT_TRUE(t.insert(id, cube({27.0 + i % 3, 59.0 + i / 3 % 3, 3.0 + i / 9}, 0.05)));
  const uint32_t node = t.nodeOf(0);
  ASSERT_EQ(t.node(node).objects.size(), 27u);
  t.refresh();
  Camera cam = wideCamera();
  cam.heading_deg = 225.0;
  cam.pitch_deg = -std::atan(1.0 / std::sqrt(2.0)) * 180.0 / 3.14159265358979323846;  // along (-1, -1, -1)
  cam.eye_m = t.node(node).bounds.max - glm::dvec3(0.001);
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 10;
  tr.eye_m = cam.eye_m;
  const auto r = t.traverse(makeFrustum(cam), tr, draw, test);
  EXPECT_TRUE(holds(draw, r.drawn, node));
  EXPECT_FALSE(holds(test, r.candidates, node));
}

// A "hidden" result says nothing once the eye is inside the node's box (a box test there says
// nothing): the node is drawn and its objects are not in the estimate.
TEST(DynamicOctree, AHiddenNodeAroundTheEyeIsDrawn) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(5)));
  uint32_t id = 0;
  insertCluster(t, id, {30.0, 60.0, 5.0}, 20);
  const uint32_t node = t.nodeOf(0);
  t.refresh();
  t.setOcclusionResult(node, false, 10);
  Camera cam = wideCamera();
  cam.eye_m = 0.5 * (t.node(node).bounds.min + t.node(node).bounds.max);
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 11;
  tr.eye_m = cam.eye_m;
  for (const bool useOcclusion : {true, false}) {
    tr.useOcclusion = useOcclusion;
    const auto r = t.traverse(makeFrustum(cam), tr, draw, test);
    EXPECT_TRUE(holds(draw, r.drawn, node)) << useOcclusion;
    EXPECT_EQ(r.hiddenObjects, 0u) << useOcclusion;
  }
}

// A hidden node is re-tested every frame, "excluding nodes with a query in flight": while its
// re-test is pending it stays skipped but is not written to `test` again.
TEST(DynamicOctree, AHiddenNodeWithAQueryInFlightIsNotReTested) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(5)));
  uint32_t id = 0;
  insertCluster(t, id, {30.0, 60.0, 5.0}, 20);
  const uint32_t node = t.nodeOf(0);
  t.refresh();
  t.setOcclusionResult(node, false, 10);
  t.setQueryPending(node, true);
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 11;
  tr.useOcclusion = true;
  const auto r = t.traverse(makeFrustum(wideCamera()), tr, draw, test);
  EXPECT_FALSE(holds(draw, r.drawn, node));
  EXPECT_EQ(r.hiddenObjects, 20u);
  EXPECT_EQ(r.retests, 0u);
  EXPECT_FALSE(holds(test, r.candidates, node));
}

// Occlusion culling skips the whole subtree of a hidden node that lies wholly in view: its
// objects are counted from the node's subtree count, its octants are not walked (frustumTests,
// the cull cost of the performance model, counts the node alone). An empty tree costs nothing.
TEST(DynamicOctree, AHiddenSubtreeWhollyInViewIsNotWalked) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(5)));
  uint32_t id = 0;
  insertCluster(t, id, {20.0, 60.0, 5.0}, 20);
  insertCluster(t, id, {28.0, 60.0, 5.0}, 20);  // a sibling leaf (8 m cells) under the same parent
  insertCluster(t, id, {-30.0, 60.0, 5.0}, 20);
  t.refresh();
  uint32_t parent = t.node(t.nodeOf(0)).parent;
  ASSERT_EQ(t.node(parent).subtreeCount, 40u);
  ASSERT_NE(t.nodeOf(0), t.nodeOf(20));
  const Frustum f = makeFrustum(wideCamera());
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 10;
  tr.useOcclusion = true;
  const auto clear = t.traverse(f, tr, draw, test);
  t.setOcclusionResult(parent, false, 10);
  const auto r = t.traverse(f, tr, draw, test);
  EXPECT_EQ(r.hiddenObjects, 40u);
  EXPECT_EQ(r.objectsDrawn, 20u);
  EXPECT_EQ(r.frustumTests, clear.frustumTests - 2);  // the two leaves below it
  DynamicOctree empty;
  ASSERT_TRUE(empty.init(rootConfig(5)));
  EXPECT_EQ(empty.traverse(f, tr, draw, test).frustumTests, 0u);
}

// "An older result does not override a newer one": a result of the same frame is not older, so
// it replaces the last one (hidden then visible in frame 10: visible). The same holds for a
// "visible" result from before a new occluder: it still ends a "hidden" one of its own frame.
TEST(DynamicOctree, AResultOfTheSameFrameReplacesTheLastOne) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(5)));
  uint32_t id = 0;
  insertCluster(t, id, {30.0, 60.0, 5.0}, 20);
  const uint32_t node = t.nodeOf(0);
  t.refresh();
  t.setOcclusionResult(node, false, 10);
  t.setOcclusionResult(node, true, 10);
  EXPECT_FALSE(t.node(node).occluded);
  t.setOcclusionResult(node, false, 10);
  EXPECT_TRUE(t.node(node).occluded);
  t.expireVisibleResults(12);
  t.setOcclusionResult(node, true, 10);  // measured before the occluder, not older than the hidden one
  EXPECT_FALSE(t.node(node).occluded);
}

// expireVisibleResults(frame): "a visible result of a test issued before `frame` is not taken as
// fresh": a later call with an earlier frame does not make such results fresh again.
TEST(DynamicOctree, ExpiringVisibleResultsNeverMovesTheirValidityBack) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(5)));
  uint32_t id = 0;
  insertCluster(t, id, {30.0, 60.0, 5.0}, 20);
  const uint32_t node = t.nodeOf(0);
  t.refresh();
  t.expireVisibleResults(12);
  t.expireVisibleResults(8);
  t.setOcclusionResult(node, true, 10);  // issued before 12: not fresh
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 12;
  const auto r = t.traverse(makeFrustum(wideCamera()), tr, draw, test);
  EXPECT_TRUE(holds(test, r.candidates, node));
}

// clearOcclusion() forgets every result and every query in flight: a node whose query was pending
// is a test candidate again.
TEST(DynamicOctree, ClearOcclusionEndsQueriesInFlight) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(5)));
  uint32_t id = 0;
  insertCluster(t, id, {30.0, 60.0, 5.0}, 20);
  const uint32_t node = t.nodeOf(0);
  t.refresh();
  t.setQueryPending(node, true);
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 10;
  const Frustum f = makeFrustum(wideCamera());
  auto r = t.traverse(f, tr, draw, test);
  ASSERT_FALSE(holds(test, r.candidates, node));
  t.clearOcclusion();
  EXPECT_FALSE(t.node(node).queryPending);
  r = t.traverse(f, tr, draw, test);
  EXPECT_TRUE(holds(test, r.candidates, node));
}

// The estimate counts, under a hidden node partly in view, only the objects in view: the node
// reaches out of the view sideways (its far corner, not its near one, is outside the right-hand
// plane), so its octants are walked; an octant emptied by removals is not (no frustum test, the
// cull cost of the performance model, for it).
TEST(DynamicOctree, AHiddenNodeReachingOutOfTheViewSidewaysCountsOnlyWhatIsInView) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(5)));
  uint32_t id = 0;
  insertCluster(t, id, {20.0, 60.0, 5.0}, 20);   // in view
  insertCluster(t, id, {120.0, 60.0, 5.0}, 20);  // 63 deg to the right: out of the 60.6 deg half-width
  insertCluster(t, id, {20.0, 100.0, 5.0}, 20);  // removed again: its octants stay, empty
  t.refresh();
  for (uint32_t i = 40; i < 60; ++i) ASSERT_TRUE(t.remove(i));
  t.refresh();
  uint32_t node = t.nodeOf(0);
  while (t.node(node).depth > 1) node = t.node(node).parent;
  ASSERT_EQ(t.node(node).subtreeCount, 40u);
  const Frustum f = makeFrustum(wideCamera());
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 10;
  tr.useOcclusion = true;
  const auto clear = t.traverse(f, tr, draw, test);
  ASSERT_EQ(clear.objectsDrawn, 20u);
  t.setOcclusionResult(node, false, 10);
  const auto r = t.traverse(f, tr, draw, test);
  EXPECT_EQ(r.objectsDrawn, 0u);
  EXPECT_EQ(r.hiddenObjects, 20u);
  // Tested: the root, the node, and its two non-empty octants (the one in view lies wholly in
  // it: counted from its subtree count, not walked), not the emptied one.
  EXPECT_EQ(r.frustumTests, 4u);
}

// Node::bounds is documented as the "tight box of the objects of the whole subtree", and
// insert() takes any finite box. refresh() started every box from {+1e300, -1e300} (now
// {+inf, -inf}), so an object whose box lay beyond +-1e300 (finite, accepted) got bounds clamped
// at 1e300: [1e300, 3e300] for an object at [2e300, 3e300] (outside the root cell: in the root).
TEST(DynamicOctree, BoundsAreTightForBoxesBeyondOneE300) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(rootConfig(5)));
  const Aabb far{glm::dvec3(2e300), glm::dvec3(3e300)};
  ASSERT_TRUE(t.insert(0, far));
  t.refresh();
  EXPECT_EQ(t.node(0).bounds.min.x, 2e300);  // is 1e300
  EXPECT_EQ(t.node(0).bounds.max.x, 3e300);
  ASSERT_TRUE(t.move(0, {glm::dvec3(-3e300), glm::dvec3(-2e300)}));
  t.refresh();
  EXPECT_EQ(t.node(0).bounds.min.x, -3e300);
  EXPECT_EQ(t.node(0).bounds.max.x, -2e300);  // is -1e300
}
