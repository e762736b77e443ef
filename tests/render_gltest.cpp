// GL tests on a real headless context (Mesa llvmpipe through EGL surfaceless): golden image
// of the default scene, the same view 1,000 km from the origin, reverse-Z against
// z-fighting at 0.1 m / 100 km, the OSMesa fallback, failed set-ups that leave no GL error, and
// several contexts (headless, and window contexts on an Xvfb the test starts) in one process.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <glm/gtc/type_ptr.hpp>

#include "gl_fixture.h"
#include "lod/heightfield.h"
#include "lod/terrain_grid.h"
#include "lod/view.h"
#include "render/context.h"
#include "render/gl.h"
#include "render/image.h"
#include "render/renderer.h"

using namespace ig;

namespace {

// ~1,000 km, a whole number of ground-detail periods (1024 m) so the detail pattern lines up.
constexpr double kFar_m = 977.0 * 1024.0;
// ~10,000 km (ECEF-like offsets, where a float's step is 1 m), also whole periods.
constexpr double kEcef_m = 9766.0 * 1024.0;

// The golden frame: frame 150 of the default run (30 Hz), i.e. replay time 5 s.
constexpr double kGoldenTime_s = 5.0;
const std::string kGolden = test::kSource + "/tests/golden/default_t5_320x180.png";

render::Image renderView(const io::HostState& view, glm::dvec3 worldShift_m, OutputMode mode = OutputMode::Headless,
                         int msaa = 1, int scale = 1) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  cfg.output = mode;
  cfg.msaa = msaa;
  cfg.width_px *= scale;
  cfg.height_px *= scale;
  for (int i = 0; i < 3; ++i) scene.terrain->offset_m[static_cast<size_t>(i)] += worldShift_m[i];
  std::string error;
  auto service = Service::create(cfg, scene, error);
  EXPECT_TRUE(service) << error;
  render::Image image;
  if (!service) return image;
  io::HostState host = view;
  host.eyeEnu_m += worldShift_m;
  const FrameRecord r = service->renderOnce(host, &image);
  EXPECT_GT(r.triangles, 0u);
  return image;
}

render::Image renderDefault(double time_s, glm::dvec3 worldShift_m, OutputMode mode = OutputMode::Headless) {
  return renderView(test::defaultHostAt(time_s), worldShift_m, mode);
}

}  // namespace

TEST(RenderGL, HeadlessContextIsGl45CoreOnEglWithoutEnvironment) {
  std::string error;
  auto ctx = render::createContext(render::ContextKind::Headless, 64, 64, error);
  ASSERT_TRUE(ctx) << error;
  EXPECT_NE(ctx->description().find("EGL"), std::string::npos) << ctx->description();
  EXPECT_NE(ctx->description().find("4.5"), std::string::npos) << ctx->description();
  EXPECT_FALSE(ctx->hasWindow());
}

TEST(RenderGL, DefaultSceneMatchesGoldenImage) {
  const render::Image image = renderDefault(kGoldenTime_s, {0, 0, 0});
  render::Image golden;
  std::string error;
  ASSERT_TRUE(render::readPng(kGolden, golden, error))
      << error << " (make it with: build/igtool render --width 320 --height 180 --time 5 --out " << kGolden << ")";
  const double e = render::rmse(image, golden);
  if (e > 2.0 || e < 0) {
    std::string failed;
    render::writePng(IG_BINARY_DIR "/golden_failed.png", image, failed);
  }
  EXPECT_GE(e, 0.0) << "size differs from the golden image";
  EXPECT_LE(e, 2.0) << "per-pixel RMSE in 8-bit levels; this frame written to build/golden_failed.png";
  // The frame shows terrain, not only sky: a sanity check that a blank image cannot pass.
  render::Image sky = image;
  for (size_t i = 0; i < sky.rgba.size(); i += 4)
    for (size_t c = 0; c < 3; ++c) sky.rgba[i + c] = golden.rgba[c];  // top-left pixel is sky
  EXPECT_GT(render::rmse(image, sky), 10.0);
}

TEST(RenderGL, SameViewOneThousandKilometresFromOriginMatches) {
  const render::Image origin = renderDefault(kGoldenTime_s, {0, 0, 0});
  const render::Image far = renderDefault(kGoldenTime_s, {kFar_m, kFar_m, 0.0});
  const double e = render::rmse(origin, far);
  EXPECT_GE(e, 0.0);
  EXPECT_LT(e, 0.5) << "camera-relative rendering must not jitter or shift far from the origin";
  EXPECT_LT(render::fractionDifferent(origin, far, 8), 0.001);
}

TEST(RenderGL, CloseUpOneThousandKilometresFromOriginMatches) {
  // 1 m above the ground, looking down at it, with an eyepoint that is not a float value
  // at 1e6 m: float world coordinates would move the ground by centimetres = several pixels.
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  const lod::TerrainGrid grid(terrainGridDesc(*scene.terrain));
  io::HostState h = test::defaultHostAt(0.0);
  h.eyeEnu_m = {123.47, -456.72, 0.0};  // 3 cm and 2 cm from the nearest float at 1e6 m
  h.eyeEnu_m.z = grid.heightAt(h.eyeEnu_m.x, h.eyeEnu_m.y) + 1.0;
  h.pitch_deg = -50.0;
  h.roll_deg = 0.0;
  const render::Image origin = renderView(h, {0, 0, 0});
  const render::Image far = renderView(h, {kFar_m, -kFar_m, 0.0});
  // Measured: 0.0 with camera-relative double maths; 0.78 if the eye-to-chunk offset is
  // computed in float (the classic jitter), so this bound separates the two.
  EXPECT_LT(render::rmse(origin, far), 0.1);
  EXPECT_LT(render::fractionDifferent(origin, far, 2), 0.001);
  // And at ECEF-like offsets (~1e7 m east and north, a float step of 1 m): the same picture.
  const render::Image ecef = renderView(h, {kEcef_m, -kEcef_m, 0.0});
  EXPECT_LT(render::rmse(origin, ecef), 0.1);
  EXPECT_LT(render::fractionDifferent(origin, ecef, 2), 0.001);
}

// MSAA ([output] msaa): the terrain's silhouette against the sky and the far hills are
// anti-aliased, so 4 samples per pixel come closer to a 2x2 supersampled reference (rendered at
// twice the size, box-filtered) than 1 sample does; a bad sample count is refused by name.
TEST(RenderGL, MsaaComesCloserToSupersamplingAndBadCountsAreRefused) {
  const io::HostState view = test::defaultHostAt(kGoldenTime_s);
  const render::Image one = renderView(view, {0, 0, 0}, OutputMode::Headless, 1);
  const render::Image four = renderView(view, {0, 0, 0}, OutputMode::Headless, 4);
  const render::Image big = renderView(view, {0, 0, 0}, OutputMode::Headless, 1, 2);
  ASSERT_EQ(big.width, 2 * one.width);
  render::Image reference = one;
  for (int y = 0; y < one.height; ++y) {
    for (int x = 0; x < one.width; ++x) {
      for (size_t c = 0; c < 4; ++c) {
        unsigned sum = 0;
        for (int k = 0; k < 4; ++k) {
          const size_t i = (static_cast<size_t>(2 * y + k / 2) * static_cast<size_t>(big.width) + static_cast<size_t>(2 * x + k % 2)) * 4 + c;
          sum += big.rgba[i];
        }
        reference.rgba[(static_cast<size_t>(y) * static_cast<size_t>(one.width) + static_cast<size_t>(x)) * 4 + c] =
            static_cast<uint8_t>((sum + 2) / 4);
      }
    }
  }
  const double eOne = render::rmse(one, reference), eFour = render::rmse(four, reference);
  EXPECT_GT(render::rmse(one, four), 0.05) << "MSAA changed nothing";
  EXPECT_LT(eFour, eOne) << "4 samples: " << eFour << ", 1 sample: " << eOne;

  std::string error;
  auto ctx = render::createContext(render::ContextKind::Headless, 64, 64, error);
  ASSERT_TRUE(ctx) << error;
  render::Renderer renderer;
  EXPECT_FALSE(renderer.init(64, 64, error, 3));
  EXPECT_NE(error.find("msaa 3"), std::string::npos) << error;
  GLint maxSamples = 0;
  render::gl.GetIntegerv(GL_MAX_SAMPLES, &maxSamples);
  error.clear();
  EXPECT_EQ(renderer.init(64, 64, error, 8), maxSamples >= 8) << error;
  if (maxSamples < 8) {
    EXPECT_NE(error.find("at most " + std::to_string(maxSamples)), std::string::npos) << error;
  }
}

TEST(RenderGL, OSMesaFallbackRendersTheSameFrame) {
  const render::Image egl = renderDefault(kGoldenTime_s, {0, 0, 0});
  const render::Image osmesa = renderDefault(kGoldenTime_s, {0, 0, 0}, OutputMode::OSMesa);
  ASSERT_EQ(osmesa.width, 320);
  EXPECT_LT(render::rmse(egl, osmesa), 1.0);
}

namespace {

// Draws two camera-facing quads straight ahead into `fbo` with the current depth state: first
// a red one `gap_m` behind, then a green one at `front_m`. Returns the number of pixels where
// red survived, i.e. where the depth test failed to put the nearer surface in front.
int redPixelsLeft(const lod::Camera& cam, unsigned fbo, int w, int h, double front_m, double gap_m) {
  using namespace ig::render;
  const char* vs = R"(#version 450 core
layout(location = 0) in vec3 aPos;
uniform mat4 uViewProjection;
void main() { gl_Position = uViewProjection * vec4(aPos, 1.0); })";
  const char* fs = R"(#version 450 core
uniform vec3 uColor;
out vec4 o;
void main() { o = vec4(uColor, 1.0); })";
  std::string error;
  GlProgram program = buildProgram(vs, fs, error);
  EXPECT_TRUE(program) << error;
  // Quads in eye-relative world coordinates (the camera looks north, +y), 90 degrees wide.
  std::vector<float> v;
  for (double d : {front_m + gap_m, front_m}) {
    const auto y = static_cast<float>(d), s = static_cast<float>(d);
    const float quad[] = {-s, y, -s, s, y, -s, s, y, s, -s, y, -s, s, y, s, -s, y, s};
    v.insert(v.end(), std::begin(quad), std::end(quad));
  }
  const uint32_t idx[] = {0, 1, 2, 3, 4, 5};
  GlBuffer vbuf, ibuf;
  GLuint ids[2];
  gl.CreateBuffers(2, ids);
  vbuf = GlBuffer::wrap(ids[0]);
  ibuf = GlBuffer::wrap(ids[1]);
  gl.NamedBufferStorage(vbuf.id(), static_cast<GLsizeiptr>(v.size() * sizeof(float)), v.data(), 0);
  gl.NamedBufferStorage(ibuf.id(), sizeof idx, idx, 0);
  GLuint vao = 0;
  gl.CreateVertexArrays(1, &vao);
  GlVertexArray vertexArray = GlVertexArray::wrap(vao);
  gl.VertexArrayVertexBuffer(vao, 0, vbuf.id(), 0, 3 * sizeof(float));
  gl.VertexArrayElementBuffer(vao, ibuf.id());
  gl.EnableVertexArrayAttrib(vao, 0);
  gl.VertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
  gl.VertexArrayAttribBinding(vao, 0, 0);
  const glm::mat4 vp(lod::projection(cam) *
                     glm::dmat4(lod::viewRotation(cam)));
  const GLuint p = program.id();
  gl.ProgramUniformMatrix4fv(p, gl.GetUniformLocation(p, "uViewProjection"), 1, GL_FALSE, glm::value_ptr(vp));
  gl.Disable(GL_CULL_FACE);
  gl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
  gl.Viewport(0, 0, w, h);
  gl.UseProgram(p);
  gl.BindVertexArray(vao);
  const float red[] = {1, 0, 0}, green[] = {0, 1, 0};
  gl.ProgramUniform3fv(p, gl.GetUniformLocation(p, "uColor"), 1, red);
  gl.DrawElementsBaseVertex(GL_TRIANGLES, 6, GL_UNSIGNED_INT, nullptr, 0);
  gl.ProgramUniform3fv(p, gl.GetUniformLocation(p, "uColor"), 1, green);
  gl.DrawElementsBaseVertex(GL_TRIANGLES, 6, GL_UNSIGNED_INT, nullptr, 6);
  gl.Finish();
  std::vector<uint8_t> px(static_cast<size_t>(w) * static_cast<size_t>(h) * 4);
  gl.BindFramebuffer(GL_READ_FRAMEBUFFER, fbo);
  gl.ReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, px.data());
  int redCount = 0, greenCount = 0;
  for (size_t i = 0; i < px.size(); i += 4) {
    redCount += px[i] > 128 && px[i + 1] < 64;
    greenCount += px[i + 1] > 128 && px[i] < 64;
  }
  EXPECT_GT(greenCount + redCount, w * h / 2) << "the quads must cover the view";
  gl.BindVertexArray(0);
  return redCount;
}

lod::Camera testCamera() {
  lod::Camera cam;
  cam.fovY_deg = 60;
  cam.aspect = 1.0;
  cam.near_m = 0.1;
  cam.far_m = 100000.0;
  return cam;
}

}  // namespace

// A cabin's display channels meet without a seam: the left and right halves of a window, each
// rendered by its own service at half the width through an off-axis frustum ([channel]
// left/right/bottom/top_deg), put side by side give the same pixels as one full-width render of
// the whole window (terrain, its chunk culling, sky and fog). With the window shift ignored each
// half would look straight ahead: the halves would repeat the middle of the view.
TEST(RenderGL, TwoHalfChannelsMeetTheFullViewWithoutASeam) {
  constexpr double kHalfWidth_deg = 40.0;
  const double top_deg = std::atan(std::tan(kHalfWidth_deg * M_PI / 180.0) * 180.0 / 320.0) * 180.0 / M_PI;
  auto render = [&](int width_px, double left_deg, double right_deg) {
    ServiceConfig cfg;
    SceneConfig scene;
    test::defaultConfigs(cfg, scene);
    cfg.width_px = width_px;
    cfg.height_px = 180;
    cfg.channel.frustum = lod::WindowAngles{left_deg, right_deg, -top_deg, top_deg};
    render::Image image;
    std::string error;
    auto service = Service::create(cfg, scene, error);
    EXPECT_TRUE(service) << error;
    if (service) service->renderOnce(test::defaultHostAt(kGoldenTime_s), &image);
    return image;
  };
  const render::Image full = render(320, -kHalfWidth_deg, kHalfWidth_deg);
  const render::Image left = render(160, -kHalfWidth_deg, 0.0);
  const render::Image right = render(160, 0.0, kHalfWidth_deg);
  ASSERT_EQ(full.width, 320);
  ASSERT_EQ(left.width, 160);
  ASSERT_EQ(right.width, 160);
  render::Image joined = full;
  for (int y = 0; y < 180; ++y) {
    for (int x = 0; x < 320; ++x) {
      const render::Image& half = x < 160 ? left : right;
      const size_t from = (static_cast<size_t>(y) * 160 + static_cast<size_t>(x % 160)) * 4;
      const size_t to = (static_cast<size_t>(y) * 320 + static_cast<size_t>(x)) * 4;
      for (size_t c = 0; c < 4; ++c) joined.rgba[to + c] = half.rgba[from + c];
    }
  }
  // Bit-identical on llvmpipe (measured: RMSE 0, no pixel differs): every pixel centre of a half
  // falls on the same view ray as in the full view, and the seam is a pixel boundary, so no
  // tolerance is needed. With the shift ignored: RMSE 23, 52 % of the pixels differ.
  const bool same = full.rgba == joined.rgba;
  if (!same) {
    std::string failed;
    render::writePng(IG_BINARY_DIR "/channels_joined.png", joined, failed);
    render::writePng(IG_BINARY_DIR "/channels_full.png", full, failed);
  }
  EXPECT_TRUE(same) << "RMSE " << render::rmse(full, joined) << ", fraction of pixels differing by more than 2: "
                    << render::fractionDifferent(full, joined, 2)
                    << "; halves written to build/channels_joined.png, the full view to build/channels_full.png";
  // Not a blank picture: the two halves differ from each other.
  EXPECT_GT(render::rmse(left, right), 10.0);
}

TEST(RenderGL, ReverseZHasNoZFightingFromTwoMetresToFiftyKilometres) {
  std::string error;
  auto ctx = render::createContext(render::ContextKind::Headless, 64, 64, error);
  ASSERT_TRUE(ctx) << error;
  render::Renderer renderer;
  ASSERT_TRUE(renderer.init(128, 128, error)) << error;
  const lod::Camera cam = testCamera();
  render::Lighting light;
  // The renderer's own depth set-up (float depth, zero-to-one clip, GREATER, clear to 0).
  for (auto [front, gap] : {std::pair{50000.0, 2.0}, std::pair{5000.0, 0.05}, std::pair{2.0, 0.0005}}) {
    renderer.beginFrame(cam, light);
    EXPECT_EQ(redPixelsLeft(cam, renderer.framebuffer(), 128, 128, front, gap), 0)
        << "z-fighting at " << front << " m with a " << gap << " m gap";
  }
  EXPECT_EQ(renderer.errors(), "");
}

TEST(RenderGL, TheSameSetUpWithA24BitDepthBufferFails) {
  // Contrast for the test above: it can fail. Same state, fixed-point 24-bit depth.
  std::string error;
  auto ctx = render::createContext(render::ContextKind::Headless, 64, 64, error);
  ASSERT_TRUE(ctx) << error;
  render::Renderer renderer;
  ASSERT_TRUE(renderer.init(128, 128, error)) << error;  // sets clip control + GREATER
  using namespace ig::render;
  GLuint rb[2], fbo = 0;
  gl.CreateRenderbuffers(2, rb);
  GlRenderbuffer color = GlRenderbuffer::wrap(rb[0]), depth = GlRenderbuffer::wrap(rb[1]);
  gl.NamedRenderbufferStorage(rb[0], GL_RGBA8, 128, 128);
  gl.NamedRenderbufferStorage(rb[1], GL_DEPTH_COMPONENT24, 128, 128);
  gl.CreateFramebuffers(1, &fbo);
  GlFramebuffer framebuffer = GlFramebuffer::wrap(fbo);
  gl.NamedFramebufferRenderbuffer(fbo, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb[0]);
  gl.NamedFramebufferRenderbuffer(fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, rb[1]);
  ASSERT_EQ(gl.CheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER), static_cast<GLenum>(GL_FRAMEBUFFER_COMPLETE));
  const float zero[4] = {0, 0, 0, 1};
  gl.ClearNamedFramebufferfv(fbo, GL_COLOR, 0, zero);
  gl.ClearNamedFramebufferfv(fbo, GL_DEPTH, 0, zero);
  EXPECT_GT(redPixelsLeft(testCamera(), fbo, 128, 128, 50000.0, 2.0), 128 * 128 / 2);
}

// Near-ground detail (render::kTerrainDetailReach_m, kTerrainFineDetailReach_m): the terrain's
// fragment shader has variants without the 0.25 m noise (0 from 40 m) and without both noises
// (0 from 400 m), chosen from a lower bound on the distance to what is drawn (the noise is a
// third of a frame seen from the air on llvmpipe, which runs both sides of a branch). Close to
// the ground each term shows; where a term is 0 the variants give the same bits; ranges marked
// far are drawn without the detail and the split into two multi-draws changes nothing else.
TEST(RenderGL, TerrainDetailOnlyNearTheGroundAndTheSamePictureFar) {
  constexpr int kW = 160, kH = 120, kPosts = 65;
  constexpr double kSpacing = 16.0, kRelief = 40.0;  // 1,024 m square
  std::string error;
  auto ctx = render::createContext(render::ContextKind::Headless, kW, kH, error);
  ASSERT_TRUE(ctx) << error;
  render::Renderer renderer;
  ASSERT_TRUE(renderer.init(kW, kH, error)) << error;
  lod::HeightfieldDesc hd;
  hd.postsX = hd.postsY = kPosts;
  hd.postSpacing_m = kSpacing;
  hd.heightScale_m = kRelief;
  std::vector<float> heights(static_cast<size_t>(kPosts) * kPosts);
  lod::generateHeightfield(hd, heights);
  const size_t quads = static_cast<size_t>(kPosts - 1) * (kPosts - 1);
  ASSERT_TRUE(renderer.addTerrainMesh(quads * 6, kRelief, error)) << error;
  auto dst = renderer.terrainMeshVertices();
  size_t n = 0;
  const auto v = [&](int x, int y) { return lod::heightFieldVertex(heights, kPosts, kPosts, kSpacing, x, y); };
  for (int y = 0; y + 1 < kPosts; ++y)
    for (int x = 0; x + 1 < kPosts; ++x) {
      dst[n++] = v(x, y), dst[n++] = v(x + 1, y), dst[n++] = v(x + 1, y + 1);
      dst[n++] = v(x, y), dst[n++] = v(x + 1, y + 1), dst[n++] = v(x, y + 1);
    }
  const render::Lighting light;
  auto finish = [&] {
    renderer.endFrame();
    renderer.finish();
    render::Image img;
    renderer.readPixels(img);
    return img;
  };
  auto whole = [&](const lod::Camera& cam, double nearest_m) {
    renderer.beginFrame(cam, light);
    renderer.drawTerrainMesh(glm::dvec3(0.0), n, nearest_m);
    return finish();
  };
  // The mesh's two halves as ranges, each marked near (1) or far (0).
  auto halves = [&](const lod::Camera& cam, uint32_t nearA, uint32_t nearB, double nearest_m) {
    const auto t = static_cast<uint32_t>(n / 3);
    const lod::TerrainDrawRange ranges[2] = {{0, t / 2, nearA}, {t / 2, t - t / 2, nearB}};
    renderer.beginFrame(cam, light);
    renderer.drawTerrainMeshRanges(glm::dvec3(0.0), ranges, nearest_m);
    return finish();
  };
  lod::Camera low;
  low.eye_m = {512.0, 200.0, static_cast<double>(heights[static_cast<size_t>(200 / 16) * kPosts + 32]) + 12.0};
  low.heading_deg = 0.0;
  low.pitch_deg = -25.0;
  low.fovY_deg = 60.0;
  low.aspect = static_cast<double>(kW) / kH;
  low.near_m = 0.5;
  low.far_m = 5000.0;
  lod::Camera high = low;
  high.eye_m = {512.0, -600.0, 1500.0};  // every point of the terrain over 1,400 m away
  high.pitch_deg = -60.0;

  lod::Camera mid = low;  // every point of the terrain 150 ... 400 m away in view
  mid.eye_m.z = 200.0;

  const render::Image lowFull = whole(low, 0.0), lowCoarse = whole(low, 100.0), lowPlain = whole(low, 1e9);
  EXPECT_GT(render::rmse(lowFull, lowCoarse), 0.2) << "the 0.25 m noise does not show near the ground";
  EXPECT_GT(render::rmse(lowCoarse, lowPlain), 0.5) << "the 2 m noise does not show near the ground";
  const render::Image midFull = whole(mid, 0.0), midCoarse = whole(mid, 150.0), midPlain = whole(mid, 1e9);
  EXPECT_EQ(midFull.rgba, midCoarse.rgba) << "beyond 40 m the 0.25 m noise is 0: the same bits";
  EXPECT_GT(render::rmse(midCoarse, midPlain), 0.2) << "the 2 m noise shows within 400 m";
  const render::Image highFull = whole(high, 0.0), highPlain = whole(high, 1400.0);
  EXPECT_EQ(highFull.rgba, highPlain.rgba) << "beyond the reach every variant must give the same bits";
  EXPECT_GT(render::rmse(highFull, midFull), 10.0);  // the views differ: the checks above are not vacuous

  EXPECT_EQ(halves(low, 1, 1, 0.0).rgba, lowFull.rgba);
  EXPECT_EQ(halves(low, 1, 1, 100.0).rgba, lowCoarse.rgba);
  EXPECT_EQ(halves(low, 0, 0, 0.0).rgba, lowPlain.rgba);
  EXPECT_GT(render::rmse(halves(low, 1, 0, 0.0), lowFull), 0.0) << "a range marked far is drawn without the detail";
  EXPECT_EQ(halves(high, 0, 1, 0.0).rgba, highFull.rgba);
}

// A frame size the GL cannot make (beyond GL_MAX_RENDERBUFFER_SIZE) is an error naming the
// size and the framebuffer status (in hex), and its GL errors go with it: left queued, they
// made the next, valid init fail with "GL errors 0x0501" (and any pass set-up that checks).
TEST(RenderGL, AFailedInitLeavesNoGlErrorsBehind) {
  std::string error;
  auto ctx = render::createContext(render::ContextKind::Headless, 64, 64, error);
  ASSERT_TRUE(ctx) << error;
  GLint maxSize = 0;
  render::gl.GetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &maxSize);
  ASSERT_GT(maxSize, 0);
  render::Renderer renderer;
  EXPECT_FALSE(renderer.init(maxSize + 1, 64, error));
  EXPECT_NE(error.find(std::to_string(maxSize + 1) + "x64 incomplete (status 0x8cd6)"), std::string::npos) << error;
  EXPECT_EQ(renderer.errors(), "");
  error.clear();
  EXPECT_TRUE(renderer.init(64, 64, error)) << error;
  EXPECT_EQ(renderer.width(), 64);
}

// Every headless context of a process is made on the same EGL display. Destroying one while a
// later one is current must leave the later one working: it terminated the display and released
// the thread's current context, and the later context's GL calls then did nothing (a black frame,
// no GL error).
TEST(RenderGL, DestroyingOneHeadlessContextKeepsAnotherWorking) {
  std::string error;
  auto first = render::createContext(render::ContextKind::Headless, 64, 64, error);
  ASSERT_TRUE(first) << error;
  auto second = render::createContext(render::ContextKind::Headless, 64, 64, error);
  ASSERT_TRUE(second) << error;
  render::Renderer renderer;
  ASSERT_TRUE(renderer.init(32, 32, error)) << error;
  first.reset();
  render::Lighting sky;
  sky.fogColor = {1.0, 0.0, 0.0};
  renderer.beginFrame(lod::Camera{}, sky);
  renderer.endFrame();
  renderer.finish();
  render::Image image;
  renderer.readPixels(image);
  ASSERT_EQ(image.rgba.size(), 32u * 32u * 4u);
  EXPECT_EQ(image.rgba[0], 255);  // the sky colour the frame was cleared to
  EXPECT_EQ(image.rgba[1], 0);
  EXPECT_EQ(renderer.errors(), "");
  // And a context made after that works too (the display is still initialised or made again).
  auto third = render::createContext(render::ContextKind::Headless, 64, 64, error);
  ASSERT_TRUE(third) << error;
}

// A terrain mesh the GL cannot make is refused with a message naming the capacity, and leaves no
// GL error queued: glNamedBufferStorage(size 0) and the failed map left GL_INVALID_VALUE (or
// GL_OUT_OF_MEMORY) behind, which the next unrelated check (a renderer init, a pass set-up)
// reported as its own failure. A good capacity still works afterwards.
TEST(RenderGL, AFailedTerrainMeshLeavesNoGlErrorsBehind) {
  std::string error;
  auto ctx = render::createContext(render::ContextKind::Headless, 64, 64, error);
  ASSERT_TRUE(ctx) << error;
  render::Renderer renderer;
  ASSERT_TRUE(renderer.init(32, 32, error)) << error;
  const size_t tooLarge = static_cast<size_t>(PTRDIFF_MAX) / sizeof(lod::TerrainVertex) + 1;  // bytes overflow GLsizeiptr
  const size_t unmappable = size_t{1} << 45;  // 768 TiB: no GL can allocate it
  for (size_t capacity : {size_t{0}, tooLarge, unmappable}) {
    error.clear();
    EXPECT_FALSE(renderer.addTerrainMesh(capacity, 40.0, error)) << capacity;
    EXPECT_NE(error.find(std::to_string(capacity)), std::string::npos) << error;
    EXPECT_EQ(renderer.errors(), "") << "capacity " << capacity << ": " << error;
    EXPECT_TRUE(renderer.terrainMeshVertices().empty());
    EXPECT_EQ(renderer.terrainMeshVertexBuffer(), 0u);
  }
  error.clear();
  render::Renderer other;
  EXPECT_TRUE(other.init(32, 32, error)) << error;
  EXPECT_TRUE(renderer.addTerrainMesh(300, 40.0, error)) << error;
  EXPECT_EQ(renderer.terrainMeshVertices().size(), 300u);
  EXPECT_EQ(renderer.errors(), "");
}

namespace {

// An X server of the test's own (Xvfb on the first free display, found with -displayfd), for the
// window-mode context; stopped when it goes. `display` is empty and `error` says why when it
// could not be started.
struct OwnXServer {
  pid_t pid = -1;
  std::string display, error;
  OwnXServer() {
    int fds[2];
    if (::pipe(fds) != 0) {
      error = "pipe failed";
      return;
    }
    const std::string fd = std::to_string(fds[1]);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addclose(&actions, fds[0]);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
    // -noreset: an X server resets when its last client disconnects and refuses connections
    // meanwhile; a test that closes its only window and opens another failed to open the display
    // under load (19 of 40 runs with the CPUs busy).
    const char* argv[] = {"Xvfb",   "-displayfd", fd.c_str(), "-screen", "0", "320x240x24", "-nolisten", "tcp",
                          "-noreset", nullptr};
    const int rc = posix_spawnp(&pid, "Xvfb", &actions, nullptr, const_cast<char* const*>(argv), environ);
    posix_spawn_file_actions_destroy(&actions);
    ::close(fds[1]);
    if (rc != 0) {
      pid = -1;
      ::close(fds[0]);
      error = "cannot run Xvfb (Debian package xvfb; scripts/setup installs it): " + std::string(std::strerror(rc));
      return;
    }
    // Xvfb writes its display number once it accepts connections (a bound, not a timing check).
    std::string number;
    pollfd p{fds[0], POLLIN, 0};
    char c = 0;
    while (::poll(&p, 1, 20000) == 1 && ::read(fds[0], &c, 1) == 1 && c != '\n') number += c;
    ::close(fds[0]);
    if (number.empty()) {
      error = "Xvfb did not report a display";
      return;
    }
    display = ":" + number;
  }
  ~OwnXServer() {
    if (pid > 0) {
      ::kill(pid, SIGTERM);
      ::waitpid(pid, nullptr, 0);
    }
  }
};

}  // namespace

// Window contexts share GLFW, which is initialised once per process. Destroying one while
// another is current must leave the other working: glfwTerminate() under it destroyed every
// window and its EGL context, and the later context's GL calls then did nothing (a black
// frame), its present() and destructor only printed "GLFW library is not initialized".
TEST(RenderGL, DestroyingOneWindowContextKeepsAnotherWorking) {
  const OwnXServer x;
  ASSERT_FALSE(x.display.empty()) << x.error;
  ::setenv("DISPLAY", x.display.c_str(), 1);
  ::unsetenv("WAYLAND_DISPLAY");
  std::string error;
  auto first = render::createContext(render::ContextKind::Window, 64, 64, error);
  ASSERT_TRUE(first) << error;
  auto second = render::createContext(render::ContextKind::Window, 64, 64, error);
  ASSERT_TRUE(second) << error;
  EXPECT_TRUE(second->hasWindow());
  {
    render::Renderer renderer;
    ASSERT_TRUE(renderer.init(32, 32, error)) << error;
    first.reset();
    render::Lighting sky;
    sky.fogColor = {1.0, 0.0, 0.0};
    renderer.beginFrame(lod::Camera{}, sky);
    renderer.endFrame();
    renderer.finish();
    render::Image image;
    renderer.readPixels(image);
    ASSERT_EQ(image.rgba.size(), 32u * 32u * 4u);
    EXPECT_EQ(image.rgba[0], 255);  // the sky colour the frame was cleared to
    EXPECT_EQ(image.rgba[1], 0);
    second->present(renderer.framebuffer(), 32, 32);
    EXPECT_FALSE(second->closeRequested());
    EXPECT_EQ(renderer.errors(), "");
  }
  second.reset();
  // With every window gone GLFW is terminated; a new window context initialises it again.
  auto third = render::createContext(render::ContextKind::Window, 64, 64, error);
  ASSERT_TRUE(third) << error;
  render::Renderer renderer;
  ASSERT_TRUE(renderer.init(16, 16, error)) << error;
  EXPECT_EQ(renderer.errors(), "");
}

// A cabin display: full screen on a monitor at its own video mode, the rendered frame scaled to
// it. Xvfb's one screen (320 x 240) is its one monitor; asking for a second is an error that says
// how many there are.
TEST(RenderGL, FullScreenWindowCoversTheMonitorAndAMissingMonitorIsNamed) {
  const OwnXServer x;
  ASSERT_FALSE(x.display.empty()) << x.error;
  ::setenv("DISPLAY", x.display.c_str(), 1);
  ::unsetenv("WAYLAND_DISPLAY");
  std::string error;
  EXPECT_FALSE(render::createContext(render::ContextKind::Window, 64, 48, error, render::WindowOptions{true, 1}));
  EXPECT_NE(error.find("output.monitor = 1, but the X server has 1 monitor (0 ..= 0)"), std::string::npos) << error;
  error.clear();
  auto full = render::createContext(render::ContextKind::Window, 64, 48, error, render::WindowOptions{true, 0});
  ASSERT_TRUE(full) << error;
  EXPECT_NE(full->description().find("full screen 320x240 on monitor 0"), std::string::npos) << full->description();
  int w = 0, h = 0;
  full->windowSize(w, h);
  EXPECT_EQ(w, 320);
  EXPECT_EQ(h, 240);
  render::Renderer renderer;
  ASSERT_TRUE(renderer.init(64, 48, error)) << error;
  renderer.beginFrame(lod::Camera{}, render::Lighting{});
  renderer.endFrame();
  full->present(renderer.framebuffer(), 64, 48);
  EXPECT_FALSE(full->closeRequested());
  EXPECT_EQ(renderer.errors(), "");
  full.reset();
  // Windowed: the rendered size, not the monitor's.
  auto windowed = render::createContext(render::ContextKind::Window, 64, 48, error);
  ASSERT_TRUE(windowed) << error;
  windowed->windowSize(w, h);
  EXPECT_EQ(w, 64);
  EXPECT_EQ(h, 48);
}

// The image error of the LOD benchmarks (render/image.h) on hand-made images, no GL.
namespace {
render::Image flatImage(int w, int h, uint8_t r, uint8_t g, uint8_t b) {
  render::Image im;
  im.width = w;
  im.height = h;
  im.rgba.resize(static_cast<size_t>(w) * static_cast<size_t>(h) * 4);
  for (size_t i = 0; i < im.rgba.size(); i += 4) im.rgba[i] = r, im.rgba[i + 1] = g, im.rgba[i + 2] = b, im.rgba[i + 3] = 255;
  return im;
}
}  // namespace

TEST(ImageError, RmseAndPsnrOnHandMadeImages) {
  const render::Image a = flatImage(4, 2, 10, 20, 30);
  render::Image b = a;
  EXPECT_EQ(render::rmse(a, b), 0.0);
  EXPECT_EQ(render::psnrDb(a, b), 99.0);  // identical
  // One channel of every pixel 6 levels off: the mean over R, G, B of the squares is 36 / 3.
  for (size_t i = 0; i < b.rgba.size(); i += 4) b.rgba[i + 1] = 26;
  EXPECT_DOUBLE_EQ(render::rmse(a, b), std::sqrt(12.0));
  EXPECT_NEAR(render::psnrDb(a, b), 20.0 * std::log10(255.0 / std::sqrt(12.0)), 1e-9);
  // Alpha does not count.
  render::Image c = a;
  for (size_t i = 3; i < c.rgba.size(); i += 4) c.rgba[i] = 0;
  EXPECT_EQ(render::rmse(a, c), 0.0);
  // Black against white: the largest error, 0 dB.
  EXPECT_DOUBLE_EQ(render::rmse(flatImage(3, 3, 0, 0, 0), flatImage(3, 3, 255, 255, 255)), 255.0);
  EXPECT_DOUBLE_EQ(render::psnrDb(flatImage(3, 3, 0, 0, 0), flatImage(3, 3, 255, 255, 255)), 0.0);
  // Sizes differ: negative.
  EXPECT_LT(render::rmse(a, flatImage(2, 4, 10, 20, 30)), 0.0);
  EXPECT_LT(render::psnrDb(a, flatImage(2, 4, 10, 20, 30)), 0.0);
}

// 99 dB stands for identical images, so nothing may score above it: one level off in one pixel of
// a 256 x 256 image is an RMSE of 1 / sqrt(3 * 65536), 101 dB by the formula, and the sweeps
// (terrain, hdlod, forest, cells) would rank it better than an identical picture.
TEST(ImageError, PsnrOfANearlyIdenticalImageIsNotAboveThatOfAnIdenticalOne) {
  const render::Image a = flatImage(256, 256, 100, 100, 100);
  render::Image b = a;
  b.rgba[0] = 101;
  EXPECT_GT(render::rmse(a, b), 0.0);
  EXPECT_LE(render::psnrDb(a, b), render::psnrDb(a, a));
  EXPECT_LE(render::psnrDb(a, b), 99.0);
}


namespace {
// A height-field patch as a triangle list (two triangles a quad), its vertices moved by `shift`
// (a whole number of post spacings, exact in float at the sizes used).
std::vector<lod::TerrainVertex> patchTriangles(const std::vector<float>& heights, int posts, double spacing_m,
                                               glm::dvec2 shift) {
  std::vector<lod::TerrainVertex> out;
  const auto v = [&](int x, int y) {
    lod::TerrainVertex t = lod::heightFieldVertex(heights, posts, posts, spacing_m, x, y);
    t.position[0] = static_cast<float>(static_cast<double>(t.position[0]) + shift.x);
    t.position[1] = static_cast<float>(static_cast<double>(t.position[1]) + shift.y);
    return t;
  };
  for (int y = 0; y + 1 < posts; ++y)
    for (int x = 0; x + 1 < posts; ++x) {
      out.push_back(v(x, y)), out.push_back(v(x + 1, y)), out.push_back(v(x + 1, y + 1));
      out.push_back(v(x, y)), out.push_back(v(x + 1, y + 1)), out.push_back(v(x, y + 1));
    }
  return out;
}

// A headless context and renderer of w x h with room for a posts x posts height-field patch
// (2 m spacing, 6 m of relief) and its heights: the set-up of the patch tests below.
struct PatchScene {
  static constexpr double kSpacing = 2.0;
  std::unique_ptr<render::GlContext> ctx;
  render::Renderer renderer;
  std::vector<float> heights;
  int posts = 0;
  // Call with ASSERT_NO_FATAL_FAILURE.
  void setUp(int w, int h, int postsPerSide) {
    posts = postsPerSide;
    std::string error;
    ctx = render::createContext(render::ContextKind::Headless, w, h, error);
    ASSERT_TRUE(ctx) << error;
    ASSERT_TRUE(renderer.init(w, h, error)) << error;
    lod::HeightfieldDesc hd;
    hd.postsX = hd.postsY = posts;
    hd.postSpacing_m = kSpacing;
    hd.heightScale_m = 6.0;
    heights.resize(static_cast<size_t>(posts) * static_cast<size_t>(posts));
    lod::generateHeightfield(hd, heights);
    ASSERT_TRUE(renderer.addTerrainMesh(static_cast<size_t>(posts - 1) * static_cast<size_t>(posts - 1) * 6, 6.0, error))
        << error;
  }
};
}  // namespace

// A terrain mesh (ROAM, block LOD) keeps one origin, the DEM's south-west post, so its vertices
// lie up to a tile's size from it (111 km for an SRTM tile). The eye-to-origin offset was sent as
// one float (a 7.8 mm step at 120 km): the whole terrain moved in those steps as the eye moved,
// about 1 px at this zoom (10 degree field of view, 1.5 m above the ground), and the ground
// detail was computed from float positions of 1e5 m. The same ground drawn from an origin beside
// it must give the same picture, with and without the detail terms.
TEST(RenderGL, ATerrainMeshFarFromItsOriginIsPlacedAsNearIt) {
  constexpr int kW = 160, kH = 120, kPosts = 33;
  constexpr double kSpacing = PatchScene::kSpacing;
  PatchScene scene;
  ASSERT_NO_FATAL_FAILURE(scene.setUp(kW, kH, kPosts));
  render::Renderer& renderer = scene.renderer;
  const std::vector<float>& heights = scene.heights;
  const glm::dvec2 base(120000.0, 120000.0);  // the patch's south-west corner, 170 km from the far origin
  const auto nearOrigin = patchTriangles(heights, kPosts, kSpacing, {0.0, 0.0});
  const auto farOrigin = patchTriangles(heights, kPosts, kSpacing, base);
  // Looking north across the patch's north edge (ground against sky), from an eyepoint 0.45 of a
  // float step (1/128 m at 120 km) off the float grid in x and y.
  lod::Camera cam;
  const double edgeZ = static_cast<double>(heights[static_cast<size_t>(kPosts - 1) * kPosts + 16]);
  cam.eye_m = {base.x + 32.0 + 0.45 / 128.0, base.y + 7962.45 / 128.0, edgeZ + 1.5};
  cam.pitch_deg = -40.0;
  cam.fovY_deg = 10.0;
  cam.aspect = static_cast<double>(kW) / kH;
  cam.near_m = 0.1;
  cam.far_m = 5000.0;
  const render::Lighting light;
  auto frame = [&](const glm::dvec3& origin, const std::vector<lod::TerrainVertex>& v, double nearest_m) {
    renderer.beginFrame(cam, light);
    std::copy(v.begin(), v.end(), renderer.terrainMeshVertices().begin());
    renderer.drawTerrainMesh(origin, v.size(), nearest_m);
    renderer.endFrame();
    renderer.finish();
    render::Image img;
    renderer.readPixels(img);
    return img;
  };
  for (double nearest_m : {0.0, 1e9}) {  // with both detail terms, and without
    const render::Image a = frame({base.x, base.y, 0.0}, nearOrigin, nearest_m);
    const render::Image b = frame(glm::dvec3(0.0), farOrigin, nearest_m);
    EXPECT_LT(render::rmse(a, b), 0.1) << "nearest " << nearest_m << " m";
    EXPECT_LT(render::fractionDifferent(a, b, 2), 0.0005) << "nearest " << nearest_m << " m";
    // Not vacuous: the view shows ground and sky.
    EXPECT_GT(render::rmse(a, flatImage(kW, kH, a.rgba[0], a.rgba[1], a.rgba[2])), 10.0);
  }
  EXPECT_EQ(renderer.errors(), "");
}

// beginFrame refuses a camera with NaN / infinite values, a field of view outside (0, 180) deg,
// near <= 0 or far <= near (igtool render, benchmarks and tests call the renderer without the
// frame loop's host filter): it went straight into the uniforms. The frame keeps the last good
// camera (the same picture) and errors() names the refused camera, once.
TEST(RenderGL, ABadCameraIsRefusedAndTheLastGoodOneIsDrawn) {
  constexpr int kW = 64, kH = 48, kPosts = 17;
  constexpr double kSpacing = PatchScene::kSpacing;
  PatchScene scene;
  ASSERT_NO_FATAL_FAILURE(scene.setUp(kW, kH, kPosts));
  render::Renderer& renderer = scene.renderer;
  const std::vector<float>& heights = scene.heights;
  const auto tris = patchTriangles(heights, kPosts, kSpacing, {0.0, 0.0});
  lod::Camera good;
  good.eye_m = {16.0, -10.0, 12.0};
  good.pitch_deg = -30.0;
  good.fovY_deg = 60.0;
  good.aspect = static_cast<double>(kW) / kH;
  good.near_m = 0.1;
  good.far_m = 5000.0;
  const render::Lighting light;
  auto frame = [&](const lod::Camera& cam) {
    renderer.beginFrame(cam, light);
    renderer.drawTerrainMesh(glm::dvec3(0.0), tris);
    renderer.endFrame();
    renderer.finish();
    render::Image img;
    renderer.readPixels(img);
    return img;
  };
  const render::Image want = frame(good);
  ASSERT_EQ(renderer.errors(), "");
  ASSERT_GT(render::rmse(want, flatImage(kW, kH, want.rgba[0], want.rgba[1], want.rgba[2])), 10.0);  // ground and sky
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  std::vector<std::pair<const char*, lod::Camera>> bad;
  auto add = [&](const char* what, auto change) {
    lod::Camera c = good;
    change(c);
    bad.emplace_back(what, c);
  };
  add("nan eye", [&](lod::Camera& c) { c.eye_m.x = nan; });
  add("inf eye", [&](lod::Camera& c) { c.eye_m.z = inf; });
  add("nan heading", [&](lod::Camera& c) { c.heading_deg = nan; });
  add("inf pitch", [&](lod::Camera& c) { c.pitch_deg = -inf; });
  add("nan roll", [&](lod::Camera& c) { c.roll_deg = nan; });
  add("nan fov", [&](lod::Camera& c) { c.fovY_deg = nan; });
  add("fov 0", [&](lod::Camera& c) { c.fovY_deg = 0.0; });
  add("fov 180", [&](lod::Camera& c) { c.fovY_deg = 180.0; });
  add("nan aspect", [&](lod::Camera& c) { c.aspect = nan; });
  add("near 0", [&](lod::Camera& c) { c.near_m = 0.0; });
  add("near < 0", [&](lod::Camera& c) { c.near_m = -1.0; });
  add("far = near", [&](lod::Camera& c) { c.far_m = c.near_m; });
  add("far < near", [&](lod::Camera& c) { c.far_m = 0.05; });
  add("inf far", [&](lod::Camera& c) { c.far_m = inf; });
  add("nan near", [&](lod::Camera& c) { c.near_m = nan; });
  for (const auto& [what, cam] : bad) {
    const render::Image got = frame(cam);
    const lod::Camera& used = renderer.camera();
    EXPECT_EQ(used.eye_m, good.eye_m) << what;
    EXPECT_EQ(used.fovY_deg, good.fovY_deg) << what;
    EXPECT_EQ(used.near_m, good.near_m) << what;
    EXPECT_EQ(used.far_m, good.far_m) << what;
    EXPECT_EQ(got.rgba, want.rgba) << what;
    const std::string e = renderer.errors();
    EXPECT_NE(e.find("camera refused"), std::string::npos) << what << ": '" << e << "'";
    EXPECT_EQ(renderer.errors(), "") << what;  // reported once
  }
  // A good camera after them is used.
  lod::Camera moved = good;
  moved.heading_deg = 20.0;
  frame(moved);
  EXPECT_EQ(renderer.camera().heading_deg, 20.0);
  EXPECT_EQ(renderer.errors(), "");
}

// The scene's fixed sun ([sun] elevation_deg, -90 ..= 90) below the horizon: night, as the same
// sun placed by the host's time of day gives (sun, ambient light and sky dimmed by
// lod::sunlightFraction). It lit the terrain and sky as at noon, and slopes facing a sun 5
// degrees below the horizon got direct light.
TEST(RenderGL, AFixedSunBelowTheHorizonIsNight) {
  auto render = [](double elevation_deg, std::array<double, 3> color) {
    ServiceConfig cfg;
    SceneConfig scene;
    test::defaultConfigs(cfg, scene);
    scene.sun.elevation_deg = elevation_deg;
    scene.sun.color = color;
    std::string error;
    auto service = Service::create(cfg, scene, error);
    EXPECT_TRUE(service) << error;
    render::Image image;
    if (service) service->renderOnce(test::defaultHostAt(kGoldenTime_s), &image);
    return image;
  };
  const render::Image night = render(-5.0, {1.0, 0.96, 0.88}), sunless = render(-5.0, {0.0, 0.0, 0.0});
  ASSERT_EQ(night.width, 320);
  EXPECT_EQ(render::rmse(night, sunless), 0.0) << "a sun 5 degrees below the horizon lights nothing directly";
  // The sky (top-left pixel): the fog colour (0.70, 0.78, 0.86) at 8 % for night, not at full.
  EXPECT_LT(night.rgba[0], 30);
  EXPECT_LT(night.rgba[2], 30);
  // A sun high up is unchanged: full daylight sky.
  const render::Image day = render(35.0, {1.0, 0.96, 0.88});
  EXPECT_GT(day.rgba[0], 150);
}
