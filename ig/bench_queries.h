// igbench queries: what the host's terrain queries cost (CIGI HAT/HOT and line of sight,
// docs/cigi.md), per kind of surface, on the scenes igd answers them from: a 4097 x 4097-post
// terrain grid (fractal, 2 m posts), the synthetic construction site's objects
// (lod/hdlod_rays.h, site scale --site-scale) and the default generated forest
// (lod/forest_rays.h: 7.7 km, 6 m spacing, procedural pine and cypress). Per query kind: the
// microseconds per query (p50, p99, mean; each query timed alone with the monotonic clock),
// the work units the per-frame query work budget counts (grid cells, hierarchy nodes, tree boxes,
// triangles; mean and max), the share of queries that hit, and the ns per work unit; per index
// its build time. Queries are random, seeded, the same every run.
#pragma once

#include <cstdint>

namespace ig {

struct QueriesBenchOptions {
  int queries = 4000;        // per kind
  double siteScale = 0.25;   // construction site scale (igd's [hdlod] default)
  uint32_t seed = 1;
  bool json = false;
};

// JSON fields: suite, queries, and per kind (terrain_hot, terrain_los, objects_hot, objects_los,
// forest_los) an object {us_p50, us_p99, us_mean, work_mean, work_max, hit_pct, ns_per_work};
// terrain_posts, objects, object_triangles, objects_index_ms, trees, forest_index_ms,
// forest_index_mb. Returns the exit status.
int runQueriesBench(const QueriesBenchOptions& options);

}  // namespace ig
