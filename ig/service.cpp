#include "ig/service.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <cstdlib>
#include <filesystem>
#include <span>
#include <thread>
#include <utility>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "ig/frame_loop.h"
#include "ig/snapshot_writer.h"
#include "ig/systemd.h"
#include "ig/realtime.h"
#include "ig/reload.h"
#include "ig/roam_deadline.h"
#include "ig/status.h"
#include "io/dem.h"
#include "io/replay.h"
#include "lod/sun.h"
#include "ig/cells_layer.h"
#include "ig/forest_layer.h"
#include "ig/hdlod_layer.h"
#include "ig/scene_surfaces.h"
#include "ig/host_input.h"
#include "ig/host_links.h"
#include "lod/block_lod.h"
#include "lod/roam.h"
#include "lod/geo.h"
#include "lod/terrain_grid.h"
#include "lod/geomorph.h"
#include "lod/governor.h"
#include "lod/terrain_chunks.h"
#include "lod/triangle_slots.h"
#include "lod/view.h"
#include "render/context.h"
#include "render/renderer.h"

namespace ig {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

std::string formatMs(std::chrono::steady_clock::duration d) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.0f ms", std::chrono::duration<double, std::milli>(d).count());
  return buf;
}

render::ContextKind contextKind(OutputMode m) {
  switch (m) {
    case OutputMode::Headless: return render::ContextKind::Headless;
    case OutputMode::Window: return render::ContextKind::Window;
    case OutputMode::OSMesa: return render::ContextKind::OSMesa;
  }
  return render::ContextKind::Headless;
}

bool fileReadable(const std::string& path, const std::string& what, std::string& error) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    error = what + " '" + path + "': no such file";
    return false;
  }
  return true;
}

// The terrain layer: CPU grid + per-frame selection buffer (sized once).
struct TerrainLayer {
  explicit TerrainLayer(const lod::TerrainGridDesc& d) : grid(d), selected(grid.chunks().size()) {}
  lod::TerrainGrid grid;
  std::vector<uint32_t> selected;
  size_t selectedCount = 0;
};

}  // namespace

// Terrain drawn from a per-frame triangle list: ROAM (Deferred or enhMerge updates), or block
// LOD, over a DEM or the procedural heights. All buffers are sized at start-up.
//
// Geomorphing (morph_s > 0, ROAM): a vertex a split adds rises from the coarser surface to its
// height (lod::Geomorph `morph`); a merge morphs out (lod::MorphOut `morphOut`): the triangles
// that left stay drawn as ghosts in the slots above the mesh's high-water mark while the
// removed vertices move onto the coarse surface, and the coarse triangles that replace them
// stay degenerate in their slots (`hiddenSlot`) until the morph ends.
struct TerrainMeshLayer {
  struct FreeDeleter {
    void operator()(void* p) const { std::free(p); }
  };
  std::vector<float> heights_m;  // row-major, row y grows northwards
  int width = 0, height = 0;
  double spacing_m = 1.0;
  glm::dvec3 origin_m{0.0};      // ENU of sample (0, 0)
  double heightRange_m = 1.0;
  double minHeight_m = 0.0;     // the lowest post (relative to origin_m): the bottom of the relief the shading scales
  double maxHeight_m = 0.0;     // the highest post (relative to origin_m)
  double drawNearest_m = 0.0;   // a lower bound on the distance from the eye to what is drawn (terrain detail variant)
  std::unique_ptr<lod::Roam> roam;
  lod::RoamMode roamMode = lod::RoamMode::Deferred;
  std::unique_ptr<lod::BlockLod> block;
  // This frame's mesh, room for the whole ROAM mesh (Deferred refines beyond the view, and
  // emitVisible needs room for all of it): calloc'd, so only what is written is committed.
  std::unique_ptr<lod::RoamTriangle[], FreeDeleter> triangles;
  size_t triangleRoom = 0;
  // ROAM without geomorphing: the whole mesh stays in the vertex buffer by chunk; a frame
  // writes the slots ROAM changed and draws the chunks in view (lod/terrain_chunks.h).
  std::unique_ptr<lod::TerrainChunks> chunks;
  std::vector<lod::TerrainDrawRange> ranges;  // this frame's draw ranges (chunks, or the slots)
  std::unique_ptr<lod::TriangleSlots> slots;  // otherwise: which buffer slot each triangle occupies
  std::vector<lod::RoamTriangle> slotTriangle;  // the triangle in each slot (x = kFreeSlot: none)
  std::unique_ptr<lod::Geomorph> morph;       // roam with morph_s > 0: splits
  std::unique_ptr<lod::MorphOut> morphOut;    // roam with morph_s > 0: merges
  std::vector<uint8_t> hiddenSlot;            // 1: the slot holds a MorphOut cover, drawn degenerate
  std::vector<lod::RoamTriangle> left, coverOf;  // MorphOut input: triangles that left, their covers
  std::vector<float> removedTargets_m;        // MorphOut input: heights removed vertices go to
  size_t ghostsDrawn = 0;                     // ghost triangles above the high-water mark
  std::vector<uint32_t> addedTriangles, addedSlots, freedSlots;
  std::vector<uint32_t> movedFrom, movedTo;   // this frame's compaction moves (TriangleSlots::compact)
  std::span<lod::TerrainVertex> gpu;          // the renderer's mapped vertex buffer
  size_t bufferTriangles = 0;                 // its size: slots + ghosts
  uint64_t uploadedTriangles = 0;             // written into `gpu` this frame
  size_t emitted = 0;                         // triangles of this frame's mesh (the governor's load)
  double tolerance_px = 1.0;
  double budget_ms = 0.0;
  double nsPerOperation = 2000.0;  // EnhMerge: measured, smoothed: turns the time budget into operations
  double nsPerVisit = 100.0;       // Deferred: the same for node visits
  uint64_t maxTriangles = 0;       // ROAM mesh cap (Deferred: the whole surroundings)
  uint64_t meshCap = 0;            // Deferred: this frame's cap, lowered while the view overflows the slots
  // The governor's cap on the visible triangles (lod::Governor::loadCap; +inf: none), turned into
  // a cap on ROAM's mesh by the last frame's mesh / visible ratio.
  double visibleCap = std::numeric_limits<double>::infinity();
  double meshPerVisible = 1.0;

  static constexpr int32_t kFreeSlot = INT32_MIN;

  void writeTriangle(uint32_t slot, const lod::RoamTriangle& t, double now_s, bool ghost = false) {
    for (size_t k = 0; k < 3; ++k) {
      lod::TerrainVertex v = lod::heightFieldVertex(heights_m, width, height, spacing_m, t.v[k].x, t.v[k].y);
      if (morph) v.position[2] = morph->height(t.v[k].x, t.v[k].y, v.position[2], now_s);
      if (ghost) {
        v.position[2] = morphOut->height(t.v[k].x, t.v[k].y, v.position[2], now_s);
        const double f = morphOut->progress(t.v[k].x, t.v[k].y, now_s);
        if (f > 0.0) blendNormal(v, t.v[k], static_cast<float>(f));
      }
      gpu[slot * 3 + k] = v;
    }
  }
  // A ghost vertex moving onto the coarse surface also takes on the coarse surface's shading:
  // its normal goes by `f` towards the normal the coarse triangle under it interpolates there,
  // so the swap to that triangle at the end of the morph does not show.
  void blendNormal(lod::TerrainVertex& v, const lod::RoamVertex& at, float f) const {
    const lod::RoamTriangle c = roam->leafAt(3 * int64_t{at.x}, 3 * int64_t{at.y});
    const double x0 = c.v[0].x, y0 = c.v[0].y;
    const double d = (c.v[1].x - x0) * (c.v[2].y - y0) - (c.v[2].x - x0) * (c.v[1].y - y0);
    if (d == 0.0) return;
    const double w1 = ((at.x - x0) * (c.v[2].y - y0) - (c.v[2].x - x0) * (at.y - y0)) / d;
    const double w2 = ((c.v[1].x - x0) * (at.y - y0) - (at.x - x0) * (c.v[1].y - y0)) / d;
    const double w[3] = {1.0 - w1 - w2, w1, w2};
    glm::vec3 n(0.0f);
    for (int i = 0; i < 3; ++i) {
      const lod::TerrainVertex cv = lod::heightFieldVertex(heights_m, width, height, spacing_m, c.v[i].x, c.v[i].y);
      n += static_cast<float>(w[i]) * glm::vec3(cv.normal[0], cv.normal[1], cv.normal[2]);
    }
    const glm::vec3 own(v.normal[0], v.normal[1], v.normal[2]);
    const glm::vec3 blended = own + (n - own) * f;
    const float len = glm::length(blended);
    if (!(len > 0.0f)) return;
    for (int i = 0; i < 3; ++i) v.normal[i] = blended[i] / len;
  }
  void hideSlot(uint32_t slot) {
    for (size_t k = 0; k < 3; ++k) gpu[slot * 3 + k] = lod::TerrainVertex{};
  }

  // lod phase: update the mesh for this view within the time budget, emit what is visible.
  // now_s is the frame's simulation-loop time for geomorphing; NaN = no morphing (one-off
  // frames converge to the true surface).
  void select(const lod::Camera& cam, double viewportHeight_px, Clock* clock, double now_s) {
    lod::RoamView view;
    view.camera = cam;
    view.viewportHeight_px = viewportHeight_px;
    view.tolerance_px = tolerance_px;
    view.maxTriangles = maxTriangles;
    const bool morphing = std::isfinite(now_s);
    const double t = morph && morphing ? now_s : 1e300;  // 1e300: every morph finished
    size_t n = 0;
    if (roam) {
      const int64_t t0 = clock ? clock->now_ns() : 0;
      if (roamMode == lod::RoamMode::Deferred) view.maxTriangles = meshCap;
      if (std::isfinite(visibleCap)) {
        const auto limit = static_cast<uint64_t>(std::max(2.0 * static_cast<double>(roam->baseTriangles()), visibleCap * meshPerVisible));
        view.maxTriangles = view.maxTriangles != 0 ? std::min(view.maxTriangles, limit) : limit;
      }
      if (roamMode == lod::RoamMode::Deferred) {
        // Work in node visits, from the time budget and the measured time per visit; what is
        // left stays queued for the next frame (the mesh is valid at every stop).
        // The budget's end is also a hard stop, for the updates whose visits cost more than
        // the rate says (cache misses after a teleport, a busy machine).
        RoamDeadline deadline;
        if (clock && budget_ms > 0.0) {
          view.maxVisits = static_cast<uint32_t>(std::clamp(budget_ms * 1e6 / nsPerVisit, 256.0, 1e9));
          deadline.arm(view, *clock, t0, budget_ms);
        }
        const lod::RoamStats st = roam->update(view, lod::RoamMode::Deferred);
        if (clock && st.visits >= 256)
          nsPerVisit = lod::budgetRate(nsPerVisit, static_cast<double>(clock->now_ns() - t0) / static_cast<double>(st.visits));
      } else {
        if (clock && budget_ms > 0.0)
          view.maxOperations = static_cast<uint32_t>(std::clamp(budget_ms * 1e6 / nsPerOperation, 64.0, 1e9));
        const lod::RoamStats st = roam->update(view, lod::RoamMode::EnhMerge);
        const uint64_t ops = st.splits + st.merges + st.enhMerges;
        if (clock && ops >= 16)
          nsPerOperation =
              0.8 * nsPerOperation + 0.2 * static_cast<double>(clock->now_ns() - t0) / static_cast<double>(ops);
      }
      if (chunks) {
        selectChunks(cam);
        return;
      }
      if (morph && morphing) morph->startSplits(*roam, heights_m, width, height, now_s);
      n = roam->emitVisible(cam, std::span(triangles.get(), triangleRoom));
      meshPerVisible = n > 0 ? std::max(1.0, static_cast<double>(roam->triangleCount()) / static_cast<double>(n)) : 1.0;
      if (roamMode == lod::RoamMode::Deferred) {
        // Deferred refines the whole surroundings: keep the visible part within the slots by
        // lowering the mesh cap while it overflows, raising it back slowly.
        const size_t room = slots->capacity();
        if (n > room)
          meshCap = std::max<uint64_t>(roam->baseTriangles() * 4, roam->triangleCount() * room / n * 9 / 10);
        else if (meshCap < maxTriangles && n < room * 8 / 10)
          meshCap = std::min(maxTriangles, meshCap + meshCap / 16 + 1);
      }
    } else {
      block->update(view);
      n = block->emitTriangles(std::span(triangles.get(), triangleRoom));
    }
    emitted = n;
    // The slots path draws the whole buffer in one range; the ground detail terms whose reach
    // all of it lies beyond are left out (render::kTerrainDetailReach_m). Without morphing the
    // buffer holds exactly these triangles (each within the box of its posts); morphing vertices
    // and ghosts move between heights, so then only the eye's height above the highest post.
    drawNearest_m = std::max(0.0, cam.eye_m.z - (origin_m.z + maxHeight_m));
    if (!morph && !morphOut)
      drawNearest_m = std::max(drawNearest_m, lod::nearestTriangleBox(std::span(triangles.get(), n), heights_m, width, height,
                                                                      spacing_m, cam.eye_m - origin_m,
                                                                      render::kTerrainFineDetailReach_m));
    // Write only what changed: freed slots become degenerate, new triangles take slots. The
    // GPU is idle here (the previous frame ended with glFinish).
    const lod::TriangleSlots::Changes c =
        slots->update(std::span(triangles.get(), n), addedTriangles, addedSlots, freedSlots);
    // Morph-out: the triangles that left (this frame's freed slots), the new mesh's triangle
    // over each, and the heights the merge-removed vertices go to.
    if (morphOut && morphing) {
      for (size_t i = 0; i < c.freed; ++i) left[i] = slotTriangle[freedSlots[i]];
      const std::span<const lod::RoamVertex> removed = roam->removedVertices();
      size_t covers = 0;
      if (!removed.empty()) {
        for (size_t i = 0; i < removed.size(); ++i)
          removedTargets_m[i] = static_cast<float>(roam->meshHeight(removed[i].x, removed[i].y));
        for (size_t i = 0; i < c.freed; ++i) {
          const lod::RoamTriangle& l = left[i];
          coverOf[i] = roam->leafAt(int64_t{l.v[0].x} + l.v[1].x + l.v[2].x, int64_t{l.v[0].y} + l.v[1].y + l.v[2].y);
        }
        covers = c.freed;
      }
      morphOut->update(std::span(left.data(), c.freed), std::span(coverOf.data(), covers), removed,
                       std::span(removedTargets_m.data(), removed.size()), now_s);
    }
    for (size_t i = 0; i < c.freed; ++i) {
      hideSlot(freedSlots[i]);
      slotTriangle[freedSlots[i]].v[0].x = kFreeSlot;
      if (morphOut) hiddenSlot[freedSlots[i]] = 0;
    }
    for (size_t i = 0; i < c.added; ++i) {
      slotTriangle[addedSlots[i]] = triangles[addedTriangles[i]];
      writeTriangle(addedSlots[i], triangles[addedTriangles[i]], t);
      if (morphOut) hiddenSlot[addedSlots[i]] = 0;
    }
    // Compaction: the triangles of the top slots move into the holes below, so that the drawn
    // range follows the mesh back down after a heavy view (a move is no change of the mesh: no
    // morph starts; a hidden cover stays hidden in its new slot).
    const size_t moves = slots->compact(std::min(slots->holes(), movedFrom.size()), movedFrom, movedTo);
    for (size_t i = 0; i < moves; ++i) {
      const uint32_t from = movedFrom[i], to = movedTo[i];
      slotTriangle[to] = slotTriangle[from];
      slotTriangle[from].v[0].x = kFreeSlot;
      if (morphOut && hiddenSlot[from]) {
        hideSlot(to);
      } else {
        writeTriangle(to, slotTriangle[to], t);
      }
      if (morphOut) {
        hiddenSlot[to] = hiddenSlot[from];
        hiddenSlot[from] = 0;
      }
      hideSlot(from);
    }
    uploadedTriangles = c.added + c.freed + 2 * moves;
    // Geomorph: rewrite the triangles that touch a vertex still on its way to its height, once
    // more after it arrives (expire() runs after this pass).
    if (morph && morph->size() > 0) {
      for (uint32_t s = 0; s < slots->highWater(); ++s) {
        const lod::RoamTriangle& tri = slotTriangle[s];
        if (tri.v[0].x == kFreeSlot || (morphOut && hiddenSlot[s])) continue;
        if (morph->contains(tri.v[0].x, tri.v[0].y) || morph->contains(tri.v[1].x, tri.v[1].y) ||
            morph->contains(tri.v[2].x, tri.v[2].y)) {
          writeTriangle(s, tri, t);
          ++uploadedTriangles;
        }
      }
    }
    ghostsDrawn = 0;
    if (morphOut) {
      // Finished morph-outs: the covers show again, their ghosts go.
      for (const lod::RoamTriangle& cover : morphOut->expire(t)) {
        const uint32_t s = slots->slotOf(cover);
        if (s == lod::TriangleSlots::kNone || !hiddenSlot[s]) continue;
        hiddenSlot[s] = 0;
        writeTriangle(s, slotTriangle[s], t);
        ++uploadedTriangles;
      }
      // Running ones: covers degenerate (also one that has just come into view), ghosts drawn
      // above the high-water mark (rewritten every frame: their vertices move).
      for (size_t i = 0; i < morphOut->coverCount(); ++i) {
        if (!morphOut->coverHidden(i)) continue;
        const uint32_t s = slots->slotOf(morphOut->cover(i));
        if (s == lod::TriangleSlots::kNone || hiddenSlot[s]) continue;
        hiddenSlot[s] = 1;
        hideSlot(s);
        ++uploadedTriangles;
      }
      const std::span<const lod::RoamTriangle> ghosts = morphOut->ghosts();
      ghostsDrawn = std::min(ghosts.size(), bufferTriangles - slots->highWater());
      for (size_t i = 0; i < ghostsDrawn; ++i)
        writeTriangle(static_cast<uint32_t>(slots->highWater() + i), ghosts[i], t, true);
      uploadedTriangles += ghostsDrawn;
    }
    if (morph) morph->expire(t);
  }
  size_t vertexCount() const {
    return chunks ? 0 : (static_cast<size_t>(slots->highWater()) + ghostsDrawn) * 3;
  }
  // What submit draws: the chunks in view, or every slot up to the high-water mark and the ghosts.
  std::span<const lod::TerrainDrawRange> drawRanges() {
    if (!chunks) {
      ranges.clear();
      if (vertexCount() > 0)
        ranges.push_back({0, static_cast<uint32_t>(vertexCount() / 3), drawNearest_m < render::kTerrainDetailReach_m ? 1u : 0u});
    }
    return ranges;
  }

  // The chunked mesh: replay ROAM's changes into the buffer, cull the chunks.
  void selectChunks(const lod::Camera& cam) {
    const lod::TerrainChunks::Changes c = chunks->apply();
    chunks->forEachDirty([&](uint32_t s, const lod::RoamTriangle& t) { writeTriangle(s, t, 1e300); },
                         [&](uint32_t s) { hideSlot(s); });
    uploadedTriangles = c.dirty;
    const size_t n = chunks->cull(cam, ranges, render::kTerrainDetailReach_m, &drawNearest_m);
    emitted = n;
    meshPerVisible = n > 0 ? std::max(1.0, static_cast<double>(roam->triangleCount()) / static_cast<double>(n)) : 1.0;
    // The buffer holds the whole mesh: lower the mesh cap while leaves find no slot (the
    // next apply reads them all again), raise it back slowly.
    const uint64_t floor = roam->baseTriangles() * 4;
    if (chunks->overflowed())
      meshCap = std::max<uint64_t>(floor, roam->triangleCount() * 9 / 10);
    else if (meshCap < maxTriangles && chunks->liveTriangles() < chunks->capacity() * 6 / 10)
      meshCap = std::min(maxTriangles, meshCap + meshCap / 16 + 1);
  }
};

lod::TerrainGridDesc terrainGridDesc(const TerrainLayerConfig& t) {
  lod::TerrainGridDesc d;
  const int quads = static_cast<int>(std::llround(t.size_m / t.gridStep_m));
  d.heights.seed = t.seed;
  d.heights.postsX = d.heights.postsY = quads + 1;
  d.heights.postSpacing_m = t.gridStep_m;
  d.heights.heightScale_m = t.heightScale_m;
  d.offset_m = {t.offset_m[0], t.offset_m[1], t.offset_m[2]};
  d.chunkQuads = t.chunkQuads;
  return d;
}

static bool createTerrainMesh(const TerrainLayerConfig& t, const ServiceConfig& config,
                              std::unique_ptr<TerrainMeshLayer>& out, std::string& error) {
  auto layer = std::make_unique<TerrainMeshLayer>();
  TerrainMeshLayer& m = *layer;
  if (t.source == TerrainLayerConfig::Source::Dem) {
    io::DemLoadOptions o;
    o.pngScale_m = t.pngScale_m;
    o.pngOffset_m = t.pngOffset_m;
    io::Dem dem;
    if (!io::loadDem(t.file, o, dem, error)) {
      error = "terrain.file: " + error;
      return false;
    }
    io::flipRows(dem);
    m.spacing_m = t.demSpacing_m > 0 ? t.demSpacing_m : dem.spacing_m;
    if (m.spacing_m <= 0) {
      error = "terrain.file '" + t.file + "': the file gives no sample spacing; set terrain.spacing_m";
      return false;
    }
    m.width = dem.width;
    m.height = dem.height;
    m.heights_m = std::move(dem.heights_m);
  } else {
    const lod::TerrainGridDesc d = terrainGridDesc(t);
    m.width = d.heights.postsX;
    m.height = d.heights.postsY;
    m.spacing_m = d.heights.postSpacing_m;
    m.heights_m.resize(static_cast<size_t>(m.width) * static_cast<size_t>(m.height));
    lod::generateHeightfield(d.heights, m.heights_m);
  }
  const auto [lo, hi] = std::minmax_element(m.heights_m.begin(), m.heights_m.end());
  m.heightRange_m = std::max(1.0, static_cast<double>(*hi - *lo));
  m.maxHeight_m = static_cast<double>(*hi);
  m.minHeight_m = static_cast<double>(*lo);
  m.origin_m = {t.offset_m[0], t.offset_m[1], t.offset_m[2]};
  m.tolerance_px = t.tolerance_px;
  m.budget_ms = t.lodBudget_ms;
  // Never more than the full-resolution mesh: the node pool and buffers are sized from this.
  const uint64_t fullResolution = 2ull * static_cast<uint64_t>(m.width - 1) * static_cast<uint64_t>(m.height - 1);
  m.maxTriangles = std::min({static_cast<uint64_t>(config.budgetTriangles), uint64_t{1} << 20, fullResolution});
  size_t capacity = 0;
  if (t.lod == TerrainLayerConfig::Lod::Roam) {
    m.roamMode = t.roamMode == TerrainLayerConfig::RoamMode::Deferred ? lod::RoamMode::Deferred : lod::RoamMode::EnhMerge;
    capacity = static_cast<size_t>(m.maxTriangles);
    // Deferred refines the whole surroundings, not only the view (4-7x the triangles of the
    // view, docs/terrain.md): its mesh may grow to 4x what the slots hold.
    if (m.roamMode == lod::RoamMode::Deferred) m.maxTriangles = std::min(4 * m.maxTriangles, fullResolution);
    m.meshCap = m.maxTriangles;
    lod::RoamConfig rc;
    rc.maxTriangles = m.maxTriangles;
    m.roam = std::make_unique<lod::Roam>(m.heights_m, m.width, m.height, m.spacing_m, m.origin_m, rc);
    m.triangleRoom = static_cast<size_t>(m.maxTriangles);
  } else {
    m.block = std::make_unique<lod::BlockLod>(m.heights_m, m.width, m.height, m.spacing_m, m.origin_m);
    // Block LOD has no triangle control: room for every block at its finest level.
    const auto q = static_cast<size_t>(lod::BlockLodConfig{}.blockQuads);
    capacity = static_cast<size_t>(m.block->blocksX()) * static_cast<size_t>(m.block->blocksY()) * (2 * q * q + 8);
    m.triangleRoom = capacity;
  }
  if (m.roam && !(t.morph_s > 0.0)) {
    // No geomorphing: the mesh lives in the buffer by chunk (room for 1.5x the mesh cap).
    m.chunks = std::make_unique<lod::TerrainChunks>(*m.roam);
    m.bufferTriangles = m.chunks->capacity();
    out = std::move(layer);
    return true;
  }
  m.triangles.reset(static_cast<lod::RoamTriangle*>(std::calloc(m.triangleRoom, sizeof(lod::RoamTriangle))));
  if (!m.triangles) {
    error = "terrain: cannot allocate the triangle list (" + std::to_string(m.triangleRoom) + " triangles)";
    return false;
  }
  m.slots = std::make_unique<lod::TriangleSlots>(capacity);
  m.slotTriangle.assign(capacity, lod::RoamTriangle{{{TerrainMeshLayer::kFreeSlot, 0}, {0, 0}, {0, 0}}});
  m.bufferTriangles = capacity;
  if (t.morph_s > 0.0 && m.roam) {
    m.morph = std::make_unique<lod::Geomorph>(16384, t.morph_s);
    const size_t ghosts = std::min<size_t>(capacity, 1u << 16);
    m.morphOut = std::make_unique<lod::MorphOut>(ghosts, t.morph_s);
    m.hiddenSlot.assign(capacity, 0);
    m.left.resize(capacity);
    m.coverOf.resize(capacity);
    m.removedTargets_m.resize(lod::Roam::kCreatedCapacity);
    m.bufferTriangles += ghosts;
  }
  m.addedTriangles.resize(capacity);
  m.addedSlots.resize(capacity);
  m.freedSlots.resize(capacity);
  m.movedFrom.resize(lod::TriangleSlots::kCompactMovesPerFrame);
  m.movedTo.resize(lod::TriangleSlots::kCompactMovesPerFrame);
  out = std::move(layer);
  return true;
}

lod::Camera cameraFor(const io::HostState& h, const ChannelSettings& channel, int width_px, int height_px) {
  lod::Camera c;
  c.eye_m = h.eyeEnu_m;
  c.heading_deg = h.heading_deg;
  c.pitch_deg = h.pitch_deg;
  c.roll_deg = h.roll_deg;
  if (channel.yaw_deg != 0.0 || channel.pitch_deg != 0.0 || channel.roll_deg != 0.0) {
    const lod::Attitude a = lod::composeAttitude({h.heading_deg, h.pitch_deg, h.roll_deg},
                                                 {channel.yaw_deg, channel.pitch_deg, channel.roll_deg});
    c.heading_deg = a.heading_deg;
    c.pitch_deg = a.pitch_deg;
    c.roll_deg = a.roll_deg;
  }
  c.near_m = h.near_m;
  c.far_m = h.far_m;
  c.fovY_deg = h.fovY_deg;
  c.aspect = static_cast<double>(width_px) / static_cast<double>(height_px);
  // The channel's frustum is the cabin's geometry: it wins over the host's field of view.
  if (channel.frustum && lod::setWindow(c, *channel.frustum)) return c;
  c.shiftX = h.windowShiftX;
  c.shiftY = h.windowShiftY;
  if (h.windowWidth_tan > 0.0) c.aspect = h.windowWidth_tan / (2.0 * std::tan(0.5 * h.fovY_deg * kDeg));
  return c;
}

bool hostStateValid(const io::HostState& s, std::string* why) {
  auto bad = [&](const char* what, double v) {
    if (why) *why = std::string(what) + " = " + std::to_string(v);
    return false;
  };
  const double values[] = {s.simTime_s, s.eyeEnu_m.x, s.eyeEnu_m.y, s.eyeEnu_m.z, s.heading_deg,
                           s.pitch_deg, s.roll_deg, s.fovY_deg, s.near_m, s.far_m,
                           s.windowShiftX, s.windowShiftY, s.windowWidth_tan};
  const char* names[] = {"sim_time_s", "east_m", "north_m", "up_m", "heading_deg",
                         "pitch_deg", "roll_deg", "fovy_deg", "near_m", "far_m",
                         "window_shift_x", "window_shift_y", "window_width_tan"};
  for (size_t i = 0; i < std::size(values); ++i)
    if (!std::isfinite(values[i])) return bad(names[i], values[i]);
  if (!(s.fovY_deg > 0.0 && s.fovY_deg < 180.0)) return bad("fovy_deg", s.fovY_deg);
  if (!(s.near_m > 0.0)) return bad("near_m", s.near_m);
  if (!(s.far_m > s.near_m)) return bad("far_m", s.far_m);
  if (!(std::abs(s.windowShiftX) <= lod::kMaxWindowShift)) return bad("window_shift_x", s.windowShiftX);
  if (!(std::abs(s.windowShiftY) <= lod::kMaxWindowShift)) return bad("window_shift_y", s.windowShiftY);
  if (!(s.windowWidth_tan >= 0.0 && s.windowWidth_tan <= 2.0 * lod::kMaxWindowShift))
    return bad("window_width_tan", s.windowWidth_tan);
  // Time of day: negative = none (the scene's sun), else UTC hours below 24 (io/host_state.h).
  if (std::isinf(s.timeOfDay_h) || !(s.timeOfDay_h < 24.0)) return bad("tod_h", s.timeOfDay_h);
  // Visibility: <= 0 = none (the scene's fog), else metres up to io::kMaxVisibility_m.
  if (std::isinf(s.visibility_m) || !(s.visibility_m <= io::kMaxVisibility_m)) return bad("visibility_m", s.visibility_m);
  return true;
}

struct Service::Impl {
  ServiceConfig config;
  SceneConfig scene;
  std::unique_ptr<render::GlContext> context;
  render::Renderer renderer;
  std::unique_ptr<TerrainLayer> terrain;          // lod = "grid"
  std::unique_ptr<TerrainMeshLayer> terrainMesh;  // lod = "roam" | "block"
  // The terrain's full-resolution heights (either layer's), for the host link's HAT/HOT answers.
  lod::HeightGrid ground;
  bool hasGround = false;
  std::unique_ptr<ForestLayer> forest;            // [forest]: on the terrain mesh
  std::unique_ptr<HdlodLayer> hdlod;              // [hdlod]: 4D scene
  std::unique_ptr<CellsLayer> cells;              // [cells]: streamed hierarchical cells
  SurfaceSet surfaces;  // the [hdlod] objects and [forest] trees for the host link's HAT/HOT and LOS answers
  std::unique_ptr<io::ReplaySource> replay;
  MonotonicClock startClock;                 // stamps host samples until run() hands over its clock
  std::unique_ptr<HostInput> hostInput;      // live link and recorder; only for link sources
  std::optional<lod::EnuFrame> enu;
  render::Lighting lighting;       // the scene's sun and fog at full daylight
  render::Lighting fixedLighting;  // the same dimmed for the scene's fixed sun (render::daylight())
  render::Lighting haze;           // `lighting` with the scene's fog colour on: a host's visibility applies
  render::Lighting fixedHaze;      //   (CIGI Atmosphere Control) even where the scene has no fog
  SummaryCollector summary{1};
  int64_t overruns = 0, missed = 0;  // of every run() so far, as the summary's frames
  int64_t loopStart_ns = 0;
  // The geomorphing time of the next run()'s slot 0: the time after the previous run's last frame,
  // so that a run after another goes on from there (slot times restart at 0; morphs started near
  // the end of a run would otherwise stand still at their start heights until the new run's time
  // caught up with theirs).
  double morphTimeBase_s = 0.0;
  std::unique_ptr<SnapshotWriter> snapshots;  // only while the config asks for snapshots
  bool snapshotsAtStartup = false;            // the start-up config asked for them (folder made)
  int generation = 1;                         // config generation: +1 per applied reload
  std::optional<lod::Governor> governor;      // [governor] enabled and a layer with a knob
  double terrainSelect_ms = 0.0;              // this frame's terrain selection (governor phase)
  double forestSelect_ms = 0.0;                // this frame's forest selection (governor phase)
  double hdlodSelect_ms = 0.0;                 // this frame's HDLOD selection (governor phase)
  double cellsSelect_ms = 0.0, cellsDraw_ms = 0.0;  // this frame's cells selection and draw

  // The forest's shell layers the governor may draw, {least, most}: [governor.forest] min_layers
  // and max_layers (0: the scene's count), within the scene's count. With least = most the count
  // is fixed there (no knob).
  std::pair<int, int> forestLayerBounds() const { return forestLayerBounds(config); }
  std::pair<int, int> forestLayerBounds(const ServiceConfig& cf) const {
    const int count = forest ? forest->layerCount() : 0;
    const int most = cf.governor.forestMaxLayers > 0 ? std::min(cf.governor.forestMaxLayers, count) : count;
    return {std::min(cf.governor.forestMinLayers, most), most};
  }

  // The governor's config from [governor] and the layers this scene has (or from a reload's
  // configs, to validate them before anything is applied).
  lod::GovernorConfig governorConfig() const { return governorConfig(config, scene); }
  lod::GovernorConfig governorConfig(const ServiceConfig& cf, const SceneConfig& sc) const {
    const GovernorSettings& g = cf.governor;
    lod::GovernorConfig c;
    c.rate_hz = cf.rate_hz;
    c.frameBudget_ms = cf.budgetFrame_ms;
    c.decreaseAbove = g.decreaseAbove;
    c.increaseBelow = g.increaseBelow;
    c.marginSigmas = g.marginSigmas;
    c.spikeWindow_frames = g.spikeWindow_frames;
    c.maxDecrease = g.maxDecrease;
    c.maxIncrease = g.maxIncrease;
    c.raiseInterval_frames = g.raiseInterval_frames;
    c.holdAfterDecrease_frames = g.holdAfterDecrease_frames;
    // A pixel tolerance (terrain, HDLOD r): the scene's starts it and is the finest the governor
    // gives unless min_px says otherwise.
    auto tolerance = [&c](lod::GovLayer layer, double scene_px, double min_px, double max_px, double loadExponent) {
      lod::GovKnob& k = c.knobs[static_cast<size_t>(layer)];
      k.present = true;
      k.initial = scene_px;
      k.min = min_px > 0.0 ? min_px : scene_px;
      k.max = std::max(max_px, k.min * 1.01);
      k.loadExponent = loadExponent;
      k.loadUnit = 1e5;
    };
    if (terrainMesh && sc.terrain)
      tolerance(lod::GovLayer::Terrain, sc.terrain->tolerance_px, g.terrainMin_px, g.terrainMax_px, g.terrainLoadExponent);
    if (hdlod && sc.hdlod)
      tolerance(lod::GovLayer::Hdlod, sc.hdlod->tolerance_px, g.hdlodMin_px, g.hdlodMax_px, g.hdlodLoadExponent);
    if (forest && sc.forest) {
      // The 3D trees' near distance (trees drawn ~ distance^2): the scene's is the start value
      // and, unless max_m says otherwise, the most the governor gives.
      lod::GovKnob& k = c.knobs[static_cast<size_t>(lod::GovLayer::Forest)];
      k.present = true;
      k.initial = sc.forest->nearFadeEnd_m;
      k.max = g.forestMax_m > 0.0 ? std::min(g.forestMax_m, sc.forest->fadeOut_m) : sc.forest->nearFadeEnd_m;
      // [governor.forest] min_m, unless the most is not above it (the scene's near_fade_end_m
      // below min_m): then half the most, so that the knob still has a range.
      k.min = g.forestMin_m < k.max ? g.forestMin_m : 0.5 * k.max;
      k.loadExponent = 2.0;
      k.loadUnit = 1e4;
      // The shell layers drawn (their fill ~ the count): the most is the start value; a count
      // that cannot move (1 layer, or min_layers = max_layers) is not a knob.
      const auto [least, most] = forestLayerBounds(cf);
      if (least < most) {
        lod::GovKnob& n = c.knobs[static_cast<size_t>(lod::GovLayer::ForestLayers)];
        n.present = true;
        n.initial = most;
        n.min = least;
        n.max = most;
        n.loadExponent = 1.0;
        n.quantum = 1.0;
        n.loadUnit = 1.0;
      }
    }
    if (cells && sc.cells) {
      // The voxel budget: the scene's is the start value and, unless max_voxels says otherwise,
      // the most the governor gives (never more detail than the scene asks for).
      lod::GovKnob& k = c.knobs[static_cast<size_t>(lod::GovLayer::Cells)];
      k.present = true;
      k.initial = static_cast<double>(sc.cells->voxelBudget);
      k.max = static_cast<double>(g.cellsMax_voxels > 0 ? g.cellsMax_voxels : sc.cells->voxelBudget);
      // [governor.cells] min_voxels, unless the most is not above it (then half the most).
      const auto least = static_cast<double>(g.cellsMin_voxels);
      k.min = least < k.max ? least : 0.5 * k.max;
      k.loadExponent = 1.0;
      k.loadBudget = true;
      k.quantum = 0.0;
      k.loadUnit = 1e5;
    }
    return c;
  }
  std::string lastReloadError;

  // The detail the governor gives each layer now (its knobs; the forest's bands as in use, a
  // knob it refused leaves them), NaN for a layer the scene does not have. Needs the governor.
  std::array<double, lod::kGovLayers> governorDetail() const {
    std::array<double, lod::kGovLayers> d{};
    for (int l = 0; l < lod::kGovLayers; ++l) d[static_cast<size_t>(l)] = governor->knob(static_cast<lod::GovLayer>(l));
    if (forest) d[static_cast<size_t>(lod::GovLayer::Forest)] = forest->nearDistance();
    if (forest) d[static_cast<size_t>(lod::GovLayer::ForestLayers)] = forest->layersDrawn();  // fixed or steered
    return d;
  }

  // The scene's sun and fog (start-up and reload).
  void setLighting() {
    const double az = scene.sun.azimuth_deg * kDeg, el = scene.sun.elevation_deg * kDeg;
    lighting.sunDirection = {std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el)};
    lighting.sunColor = {scene.sun.color[0], scene.sun.color[1], scene.sun.color[2]};
    lighting.ambient = scene.sun.ambient;
    lighting.fog = scene.fog.enabled;
    lighting.fogVisibility_m = scene.fog.visibility_m;
    lighting.fogColor = {scene.fog.color[0], scene.fog.color[1], scene.fog.color[2]};
    if (!scene.fog.enabled) lighting.fogColor = {0.52, 0.68, 0.88};  // clear sky
    fixedLighting = render::daylight(lighting, scene.sun.elevation_deg);
    haze = lighting;
    haze.fog = true;
    haze.fogColor = {scene.fog.color[0], scene.fog.color[1], scene.fog.color[2]};
    fixedHaze = render::daylight(haze, scene.sun.elevation_deg);
  }

  // The fog's visibility this frame: the host's when it sent one, else the scene's; 0: no fog.
  double fogVisibility_m(const io::HostState& h) const {
    if (h.visibility_m > 0.0) return h.visibility_m;
    return scene.fog.enabled ? scene.fog.visibility_m : 0.0;
  }

  // The host's camera, its far plane moved in to where the fog is opaque ([fog] cull).
  lod::Camera cameraFor(const io::HostState& h) const {
    lod::Camera c = ig::cameraFor(h, config.channel, config.width_px, config.height_px);
    if (const double v = fogVisibility_m(h); v > 0.0 && scene.fog.cull)
      c.far_m = std::min(c.far_m, std::max(render::fogOpaqueDistance_m(v), 2.0 * c.near_m));
    return c;
  }

  // lod phase: every layer the scene has selects what to draw. `clock` (the frame loop's)
  // lets layers keep to their time budgets; without it they converge fully.
  void select(const lod::Camera& cam, Clock* clock, double now_s, double simTime_s) {
    if (terrainMesh) {
      const int64_t t0 = clock ? clock->now_ns() : 0;
      if (governor) {
        terrainMesh->tolerance_px = governor->knob(lod::GovLayer::Terrain);
        // Deferrable refinement yields at the terrain phase's budget (or the scene's, if smaller),
        // shrunk for a while after an overrun (Governor::deferrableBudget_ms).
        const double phase_ms = governor->deferrableBudget_ms(lod::GovPhase::Terrain);
        const double own_ms = scene.terrain ? scene.terrain->lodBudget_ms : 0.0;
        terrainMesh->budget_ms = own_ms > 0.0 ? std::min(own_ms, phase_ms) : phase_ms;
        terrainMesh->visibleCap = governor->loadCap(lod::GovLayer::Terrain);
      }
      terrainMesh->select(cam, config.height_px, clock, now_s);
      terrainSelect_ms = clock ? static_cast<double>(clock->now_ns() - t0) * 1e-6 : 0.0;
    }
    if (forest) {
      const int64_t t0 = clock ? clock->now_ns() : 0;
      if (governor) {
        forest->setNearDistance(governor->knob(lod::GovLayer::Forest));
        const double n = governor->knob(lod::GovLayer::ForestLayers);
        forest->setLayersDrawn(std::isnan(n) ? forestLayerBounds().second : static_cast<int>(std::lround(n)));
      }
      forest->select(cam);
      forestSelect_ms = clock ? static_cast<double>(clock->now_ns() - t0) * 1e-6 : 0.0;
    }
    if (hdlod) {
      const int64_t t0 = clock ? clock->now_ns() : 0;
      if (governor) hdlod->setTolerance_px(governor->knob(lod::GovLayer::Hdlod));
      hdlod->select(cam, simTime_s, config.height_px);
      hdlodSelect_ms = clock ? static_cast<double>(clock->now_ns() - t0) * 1e-6 : 0.0;
    }
    if (cells) {
      const int64_t t0 = clock ? clock->now_ns() : 0;
      if (governor) {
        // The governor's budget, and no more than the last frame's voxels grown by its headroom
        // (cells arriving after a jump of the eye fill the budget faster than it can follow).
        const double budget = std::min(governor->knob(lod::GovLayer::Cells), governor->loadCap(lod::GovLayer::Cells));
        cells->setVoxelBudget(static_cast<uint64_t>(std::max(1.0, std::floor(budget))));
      }
      // The refinement yields at the cells phase's budget (or the scene's, if smaller); the
      // passes over the cut are not deferrable.
      const double own_ms = scene.cells ? scene.cells->selectBudget_ms : 0.0;
      const double phase_ms = governor ? governor->deferrableBudget_ms(lod::GovPhase::Cells) : 0.0;
      const double budget_ms = own_ms > 0.0 && phase_ms > 0.0 ? std::min(own_ms, phase_ms) : std::max(own_ms, phase_ms);
      cells->select(cam, config.height_px, clock, budget_ms);
      cellsSelect_ms = clock ? static_cast<double>(clock->now_ns() - t0) * 1e-6 : 0.0;
    }
    if (terrain) {
      const lod::Frustum fr = lod::makeFrustum(cam);
      terrain->selectedCount =
          terrain->grid.select(fr, cam.eye_m, static_cast<uint64_t>(config.budgetTriangles), terrain->selected);
    }
  }

  // The scene's fixed sun, or the sun for the host's date and time of day at the eyepoint
  // (no date: the March equinox). Night dims sun, ambient light and sky together. A host's
  // visibility turns the fog on (the scene's fog colour) at that visibility.
  render::Lighting lightingFor(const io::HostState& h) const {
    if (h.visibility_m > 0.0) {
      render::Lighting l = h.timeOfDay_h < 0.0 ? fixedHaze : sunlit(h, haze);
      l.fogVisibility_m = h.visibility_m;
      return l;
    }
    return h.timeOfDay_h < 0.0 ? fixedLighting : sunlit(h, lighting);
  }
  render::Lighting sunlit(const io::HostState& h, const render::Lighting& full) const {
    const lod::Geodetic g = enu->toGeodetic(h.eyeEnu_m);
    const lod::SunPosition sun = lod::sunPosition(h.dateYmd != 0 ? h.dateYmd : 20260320, h.timeOfDay_h, g.lat_deg, g.lon_deg);
    const double az = sun.azimuth_deg * kDeg, el = sun.elevation_deg * kDeg;
    render::Lighting l = render::daylight(full, sun.elevation_deg);
    l.sunDirection = {std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el)};
    return l;
  }

  // submit phase: the selections become GL work. `clock` (the frame loop's) times the layers.
  render::RenderStats submit(const lod::Camera& cam, const io::HostState& host, Clock* clock = nullptr) {
    renderer.beginFrame(cam, lightingFor(host));
    if (terrain) renderer.drawTerrain(std::span(terrain->selected.data(), terrain->selectedCount));
    if (terrainMesh) renderer.drawTerrainMeshRanges(terrainMesh->origin_m, terrainMesh->drawRanges(), terrainMesh->drawNearest_m);
    if (forest) forest->draw(renderer, terrainMesh->origin_m, terrainMesh->ranges);
    if (hdlod) hdlod->draw(renderer);
    if (cells) {
      const int64_t t0 = clock ? clock->now_ns() : 0;
      cells->draw(renderer);
      cellsDraw_ms = clock ? static_cast<double>(clock->now_ns() - t0) * 1e-6 : 0.0;
      if (clock) cells->recordTiming(cellsSelect_ms, cellsDraw_ms);
    }
    render::RenderStats st = renderer.endFrame();
    st.passes += (forest ? 1u : 0u) + (hdlod ? 1u : 0u) + (cells ? 1u : 0u);  // passes in their own files
    return st;
  }

  FrameRecord record(const render::RenderStats& st, const io::HostState& host, const lod::Camera& cam) const {
    FrameRecord r;
    r.far_m = cam.far_m;
    if (const double v = fogVisibility_m(host); v > 0.0) r.fogVisibility_m = v;
    r.triangles = st.triangles;
    r.drawCalls = st.drawCalls;
    r.passes = st.passes;
    r.hostFrame = host.hostFrame;
    r.simTime_s = host.simTime_s;
    r.eyeEast_m = host.eyeEnu_m.x;
    r.eyeNorth_m = host.eyeEnu_m.y;
    r.eyeHeight_m = host.eyeEnu_m.z;
    r.heading_deg = host.heading_deg;
    return r;
  }
};

Service::Service() : impl_(std::make_unique<Impl>()) {}
Service::~Service() {
  // The link thread publishes into mailbox_, which (a member declared after impl_) is destroyed
  // before impl_ and its HostInput: stop the link first. run() stops it too; this covers a
  // Service destroyed without run(), e.g. create() failing after the link started.
  if (impl_ && impl_->hostInput) impl_->hostInput->stop();
  // The layers and the renderer delete their GL objects in this service's context.
  if (impl_ && impl_->context) {
    std::string error;
    if (!impl_->context->makeCurrent(error)) std::fprintf(stderr, "igd: cannot make the GL context current to delete its objects: %s\n", error.c_str());
  }
}

std::unique_ptr<Service> Service::create(const ServiceConfig& config, const SceneConfig& scene, std::string& error,
                                         std::unique_ptr<io::HostLink> link) {
  std::unique_ptr<Service> s(new Service());
  Impl& m = *s->impl_;
  m.config = config;
  m.scene = scene;
  // At most SummaryCollector::kMaxCapacity frames are kept (frames = 1e11 must not reserve terabytes).
  m.summary = SummaryCollector(SummaryCollector::capacityFor(config.frames));

  if (config.host == HostSource::Replay) {
    io::Recording rec;
    if (!fileReadable(config.replayFile, "host.replay_file", error)) return nullptr;
    if (!io::loadRecording(config.replayFile, rec, error)) return nullptr;
    m.replay = std::make_unique<io::ReplaySource>(std::move(rec), config.replayLoop);
  }

  m.context = render::createContext(contextKind(config.output), config.width_px, config.height_px, error,
                                    render::WindowOptions{config.fullscreen, config.monitor});
  if (!m.context) return nullptr;
  if (!m.renderer.init(config.width_px, config.height_px, error, config.msaa)) return nullptr;
  s->info_.context = m.context->description();

  const auto terrainStart = std::chrono::steady_clock::now();
  if (scene.terrain && scene.terrain->lod == TerrainLayerConfig::Lod::Grid) {
    m.terrain = std::make_unique<TerrainLayer>(terrainGridDesc(*scene.terrain));
    if (!m.renderer.addTerrain(m.terrain->grid, error)) return nullptr;
    s->info_.layers.push_back("terrain");
    s->info_.terrainTriangles = m.terrain->grid.totalTriangles();
  } else if (scene.terrain) {
    if (!createTerrainMesh(*scene.terrain, config, m.terrainMesh, error)) return nullptr;
    TerrainMeshLayer& t = *m.terrainMesh;
    if (!m.renderer.addTerrainMesh(t.bufferTriangles * 3, t.heightRange_m, error, t.minHeight_m)) return nullptr;
    t.gpu = m.renderer.terrainMeshVertices();
    s->info_.layers.push_back(scene.terrain->lod == TerrainLayerConfig::Lod::Roam ? "terrain (roam)" : "terrain (block)");
    s->info_.terrainTriangles = 2ull * static_cast<uint64_t>(t.width - 1) * static_cast<uint64_t>(t.height - 1);
  }
  if (m.terrain) {
    const lod::TerrainGridDesc& d = m.terrain->grid.desc();
    m.ground = {m.terrain->grid.heights(), d.heights.postsX, d.heights.postsY, d.heights.postSpacing_m, d.offset_m};
    m.hasGround = true;
  } else if (m.terrainMesh) {
    const TerrainMeshLayer& t = *m.terrainMesh;
    m.ground = {t.heights_m, t.width, t.height, t.spacing_m, t.origin_m};
    m.hasGround = true;
  }
  if (scene.terrain) {
    s->info_.terrainBuild_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - terrainStart).count();
    const int w = m.terrainMesh ? m.terrainMesh->width : m.terrain->grid.desc().heights.postsX;
    const int h = m.terrainMesh ? m.terrainMesh->height : m.terrain->grid.desc().heights.postsY;
    s->info_.terrainSource = (scene.terrain->source == TerrainLayerConfig::Source::Dem ? scene.terrain->file
                                                                                        : std::string("procedural")) +
                             " " + std::to_string(w) + "x" + std::to_string(h);
  }
  if (scene.forest) {
    if (!m.terrainMesh) {
      error = "scene '" + scene.path + "': [forest] needs [terrain] with lod = \"roam\" or \"block\" (the shell "
              "layers are drawn from the terrain mesh)";
      return nullptr;
    }
    const TerrainMeshLayer& t = *m.terrainMesh;
    m.forest = ForestLayer::create(*scene.forest, ForestGround{t.heights_m, t.width, t.height, t.spacing_m, t.origin_m},
                                   error);
    if (!m.forest) {
      error = "scene '" + scene.path + "' [forest]: " + error;
      return nullptr;
    }
    s->info_.layers.push_back("forest");
    const auto q0 = std::chrono::steady_clock::now();
    m.forest->enableQueries(config.host == HostSource::Cigi);  // the link that answers LOS requests
    if (config.host == HostSource::Cigi) {
      m.surfaces.add(&m.forest->surfaces());
      s->info_.queriesDescription += ", " + std::to_string(m.forest->kdTree().trees().size()) + " [forest] trees (LOS, index " +
                                     formatMs(std::chrono::steady_clock::now() - q0) + ")";
    }
  }
  if (scene.hdlod) {
    const auto t0 = std::chrono::steady_clock::now();
    m.hdlod = HdlodLayer::create(*scene.hdlod, error);
    if (!m.hdlod) {
      error = "scene '" + scene.path + "' [hdlod]: " + error;
      return nullptr;
    }
    if (!m.hdlod->initRender(error)) {
      error = "scene '" + scene.path + "' [hdlod]: " + error;
      return nullptr;
    }
    s->info_.layers.push_back("hdlod");
    if (config.host == HostSource::Cigi) {  // the link that answers HAT/HOT and LOS requests
      const auto q0 = std::chrono::steady_clock::now();
      m.hdlod->enableQueries();
      m.surfaces.add(&m.hdlod->surfaces());
      s->info_.queriesDescription += ", " + std::to_string(m.hdlod->scene().objects.size()) + " [hdlod] objects (" +
                                     std::to_string(m.hdlod->rays().triangles()) + " model triangles, index " +
                                     formatMs(std::chrono::steady_clock::now() - q0) + ")";
    }
    s->info_.hdlodDescription = m.hdlod->describe();
    s->info_.hdlodBuild_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  }
  if (scene.cells) {
    m.cells = CellsLayer::create(*scene.cells, error);
    if (!m.cells || !m.cells->initRender(error)) {
      error = "scene '" + scene.path + "' " + error;
      return nullptr;
    }
    s->info_.layers.push_back("cells");
    s->info_.cellsDescription = m.cells->describe();
    s->info_.threads += m.cells->threads();
  }
  if (config.snapshotEvery > 0 || !config.snapshotFrames.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(config.snapshotDir, ec);
    if (ec) {
      error = "output.snapshot_dir '" + config.snapshotDir + "': cannot create: " + ec.message();
      return nullptr;
    }
    m.snapshots = std::make_unique<SnapshotWriter>(3, config.width_px, config.height_px);
    m.snapshotsAtStartup = true;
    ++s->info_.threads;
  }
  const lod::Geodetic origin{scene.originGeodetic[0], scene.originGeodetic[1], scene.originGeodetic[2]};
  if (!link && isLinkSource(config.host)) {
    link = makeHostLink(config, origin, error);
    if (!link) return nullptr;
  }
  if (link || !config.recordFile.empty()) {
    m.hostInput = std::make_unique<HostInput>(s->mailbox_, m.startClock);
    if (!m.hostInput->start(std::move(link), config.recordFile, config.linkTimeout_s, error)) return nullptr;
    s->info_.threads += m.hostInput->threads();
  }
  if (config.host == HostSource::Cigi) {
    s->info_.queriesDescription =
        (m.hasGround ? "the terrain grid (" + std::to_string(m.ground.width) + " x " + std::to_string(m.ground.height) +
                           " posts)"
                     : std::string("no terrain (every answer Valid = 0)")) +
        s->info_.queriesDescription;
  }
  s->info_.passes = m.renderer.passCount();
  s->info_.gpuBufferBytes = m.renderer.bufferBytes() + (m.hdlod ? m.hdlod->gpuBytes() : 0) +
                            (m.forest ? m.forest->bufferBytes() : 0) + (m.cells ? m.cells->gpuBytes() : 0);
  s->info_.passes += (m.hdlod ? 1u : 0u) + (m.forest ? 1u : 0u) + (m.cells ? 1u : 0u);

  m.enu.emplace(origin);
  m.setLighting();

  // Until the host speaks: above the scene origin, looking north and slightly down.
  s->host_.eyeEnu_m = {0.0, 0.0, 1000.0};
  s->host_.pitch_deg = -10.0;
  if (config.governor.enabled) {
    if (!m.terrainMesh && !m.forest && !m.hdlod && !m.cells) {
      std::fprintf(stderr, "igd: governor: the scene has no layer whose detail it can steer (terrain lod = "
                           "\"roam\" or \"block\", [hdlod] or [cells]); governor off\n");
    } else {
      const lod::GovernorConfig g = m.governorConfig();
      if (const std::string why = lod::Governor::validate(g); !why.empty()) {
        error = "governor." + why;
        return nullptr;
      }
      m.governor.emplace(g);
      s->info_.layers.push_back("governor");
      // The forest's coarser layer counts the governor may choose, made now rather than in the
      // late frame that first needs one.
      if (m.forest) {
        const uint64_t before = m.forest->bufferBytes();
        const auto [least, most] = m.forestLayerBounds();
        m.forest->prepareLayersDrawn(least, most);
        s->info_.gpuBufferBytes += m.forest->bufferBytes() - before;
      }
    }
  }
  // Real-time scheduling for this (the render) thread only: every thread started above keeps
  // normal scheduling; threads started later reset themselves (ig/realtime.h).
  RealtimeSettings rt;
  rt.priority = config.realtimePriority;
  rt.cpus = config.cpuAffinity;
  rt.lockMemory = config.lockMemory;
  if (!applyRealtime(rt, error)) return nullptr;
  s->info_.scheduling = describeScheduling();

  // Warm-up frame: the driver compiles shaders and faults in buffers on first use, which
  // would otherwise make frame 0 an overrun.
  s->renderOnce(s->host_, nullptr);
  const std::string glErr = m.renderer.errors();
  if (!glErr.empty()) {
    error = "GL errors during start-up: " + glErr;
    return nullptr;
  }
  return s;
}

FrameRecord Service::renderOnce(const io::HostState& host, render::Image* image) {
  Impl& m = *impl_;
  std::string error;
  if (!m.context->makeCurrent(error)) {  // no GL work in another context: nothing rendered
    std::fprintf(stderr, "igd: renderOnce: %s\n", error.c_str());
    if (image) *image = render::Image{};
    return FrameRecord{};
  }
  const lod::Camera cam = m.cameraFor(host);
  m.select(cam, nullptr, std::nan(""), host.simTime_s);
  const render::RenderStats st = m.submit(cam, host);
  m.renderer.finish();
  if (image) m.renderer.readPixels(*image);
  return m.record(st, host, cam);
}

// A reload in progress: the configs are read on a short-lived thread.
struct PendingReload {
  std::thread thread;
  std::atomic<bool> done{false};
  bool ok = false;
  ServiceConfig config;
  SceneConfig scene;
  std::string error;
};

int Service::run(Clock& clock, const std::atomic<bool>& stop, ReloadSource* reload) {
  Impl& m = *impl_;
  const ServiceConfig& cfg = m.config;
  StatsWriter stats;
  std::string error;
  if (!m.context->makeCurrent(error)) {
    std::fprintf(stderr, "igd: the GL context: %s\n", error.c_str());
    return 3;  // before the first frame
  }
  if (!cfg.statsFile.empty()) {
    std::error_code ec;  // a failure here shows up as the open error below
    std::filesystem::create_directories(std::filesystem::path(cfg.statsFile).parent_path(), ec);
    std::string layers;
    for (const auto& l : info_.layers) layers += (layers.empty() ? "\"" : ",\"") + l + "\"";
    char runInfo[512];
    std::snprintf(runInfo, sizeof runInfo,
                  "\"rate_hz\":%.3f,\"width_px\":%d,\"height_px\":%d,\"layers\":[%s],\"passes\":%u,"
                  "\"gpu_buffer_bytes\":%llu,\"threads\":%u,\"terrain_build_ms\":%.1f",
                  cfg.rate_hz, cfg.width_px, cfg.height_px, layers.c_str(), info_.passes,
                  static_cast<unsigned long long>(info_.gpuBufferBytes), info_.threads, info_.terrainBuild_ms);
    StatsRotation rotation;
    rotation.maxBytes = static_cast<uint64_t>(cfg.statsMax_mb * 1048576.0);
    rotation.keep = cfg.statsKeep;
    if (!stats.open(cfg.statsFile, cfg.statsFormat, runInfo, error, rotation)) {
      std::fprintf(stderr, "igd: %s\n", error.c_str());
      return 3;  // a start-up failure, before the first frame (README: exit codes)
    }
  }

  SystemdNotifier notifier(cfg.watchdogInterval_s);
  if (!notifier.warning().empty()) std::fprintf(stderr, "igd: %s\n", notifier.warning().c_str());
  io::HostLink* link = m.hostInput ? m.hostInput->link() : nullptr;
  // Synchronous host (CIGI sync mode): the host's messages pace the frames; the configured
  // rate is the fallback when the host is silent (wait at most one period per frame).
  const bool hostPaced = link != nullptr && link->synchronous();
  FramePacer pacer(clock, cfg.rate_hz, cfg.freeRun || hostPaced, cfg.budgetFrame_ms);
  const double morphTimeBase_s = m.morphTimeBase_s;
  // The summary counts every run's frames: its overruns and missed slots too, also on a
  // return from the middle of the loop.
  struct AddCounts {
    Impl& m;
    const FramePacer& pacer;
    ~AddCounts() {
      m.overruns += pacer.overruns();
      m.missed += pacer.missedSlots();
    }
  } addCounts{m, pacer};
  const int64_t loopStart_ns = clock.now_ns();
  m.loopStart_ns = loopStart_ns;
  pacer.startAt(loopStart_ns);
  if (m.hostInput) m.hostInput->setTimeBase(clock, loopStart_ns);
  if (hostPaced) {
    // The wait for the host's next message comes before the frame, not in its input phase: it
    // is no work, and a frame that waited for the host is no overrun.
    pacer.setWait([this, &pacer](int64_t) {
      mailbox_.waitNewer(mailboxSequence_, std::chrono::nanoseconds(pacer.period_ns()));
      return true;
    });
  } else if (!cfg.freeRun) {
    // A long period (rate_hz goes down to 0.01: 100 s) is slept in pieces of at most a second
    // (and the watchdog interval): the watchdog is pinged and a stop request (SIGTERM) seen
    // within a piece, not a period later, after systemd's WatchdogSec or TimeoutStopSec. The
    // pacer sleeps the last piece.
    const int64_t piece_ns =
        notifier.watchdogEnabled() ? std::clamp<int64_t>(notifier.watchdogInterval_ns(), 10'000'000, 1'000'000'000)
                                   : 1'000'000'000;
    pacer.setWait([&clock, &stop, &notifier, piece_ns](int64_t slot_ns) {
      for (int64_t now = clock.now_ns(); slot_ns - now > piece_ns;) {
        if (stop.load(std::memory_order_relaxed)) return false;
        clock.sleepUntil_ns(now + piece_ns);
        const int64_t after = clock.now_ns();
        notifier.watchdog(after);
        if (after <= now) break;  // a clock that does not move (tests): the pacer's sleep decides
        now = after;
      }
      return !stop.load(std::memory_order_relaxed);
    });
  }
  // The health report exists only where someone reads it: systemd or a status file.
  // A reload that changes the file or the interval keeps the totals (frames, overruns, missed
  // slots): the running reporter is reconfigured, a new one starts from the pacer's counts.
  std::unique_ptr<StatusReporter> status;
  bool statusErrorLogged = false;
  auto makeStatus = [&] {
    if (notifier.underSystemd() || !cfg.statusFile.empty()) {
      if (status) {
        status->reconfigure(cfg.statusFile, cfg.statusInterval_s, cfg.rate_hz);
      } else {
        status = std::make_unique<StatusReporter>(cfg.statusFile, cfg.statusInterval_s, cfg.rate_hz);
        status->setTotals(pacer.frames(), pacer.overruns(), pacer.missedSlots());
        status->start(clock.now_ns());
      }
    } else {
      // A reload that switches the report off: its file goes too, as when it moves (left, it
      // would say "running" forever).
      if (status) status->reconfigure(std::string(), cfg.statusInterval_s, cfg.rate_hz);
      status.reset();
    }
    statusErrorLogged = false;
  };
  makeStatus();
  std::string layerList;
  for (const auto& l : info_.layers) layerList += (layerList.empty() ? "" : ", ") + l;
  auto statusContext = [&](const char* state) {
    StatusContext c;
    c.state = state;
    c.rate_hz = cfg.rate_hz;
    c.budgetFrame_ms = pacer.budget_ms();
    c.budgetTriangles = cfg.budgetTriangles;
    c.hostSource = toString(cfg.host);
    c.hostLost = m.hostInput && m.hostInput->lost();
    if (link) {
      c.haveLink = true;
      c.link = io::snapshot(link->counters());
      c.haveHatHot = link->hatHotCounters(c.hatHot);
    }
    c.hostRejected = hostRejected_;
    c.configGeneration = m.generation;
    c.lastReloadError = m.lastReloadError;
    c.layers = layerList;
    c.scheduling = info_.scheduling;
    if (m.governor) {
      c.haveGovernor = true;
      const std::array<double, lod::kGovLayers> d = m.governorDetail();
      c.terrainTolerance_px = d[static_cast<size_t>(lod::GovLayer::Terrain)];
      c.forestNear_m = d[static_cast<size_t>(lod::GovLayer::Forest)];
      c.forestLayers = d[static_cast<size_t>(lod::GovLayer::ForestLayers)];
      c.hdlodTolerance_px = d[static_cast<size_t>(lod::GovLayer::Hdlod)];
      c.cellsVoxelBudget = d[static_cast<size_t>(lod::GovLayer::Cells)];
      const lod::GovStats& g = m.governor->stats();
      c.governorDecreases = g.decreases;
      c.governorIncreases = g.increases;
      c.governorEmergencies = g.emergencies;
    }
    return c;
  };
  // Writes what is queued and logs the snapshots that were dropped or failed.
  auto reportSnapshots = [](SnapshotWriter& w) {
    w.flush();
    if (w.failed() > 0 || w.dropped() > 0)
      std::fprintf(stderr, "igd: snapshots: %llu written, %llu dropped (writer busy), %llu failed (first: %s)\n",
                   static_cast<unsigned long long>(w.written()), static_cast<unsigned long long>(w.dropped()),
                   static_cast<unsigned long long>(w.failed()), w.firstError().c_str());
  };
  // A snapshot writer a reload switched off finishes its queue here, off the render thread (a
  // queued full-size PNG takes tens of milliseconds: the reload must not cost a frame).
  std::thread retiredSnapshots;
  std::unique_ptr<PendingReload> pending;
  // Between two frames: takes the reloadable keys of a finished reload.
  auto applyReloadFailed = [&](const PendingReload& p, int64_t frame) {
    m.lastReloadError = p.error;
    std::fprintf(stderr, "igd: reload failed after frame %lld, the running config is unchanged: %s\n",
                 static_cast<long long>(frame), p.error.c_str());
  };
  auto applyReload = [&](PendingReload& p, int64_t frame) {
    if (!p.ok) {
      applyReloadFailed(p, frame);
      return;
    }
    ServiceConfig mc;
    SceneConfig ms;
    const ReloadPlan plan = planReload(m.config, m.scene, p.config, p.scene, mc, ms, m.snapshotsAtStartup);
    // W below the largest cell: that cell could never be fetched (create() refuses it at start-up).
    if (m.cells && ms.cells && !m.cells->checkByteBudget(ms.cells->wBytes, p.error)) {
      p.ok = false;
      applyReloadFailed(p, frame);
      return;
    }
    if (m.governor) {
      // The governor's config comes from both files and the layers; Governor::reconfigure only
      // asserts it. One it refuses fails the reload like a bad file (nothing applied).
      const std::string why = lod::Governor::validate(m.governorConfig(mc, ms));
      if (!why.empty()) {
        p.ok = false;
        p.error = p.config.path + ": governor." + why;
        applyReloadFailed(p, frame);
        return;
      }
    }
    // Snapshots switched on again after a reload switched them off (planReload allows it only
    // when they were on at start-up): the folder may have gone since.
    const bool wantsSnapshots = mc.snapshotEvery > 0 || !mc.snapshotFrames.empty();
    if (wantsSnapshots && !m.snapshots) {
      std::error_code ec;
      std::filesystem::create_directories(mc.snapshotDir, ec);
      if (ec) {
        p.ok = false;
        p.error = p.config.path + ": output.snapshot_dir '" + mc.snapshotDir + "': cannot create: " + ec.message();
        applyReloadFailed(p, frame);
        return;
      }
    }
    const bool statusChanged = mc.statusFile != cfg.statusFile || mc.statusInterval_s != cfg.statusInterval_s;
    m.config = std::move(mc);  // `cfg` refers to m.config
    m.scene = std::move(ms);
    // More frames than at start-up: the exit summary's percentiles still cover the run's last
    // kMaxCapacity frames (sized by the start-up frames, they covered only that many).
    m.summary.grow(SummaryCollector::capacityFor(cfg.frames));
    ++m.generation;
    m.lastReloadError.clear();
    pacer.setBudget_ms(cfg.budgetFrame_ms);
    if (m.hostInput) m.hostInput->setLinkTimeout(cfg.linkTimeout_s);
    m.setLighting();
    if (m.terrainMesh && m.scene.terrain) {
      m.terrainMesh->tolerance_px = m.scene.terrain->tolerance_px;
      m.terrainMesh->budget_ms = m.scene.terrain->lodBudget_ms;
    }
    if (m.cells && m.scene.cells)
      m.cells->setBudgets(m.scene.cells->voxelBudget, m.scene.cells->wBytes, m.scene.cells->minVoxel_px);
    if (statusChanged) makeStatus();
    if (m.governor) m.governor->reconfigure(m.governorConfig());
    if (m.governor && m.forest) {
      // Layer counts the new [governor.forest] bounds allow: made now, between two frames, as
      // create() does, not in the late frame whose cut first needs one.
      const uint64_t before = m.forest->bufferBytes();
      const auto [least, most] = m.forestLayerBounds();
      m.forest->prepareLayersDrawn(least, most);
      info_.gpuBufferBytes += m.forest->bufferBytes() - before;
    }
    // An unused subsystem costs nothing: snapshots switched off release their thread and image
    // slots (after writing what is queued); switched on again, they get new ones.
    if (!wantsSnapshots && m.snapshots) {
      if (retiredSnapshots.joinable()) retiredSnapshots.join();
      retiredSnapshots = std::thread([w = std::move(m.snapshots), &reportSnapshots]() mutable {
        normalScheduling();
        reportSnapshots(*w);
        w.reset();  // joins the writer's thread
      });
      --info_.threads;
    } else if (wantsSnapshots && !m.snapshots) {
      // Made on a helper thread with normal scheduling: the writer thread inherits its creator's
      // policy and CPUs, and must not run as the real-time render thread does (ig/realtime.h).
      std::thread([&] {
        normalScheduling();
        m.snapshots = std::make_unique<SnapshotWriter>(3, cfg.width_px, cfg.height_px);
      }).join();
      ++info_.threads;
    }
    std::fprintf(stderr,
                 "igd: config reloaded after frame %lld (#%d): applied: %s; needs a restart (running value kept): %s\n",
                 static_cast<long long>(frame), m.generation, joinKeys(plan.applied).c_str(),
                 joinKeys(plan.needRestart).c_str());
  };
  notifier.ready("rendering at " + std::to_string(cfg.rate_hz) + " Hz");
  std::string why;
  bool statsErrorLogged = false;
  bool statsRotateLogged = false;
  auto logRotateError = [&] {
    if (!stats.rotateError().empty() && !statsRotateLogged) {
      std::fprintf(stderr, "igd: %s; the file is not rotated (it grows past stats.max_mb)\n", stats.rotateError().c_str());
      statsRotateLogged = true;
    }
  };
  logRotateError();  // at start-up: the previous run's file could not be kept
  bool hostWasBad = false;
  bool prevOverrun = false;
  char snapshotPath[4096];
  int64_t prevSlot = -1;  // the previous frame's slot (snapshots)

  while (!stop.load(std::memory_order_relaxed)) {
    if (cfg.frames > 0 && pacer.frames() >= cfg.frames) break;
    if (m.context->closeRequested()) break;
    const int64_t slot = pacer.beginFrame();
    if (slot < 0) break;  // stopped while waiting for the slot

    // input
    if (m.replay) m.replay->advanceTo(pacer.slotTime_s(slot), mailbox_);
    io::HostState incoming;
    if (mailbox_.readIfNewer(incoming, mailboxSequence_)) {
      if (hostStateValid(incoming, &why)) {
        host_ = incoming;
        const lod::Geodetic g = m.enu->toGeodetic(host_.eyeEnu_m);
        host_.lat_deg = g.lat_deg;
        host_.lon_deg = g.lon_deg;
        host_.height_m = g.height_m;
        if (hostWasBad) std::fprintf(stderr, "igd: host input valid again at host frame %llu\n",
                                     static_cast<unsigned long long>(incoming.hostFrame));
        hostWasBad = false;
      } else {
        ++hostRejected_;
        if (!hostWasBad)
          std::fprintf(stderr, "igd: host sample rejected (%s); keeping the last good eyepoint\n", why.c_str());
        hostWasBad = true;
      }
    }
    const bool lost = m.hostInput && m.hostInput->updateLost();
    if (link) {
      io::FrameStart fs;
      fs.igFrame = static_cast<uint32_t>(slot);
      fs.lastHostFrame = static_cast<uint32_t>(host_.hostFrame);
      fs.time_s = static_cast<double>(clock.now_ns() - loopStart_ns) * 1e-9;
      fs.hostLost = lost;
      fs.overrun = prevOverrun;
      fs.host = &host_;
      fs.terrain = m.hasGround ? &m.ground : nullptr;
      if (m.hdlod) m.hdlod->setQueryTime(host_.simTime_s);  // where this frame draws the objects
      fs.objects = m.surfaces.empty() ? nullptr : &m.surfaces;
      link->frameStarted(fs);
    }
    pacer.endPhase(Phase::Input);

    // lod
    const lod::Camera cam = m.cameraFor(host_);
    m.select(cam, &clock, morphTimeBase_s + pacer.slotTime_s(slot), host_.simTime_s);
    m.morphTimeBase_s = morphTimeBase_s + pacer.slotTime_s(slot + 1);
    pacer.endPhase(Phase::Lod);

    // submit
    const render::RenderStats st = m.submit(cam, host_, &clock);
    pacer.endPhase(Phase::Submit);

    // gpu
    m.renderer.finish();
    pacer.endPhase(Phase::GpuFinish);

    // present
    if (m.context->hasWindow()) m.context->present(m.renderer.framebuffer(), cfg.width_px, cfg.height_px);
    // Snapshot numbers are slot numbers (the stats' frame column, which fixes the simulation
    // time). A number skipped with missed slots goes to the first frame after it, which is named
    // by its own slot.
    bool snap = cfg.snapshotEvery > 0 && slot / cfg.snapshotEvery * cfg.snapshotEvery > prevSlot;
    for (int64_t f : cfg.snapshotFrames) snap = snap || (f > prevSlot && f <= slot);
    prevSlot = slot;
    if (snap && m.snapshots) {
      // Read back here; encode and write on the snapshot thread.
      if (render::Image* image = m.snapshots->acquire()) {
        m.renderer.readPixels(*image);
        std::snprintf(snapshotPath, sizeof snapshotPath, "%s/frame_%06lld.png", cfg.snapshotDir.c_str(),
                      static_cast<long long>(slot));
        m.snapshots->submit(image, snapshotPath);
      }
    }
    pacer.endPhase(Phase::Present);

    // report
    FrameRecord r = m.record(st, host_, cam);
    r.uploads = m.terrainMesh ? m.terrainMesh->uploadedTriangles : 0;
    r.hostLost = lost;
    if (m.governor) {
      // What this frame was drawn with (update() below chooses the next frame's).
      r.predicted_ms = m.governor->predicted_ms();
      if (m.terrainMesh) r.terrainTolerance_px = m.terrainMesh->tolerance_px;
      if (m.forest) r.forestNear_m = m.forest->nearDistance();
      if (m.forest) r.forestLayers = m.forest->layersDrawn();
      if (m.hdlod) r.hdlodTolerance_px = m.hdlod->tolerance_px();
      if (m.cells) r.cellsVoxelBudget = static_cast<double>(m.cells->voxelBudget());
    }
    r.timing = pacer.endFrame();
    prevOverrun = r.timing.overrun;
    if (m.governor) {
      lod::GovSample gs;
      gs.phase_ms[static_cast<size_t>(lod::GovPhase::Input)] = r.timing.phase_ms[static_cast<size_t>(Phase::Input)];
      gs.phase_ms[static_cast<size_t>(lod::GovPhase::Terrain)] = m.terrainSelect_ms;
      gs.phase_ms[static_cast<size_t>(lod::GovPhase::Submit)] = r.timing.phase_ms[static_cast<size_t>(Phase::Submit)];
      gs.phase_ms[static_cast<size_t>(lod::GovPhase::Gpu)] = r.timing.phase_ms[static_cast<size_t>(Phase::GpuFinish)];
      gs.phase_ms[static_cast<size_t>(lod::GovPhase::Forest)] = m.forestSelect_ms;
      gs.phase_ms[static_cast<size_t>(lod::GovPhase::Hdlod)] = m.hdlodSelect_ms;
      gs.phase_ms[static_cast<size_t>(lod::GovPhase::Cells)] = m.cellsSelect_ms;
      // Loads: what each layer drew (absent layers are ignored whatever they hold).
      if (m.terrainMesh) gs.load[static_cast<size_t>(lod::GovLayer::Terrain)] = static_cast<double>(m.terrainMesh->emitted);
      if (m.forest) gs.load[static_cast<size_t>(lod::GovLayer::Forest)] = static_cast<double>(m.forest->stats().treesDrawn);
      if (m.forest) gs.load[static_cast<size_t>(lod::GovLayer::ForestLayers)] = static_cast<double>(m.forest->stats().layers);
      if (m.hdlod) gs.load[static_cast<size_t>(lod::GovLayer::Hdlod)] = static_cast<double>(m.hdlod->stats().select.triangles);
      if (m.cells) gs.load[static_cast<size_t>(lod::GovLayer::Cells)] = static_cast<double>(m.cells->stats().select.drawnVoxels);
      gs.frame_ms = r.timing.work_ms;
      m.governor->update(gs);
    }
    r.period_ms = pacer.period_s() * 1e3;
    stats.write(r);
    if (!stats.error().empty() && !statsErrorLogged) {
      std::fprintf(stderr, "igd: %s; stats lines are being lost\n", stats.error().c_str());
      statsErrorLogged = true;
    }
    logRotateError();
    m.summary.add(r);
    const int64_t now = clock.now_ns();
    notifier.watchdog(now);
    if (status) {
      status->addFrame(r.timing, r.triangles);
      if (status->due(now)) {
        notifier.status(status->report(now, statusContext("running")));
        if (!status->fileError().empty() && !statusErrorLogged) {
          std::fprintf(stderr, "igd: %s (the report goes on to systemd only)\n", status->fileError().c_str());
          statusErrorLogged = true;
        }
      }
    }

    // reload: read the files off the render thread, apply between frames
    if (reload) {
      if (!pending && reload->requested.exchange(false)) {
        pending = std::make_unique<PendingReload>();
        PendingReload* p = pending.get();
        p->thread = std::thread([p, reload] {
          normalScheduling();
          p->ok = reload->load(p->config, p->scene, p->error);
          p->done.store(true, std::memory_order_release);
        });
      }
      if (pending && pending->done.load(std::memory_order_acquire)) {
        pending->thread.join();
        applyReload(*pending, r.timing.frame);
        pending.reset();
      }
    }
  }
  if (pending) pending->thread.join();
  if (!stats.close() && !statsErrorLogged) std::fprintf(stderr, "igd: %s\n", stats.error().c_str());
  if (status) notifier.status(status->report(clock.now_ns(), statusContext("stopping")));
  notifier.stopping();
  if (m.hostInput) {
    m.hostInput->stop();
    const std::string line = m.hostInput->countersLine();
    if (!line.empty()) std::fprintf(stderr, "%s\n", line.c_str());
    if (HostRecorder* rec = m.hostInput->recorder()) {
      std::fprintf(stderr, "igd: recorded %llu host samples to %s\n", static_cast<unsigned long long>(rec->written()),
                   rec->file().c_str());
      if (rec->failed() > 0)
        std::fprintf(stderr, "igd: %llu host samples were not recorded (first: %s)\n",
                     static_cast<unsigned long long>(rec->failed()), rec->firstError().c_str());
    }
  }
  if (retiredSnapshots.joinable()) retiredSnapshots.join();
  if (m.snapshots) reportSnapshots(*m.snapshots);
  if (m.governor) {
    const lod::GovStats& g = m.governor->stats();
    const std::array<double, lod::kGovLayers> d = m.governorDetail();
    std::string knobs;
    char buf[160];
    for (int l = 0; l < lod::kGovLayers; ++l) {
      const double v = d[static_cast<size_t>(l)];
      if (std::isnan(v)) continue;
      const char* sep = knobs.empty() ? "" : ", ";
      switch (static_cast<lod::GovLayer>(l)) {
        case lod::GovLayer::Terrain: std::snprintf(buf, sizeof buf, "%sterrain tolerance now %.2f px", sep, v); break;
        case lod::GovLayer::Forest: std::snprintf(buf, sizeof buf, "%sforest near distance now %.0f m", sep, v); break;
        case lod::GovLayer::Hdlod: std::snprintf(buf, sizeof buf, "%shdlod tolerance now %.2f px", sep, v); break;
        case lod::GovLayer::Cells: std::snprintf(buf, sizeof buf, "%scells voxel budget now %.0f", sep, v); break;
        case lod::GovLayer::ForestLayers: std::snprintf(buf, sizeof buf, "%sforest shell layers now %.0f", sep, v); break;
        case lod::GovLayer::Count: buf[0] = '\0'; break;
      }
      knobs += buf;
    }
    int64_t reversals = 0;
    for (int64_t n : g.directionChanges) reversals += n;
    std::fprintf(stderr,
                 "igd: governor: %s; %lld decreases, %lld increases, %lld emergencies, "
                 "%lld direction changes, prediction error scale %.2f ms, %lld bad measurements ignored\n",
                 knobs.c_str(), static_cast<long long>(g.decreases), static_cast<long long>(g.increases),
                 static_cast<long long>(g.emergencies), static_cast<long long>(reversals), g.errorScale_ms,
                 static_cast<long long>(g.ignored));
  }
  if (m.cells) std::fprintf(stderr, "igd: %s\n", m.cells->summaryLine().c_str());
  const std::string glErr = m.renderer.errors();
  if (!glErr.empty()) {
    std::fprintf(stderr, "igd: GL errors during the run: %s\n", glErr.c_str());
    return 1;
  }
  return 0;
}

const io::HostLink* Service::hostLink() const { return impl_->hostInput ? impl_->hostInput->link() : nullptr; }
int64_t Service::loopStart_ns() const { return impl_->loopStart_ns; }
bool Service::hostLost() const { return impl_->hostInput && impl_->hostInput->lost(); }

int Service::configGeneration() const { return impl_->generation; }

RunSummary Service::summary() const { return impl_->summary.summarize(impl_->overruns, impl_->missed); }

}  // namespace ig
