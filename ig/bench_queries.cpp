#include "ig/bench_queries.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "ig/stats.h"
#include "lod/forest.h"
#include "lod/forest_kdtree.h"
#include "lod/forest_model.h"
#include "lod/forest_rays.h"
#include "lod/hdlod_rays.h"
#include "lod/hdlod_site.h"
#include "lod/heightfield.h"

namespace ig {
namespace {

using BenchClock = std::chrono::steady_clock;
double msSince(BenchClock::time_point t0) { return std::chrono::duration<double, std::milli>(BenchClock::now() - t0).count(); }

struct Kind {
  const char* name;
  std::vector<double> us;
  double workSum = 0.0;
  uint32_t workMax = 0;
  int hits = 0;
};

// Runs `n` queries: query(i, work) returns whether it hit and adds its work units.
Kind measure(const char* name, int n, const std::function<bool(int, uint32_t&)>& query) {
  Kind k{name, {}, 0.0, 0, 0};
  k.us.reserve(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    uint32_t work = 0;
    const auto t0 = BenchClock::now();
    const bool hit = query(i, work);
    k.us.push_back(msSince(t0) * 1000.0);
    k.hits += hit ? 1 : 0;
    k.workSum += work;
    k.workMax = std::max(k.workMax, work);
  }
  return k;
}

// A fractal height field: a few octaves of sines, 0 ... ~300 m.
float fractalHeight(int x, int y) {
  double h = 150.0;
  double amp = 80.0, f = 0.002;
  for (int o = 0; o < 6; ++o) {
    h += amp * std::sin(f * x * 2.0 + 1.3 * o) * std::cos(f * y * 2.0 + 0.7 * o);
    amp *= 0.5;
    f *= 2.1;
  }
  return static_cast<float>(h);
}

}  // namespace

int runQueriesBench(const QueriesBenchOptions& o) {
  if (o.queries < 1 || !(o.siteScale > 0.0 && o.siteScale <= 10.0)) {
    std::fprintf(stderr, "igbench queries: bad options (queries = %d, site scale = %g)\n", o.queries, o.siteScale);
    return 2;
  }
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Kind> kinds;

  // Terrain: 4097 x 4097 posts, 2 m apart, centred on the origin.
  const int posts = 4097;
  std::vector<float> heights(static_cast<size_t>(posts) * posts);
  for (int y = 0; y < posts; ++y)
    for (int x = 0; x < posts; ++x) heights[static_cast<size_t>(y) * posts + static_cast<size_t>(x)] = fractalHeight(x, y);
  const double half = 0.5 * (posts - 1) * 2.0;
  const lod::HeightGrid grid{heights, posts, posts, 2.0, {-half, -half, 0.0}};
  kinds.push_back(measure("terrain_hot", o.queries, [&](int, uint32_t& work) {
    lod::GroundSample g;
    work += 1;
    return lod::sampleGround(grid, (2.0 * u(rng) - 1.0) * half, (2.0 * u(rng) - 1.0) * half, g);
  }));
  kinds.push_back(measure("terrain_los", o.queries, [&](int, uint32_t& work) {
    // From 2 m above the ground, 2 km in a random direction and slope (-2 ... +1 deg).
    const double x = (2.0 * u(rng) - 1.0) * 0.8 * half, y = (2.0 * u(rng) - 1.0) * 0.8 * half, a = 6.2832 * u(rng);
    lod::GroundSample g;
    lod::sampleGround(grid, x, y, g);
    const glm::dvec3 from{x, y, g.height_m + 2.0};
    const double slope = (3.0 * u(rng) - 2.0) * 0.01745;
    const glm::dvec3 to = from + 2000.0 * glm::dvec3(std::cos(a), std::sin(a), std::tan(slope));
    lod::GroundHit hit;
    return lod::intersectGround(grid, from, to, hit, &work);
  }));

  // The construction site's objects.
  lod::hdlod::SiteParams sp;
  sp.scale = o.siteScale;
  std::string error;
  const lod::hdlod::Scene site = lod::hdlod::makeConstructionSite(sp, error);
  if (!error.empty()) {
    std::fprintf(stderr, "igbench queries: site: %s\n", error.c_str());
    return 1;
  }
  size_t siteTriangles = 0;
  for (const auto& ob : site.objects) siteTriangles += site.models[ob.model].triangleCount();
  auto t0 = BenchClock::now();
  const lod::hdlod::SceneRays objects(site);
  const double objectsIndex_ms = msSince(t0);
  glm::dvec3 lo(1e300), hi(-1e300);
  for (const auto& ob : site.objects) lo = glm::min(lo, ob.path[0].position_m), hi = glm::max(hi, ob.path[0].position_m);
  const auto sitePoint = [&] { return glm::dvec3(lo.x + u(rng) * (hi.x - lo.x), lo.y + u(rng) * (hi.y - lo.y), 0.0); };
  kinds.push_back(measure("objects_hot", o.queries, [&](int, uint32_t& work) {
    const glm::dvec3 p = sitePoint();
    lod::hdlod::RayHit hit;
    lod::RayWork w;
    const bool found = objects.intersect(p + glm::dvec3(0.0, 0.0, objects.top_m() + 1.0), p - glm::dvec3(0.0, 0.0, 10.0),
                                         site.duration_s * u(rng), hit, &w);
    work += w.nodes + w.triangles;
    return found;
  }));
  kinds.push_back(measure("objects_los", o.queries, [&](int, uint32_t& work) {
    const glm::dvec3 p = sitePoint() + glm::dvec3(0.0, 0.0, 1.8);
    const double a = 6.2832 * u(rng);
    lod::hdlod::RayHit hit;
    lod::RayWork w;
    const bool found = objects.intersect(p, p + 2000.0 * glm::dvec3(std::cos(a), std::sin(a), 0.0),
                                         site.duration_s * u(rng), hit, &w);
    work += w.nodes + w.triangles;
    return found;
  }));

  // The default generated forest on flat ground.
  const lod::ForestMap map = lod::generateForestMap(lod::ForestMapDesc{});
  std::vector<float> flat(257 * 257, 0.0f);
  const lod::ForestHeightField ground{flat, 257, 257, 30.0, glm::dvec3(0.0)};
  std::vector<lod::TreeInstance> trees;
  if (!lod::placeTrees(map, ground, lod::TreePlacementDesc{}, trees, error)) {
    std::fprintf(stderr, "igbench queries: forest: %s\n", error.c_str());
    return 1;
  }
  const std::vector<lod::TreeMesh> models{lod::makeProceduralTree(lod::ProceduralTree::Pine, 18.0),
                                          lod::makeProceduralTree(lod::ProceduralTree::Cypress, 12.0)};
  lod::ForestKdParams kp;
  kp.modelCount = 2;
  for (const lod::TreeMesh& m : models) {
    kp.treeHeight_m = std::max(kp.treeHeight_m, 1.1 * static_cast<double>(m.height_m));
    kp.crownRadius_m = std::max(kp.crownRadius_m, 1.1 * static_cast<double>(m.radius_m));
  }
  lod::ForestKdTree kd;
  if (!kd.build(trees, kp, error)) {
    std::fprintf(stderr, "igbench queries: forest: %s\n", error.c_str());
    return 1;
  }
  t0 = BenchClock::now();
  const lod::ForestRays forest(kd, models, 1.0f);
  const double forestIndex_ms = msSince(t0);
  const double forestIndex_mb =
      (4.0 * static_cast<double>(kd.trees().size()) + 4.0 * static_cast<double>(forest.entries()) +
       4.0 * static_cast<double>(forest.cellsX()) * forest.cellsY()) / 1e6;
  const double fx = map.extentEast_m(), fy = map.extentNorth_m();
  kinds.push_back(measure("forest_los", o.queries, [&](int i, uint32_t& work) {
    // Level 2 km rays at 1.8, 10 and 17 m above the ground, in turn (below the tree tops).
    const double z = i % 3 == 0 ? 1.8 : i % 3 == 1 ? 10.0 : 17.0, a = 6.2832 * u(rng);
    const glm::dvec3 p{0.1 * fx + 0.8 * fx * u(rng), 0.1 * fy + 0.8 * fy * u(rng), z};
    lod::TreeHit hit;
    lod::RayWork w;
    const bool found = forest.intersect(p, p + 2000.0 * glm::dvec3(std::cos(a), std::sin(a), 0.0), hit, &w);
    work += w.nodes + w.triangles;
    return found;
  }));

  if (o.json) {
    std::printf("{\"suite\":\"queries\",\"queries\":%d,\"terrain_posts\":%d,\"objects\":%zu,\"object_triangles\":%zu,"
                "\"objects_index_ms\":%.3f,\"trees\":%zu,\"forest_index_ms\":%.3f,\"forest_index_mb\":%.2f",
                o.queries, posts * posts, site.objects.size(), siteTriangles, objectsIndex_ms, kd.trees().size(),
                forestIndex_ms, forestIndex_mb);
  } else {
    std::printf("igbench queries: %d queries per kind; terrain %d x %d posts, %zu objects (%zu triangles, index %.1f ms), "
                "%zu trees (index %.0f ms, %.1f MB)\n",
                o.queries, posts, posts, site.objects.size(), siteTriangles, objectsIndex_ms, kd.trees().size(),
                forestIndex_ms, forestIndex_mb);
  }
  for (const Kind& k : kinds) {
    double sum = 0.0;
    for (double v : k.us) sum += v;
    const double mean = sum / static_cast<double>(k.us.size()), workMean = k.workSum / static_cast<double>(k.us.size());
    const double hitPct = 100.0 * k.hits / static_cast<double>(k.us.size());
    const double nsPerWork = workMean > 0.0 ? 1000.0 * mean / workMean : 0.0;
    if (o.json) {
      std::printf(",\"%s\":{\"us_p50\":%.3f,\"us_p99\":%.3f,\"us_mean\":%.3f,\"work_mean\":%.1f,\"work_max\":%u,"
                  "\"hit_pct\":%.1f,\"ns_per_work\":%.1f}",
                  k.name, percentile(k.us, 50), percentile(k.us, 99), mean, workMean, k.workMax, hitPct, nsPerWork);
    } else {
      std::printf("  %-12s us p50 %8.2f p99 %8.2f mean %8.2f | work mean %8.1f max %6u | hits %5.1f %% | %.1f ns a unit\n",
                  k.name, percentile(k.us, 50), percentile(k.us, 99), mean, workMean, k.workMax, hitPct, nsPerWork);
    }
  }
  if (o.json) std::printf("}\n");
  return 0;
}

}  // namespace ig
