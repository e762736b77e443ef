#include "ig/bench_forest.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <time.h>

#include "ig/stats.h"
#include "lod/forest.h"
#include "lod/forest_fins.h"
#include "lod/forest_kdtree.h"

namespace ig {
namespace {

using BenchClock = std::chrono::steady_clock;

constexpr double kPostSpacing_m = 32.0;

// CPU time of this thread: unlike wall time it does not count time the thread was preempted
// (on a shared machine a preemption costs a whole scheduler tick, ~4 ms).
double threadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}
constexpr size_t kInstanceCapacity = 1 << 18;

// A low flight over the forest: a wide loop at ~60 m above the ground, turning, slightly nose-down.
lod::Camera pathCamera(int i, int frames, double extent_m, const lod::TerrainGrid& terrain) {
  lod::Camera cam;
  cam.fovY_deg = 45.0;
  cam.aspect = 16.0 / 9.0;
  cam.near_m = 0.5;
  cam.far_m = 20000.0;
  const double s = static_cast<double>(i) / std::max(frames, 1);
  const double a = 2.0 * 3.14159265358979323846 * s;
  const double r = 0.3 * extent_m;
  cam.eye_m = {0.5 * extent_m + r * std::cos(a), 0.5 * extent_m + r * std::sin(a), 0.0};
  cam.eye_m.z = terrain.heightAt(cam.eye_m.x, cam.eye_m.y) + 60.0 + 30.0 * std::sin(5.0 * a);
  cam.heading_deg = std::fmod(360.0 - a * 57.29577951308232 + 20.0 * std::sin(9.0 * a), 360.0);  // along the loop
  cam.pitch_deg = -8.0 + 4.0 * std::sin(7.0 * a);
  return cam;
}

struct Run {
  double p50 = 0, p99 = 0, max = 0;
  double cpuP99 = 0;
  double drawnP50 = 0;
  uint32_t droppedMax = 0;
  double testedP50 = 0;
};

Run flight(const lod::ForestKdTree& kd, const lod::TerrainGrid& terrain, const lod::NearFade& fade, int frames,
           double extent_m, std::vector<lod::ForestInstance>& inst, std::vector<lod::ForestInstance>& scratch,
           std::vector<lod::ForestModelRange>& models) {
  std::vector<double> ms, cpu, drawn, tested;
  ms.reserve(static_cast<size_t>(frames));
  Run r;
  for (int i = 0; i < frames; ++i) {
    const lod::Camera cam = pathCamera(i, frames, extent_m, terrain);
    lod::ForestSelectStats st;
    const double c0 = threadCpuMs();
    const auto t0 = BenchClock::now();
    const size_t n = kd.select(cam, fade, inst, scratch, models, &st);
    ms.push_back(std::chrono::duration<double, std::milli>(BenchClock::now() - t0).count());
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

}  // namespace

int runForestBench(const ForestBenchOptions& o) {
  if (o.posts < 2 || o.frames < 1) {
    std::fprintf(stderr, "igbench forest: posts = %d, frames = %d: need posts >= 2 and frames >= 1\n", o.posts, o.frames);
    return 2;
  }
  lod::TerrainGridDesc td;
  td.heights.seed = o.seed;
  td.heights.postsX = td.heights.postsY = o.posts;
  td.heights.postSpacing_m = kPostSpacing_m;
  td.heights.heightScale_m = 400.0;
  const lod::TerrainGrid terrain(td);
  const double extent_m = (o.posts - 1) * kPostSpacing_m;

  lod::ForestMapDesc md;
  md.seed = o.seed;
  md.width = md.height = o.posts - 1;
  md.cell_m = kPostSpacing_m;
  const lod::ForestMap map = lod::generateForestMap(md);
  lod::TreePlacementDesc pd;
  pd.seed = o.seed + 6;
  pd.spacing_m = o.treeSpacing_m;
  std::vector<lod::TreeInstance> trees;
  std::string err;
  const auto tPlace = BenchClock::now();
  if (!lod::placeTrees(map, terrain, pd, trees, err)) {
    std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
    return 2;
  }
  const double placeMs = std::chrono::duration<double, std::milli>(BenchClock::now() - tPlace).count();
  size_t glades = 0;
  for (uint32_t g : map.gr) glades += (g >> 24) == 0;

  lod::ForestKdParams kp;
  kp.leafSize_m = o.leafSize_m;
  kp.modelCount = pd.modelCount;
  lod::ForestKdTree kd;
  const auto tBuild = BenchClock::now();
  if (!kd.build(trees, kp, err)) {
    std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
    return 2;
  }
  const double buildMs = std::chrono::duration<double, std::milli>(BenchClock::now() - tBuild).count();
  size_t nonEmpty = 0;
  for (const lod::ForestKdLeaf& l : kd.leaves()) nonEmpty += l.count > 0;

  // Fins on the full-resolution terrain grid.
  std::vector<float> heights(static_cast<size_t>(o.posts) * static_cast<size_t>(o.posts));
  lod::generateHeightfield(td.heights, heights);
  std::vector<glm::dvec3> pos;
  std::vector<uint32_t> tri;
  lod::makeGridMesh(heights, o.posts, o.posts, kPostSpacing_m, td.offset_m, pos, tri);
  lod::FinParams fp;
  fp.criticalAngle_deg = o.criticalAngle_deg;
  lod::FinSet fins;
  if (!lod::buildFins(pos, tri, &map, fp, fins, err)) {
    std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
    return 2;
  }

  const lod::NearFade nearFade{o.nearFadeStart_m, o.nearFadeEnd_m};
  const lod::FarFade farFade{o.nearFadeStart_m, o.nearFadeEnd_m, 6000.0, 8000.0};
  if (!lod::validateForestFades(farFade, nearFade, err)) {
    std::fprintf(stderr, "igbench forest: %s\n", err.c_str());
    return 2;
  }
  std::vector<lod::ForestInstance> inst(kInstanceCapacity), scratch(kInstanceCapacity);
  std::vector<lod::ForestModelRange> models(static_cast<size_t>(kp.modelCount));
  flight(kd, terrain, nearFade, std::min(o.frames, 60), extent_m, inst, scratch, models);  // warm caches
  const Run main = flight(kd, terrain, nearFade, o.frames, extent_m, inst, scratch, models);

  std::vector<uint32_t> groupOut(fins.groups.size());
  std::vector<double> finsDrawn, groupsRejected, finMs;
  for (int i = 0; i < o.frames; ++i) {
    const lod::Camera cam = pathCamera(i, o.frames, extent_m, terrain);
    lod::FinSelectStats st;
    const auto t0 = BenchClock::now();
    lod::selectFinGroups(fins.groups, cam, farFade, o.finAlphaThreshold, groupOut, &st);
    finMs.push_back(std::chrono::duration<double, std::milli>(BenchClock::now() - t0).count());
    finsDrawn.push_back(static_cast<double>(st.finsDrawn));
    groupsRejected.push_back(st.groupsRejected);
  }

  struct SweepPoint {
    double nearEnd_m;
    Run run;
  };
  std::vector<SweepPoint> sweep;
  for (double nearEnd : {200.0, 300.0, 500.0, 800.0, 1200.0}) {
    const lod::NearFade f{0.6 * nearEnd, nearEnd};
    sweep.push_back({nearEnd, flight(kd, terrain, f, o.frames, extent_m, inst, scratch, models)});
  }

  const double area = extent_m * extent_m / 1e6;
  if (o.json) {
    std::printf("{\"trees\":%zu,\"area_km2\":%.3f,\"extent_m\":%.1f,\"glade_fraction\":%.3f,\"place_ms\":%.1f,"
                "\"build_ms\":%.1f,\"leaves\":%zu,\"leaves_nonempty\":%zu,\"kd_depth\":%d,\"frames\":%d,"
                "\"near_fade_start_m\":%.1f,\"near_fade_end_m\":%.1f,\"cull_ms_p50\":%.4f,\"cull_ms_p99\":%.4f,"
                "\"cull_ms_max\":%.4f,\"cull_cpu_ms_p99\":%.4f,\"trees_tested_p50\":%.0f,\"trees_drawn_p50\":%.0f,\"dropped_max\":%u,"
                "\"fin_edges_tested\":%llu,\"fin_edges_below_angle\":%llu,\"fins\":%zu,\"fin_groups\":%zu,"
                "\"fins_drawn_p50\":%.0f,\"fin_groups_rejected_p50\":%.0f,\"fin_select_ms_p99\":%.4f,"
                "\"rendering\":false,\"sweep\":[",
                trees.size(), area, extent_m, static_cast<double>(glades) / static_cast<double>(map.gr.size()),
                placeMs, buildMs, kd.leaves().size(), nonEmpty, kd.depth(), o.frames, o.nearFadeStart_m,
                o.nearFadeEnd_m, main.p50, main.p99, main.max, main.cpuP99, main.testedP50, main.drawnP50, main.droppedMax,
                static_cast<unsigned long long>(fins.edgesTested), static_cast<unsigned long long>(fins.edgesBelowAngle),
                fins.fins.size(), fins.groups.size(), percentile(finsDrawn, 50), percentile(groupsRejected, 50),
                percentile(finMs, 99));
    for (size_t i = 0; i < sweep.size(); ++i) {
      std::printf("%s{\"near_m\":%.0f,\"cull_ms_p50\":%.4f,\"cull_ms_p99\":%.4f,\"cull_cpu_ms_p99\":%.4f,\"trees_drawn_p50\":%.0f,\"dropped_max\":%u}",
                  i ? "," : "", sweep[i].nearEnd_m, sweep[i].run.p50, sweep[i].run.p99, sweep[i].run.cpuP99, sweep[i].run.drawnP50,
                  sweep[i].run.droppedMax);
    }
    std::printf("]}\n");
  } else {
    std::printf("forest: %zu trees over %.1f km2, %zu leaves (%zu non-empty), kd build %.0f ms\n", trees.size(), area,
                kd.leaves().size(), nonEmpty, buildMs);
    std::printf("near %.0f-%.0f m: cull+gather+sort p50 %.3f ms p99 %.3f ms (thread CPU p99 %.3f ms), trees drawn p50 %.0f\n",
                o.nearFadeStart_m, o.nearFadeEnd_m, main.p50, main.p99, main.cpuP99, main.drawnP50);
    std::printf("fins: %zu in %zu groups, drawn p50 %.0f after cone rejection\n", fins.fins.size(), fins.groups.size(),
                percentile(finsDrawn, 50));
    for (const SweepPoint& s : sweep) {
      std::printf("  near %5.0f m: cull p99 %.3f ms (CPU %.3f ms), trees drawn p50 %.0f\n", s.nearEnd_m, s.run.p99,
                  s.run.cpuP99, s.run.drawnP50);
    }
    std::printf("(no rendering yet: no frame time, PSNR or popping)\n");
  }
  return main.droppedMax > 0 ? 1 : 0;
}

}  // namespace ig
