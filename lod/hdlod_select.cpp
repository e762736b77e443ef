// HDLOD selection: paper 000, appendix 1 (see hdlod_select.h for the rule).
#include "lod/hdlod_select.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <new>

#include <sys/mman.h>
#include <limits>
#include <vector>

namespace ig::lod::hdlod {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

bool finite3(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

bool validView(const SelectView& v) {
  const Camera& c = v.camera;
  return finite3(c.eye_m) && std::isfinite(c.heading_deg) && std::isfinite(c.pitch_deg) && std::isfinite(c.roll_deg) &&
         c.fovY_deg > 0.0 && c.fovY_deg < 180.0 && c.aspect > 0.0 && std::isfinite(c.aspect) && c.near_m > 0.0 &&
         c.far_m > c.near_m && std::isfinite(c.far_m) && validWindowShift(c) && std::isfinite(v.time_s) && !std::isnan(v.tolerance_rad);
}

// Step functions longer than kScanSteps are searched through a table of `bucketsFor(n)` + 1
// step indices, the answer at the start of each of as many equal spans of [0, T] (and n - 1 at
// the end), held in the slots just before the steps: a lookup reads the table's line and the
// steps of one span (~4) instead of the log2(n) lines of a binary search.
constexpr uint32_t kScanSteps = 16;
uint32_t bucketsFor(uint32_t steps) { return std::bit_ceil(std::max(8u, steps / 4)); }
uint32_t tableSlots(uint32_t buckets) { return static_cast<uint32_t>(((buckets + 1) * sizeof(uint32_t) + sizeof(glm::dvec2) - 1) / sizeof(glm::dvec2)); }
uint32_t bucketOf(double t, double duration_s, uint32_t buckets) {
  const double x = t * (buckets / duration_s);
  return x >= buckets ? buckets - 1 : x > 0.0 ? static_cast<uint32_t>(x) : 0u;
}

double maxAbs(const glm::dvec3& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

double distance2ToBox(const Aabb& box, const glm::dvec3& p) {
  const glm::dvec3 d = glm::max(glm::max(box.min - p, p - box.max), glm::dvec3(0.0));
  return d.x * d.x + d.y * d.y + d.z * d.z;
}

// The plane test of Frustum::intersects() with its "inside" outcome: -1 when the eye-relative
// box is outside plane q, 1 when wholly inside it, 0 when it straddles.
int planeSide(const glm::dvec4& q, const glm::dvec3& lo, const glm::dvec3& hi) {
  const double far = q.x * (q.x >= 0 ? hi.x : lo.x) + q.y * (q.y >= 0 ? hi.y : lo.y) + q.z * (q.z >= 0 ? hi.z : lo.z) + q.w;
  if (far < 0.0) return -1;
  const double near = q.x * (q.x >= 0 ? lo.x : hi.x) + q.y * (q.y >= 0 ? lo.y : hi.y) + q.z * (q.z >= 0 ? lo.z : hi.z) + q.w;
  return near >= 0.0 ? 1 : 0;
}

// Frustum planes with the plane-mask test: a box inside a plane's half-space passes the bit
// down cleared, so its descendants (whose boxes lie inside it) skip that plane. The outcome of
// each test is that of Frustum::intersects() on b_c.
//
// The test runs on the record's float box, which holds b_c with every side at least
// selectWidenMin_m and at most selectWidenMax_m further out. Against plane q that moves the far
// corner out and the near corner in by |q|_1 x widen, so: the float box outside (far < 0) means
// b_c is outside, the float box inside (near >= 0) means b_c is inside, and far >= sure and
// near < -sure (sure = |q|_1 x selectWidenMax_m + rounding) means b_c straddles. Only a box
// closer than that to a plane reads b_c from the cluster record. The rounding of both
// computations (double, eye-relative) is bounded by `tol`; where the widening does not exceed
// it by far (coordinates ~1e9 m), every test is exact.
struct Planes {
  glm::dvec4 p[6];
  double sure[6];
  bool fast = false;

  void init(const Frustum& fr, const HdlodTree& tree, double magnitude) {
    fast = tree.selectWidenMin_m > 0.0 && std::isfinite(tree.selectWidenMax_m);
    for (int i = 0; i < 6; ++i) {
      const glm::dvec4 q = fr.planes[static_cast<size_t>(i)];
      p[i] = q;
      const double n1 = std::abs(q.x) + std::abs(q.y) + std::abs(q.z);
      const double tol = 1e-13 * (n1 * magnitude + std::abs(q.w));
      sure[i] = n1 * tree.selectWidenMax_m + 2.0 * tol;
      fast = fast && std::isfinite(sure[i]) && tree.selectWidenMin_m * n1 > 4.0 * tol;
    }
  }
};

struct Traversal {
  const HdlodTree& tree;
  const Scene& scene;
  const SelectRecord* records;
  const glm::dvec2* steps;
  Planes planes;
  glm::dvec3 eye, eyeRel;  // eyeRel: relative to tree.selectOrigin_m
  double t, r, r2;
  double tolD;      // bound on the rounding of an eye-to-box distance (either computation)
  bool all;         // selectAll(): draw every present leaf in the frustum
  std::span<Draw> out;
  std::span<glm::dmat4> moving;
  SelectStats stats{};
  size_t written = 0, movingWritten = 0;

  // f_c(t), t already clamped: the step functions are short (leaves: at most a few steps).
  double presence(const SelectRecord& h) const {
    if (h.flags & SelectRecord::kAlwaysPresent) return 1.0;
    if (h.flags & SelectRecord::kInlineSteps) {
      // The scan below on at most 3 increasing times, the missing ones +inf.
      const int i = (h.u.leafStepTimes[0] <= t) + (h.u.leafStepTimes[1] <= t);
      return (h.flags >> (2 + i)) & 1u ? 1.0 : 0.0;
    }
    if (h.stepCount == 0) return 0.0;
    const glm::dvec2* s = steps + h.stepBegin;
    const uint32_t n = h.stepCount;
    uint32_t i = 0;
    if (n <= kScanSteps) {
      while (i + 1 < n && s[i + 1].x <= t) ++i;
      return s[i].y;
    }
    const auto later = [](double v, const glm::dvec2& e) { return v < e.x; };
    const uint32_t buckets = bucketsFor(n), b = bucketOf(t, tree.duration_s, buckets);
    const char* table = reinterpret_cast<const char*>(s - tableSlots(buckets));
    uint32_t lo = 0, hi = 0;
    std::memcpy(&lo, table + sizeof(uint32_t) * b, sizeof lo);
    std::memcpy(&hi, table + sizeof(uint32_t) * (b + 1), sizeof hi);
    i = static_cast<uint32_t>(std::upper_bound(s + lo + 1, s + hi + 1, t, later) - s) - 1;
    if (!(s[i].x <= t && (i + 1 == n || t < s[i + 1].x))) {  // t rounded into a neighbouring span
      i = static_cast<uint32_t>(std::upper_bound(s + 1, s + n, t, later) - s) - 1;
    }
    return s[i].y;
  }

  // Plane-masked frustum test of an exact, world box.
  bool inFrustumExact(const Aabb& box, uint32_t& mask) const {
    const glm::dvec3 lo = box.min - eye, hi = box.max - eye;
    for (uint32_t i = 0; i < 6 && mask; ++i) {
      if (!(mask & (1u << i))) continue;
      const int side = planeSide(planes.p[i], lo, hi);
      if (side < 0) return false;
      if (side > 0) mask &= ~(1u << i);
    }
    return true;
  }

  // b_c of cluster `id` (record h) against the planes still in `mask` (see Planes).
  bool inFrustum(const SelectRecord& h, uint32_t id, uint32_t& mask) const {
    if (mask == 0) return true;
    if (!planes.fast) return inFrustumExact(tree.clusters[id].box, mask);
    const glm::dvec3 lo{double(h.lo[0]) - eyeRel.x, double(h.lo[1]) - eyeRel.y, double(h.lo[2]) - eyeRel.z};
    const glm::dvec3 hi{double(h.hi[0]) - eyeRel.x, double(h.hi[1]) - eyeRel.y, double(h.hi[2]) - eyeRel.z};
    for (uint32_t i = 0; i < 6; ++i) {
      if (!(mask & (1u << i))) continue;
      const glm::dvec4& q = planes.p[i];
      const double far = q.x * (q.x >= 0 ? hi.x : lo.x) + q.y * (q.y >= 0 ? hi.y : lo.y) + q.z * (q.z >= 0 ? hi.z : lo.z) + q.w;
      if (far < 0.0) return false;
      const double near = q.x * (q.x >= 0 ? lo.x : hi.x) + q.y * (q.y >= 0 ? lo.y : hi.y) + q.z * (q.z >= 0 ? lo.z : hi.z) + q.w;
      if (near >= 0.0) {
        mask &= ~(1u << i);
      } else if (!(far >= planes.sure[i] && near < -planes.sure[i])) {
        const Aabb& b = tree.clusters[id].box;
        const int side = planeSide(q, b.min - eye, b.max - eye);
        if (side < 0) return false;
        if (side > 0) mask &= ~(1u << i);
      }
    }
    return true;
  }

  // The squared eye-to-b_c distance as distance2ToBox(b_c, eye) gives it, for comparisons
  // x < r2 * d2: bounded from the record's float box (lo2 <= d2 <= hi2) when first needed,
  // read from the cluster record only when a comparison falls between the bounds.
  struct EyeDistance {
    const SelectRecord* record = nullptr;  // null once the bounds are set
    uint32_t id = 0;
    bool known = false;  // exact2 holds d2
    double lo2 = 0.0, hi2 = 0.0, exact2 = 0.0;
  };

  static EyeDistance exactDistance(double d2) {
    EyeDistance d;
    d.lo2 = d.hi2 = d.exact2 = d2;
    d.known = true;
    return d;
  }

  // x < r2 * distance2ToBox(b_c, eye), decided as that expression decides it.
  bool closerThan(double x, EyeDistance& d) const {
    if (!d.known) {
      if (d.record) {
        // df = |v| is the distance to the float box, which holds b_c: d >= df - rounding and
        // d <= df + sqrt(3) x widening + rounding. |v|_1 >= df keeps the bounds free of sqrt.
        const SelectRecord& h = *d.record;
        const glm::dvec3 lo{double(h.lo[0]), double(h.lo[1]), double(h.lo[2])}, hi{double(h.hi[0]), double(h.hi[1]), double(h.hi[2])};
        const glm::dvec3 v = glm::max(glm::max(lo - eyeRel, eyeRel - hi), glm::dvec3(0.0));
        const double df2 = v.x * v.x + v.y * v.y + v.z * v.z, l1 = v.x + v.y + v.z;
        const double w = 1.7320508075688772 * tree.selectWidenMax_m + 2.0 * tolD;
        d.lo2 = df2 - 4.0 * tolD * l1;
        d.hi2 = df2 + 2.0 * w * l1 + w * w;
        d.record = nullptr;
      }
      if (x < r2 * d.lo2 * (1.0 - 1e-12)) return true;
      if (x >= r2 * d.hi2 * (1.0 + 1e-12)) return false;
      d.exact2 = distance2ToBox(tree.clusters[d.id].box, eye);
      d.known = true;
    }
    return x < r2 * d.exact2;
  }

  void emit(uint32_t id, uint32_t lod, const glm::dmat4* m, uint32_t triangles) {
    if (written < out.size() && m) {
      out[written++] = Draw{id, lod, m};
    } else {
      stats.overflow = true;
    }
    ++stats.draws;
    stats.triangles += triangles;
  }

  // A dynamic object's matrix at t, kept in `moving`; null when that is full.
  const glm::dmat4* keepMoving(const glm::dmat4& m) {
    if (movingWritten >= moving.size()) return nullptr;
    moving[movingWritten] = m;
    return &moving[movingWritten++];
  }

  // A leaf: the coarsest version of its model whose eps < r * distance (0 = the model itself).
  void emitLeaf(uint32_t id, uint32_t model, uint32_t triangles, EyeDistance distance, const glm::dmat4* m) {
    uint32_t lod = 0;
    if (!all && r > 0.0) {
      const auto lods = tree.lodsOf(model);
      for (size_t k = 0; k < lods.size(); ++k) {
        if (!closerThan(lods[k].eps_m * lods[k].eps_m, distance)) break;
        lod = static_cast<uint32_t>(k + 1);
        triangles = lods[k].triangles;
      }
    }
    emit(id, lod, m, triangles);
  }

  // Cluster `id`, whose record is records[slot].
  void visit(uint32_t slot, uint32_t id, uint32_t mask) {
    const SelectRecord& h = records[slot];
    ++stats.visited;
    const double f = presence(h);
    if (f == 0.0) {
      ++stats.absent;
      return;
    }
    if (h.kind == ClusterKind::Dynamic) {
      // The swept box first (it holds the object at every time), then the box where it is now.
      const Cluster& c = tree.clusters[id];
      if (!inFrustumExact(c.box, mask)) {
        ++stats.culled;
        return;
      }
      const Object& o = scene.objects[c.object];
      const glm::dmat4 m = objectMatrix(o, t, tree.duration_s);
      const Aabb box = transformBox(scene.models[o.model].box, m);
      if (!inFrustumExact(box, mask)) {
        ++stats.culled;
        return;
      }
      emitLeaf(id, c.mesh, c.triangles, exactDistance(distance2ToBox(box, eye)), keepMoving(m));
      return;
    }
    if (!inFrustum(h, id, mask)) {
      ++stats.culled;
      return;
    }
    if (h.kind == ClusterKind::Object) {
      emitLeaf(id, h.first, h.triangles, EyeDistance{&h, id}, &tree.leafMatrix[id]);
      return;
    }
    if (h.kind == ClusterKind::Merged && !all) {
      // delta < r * distance, squared (both sides >= 0; distance 0 is never good enough).
      const double delta = h.u.merged.eps_m + h.u.merged.size_m * (1.0 - std::abs(2.0 * f - 1.0));
      EyeDistance d{&h, id};
      if (closerThan(delta * delta, d)) {
        if (f >= 0.5) {
          emit(id, 0, &tree.leafMatrix[id], h.triangles);
        } else {
          ++stats.halfSkipped;
        }
        return;
      }
    }
    const uint32_t end = h.first + h.count;
    // The children's records (adjacent, a cache line each) are requested together before the
    // first child is visited, and each sibling's steps while the one before it is visited: with
    // cold caches (after a rendered frame) a skipped subtree makes the next sibling a jump the
    // hardware prefetcher cannot guess.
    for (uint32_t k = h.first; k < end; ++k) __builtin_prefetch(records + k);
    // The children's steps, from the parent: not one record latency later.
    if (h.childSteps < tree.selectSteps.size()) {
      const char* childSteps = reinterpret_cast<const char*>(steps + h.childSteps);
      for (int line = 0; line < 4; ++line) __builtin_prefetch(childSteps + 64 * line);
    }
    for (uint32_t k = h.first; k < end; ++k) {
      if (k + 1 < end && !(records[k + 1].flags & (SelectRecord::kAlwaysPresent | SelectRecord::kInlineSteps)))
        __builtin_prefetch(steps + records[k + 1].stepBegin);
      visit(k, tree.children[k], mask);
    }
  }
};

size_t run(const HdlodTree& tree, const Scene& scene, const SelectView& view, std::span<Draw> out, std::span<glm::dmat4> moving,
           SelectStats* stats, bool all) {
  const bool prepared = tree.selectRecords.size() == tree.children.size() + 1;
  if (!validView(view) || tree.root >= tree.clusters.size() || !prepared) {
    if (stats) {
      *stats = SelectStats{};
      stats->rejected = !validView(view);
    }
    return 0;
  }
  const Frustum fr = makeFrustum(view.camera);
  const Aabb& rootBox = tree.clusters[tree.root].box;
  const double magnitude = maxAbs(view.camera.eye_m) + maxAbs(tree.selectOrigin_m) + glm::length(rootBox.max - rootBox.min) + 1.0;
  const double r = view.tolerance_rad > 0.0 ? view.tolerance_rad : 0.0;
  Traversal tr{tree,
               scene,
               tree.selectRecords.data(),
               tree.selectSteps.data(),
               Planes{},
               view.camera.eye_m,
               view.camera.eye_m - tree.selectOrigin_m,
               clampTime(view.time_s, tree.duration_s),
               r,
               r * r,
               1e-13 * magnitude,
               all,
               out,
               moving};
  tr.planes.init(fr, tree, magnitude);
  tr.visit(static_cast<uint32_t>(tree.children.size()), tree.root, 0x3fu);
  if (stats) *stats = tr.stats;
  return tr.written;
}

}  // namespace

void* selectionAllocate(size_t bytes) {
  constexpr size_t kHuge = size_t{2} << 20;
  const size_t align = bytes >= (size_t{1} << 20) ? kHuge : 64;
  const size_t rounded = (std::max<size_t>(bytes, 1) + align - 1) / align * align;
  void* p = std::aligned_alloc(align, rounded);
  if (!p) throw std::bad_alloc();
#ifdef MADV_HUGEPAGE
  if (align == kHuge) ::madvise(p, rounded, MADV_HUGEPAGE);  // advice only: ignored where THP is off
#endif
  return p;
}

void selectionFree(void* p) { std::free(p); }

bool prepareSelection(HdlodTree& tree) {
  tree.selectRecords.clear();
  tree.selectSteps.clear();
  tree.selectOrigin_m = glm::dvec3(0.0);
  tree.selectWidenMin_m = tree.selectWidenMax_m = 0.0;
  const size_t nc = tree.clusters.size();
  if (tree.root >= nc) return nc == 0;
  if (tree.stepTimes.size() != tree.stepValues.size()) return false;
  // A tree: every entry of `children` in one cluster's range, every cluster at most once, never the root.
  std::vector<uint8_t> isChild(nc, 0), owned(tree.children.size(), 0);
  for (const Cluster& c : tree.clusters) {
    if (uint64_t{c.firstChild} + c.childCount > tree.children.size() || uint64_t{c.stepBegin} + c.stepCount > tree.stepTimes.size())
      return false;
    if (c.childCount > 65535) return false;  // SelectRecord::count
    for (uint32_t k = c.firstChild; k < c.firstChild + c.childCount; ++k) {
      if (owned[k]) return false;
      owned[k] = 1;
    }
  }
  for (uint32_t child : tree.children) {
    if (child >= nc || child == tree.root || isChild[child]) return false;
    isChild[child] = 1;
  }
  const Aabb& rootBox = tree.clusters[tree.root].box;
  const double diag = glm::length(rootBox.max - rootBox.min);
  if (std::isfinite(diag)) tree.selectOrigin_m = 0.5 * (rootBox.min + rootBox.max);
  // At least 0.1 mm and a millionth of the scene: far above the rounding of the tests (Planes).
  const double widen = std::max(1e-6 * (std::isfinite(diag) ? diag : 0.0), 1e-4);
  double widenMin = std::numeric_limits<double>::infinity(), widenMax = 0.0;
  auto record = [&](const Cluster& c) {
    SelectRecord h;
    for (int a = 0; a < 3; ++a) {
      const double lo = c.box.min[a] - tree.selectOrigin_m[a], hi = c.box.max[a] - tree.selectOrigin_m[a];
      float flo = static_cast<float>(lo - widen), fhi = static_cast<float>(hi + widen);
      if (double(flo) > lo - widen) flo = std::nextafter(flo, -std::numeric_limits<float>::infinity());
      if (double(fhi) < hi + widen) fhi = std::nextafter(fhi, std::numeric_limits<float>::infinity());
      h.lo[a] = flo;
      h.hi[a] = fhi;
      widenMin = std::min({widenMin, lo - double(flo), double(fhi) - hi});
      widenMax = std::max({widenMax, lo - double(flo), double(fhi) - hi});
    }
    const bool leaf = c.kind == ClusterKind::Object || c.kind == ClusterKind::Dynamic;
    h.u.merged = {c.eps_m, c.size_m};
    h.first = leaf ? c.mesh : c.firstChild;
    h.count = leaf ? 0 : static_cast<uint16_t>(c.childCount);
    h.stepCount = c.stepCount;
    h.triangles = c.triangles;
    h.kind = c.kind;
    bool always = c.stepCount > 0, zeroOne = c.stepCount > 0 && c.stepCount <= 3;
    for (uint32_t i = 0; i < c.stepCount; ++i) {
      const double v = tree.stepValues[c.stepBegin + i];
      always = always && v == 1.0;
      zeroOne = zeroOne && (v == 0.0 || v == 1.0);
    }
    if (always) {
      h.flags = SelectRecord::kAlwaysPresent;
    } else if (leaf && zeroOne) {
      h.flags = SelectRecord::kInlineSteps;
      for (uint32_t i = 0; i < 3; ++i) {
        if (i > 0) h.u.leafStepTimes[i - 1] = i < c.stepCount ? tree.stepTimes[c.stepBegin + i] : std::numeric_limits<double>::infinity();
        if (i < c.stepCount && tree.stepValues[c.stepBegin + i] == 1.0) h.flags |= static_cast<uint8_t>(4u << i);
      }
    } else {
      // In record order: the steps of siblings are adjacent too; long ones after their table.
      const double* times = tree.stepTimes.data() + c.stepBegin;
      if (c.stepCount > kScanSteps) {
        const uint32_t buckets = bucketsFor(c.stepCount);
        std::vector<uint32_t> table(buckets + 1);
        for (uint32_t b = 0; b < buckets; ++b) {
          const double start = b * (tree.duration_s / buckets);
          table[b] = static_cast<uint32_t>(std::upper_bound(times + 1, times + c.stepCount, start) - times) - 1;
        }
        table[buckets] = c.stepCount - 1;
        const size_t at = tree.selectSteps.size();
        tree.selectSteps.resize(at + tableSlots(buckets));
        std::memcpy(tree.selectSteps.data() + at, table.data(), table.size() * sizeof(uint32_t));
      }
      h.stepBegin = static_cast<uint32_t>(tree.selectSteps.size());
      for (uint32_t i = 0; i < c.stepCount; ++i) tree.selectSteps.emplace_back(times[i], tree.stepValues[c.stepBegin + i]);
    }
    return h;
  };
  tree.selectRecords.reserve(tree.children.size() + 1);
  std::vector<uint32_t> stepsBefore(tree.children.size() + 1);
  for (size_t k = 0; k <= tree.children.size(); ++k) {
    stepsBefore[k] = static_cast<uint32_t>(tree.selectSteps.size());
    tree.selectRecords.push_back(record(tree.clusters[k < tree.children.size() ? tree.children[k] : tree.root]));
  }
  for (SelectRecord& h : tree.selectRecords) {
    if (h.count) h.childSteps = stepsBefore[h.first];
  }
  // NaN (a non-finite box) leaves the bounds unusable: every test is then exact (Planes::fast).
  tree.selectWidenMin_m = std::isnan(widenMin) ? 0.0 : widenMin;
  tree.selectWidenMax_m = std::isnan(widenMax) ? std::numeric_limits<double>::infinity() : widenMax;
  return true;
}

double toleranceFromPixels(double r_px, double fovY_deg, double viewportHeight_px) {
  return r_px * 2.0 * std::tan(0.5 * fovY_deg * kDeg) / viewportHeight_px;
}

size_t drawBound(const HdlodTree& tree) {
  size_t n = 0;
  for (const Cluster& c : tree.clusters) n += c.kind != ClusterKind::Group ? 1 : 0;
  return n;
}

size_t movingBound(const HdlodTree& tree) {
  size_t n = 0;
  for (const Cluster& c : tree.clusters) n += c.kind == ClusterKind::Dynamic ? 1 : 0;
  return n;
}

size_t selectHdlod(const HdlodTree& tree, const Scene& scene, const SelectView& view, std::span<Draw> out,
                   std::span<glm::dmat4> moving, SelectStats* stats) {
  return run(tree, scene, view, out, moving, stats, false);
}

size_t selectAll(const HdlodTree& tree, const Scene& scene, const SelectView& view, std::span<Draw> out,
                 std::span<glm::dmat4> moving, SelectStats* stats) {
  return run(tree, scene, view, out, moving, stats, true);
}

size_t selectHdlod(const HdlodTree& tree, const Scene& scene, const SelectView& view, DrawList& out, SelectStats* stats) {
  return out.count = run(tree, scene, view, out.draws, out.moving, stats, false);
}

size_t selectAll(const HdlodTree& tree, const Scene& scene, const SelectView& view, DrawList& out, SelectStats* stats) {
  return out.count = run(tree, scene, view, out.draws, out.moving, stats, true);
}

}  // namespace ig::lod::hdlod
