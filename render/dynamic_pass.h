// Dynamic objects of paper 002 (adaptive rendering of dynamic scenes; ../shared/SEEDS.md
// section 002): boxes with a per-object matrix and colour, drawn with one of three strategies
//   PerCommand - every frame each object is frustum-tested and, if visible, its instance data
//                and one indirect draw command are written again; one glMultiDrawElementsIndirect
//                submits them (the "command buffer re-recorded every frame").
//   Octree     - a single-reference octree (lod/dynamic_octree.h); each node owns a block of
//                instance slots and a pre-built indirect command (its "secondary command
//                buffer"); only nodes whose objects changed are rewritten; visible nodes (node
//                frustum culling) are submitted with one glMultiDrawElementsIndirect each.
//   Occlusion  - Octree plus GL_ANY_SAMPLES_PASSED_CONSERVATIVE queries on the bounding boxes of
//                q nodes after the frame's geometry; a result is read only once
//                GL_QUERY_RESULT_AVAILABLE says so, one or more frames later (never a stall), and
//                nodes found hidden are skipped (with their subtree) until a newer result.
//   Adaptive   - picks one of the three each frame by conditions (5) and (6) with hysteresis
//                (lod/perfmodel.h) and the number of tests q by equation (11) from c(q), s(q),
//                e(q) fitted online.
// All strategies use the same program, box mesh and instance layout, so they draw the same
// image (occlusion: once results have arrived, hidden nodes are hidden anyway).
//
// Drawing is camera-relative: instance positions are stored relative to `origin_m` in float and
// the eye offset is computed in double each frame. Instance and command buffers are mapped
// persistently; like Renderer's terrain mesh they are rewritten between frames without fences,
// which is safe because every frame ends with glFinish (Renderer::finish()).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/dynamic_octree.h"
#include "lod/perfmodel.h"
#include "lod/view.h"

namespace ig::render {

class Renderer;

enum class DynamicStrategy : uint8_t { PerCommand, Octree, Occlusion, Adaptive };
const char* strategyName(DynamicStrategy s);

struct DynamicObject {
  glm::dvec3 center_m{0.0};     // world (ENU)
  glm::dvec3 halfSize_m{0.5};   // half extents along the box's own axes
  double yaw_deg = 0.0;         // rotation about the vertical axis
  uint32_t rgba = 0xffffffffu;  // colour, R in the low byte
};

struct DynamicPassConfig {
  uint32_t maxObjects = 1 << 16;     // capacity (buffers are sized once)
  lod::Aabb bounds{glm::dvec3(-1000.0), glm::dvec3(1000.0)};  // octree root cell
  uint32_t octreeDepth = 6;
  uint32_t maxQueries = 4096;        // occlusion query pool
  uint32_t estimatorTests = 4;       // Adaptive, Octree mode: at least this many tests per frame for
                                     // the hidden estimate (more, up to 5 % of the predicted frame)
  uint32_t fragmentWork = 0;         // material cost: extra shading iterations per fragment
  uint32_t testMinObjects = 8;       // nodes with fewer objects below them are not tested
  uint32_t resultMaxAge = 8;         // frames an occlusion result stays valid
  glm::dvec3 origin_m{0.0};          // instance positions are stored relative to this
  lod::PerfConstants constants;      // Adaptive: the calibrated model (render/perf_calibration.h)
  lod::ModeSwitchConfig switching;   // Adaptive: hysteresis
};

// What one draw() did: the statistics of (2), (7) and (8)-(10).
struct DynamicFrameStats {
  lod::DynamicMode mode = lod::DynamicMode::PerCommand;
  uint32_t objects = 0;           // objects in the scene
  uint32_t objectsDrawn = 0;      // objects submitted (visible by frustum / occlusion state)
  uint32_t commands = 0;          // draw commands issued: one per visible object (PerCommand),
                                  // one per drawn node range (octree modes: all objects are boxes)
  uint32_t rerecorded = 0;        // objects rewritten into the ranges of dirty nodes
  uint32_t submissions = 0;       // glMultiDrawElementsIndirect calls
  uint32_t draws = 0;             // draw set-ups executed (sub-draws of the indirect calls)
  uint32_t frustumTests = 0;      // object or node boxes tested against the frustum
  uint32_t nodesDrawn = 0;
  uint32_t dirtyNodes = 0;        // node command ranges rebuilt
  uint32_t occlusionTests = 0;    // queries issued this frame (q)
  uint32_t resultsRead = 0;       // query results read this frame (all issued in earlier frames)
  uint32_t queriesPending = 0;    // queries in flight after this frame
  uint64_t hiddenEstimate = 0;    // objects under nodes found occluded (skipped in Occlusion mode; in the
                                  // other modes the estimate of what culling would skip)
  uint64_t triangles = 0;
  uint32_t nonEmptyNodes = 0;     // n0
  double predicted_ns = 0.0;      // Adaptive: the model's T(S), everything in the visible nodes drawn ((6) left)
};

class DynamicPass {
 public:
  static constexpr uint32_t kNone = 0xffffffffu;
  DynamicPass();
  ~DynamicPass();
  DynamicPass(const DynamicPass&) = delete;
  DynamicPass& operator=(const DynamicPass&) = delete;

  // Creates the program, mesh and buffers. A GL context must be current.
  bool init(const DynamicPassConfig& config, std::string& error);
  const DynamicPassConfig& config() const { return config_; }

  // Scene edits (between frames). add returns the object id, kNone when full or the object is
  // invalid (NaN, negative size). set moves / recolours; remove frees the id.
  uint32_t add(const DynamicObject& o);
  bool set(uint32_t id, const DynamicObject& o);
  bool remove(uint32_t id);
  uint32_t objectCount() const { return octree_.objectCount(); }
  void clear();

  void setStrategy(DynamicStrategy s);
  DynamicStrategy strategy() const { return strategy_; }
  // Occlusion strategy: tests per frame (Adaptive chooses its own).
  void setOcclusionTests(uint32_t q) { fixedQ_ = q; }
  void setConstants(const lod::PerfConstants& c) { config_.constants = c; }
  // Count the samples that pass the depth test (GL_SAMPLES_PASSED) in every frame, not only in
  // Adaptive (which always does); read back frames later, never waiting.
  void setMeasureSamples(bool on) { measureSamples_ = on; }
  // The last samples-passed count that has arrived (0 before the first).
  uint64_t samplesPassed() const { return lastSamples_; }

  // Draws every object with the current strategy; call between Renderer::beginFrame and
  // endFrame. `frame` numbers frames (increasing by one) for the age of query results.
  void draw(Renderer& renderer, uint64_t frame);
  const DynamicFrameStats& stats() const { return stats_; }
  const lod::DynamicOctree& octree() const { return octree_; }
  // Model inputs of the last adaptive decision (for traces and tests).
  const lod::ModeInputs& lastModeInputs() const { return lastInputs_; }
  uint32_t lastQ() const { return lastQ_; }
  uint32_t modeSwitches() const { return switcher_.switches(); }

  // Calibration draws (render/perf_calibration.cpp), between beginFrame and endFrame:
  // `count` draws of the first object alone, with a uniform change before each (T_state).
  void drawStateChanges(Renderer& renderer, uint32_t count);
  // Boxes drawn depth-only with the query program (no query), for the depth-fragment cost.
  void drawDepthBoxes(Renderer& renderer, std::span<const lod::Aabb> boxes);
  // Blocking query reads ever made (always 0: the strategy never waits; for tests).
  uint64_t blockingReads() const { return blockingReads_; }

  uint64_t bufferBytes() const;

 private:
  struct Gpu;
  struct Instance;
  void writeInstance(uint32_t id);
  void rebuildDirtyNodes();
  void drawPerCommand(Renderer& r);
  // budget_ns: the tests stop once their estimated cost (occlusionTest_ns plus the box's
  // depth-only fragments) would exceed it; +inf: q alone decides.
  void drawNodes(Renderer& r, bool occlusion, uint64_t frame, uint32_t q, double budget_ns);
  void pollQueries();
  void noteChanged(const DynamicObject& o);
  // Returns the view axis in world coordinates (for estimateNow).
  glm::dvec3 watchOccluders(const lod::Camera& cam, uint64_t frame);
  bool estimateNow(const lod::Camera& cam, const glm::dvec3& forward, uint64_t frame);
  void issueQueries(Renderer& r, uint64_t frame, uint32_t q, double budget_ns);
  lod::DynamicMode chooseMode();
  void endSamples();
  void warmUp(Renderer& r, uint64_t frame);

  DynamicPassConfig config_;
  std::unique_ptr<Gpu> gpu_;
  lod::DynamicOctree octree_;
  std::vector<DynamicObject> objects_;
  std::vector<uint8_t> alive_;
  // One past the largest id handed out since init or clear(): ids come lowest first, so every
  // live object is below it and the per-object pass scans that many, not maxObjects (a pass
  // sized for 300,000 objects drawing ten scanned 300,000 flags a frame: 0.17 ms).
  uint32_t idEnd_ = 0;
  std::vector<uint32_t> freeIds_;
  std::vector<uint32_t> drawList_, testList_;
  // Node slot blocks: first slot and capacity per node (power of two), free lists per size class.
  std::vector<uint32_t> blockFirst_, blockCap_;
  std::vector<std::vector<uint32_t>> freeBlocks_;
  uint32_t blockTop_ = 0;
  // Queries in flight: (query name, node, frame issued).
  struct Pending {
    uint32_t query, node;
    uint64_t frame;
  };
  std::vector<Pending> pending_;
  std::vector<uint32_t> freeQueries_;
  DynamicStrategy strategy_ = DynamicStrategy::Octree;
  lod::ModeSwitcher switcher_;
  lod::OcclusionFits fits_;
  lod::ModeInputs lastInputs_;
  uint32_t fixedQ_ = 64;
  uint32_t lastQ_ = 0;
  uint32_t estimatorQ_ = 0;       // tests of the last hidden estimate (Octree mode)
  // Octree mode: the estimate runs every estimateEvery_ frames (1, 2, 4, 8: doubled while it
  // finds nothing hidden), every frame again once something is hidden, an object that could
  // hide others appears or moves (a large angular size), or the view turns or moves. It starts
  // at 8: the first estimate runs at once, and nothing has been seen yet that calls for more.
  uint32_t estimateEvery_ = 8;
  uint64_t nextEstimate_ = 0;
  glm::dvec3 estimateEye_{0.0}, estimateForward_{0.0};
  uint64_t exploreUntil_ = 0;       // Occlusion mode: test every candidate node until then
  static constexpr uint64_t kNoFrame = ~uint64_t{0};
  uint64_t occluderFrame_ = kNoFrame;  // the last burst for an occluder (Octree mode: test all)
  uint64_t newlyHidden_ = 0;        // objects under nodes whose results just read came back
                                    // hidden while they had no fresh hidden result before
  glm::dvec3 occluderCenter_{0.0};  // the largest object added or moved since the last draw
  double occluderRadius_ = 0.0;
  uint32_t lastRetests_ = 0;      // hidden nodes re-tested in the last occlusion traversal
  double movedEma_ = 0.0;         // objects changed per frame (Adaptive: alpha_n)
  uint32_t movedThisFrame_ = 0;
  uint64_t blockingReads_ = 0;
  bool warmed_ = false;           // Adaptive: node draws and the query program used once (warmUp)
  uint64_t lastSamples_ = 0;
  bool samplesActive_ = false;
  bool measureSamples_ = false;
  DynamicFrameStats stats_;
  DynamicFrameStats lastNodeStats_;  // from the last octree traversal (Adaptive in PerCommand)
  uint64_t lastTraversalFrame_ = 0;
};

}  // namespace ig::render
