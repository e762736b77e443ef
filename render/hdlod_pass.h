// HDLOD render pass (paper 000, section 4): draws an HDLOD selection (lod/hdlod_select.h) with
// one glMultiDrawElementsIndirect per octant of a single-reference octree.
//
// Geometry is uploaded once at init into one vertex and one index buffer: every scene model once
// (shared by all its instances, static or moving), every coarser model version and every merged
// cluster's mesh. A vertex is a float position (model space, or relative to the merged mesh's
// origin) and a material (the scene model it stands for; colours in a table, one per model);
// meshes (materials per triangle) get three vertices per triangle.
//
// Octree: over the tree's root box, `octreeDepth` levels below the root. A draw lives in exactly
// one node (single reference): the deepest node whose box holds the draw's box (static and
// merged clusters: their box; moving objects: their model box where they are now). Each node
// keeps its own arrays, on the CPU and in GPU buffers: indirect commands, and per draw a float
// matrix relative to the node's centre (an SSBO; the node's centre minus the eye is computed
// in double per frame and passed as a uniform, so huge coordinates keep their precision).
// Updates are incremental: per frame, a draw already in its node keeps its slot (a moving one
// rewrites only its matrix when it changed); a draw that moved to another node is removed from
// the old node's arrays and appended to the new node's; draws no longer selected are removed
// (the last slot moves into the hole); only the changed range of each node is uploaded.
//
// Shading: flat (face normals from screen-space derivatives: no normal attribute, so merged
// meshes need none), sun + ambient, the renderer's fog. The pass binds its own program, VAO and
// buffers and leaves the FBO, viewport and depth state as Renderer::beginFrame set them.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "lod/hdlod_build.h"
#include "lod/hdlod_scene.h"
#include "lod/hdlod_select.h"

namespace ig::render {

class Renderer;

struct HdlodPassStats {
  uint32_t draws = 0;          // draws submitted this frame
  uint64_t triangles = 0;
  uint32_t multiDraws = 0;     // glMultiDrawElementsIndirect calls (non-empty octants)
  uint32_t added = 0;          // draws appended to an octant's arrays
  uint32_t removed = 0;        // draws no longer selected
  uint32_t movedAcross = 0;    // moving objects that changed octant (removed from one, added to another)
  uint32_t matrixUpdates = 0;  // moving objects that stayed in their octant: matrix rewritten
  uint64_t uploadedBytes = 0;  // commands + matrices sent to the GPU this frame
};

class HdlodPass {
 public:
  HdlodPass();
  ~HdlodPass();
  HdlodPass(const HdlodPass&) = delete;
  HdlodPass& operator=(const HdlodPass&) = delete;

  // Uploads the geometry and creates the program; a GL context must be current. The tree and
  // scene must outlive the pass. octreeDepth in 0..6.
  bool init(const lod::hdlod::HdlodTree& tree, const lod::hdlod::Scene& scene, int octreeDepth, std::string& error);
  // Between Renderer::beginFrame and endFrame: updates the octants' arrays from this frame's
  // selection and draws them. Adds to the renderer's stats.
  void draw(Renderer& renderer, std::span<const lod::hdlod::Draw> draws);
  const HdlodPassStats& lastStats() const;
  uint64_t bufferBytes() const;
  // Drops every octant's arrays (the next frame re-adds all its draws).
  void clear();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The colour of a scene model's material (linear RGB 0..1), by name (the construction site's
// models have fixed colours; other names a stable hash).
void hdlodMaterialColor(const std::string& modelName, float rgb[3]);

}  // namespace ig::render
