// Turns draw lists into GL work. Everything is drawn camera-relative into an off-screen FBO
// with a reverse-Z float depth buffer (glClipControl zero-to-one, depth cleared to 0, test
// GREATER), so a 0.1 m near plane and a 100 km far plane do not z-fight. A pass exists only
// for a layer the scene has: no terrain in the scene, no terrain buffers or program.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include <glm/vec3.hpp>

#include "lod/terrain_chunks.h"
#include "lod/terrain_grid.h"
#include "lod/view.h"
#include "render/image.h"

namespace ig::render {

// Koschmieder fog: a surface at distance d keeps exp(-kFogExtinction * d / visibility) of its
// colour (2 % at the meteorological visibility: ln 50); the rest is the fog colour, which is also
// the sky's.
inline constexpr double kFogExtinction = 3.912;
// Beyond this distance the fog lets less than 1/1024 of a surface's colour through, so a pixel
// there differs from the sky by under a quarter of an 8-bit level (1.77 x the visibility). The
// service uses it as the far plane while fog is on ([fog] cull): nothing beyond is drawn.
inline double fogOpaqueDistance_m(double visibility_m) { return visibility_m * (6.931471805599453 / kFogExtinction); }  // ln 1024

struct Lighting {
  glm::dvec3 sunDirection{0.0, 0.0, 1.0};  // ENU, unit, towards the sun
  glm::dvec3 sunColor{1.0};
  double ambient = 0.25;
  bool fog = true;
  double fogVisibility_m = 20000.0;
  glm::dvec3 fogColor{0.7, 0.78, 0.86};    // also the sky/background colour
  double daylight = 1.0;                   // lod::sunlightFraction of the sun's elevation (daylight()):
                                           // 1 by day, 0 at night; colours baked in daylight dim by it
};

// `full` (daylight) dimmed for a sun at `elevation_deg`: night dims sun, ambient light and sky
// together (lod::sunlightFraction = `day`): sun colour * day, ambient * ambientScale(day), fog and
// sky colour * (0.08 + 0.92 day); `daylight` = day. Whether the sun is a scene's or a host's time
// of day.
Lighting daylight(const Lighting& full, double elevation_deg);
inline double ambientScale(double day) { return 0.15 + 0.85 * day; }

struct RenderStats {
  uint64_t triangles = 0;
  uint32_t drawCalls = 0;
  uint32_t passes = 0;
};

class TerrainPass;

// Terrain within these distances of the eye is shaded with its near-ground detail: 2 m value
// noise faded out by 400 m, 0.25 m noise faded out by 40 m. Beyond them cheaper program variants
// draw the same colours (the noise terms are 0 there).
inline constexpr double kTerrainDetailReach_m = 400.0;
inline constexpr double kTerrainFineDetailReach_m = 40.0;

class Renderer {
 public:
  Renderer();
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Creates the FBO. A GL context must be current (render/context.h). `samples` > 1 draws into
  // a multisampled FBO (MSAA: 2, 4 or 8, at most what GL_MAX_SAMPLES allows; anything else is
  // an error naming the value) that readPixels() and framebuffer() resolve into a single-sample
  // one. Edges and sub-pixel parts (window frames, lattices, wires) then cover the share of the
  // pixel they really cover instead of all or nothing, at the price of fill rate.
  bool init(int width_px, int height_px, std::string& error, int samples = 1);
  int samples() const { return samples_; }
  // Uploads a terrain once (start-up). Creates the terrain pass.
  bool addTerrain(const lod::TerrainGrid& grid, std::string& error);
  bool hasTerrain() const { return terrain_ != nullptr; }
  // Creates the pass for a terrain triangle list that changes every frame (ROAM, block LOD),
  // with a vertex buffer of `capacityVertices` allocated once and mapped persistently. The
  // shading places a vertex's height within the relief: (z - heightBase_m) / heightScale_m,
  // z relative to the mesh origin (a DEM's lowest post is its base, not 0).
  bool addTerrainMesh(size_t capacityVertices, double heightScale_m, std::string& error, double heightBase_m = 0.0);
  // The mapped vertex buffer of the terrain mesh (empty without one): write only what changed
  // (lod/triangle_slots.h), between frames (every frame ends with glFinish).
  std::span<lod::TerrainVertex> terrainMeshVertices() const;

  // One frame: begin (clear), draw the selected items of each pass, end.
  // A camera with a NaN / infinite eye, angle or aspect, a field of view outside (0, 180) deg,
  // near <= 0 or far <= near (or infinite) is refused: the frame keeps the last good camera (the
  // default Camera before any) and errors() reports it, naming the values.
  void beginFrame(const lod::Camera& camera, const Lighting& lighting);
  void drawTerrain(std::span<const uint32_t> chunkIndices);
  // Draws the first `vertexCount` vertices of the mapped buffer (3 a triangle, positions
  // relative to `origin_m`; degenerate triangles mark free slots). `nearest_m`: a lower bound on
  // the distance from the eye to the mesh; the ground detail terms whose reach it exceeds are
  // left out (they are 0 there anyway): up to a third less fragment work.
  void drawTerrainMesh(const glm::dvec3& origin_m, size_t vertexCount, double nearest_m = 0.0);
  // Draws ranges of triangle slots of the mapped buffer (the chunks of lod/terrain_chunks.h inside
  // the frustum): one multi-draw for the ranges marked near (with the detail; `nearest_m`: a
  // lower bound on their distance from the eye, TerrainChunks::cull's), one for the rest.
  // Pass kTerrainDetailReach_m to TerrainChunks::cull().
  void drawTerrainMeshRanges(const glm::dvec3& origin_m, std::span<const lod::TerrainDrawRange> ranges,
                             double nearest_m = 0.0);
  // Convenience: copies a whole triangle list into the mapped buffer, then draws it.
  void drawTerrainMesh(const glm::dvec3& origin_m, std::span<const lod::TerrainVertex> vertices);
  RenderStats endFrame();
  // Blocks until the GPU has finished the frame (timing with a monotonic clock: timer
  // queries are not trustworthy on llvmpipe).
  void finish();
  // Reads the finished frame, top row first.
  void readPixels(Image& out);

  // The finished frame's single-sample framebuffer (a multisampled frame is resolved into it
  // first, once per frame).
  unsigned framebuffer();
  // For passes that live in their own files (render/<part>_pass.*): the frame's camera and
  // lighting (valid between beginFrame and endFrame), and a place to add what they drew so
  // endFrame's stats cover every pass. Such a pass binds its own program and VAO and leaves
  // the FBO, viewport, depth state (reverse-Z, GL_GREATER) as beginFrame set them.
  const lod::Camera& camera() const { return camera_; }
  const Lighting& lighting() const { return lighting_; }
  void addStats(uint64_t triangles, uint32_t drawCalls) {
    stats_.triangles += triangles;
    stats_.drawCalls += drawCalls;
  }
  // GL name of the terrain mesh's vertex buffer (lod::TerrainVertex layout), 0 without one.
  unsigned terrainMeshVertexBuffer() const;
  int width() const { return width_; }
  int height() const { return height_; }
  // Bytes of GPU buffers owned by passes (0 when the scene has no layers).
  uint64_t bufferBytes() const;
  uint32_t passCount() const { return (terrain_ ? 1u : 0u) + (terrainMesh_ ? 1u : 0u); }
  // Pending GL errors and refused cameras (beginFrame), "" if none; reading clears them.
  std::string errors() const;

 private:
  struct Target;
  std::unique_ptr<Target> target_;
  std::unique_ptr<TerrainPass> terrain_;
  std::unique_ptr<TerrainPass> terrainMesh_;
  int width_ = 0, height_ = 0, samples_ = 1;
  bool resolved_ = true;
  void resolve();
  lod::Camera camera_;
  mutable std::string cameraError_;  // the last refused camera, until errors() reads it
  Lighting lighting_;
  RenderStats stats_;
};

}  // namespace ig::render
