#include "ig/bench_forest.h"
#include "ig/json.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <time.h>

#include "ig/clock.h"
#include "ig/forest_layer.h"
#include "ig/forest_tool.h"
#include "io/dem.h"
#include "lod/forest.h"
#include "lod/forest_fins.h"
#include "lod/forest_kdtree.h"
#include "lod/heightfield.h"
#include "lod/terrain_grid.h"
#include "render/context.h"
#include "render/image.h"
#include "render/renderer.h"

namespace ig {
namespace {

using BenchClock = std::chrono::steady_clock;

constexpr double kPostSpacing_m = 32.0;

// Nearest-rank percentile (ig/stats.h's, repeated here: that header pulls in ig/config.h).
double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<size_t>(std::ceil(p / 100.0 * static_cast<double>(v.size())));
  return v[std::clamp<size_t>(k, 1, v.size()) - 1];
}

double msSince(BenchClock::time_point t0) {
  return std::chrono::duration<double, std::milli>(BenchClock::now() - t0).count();
}

constexpr size_t kInstanceCapacity = 1 << 18;
constexpr int kPopLevels = 8;            // a pixel "pops" when a channel changes by more in one frame
constexpr size_t kNearTriangles = 120;   // near LOD of each model (meshoptimizer)
constexpr size_t kBakeTriangles = 20000; // LOD the textures T and S are rendered from

struct Ground {
  std::vector<float> heights;
  int posts = 0;
  std::string source;
  lod::ForestHeightField field() const { return {heights, posts, posts, kPostSpacing_m, glm::dvec3(0.0)}; }
};

// The posts x posts window (32 m) of the DEM with the most relief and no sea (no sample at or
// below 1 m), resampled bilinearly. False if the file cannot be read.
bool demGround(const std::string& file, int posts, Ground& g, std::string& error) {
  io::Dem dem;
  if (!io::loadDem(file, {}, dem, error)) return false;
  io::flipRows(dem);
  const double step = kPostSpacing_m / dem.spacing_m;  // DEM samples per post
  const int span = static_cast<int>(std::ceil((posts - 1) * step)) + 2;
  if (span >= dem.width || span >= dem.height) {
    error = "DEM '" + file + "' (" + std::to_string(dem.width) + " x " + std::to_string(dem.height) + ", " +
            std::to_string(dem.spacing_m) + " m) is smaller than the " + std::to_string((posts - 1) * kPostSpacing_m) +
            " m forest";
    return false;
  }
  double best = -1.0;
  int bx = 0, by = 0;
  for (int y = 0; y + span < dem.height; y += 25) {
    for (int x = 0; x + span < dem.width; x += 25) {
      double s = 0, s2 = 0, lo = 1e9;
      int n = 0;
      for (int j = 0; j < span; j += 3)
        for (int i = 0; i < span; i += 3) {
          const auto h = static_cast<double>(dem.at(x + i, y + j));
          s += h, s2 += h * h, lo = std::min(lo, h), ++n;
        }
      const double sd = std::sqrt(std::max(0.0, s2 / n - (s / n) * (s / n)));
      if (lo > 1.0 && sd > best) best = sd, bx = x, by = y;
    }
  }
  if (best < 0) {
    error = "DEM '" + file + "': no window without sea";
    return false;
  }
  g.posts = posts;
  g.heights.resize(static_cast<size_t>(posts) * static_cast<size_t>(posts));
  for (int y = 0; y < posts; ++y)
    for (int x = 0; x < posts; ++x) {
      const double fx = bx + x * step, fy = by + y * step;
      const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
      const double tx = fx - x0, ty = fy - y0;
      const auto h = [&](int px, int py) { return static_cast<double>(dem.at(px, py)); };
      const double a = h(x0, y0) + (h(x0 + 1, y0) - h(x0, y0)) * tx;
      const double b = h(x0, y0 + 1) + (h(x0 + 1, y0 + 1) - h(x0, y0 + 1)) * tx;
      g.heights[static_cast<size_t>(y) * static_cast<size_t>(posts) + static_cast<size_t>(x)] =
          static_cast<float>(a + (b - a) * ty);
    }
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s window at samples (%d, %d) from the south-west, %.1f m posts resampled to 32 m",
                std::filesystem::path(file).filename().c_str(), bx, by, dem.spacing_m);
  g.source = buf;
  return true;
}

// A low flight over the forest: a wide loop at ~60 m above the ground, turning, slightly nose-down.
lod::Camera pathCamera(int i, int frames, double extent_m, const lod::ForestHeightField& ground) {
  lod::Camera cam;
  cam.fovY_deg = 45.0;
  cam.aspect = 16.0 / 9.0;
  cam.near_m = 0.5;
  cam.far_m = 20000.0;
  const double s = static_cast<double>(i) / std::max(frames, 1);
  const double a = 2.0 * 3.14159265358979323846 * s;
  const double r = 0.3 * extent_m;
  cam.eye_m = {0.5 * extent_m + r * std::cos(a), 0.5 * extent_m + r * std::sin(a), 0.0};
  cam.eye_m.z = ground.heightAt(cam.eye_m.x, cam.eye_m.y) + 60.0 + 30.0 * std::sin(5.0 * a);
  cam.heading_deg = std::fmod(360.0 - a * 57.29577951308232 + 20.0 * std::sin(9.0 * a), 360.0);  // along the loop
  cam.pitch_deg = -8.0 + 4.0 * std::sin(7.0 * a);
  return cam;
}

// The slow approach: straight and level, 1 m per frame, 45 m above the start, looking ahead
// slightly down, so the trees ahead cross the near/far transition band.
lod::Camera approachCamera(int i, double extent_m, const lod::ForestHeightField& ground) {
  lod::Camera cam;
  cam.fovY_deg = 45.0;
  cam.aspect = 16.0 / 9.0;
  cam.near_m = 0.5;
  cam.far_m = 20000.0;
  const double heading = 35.0 * 3.14159265358979323846 / 180.0;
  const glm::dvec2 start(0.35 * extent_m, 0.3 * extent_m);
  cam.eye_m = {start.x + i * std::sin(heading), start.y + i * std::cos(heading), 0.0};
  cam.eye_m.z = std::max(ground.heightAt(start.x, start.y) + 45.0, ground.heightAt(cam.eye_m.x, cam.eye_m.y) + 25.0);
  cam.heading_deg = 35.0;
  cam.pitch_deg = -6.0;
  return cam;
}

struct Run {
  double p50 = 0, p99 = 0, max = 0;
  double cpuP99 = 0;
  double drawnP50 = 0;
  uint32_t droppedMax = 0;
  double testedP50 = 0;
};

Run flight(const lod::ForestKdTree& kd, const lod::ForestHeightField& ground, const lod::NearFade& fade, int frames,
           double extent_m, std::vector<lod::ForestInstance>& inst, std::vector<lod::ForestInstance>& scratch,
           std::vector<lod::ForestModelRange>& models) {
  std::vector<double> ms, cpu, drawn, tested;
  ms.reserve(static_cast<size_t>(frames));
  Run r;
  for (int i = 0; i < frames; ++i) {
    const lod::Camera cam = pathCamera(i, frames, extent_m, ground);
    lod::ForestSelectStats st;
    const double c0 = threadCpuMs();
    const auto t0 = BenchClock::now();
    const size_t n = kd.select(cam, fade, inst, scratch, models, &st);
    ms.push_back(msSince(t0));
    cpu.push_back(threadCpuMs() - c0);
    drawn.push_back(static_cast<double>(n));
    tested.push_back(st.treesTested);
    r.droppedMax = std::max(r.droppedMax, st.dropped);
  }
  r.p50 = percentile(ms, 50);
  r.p99 = percentile(ms, 99);
  r.max = *std::max_element(ms.begin(), ms.end());
  r.cpuP99 = percentile(cpu, 99);
  r.drawnP50 = percentile(drawn, 50);
  r.testedP50 = percentile(tested, 50);
  return r;
}

// Mean over pixels of the mean absolute RGB difference, in 8-bit levels.
double meanChange(const render::Image& a, const render::Image& b) {
  if (a.rgba.size() != b.rgba.size() || a.rgba.empty()) return 0.0;
  uint64_t sum = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4)
    for (size_t k = 0; k < 3; ++k) sum += static_cast<uint64_t>(std::abs(int{a.rgba[i + k]} - int{b.rgba[i + k]}));
  return static_cast<double>(sum) / (3.0 * static_cast<double>(a.rgba.size() / 4));
}

struct Scene {
  render::Renderer renderer;
  render::Lighting lighting;
  size_t vertexCount = 0;
  ForestLayer* forest = nullptr;

  // One frame: select + draw + glFinish; returns wall ms.
  double frame(const lod::Camera& cam, bool withForest, render::Image* out) {
    const auto t0 = BenchClock::now();
    if (withForest) forest->select(cam);
    renderer.beginFrame(cam, lighting);
    renderer.drawTerrainMesh(glm::dvec3(0.0), vertexCount);
    if (withForest) forest->draw(renderer, glm::dvec3(0.0), vertexCount);
    renderer.endFrame();
    renderer.finish();
    const double ms = msSince(t0);
    if (out) renderer.readPixels(*out);
    return ms;
  }
};

void saveImage(const std::string& dir, const std::string& name, const render::Image& img) {
  if (dir.empty()) return;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  std::string error;
  if (!render::writePng(dir + "/" + name, img, error)) std::fprintf(stderr, "igbench forest: %s\n", error.c_str());
}

}  // namespace

render::ForestTextureDesc forestBenchTextureDesc(const ForestBenchOptions& o) {
  render::ForestTextureDesc td = forestTextureDesc(o.treeSpacing_m, o.layers);
  if (o.quick) td.size_px = 128;
  return td;
}

int runForestBench(const ForestBenchOptions& in) {
  ForestBenchOptions o = in;
  if (o.quick) {
    o.posts = std::min(o.posts, 65);
    o.frames = std::min(o.frames, 60);
    o.renderFrames = std::min(o.renderFrames, 10);
    o.popFrames = std::min(o.popFrames, 16);
    o.width = std::min(o.width, 256);
    o.height = std::min(o.height, 144);
  }
  if (o.posts < 9 || o.frames < 1 || o.renderFrames < 1 || o.popFrames < 2 || o.width < 16 || o.height < 16 ||
      o.layers < 1 || o.layers > 32) {
    std::fprintf(stderr,
                 "igbench forest: posts = %d, frames = %d, render frames = %d, pop frames = %d, size %d x %d, layers "
                 "= %d: need posts >= 9, frames >= 1, pop frames >= 2, size >= 16, layers 1..32\n",
                 o.posts, o.frames, o.renderFrames, o.popFrames, o.width, o.height, o.layers);
    return 2;
  }
  std::string err;
  // Ground: the real DEM, or the procedural relief when it is missing.
  Ground ground;
  if (o.dem.empty() || !std::filesystem::exists(o.dem) || !demGround(o.dem, o.posts, ground, err)) {
    if (!o.dem.empty() && std::filesystem::exists(o.dem)) {
      std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
      return 2;
    }
    lod::HeightfieldDesc hd;
    hd.seed = o.seed;
    hd.postsX = hd.postsY = o.posts;
    hd.postSpacing_m = kPostSpacing_m;
    hd.heightScale_m = 400.0;
    ground.posts = o.posts;
    ground.heights.resize(static_cast<size_t>(o.posts) * static_cast<size_t>(o.posts));
    lod::generateHeightfield(hd, ground.heights);
    ground.source = "procedural (no DEM: run scripts/fetch-data)";
  }
  const lod::ForestHeightField field = ground.field();
  const double extent_m = (o.posts - 1) * kPostSpacing_m;

  // Models: Scopia pine and cypress when fetched, else procedural.
  std::vector<lod::TreeMesh> nearModels, bakeModels;
  std::string modelSource = "scopia";
  std::vector<lod::TreeMesh> fullModels;
  if (loadScopiaTrees(o.models, 0, fullModels, err)) {
    for (const lod::TreeMesh& m : fullModels) {
      nearModels.push_back(simplifyTree(m, kNearTriangles));
      bakeModels.push_back(simplifyTree(m, o.quick ? kBakeTriangles / 8 : kBakeTriangles));
    }
  } else {
    nearModels = bakeModels = proceduralTrees();
    modelSource = "procedural (no " + o.models + ": run scripts/fetch-forest)";
  }
  size_t modelTriangles = 0;
  for (const lod::TreeMesh& m : nearModels) modelTriangles += m.indices.size() / 3;

  auto ctx = render::createContext(render::ContextKind::Headless, o.width, o.height, err);
  if (!ctx) {
    std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
    return 1;
  }
  Scene scene;
  if (!scene.renderer.init(o.width, o.height, err)) {
    std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
    return 1;
  }
  scene.lighting.sunDirection = glm::normalize(glm::dvec3(0.5, -0.5, 0.6));
  scene.lighting.fogVisibility_m = 12000.0;
  // Terrain: the full-resolution grid as a triangle list in the renderer's mesh buffer.
  {
    const size_t quads = static_cast<size_t>(o.posts - 1) * static_cast<size_t>(o.posts - 1);
    const auto [lo, hi] = std::minmax_element(ground.heights.begin(), ground.heights.end());
    if (!scene.renderer.addTerrainMesh(quads * 6, std::max(1.0, static_cast<double>(*hi - *lo)), err)) {
      std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
      return 1;
    }
    auto dst = scene.renderer.terrainMeshVertices();
    size_t k = 0;
    const auto vtx = [&](int x, int y) {
      return lod::heightFieldVertex(ground.heights, o.posts, o.posts, kPostSpacing_m, x, y);
    };
    for (int y = 0; y + 1 < o.posts; ++y)
      for (int x = 0; x + 1 < o.posts; ++x) {
        dst[k++] = vtx(x, y), dst[k++] = vtx(x + 1, y), dst[k++] = vtx(x + 1, y + 1);
        dst[k++] = vtx(x, y), dst[k++] = vtx(x + 1, y + 1), dst[k++] = vtx(x, y + 1);
      }
    scene.vertexCount = k;
  }

  // The forest layer, as the service builds it; instance room for the reference (every tree).
  ForestLayerConfig fc;
  fc.seed = o.seed;
  fc.spacing_m = o.treeSpacing_m;
  fc.leafSize_m = o.leafSize_m;
  fc.nearFadeStart_m = o.nearFadeStart_m;
  fc.nearFadeEnd_m = o.nearFadeEnd_m;
  fc.criticalAngle_deg = o.criticalAngle_deg;
  fc.finAlphaThreshold = o.finAlphaThreshold;
  fc.layers = o.layers;
  const double slots = extent_m * extent_m / (o.treeSpacing_m * o.treeSpacing_m);
  fc.maxTrees = static_cast<int>(std::clamp(slots, 1024.0, 4194304.0));
  const render::ForestTextureDesc td = forestBenchTextureDesc(o);
  render::ForestTextures textures;
  const auto tTex = BenchClock::now();
  if (!render::renderForestTextures(bakeModels, td, textures, err)) {
    std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
    return 1;
  }
  textures.spacing_m = o.treeSpacing_m;
  const double texturesMs = msSince(tTex);
  const auto tBuild = BenchClock::now();
  std::unique_ptr<ForestLayer> forest =
      ForestLayer::create(fc, {ground.heights, o.posts, o.posts, kPostSpacing_m, glm::dvec3(0.0)}, err, &nearModels, &textures);
  if (!forest) {
    std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
    return 2;
  }
  const double buildMs = msSince(tBuild);
  scene.forest = forest.get();
  const lod::ForestKdTree& kd = forest->kdTree();
  const lod::FinSet& fins = forest->fins();
  size_t nonEmpty = 0;
  for (const lod::ForestKdLeaf& l : kd.leaves()) nonEmpty += l.count > 0;
  size_t glades = 0;
  for (uint32_t g : forest->map().gr) glades += (g >> 24) == 0;
  const size_t treeCount = kd.trees().size();

  // 1. CPU: near-tree selection on one core (the existing measure), fins.
  const lod::NearFade nearFade{o.nearFadeStart_m, o.nearFadeEnd_m};
  const lod::FarFade farFade{o.nearFadeStart_m, o.nearFadeEnd_m, 6000.0, 8000.0};
  std::vector<lod::ForestInstance> inst(kInstanceCapacity), scratch(kInstanceCapacity);
  std::vector<lod::ForestModelRange> models(nearModels.size());
  flight(kd, field, nearFade, std::min(o.frames, 60), extent_m, inst, scratch, models);  // warm caches
  const Run main = flight(kd, field, nearFade, o.frames, extent_m, inst, scratch, models);
  std::vector<uint32_t> groupOut(fins.groups.size());
  std::vector<double> finsSelected, groupsRejected, finMs;
  for (int i = 0; i < o.frames; ++i) {
    const lod::Camera cam = pathCamera(i, o.frames, extent_m, field);
    lod::FinSelectStats st;
    const auto t0 = BenchClock::now();
    lod::selectFinGroups(fins.groups, cam, farFade, o.finAlphaThreshold, groupOut, &st);
    finMs.push_back(msSince(t0));
    finsSelected.push_back(static_cast<double>(st.finsDrawn));
    groupsRejected.push_back(st.groupsRejected);
  }
  struct CullPoint {
    double nearEnd_m;
    Run run;
  };
  std::vector<CullPoint> cullSweep;
  for (double nearEnd : {200.0, 300.0, 500.0, 800.0, 1200.0}) {
    const lod::NearFade f{0.6 * nearEnd, nearEnd};
    cullSweep.push_back({nearEnd, flight(kd, field, f, o.frames, extent_m, inst, scratch, models)});
  }

  // 2. Rendered flight: frame time, trees / fins drawn.
  std::vector<double> frameMs, treesDrawn, finsDrawn, dropped;
  render::Image img, prev;
  scene.frame(pathCamera(0, o.renderFrames, extent_m, field), true, nullptr);  // warm-up (shader compile)
  for (int i = 0; i < o.renderFrames; ++i) {
    const lod::Camera cam = pathCamera(i, o.renderFrames, extent_m, field);
    frameMs.push_back(scene.frame(cam, true, i == 0 ? &img : nullptr));
    const ForestLayerStats st = forest->stats();
    treesDrawn.push_back(st.treesDrawn);
    finsDrawn.push_back(static_cast<double>(st.finsDrawn));
    dropped.push_back(st.treesDropped);
    if (i == 0) saveImage(o.images, "forest_flight.png", img);
  }
  const int layersDrawn = forest->stats().layers;

  // 3. Popping: the slow approach with and without the forest, and (not in --quick) with a hard
  // switch (0.1 m bands at the near distance: what popping looks like to this measure).
  std::vector<double> pop, popOff, popHard;
  for (int pass = 0; pass < (o.quick ? 2 : 3); ++pass) {
    std::vector<double>& out = pass == 0 ? pop : pass == 1 ? popOff : popHard;
    if (pass == 2) {
      const double e = o.nearFadeEnd_m;
      if (!forest->setFades({e - 0.1, e}, {e - 0.1, e, 6000.0, 8000.0}, err)) {
        std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
        return 1;
      }
    }
    for (int i = 0; i < o.popFrames; ++i) {
      scene.frame(approachCamera(i, extent_m, field), pass != 1, &img);
      if (i > 0) out.push_back(meanChange(prev, img));
      if (i == 0 && pass < 2) saveImage(o.images, pass == 0 ? "approach_forest.png" : "approach_no_forest.png", img);
      std::swap(prev, img);
    }
  }
  // 3b. Transitions alone: the approach's first camera held still while the fade bands move 1 m
  // nearer per frame (what a 1 m approach does to the bands, without the motion): every change
  // between consecutive frames is the transition's own. Smooth bands, then (not in --quick) the
  // hard switch.
  std::vector<double> trans, transHard, transPopped, transHardPopped;
  const lod::Camera still = approachCamera(0, extent_m, field);
  for (int pass = 0; pass < (o.quick ? 1 : 2); ++pass) {
    std::vector<double>& out = pass == 0 ? trans : transHard;
    std::vector<double>& popped = pass == 0 ? transPopped : transHardPopped;
    for (int i = 0; i < o.popFrames; ++i) {
      const double shift = std::min(static_cast<double>(i), 0.5 * o.nearFadeStart_m);
      const double e = o.nearFadeEnd_m - shift, s0 = pass == 0 ? o.nearFadeStart_m - shift : e - 0.1;
      if (!forest->setFades({s0, e}, {s0, e, 6000.0, 8000.0}, err)) {
        std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
        return 1;
      }
      scene.frame(still, true, &img);
      if (i > 0) {
        out.push_back(meanChange(prev, img));
        popped.push_back(render::fractionDifferent(prev, img, kPopLevels));
      }
      std::swap(prev, img);
    }
  }
  if (!forest->setFades(nearFade, farFade, err)) {
    std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
    return 1;
  }
  const auto maxOf = [](const std::vector<double>& v) { return v.empty() ? -1.0 : *std::max_element(v.begin(), v.end()); };
  // Per frame, the change the forest adds to the same camera motion; its median is the steady
  // part (the forest's own detail moving), a pop is a spike above it.
  std::vector<double> excess(pop.size());
  for (size_t i = 0; i < pop.size(); ++i) excess[i] = pop[i] - popOff[i];
  const double steadyExcess = percentile(excess, 50);

  // 4. Sweep: layer counts x near distances, frame time and PSNR against the 3D reference.
  struct SweepPoint {
    int layers;
    double near_m;
    double frameMs;
    double psnr;
    double treesDrawn;
    double switchChange = 0, switchPopped = 0;  // drawnSweep: against all n layers, the same view
  };
  std::vector<SweepPoint> sweep, drawnSweep;  // drawnSweep: `layers` = the count drawn of o.layers baked
  double referenceMs = 0.0;
  uint64_t referenceTrees = 0;
  const int views = o.quick ? 1 : 3;
  const int sweepFrames = o.quick ? 3 : 12;
  if (o.renderSweep) {
    std::vector<lod::Camera> viewCams;
    for (int v = 0; v < views; ++v) viewCams.push_back(pathCamera(v * o.renderFrames / views + 1, o.renderFrames, extent_m, field));
    std::vector<render::Image> reference(static_cast<size_t>(views));
    // Reference: every tree up to the far plane as a 3D model (alpha 1), no layers, no fins.
    forest->enableParts(true, false, false);
    if (!forest->setFades({7999.0, 8000.0}, {7998.0, 7999.5, 7999.8, 8000.0}, err)) {
      std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
      return 1;
    }
    for (int v = 0; v < views; ++v) {
      referenceMs += scene.frame(viewCams[static_cast<size_t>(v)], true, &reference[static_cast<size_t>(v)]);
      referenceTrees += forest->stats().treesDrawn;
      if (v == 0) saveImage(o.images, "reference.png", reference[0]);
    }
    referenceMs /= views;
    forest->enableParts(true, true, true);
    const std::vector<int> layerCounts = o.quick ? std::vector<int>{4, 8} : std::vector<int>{2, 4, 8, 16};
    const std::vector<double> nears = o.quick ? std::vector<double>{200.0, 500.0} : std::vector<double>{200.0, 300.0, 500.0, 800.0};
    for (int n : layerCounts) {
      render::ForestTextureDesc d = td;
      d.layers = n;
      render::ForestTextures t;
      if (!render::renderForestTextures(bakeModels, d, t, err) || !forest->pass().setTextures(t, err)) {
        std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
        return 1;
      }
      for (double nearEnd : nears) {
        if (!forest->setFades({0.6 * nearEnd, nearEnd}, {0.6 * nearEnd, nearEnd, 6000.0, 8000.0}, err)) {
          std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
          return 1;
        }
        SweepPoint p{n, nearEnd, 0, 0, 0};
        std::vector<double> ms, drawn;
        for (int i = 0; i < sweepFrames; ++i) {
          ms.push_back(scene.frame(pathCamera(i * o.renderFrames / sweepFrames, o.renderFrames, extent_m, field), true, nullptr));
          drawn.push_back(forest->stats().treesDrawn);
        }
        p.frameMs = percentile(ms, 50);
        p.treesDrawn = percentile(drawn, 50);
        for (int v = 0; v < views; ++v) {
          scene.frame(viewCams[static_cast<size_t>(v)], true, &img);
          p.psnr += render::psnrDb(img, reference[static_cast<size_t>(v)]) / views;
          if (v == 0 && n == o.layers && nearEnd == 500.0) {
            saveImage(o.images, "forest_view.png", img);
            prev = img;  // what a switch of the layer count changes (below)
          }
        }
        sweep.push_back(p);
        // The frame governor's layer knob: fewer layers drawn of the main run's n, their slabs
        // composited per group (not baked for that count), at the default near range.
        if (n != o.layers || nearEnd != 500.0) continue;
        for (int m = n / 2; m >= 1; m /= 2) {
          forest->prepareLayersDrawn(m, m);
          forest->setLayersDrawn(m);
          SweepPoint q{m, nearEnd, 0, 0, 0};
          ms.clear();
          drawn.clear();
          for (int i = 0; i < sweepFrames; ++i) {
            ms.push_back(scene.frame(pathCamera(i * o.renderFrames / sweepFrames, o.renderFrames, extent_m, field), true, nullptr));
            drawn.push_back(forest->stats().treesDrawn);
          }
          q.frameMs = percentile(ms, 50);
          q.treesDrawn = percentile(drawn, 50);
          for (int v = 0; v < views; ++v) {
            scene.frame(viewCams[static_cast<size_t>(v)], true, &img);
            q.psnr += render::psnrDb(img, reference[static_cast<size_t>(v)]) / views;
            if (v == 0) {
              q.switchChange = meanChange(prev, img);
              q.switchPopped = render::fractionDifferent(prev, img, kPopLevels);
            }
          }
          drawnSweep.push_back(q);
        }
        forest->setLayersDrawn(0);
      }
    }
  }

  const double area = extent_m * extent_m / 1e6;
  const double droppedMax = dropped.empty() ? 0.0 : *std::max_element(dropped.begin(), dropped.end());
  const double popMax = *std::max_element(pop.begin(), pop.end());
  const double popOffMax = *std::max_element(popOff.begin(), popOff.end());
  if (o.json) {
    std::printf("{\"trees\":%zu,\"area_km2\":%.3f,\"extent_m\":%.1f,\"ground\":\"%s\",\"models\":\"%s\","
                "\"model_triangles\":%zu,\"glade_fraction\":%.3f,\"forest_build_ms\":%.1f,\"textures_ms\":%.1f,"
                "\"leaves\":%zu,\"leaves_nonempty\":%zu,\"kd_depth\":%d,\"frames\":%d,"
                "\"near_fade_start_m\":%.1f,\"near_fade_end_m\":%.1f,\"cull_ms_p50\":%.4f,\"cull_ms_p99\":%.4f,"
                "\"cull_ms_max\":%.4f,\"cull_cpu_ms_p99\":%.4f,\"trees_tested_p50\":%.0f,\"cull_trees_drawn_p50\":%.0f,"
                "\"dropped_max\":%u,\"fin_edges_tested\":%llu,\"fin_edges_below_angle\":%llu,\"fins\":%zu,"
                "\"fin_groups\":%zu,\"fins_selected_p50\":%.0f,\"fin_groups_rejected_p50\":%.0f,\"fin_select_ms_p99\":%.4f,"
                "\"rendering\":true,\"width\":%d,\"height\":%d,\"render_frames\":%d,\"frame_ms_p50\":%.2f,"
                "\"frame_ms_p99\":%.2f,\"trees_drawn_p50\":%.0f,\"trees_dropped_max\":%.0f,\"layers\":%d,"
                "\"fins_drawn_p50\":%.0f,\"pop_frames\":%d,\"popping_max\":%.3f,\"popping_p50\":%.3f,"
                "\"popping_max_no_forest\":%.3f,\"popping_p50_no_forest\":%.3f,\"popping_steady_excess\":%.3f,"
                "\"popping_spike\":%.3f,\"popping_max_hard_switch\":%.3f,\"transition_max\":%.4f,\"transition_p50\":%.4f,"
                "\"transition_max_hard_switch\":%.4f,\"transition_popped_max\":%.6f,\"transition_popped_max_hard_switch\":%.6f,"
                "\"reference_views\":%d,"
                "\"reference_ms\":%.0f,\"reference_trees_per_view\":%.0f,\"cull_sweep\":[",
                treeCount, area, extent_m, jsonEscape(ground.source).c_str(), jsonEscape(modelSource).c_str(), modelTriangles,
                static_cast<double>(glades) / static_cast<double>(forest->map().gr.size()), buildMs, texturesMs,
                kd.leaves().size(), nonEmpty, kd.depth(), o.frames, o.nearFadeStart_m, o.nearFadeEnd_m, main.p50, main.p99,
                main.max, main.cpuP99, main.testedP50, main.drawnP50, main.droppedMax,
                static_cast<unsigned long long>(fins.edgesTested), static_cast<unsigned long long>(fins.edgesBelowAngle),
                fins.fins.size(), fins.groups.size(), percentile(finsSelected, 50), percentile(groupsRejected, 50),
                percentile(finMs, 99), o.width, o.height, o.renderFrames, percentile(frameMs, 50), percentile(frameMs, 99),
                percentile(treesDrawn, 50), droppedMax, layersDrawn, percentile(finsDrawn, 50), o.popFrames, popMax,
                percentile(pop, 50), popOffMax, percentile(popOff, 50), steadyExcess,
                *std::max_element(excess.begin(), excess.end()) - steadyExcess,
                maxOf(popHard), maxOf(trans), percentile(trans, 50), maxOf(transHard), maxOf(transPopped),
                maxOf(transHardPopped), views, referenceMs,
                static_cast<double>(referenceTrees) / views);
    for (size_t i = 0; i < cullSweep.size(); ++i) {
      std::printf("%s{\"near_m\":%.0f,\"cull_ms_p50\":%.4f,\"cull_ms_p99\":%.4f,\"cull_cpu_ms_p99\":%.4f,\"trees_drawn_p50\":%.0f,\"dropped_max\":%u}",
                  i ? "," : "", cullSweep[i].nearEnd_m, cullSweep[i].run.p50, cullSweep[i].run.p99, cullSweep[i].run.cpuP99,
                  cullSweep[i].run.drawnP50, cullSweep[i].run.droppedMax);
    }
    std::printf("],\"sweep\":[");
    for (size_t i = 0; i < sweep.size(); ++i) {
      std::printf("%s{\"layers\":%d,\"near_m\":%.0f,\"frame_ms\":%.2f,\"psnr_db\":%.2f,\"trees_drawn_p50\":%.0f}", i ? "," : "",
                  sweep[i].layers, sweep[i].near_m, sweep[i].frameMs, sweep[i].psnr, sweep[i].treesDrawn);
    }
    std::printf("],\"drawn_sweep\":[");
    for (size_t i = 0; i < drawnSweep.size(); ++i) {
      std::printf("%s{\"layers\":%d,\"layers_drawn\":%d,\"near_m\":%.0f,\"frame_ms\":%.2f,\"psnr_db\":%.2f,"
                  "\"switch_change\":%.3f,\"switch_popped\":%.5f}",
                  i ? "," : "", o.layers, drawnSweep[i].layers, drawnSweep[i].near_m, drawnSweep[i].frameMs, drawnSweep[i].psnr,
                  drawnSweep[i].switchChange, drawnSweep[i].switchPopped);
    }
    std::printf("]}\n");
  } else {
    std::printf("forest: %zu trees over %.1f km2 (%s; models %s, %zu triangles), %zu leaves (%zu non-empty)\n", treeCount,
                area, ground.source.c_str(), modelSource.c_str(), modelTriangles, kd.leaves().size(), nonEmpty);
    std::printf("near %.0f-%.0f m: cull+gather+sort p50 %.3f ms p99 %.3f ms (thread CPU p99 %.3f ms)\n", o.nearFadeStart_m,
                o.nearFadeEnd_m, main.p50, main.p99, main.cpuP99);
    std::printf("rendered %d x %d: frame p50 %.1f ms, trees drawn p50 %.0f, %d layers, fins drawn p50 %.0f\n", o.width,
                o.height, percentile(frameMs, 50), percentile(treesDrawn, 50), layersDrawn, percentile(finsDrawn, 50));
    std::printf("popping (mean |dRGB| between frames, slow approach): max %.2f (p50 %.2f); no forest: max %.2f (p50 %.2f); "
                "steady excess %.2f, spike %.2f, hard switch max %.2f; transitions alone: max %.3f (hard switch %.3f), "
                "pixels changing by > 8 levels in a frame: max %.5f (hard switch %.5f)\n",
                popMax, percentile(pop, 50), popOffMax, percentile(popOff, 50), steadyExcess,
                *std::max_element(excess.begin(), excess.end()) - steadyExcess,
                maxOf(popHard), maxOf(trans), maxOf(transHard), maxOf(transPopped), maxOf(transHardPopped));
    for (const SweepPoint& s : sweep)
      std::printf("  layers %2d near %4.0f m: frame %.1f ms, PSNR %.2f dB vs 3D reference, trees %.0f\n", s.layers, s.near_m,
                  s.frameMs, s.psnr, s.treesDrawn);
    for (const SweepPoint& s : drawnSweep)
      std::printf("  %d of %d layers drawn (composited) near %4.0f m: frame %.1f ms, PSNR %.2f dB; a switch from %d "
                  "changes %.3f (mean |dRGB|), %.5f of the pixels by > %d levels\n",
                  s.layers, o.layers, s.near_m, s.frameMs, s.psnr, o.layers, s.switchChange, s.switchPopped, kPopLevels);
  }
  return main.droppedMax > 0 || droppedMax > 0 ? 1 : 0;
}

}  // namespace ig
