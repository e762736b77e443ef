// Hard cases of the renderer core the other GL tests leave out (docs/hard_cases.md has the whole
// matrix): degenerate triangles in the terrain mesh (renderer.h: they mark free slots) draw
// nothing, alone or between ordinary triangles, also with the eye 0.1 m above the ground, the
// near plane at 0.1 m and the far plane at 100 km, and ~1e7 m from the origin.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "lod/terrain_grid.h"
#include "lod/view.h"
#include "render/context.h"
#include "render/image.h"
#include "render/renderer.h"

using namespace ig;

namespace {

lod::TerrainVertex vertex(float x, float y, float z) { return {{x, y, z}, {0.0f, 0.0f, 1.0f}}; }

// Two triangles of a 400 m ground square around (0, 0), counter-clockwise from above.
void addQuad(std::vector<lod::TerrainVertex>& v) {
  const float s = 200.0f;
  for (const auto& p : {vertex(-s, -s, 0), vertex(s, -s, 0), vertex(s, s, 0), vertex(-s, -s, 0), vertex(s, s, 0),
                        vertex(-s, s, 0)})
    v.push_back(p);
}

// Zero-area triangles: three equal vertices (a free slot), collinear vertices, two equal.
void addDegenerate(std::vector<lod::TerrainVertex>& v) {
  for (const auto& p : {vertex(0, 0, 0), vertex(0, 0, 0), vertex(0, 0, 0), vertex(-50, 3, 0), vertex(0, 3, 0),
                        vertex(50, 3, 0), vertex(10, 10, 0), vertex(10, 10, 0), vertex(40, 10, 0)})
    v.push_back(p);
}

render::Image frame(render::Renderer& r, const lod::Camera& cam, const glm::dvec3& origin,
                    const std::vector<lod::TerrainVertex>& v) {
  r.beginFrame(cam, render::Lighting{});
  r.drawTerrainMesh(origin, v);
  r.endFrame();
  r.finish();
  render::Image img;
  r.readPixels(img);
  return img;
}

}  // namespace

TEST(HardCasesGL, DegenerateTerrainTrianglesDrawNothing) {
  std::string error;
  auto ctx = render::createContext(render::ContextKind::Headless, 64, 64, error);
  ASSERT_TRUE(ctx) << error;
  render::Renderer r;
  ASSERT_TRUE(r.init(64, 64, error)) << error;
  ASSERT_TRUE(r.addTerrainMesh(64, 40.0, error)) << error;
  for (const glm::dvec3 origin : {glm::dvec3(0.0), glm::dvec3(4.1e6, -1.0e7, 300.0)}) {
    for (double pitch : {-90.0, -10.0}) {
      lod::Camera cam;
      cam.eye_m = origin + glm::dvec3(0.25, -0.5, 0.1);  // 0.1 m above the ground
      cam.pitch_deg = pitch;
      cam.fovY_deg = 60;
      cam.aspect = 1.0;
      cam.near_m = 0.1;
      cam.far_m = 1.0e5;
      std::vector<lod::TerrainVertex> none, degenerate, quad, mixed;
      addDegenerate(degenerate);
      addQuad(quad);
      addDegenerate(mixed);
      addQuad(mixed);
      addDegenerate(mixed);
      const render::Image empty = frame(r, cam, origin, none);
      const render::Image onlyDegenerate = frame(r, cam, origin, degenerate);
      const render::Image ground = frame(r, cam, origin, quad);
      const render::Image both = frame(r, cam, origin, mixed);
      EXPECT_EQ(r.errors(), "");
      ASSERT_EQ(empty.rgba.size(), 64u * 64u * 4u);
      EXPECT_EQ(onlyDegenerate.rgba, empty.rgba) << "pitch " << pitch << " origin " << origin.x;
      EXPECT_GT(render::fractionDifferent(ground, empty, 8), 0.2) << "pitch " << pitch;  // the ground is drawn
      EXPECT_EQ(both.rgba, ground.rgba) << "pitch " << pitch << " origin " << origin.x;
    }
  }
}
