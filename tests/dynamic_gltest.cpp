// GL tests of the dynamic-object pass of paper 002 (render/dynamic_pass.h) and the calibration
// cache (render/perf_calibration.h), on a real headless context (llvmpipe).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <sched.h>
#include <unistd.h>

#include "render/context.h"
#include "render/dynamic_pass.h"
#include "render/gl.h"
#include "render/image.h"
#include "render/perf_calibration.h"
#include "render/renderer.h"

using namespace ig;
using render::DynamicObject;
using render::DynamicStrategy;

namespace {

constexpr int kW = 160, kH = 90;

class DynamicGl : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ctx_ = render::createContext(render::ContextKind::Headless, kW, kH, error);
    ASSERT_TRUE(ctx_) << error;
    ASSERT_TRUE(renderer_.init(kW, kH, error)) << error;
    cam_.aspect = static_cast<double>(kW) / kH;
    cam_.near_m = 0.5;
    cam_.far_m = 5000.0;
    light_.fog = false;
  }

  std::unique_ptr<render::DynamicPass> makePass(glm::dvec3 origin = glm::dvec3(0.0), uint32_t capacity = 4096) {
    render::DynamicPassConfig c;
    c.maxObjects = capacity;
    c.bounds = {origin - glm::dvec3(128.0), origin + glm::dvec3(128.0)};
    c.octreeDepth = 6;
    c.maxQueries = 1024;
    c.origin_m = origin;
    auto p = std::make_unique<render::DynamicPass>();
    std::string error;
    EXPECT_TRUE(p->init(c, error)) << error;
    return p;
  }

  // A static scene: random boxes in view, and optionally a wall hiding the left half.
  static std::vector<DynamicObject> scene(bool wall, glm::dvec3 shift = glm::dvec3(0.0)) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0), u01(0.0, 1.0);
    std::vector<DynamicObject> v;
    for (int i = 0; i < 600; ++i) {
      const double y = 40.0 + 60.0 * u01(rng);
      v.push_back({shift + glm::dvec3(0.6 * y * u(rng), y, 0.3 * y * u(rng)), glm::dvec3(0.6 + 0.4 * u01(rng)),
                   90.0 * u(rng), 0xff000000u | (static_cast<uint32_t>(rng()) & 0xffffffu)});
    }
    if (wall) v.push_back({shift + glm::dvec3(-12.0, 25.0, 0.0), {12.0, 0.5, 12.0}, 0.0, 0xff606060u});
    return v;
  }

  // Adaptive with synthetic constants (the decision logic, not this machine's speed):
  // per-object commands cost 2 us, a node range 2 us, a frustum test 20 ns, a test 5 us.
  static render::DynamicPassConfig syntheticAdaptive() {
    render::DynamicPassConfig c;
    c.maxObjects = 20000;
    c.bounds = {glm::dvec3(-128.0), glm::dvec3(128.0)};
    c.switching.minFrames = 2;
    c.constants.tri_ns = 10.0;
    c.constants.frag_ns = 1.0;
    c.constants.command_ns = 2000.0;
    c.constants.rerecord_ns = 50.0;
    c.constants.submit_ns = 2000.0;
    c.constants.cull_ns = 20.0;
    c.constants.occlusionTest_ns = 5000.0;
    return c;
  }

  render::Image frame(render::DynamicPass& p, uint64_t f, bool finish = true) {
    renderer_.beginFrame(cam_, light_);
    p.draw(renderer_, f);
    renderer_.endFrame();
    render::Image img;
    if (finish) {
      renderer_.finish();
      renderer_.readPixels(img);
    }
    EXPECT_EQ(renderer_.errors(), "");
    return img;
  }

  std::unique_ptr<render::GlContext> ctx_;
  render::Renderer renderer_;
  lod::Camera cam_;
  render::Lighting light_;
};

TEST_F(DynamicGl, ThreeStrategiesDrawTheSameImageOfAStaticScene) {
  for (bool wall : {false, true}) {
    std::vector<render::Image> images;
    std::vector<render::DynamicFrameStats> stats;
    for (DynamicStrategy s : {DynamicStrategy::PerCommand, DynamicStrategy::Octree, DynamicStrategy::Occlusion}) {
      auto p = makePass();
      for (const DynamicObject& o : scene(wall)) ASSERT_NE(p->add(o), render::DynamicPass::kNone);
      p->setStrategy(s);
      p->setOcclusionTests(1024);
      render::Image img;
      for (uint64_t f = 1; f <= 6; ++f) img = frame(*p, f);  // occlusion: results of earlier frames
      images.push_back(img);
      stats.push_back(p->stats());
    }
    EXPECT_EQ(stats[0].objectsDrawn, stats[0].objects);  // everything is in view
    EXPECT_GT(stats[1].nodesDrawn, 10u);
    EXPECT_EQ(stats[0].submissions, 1u);
    EXPECT_EQ(stats[1].submissions, stats[1].nodesDrawn);
    EXPECT_LT(render::fractionDifferent(images[0], images[1], 2), 0.002) << "wall " << wall;
    EXPECT_LT(render::fractionDifferent(images[1], images[2], 2), 0.002) << "wall " << wall;
    EXPECT_GT(render::fractionDifferent(images[0], render::Image{images[0].width, images[0].height,
                                                                 std::vector<uint8_t>(images[0].rgba.size(), 0)}, 2),
              0.3);  // something was drawn
    if (wall) {
      EXPECT_GT(stats[2].hiddenEstimate, 100u);  // the wall hides a good part of the boxes
      EXPECT_LT(stats[2].objectsDrawn, stats[1].objectsDrawn);
    } else {
      EXPECT_LT(stats[2].hiddenEstimate, 60u);  // nothing big hides anything
    }
  }
}

// Per-object commands draw every live object whatever ids they hold after removals, re-adds and
// a clear (the pass scans ids up to the largest handed out, not its capacity).
TEST_F(DynamicGl, PerObjectCommandsDrawEveryLiveObjectAfterRemovalsAndClear) {
  auto p = makePass(glm::dvec3(0.0), 100000);
  const std::vector<DynamicObject> all = scene(false);
  std::vector<uint32_t> ids;
  for (size_t i = 0; i < 40; ++i) ids.push_back(p->add(all[i]));
  for (size_t i = 0; i < 40; i += 3) ASSERT_TRUE(p->remove(ids[i]));  // 14 removed, 26 left
  for (size_t i = 40; i < 50; ++i) ASSERT_NE(p->add(all[i]), render::DynamicPass::kNone);  // reuse freed ids
  ASSERT_TRUE(p->remove(ids[38]));  // the largest id not re-used
  p->setStrategy(DynamicStrategy::PerCommand);
  const render::Image perObject = frame(*p, 1);
  EXPECT_EQ(p->stats().objectsDrawn, 35u);
  EXPECT_EQ(p->stats().frustumTests, 35u);
  p->setStrategy(DynamicStrategy::Octree);
  const render::Image nodes = frame(*p, 2);
  EXPECT_EQ(p->stats().objectsDrawn, 35u);
  EXPECT_LT(render::fractionDifferent(perObject, nodes, 2), 0.002);
  p->clear();
  p->setStrategy(DynamicStrategy::PerCommand);
  frame(*p, 3);
  EXPECT_EQ(p->stats().objectsDrawn, 0u);
  for (size_t i = 100; i < 103; ++i) ASSERT_NE(p->add(all[i]), render::DynamicPass::kNone);
  frame(*p, 4);
  EXPECT_EQ(p->stats().objectsDrawn, 3u);
}

// Adaptive starts with per-object commands; on its first frame it also draws one node's range
// and issues one occlusion test (so that their first use, ~1 ms on llvmpipe, does not fall on the
// first switch) and leaves the image exactly as the per-object strategy draws it.
TEST_F(DynamicGl, AdaptiveWarmsUpNodeDrawsAndTestsOnItsFirstFrameWithoutChangingTheImage) {
  render::Image images[2];
  render::DynamicFrameStats stats[2];
  int k = 0;
  for (DynamicStrategy s : {DynamicStrategy::PerCommand, DynamicStrategy::Adaptive}) {
    auto p = makePass();
    for (const DynamicObject& o : scene(true)) ASSERT_NE(p->add(o), render::DynamicPass::kNone);
    p->setStrategy(s);
    images[k] = frame(*p, 1);
    stats[k++] = p->stats();
  }
  ASSERT_EQ(stats[1].mode, lod::DynamicMode::PerCommand);
  EXPECT_EQ(stats[0].occlusionTests, 0u);
  EXPECT_EQ(stats[1].occlusionTests, 1u);
  EXPECT_EQ(stats[1].draws, stats[0].draws + 1);
  EXPECT_EQ(render::fractionDifferent(images[0], images[1], 0), 0.0);
}

TEST_F(DynamicGl, SameImageOneThousandKilometresFromTheOrigin) {
  const glm::dvec3 far(977.0 * 1024.0, -512.0 * 1024.0, 0.0), ecef(4.1e6, -1.0e7, 4.9e6);  // and ~1e7 m
  std::vector<render::Image> images;
  for (glm::dvec3 shift : {glm::dvec3(0.0), far, ecef}) {
    auto p = makePass(shift);
    for (const DynamicObject& o : scene(true, shift)) p->add(o);
    p->setStrategy(DynamicStrategy::Octree);
    cam_.eye_m = shift;
    images.push_back(frame(*p, 1));
  }
  cam_.eye_m = glm::dvec3(0.0);
  EXPECT_LT(render::fractionDifferent(images[0], images[1], 2), 0.002);
  EXPECT_LT(render::fractionDifferent(images[0], images[2], 2), 0.002);
}

// The pass's origin (DynamicPassConfig::origin_m) 170 km from the boxes and the eye (bounds of
// 262 km about it): origin - eye was sent as one float, so that every box moved in its 7.8 mm
// steps as the eye moved. The same boxes drawn with the origin beside them must give the same
// picture, from an eyepoint 0.45 of a float step (1/128 m at 120 km) off the float grid and with
// boxes 3 .. 6 m away in a 5 degree field of view (a float step is a pixel there).
TEST_F(DynamicGl, BoxesFarFromTheOriginArePlacedAsNearIt) {
  const glm::dvec3 base(120000.0, 120000.0, 0.0);
  std::vector<render::Image> images;
  for (const glm::dvec3 origin : {base, glm::dvec3(0.0)}) {
    render::DynamicPassConfig c;
    c.maxObjects = 256;
    c.bounds = {origin - glm::dvec3(131072.0), origin + glm::dvec3(131072.0)};
    c.octreeDepth = 6;
    c.maxQueries = 64;
    c.origin_m = origin;
    render::DynamicPass p;
    std::string error;
    ASSERT_TRUE(p.init(c, error)) << error;
    // Box centres on the 1/128 m grid: floats relative to either origin.
    for (int i = 0; i < 48; ++i) {
      const glm::dvec3 at(0.0625 * (i % 8) - 0.25, 3.0 + 0.0625 * i, 0.0625 * ((i * 5) % 7) - 0.1875);
      ASSERT_NE(p.add({base + at, glm::dvec3(0.015625), 0.0, 0xff000000u | (0x3f1fu * static_cast<uint32_t>(i + 1))}),
                render::DynamicPass::kNone);
    }
    p.setStrategy(DynamicStrategy::PerCommand);
    cam_.eye_m = base + glm::dvec3(0.45 / 128.0, 0.45 / 128.0, 0.45 / 128.0);
    cam_.fovY_deg = 5.0;
    images.push_back(frame(p, 1));
  }
  cam_ = lod::Camera{};
  EXPECT_LT(render::rmse(images[0], images[1]), 0.1);
  EXPECT_LT(render::fractionDifferent(images[0], images[1], 2), 0.0005);
  // Not vacuous: boxes and background.
  render::Image flat = images[0];
  for (size_t i = 4; i < flat.rgba.size(); ++i) flat.rgba[i] = flat.rgba[i % 4];
  EXPECT_GT(render::rmse(images[0], flat), 10.0);
}

// A failed init (here: bounds that are not finite) leaves the pass as it was. It replaced the
// configuration first: the pass kept its buffers for 64 objects but placed the node commands
// and instance blocks after 4,096, beyond them (GL_INVALID_OPERATION, nothing drawn; writes
// past the mapped buffers once a node changes).
TEST_F(DynamicGl, AFailedInitLeavesThePassAsItWas) {
  auto p = makePass(glm::dvec3(0.0), 1024);
  for (const DynamicObject& o : scene(false)) ASSERT_NE(p->add(o), render::DynamicPass::kNone);
  p->setStrategy(DynamicStrategy::Octree);
  const render::Image before = frame(*p, 1);
  const uint32_t drawn = p->stats().objectsDrawn;
  ASSERT_GT(drawn, 500u);
  render::DynamicPassConfig bad = p->config();
  bad.maxObjects = 4096;
  bad.bounds.max.x = std::nan("");
  std::string error;
  EXPECT_FALSE(p->init(bad, error));
  EXPECT_NE(error.find("bounds"), std::string::npos) << error;
  EXPECT_EQ(p->config().maxObjects, 1024u);
  const render::Image after = frame(*p, 2);  // expects no GL errors
  EXPECT_EQ(p->stats().objectsDrawn, drawn);
  EXPECT_LT(render::fractionDifferent(before, after, 0), 1e-9);
}

TEST_F(DynamicGl, MovingAnObjectRebuildsOnlyItsNodes) {
  auto p = makePass();
  std::vector<DynamicObject> objs = scene(false);
  for (const DynamicObject& o : objs) p->add(o);
  p->setStrategy(DynamicStrategy::Octree);
  frame(*p, 1);
  EXPECT_GT(p->stats().dirtyNodes, 10u);  // first frame: every node is built
  frame(*p, 2);
  EXPECT_EQ(p->stats().dirtyNodes, 0u);   // nothing changed: nothing rebuilt
  EXPECT_EQ(p->stats().rerecorded, 0u);
  // Within its octant (a 1 cm nudge keeps it in the same leaf or the same parent).
  const uint32_t id = 5;
  const uint32_t before = p->octree().nodeOf(id);
  DynamicObject o = objs[id];
  o.center_m.z += 0.01;
  ASSERT_TRUE(p->set(id, o));
  ASSERT_EQ(p->octree().nodeOf(id), before);
  frame(*p, 3);
  EXPECT_EQ(p->stats().dirtyNodes, 1u);
  EXPECT_EQ(p->stats().rerecorded, p->octree().node(before).objects.size());
  // Across octants: to the other side of the scene.
  o.center_m = {-o.center_m.x, o.center_m.y + 5.0, -o.center_m.z};
  ASSERT_TRUE(p->set(id, o));
  const uint32_t after = p->octree().nodeOf(id);
  ASSERT_NE(after, before);
  frame(*p, 4);
  EXPECT_EQ(p->stats().dirtyNodes, 2u);
  EXPECT_EQ(p->stats().rerecorded, p->octree().node(before).objects.size() + p->octree().node(after).objects.size());
  EXPECT_TRUE(p->octree().checkInvariant());
  // Per-object commands are rebuilt every frame whatever moved.
  p->setStrategy(DynamicStrategy::PerCommand);
  frame(*p, 5);
  EXPECT_EQ(p->stats().commands, p->stats().objectsDrawn);
  // Bad input is refused and leaves the object where it was.
  DynamicObject bad = o;
  bad.center_m.x = std::nan("");
  EXPECT_FALSE(p->set(id, bad));
  bad = o;
  bad.halfSize_m.y = -1.0;
  EXPECT_EQ(p->add(bad), render::DynamicPass::kNone);
  EXPECT_EQ(p->octree().nodeOf(id), after);
}

TEST_F(DynamicGl, OcclusionResultsAreReadOnlyFramesLaterAndNeverWaitedOn) {
  auto p = makePass();
  for (const DynamicObject& o : scene(true)) p->add(o);
  p->setStrategy(DynamicStrategy::Occlusion);
  p->setOcclusionTests(200);
  frame(*p, 1, /*finish=*/false);
  const uint32_t issued = p->stats().occlusionTests;
  EXPECT_GT(issued, 20u);
  EXPECT_EQ(p->stats().resultsRead, 0u);  // nothing is read in the frame that issued it
  EXPECT_EQ(p->stats().queriesPending, issued);
  renderer_.finish();
  frame(*p, 2);
  EXPECT_EQ(p->stats().resultsRead, issued);  // finished: all available, all read
  EXPECT_EQ(p->blockingReads(), 0u);
  // The camera inside a node's box: that node is never tested (a box test says nothing there).
  cam_.eye_m = p->octree().node(p->octree().nodeOf(0)).bounds.min + glm::dvec3(0.01);
  for (uint64_t f = 3; f < 6; ++f) frame(*p, f);
  cam_.eye_m = glm::dvec3(0.0);
}

// An object that moves into a node found hidden, to a place that is in view, is drawn on the frame
// it arrives: the node's "hidden" result was measured on its old (smaller) box and says nothing
// about the new one. (It was skipped with the node until the re-test's result came back.)
TEST_F(DynamicGl, AnObjectMovedIntoAHiddenNodeWhereItIsVisibleIsDrawnAtOnce) {
  render::DynamicPassConfig c;
  c.maxObjects = 256;
  c.bounds = {glm::dvec3(-128.0), glm::dvec3(128.0)};
  c.octreeDepth = 3;  // leaves of 32 m
  c.maxQueries = 256;
  render::DynamicPass p;
  std::string error;
  ASSERT_TRUE(p.init(c, error)) << error;
  // A wall hiding x/y < 0.256 (straddles x = 0: in the root), a cluster behind it in the leaf
  // [0, 32] x [32, 64] x [0, 32], and a red box in view to the left.
  p.add({{-2.5, 20.0, 0.0}, {7.5, 0.5, 10.0}, 0.0, 0xff606060u});
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  uint32_t cluster = render::DynamicPass::kNone;
  for (int i = 0; i < 20; ++i)
    cluster = p.add({{3.0 + 4.0 * u01(rng), 46.0 + 8.0 * u01(rng), 2.0 + 5.0 * u01(rng)}, glm::dvec3(0.3), 0.0, 0xff00ff00u});
  DynamicObject red{{-32.0, 50.0, 6.0}, glm::dvec3(2.0), 0.0, 0xff0000ffu};
  const uint32_t id = p.add(red);
  ASSERT_NE(id, render::DynamicPass::kNone);
  p.setStrategy(DynamicStrategy::Occlusion);
  p.setOcclusionTests(256);
  const auto redPixels = [](const render::Image& img) {
    int n = 0;
    for (size_t i = 0; i + 3 < img.rgba.size(); i += 4) n += img.rgba[i] > 40 && img.rgba[i] > 3 * img.rgba[i + 1] + 10 && img.rgba[i] > 3 * img.rgba[i + 2] + 10;
    return n;
  };
  render::Image img;
  for (uint64_t f = 1; f <= 4; ++f) img = frame(p, f);
  const uint32_t leaf = p.octree().nodeOf(cluster);
  ASSERT_TRUE(p.octree().node(leaf).occluded) << "the wall hides the cluster's node";
  ASSERT_GT(redPixels(img), 20);
  // Into the cluster's leaf, still in view (x/y > 0.34).
  red.center_m = {20.0, 50.0, 6.0};
  ASSERT_TRUE(p.set(id, red));
  ASSERT_EQ(p.octree().nodeOf(id), leaf);
  img = frame(p, 5);
  EXPECT_EQ(p.stats().objectsDrawn, 22u);  // the wall, the cluster (its node is tested again), the red box
  EXPECT_GT(redPixels(img), 20) << "the moved box vanished for a frame";
  img = frame(p, 6);
  EXPECT_GT(redPixels(img), 20);
}

// A node whose objects cover its bounding box's visible faces (axis-aligned boxes packed into a
// block: crates on a pallet, stacked containers) is not hidden by itself: its query box is drawn
// after its objects, on the same planes, and with the depth test GL_GREATER a box face exactly on
// an object's face passes no sample. The block vanished for a frame each time its node was tested
// (frame 2, then every resultMaxAge + 2 frames).
TEST_F(DynamicGl, ANodeIsNotHiddenByItsOwnObjectsOnItsBoxFaces) {
  for (const glm::dvec3 shift : {glm::dvec3(0.0), glm::dvec3(0.3, 0.0, 0.0), glm::dvec3(977.0 * 1024.0, -512.0 * 1024.0, 0.0)}) {
    auto p = makePass(shift.x > 1.0 ? shift : glm::dvec3(0.0));
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 2; ++j)
        for (int k = 0; k < 3; ++k) p->add({shift + glm::dvec3(0.5 + i, 48.5 + j, 0.5 + k), glm::dvec3(0.5), 0.0, 0xff00ff00u});
    p->setStrategy(DynamicStrategy::Occlusion);
    p->setOcclusionTests(256);
    cam_.eye_m = shift.x > 1.0 ? shift : glm::dvec3(0.0);
    uint32_t tests = 0;
    for (uint64_t f = 1; f <= 24; ++f) {
      frame(*p, f);
      tests += p->stats().occlusionTests;
      ASSERT_EQ(p->stats().objectsDrawn, 18u) << "frame " << f << ", shift x " << shift.x;
    }
    EXPECT_GE(tests, 3u);  // the node was tested, and more than once
  }
  cam_.eye_m = glm::dvec3(0.0);
}

TEST_F(DynamicGl, AdaptiveStartsWithPerObjectCommandsAndMovesToTheOctreeAsObjectsAreAdded) {
  render::DynamicPass p;
  std::string error;
  ASSERT_TRUE(p.init(syntheticAdaptive(), error)) << error;
  p.setStrategy(DynamicStrategy::Adaptive);
  p.add({{0.0, 50.0, 0.0}, glm::dvec3(1.0), 0.0, 0xffffffffu});
  for (uint64_t f = 1; f < 12; ++f) frame(p, f, false), renderer_.finish();
  EXPECT_EQ(p.stats().mode, lod::DynamicMode::PerCommand);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  // A dense cluster: a few octree nodes hold thousands of objects.
  for (int i = 0; i < 5000; ++i) p.add({{3.0 * u(rng), 50.0 + 3.0 * u(rng), 3.0 * u(rng)}, glm::dvec3(0.05), 0.0, 0xffffffffu});
  for (uint64_t f = 12; f < 20; ++f) frame(p, f, false), renderer_.finish();
  EXPECT_NE(p.stats().mode, lod::DynamicMode::PerCommand);
  EXPECT_GE(p.modeSwitches(), 1u);
}

// Octree mode estimates the hidden objects with a few tests; while they find nothing and nothing
// changes that could hide objects, the estimate runs every 2nd, 4th, then 8th frame. A large
// object appearing in front of the camera brings it back at once, with every candidate node
// tested on that frame, and the pass turns to occlusion culling within a few frames.
TEST_F(DynamicGl, AdaptiveEstimatesHiddenObjectsLessOftenUntilAnOccluderAppears) {
  render::DynamicPass p;
  std::string error;
  ASSERT_TRUE(p.init(syntheticAdaptive(), error)) << error;
  p.setStrategy(DynamicStrategy::Adaptive);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 5000; ++i) p.add({{3.0 * u(rng), 50.0 + 3.0 * u(rng), 3.0 * u(rng)}, glm::dvec3(0.05), 0.0, 0xffffffffu});
  uint64_t f = 1;
  for (; f < 20; ++f) {
    frame(p, f, false);
    renderer_.finish();
  }
  ASSERT_EQ(p.stats().mode, lod::DynamicMode::Octree);
  int estimates = 0;
  for (int i = 0; i < 48; ++i, ++f) {
    frame(p, f, false);
    renderer_.finish();
    ASSERT_EQ(p.stats().mode, lod::DynamicMode::Octree);
    ASSERT_EQ(p.stats().hiddenEstimate, 0u);
    estimates += p.stats().occlusionTests > 0;
  }
  EXPECT_GE(estimates, 48 / 8);
  EXPECT_LE(estimates, 48 / 8 + 2);
  // A turn of the view: the next frame estimates again.
  cam_.heading_deg = 5.0;
  frame(p, f++, false), renderer_.finish();
  ASSERT_EQ(p.stats().mode, lod::DynamicMode::Octree);
  EXPECT_GT(p.stats().occlusionTests, 0u);
  int later = 0;
  for (int i = 0; i < 16; ++i, ++f) {
    frame(p, f, false);
    renderer_.finish();
    later += p.stats().occlusionTests > 0;
  }
  EXPECT_LT(later, 16);
  // A wall in front of the cluster: so does the next frame after it appears.
  int before = 0;
  uint32_t sampled = 0;  // tests of one estimate
  for (int i = 0; i < 16; ++i, ++f) {
    frame(p, f, false);
    renderer_.finish();
    before += p.stats().occlusionTests > 0;
    sampled = std::max(sampled, p.stats().occlusionTests);
  }
  EXPECT_LE(before, 3);  // backed off to every 8th frame
  ASSERT_GT(sampled, 0u);
  p.add({{0.0, 25.0, 0.0}, {12.0, 0.5, 12.0}, 0.0, 0xff606060u});
  frame(p, f++, false), renderer_.finish();
  // The frame the wall appears tests every candidate node, not the estimate's sample.
  EXPECT_GT(p.stats().occlusionTests, 2 * sampled);
  // So the next frame knows what the wall hides, and the pass moves to occlusion culling.
  frame(p, f++, false), renderer_.finish();
  EXPECT_GT(p.stats().hiddenEstimate, 2500u);
  bool culling = false;
  for (int i = 0; i < 4 && !culling; ++i, ++f) {
    frame(p, f, false);
    renderer_.finish();
    culling = p.stats().mode == lod::DynamicMode::Occlusion;
  }
  EXPECT_TRUE(culling);
  cam_.heading_deg = 0.0;
}

// A large object that moves every frame but hides nothing: the burst of tests an occluder
// brings (every candidate node) comes at most once per resultMaxAge frames, not every frame.
TEST_F(DynamicGl, AdaptiveTestsEverythingAtMostOncePerResultAgeForAMovingLargeObject) {
  render::DynamicPass p;
  std::string error;
  const render::DynamicPassConfig config = syntheticAdaptive();
  ASSERT_TRUE(p.init(config, error)) << error;
  p.setStrategy(DynamicStrategy::Adaptive);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 5000; ++i) p.add({{3.0 * u(rng), 50.0 + 3.0 * u(rng), 3.0 * u(rng)}, glm::dvec3(0.05), 0.0, 0xffffffffu});
  uint64_t f = 1;
  uint32_t sampled = 0;  // the largest estimate before the large object
  for (; f < 40; ++f) {
    frame(p, f, false);
    renderer_.finish();
    if (f > 20) sampled = std::max(sampled, p.stats().occlusionTests);
  }
  ASSERT_EQ(p.stats().mode, lod::DynamicMode::Octree);
  ASSERT_GT(sampled, 0u);
  // In view, to the left of the cluster, seen under ~0.14 rad.
  render::DynamicObject big{{-20.0, 30.0, 0.0}, glm::dvec3(3.0), 0.0, 0xff808080u};
  const uint32_t id = p.add(big);
  int bursts = 0;
  const int frames = 4 * static_cast<int>(config.resultMaxAge);
  for (int i = 0; i < frames; ++i, ++f) {
    big.center_m.z = 0.1 * (i % 2);
    ASSERT_TRUE(p.set(id, big));
    frame(p, f, false);
    renderer_.finish();
    ASSERT_EQ(p.stats().mode, lod::DynamicMode::Octree);  // it hides nothing
    bursts += p.stats().occlusionTests > 2 * sampled;
  }
  EXPECT_GE(bursts, 1);
  EXPECT_LE(bursts, frames / static_cast<int>(config.resultMaxAge) + 1);
}

// ---- calibration cache ---------------------------------------------------------------------

std::string tempPath(const char* name) { return "/tmp/igd_dyn_" + std::to_string(getpid()) + "_" + name; }

TEST_F(DynamicGl, CalibrationCacheRoundTripsAndRejectsCorruptFiles) {
  lod::PerfConstants c;
  c.frame_ns = 120000.5;
  c.tri_ns = 33.25;
  c.frag_ns = 1.125;
  c.depthFrag_ns = 0.5;
  c.state_ns = 900;
  c.command_ns = 1500;
  c.rerecord_ns = 40;
  c.submit_ns = 2500;
  c.cull_ns = 6.5;
  c.occlusionTest_ns = 7000;
  c.overlap = 0.25;
  c.overlapTriangles = 250000;
  c.rasterTri_ns = 3.5;
  c.edge_ns = 150.5;
  c.drawRaster_ns = 210.25;
  c.commandCount = 20000;
  c.commandLarge_ns = 310.5;
  c.commandLargeCount = 135000;
  c.triByDraw_ns = {80.5, 70, 66, 62, 58, 55, 33.25};
  const std::string path = tempPath("cache.txt"), key = "vendor|renderer|4.5|work=0|64x64";
  std::string error, why;
  ASSERT_TRUE(render::writeCalibrationCache(path, key, c, error)) << error;
  lod::PerfConstants r;
  ASSERT_TRUE(render::readCalibrationCache(path, key, r, why)) << why;
  EXPECT_DOUBLE_EQ(r.frame_ns, c.frame_ns);
  EXPECT_DOUBLE_EQ(r.tri_ns, c.tri_ns);
  EXPECT_DOUBLE_EQ(r.overlap, c.overlap);
  EXPECT_DOUBLE_EQ(r.occlusionTest_ns, c.occlusionTest_ns);
  EXPECT_DOUBLE_EQ(r.overlapTriangles, c.overlapTriangles);
  EXPECT_DOUBLE_EQ(r.rasterTri_ns, c.rasterTri_ns);
  EXPECT_DOUBLE_EQ(r.edge_ns, c.edge_ns);
  EXPECT_DOUBLE_EQ(r.drawRaster_ns, c.drawRaster_ns);
  EXPECT_DOUBLE_EQ(r.commandCount, c.commandCount);
  EXPECT_DOUBLE_EQ(r.commandLarge_ns, c.commandLarge_ns);
  EXPECT_DOUBLE_EQ(r.commandLargeCount, c.commandLargeCount);
  for (size_t i = 0; i < c.triByDraw_ns.size(); ++i) EXPECT_DOUBLE_EQ(r.triByDraw_ns[i], c.triByDraw_ns[i]) << i;
  EXPECT_FALSE(render::readCalibrationCache(path, "other|device", r, why));
  EXPECT_NE(why.find("key"), std::string::npos) << why;
  std::string text;
  {
    std::ifstream in(path);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  const auto corrupt = [&](const std::string& from, const std::string& to) {
    std::string t = text;
    const size_t at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    t.replace(at, from.size(), to);
    std::ofstream(path, std::ios::trunc) << t;
    lod::PerfConstants x;
    std::string w;
    EXPECT_FALSE(render::readCalibrationCache(path, key, x, w)) << "accepted " << to;
    EXPECT_NE(w.find(path), std::string::npos) << w;
    return w;
  };
  EXPECT_NE(corrupt("tri_ns 33.25", "tri_ns nan").find("tri_ns"), std::string::npos);
  corrupt("tri_ns 33.25", "tri_ns -4");
  corrupt("tri_ns 33.25", "tri_ns 33.25x");
  corrupt("tri_ns 33.25\n", "");                 // missing
  corrupt("cull_ns", "cull_ms");                 // unknown field
  corrupt("version 10", "version 11");
  corrupt("version 10", "version 1");             // an older calibration (heap not settled)
  corrupt("version 10", "version 2");             // an older model (frag_block_px, no rasterizer terms)
  corrupt("version 10", "version 3");             // one T_tri for every draw size, no binning term
  corrupt("version 10", "version 4");             // no per-draw rasterizer cost (in raster_tri_ns)
  corrupt("version 10", "version 5");             // the overlap fitted with every box rasterized
  corrupt("version 10", "version 6");             // T_edge from the rasterizer's side only
  corrupt("version 10", "version 7");             // T_tri by call size from leaves of mixed counts
  corrupt("version 10", "version 8");             // the overlap as the median of the runs' own fits
  corrupt("version 10", "version 9");             // each load timed after another load's frame
  EXPECT_NE(corrupt("draw_raster_ns 210.25\n", "").find("draw_raster_ns"), std::string::npos);  // missing
  corrupt("draw_raster_ns 210.25", "draw_raster_ns -3");
  EXPECT_NE(corrupt("tri_ns_96 62\n", "").find("tri_ns_96 missing"), std::string::npos);
  corrupt("tri_ns_24 70", "tri_ns_24 inf");
  corrupt("tri_ns_24 70", "tri_ns_24 70\ntri_ns_24 71");  // repeated
  corrupt("command_large_ns 310.5\n", "");  // missing
  corrupt("overlap 0.25", "overlap 3");          // out of range
  corrupt("overlap_triangles 250000", "overlap_triangles -1");
  corrupt("frag_ns 1.125", "frag_ns 1.125\nfrag_ns 2");  // repeated
  std::ofstream(path, std::ios::trunc) << text.substr(0, text.size() / 2);  // truncated
  EXPECT_FALSE(render::readCalibrationCache(path, key, r, why));
  std::remove(path.c_str());
  EXPECT_FALSE(render::readCalibrationCache(path, key, r, why));  // absent
}

// The loads of T_tri by the size of a call: k boxes in each of 900 leaves, one instanced call of
// k boxes per leaf, which is what the fit divides by (900 calls of 12 k triangles). A lattice
// that reaches past its 2 m leaf moves a quarter of each row into the next leaf: up to 1,885
// calls of mixed sizes.
TEST_F(DynamicGl, CalibrationGridKeepsEveryBoxOfALeafInThatLeaf) {
  for (int perNode : {1, 2, 4, 16, 64}) {
    render::DynamicPassConfig c;
    c.maxObjects = 900u * static_cast<uint32_t>(perNode);
    c.octreeDepth = 6;
    c.bounds = {glm::dvec3(-64.0), glm::dvec3(64.0)};
    render::DynamicPass pass;
    std::string error;
    ASSERT_TRUE(pass.init(c, error)) << error;
    render::addCalibrationGrid(pass, 900, perNode);
    EXPECT_EQ(pass.objectCount(), 900u * static_cast<uint32_t>(perNode));
    EXPECT_EQ(pass.octree().nonEmptyNodes(), 900u) << perNode << " boxes a leaf";
    size_t wrong = 0;
    for (const auto& n : pass.octree().nodes())
      if (!n.objects.empty() && (n.objects.size() != static_cast<size_t>(perNode) || n.depth != 6)) ++wrong;
    EXPECT_EQ(wrong, 0u) << perNode << " boxes a leaf";
  }
}

TEST_F(DynamicGl, CalibrateUsesAMatchingCacheAndRewritesACorruptOne) {
  const std::string path = tempPath("cal.txt");
  render::CalibrationOptions o;
  o.width_px = 64;
  o.height_px = 64;
  o.budget_s = 0.2;
  render::CalibrationResult r;
  std::string error;
  std::ofstream(path, std::ios::trunc) << "version 1\nkey garbage\ntri_ns x\n";
  ASSERT_TRUE(render::calibrate(path, o, r, error)) << error;
  EXPECT_FALSE(r.fromCache);
  EXPECT_TRUE(lod::valid(r.constants));
  EXPECT_EQ(r.key, render::calibrationKey(o));
  lod::PerfConstants cached;
  std::string why;
  ASSERT_TRUE(render::readCalibrationCache(path, r.key, cached, why)) << why;  // rewritten
  render::CalibrationResult again;
  ASSERT_TRUE(render::calibrate(path, o, again, error)) << error;
  EXPECT_TRUE(again.fromCache);
  EXPECT_DOUBLE_EQ(again.constants.tri_ns, cached.tri_ns);
  // Another material is another key: the cache does not match it (calibrate would measure).
  o.fragmentWork = 4;
  EXPECT_NE(render::calibrationKey(o), r.key);
  EXPECT_FALSE(render::readCalibrationCache(path, render::calibrationKey(o), cached, why));
  // So is another CPU set or llvmpipe thread count (the same GL strings on a resized VM).
  o.fragmentWork = 0;
  EXPECT_EQ(render::calibrationKey(o), r.key);
  cpu_set_t all, one;
  ASSERT_EQ(sched_getaffinity(0, sizeof all, &all), 0);
  CPU_ZERO(&one);
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (CPU_ISSET(c, &all)) {
      CPU_SET(c, &one);
      break;
    }
  }
  ASSERT_EQ(sched_setaffinity(0, sizeof one, &one), 0);
  const std::string oneCpu = render::calibrationKey(o);
  ASSERT_EQ(sched_setaffinity(0, sizeof all, &all), 0);
  if (CPU_COUNT(&all) > 1) {
    EXPECT_NE(oneCpu, r.key);
  }
  const char* lp = std::getenv("LP_NUM_THREADS");
  const std::string lpBefore = lp != nullptr ? lp : "";
  setenv("LP_NUM_THREADS", lpBefore == "1" ? "2" : "1", 1);
  EXPECT_NE(render::calibrationKey(o), r.key);
  if (lp != nullptr) setenv("LP_NUM_THREADS", lpBefore.c_str(), 1);
  else unsetenv("LP_NUM_THREADS");
  EXPECT_NE(r.key.find("|cpu="), std::string::npos) << r.key;
  o.budget_s = std::nan("");
  EXPECT_FALSE(render::calibrate(path, o, again, error));
  EXPECT_NE(error.find("budget"), std::string::npos) << error;
  std::remove(path.c_str());
}

// CalibrationOptions::afterRun: called once after each run's measurements, in order, and only
// when the calibration measures (igbench perfmodel draws its sweeps there); false stops the
// calibration with its error; its time is not the calibration's.
TEST_F(DynamicGl, CalibrateCallsAfterRunBetweenItsRuns) {
  const std::string path = tempPath("after.txt");
  std::remove(path.c_str());
  render::CalibrationOptions o;
  o.width_px = 64;
  o.height_px = 64;
  o.budget_s = 0.2;
  o.runs = 2;
  std::vector<render::CalibrationFrame> frames;
  o.trace = &frames;
  std::vector<int> calls;
  std::vector<size_t> framesBefore;  // trace frames measured before each call
  double hook_s = 0.0;               // time spent in the calls
  o.afterRun = [&](int run, std::string&) {
    const auto h0 = std::chrono::steady_clock::now();
    calls.push_back(run);
    framesBefore.push_back(frames.size());
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    hook_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - h0).count();
    return true;
  };
  render::CalibrationResult r;
  std::string error;
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(render::calibrate(path, o, r, error)) << error;
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_FALSE(r.fromCache);
  EXPECT_EQ(calls, (std::vector<int>{0, 1}));
  ASSERT_EQ(framesBefore.size(), 2u);
  // Each call comes after its run's frames and before the next run's.
  for (size_t i = 0; i < 2; ++i) {
    ASSERT_GT(framesBefore[i], 0u);
    EXPECT_EQ(frames[framesBefore[i] - 1].run, static_cast<int>(i));
    if (i + 1 < 2) {
      ASSERT_LT(framesBefore[i], frames.size());
      EXPECT_EQ(frames[framesBefore[i]].run, static_cast<int>(i + 1));
    }
  }
  EXPECT_EQ(framesBefore.back(), frames.size());
  EXPECT_LE(r.seconds, wall_s - 0.55) << "the 0.6 s in afterRun counted as measuring";
  EXPECT_GE(r.seconds, wall_s - hook_s - 0.1) << "more than afterRun's time taken out";
  EXPECT_GT(r.seconds, 0.0);
  // From the cache: no runs, no calls.
  calls.clear();
  ASSERT_TRUE(render::calibrate(path, o, r, error)) << error;
  EXPECT_TRUE(r.fromCache);
  EXPECT_TRUE(calls.empty());
  // A failing hook stops the calibration with its error (and writes no cache).
  std::remove(path.c_str());
  o.afterRun = [&](int run, std::string& e) {
    calls.push_back(run);
    e = "sweep failed";
    return false;
  };
  EXPECT_FALSE(render::calibrate(path, o, r, error));
  EXPECT_EQ(error, "sweep failed");
  EXPECT_EQ(calls, (std::vector<int>{0}));
  lod::PerfConstants cached;
  std::string why;
  EXPECT_FALSE(render::readCalibrationCache(path, r.key, cached, why));
  std::remove(path.c_str());
}

}  // namespace

// calibrate() with runs > 1 takes each constant's median over the runs. Of an even count it took
// the upper middle, v[n / 2]: of two runs the slower (on a shared machine the one a slow phase
// covered, which the median is there to leave out), unlike the nearest-rank p50 of the rest of
// the project (ig::percentile: the lower middle).
TEST(Calibration, TheMedianOfTheRunsIsTheNearestRankLowerMiddle) {
  EXPECT_DOUBLE_EQ(render::medianOfRuns({2.0, 1.0}), 1.0);
  EXPECT_DOUBLE_EQ(render::medianOfRuns({4.0, 1.0, 3.0, 2.0}), 2.0);
  EXPECT_DOUBLE_EQ(render::medianOfRuns({3.0, 1.0, 2.0}), 2.0);
  EXPECT_DOUBLE_EQ(render::medianOfRuns({7.0}), 7.0);
  EXPECT_DOUBLE_EQ(render::medianOfRuns({}), 0.0);
}
