#include "ig/bench_hdlod.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "lod/hdlod_build.h"
#include "lod/hdlod_select.h"
#include "lod/hdlod_site.h"

namespace ig {
namespace {

using BenchClock = std::chrono::steady_clock;
double secondsSince(BenchClock::time_point t0) { return std::chrono::duration<double>(BenchClock::now() - t0).count(); }

struct Result {
  uint64_t triangles = 0;
  uint32_t draws = 0;
  double selectMs = 0.0;
};

// Median time of `repeats` selections (the output buffer is reserved once, outside the timing).
template <typename Select>
Result measure(int repeats, Select&& select) {
  std::vector<double> ms;
  Result r;
  for (int i = 0; i < std::max(1, repeats); ++i) {
    const auto t0 = BenchClock::now();
    const lod::hdlod::SelectStats st = select();
    ms.push_back(secondsSince(t0) * 1e3);
    r.triangles = st.triangles;
    r.draws = st.draws;
  }
  std::nth_element(ms.begin(), ms.begin() + static_cast<long>(ms.size() / 2), ms.end());
  r.selectMs = ms[ms.size() / 2];
  return r;
}

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

}  // namespace

int runHdlodBench(const HdlodBenchOptions& o) {
  namespace hd = lod::hdlod;
  if (!(o.scale > 0.0) || o.width_px < 16 || o.height_px < 16 || !(o.tolerance_px >= 0.0) || !(o.fovY_deg > 0.0 && o.fovY_deg < 180.0)) {
    std::fprintf(stderr, "igbench hdlod: bad options (scale %g, %dx%d px, r %g px, fov %g deg)\n", o.scale, o.width_px, o.height_px,
                 o.tolerance_px, o.fovY_deg);
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
  const auto tBuild = BenchClock::now();
  const hd::HdlodTree tree = hd::buildHdlod(scene, config);
  const double buildS = secondsSince(tBuild);
  uint64_t triangles = 0;
  for (const hd::Object& obj : scene.objects) triangles += scene.models[obj.model].triangleCount();
  const hd::Cluster& root = tree.clusters[tree.root];

  std::vector<hd::Draw> draws(hd::drawBound(tree));
  const char* timeNames[] = {"start", "1/3", "2/3", "end"};
  const double timeFrac[] = {0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0};
  const char* screenNames[] = {"1/1", "1/4", "1/16"};
  const double screenLinear[] = {1.0, 0.5, 0.25};
  struct Case {
    int time, screen;
    Result hdlod, full;
  };
  std::vector<Case> cases;
  const double r = hd::toleranceFromPixels(o.tolerance_px, o.fovY_deg, o.height_px);
  for (int ti = 0; ti < 4; ++ti) {
    for (int si = 0; si < 3; ++si) {
      hd::SelectView v;
      v.camera = cameraFor(root.box, screenLinear[si], o);
      v.time_s = timeFrac[ti] * scene.duration_s;
      v.tolerance_rad = r;
      Case c{ti, si, {}, {}};
      c.hdlod = measure(o.repeats, [&] {
        hd::SelectStats st;
        hd::selectHdlod(tree, scene, v, draws, &st);
        return st;
      });
      c.full = measure(o.repeats, [&] {
        hd::SelectStats st;
        hd::selectAll(tree, scene, v, draws, &st);
        return st;
      });
      cases.push_back(c);
    }
  }
  const double sweepPx[] = {0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0};
  std::vector<Result> sweep;
  for (double px : sweepPx) {
    hd::SelectView v;
    v.camera = cameraFor(root.box, 1.0, o);
    v.time_s = scene.duration_s / 3.0;
    v.tolerance_rad = hd::toleranceFromPixels(px, o.fovY_deg, o.height_px);
    sweep.push_back(measure(o.repeats, [&] {
      hd::SelectStats st;
      hd::selectHdlod(tree, scene, v, draws, &st);
      return st;
    }));
  }
  double worstSelect = 0.0, worstRatio116 = 1e300;
  for (const Case& c : cases) {
    worstSelect = std::max(worstSelect, c.hdlod.selectMs);
    if (c.screen == 2 && c.hdlod.triangles > 0) {
      worstRatio116 = std::min(worstRatio116, static_cast<double>(c.full.triangles) / static_cast<double>(c.hdlod.triangles));
    }
  }

  // Per simplifier: build time, measured error of the merged clusters' own simplification (D,
  // the sampled Hausdorff distance without the children's eps: mean and max), and the smallest
  // full / HDLOD triangle ratio at 1/16 of the screen over the four times.
  struct SimplifierRun {
    hd::Simplifier simplifier;
    double seconds = 0.0, meanM = 0.0, maxM = 0.0, ratio116 = 0.0;
    uint64_t mergedTriangles = 0;
    uint32_t sloppy = 0;
  };
  std::vector<SimplifierRun> runs;
  for (hd::Simplifier s : {hd::Simplifier::Meshoptimizer, hd::Simplifier::OpenMesh, hd::Simplifier::Clustering}) {
    if (!o.compareSimplifiers) break;
    hd::BuildConfig sc = config;
    sc.simplifier = s;
    const auto t0 = BenchClock::now();
    const hd::HdlodTree other = hd::buildHdlod(scene, sc);
    SimplifierRun run{s};
    run.seconds = secondsSince(t0);
    const auto& os = other.stats;
    run.meanM = os.mergedClusters ? os.simplifyErrorSum_m / os.mergedClusters : 0.0;
    run.maxM = os.simplifyErrorMax_m;
    run.mergedTriangles = os.mergedTriangles;
    run.sloppy = os.sloppyClusters;
    run.ratio116 = 1e300;
    std::vector<hd::Draw> otherDraws(hd::drawBound(other));
    for (int ti = 0; ti < 4; ++ti) {
      hd::SelectView v;
      v.camera = cameraFor(root.box, 0.25, o);
      v.time_s = timeFrac[ti] * scene.duration_s;
      v.tolerance_rad = r;
      hd::SelectStats a, b;
      hd::selectHdlod(other, scene, v, otherDraws, &a);
      hd::selectAll(other, scene, v, otherDraws, &b);
      if (a.triangles > 0) run.ratio116 = std::min(run.ratio116, static_cast<double>(b.triangles) / static_cast<double>(a.triangles));
    }
    runs.push_back(run);
  }

  const auto& st = tree.stats;
  if (o.json) {
    std::printf("{\"suite\":\"hdlod\",\"scale\":%g,\"seed\":%u,\"objects\":%zu,\"static\":%u,\"pseudo_dynamic\":%u,\"dynamic\":%u,"
                "\"empty\":%u,\"triangles\":%llu,\"scene_s\":%.3f,\"build_s\":%.3f,\"clusters\":%zu,\"merged_clusters\":%u,"
                "\"levels\":%u,\"merged_triangles\":%llu,\"hausdorff_samples\":%llu,\"width\":%d,\"height\":%d,\"r_px\":%g,"
                "\"cases\":[",
                o.scale, o.seed, scene.objects.size(), st.staticObjects, st.pseudoDynamicObjects, st.dynamicObjects, st.emptyObjects,
                static_cast<unsigned long long>(triangles), sceneS, buildS, tree.clusters.size(), st.mergedClusters, st.levels,
                static_cast<unsigned long long>(st.mergedTriangles), static_cast<unsigned long long>(st.hausdorffSamples), o.width_px,
                o.height_px, o.tolerance_px);
    for (size_t i = 0; i < cases.size(); ++i) {
      const Case& c = cases[i];
      std::printf("%s{\"time\":\"%s\",\"screen\":\"%s\",\"hdlod\":{\"triangles\":%llu,\"draws\":%u,\"select_ms\":%.4f},"
                  "\"full\":{\"triangles\":%llu,\"draws\":%u,\"select_ms\":%.4f}}",
                  i ? "," : "", timeNames[c.time], screenNames[c.screen], static_cast<unsigned long long>(c.hdlod.triangles),
                  c.hdlod.draws, c.hdlod.selectMs, static_cast<unsigned long long>(c.full.triangles), c.full.draws, c.full.selectMs);
    }
    std::printf("],\"sweep_time\":\"1/3\",\"sweep_screen\":\"1/1\",\"sweep\":[");
    for (size_t i = 0; i < sweep.size(); ++i) {
      std::printf("%s{\"r_px\":%g,\"triangles\":%llu,\"draws\":%u,\"select_ms\":%.4f}", i ? "," : "", sweepPx[i],
                  static_cast<unsigned long long>(sweep[i].triangles), sweep[i].draws, sweep[i].selectMs);
    }
    std::printf("],\"simplifier\":\"%s\",\"sloppy_clusters\":%u,\"simplifiers\":[", hd::simplifierName(config.simplifier),
                st.sloppyClusters);
    for (size_t i = 0; i < runs.size(); ++i) {
      const SimplifierRun& run = runs[i];
      std::printf("%s{\"name\":\"%s\",\"seconds\":%.3f,\"hausdorff_m\":%.4f,\"hausdorff_max_m\":%.4f,\"merged_triangles\":%llu,"
                  "\"sloppy_clusters\":%u,\"triangle_ratio_1_16_min\":%.2f}",
                  i ? "," : "", hd::simplifierName(run.simplifier), run.seconds, run.meanM, run.maxM,
                  static_cast<unsigned long long>(run.mergedTriangles), run.sloppy, run.ratio116);
    }
    std::printf("],\"select_ms_max\":%.4f,\"triangle_ratio_1_16_min\":%.2f}\n", worstSelect, worstRatio116);
  } else {
    std::printf("hdlod suite: site scale %g (seed %u): %zu objects (%u static, %u pseudo-dynamic, %u dynamic, %u empty), %llu triangles\n",
                o.scale, o.seed, scene.objects.size(), st.staticObjects, st.pseudoDynamicObjects, st.dynamicObjects, st.emptyObjects,
                static_cast<unsigned long long>(triangles));
    std::printf("  generated in %.2f s, tree built in %.2f s (%s): %zu clusters (%u merged, %u levels, %llu merged triangles)\n", sceneS,
                buildS, hd::simplifierName(config.simplifier), tree.clusters.size(), st.mergedClusters, st.levels,
                static_cast<unsigned long long>(st.mergedTriangles));
    std::printf("  r = %g px, %dx%d: time screen | HDLOD triangles draws select ms | full triangles draws select ms | ratio\n",
                o.tolerance_px, o.width_px, o.height_px);
    for (const Case& c : cases) {
      std::printf("    %-5s %-4s | %9llu %6u %8.3f | %9llu %6u %8.3f | %6.1fx\n", timeNames[c.time], screenNames[c.screen],
                  static_cast<unsigned long long>(c.hdlod.triangles), c.hdlod.draws, c.hdlod.selectMs,
                  static_cast<unsigned long long>(c.full.triangles), c.full.draws, c.full.selectMs,
                  c.hdlod.triangles ? static_cast<double>(c.full.triangles) / static_cast<double>(c.hdlod.triangles) : 0.0);
    }
    std::printf("  sweep at 1/3, scene on the whole screen: r px, triangles, draws, select ms\n");
    for (size_t i = 0; i < sweep.size(); ++i) {
      std::printf("    %5.2f %9llu %6u %8.3f\n", sweepPx[i], static_cast<unsigned long long>(sweep[i].triangles), sweep[i].draws,
                  sweep[i].selectMs);
    }
    for (const SimplifierRun& run : runs) {
      std::printf("  simplifier %-13s: built in %6.2f s, measured error mean %.3f m max %.3f m, %llu merged triangles, 1/16 ratio %.1fx\n",
                  hd::simplifierName(run.simplifier), run.seconds, run.meanM, run.maxM,
                  static_cast<unsigned long long>(run.mergedTriangles), run.ratio116);
    }
    std::printf("  goals: select <= 0.5 ms (max %.3f), >= 20x fewer triangles at 1/16 (min %.1fx), build <= 300 s at scale 1\n",
                worstSelect, worstRatio116);
  }
  return 0;
}

}  // namespace ig
