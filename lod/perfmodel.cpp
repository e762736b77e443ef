// Paper 002: performance model (1), (2), switching conditions (5), (6), optimal q (7)-(11).
#include "lod/perfmodel.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/vec4.hpp>

namespace ig::lod {
namespace {

// Counts and times above kHuge are taken as kHuge: products of two and sums of a few stay finite.
constexpr double kHuge = 1e150;
double clean(double v) { return std::isfinite(v) && v > 0.0 ? std::min(v, kHuge) : 0.0; }
// PassLoad::rasterShare: unknown (not finite) means every triangle reaches the rasterizer.
double share(const PassLoad& l) { return std::isfinite(l.rasterShare) ? std::clamp(l.rasterShare, 0.0, 1.0) : 1.0; }

uint64_t satAdd(uint64_t a, uint64_t b) {
  return a > std::numeric_limits<uint64_t>::max() - b ? std::numeric_limits<uint64_t>::max() : a + b;
}
uint64_t satMul(uint64_t a, uint64_t b) {
  if (a != 0 && b > std::numeric_limits<uint64_t>::max() / a) return std::numeric_limits<uint64_t>::max();
  return a * b;
}

}  // namespace

uint64_t sceneMemoryBytes(const MemoryModelInput& in) {
  uint64_t m = satMul(in.vertices, in.vertexBytes);
  m = satAdd(m, satMul(in.indices, in.indexBytes));
  m = satAdd(m, satMul(in.texCoords, in.texCoordBytes));
  m = satAdd(m, satMul(in.normals, in.normalBytes));
  for (uint64_t b : in.textureBytes) m = satAdd(m, b);
  for (uint64_t b : in.bufferBytes) m = satAdd(m, b);
  for (uint64_t b : in.descriptorBytes) m = satAdd(m, b);
  return m;
}

bool valid(const PerfConstants& c) {
  const double all[] = {c.frame_ns,   c.tri_ns,      c.frag_ns,   c.rasterTri_ns, c.edge_ns,          c.depthFrag_ns, c.drawRaster_ns,
                        c.state_ns,   c.command_ns,  c.rerecord_ns, c.submit_ns,  c.cull_ns,          c.occlusionTest_ns,
                        c.overlapTriangles, c.commandCount, c.commandLarge_ns, c.commandLargeCount};
  for (double v : all)
    if (!std::isfinite(v) || v < 0.0) return false;
  for (double v : c.triByDraw_ns)
    if (!std::isfinite(v) || v < 0.0) return false;
  if (!(c.overlap >= 0.0 && c.overlap <= 1.0)) return false;
  return c.tri_ns > 0.0 && c.frag_ns > 0.0;
}

double commandCost_ns(const PerfConstants& c, double commands) {
  const double base = clean(c.command_ns), large = clean(c.commandLarge_ns);
  const double n0 = clean(c.commandCount), n1 = clean(c.commandLargeCount);
  if (!(n0 > 0.0 && n1 > n0 && large > 0.0) || !(std::isfinite(commands) && commands > n0)) return base;
  if (commands >= n1) return large;
  return base + (large - base) * std::log(commands / n0) / std::log(n1 / n0);
}

double triangleCost_ns(const PerfConstants& c, double trianglesPerSubmission) {
  const auto& t = c.triByDraw_ns;
  for (double v : t)
    if (!(std::isfinite(v) && v > 0.0)) return clean(c.tri_ns);  // not measured (or invalid)
  if (!(std::isfinite(trianglesPerSubmission) && trianglesPerSubmission > 0.0)) return clean(c.tri_ns);
  const double x = std::log2(trianglesPerSubmission / 12.0);
  if (x <= 0.0) return t.front();
  if (x >= PerfConstants::kDrawSizes - 1) return t.back();
  const auto i = static_cast<size_t>(x);
  const double f = x - static_cast<double>(i);
  return t[i] + f * (t[i + 1] - t[i]);
}

double predictFrame_ns(const PerfConstants& c, const PassLoad& s, const PassLoad& h, TimeBreakdown* out) {
  TimeBreakdown b;
  const double ts = clean(c.submit_ns), tv = clean(c.occlusionTest_ns);
  const double tr = clean(c.rerecord_ns);
  b.bufS = clean(s.commands) * commandCost_ns(c, clean(s.commands)) + clean(s.rerecorded) * tr +
           clean(s.submissions) * ts + clean(s.occlusionTests) * tv;
  b.stateS = clean(s.stateChanges) * clean(c.state_ns);
  // Triangles per submission; none counted: their size is unknown (tri_ns).
  const auto perCall = [](const PassLoad& l) { return l.submissions > 0.0 ? l.triangles / l.submissions : 0.0; };
  b.vertS = clean(s.triangles) * clean(triangleCost_ns(c, perCall(s)));
  const double trS = clean(s.triangles), trH = clean(h.triangles);
  b.fragS = clean(s.fragments) * clean(c.frag_ns) + clean(s.depthFragments) * clean(c.depthFrag_ns) +
            share(s) * (trS * clean(c.rasterTri_ns) + clean(s.commands) * clean(c.drawRaster_ns)) +
            clean(s.edgePx) * clean(c.edge_ns);
  b.fcS = clean(s.frustumTests) * clean(c.cull_ns);
  b.bufH = clean(h.commands) * commandCost_ns(c, clean(h.commands)) + clean(h.rerecorded) * tr +
           clean(h.submissions) * ts + clean(h.occlusionTests) * tv;
  b.stateH = clean(h.stateChanges) * clean(c.state_ns);
  b.vertH = clean(h.triangles) * clean(triangleCost_ns(c, perCall(h)));
  b.fragH = clean(h.fragments) * clean(c.frag_ns) +
            share(h) * (trH * clean(c.rasterTri_ns) + clean(h.commands) * clean(c.drawRaster_ns)) +
            clean(h.edgePx) * clean(c.edge_ns);
  b.zbufH = clean(h.depthFragments) * clean(c.depthFrag_ns);
  b.fcH = clean(h.frustumTests) * clean(c.cull_ns);
  const double argS[3] = {b.stateS, b.vertS, b.fragS};
  const double argH[4] = {b.stateH, b.vertH, b.fragH, b.zbufH};
  b.boundS = static_cast<int>(std::max_element(argS, argS + 3) - argS);
  b.boundH = static_cast<int>(std::max_element(argH, argH + 4) - argH);
  const double w = stageOverlap(c, trS + trH);
  b.gpuS = argS[b.boundS] + (1.0 - w) * (argS[0] + argS[1] + argS[2] - argS[b.boundS]);
  b.gpuH = argH[b.boundH] + (1.0 - w) * (argH[0] + argH[1] + argH[2] + argH[3] - argH[b.boundH]);
  b.total = clean(c.frame_ns) + b.bufS + b.fcS + b.gpuS + b.fcH + b.bufH + b.gpuH;
  if (out) *out = b;
  return b.total;
}

double projectedBoxArea_px(const glm::dmat4& vp, const std::array<glm::dvec3, 8>& corners, double width_px,
                           double height_px) {
  std::array<glm::dvec2, 8> p;
  for (size_t i = 0; i < 8; ++i) {
    const glm::dvec4 clip = vp * glm::dvec4(corners[i], 1.0);
    if (!(clip.w > 1e-9)) return -1.0;
    p[i] = {(clip.x / clip.w * 0.5 + 0.5) * width_px, (clip.y / clip.w * 0.5 + 0.5) * height_px};
  }
  // Convex hull (monotone chain) of the 8 points.
  std::sort(p.begin(), p.end(), [](const glm::dvec2& a, const glm::dvec2& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  std::array<glm::dvec2, 17> hull;
  size_t k = 0;
  const auto cross = [](const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
  };
  for (size_t i = 0; i < 8; ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], p[i]) <= 0.0) --k;
    hull[k++] = p[i];
  }
  for (size_t i = 7, t = k + 1; i-- > 0;) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], p[i]) <= 0.0) --k;
    hull[k++] = p[i];
  }
  if (k < 4) return 0.0;  // degenerate (k counts the first point twice)
  // Clip the hull (counter-clockwise) to the viewport with Sutherland-Hodgman.
  std::array<glm::dvec2, 32> a, bb;
  size_t na = k - 1;
  std::copy_n(hull.begin(), na, a.begin());
  const auto clipEdge = [&](int axis, double bound, bool keepLess) {
    size_t nb = 0;
    for (size_t i = 0; i < na; ++i) {
      const glm::dvec2 cur = a[i], nxt = a[(i + 1) % na];
      const bool inC = keepLess ? cur[axis] <= bound : cur[axis] >= bound;
      const bool inN = keepLess ? nxt[axis] <= bound : nxt[axis] >= bound;
      if (inC) bb[nb++] = cur;
      if (inC != inN) {
        const double t = (bound - cur[axis]) / (nxt[axis] - cur[axis]);
        bb[nb++] = cur + t * (nxt - cur);
      }
    }
    std::copy_n(bb.begin(), nb, a.begin());
    na = nb;
  };
  clipEdge(0, 0.0, false);
  clipEdge(0, width_px, true);
  clipEdge(1, 0.0, false);
  clipEdge(1, height_px, true);
  double area = 0.0;
  for (size_t i = 0; i < na; ++i) area += a[i].x * a[(i + 1) % na].y - a[(i + 1) % na].x * a[i].y;
  return std::abs(area) * 0.5;
}

double boxRasterShare(double area_px) { return area_px > 0.0 ? std::min(1.0, area_px) : 0.0; }

PerfConstants fitOverlap(PerfConstants k, const OverlapSample& small, const OverlapSample& large) {
  PerfConstants serial = k;
  serial.overlap = 0.0;
  serial.overlapTriangles = 0.0;
  double w[2] = {0.0, 0.0}, tris[2] = {0.0, 0.0};
  const OverlapSample* frames[2] = {&small, &large};
  for (int i = 0; i < 2; ++i) {
    TimeBreakdown tb;
    const double sum = predictFrame_ns(serial, frames[i]->load, {}, &tb);
    const double smaller = std::min(tb.vertS + tb.stateS, tb.fragS);
    const double measured = frames[i]->measured_ns;
    w[i] = smaller > 0.0 && std::isfinite(measured) ? std::clamp((sum - measured) / smaller, 0.0, 1.0) : 0.0;
    tris[i] = std::isfinite(frames[i]->load.triangles) ? std::max(0.0, frames[i]->load.triangles) : 0.0;
  }
  // w_k N_k = w (N_k - T0): two equations in w and T0.
  const double wMax = tris[1] > tris[0] ? (w[1] * tris[1] - w[0] * tris[0]) / (tris[1] - tris[0]) : w[1];
  if (wMax > 0.0 && w[0] < wMax) {
    k.overlap = std::min(1.0, wMax);
    k.overlapTriangles = std::max(0.0, tris[0] * (1.0 - w[0] / wMax));
  } else {
    k.overlap = std::max(w[0], w[1]);  // no growth with the size seen: a constant overlap
    k.overlapTriangles = 0.0;
  }
  return k;
}

double stageOverlap(const PerfConstants& c, double triangles) {
  const double w = std::isfinite(c.overlap) ? std::clamp(c.overlap, 0.0, 1.0) : 1.0;
  const double t0 = clean(c.overlapTriangles), n = clean(triangles);
  if (t0 == 0.0) return w;
  return n > t0 ? w * (1.0 - t0 / n) : 0.0;
}

const char* modeName(DynamicMode m) {
  switch (m) {
    case DynamicMode::PerCommand: return "percommand";
    case DynamicMode::Octree: return "octree";
    case DynamicMode::Occlusion: return "occlusion";
  }
  return "?";
}

DynamicMode ModeSwitcher::update(const ModeInputs& in) {
  ++framesInMode_;
  const double l5 = in.bufS_ns + in.fcS_ns, r5 = in.bufH_ns + in.fcH_ns;
  const double l6 = in.frameAll_ns, r6 = in.frameVisible_ns + in.visTests_ns;
  if (framesInMode_ <= config_.minFrames) return mode_;
  const double h = config_.hysteresis;
  DynamicMode next = mode_;
  const bool ok5 = std::isfinite(l5) && std::isfinite(r5), ok6 = std::isfinite(l6) && std::isfinite(r6);
  switch (mode_) {
    case DynamicMode::PerCommand:
      if (ok5 && l5 > r5 * (1.0 + h)) next = DynamicMode::Octree;
      // Hidden objects found while drawing per-object commands: the whole per-object frame
      // (T(S) with the per-object buffers in place of the node ranges') against occlusion culling.
      else if (ok5 && ok6 && r6 < l6 && l6 - r5 + l5 > r6 * (1.0 + h)) next = DynamicMode::Occlusion;
      break;
    case DynamicMode::Octree:
      if (ok5 && l5 < r5 * (1.0 - h)) next = DynamicMode::PerCommand;
      else if (ok6 && l6 > r6 * (1.0 + h)) next = DynamicMode::Occlusion;
      break;
    case DynamicMode::Occlusion:
      if (ok6 && l6 < r6 * (1.0 - h)) next = DynamicMode::Octree;
      break;
  }
  if (next != mode_) {
    mode_ = next;
    framesInMode_ = 0;
    ++switches_;
  }
  return mode_;
}

double occlusionFrame_ns(const OcclusionCoefficients& k, const OcclusionCosts& t, double q) {
  q = clean(q);
  const double l = std::log1p(q);
  const double tq = t.tq_ns < 0.0 ? clean(t.tc_ns) : clean(t.tq_ns);
  const double c = k.cA - k.cB * l;  // re-recorded commands (c(q) - q)
  const double s = k.sA - k.s1 * l;
  const double e = k.e0 + k.p * q - k.e1 * l;
  return c * clean(t.tc_ns) + q * tq + s * clean(t.ts_ns) + e * clean(t.te_ns);
}

double stationaryQ(const OcclusionCoefficients& k, const OcclusionCosts& t) {
  const double tc = clean(t.tc_ns), ts = clean(t.ts_ns), te = clean(t.te_ns);
  const double tq = t.tq_ns < 0.0 ? tc : clean(t.tq_ns);
  const double den = k.p * te + tq;
  if (!(den > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  return (k.cB * tc + k.s1 * ts + k.e1 * te) / den - 1.0;
}

uint32_t optimalQ(const OcclusionCoefficients& k, const OcclusionCosts& t, uint32_t n0, double* time_ns) {
  uint32_t best = 0;
  double bestT = occlusionFrame_ns(k, t, 0.0);
  const auto consider = [&](double q) {
    if (!std::isfinite(q)) return;
    q = std::clamp(q, 0.0, static_cast<double>(n0));
    const auto qi = static_cast<uint32_t>(q);
    const double tq = occlusionFrame_ns(k, t, static_cast<double>(qi));
    if (tq < bestT) bestT = tq, best = qi;
  };
  consider(static_cast<double>(n0));
  const double qs = stationaryQ(k, t);
  if (std::isfinite(qs)) {
    consider(std::floor(qs));
    consider(std::ceil(qs));
  }
  if (time_ns) *time_ns = bestT;
  return best;
}

bool OcclusionFits::add(double q, double c, double s, double e) {
  // No frame issues 1e12 tests, commands or primitives: a larger count is a glitch, whose square
  // would dominate the sums for thousands of frames (or overflow them to inf for good).
  constexpr double kMaxCount = 1e12;
  for (double v : {q, c, s, e})
    if (!std::isfinite(v) || v < 0.0 || v > kMaxCount) return false;
  const double f = forget_;
  const double x = std::log1p(q), yc = c - q;
  n_ = n_ * f + 1.0;
  sx_ = sx_ * f + x, sxx_ = sxx_ * f + x * x;
  sq_ = sq_ * f + q, sqq_ = sqq_ * f + q * q, sxq_ = sxq_ * f + x * q;
  syc_ = syc_ * f + yc, sxyc_ = sxyc_ * f + x * yc;
  sys_ = sys_ * f + s, sxys_ = sxys_ * f + x * s;
  sye_ = sye_ * f + e, sxye_ = sxye_ * f + x * e, sqye_ = sqye_ * f + q * e;
  bool seen = false;
  for (uint32_t i = 0; i < distinct_; ++i) seen = seen || lastQ_[i] == q;
  if (!seen) {
    if (distinct_ < 3) {
      lastQ_[distinct_++] = q;
    } else {  // keep the three most recent distinct values
      lastQ_[0] = lastQ_[1], lastQ_[1] = lastQ_[2], lastQ_[2] = q;
    }
  }
  return true;
}

bool OcclusionFits::solve(OcclusionCoefficients& out) const {
  if (distinct_ < 3 || n_ <= 0.0) return false;
  // y = a - b x: least squares on (1, x).
  const double n = n_;
  const double dx = n * sxx_ - sx_ * sx_;
  if (!(dx > 1e-12 * std::max(1.0, n * sxx_))) return false;
  const auto line = [&](double sy, double sxy, double& a, double& b) {
    const double slope = (n * sxy - sx_ * sy) / dx;  // y = a + slope x
    a = (sy - slope * sx_) / n;
    b = -slope;
  };
  OcclusionCoefficients k;
  line(syc_, sxyc_, k.cA, k.cB);
  line(sys_, sxys_, k.sA, k.s1);
  // e = e0 + p q - e1 x: normal equations for (1, q, x).
  const double m[3][3] = {{n, sq_, sx_}, {sq_, sqq_, sxq_}, {sx_, sxq_, sxx_}};
  const double r[3] = {sye_, sqye_, sxye_};
  const auto det3 = [](const double a[3][3]) {
    return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
           a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
  };
  const double d = det3(m);
  const double scale = m[0][0] * m[1][1] * m[2][2];
  if (!(std::abs(d) > 1e-12 * std::max(scale, 1e-300))) return false;
  double sol[3];
  for (int j = 0; j < 3; ++j) {
    double mj[3][3];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) mj[a][b] = b == j ? r[a] : m[a][b];
    sol[j] = det3(mj) / d;
  }
  k.e0 = sol[0], k.p = sol[1], k.e1 = -sol[2];
  for (double v : {k.cA, k.cB, k.sA, k.s1, k.e0, k.p, k.e1})
    if (!std::isfinite(v)) return false;
  out = k;
  return true;
}

}  // namespace ig::lod
