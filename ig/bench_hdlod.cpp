#include "ig/bench_hdlod.h"

#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "ig/clock.h"
#include "ig/hdlod_tool.h"
#include "ig/json.h"
#include "ig/stats.h"
#include "lod/hdlod_build.h"
#include "lod/hdlod_cache.h"
#include "lod/hdlod_select.h"
#include "lod/hdlod_site.h"
#include "render/context.h"
#include "render/hdlod_pass.h"
#include "render/image.h"
#include "render/renderer.h"

namespace ig {
namespace {

namespace hd = lod::hdlod;
using BenchClock = std::chrono::steady_clock;
double secondsSince(BenchClock::time_point t0) { return std::chrono::duration<double>(BenchClock::now() - t0).count(); }

// One side of a case (HDLOD or full detail).
struct Side {
  double triangles = 0;  // mean over the frames (animation) or of the one view
  double draws = 0;
  double selectMs = 0.0, frameMs = 0.0;
  double selectCpuMs = 0.0;  // median selection time in thread CPU time
  // The median frame's phases: selection, submission (CPU: array updates + GL calls), glFinish.
  double phaseSelectMs = 0.0, phaseSubmitMs = 0.0, phaseFinishMs = 0.0;
};

struct Case {
  std::string time, screen;
  Side hdlod, full;
  double psnr = 0.0;  // HDLOD image against the full one (min over the checked frames of the animation)
};

struct SweepRow {
  double px = 0;
  Side side;
  double psnr = 0.0;
};

// Looks at the scene's centre from the south-west, 25 degrees down, from the distance at which
// its bounding sphere spans `linear` of the screen height (linear = sqrt(area fraction)).
lod::Camera cameraFor(const lod::Aabb& box, double linear, const HdlodBenchOptions& o) {
  lod::Camera cam;
  cam.fovY_deg = o.fovY_deg;
  cam.aspect = static_cast<double>(o.width_px) / o.height_px;
  const double R = 0.5 * glm::length(box.max - box.min);
  const double d = R / (std::tan(0.5 * o.fovY_deg * 3.14159265358979323846 / 180.0) * linear);
  const double heading = 45.0, pitch = -25.0, k = 3.14159265358979323846 / 180.0;
  const glm::dvec3 fwd{std::sin(heading * k) * std::cos(pitch * k), std::cos(heading * k) * std::cos(pitch * k), std::sin(pitch * k)};
  cam.eye_m = (box.min + box.max) * 0.5 - fwd * d;
  cam.heading_deg = heading;
  cam.pitch_deg = pitch;
  cam.near_m = 0.5;
  cam.far_m = d + 4.0 * R;
  return cam;
}

// Selection, and optionally rendering, of one side (HDLOD or full) through its own pass.
class Runner {
 public:
  Runner(const hd::HdlodTree& tree, const hd::Scene& scene, bool full, render::Renderer* renderer, render::HdlodPass* pass)
      : tree_(tree), scene_(scene), full_(full), renderer_(renderer), pass_(pass), draws_(tree) {}

  hd::SelectStats select(const hd::SelectView& v, size_t& n) {
    hd::SelectStats st;
    n = full_ ? hd::selectAll(tree_, scene_, v, draws_.draws, draws_.moving, &st)
              : hd::selectHdlod(tree_, scene_, v, draws_.draws, draws_.moving, &st);
    return st;
  }

  // Median selection time over `repeats` (wall clock; the thread CPU time's median in *cpuMs).
  double selectMs(const hd::SelectView& v, int repeats, hd::SelectStats& st, double* cpuMs = nullptr) {
    std::vector<double> ms, cpu;
    size_t n = 0;
    for (int i = 0; i < std::max(1, repeats); ++i) {
      const double c0 = threadCpuMs();
      const auto t0 = BenchClock::now();
      st = select(v, n);
      ms.push_back(secondsSince(t0) * 1e3);
      cpu.push_back(threadCpuMs() - c0);
    }
    if (cpuMs) *cpuMs = median(cpu);
    return median(ms);
  }

  // One frame: select, submit, glFinish. Returns its time in ms; adds the phases to `phases`.
  double frame(const hd::SelectView& v, const render::Lighting& light) {
    const auto t0 = BenchClock::now();
    size_t n = 0;
    select(v, n);
    const auto t1 = BenchClock::now();
    renderer_->beginFrame(v.camera, light);
    pass_->draw(*renderer_, {draws_.draws.data(), n});
    renderer_->endFrame();
    const auto t2 = BenchClock::now();
    renderer_->finish();
    const auto t3 = BenchClock::now();
    lastSelectMs = std::chrono::duration<double>(t1 - t0).count() * 1e3;
    lastSubmitMs = std::chrono::duration<double>(t2 - t1).count() * 1e3;
    lastFinishMs = std::chrono::duration<double>(t3 - t2).count() * 1e3;
    return std::chrono::duration<double>(t3 - t0).count() * 1e3;
  }
  double lastSelectMs = 0.0, lastSubmitMs = 0.0, lastFinishMs = 0.0;

 private:
  const hd::HdlodTree& tree_;
  const hd::Scene& scene_;
  bool full_;
  render::Renderer* renderer_;
  render::HdlodPass* pass_;
  hd::DrawList draws_;
};

void printSide(const char* name, const Side& s, bool render) {
  std::printf("\"%s\":{\"triangles\":%.0f,\"draws\":%.0f,\"select_ms\":%.4f,\"select_cpu_ms\":%.4f", name, s.triangles, s.draws,
              s.selectMs, s.selectCpuMs);
  if (render) std::printf(",\"frame_ms\":%.3f", s.frameMs);
  if (render && s.phaseSubmitMs > 0.0) {
    std::printf(",\"frame_select_ms\":%.3f,\"frame_submit_ms\":%.3f,\"frame_finish_ms\":%.3f", s.phaseSelectMs, s.phaseSubmitMs,
                s.phaseFinishMs);
  }
  std::printf("}");
}

}  // namespace

int runHdlodBench(const HdlodBenchOptions& in) {
  HdlodBenchOptions o = in;
  if (o.quick) {
    o.scale = std::min(o.scale, 0.05);
    o.width_px = std::min(o.width_px, 480);
    o.height_px = std::min(o.height_px, 270);
    o.repeats = std::min(o.repeats, 5);
    o.frames = std::min(o.frames, 2);
    o.animationFrames = std::min(o.animationFrames, 8);
    o.compareSimplifiers = false;
  }
  if (!(o.scale > 0.0) || o.width_px < 16 || o.height_px < 16 || !(o.tolerance_px >= 0.0) || !(o.fovY_deg > 0.0 && o.fovY_deg < 180.0) ||
      o.frames < 1 || o.animationFrames < 2 || !(o.compareScale > 0.0) || !(o.epsPerSize > 0.0 && o.epsPerSize <= 1.0)) {
    std::fprintf(stderr, "igbench hdlod: bad options (scale %g, %dx%d px, r %g px, fov %g deg, frames %d, animation frames %d, compare scale %g)\n",
                 o.scale, o.width_px, o.height_px, o.tolerance_px, o.fovY_deg, o.frames, o.animationFrames, o.compareScale);
    return 2;
  }
  hd::SiteParams sp;
  sp.scale = o.scale;
  sp.seed = o.seed;
  std::string error;
  const auto tScene = BenchClock::now();
  const hd::Scene scene = hd::makeConstructionSite(sp, error);
  if (!error.empty()) {
    std::fprintf(stderr, "igbench hdlod: %s\n", error.c_str());
    return 2;
  }
  const double sceneS = secondsSince(tScene);
  hd::BuildConfig config;
  if (!hd::parseSimplifier(o.simplifier, config.simplifier)) {
    std::fprintf(stderr, "igbench hdlod: --simplifier: unknown simplifier '%s' (meshoptimizer, openmesh, clustering)\n",
                 o.simplifier.c_str());
    return 2;
  }
  config.epsPerSize = o.epsPerSize;
  config.strictHausdorff = o.strictHausdorff;
  ProgressBar bar("hdlod build", o.progress);
  config.progress = bar.callback();
  const auto tBuild = BenchClock::now();
  hd::CacheOutcome outcome = hd::CacheOutcome::Disabled;
  std::string cacheNote;
  const hd::HdlodTree tree = hd::loadOrBuildHdlod(scene, config, o.cacheFile, outcome, cacheNote);
  const double buildS = secondsSince(tBuild);
  bar.finish();
  if (!cacheNote.empty()) std::fprintf(stderr, "igbench hdlod: %s\n", cacheNote.c_str());
  uint64_t cacheBytes = 0;
  if (!o.cacheFile.empty()) {
    if (FILE* f = std::fopen(o.cacheFile.c_str(), "rb")) {
      std::fseek(f, 0, SEEK_END);
      cacheBytes = static_cast<uint64_t>(std::max(0L, std::ftell(f)));
      std::fclose(f);
    }
  }
  uint64_t triangles = 0;
  for (const hd::Object& obj : scene.objects) triangles += scene.models[obj.model].triangleCount();
  if (tree.root >= tree.clusters.size()) {
    std::fprintf(stderr, "igbench hdlod: the site has nothing to draw\n");
    return 2;
  }
  const hd::Cluster& root = tree.clusters[tree.root];

  // GL: one renderer, one pass per side (each keeps its octants' arrays from frame to frame).
  std::unique_ptr<render::GlContext> context;
  std::unique_ptr<render::Renderer> renderer;
  std::unique_ptr<render::HdlodPass> hdlodPass, fullPass;
  std::string contextName = "none";
  render::Lighting light;
  light.sunDirection = glm::normalize(glm::dvec3(-0.5, -0.6, 0.7));
  light.fog = false;
  if (o.render) {
    context = render::createContext(render::ContextKind::Headless, o.width_px, o.height_px, error);
    renderer = std::make_unique<render::Renderer>();
    hdlodPass = std::make_unique<render::HdlodPass>();
    fullPass = std::make_unique<render::HdlodPass>();
    if (!context || !renderer->init(o.width_px, o.height_px, error, o.msaa) || !hdlodPass->init(tree, scene, 3, error) ||
        !fullPass->init(tree, scene, 3, error)) {
      std::fprintf(stderr, "igbench hdlod: %s\n", error.c_str());
      return 3;
    }
    contextName = context->description();
  }
  Runner hdlodRun(tree, scene, false, renderer.get(), hdlodPass.get());
  Runner fullRun(tree, scene, true, renderer.get(), fullPass.get());
  render::Image hdlodImage, fullImage;
  auto writeImages = [&](const std::string& tag) {
    if (o.imageDir.empty()) return;
    std::string name = tag;
    std::replace(name.begin(), name.end(), '/', '_');
    std::string e;
    if (!render::writePng(o.imageDir + "/" + name + "_hdlod.png", hdlodImage, e) ||
        !render::writePng(o.imageDir + "/" + name + "_full.png", fullImage, e)) {
      std::fprintf(stderr, "igbench hdlod: --images: %s\n", e.c_str());
    }
  };

  // One still view: selection medians, frame medians, PSNR.
  auto measureView = [&](const hd::SelectView& v, Side& h, Side& f, double& psnr) {
    hd::SelectStats hs, fs;
    h.selectMs = hdlodRun.selectMs(v, o.repeats, hs, &h.selectCpuMs);
    f.selectMs = fullRun.selectMs(v, std::max(1, o.repeats / 4), fs, &f.selectCpuMs);
    h.triangles = static_cast<double>(hs.triangles);
    h.draws = hs.draws;
    f.triangles = static_cast<double>(fs.triangles);
    f.draws = fs.draws;
    if (!o.render) return;
    std::vector<double> hm, fm, hsel, hsub, hfin;
    for (int i = 0; i < o.frames + 1; ++i) {  // the first uploads the octants
      hm.push_back(hdlodRun.frame(v, light));
      hsel.push_back(hdlodRun.lastSelectMs);
      hsub.push_back(hdlodRun.lastSubmitMs);
      hfin.push_back(hdlodRun.lastFinishMs);
    }
    renderer->readPixels(hdlodImage);
    hsel.erase(hsel.begin());
    hsub.erase(hsub.begin());
    hfin.erase(hfin.begin());
    h.phaseSelectMs = median(hsel);
    h.phaseSubmitMs = median(hsub);
    h.phaseFinishMs = median(hfin);
    for (int i = 0; i < o.frames + 1; ++i) fm.push_back(fullRun.frame(v, light));
    renderer->readPixels(fullImage);
    hm.erase(hm.begin());
    fm.erase(fm.begin());
    h.frameMs = median(hm);
    f.frameMs = median(fm);
    psnr = render::psnrDb(hdlodImage, fullImage);
  };

  const char* timeNames[] = {"start", "1/3", "2/3", "end"};
  const double timeFrac[] = {0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0};
  const char* screenNames[] = {"1/1", "1/4", "1/16"};
  const double screenLinear[] = {1.0, 0.5, 0.25};
  const double r = hd::toleranceFromPixels(o.tolerance_px, o.fovY_deg, o.height_px);
  std::vector<Case> cases;
  for (int ti = 0; ti < 4; ++ti) {
    for (int si = 0; si < 3; ++si) {
      hd::SelectView v;
      v.camera = cameraFor(root.box, screenLinear[si], o);
      v.time_s = timeFrac[ti] * scene.duration_s;
      v.tolerance_rad = r;
      Case c;
      c.time = timeNames[ti];
      c.screen = screenNames[si];
      measureView(v, c.hdlod, c.full, c.psnr);
      writeImages(c.time + "_" + c.screen);
      cases.push_back(c);
    }
  }
  // Animation: the schedule played from 0 to T, camera still; per frame select + render. Images
  // compared at three frames (1/4, 1/2, 3/4 of the way).
  for (int si = 0; si < 3; ++si) {
    Case c;
    c.time = "animation";
    c.screen = screenNames[si];
    c.psnr = 99.0;
    const lod::Camera cam = cameraFor(root.box, screenLinear[si], o);
    std::vector<double> hs, hc, fs, fc, hf, ff;
    const int n = o.animationFrames;
    for (int i = 0; i < n; ++i) {
      hd::SelectView v;
      v.camera = cam;
      v.time_s = scene.duration_s * i / (n - 1);
      v.tolerance_rad = r;
      hd::SelectStats a, b;
      double cpu = 0.0;
      hs.push_back(hdlodRun.selectMs(v, 1, a, &cpu));
      hc.push_back(cpu);
      fs.push_back(fullRun.selectMs(v, 1, b, &cpu));
      fc.push_back(cpu);
      c.hdlod.triangles += static_cast<double>(a.triangles) / n;
      c.hdlod.draws += static_cast<double>(a.draws) / n;
      c.full.triangles += static_cast<double>(b.triangles) / n;
      c.full.draws += static_cast<double>(b.draws) / n;
      if (!o.render) continue;
      hf.push_back(hdlodRun.frame(v, light));
      const bool check = i == n / 4 || i == n / 2 || i == 3 * n / 4;
      if (check) renderer->readPixels(hdlodImage);
      ff.push_back(fullRun.frame(v, light));
      if (check) {
        renderer->readPixels(fullImage);
        c.psnr = std::min(c.psnr, render::psnrDb(hdlodImage, fullImage));
      }
    }
    c.hdlod.selectMs = median(hs);
    c.hdlod.selectCpuMs = median(hc);
    c.full.selectMs = median(fs);
    c.full.selectCpuMs = median(fc);
    c.hdlod.frameMs = median(hf);
    c.full.frameMs = median(ff);
    cases.push_back(c);
  }

  const double sweepPx[] = {0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0};
  std::vector<SweepRow> sweep;
  {
    hd::SelectView v;
    v.camera = cameraFor(root.box, 1.0, o);
    v.time_s = scene.duration_s / 3.0;
    Side fullSide;
    double unused = 0.0;
    v.tolerance_rad = 0.0;
    Side h0;
    measureView(v, h0, fullSide, unused);  // leaves fullImage as the sweep's reference
    const render::Image reference = fullImage;
    for (double px : sweepPx) {
      SweepRow row;
      row.px = px;
      v.tolerance_rad = hd::toleranceFromPixels(px, o.fovY_deg, o.height_px);
      hd::SelectStats st;
      row.side.selectMs = hdlodRun.selectMs(v, o.repeats, st);
      row.side.triangles = static_cast<double>(st.triangles);
      row.side.draws = st.draws;
      if (o.render) {
        std::vector<double> ms;
        for (int i = 0; i < o.frames + 1; ++i) ms.push_back(hdlodRun.frame(v, light));
        ms.erase(ms.begin());
        row.side.frameMs = median(ms);
        renderer->readPixels(hdlodImage);
        row.psnr = render::psnrDb(hdlodImage, reference);
      }
      sweep.push_back(row);
    }
  }

  double worstSelect = 0.0, worstSelectCpu = 0.0, worstRatio116 = 1e300, endRatio = 0.0, worstPsnr = 99.0, pipelineGain = 0.0;
  for (const Case& c : cases) {
    worstSelectCpu = std::max(worstSelectCpu, c.hdlod.selectCpuMs);  // animation included
    if (c.time == "animation") continue;
    // Selection on its own thread, overlapped with the previous frame's submission and GPU work,
    // would save at most min(select, submit + finish) of the frame.
    const Side& h = c.hdlod;
    if (h.frameMs > 0.0) pipelineGain = std::max(pipelineGain, std::min(h.phaseSelectMs, h.phaseSubmitMs + h.phaseFinishMs) / h.frameMs);
    worstSelect = std::max(worstSelect, c.hdlod.selectMs);
    if (c.screen == "1/16" && c.hdlod.triangles > 0) worstRatio116 = std::min(worstRatio116, c.full.triangles / c.hdlod.triangles);
    if (c.time == "end" && c.screen == "1/16" && c.hdlod.frameMs > 0) endRatio = c.full.frameMs / c.hdlod.frameMs;
    worstPsnr = std::min(worstPsnr, c.psnr);
  }

  // Per simplifier (on a site of compareScale): build time, measured error of the merged
  // clusters' own simplification (D, the sampled Hausdorff distance without the children's
  // eps: mean and max), and the smallest full / HDLOD triangle ratio at 1/16 over the four times.
  struct SimplifierRun {
    hd::Simplifier simplifier;
    double seconds = 0.0, meanM = 0.0, maxM = 0.0, ratio116 = 0.0;
    uint64_t mergedTriangles = 0;
    uint32_t sloppy = 0;
  };
  std::vector<SimplifierRun> runs;
  if (o.compareSimplifiers) {
    hd::SiteParams csp = sp;
    csp.scale = o.compareScale;
    const hd::Scene small = hd::makeConstructionSite(csp, error);
    for (hd::Simplifier s : {hd::Simplifier::Meshoptimizer, hd::Simplifier::OpenMesh, hd::Simplifier::Clustering}) {
      hd::BuildConfig sc;
      sc.simplifier = s;
      sc.epsPerSize = config.epsPerSize;
      sc.strictHausdorff = config.strictHausdorff;
      const auto t0 = BenchClock::now();
      const hd::HdlodTree other = hd::buildHdlod(small, sc);
      SimplifierRun run{s};
      run.seconds = secondsSince(t0);
      const auto& os = other.stats;
      run.meanM = os.mergedClusters ? os.simplifyErrorSum_m / os.mergedClusters : 0.0;
      run.maxM = os.simplifyErrorMax_m;
      run.mergedTriangles = os.mergedTriangles;
      run.sloppy = os.sloppyClusters;
      run.ratio116 = 1e300;
      hd::DrawList otherDraws(other);
      for (int ti = 0; ti < 4; ++ti) {
        hd::SelectView v;
        v.camera = cameraFor(other.clusters[other.root].box, 0.25, o);
        v.time_s = timeFrac[ti] * small.duration_s;
        v.tolerance_rad = r;
        hd::SelectStats a, b;
        hd::selectHdlod(other, small, v, otherDraws.draws, otherDraws.moving, &a);
        hd::selectAll(other, small, v, otherDraws.draws, otherDraws.moving, &b);
        if (a.triangles > 0) run.ratio116 = std::min(run.ratio116, static_cast<double>(b.triangles) / static_cast<double>(a.triangles));
      }
      runs.push_back(run);
    }
  }

  const auto& st = tree.stats;
  const uint64_t gpuBytes = hdlodPass ? hdlodPass->bufferBytes() : 0;
  if (o.json) {
    std::printf("{\"suite\":\"hdlod\",\"scale\":%g,\"seed\":%u,\"objects\":%zu,\"static\":%u,\"pseudo_dynamic\":%u,\"dynamic\":%u,"
                "\"empty\":%u,\"triangles\":%llu,\"scene_s\":%.3f,\"build_s\":%.3f,\"cache\":\"%s\",\"cache_bytes\":%llu,"
                "\"clusters\":%zu,\"merged_clusters\":%u,\"levels\":%u,\"merged_triangles\":%llu,\"model_lods\":%u,"
                "\"eps_per_size\":%g,\"strict_hausdorff\":%s,\"hausdorff_samples\":%llu,\"width\":%d,\"height\":%d,\"msaa\":%d,\"r_px\":%g,\"context\":\"%s\",\"gpu_bytes\":%llu,\"cases\":[",
                o.scale, o.seed, scene.objects.size(), st.staticObjects, st.pseudoDynamicObjects, st.dynamicObjects, st.emptyObjects,
                static_cast<unsigned long long>(triangles), sceneS, buildS, hd::cacheOutcomeName(outcome),
                static_cast<unsigned long long>(cacheBytes), tree.clusters.size(), st.mergedClusters, st.levels,
                static_cast<unsigned long long>(st.mergedTriangles), st.modelLods, o.epsPerSize, o.strictHausdorff ? "true" : "false", static_cast<unsigned long long>(st.hausdorffSamples),
                o.width_px, o.height_px, o.msaa, o.tolerance_px, jsonEscape(contextName).c_str(), static_cast<unsigned long long>(gpuBytes));
    for (size_t i = 0; i < cases.size(); ++i) {
      const Case& c = cases[i];
      std::printf("%s{\"time\":\"%s\",\"screen\":\"%s\",", i ? "," : "", c.time.c_str(), c.screen.c_str());
      printSide("hdlod", c.hdlod, o.render);
      std::printf(",");
      printSide("full", c.full, o.render);
      if (o.render) std::printf(",\"psnr_db\":%.2f", c.psnr);
      std::printf("}");
    }
    std::printf("],\"sweep_time\":\"1/3\",\"sweep_screen\":\"1/1\",\"sweep\":[");
    for (size_t i = 0; i < sweep.size(); ++i) {
      const SweepRow& s = sweep[i];
      std::printf("%s{\"r_px\":%g,\"triangles\":%.0f,\"draws\":%.0f,\"select_ms\":%.4f", i ? "," : "", s.px, s.side.triangles, s.side.draws,
                  s.side.selectMs);
      if (o.render) std::printf(",\"frame_ms\":%.3f,\"psnr_db\":%.2f", s.side.frameMs, s.psnr);
      std::printf("}");
    }
    std::printf("],\"simplifier\":\"%s\",\"sloppy_clusters\":%u,\"compare_scale\":%g,\"simplifiers\":[", hd::simplifierName(config.simplifier),
                st.sloppyClusters, o.compareScale);
    for (size_t i = 0; i < runs.size(); ++i) {
      const SimplifierRun& run = runs[i];
      std::printf("%s{\"name\":\"%s\",\"seconds\":%.3f,\"hausdorff_m\":%.4f,\"hausdorff_max_m\":%.4f,\"merged_triangles\":%llu,"
                  "\"sloppy_clusters\":%u,\"triangle_ratio_1_16_min\":%.2f}",
                  i ? "," : "", hd::simplifierName(run.simplifier), run.seconds, run.meanM, run.maxM,
                  static_cast<unsigned long long>(run.mergedTriangles), run.sloppy, run.ratio116);
    }
    std::printf("],\"select_ms_max\":%.4f,\"select_cpu_ms_max\":%.4f,\"triangle_ratio_1_16_min\":%.2f", worstSelect, worstSelectCpu,
                worstRatio116);
    if (o.render) {
      std::printf(",\"frame_ratio_end_1_16\":%.2f,\"psnr_db_min\":%.2f,\"two_thread_gain_max\":%.3f", endRatio, worstPsnr, pipelineGain);
    }
    std::printf("}\n");
  } else {
    std::printf("hdlod suite: site scale %g (seed %u): %zu objects (%u static, %u pseudo-dynamic, %u dynamic, %u empty), %llu triangles\n",
                o.scale, o.seed, scene.objects.size(), st.staticObjects, st.pseudoDynamicObjects, st.dynamicObjects, st.emptyObjects,
                static_cast<unsigned long long>(triangles));
    std::printf("  generated in %.2f s, tree %s in %.2f s (%s): %zu clusters (%u merged, %u levels, %llu merged triangles, %u model versions)\n",
                sceneS, hd::cacheOutcomeName(outcome), buildS, hd::simplifierName(config.simplifier), tree.clusters.size(), st.mergedClusters,
                st.levels, static_cast<unsigned long long>(st.mergedTriangles), st.modelLods);
    std::printf("  r = %g px, %dx%d, msaa %d, %s\n", o.tolerance_px, o.width_px, o.height_px, o.msaa, contextName.c_str());
    std::printf("  time      screen | HDLOD triangles draws select ms frame ms | full triangles draws select ms frame ms | ratio  PSNR dB\n");
    for (const Case& c : cases) {
      std::printf("    %-9s %-4s | %9.0f %6.0f %8.3f %8.2f | %9.0f %6.0f %8.3f %8.2f | %6.1fx %6.2f\n", c.time.c_str(), c.screen.c_str(),
                  c.hdlod.triangles, c.hdlod.draws, c.hdlod.selectMs, c.hdlod.frameMs, c.full.triangles, c.full.draws, c.full.selectMs,
                  c.full.frameMs, c.hdlod.triangles > 0 ? c.full.triangles / c.hdlod.triangles : 0.0, c.psnr);
    }
    std::printf("  sweep at 1/3, scene on the whole screen: r px, triangles, draws, select ms, frame ms, PSNR dB (against r = 0's full image)\n");
    for (const SweepRow& s : sweep) {
      std::printf("    %5.2f %9.0f %6.0f %8.3f %8.2f %6.2f\n", s.px, s.side.triangles, s.side.draws, s.side.selectMs, s.side.frameMs, s.psnr);
    }
    for (const SimplifierRun& run : runs) {
      std::printf("  simplifier %-13s (scale %g): built in %6.2f s, measured error mean %.3f m max %.3f m, %llu merged triangles, 1/16 ratio %.1fx\n",
                  hd::simplifierName(run.simplifier), o.compareScale, run.seconds, run.meanM, run.maxM,
                  static_cast<unsigned long long>(run.mergedTriangles), run.ratio116);
    }
    if (o.render) {
      std::printf("  selection on a second thread would save at most %.1f %% of a frame (min(select, submit + finish) / frame, worst case)\n",
                  100.0 * pipelineGain);
    }
    std::printf("  goals: select <= 0.5 ms (max %.3f), >= 20x fewer triangles at 1/16 (min %.1fx), frame ratio at end 1/16 >= 18.9 (%.1fx), "
                "PSNR >= 35 dB at r = 1 px (min %.1f), build <= 300 s at scale 1\n",
                worstSelect, worstRatio116, endRatio, worstPsnr);
  }
  return 0;
}

}  // namespace ig
