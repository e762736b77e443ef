// ROAM (Duchaineau et al. 1997) with split / merge queues, plus enhMerge (Graphicon 2002,
// shared/seeds/001). See roam.h for the grid, the bounds and the selection rule.
//
// Structure. Nodes live in a fixed pool of pairs: the two children of a node are the pair
// (2i, 2i + 1), child 0 = left child (apex m, left a, right l), child 1 = right child
// (apex m, left r, right a) for a parent (apex a, left l, right r) split at m = mid(l, r).
// The first pairs are the base squares (their two triangles are partners, not siblings).
// Only one neighbour link is stored: `partner`, the same-level node across the hypotenuse
// (Duchaineau's base neighbour when it is at the same level). Invariant: a node is split iff
// its partner is split, so a diamond is split or merged as one. The other neighbours follow
// from the tree in O(1) (legNode): across a child's inner leg is its sibling, across its outer
// leg is a child of the parent's partner; same-level leg neighbours share the apex and mirror
// each other (my left leg is their right leg). The Duchaineau base neighbour of a leaf without
// a partner is the coarser leaf across the parent's leg (coarseNeighbour).
#include "lod/roam.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <new>
#include <type_traits>
#include <utility>

namespace ig::lod {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;
constexpr double kInf = std::numeric_limits<double>::infinity();

uint64_t centimetres(double m) { return m < 1.8e16 ? static_cast<uint64_t>(m * 100.0) : uint64_t{1} << 62; }

bool finite3(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Rounds a non-negative double up to a float that is >= it.
float floatUp(double v) {
  float f = static_cast<float>(v);
  if (static_cast<double>(f) < v) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

}  // namespace

Roam::Roam(std::span<const float> heights_m, int width, int height, double spacing_m, const glm::dvec3& origin_m,
           const RoamConfig& config)
    : heights_m_(heights_m.data()),
      width_(width),
      height_(height),
      spacing_m_(spacing_m),
      origin_m_(origin_m),
      configMaxTriangles_(config.maxTriangles) {
  assert(width >= 2 && height >= 2 && "Roam: need at least 2x2 samples");
  assert(heights_m.size() >= static_cast<size_t>(width) * static_cast<size_t>(height) && "Roam: heights too small");
  assert(spacing_m > 0.0 && std::isfinite(spacing_m) && "Roam: spacing_m must be > 0");

  // Base squares of side S = 2^k <= min(width, height) - 1 covering the DEM.
  const int minSide = std::min(width, height) - 1;
  int k = 0;
  rootSide_ = 1;
  while (rootSide_ * 2 <= minSide) {
    rootSide_ *= 2;
    ++k;
  }
  rootsX_ = (width - 1 + rootSide_ - 1) / rootSide_;
  rootsY_ = (height - 1 + rootSide_ - 1) / rootSide_;
  px_ = rootsX_ * rootSide_ + 1;
  py_ = rootsY_ * rootSide_ + 1;
  maxLevel_ = 2 * k;
  assert(maxLevel_ < 250 && "Roam: grid too large");
  computeBounds();
  setUpPool(config);
}

Roam::Roam(const Roam& other, const RoamConfig& config)
    : heights_m_(other.heights_m_),
      width_(other.width_),
      height_(other.height_),
      spacing_m_(other.spacing_m_),
      origin_m_(other.origin_m_),
      configMaxTriangles_(config.maxTriangles),
      rootSide_(other.rootSide_),
      rootsX_(other.rootsX_),
      rootsY_(other.rootsY_),
      px_(other.px_),
      py_(other.py_),
      maxLevel_(other.maxLevel_),
      zMin_m_(other.zMin_m_),
      zStep_m_(other.zStep_m_),
      bounds_(other.bounds_) {
  setUpPool(config);
}

void Roam::setUpPool(const RoamConfig& config) {
  const size_t base = baseTriangles();
  size_t capacity = config.nodeCapacity != 0 ? config.nodeCapacity : static_cast<size_t>(2 * config.maxTriangles) + base;
  capacity = std::max(capacity, 2 * base);
  capacity = std::min<size_t>(capacity, 0xFFFFFFF0u);
  capacity += capacity & 1u;
  nodes_.reset(static_cast<Node*>(std::calloc(capacity, sizeof(Node))));
  static_assert(std::is_trivially_copyable_v<Node>, "calloc'd pool: Node must be an implicit-lifetime type");
  if (!nodes_) throw std::bad_alloc();
  nodeCap_ = capacity;
  freePairs_.reserve(capacity / 2);
  // Live queue entries are bounded by the leaves / diamonds (<= capacity / 2 + base); stale
  // ones are compacted away when a queue fills up.
  splitQ_.reserve(capacity / 2 + 64);
  mergeQ_.reserve(capacity / 2 + 64);
  chain_.reserve(static_cast<size_t>(maxLevel_) + 4);
  resetToBase();

  // Same-level neighbours across the legs of the base triangles: the base triangle of the
  // adjacent square that has the same segment as a leg.
  rootLeg_.assign(2 * base, kNone);
  for (uint32_t n = 0; n < base; ++n) {
    const Node& nd = nodes_[n];
    for (int side = 0; side < 2; ++side) {
      const int ex = side == 0 ? nd.lx : nd.rx, ey = side == 0 ? nd.ly : nd.ry;
      const int q = static_cast<int>(n / 2), qi = q % rootsX_, qj = q / rootsX_;
      int ni = qi, nj = qj;
      if (ey == nd.ay) {  // horizontal leg: bottom or top side of the square
        nj += nd.ay == qj * rootSide_ ? -1 : 1;
      } else {            // vertical leg
        ni += nd.ax == qi * rootSide_ ? -1 : 1;
      }
      if (ni < 0 || nj < 0 || ni >= rootsX_ || nj >= rootsY_) continue;
      for (uint32_t m = static_cast<uint32_t>(2 * (nj * rootsX_ + ni)); m < static_cast<uint32_t>(2 * (nj * rootsX_ + ni) + 2); ++m) {
        const Node& o = nodes_[m];
        for (int os = 0; os < 2; ++os) {
          const int ox = os == 0 ? o.lx : o.rx, oy = os == 0 ? o.ly : o.ry;
          const bool same = (o.ax == nd.ax && o.ay == nd.ay && ox == ex && oy == ey) ||
                            (o.ax == ex && o.ay == ey && ox == nd.ax && oy == nd.ay);
          if (same) {
            // The alternating diagonals make same-level leg neighbours mirror images.
            assert(os == 1 - side && o.ax == nd.ax && o.ay == nd.ay && "Roam: base squares not mirrored");
            rootLeg_[2 * n + static_cast<size_t>(side)] = m;
          }
        }
      }
    }
  }
}

void Roam::FreeDeleter::operator()(Node* p) const { std::free(p); }

float Roam::heightAt(int x, int y) const {
  const int cx = std::clamp(x, 0, width_ - 1), cy = std::clamp(y, 0, height_ - 1);
  return heights_m_[static_cast<size_t>(cy) * static_cast<size_t>(width_) + static_cast<size_t>(cx)];
}

Roam::Bound Roam::diamondBound(const Node& n) const {
  if (n.level >= maxLevel_) return Bound{0.0f, 0, 0};
  const int cx = (n.lx + n.rx) / 2, cy = (n.ly + n.ry) / 2;
  return (*bounds_)[static_cast<size_t>(cy) * static_cast<size_t>(px_) + static_cast<size_t>(cx)];
}

glm::dvec3 Roam::vertexPosition(int x, int y) const {
  const int cx = std::clamp(x, 0, width_ - 1), cy = std::clamp(y, 0, height_ - 1);
  return origin_m_ + glm::dvec3(cx * spacing_m_, cy * spacing_m_, static_cast<double>(heightAt(cx, cy)));
}

// Nested bounds, bottom-up: for half size h = 1, 2, 4, ..., S / 2 first the diamonds with an
// axis-aligned hypotenuse of length 2h (children: squares of half size h / 2), then the square
// diamonds of side 2h (children: the axis diamonds of half size h at their side midpoints).
void Roam::computeBounds() {
  const size_t samples = static_cast<size_t>(width_) * static_cast<size_t>(height_);
  float lo = heights_m_[0], hi = heights_m_[0];
  for (size_t i = 0; i < samples; ++i) {
    assert(std::isfinite(heights_m_[i]) && "Roam: heights must be finite");
    lo = std::min(lo, heights_m_[i]);
    hi = std::max(hi, heights_m_[i]);
  }
  zMin_m_ = lo;
  zStep_m_ = hi > lo ? (static_cast<double>(hi) - static_cast<double>(lo)) / 65535.0 : 1.0;
  bounds_ = std::make_shared<std::vector<Bound>>(static_cast<size_t>(px_) * static_cast<size_t>(py_), Bound{0.0f, 0, 0});
  std::vector<Bound>& bounds = *bounds_;
  auto at = [&](int x, int y) -> Bound& { return bounds[static_cast<size_t>(y) * static_cast<size_t>(px_) + static_cast<size_t>(x)]; };
  auto inGrid = [&](int x, int y) { return x >= 0 && y >= 0 && x < px_ && y < py_; };
  auto qLo = [&](double z) {
    return static_cast<uint16_t>(std::clamp(std::floor((z - static_cast<double>(zMin_m_)) / zStep_m_), 0.0, 65535.0));
  };
  auto qHi = [&](double z) {
    return static_cast<uint16_t>(std::clamp(std::ceil((z - static_cast<double>(zMin_m_)) / zStep_m_), 0.0, 65535.0));
  };
  // Corners: the hypotenuse ends a, b then the apexes (any may be off the padded grid).
  auto finish = [&](int cx, int cy, const int (&xs)[4], const int (&ys)[4], const int (&kx)[4], const int (&ky)[4], bool hasChildren) {
    double zl = static_cast<double>(heightAt(cx, cy)), zh = zl;
    int minX = cx, minY = cy;
    for (int i = 0; i < 4; ++i) {
      if (!inGrid(xs[i], ys[i])) continue;
      const double z = static_cast<double>(heightAt(xs[i], ys[i]));
      zl = std::min(zl, z);
      zh = std::max(zh, z);
      minX = std::min(minX, xs[i]);
      minY = std::min(minY, ys[i]);
    }
    // Wholly east or north of the DEM: the geometry is zero-area after clamping; no own error.
    const bool outside = minX >= width_ - 1 || minY >= height_ - 1;
    const double mid = 0.5 * (static_cast<double>(heightAt(xs[0], ys[0])) + static_cast<double>(heightAt(xs[1], ys[1])));
    double err = outside ? 0.0 : std::abs(static_cast<double>(heightAt(cx, cy)) - mid);
    Bound& b = at(cx, cy);
    b.zLo = qLo(zl);
    b.zHi = qHi(zh);
    if (hasChildren) {
      for (int i = 0; i < 4; ++i) {
        if (!inGrid(kx[i], ky[i])) continue;
        const Bound& c = at(kx[i], ky[i]);
        err = std::max(err, static_cast<double>(c.error_m));
        b.zLo = std::min(b.zLo, c.zLo);
        b.zHi = std::max(b.zHi, c.zHi);
      }
    }
    b.error_m = floatUp(err);
  };
  const int half = rootSide_ / 2;
  for (int h = 1; h <= half; h *= 2) {
    const int s = 2 * h, q = h / 2;
    // Axis diamonds: horizontal hypotenuses (y on the 2h grid) and vertical ones.
    for (int vertical = 0; vertical < 2; ++vertical) {
      for (int cy = vertical ? h : 0; cy < py_; cy += s) {
        for (int cx = vertical ? 0 : h; cx < px_; cx += s) {
          const int xs[4] = {vertical ? cx : cx - h, vertical ? cx : cx + h, vertical ? cx - h : cx, vertical ? cx + h : cx};
          const int ys[4] = {vertical ? cy - h : cy, vertical ? cy + h : cy, vertical ? cy : cy - h, vertical ? cy : cy + h};
          const int kx[4] = {cx - q, cx + q, cx - q, cx + q};
          const int ky[4] = {cy - q, cy - q, cy + q, cy + q};
          finish(cx, cy, xs, ys, kx, ky, h >= 2);
        }
      }
    }
    // Square diamonds: the hypotenuse is the diagonal through the parent square's centre,
    // SW-NE when (i + j) is even for square index (i, j), else NW-SE.
    for (int cy = h; cy < py_; cy += s) {
      for (int cx = h; cx < px_; cx += s) {
        const bool even = (((cx - h) / s) + ((cy - h) / s)) % 2 == 0;
        const int xs[4] = {cx - h, cx + h, even ? cx + h : cx - h, even ? cx - h : cx + h};
        const int ys[4] = {even ? cy - h : cy + h, even ? cy + h : cy - h, cy - h, cy + h};
        const int kx[4] = {cx - h, cx + h, cx, cx};
        const int ky[4] = {cy, cy, cy - h, cy + h};
        finish(cx, cy, xs, ys, kx, ky, true);
      }
    }
  }
}

bool Roam::splitEnds(int x, int y, RoamVertex& a, RoamVertex& b) const {
  if (x < 0 || y < 0 || x >= px_ || y >= py_) return false;
  const int bits = x | y;
  if (bits == 0) return false;
  const int h = bits & -bits;  // largest power of two dividing both
  if (h >= rootSide_) return false;  // a base-square corner
  const bool xOdd = (x / h) % 2 == 1, yOdd = (y / h) % 2 == 1;
  if (xOdd && yOdd) {  // square diamond, half side h (same rule as computeBounds)
    const int s = 2 * h;
    const bool even = (((x - h) / s) + ((y - h) / s)) % 2 == 0;
    a = {x - h, even ? y - h : y + h};
    b = {x + h, even ? y + h : y - h};
  } else if (xOdd) {  // axis diamond with a horizontal hypotenuse
    a = {x - h, y};
    b = {x + h, y};
  } else {  // vertical hypotenuse
    a = {x, y - h};
    b = {x, y + h};
  }
  return true;
}

void Roam::resetToBase() {
  const uint32_t rootPairs = static_cast<uint32_t>(rootsX_ * rootsY_);
  highPairs_ = rootPairs;
  freePairs_.clear();
  for (int j = 0; j < rootsY_; ++j) {
    for (int i = 0; i < rootsX_; ++i) {
      const uint32_t n0 = 2u * static_cast<uint32_t>(j * rootsX_ + i), n1 = n0 + 1;
      const int x0 = i * rootSide_, y0 = j * rootSide_, x1 = x0 + rootSide_, y1 = y0 + rootSide_;
      Node& a = nodes_[n0];
      Node& b = nodes_[n1];
      if ((i + j) % 2 == 0) {  // hypotenuse SW-NE; apexes SE and NW
        a.ax = x1, a.ay = y0, a.lx = x0, a.ly = y0, a.rx = x1, a.ry = y1;
        b.ax = x0, b.ay = y1, b.lx = x1, b.ly = y1, b.rx = x0, b.ry = y0;
      } else {  // hypotenuse NW-SE; apexes SW and NE
        a.ax = x0, a.ay = y0, a.lx = x0, a.ly = y1, a.rx = x1, a.ry = y0;
        b.ax = x1, b.ay = y1, b.lx = x1, b.ly = y0, b.rx = x0, b.ry = y1;
      }
      for (Node* nd : {&a, &b}) {
        nd->parent = kNone;
        nd->children = kNone;
        nd->level = 0;
        nd->free = 0;
        nd->queued = 0;
        nd->bound = diamondBound(*nd);
        ++nd->gen;
        ++nd->sched;
      }
      a.partner = n1;
      b.partner = n0;
    }
  }
  liveNodes_ = 2u * rootPairs;
  triangles_ = 2u * rootPairs;
  leafLogCount_ = 0;
  leafLogReset_ = true;  // the log cannot describe this: every leaf is new
}

// ---- structure ---------------------------------------------------------------------------

uint32_t Roam::legNode(uint32_t n, int side) const {
  const Node& nd = nodes_[n];
  if (nd.parent == kNone) return rootLeg_[2 * static_cast<size_t>(n) + static_cast<size_t>(side)];
  if (side == static_cast<int>(n & 1u)) return n ^ 1u;  // inner leg: the sibling
  const uint32_t pp = nodes_[nd.parent].partner;      // outer leg: half the parent's hypotenuse
  if (pp == kNone) return kNone;
  return nodes_[pp].children + static_cast<uint32_t>(side);
}

uint32_t Roam::coarseNeighbour(uint32_t n) const {
  const Node& nd = nodes_[n];
  if (nd.parent == kNone) return kNone;
  return legNode(nd.parent, static_cast<int>(n & 1u));
}

bool Roam::mergeable(uint32_t n) const {
  const Node& nd = nodes_[n];
  if (nd.children == kNone || !isLeaf(nd.children) || !isLeaf(nd.children + 1)) return false;
  if (nd.partner == kNone) return true;
  const Node& p = nodes_[nd.partner];
  return p.children != kNone && isLeaf(p.children) && isLeaf(p.children + 1);
}

uint32_t Roam::allocPair() {
  if (!freePairs_.empty()) {
    const uint32_t p = freePairs_.back();
    freePairs_.pop_back();
    return p;
  }
  assert(2 * static_cast<size_t>(highPairs_) + 2 <= nodeCap_);
  return highPairs_++;
}

void Roam::freePair(uint32_t firstChild) {
  nodes_[firstChild].free = 1;
  nodes_[firstChild + 1].free = 1;
  ++nodes_[firstChild].sched;  // Deferred: their scheduled entries become stale
  ++nodes_[firstChild + 1].sched;
  visitsUsed_ += 2;
  freePairs_.push_back(firstChild / 2);  // capacity reserved for every pair
  liveNodes_ -= 2;
  stats_.nodesFreed += 2;
}

void Roam::splitNode(uint32_t n) {
  assert(isLeaf(n) && nodes_[n].level < maxLevel_);
  const uint32_t c0 = 2 * allocPair(), c1 = c0 + 1;
  Node& nd = nodes_[n];
  ++nd.gen;  // its split-queue entries (as a leaf) become stale
  nd.queued = 0;
  visitsUsed_ += 2;
  const int mx = (nd.lx + nd.rx) / 2, my = (nd.ly + nd.ry) / 2;
  if (createdCount_ < created_.size()) created_[createdCount_++] = RoamVertex{mx, my};
  Node& a = nodes_[c0];
  Node& b = nodes_[c1];
  a.ax = mx, a.ay = my, a.lx = nd.ax, a.ly = nd.ay, a.rx = nd.lx, a.ry = nd.ly;
  b.ax = mx, b.ay = my, b.lx = nd.rx, b.ly = nd.ry, b.rx = nd.ax, b.ry = nd.ay;
  for (Node* c : {&a, &b}) {
    c->parent = n;
    c->children = kNone;
    c->partner = kNone;
    c->level = static_cast<uint8_t>(nd.level + 1);
    c->free = 0;
    c->queued = 0;
    c->bound = diamondBound(*c);
    ++c->gen;
  }
  nd.children = c0;
  if (!leafLog_.empty()) {
    logLeaf(n | kLeafRemoved);
    logLeaf(c0);
    logLeaf(c1);
  }
  touch(n);
  touch(c0);
  touch(c1);
  // Child c's hypotenuse is our leg c; its partner is the mirrored child of the node across.
  for (int c = 0; c < 2; ++c) {
    const uint32_t across = legNode(n, c);
    if (across == kNone || isLeaf(across)) continue;
    const uint32_t q = nodes_[across].children + static_cast<uint32_t>(1 - c);
    assert(nodes_[q].partner == kNone);
    nodes_[q].partner = c0 + static_cast<uint32_t>(c);
    nodes_[c0 + static_cast<uint32_t>(c)].partner = q;
  }
  liveNodes_ += 2;
  triangles_ += 1;
}

void Roam::splitDiamond(uint32_t n) {
  const uint32_t b = nodes_[n].partner;
  splitNode(n);
  if (b != kNone) splitNode(b);
  ++stats_.splits;
  for (const uint32_t z : {n, b}) {
    if (z == kNone) continue;
    const uint32_t first = nodes_[z].children;
    considerLeaf(first, priority(nodes_[first], vs_));
    considerLeaf(first + 1, priority(nodes_[first + 1], vs_));
  }
  if (mergesCollected_) pushMerge(b != kNone ? std::min(n, b) : n, priority(nodes_[n], vs_));
}

// Split n, first splitting the coarser base neighbours down the chain (Duchaineau's forced
// split). Every single diamond split leaves a valid mesh, so the budget may stop the chain
// anywhere. The triangle cap and the pool are checked for the whole chain before starting.
Roam::SplitResult Roam::forcedSplit(uint32_t n) {
  chain_.clear();
  uint32_t y = n;
  for (;;) {
    chain_.push_back(y);
    if (nodes_[y].partner != kNone) break;
    const uint32_t c = coarseNeighbour(y);
    if (c == kNone) break;  // hypotenuse on the grid border
    assert(isLeaf(c) && nodes_[c].level + 1 == nodes_[y].level);
    y = c;
  }
  const uint64_t added = 2 * (chain_.size() - 1) + (nodes_[chain_.back()].partner != kNone ? 2 : 1);
  if (triangles_ + added > capTriangles_) return SplitResult::Capped;
  if (liveNodes_ + 2 * added > nodeCap_) return SplitResult::PoolFull;
  for (size_t i = chain_.size(); i-- > 0;) {
    if (!takeOp()) return SplitResult::Budget;
    splitDiamond(chain_[i]);
  }
  return SplitResult::Done;
}

void Roam::mergeDiamond(uint32_t n) {
  assert(mergeable(n));
  const uint32_t b = nodes_[n].partner;
  if (removedCount_ < removed_.size())
    removed_[removedCount_++] = RoamVertex{(nodes_[n].lx + nodes_[n].rx) / 2, (nodes_[n].ly + nodes_[n].ry) / 2};
  for (const uint32_t z : {n, b}) {
    if (z == kNone) continue;
    const uint32_t first = nodes_[z].children;
    for (uint32_t c = first; c < first + 2; ++c) {
      const uint32_t q = nodes_[c].partner;
      if (q != kNone) nodes_[q].partner = kNone;  // the outside neighbour is now across a leg of z
    }
    freePair(first);
    nodes_[z].children = kNone;
    if (!leafLog_.empty()) {
      logLeaf(first | kLeafRemoved);
      logLeaf((first + 1) | kLeafRemoved);
      logLeaf(z);
    }
    triangles_ -= 1;
    touch(z);
  }
}

// enhMerge: make n (and its partner) leaves in one step. Children that are split are
// collapsed first, together with their partners across n's legs (the neighbours' subtrees
// that would leave a vertex on n's edges), recursively; then the diamond merges. Everything
// destroyed is a descendant of n's diamond in the diamond hierarchy.
void Roam::collapse(uint32_t n) {
  if (isLeaf(n)) return;
  const uint32_t b = nodes_[n].partner;
  for (const uint32_t z : {n, b}) {
    if (z == kNone) continue;
    for (uint32_t c = 0; c < 2; ++c) {
      const uint32_t child = nodes_[z].children + c;
      if (!isLeaf(child)) collapse(child);
    }
  }
  mergeDiamond(n);
}

// ---- priorities --------------------------------------------------------------------------

Roam::ViewState Roam::makeViewState(const RoamView& view) const {
  ViewState vs;
  vs.eye_m = view.camera.eye_m - origin_m_;
  vs.tolerance_px = view.tolerance_px;
  const Camera& c = view.camera;
  vs.scale = view.viewportHeight_px / (2.0 * std::tan(0.5 * c.fovY_deg * kDeg));
  vs.valid = finite3(c.eye_m) && std::isfinite(c.heading_deg) && std::isfinite(c.pitch_deg) && std::isfinite(c.roll_deg) &&
             std::isfinite(vs.scale) && vs.scale > 0.0 && std::isfinite(c.aspect) && c.aspect > 0.0 &&
             std::isfinite(c.near_m) && std::isfinite(c.far_m) && c.near_m > 0.0 && c.far_m > c.near_m &&
             validWindowShift(c);
  if (vs.valid) {
    vs.frustum = makeFrustum(c);
    for (const auto& p : vs.frustum.planes) vs.valid = vs.valid && std::isfinite(p.x + p.y + p.z + p.w);
  }
  return vs;
}

Aabb Roam::diamondBox(const Node& n) const {
  const int cx = (n.lx + n.rx) / 2, cy = (n.ly + n.ry) / 2;
  const int dx = std::abs(n.lx - n.rx), dy = std::abs(n.ly - n.ry);
  // Half size containing all descendant diamonds: 3h for squares, 2h for axis diamonds.
  const int ext = (dx != 0 && dy != 0) ? 3 * (dx / 2) : dx + dy;
  const Bound& b = n.bound;
  Aabb box;
  box.min.x = std::clamp(cx - ext, 0, width_ - 1) * spacing_m_;
  box.max.x = std::clamp(cx + ext, 0, width_ - 1) * spacing_m_;
  box.min.y = std::clamp(cy - ext, 0, height_ - 1) * spacing_m_;
  box.max.y = std::clamp(cy + ext, 0, height_ - 1) * spacing_m_;
  box.min.z = static_cast<double>(zMin_m_) + (b.zLo - 0.5) * zStep_m_;
  box.max.z = static_cast<double>(zMin_m_) + (b.zHi + 0.5) * zStep_m_;
  return box;
}

double Roam::priority(const Node& n, const ViewState& vs) const {
  const double e = static_cast<double>(n.bound.error_m);  // 0 at the finest level
  if (!vs.valid || !(e > 0.0)) return 0.0;
  Aabb box = diamondBox(n);
  box.min -= vs.eye_m;
  box.max -= vs.eye_m;
  if (vs.cullFrustum && !vs.frustum.intersects(box)) return 0.0;
  const double d = distanceToBox(box, glm::dvec3(0.0));
  if (!(d > 0.0)) return kInf;  // eye in the box
  const double p = e * vs.scale / d;
  return p == p ? p : 0.0;
}

// ---- queues ------------------------------------------------------------------------------

namespace {
struct SplitLess {
  template <class E>
  bool operator()(const E& a, const E& b) const { return a.priority < b.priority; }
};
struct MergeGreater {
  template <class E>
  bool operator()(const E& a, const E& b) const { return a.priority > b.priority; }
};
}  // namespace

bool Roam::stopRequested() {
  if (stop_ == nullptr || visitsUsed_ < nextPoll_) return false;
  nextPoll_ = visitsUsed_ + kStopPollVisits;
  return pollStop();
}

bool Roam::pollStop() {
  if (!stop_(stopContext_)) return false;
  visitBudget_ = visitsUsed_;  // the rest of this update is out of budget
  stop_ = nullptr;
  stopFired_ = true;
  return true;
}

bool Roam::schedulePending() {
  uint32_t sincePoll = 0;
  auto outOfTime = [&] {
    if (stopFired_) return true;
    if (stop_ == nullptr || ++sincePoll < kStopPollVisits) return false;
    sincePoll = 0;
    return pollStop();
  };
  while (pendingTouched_ < touched_.size()) {
    if (outOfTime()) return false;
    schedule(touched_[pendingTouched_++]);
  }
  while (pendingRecheck_ < recheck_.size()) {
    if (outOfTime()) return false;
    schedule(recheck_[pendingRecheck_++]);
  }
  dropPending();
  return true;
}

void Roam::dropPending() {
  touched_.clear();
  recheck_.clear();
  pendingTouched_ = pendingRecheck_ = 0;
}

bool Roam::outOfVisits() { return visitsUsed_ >= visitBudget_ || stopRequested(); }

bool Roam::takeOp() {
  if (opsLeft_ == 0 || outOfVisits()) return false;
  --opsLeft_;
  return true;
}

void Roam::considerLeaf(uint32_t n, double p) {
  if (p > vs_.tolerance_px && nodes_[n].level < maxLevel_) {
    pushSplit(n, vs_.cullFrustum ? p : splitKey(nodes_[n], p));
  } else {
    maxSmallPx_ = std::max(maxSmallPx_, p);
  }
}

void Roam::pushSplit(uint32_t n, double p) {
  if (nodes_[n].queued) return;  // already queued (the entry's key may be older: fine)
  if (splitQ_.size() == splitQ_.capacity()) compactSplit();
  if (splitQ_.size() == splitQ_.capacity()) return;  // full of live entries: found next frame
  nodes_[n].queued = 1;
  splitQ_.push_back({p, n, nodes_[n].gen});
  if (splitHeap_) std::push_heap(splitQ_.begin(), splitQ_.end(), SplitLess{});
}

void Roam::pushMerge(uint32_t n, double p) {
  if (mergeQ_.size() == mergeQ_.capacity()) compactMerge();
  if (mergeQ_.size() == mergeQ_.capacity()) return;
  mergeQ_.push_back({p, n, nodes_[n].gen});
  if (mergeHeap_) std::push_heap(mergeQ_.begin(), mergeQ_.end(), MergeGreater{});
}

void Roam::pushParentMerges(uint32_t n) {
  if (!mergesCollected_) return;  // collectMerges() will find them
  for (const uint32_t z : {n, nodes_[n].partner}) {
    if (z == kNone) continue;
    const uint32_t p = nodes_[z].parent;
    if (p == kNone || !mergeable(p)) continue;
    const uint32_t pp = nodes_[p].partner;
    pushMerge(pp != kNone ? std::min(p, pp) : p, priority(nodes_[p], vs_));
  }
}

namespace {
// The top of a lazily heapified queue, popping stale entries (freed or changed nodes) on the way.
template <class Entry, class Compare, class Valid>
bool topValid(std::vector<Entry>& q, bool& heapified, Compare cmp, Valid valid, Entry* e) {
  if (!heapified) {
    std::make_heap(q.begin(), q.end(), cmp);
    heapified = true;
  }
  while (!q.empty()) {
    if (valid(q.front())) {
      *e = q.front();
      return true;
    }
    std::pop_heap(q.begin(), q.end(), cmp);
    q.pop_back();
  }
  return false;
}
}  // namespace

bool Roam::topSplit(QueueEntry* e) {
  if (!splitHeap_) {
    std::make_heap(splitQ_.begin(), splitQ_.end(), SplitLess{});
    splitHeap_ = true;
  }
  while (!splitQ_.empty()) {
    const QueueEntry& t = splitQ_.front();
    const Node& nd = nodes_[t.node];
    if (!nd.free && nd.gen == t.gen && nd.children == kNone) {
      *e = t;
      return true;
    }
    popSplit();
  }
  return false;
}

void Roam::popSplit() {
  const QueueEntry& t = splitQ_.front();
  if (nodes_[t.node].gen == t.gen) nodes_[t.node].queued = 0;
  std::pop_heap(splitQ_.begin(), splitQ_.end(), SplitLess{});
  splitQ_.pop_back();
}

void Roam::clearSplitQueue() {
  for (const QueueEntry& t : splitQ_)
    if (nodes_[t.node].gen == t.gen) nodes_[t.node].queued = 0;
  splitQ_.clear();
  splitHeap_ = true;
}

// Deferred orders its (persistent) split queue by errorPx, leaves in the view frustum first:
// after a restart the drawn part converges first. The decision itself ignores the frustum.
double Roam::splitKey(const Node& n, double p) const {
  if (!vs_.valid) return p;
  Aabb box = diamondBox(n);
  box.min -= vs_.eye_m;
  box.max -= vs_.eye_m;
  return vs_.frustum.intersects(box) ? p : p * (1.0 / 64.0);
}

bool Roam::topMerge(QueueEntry* e) {
  return topValid(mergeQ_, mergeHeap_, MergeGreater{}, [&](const QueueEntry& t) {
    const Node& nd = nodes_[t.node];
    return !nd.free && nd.gen == t.gen && mergeable(t.node);
  }, e);
}

void Roam::compactSplit() {
  auto stale = [&](const QueueEntry& t) {
    const Node& nd = nodes_[t.node];
    return nd.free || nd.gen != t.gen || nd.children != kNone;
  };
  splitQ_.erase(std::remove_if(splitQ_.begin(), splitQ_.end(), stale), splitQ_.end());
  if (splitHeap_) std::make_heap(splitQ_.begin(), splitQ_.end(), SplitLess{});
}

void Roam::compactMerge() {
  auto stale = [&](const QueueEntry& t) {
    const Node& nd = nodes_[t.node];
    return nd.free || nd.gen != t.gen || !mergeable(t.node);
  };
  mergeQ_.erase(std::remove_if(mergeQ_.begin(), mergeQ_.end(), stale), mergeQ_.end());
  if (mergeHeap_) std::make_heap(mergeQ_.begin(), mergeQ_.end(), MergeGreater{});
}

// ---- update ------------------------------------------------------------------------------

// The paper's walk over last frame's tree: a split node whose diamond is within tolerance is
// enhMerged in one step (its whole subtree, and the neighbours' subtrees that would leave a
// vertex on its edges), leaves over tolerance go to the split queue (split in priority order
// by splitPhase, which continues into their children). The pool is scanned in memory order
// rather than depth-first (much faster: no pointer chasing), with the same result as the
// top-down walk: only the top-most unneeded node of a subtree is enhMerged (its parent is
// still needed, or it is a base triangle); nodes it frees are skipped when the scan reaches
// them. Errors are nested, so nothing enhMerge destroys is needed.
bool Roam::walkEnhMerge() {
  const uint32_t end = 2 * highPairs_;
  for (uint32_t n = 0; n < end; ++n) {
    const Node& nd = nodes_[n];
    if (nd.free) continue;
    ++stats_.nodesExamined;
    ++visitsUsed_;  // Deferred's unbudgeted walks count their visits too (visits = examined + created + freed)
    const double p = priority(nd, vs_);
    if (nd.children == kNone) {
      considerLeaf(n, p);
      continue;
    }
    if (p > vs_.tolerance_px) continue;
    if (nd.parent != kNone && !(priority(nodes_[nd.parent], vs_) > vs_.tolerance_px)) continue;  // not top-most
    if (!takeOp()) return false;
    collapse(n);
    ++stats_.enhMerges;
    maxSmallPx_ = std::max(maxSmallPx_, p);
  }
  return true;
}

// Mergeable diamonds are only needed when the triangle cap or the pool binds (EnhMerge mode
// coarsens with enhMerge), so the walk skips them and this pass runs on demand.
void Roam::collectMerges() {
  if (mergesCollected_) return;
  mergesCollected_ = true;
  const uint32_t end = 2 * highPairs_;
  for (uint32_t n = 0; n < end; ++n) {
    const Node& nd = nodes_[n];
    if (!nd.free && nd.children != kNone && (nd.partner == kNone || n < nd.partner) && mergeable(n))
      pushMerge(n, priority(nd, vs_));
  }
}

// Queues from the current mesh: leaves over tolerance, and every mergeable diamond once.
bool Roam::collectQueues() {
  mergesCollected_ = true;
  const uint32_t end = 2 * highPairs_;
  for (uint32_t n = 0; n < end; ++n) {
    const Node& nd = nodes_[n];
    if (nd.free) continue;
    ++stats_.nodesExamined;
    if (nd.children == kNone) {
      considerLeaf(n, priority(nd, vs_));
    } else if ((nd.partner == kNone || n < nd.partner) && mergeable(n)) {  // cheap test first
      pushMerge(n, priority(nd, vs_));
    }
  }
  return true;
}

// Classic ROAM coarsening: merge the least important diamond while it is within tolerance;
// its parent diamonds may become mergeable and join the queue.
bool Roam::mergeUnneeded() {
  QueueEntry m;
  while (topMerge(&m) && !(m.priority > vs_.tolerance_px)) {
    if (!takeOp()) return false;
    std::pop_heap(mergeQ_.begin(), mergeQ_.end(), MergeGreater{});
    mergeQ_.pop_back();
    mergeDiamond(m.node);
    ++stats_.merges;
    maxSmallPx_ = std::max(maxSmallPx_, m.priority);
    pushParentMerges(m.node);
  }
  return true;
}

// Split the highest-priority leaf (with its forced chain) while it is over tolerance. When
// the triangle cap or the pool is in the way, merge a diamond of lower priority to make room
// (Duchaineau's dual-queue rule); otherwise stop.
bool Roam::splitPhase() {
  size_t swapsLeft = nodeCap_;  // guard against cycling through forced splits
  QueueEntry s, m;
  while (topSplit(&s)) {
    if (!vs_.cullFrustum) {  // Deferred: the queue persists, its keys may be stale
      if (outOfVisits()) return false;
      ++visitsUsed_;
      ++stats_.nodesExamined;
      const double p = priority(nodes_[s.node], vs_);
      if (!(p > vs_.tolerance_px)) {  // no longer needed: back to the schedule
        popSplit();
        if (trackTouched_) recheck_.push_back(s.node);
        maxSmallPx_ = std::max(maxSmallPx_, p);
        continue;
      }
    }
    const SplitResult r = forcedSplit(s.node);
    if (r == SplitResult::Done) continue;  // s is no longer a leaf: popped as stale
    if (r == SplitResult::Budget) return false;
    collectMerges();
    if (swapsLeft > 0 && topMerge(&m) && m.priority < s.priority) {
      if (!takeOp()) return false;
      std::pop_heap(mergeQ_.begin(), mergeQ_.end(), MergeGreater{});
      mergeQ_.pop_back();
      const uint32_t partner = nodes_[m.node].partner;
      mergeDiamond(m.node);
      ++stats_.merges;
      --swapsLeft;
      considerLeaf(m.node, m.priority);
      if (partner != kNone) considerLeaf(partner, m.priority);
      pushParentMerges(m.node);
      continue;
    }
    if (r == SplitResult::Capped) stats_.triangleCapped = true;
    if (r == SplitResult::PoolFull) stats_.poolExhausted = true;
    break;
  }
  return true;
}

// Bring the mesh under the triangle cap (it may have been lowered): merge lowest first.
bool Roam::capPhase() {
  QueueEntry m;
  if (triangles_ > capTriangles_) collectMerges();
  while (triangles_ > capTriangles_ && topMerge(&m)) {
    if (!takeOp()) return false;
    std::pop_heap(mergeQ_.begin(), mergeQ_.end(), MergeGreater{});
    mergeQ_.pop_back();
    const uint32_t partner = nodes_[m.node].partner;
    mergeDiamond(m.node);
    ++stats_.merges;
    stats_.triangleCapped = true;
    considerLeaf(m.node, m.priority);
    if (partner != kNone) considerLeaf(partner, m.priority);
    pushParentMerges(m.node);
  }
  return true;
}

RoamStats Roam::update(const RoamView& view, RoamMode mode) {
  assert(view.viewportHeight_px > 0.0 && "Roam::update: viewportHeight_px must be > 0");
  assert(view.tolerance_px >= 0.0 && "Roam::update: tolerance_px must be >= 0");
  stats_ = RoamStats{};
  createdCount_ = 0;
  removedCount_ = 0;
  vs_ = makeViewState(view);
  opsLeft_ = view.maxOperations != 0 ? view.maxOperations : std::numeric_limits<uint64_t>::max();
  maxSmallPx_ = 0.0;
  visitsUsed_ = 0;
  visitBudget_ = mode == RoamMode::Deferred && view.maxVisits != 0 ? view.maxVisits : std::numeric_limits<uint64_t>::max();
  stop_ = mode == RoamMode::Deferred && view.maxVisits != 0 ? view.stop : nullptr;
  stopContext_ = view.stopContext;
  nextPoll_ = kStopPollVisits;
  stopFired_ = false;
  // Deferred keeps its split queue from update to update (leaves waiting for a split are not
  // scheduled); the other modes collect it afresh.
  if (mode != RoamMode::Deferred || !deferredQueue_) {
    clearSplitQueue();
    splitHeap_ = false;  // the collection walks append; heapified on first use
  }
  deferredQueue_ = mode == RoamMode::Deferred;
  mergeQ_.clear();
  mergeHeap_ = false;
  mergesCollected_ = false;
  capTriangles_ = view.maxTriangles != 0 ? std::min(view.maxTriangles, configMaxTriangles_) : configMaxTriangles_;

  bool ok = false;
  switch (mode) {
    case RoamMode::EnhMerge:
      ok = walkEnhMerge() && splitPhase() && capPhase();
      break;
    case RoamMode::MergeQueue:
      ok = collectQueues() && mergeUnneeded() && splitPhase() && capPhase();
      break;
    case RoamMode::Deferred:
      vs_.lateness = std::clamp(std::isfinite(view.lateness) ? view.lateness : 0.0, 0.0, 0.5);
      vs_.tolerance_px *= 1.0 - vs_.lateness;
      ok = deferredUpdate();
      stats_.unscheduled = (touched_.size() - pendingTouched_) + (recheck_.size() - pendingRecheck_);
      break;
    case RoamMode::Rebuild:
      if (!resumeRebuild_) {
        stats_.nodesFreed += static_cast<uint32_t>(liveNodes_ - baseTriangles());
        resetToBase();
      }
      ok = collectQueues() && splitPhase() && capPhase();
      break;
  }
  resumeRebuild_ = mode == RoamMode::Rebuild && !ok;
  if (mode != RoamMode::Deferred) scheduleValid_ = false;  // other modes do not keep it
  stats_.finished = ok;
  stats_.triangles = triangles_;
  stats_.visits = static_cast<uint32_t>(std::min<uint64_t>(visitsUsed_, 0xFFFFFFFFu));
  QueueEntry s;
  if (mode == RoamMode::Deferred) {
    stats_.pending = splitQ_.size() + dueQ_.countDue(centimetres(travel_m_), dueQ_.size());
    if (!ok) {
      // Interrupted: leaves were not all seen. Under a visit budget the exact bound would cost
      // a walk over every leaf, which the budget forbids: unknown.
      stats_.maxErrorPx = visitBudget_ != std::numeric_limits<uint64_t>::max() ? kInf : maxErrorPx(view);
    } else if (topSplit(&s)) {
      stats_.maxErrorPx = maxErrorPx(view);  // the cap or the pool bound: keys are not errors
    } else {
      // Unseen leaves are within tolerance (their decision cannot have changed); with
      // nothing scheduled every leaf has zero error.
      stats_.maxErrorPx = maxSmallPx_;
      if (dueQ_.size() > 0) stats_.maxErrorPx = std::max(stats_.maxErrorPx, view.tolerance_px);
    }
    return stats_;
  }
  stats_.maxErrorPx = topSplit(&s) ? std::max(maxSmallPx_, s.priority) : maxSmallPx_;
  if (!ok) stats_.maxErrorPx = maxErrorPx(view);  // interrupted: leaves were not all seen
  return stats_;
}

// ---- deferred priority recomputation -----------------------------------------------------

// How far the eye must travel before n's decision can change. A leaf is split once its
// errorPx exceeds the tolerance, i.e. once the eye is nearer to its box than
// D = e * scale / tolerance; a split node is merged once the eye is farther than D. The
// distance to a box changes by at most the eye's travel, so until the travel since now exceeds
// |d - D| the decision stands. Infinity: never changes (finest level, flat diamond).
double Roam::slack(uint32_t n) const {
  const Node& nd = nodes_[n];
  const double e = static_cast<double>(nd.bound.error_m);
  if (!vs_.valid || !(e > 0.0) || !(vs_.tolerance_px > 0.0)) return kInf;
  if (nd.children == kNone && nd.level >= maxLevel_) return kInf;
  Aabb box = diamondBox(nd);
  box.min -= vs_.eye_m;
  box.max -= vs_.eye_m;
  const double d = distanceToBox(box, glm::dvec3(0.0));
  const double threshold = e * vs_.scale / vs_.tolerance_px;
  // Split if d < threshold (errorPx > tolerance); merge if d >= threshold.
  const double s = nd.children == kNone ? d - threshold : threshold - d;
  // With lateness, a decision that is right now is looked at again no sooner than
  // lateness * threshold later (the tolerance was tightened by as much: still within it).
  return s > 0.0 ? std::max(s, vs_.lateness * threshold) : 0.0;
}

void Roam::DueQueue::clear(uint64_t now_cm) {
  size_t largest = 0;
  for (size_t i = 0; i < ring_.size(); ++i) {
    ring_[i].clear();
    if (ring_[i].capacity() > ring_[largest].capacity()) largest = i;
  }
  size_ = 0;
  cursor_ = now_cm / kBucket_cm;
  // After a restart most nodes are safe beyond the horizon and land in its last bucket: give
  // that bucket the storage of the largest one so far, so refilling it does not grow it by
  // doubling (tens of MB copied in one update at 16385^2).
  std::swap(ring_[largest], ring_[(cursor_ + kBuckets - 1) % kBuckets]);
}

void Roam::DueQueue::push(DueEntry e) {
  const uint64_t last = (cursor_ + kBuckets - 1) * kBucket_cm;  // the horizon's last bucket
  e.due_cm = std::max(std::min(e.due_cm, last), cursor_ * kBucket_cm);
  ring_[(e.due_cm / kBucket_cm) % kBuckets].push_back(e);
  ++size_;
}

size_t Roam::DueQueue::popDue(uint64_t limit_cm, std::vector<DueEntry>& out, size_t max) {
  const uint64_t limitBucket = limit_cm / kBucket_cm;
  size_t n = 0;
  // Whole buckets behind the limit, oldest first; once the eye jumped past the horizon,
  // every bucket is due.
  while (cursor_ < limitBucket) {
    auto& b = ring_[cursor_ % kBuckets];
    while (!b.empty()) {
      if (n++ == max) return max + 1;
      out.push_back(b.back());
      b.pop_back();
      --size_;
    }
    ++cursor_;
    if (size_ == 0) cursor_ = limitBucket;
  }
  // The limit's own bucket: only the entries due already.
  auto& b = ring_[cursor_ % kBuckets];
  for (size_t i = 0; i < b.size();) {
    if (b[i].due_cm > limit_cm) {
      ++i;
      continue;
    }
    if (n++ == max) return max + 1;
    out.push_back(b[i]);
    b[i] = b.back();
    b.pop_back();
    --size_;
  }
  return n;
}

size_t Roam::DueQueue::countDue(uint64_t limit_cm, size_t max) const {
  const uint64_t limitBucket = limit_cm / kBucket_cm;
  size_t n = 0;
  // Whole buckets behind the limit's own bucket (every bucket once the eye jumped past the
  // horizon, as popDue drains them), then only the entries of the limit's bucket that are due:
  // the rest of that bucket is not due yet and must not count (a finished update reported them
  // as pending).
  uint64_t b = cursor_;
  for (; b < limitBucket && b < cursor_ + kBuckets && n <= max; ++b) n += ring_[b % kBuckets].size();
  if (b == limitBucket && b < cursor_ + kBuckets)
    for (const DueEntry& e : ring_[b % kBuckets]) {
      if (n > max) break;
      n += e.due_cm <= limit_cm ? 1 : 0;
    }
  return n;
}

// Puts n where it belongs: a leaf over tolerance into the split queue, anything else into
// the schedule at the eye travel where its decision may change (or nowhere: never changes).
void Roam::scheduleOne(uint32_t n) {
  Node& nd = nodes_[n];
  if (nd.free) return;
  if (nd.children == kNone && nd.queued) return;  // waits in the split queue
  const double s = slack(n);
  if (s == kInf) return;
  if (s == 0.0 && nd.children == kNone) {
    const double p = priority(nd, vs_);
    if (p > vs_.tolerance_px) {
      pushSplit(n, splitKey(nd, p));
      if (nd.queued) return;
    }
  }
  dueQ_.push({centimetres(travel_m_ + s), n, ++nd.sched});
}

void Roam::schedule(uint32_t n) {
  if (dueQ_.size() >= dueCapacity_) {  // full of stale entries: rebuild from the live nodes
    scheduleAll();
    dropPending();  // every node is scheduled now
    return;
  }
  scheduleOne(n);
}

void Roam::scheduleAll() {
  dueQ_.clear(centimetres(travel_m_));
  const uint32_t end = 2 * highPairs_;
  for (uint32_t n = 0; n < end; ++n) scheduleOne(n);
}

// A teleport under a visit budget: drop the whole mesh in O(base triangles) (the pool is
// handed back wholesale, the schedule emptied) and refine from the base triangles again,
// over as many updates as the budget needs, visible leaves first.
void Roam::restartFromBase() {
  clearSplitQueue();
  stats_.nodesFreed += static_cast<uint32_t>(liveNodes_ - baseTriangles());
  resetToBase();
  dueQ_.clear(centimetres(travel_m_));
  stats_.restarted = true;
  for (uint32_t n = 0; n < baseTriangles(); ++n) scheduleOne(n);
}

bool Roam::deferredUpdate() {
  vs_.cullFrustum = false;
  if (dueCapacity_ == 0) {  // first Deferred update: the schedule's storage
    dueCapacity_ = nodeCap_ + nodeCap_ / 2 + 64;
    touched_.reserve(2 * nodeCap_ + 64);
    recheck_.reserve(nodeCap_ + 64);
    due_.reserve(nodeCap_ / 8 + 1024 + 1);
  }
  const bool budgeted = visitBudget_ != std::numeric_limits<uint64_t>::max();
  const bool sameView = scheduleValid_ && vs_.valid && vs_.scale == lastScale_ && vs_.tolerance_px == lastTolerance_px_ &&
                        vs_.lateness == lastLateness_;
  if (vs_.valid) {
    if (scheduleValid_) travel_m_ += glm::length(vs_.eye_m - lastEye_m_);
    lastEye_m_ = vs_.eye_m;
    lastScale_ = vs_.scale;
    lastTolerance_px_ = vs_.tolerance_px;
    lastLateness_ = vs_.lateness;
  }
  const uint64_t now_cm = centimetres(travel_m_);
  bool full = !sameView;
  bool ok = true;
  // A jump that makes most of the mesh due (a teleport) is cheaper as one linear walk, or,
  // under a visit budget, as a restart from the base triangles.
  const size_t walkInstead = liveNodes_ / 8 + 1024;
  if (!full && dueQ_.countDue(now_cm, walkInstead) > walkInstead) full = true;
  if (full) {
    dropPending();  // the walk or the restart schedules every node
  } else if (!schedulePending()) {
    return false;  // out of time before the last update's nodes were all scheduled
  }
  touchedOverflow_ = false;
  if (budgeted && full) {
    restartFromBase();
    scheduleValid_ = vs_.valid;
    full = false;
  }
  if (!full) {
    trackTouched_ = true;
    due_.clear();
    // Under a budget, leave room for the splits the queue holds.
    size_t maxPop = due_.capacity() - 1;
    if (budgeted) {
      const uint64_t left = visitBudget_ > visitsUsed_ ? visitBudget_ - visitsUsed_ : 0;
      maxPop = std::min<uint64_t>(maxPop, splitQ_.empty() ? left : left / 2);
    }
    dueQ_.popDue(now_cm, due_, maxPop);
    for (size_t i = 0; i < due_.size() && !full; ++i) {
      const DueEntry& e = due_[i];
      const Node& nd = nodes_[e.node];
      if (e.tag != nd.sched) continue;  // rescheduled or freed since
      if (stopRequested()) {  // out of time: this and the remaining due entries stay due
        for (size_t j = i; j < due_.size(); ++j)
          if (due_[j].tag == nodes_[due_[j].node].sched) dueQ_.push(due_[j]);
        ok = false;
        break;
      }
      ++stats_.nodesExamined;
      ++visitsUsed_;
      const double p = priority(nd, vs_);
      // Rescheduling happens after the loop: a node exactly at its threshold has slack 0 and
      // would be due again at once.
      if (nd.children == kNone) {
        if (p > vs_.tolerance_px && nd.level < maxLevel_) pushSplit(e.node, splitKey(nd, p));
        else recheck_.push_back(e.node);
      } else if (p > vs_.tolerance_px) {
        recheck_.push_back(e.node);
      } else if (nd.parent == kNone || priority(nodes_[nd.parent], vs_) > vs_.tolerance_px) {
        if (!takeOp()) {  // out of budget: this and the remaining due entries stay due
          for (size_t j = i; j < due_.size(); ++j)
            if (due_[j].tag == nodes_[due_[j].node].sched) dueQ_.push(due_[j]);
          ok = false;
          break;
        }
        collapse(e.node);  // enhMerge; touches the node, now a leaf
        ++stats_.enhMerges;
        maxSmallPx_ = std::max(maxSmallPx_, p);
      } else {
        recheck_.push_back(e.node);  // its ancestor is due as well and merges it
      }
    }
    if (ok && !full) ok = splitPhase() && capPhase();
    // The pop was limited by the budget and entries remain due: not finished.
    if (ok && budgeted && due_.size() == maxPop && dueQ_.countDue(now_cm, 0) > 0) ok = false;
    trackTouched_ = false;
  }
  if (full) {
    trackTouched_ = false;
    ok = walkEnhMerge() && splitPhase() && capPhase();
    scheduleAll();
    scheduleValid_ = vs_.valid;
    return ok;
  }
  if (touchedOverflow_) {
    dropPending();
    scheduleAll();
  } else if (!schedulePending()) {
    ok = false;  // out of time: the rest is scheduled first thing next update
  }
  return ok;
}

// ---- output ------------------------------------------------------------------------------

bool Roam::emittableLeaf(const Node& nd, ClampedCorners& c) const {
  if (nd.free || nd.children != kNone) return false;
  c = {std::min(nd.ax, width_ - 1), std::min(nd.ay, height_ - 1), std::min(nd.lx, width_ - 1),
       std::min(nd.ly, height_ - 1), std::min(nd.rx, width_ - 1), std::min(nd.ry, height_ - 1)};
  // Zero area once clamped onto the DEM: nothing to draw.
  return static_cast<int64_t>(c.rx - c.ax) * (c.ly - c.ay) - static_cast<int64_t>(c.ry - c.ay) * (c.lx - c.ax) != 0;
}

void Roam::enableLeafLog(size_t capacity) {
  leafLog_.assign(std::max<size_t>(capacity, 16), 0u);
  leafLogCount_ = 0;
  leafLogReset_ = true;
}

bool Roam::leafTriangle(uint32_t node, RoamTriangle* out) const {
  if (node >= 2 * static_cast<size_t>(highPairs_)) return false;
  const Node& nd = nodes_[node];
  ClampedCorners c;
  if (!emittableLeaf(nd, c)) return false;
  *out = RoamTriangle{{{nd.ax, nd.ay}, {nd.rx, nd.ry}, {nd.lx, nd.ly}}};
  return true;
}

template <class F>
void Roam::forEachLeaf(F&& f) const {
  const uint32_t end = 2 * highPairs_;
  for (uint32_t n = 0; n < end; ++n) {
    ClampedCorners c;
    if (emittableLeaf(nodes_[n], c)) f(n, nodes_[n]);
  }
}

size_t Roam::emitLeafNodes(std::span<uint32_t> out) const {
  assert(out.size() >= triangleCount() && "Roam::emitLeafNodes: out smaller than triangleCount()");
  size_t count = 0;
  forEachLeaf([&](uint32_t n, const Node&) { out[count++] = n; });
  return count;
}

size_t Roam::emitTriangles(std::span<RoamTriangle> out) const {
  assert(out.size() >= triangleCount() && "Roam::emitTriangles: out smaller than triangleCount()");
  size_t count = 0;
  forEachLeaf([&](uint32_t, const Node& nd) {
    out[count++] = RoamTriangle{{{nd.ax, nd.ay}, {nd.rx, nd.ry}, {nd.lx, nd.ly}}};
  });
  return count;
}

size_t Roam::emitVisible(const Camera& camera, std::span<RoamTriangle> out) const {
  assert(out.size() >= triangleCount() && "Roam::emitVisible: out smaller than triangleCount()");
  const Frustum frustum = makeFrustum(camera);
  const glm::dvec3 eye = camera.eye_m - origin_m_;
  size_t count = 0;
  // Depth-first from the base triangles. An inner node's diamond box holds all its
  // descendants' geometry (nested boxes), so a subtree whose box is outside is skipped whole.
  // The stack holds at most (levels + 1) pending siblings plus the base triangles.
  uint32_t stack[512];
  const uint32_t base = static_cast<uint32_t>(baseTriangles());
  for (uint32_t r = 0; r < base; ++r) {
    size_t top = 0;
    stack[top++] = r;
    while (top > 0) {
      const uint32_t n = stack[--top];
      const Node& nd = nodes_[n];
      if (nd.children != kNone) {
        Aabb box = diamondBox(nd);
        box.min -= eye;
        box.max -= eye;
        if (!frustum.intersects(box)) continue;
        stack[top++] = nd.children + 1;
        stack[top++] = nd.children;
        continue;
      }
      ClampedCorners c;
      if (!emittableLeaf(nd, c)) continue;
      const auto [ax, ay, lx, ly, rx, ry] = c;
      // The leaf's own xy extent; its heights lie in the parent diamond's nested range (the
      // leaf's corners are the parent's apex, hypotenuse end and split vertex), already in
      // cache: no height look-ups (a large DEM's heights are far apart in memory).
      Aabb box;
      box.min = glm::dvec3(std::min({ax, lx, rx}) * spacing_m_, std::min({ay, ly, ry}) * spacing_m_, 0.0);
      box.max = glm::dvec3(std::max({ax, lx, rx}) * spacing_m_, std::max({ay, ly, ry}) * spacing_m_, 0.0);
      if (nd.parent != kNone) {
        const Bound& b = nodes_[nd.parent].bound;
        box.min.z = static_cast<double>(zMin_m_) + (b.zLo - 0.5) * zStep_m_;
        box.max.z = static_cast<double>(zMin_m_) + (b.zHi + 0.5) * zStep_m_;
      } else {
        box.min.z = static_cast<double>(std::min({heightAt(ax, ay), heightAt(lx, ly), heightAt(rx, ry)}));
        box.max.z = static_cast<double>(std::max({heightAt(ax, ay), heightAt(lx, ly), heightAt(rx, ry)}));
      }
      box.min -= eye;
      box.max -= eye;
      if (!frustum.intersects(box)) continue;
      out[count++] = RoamTriangle{{{nd.ax, nd.ay}, {nd.rx, nd.ry}, {nd.lx, nd.ly}}};
    }
  }
  return count;
}

namespace {
int64_t cross64(int64_t ax, int64_t ay, int64_t bx, int64_t by, int64_t cx, int64_t cy) {
  return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
}
}  // namespace

uint32_t Roam::leafNodeAt(int64_t x3, int64_t y3) const {
  x3 = std::clamp<int64_t>(x3, 0, 3 * static_cast<int64_t>(px_ - 1));
  y3 = std::clamp<int64_t>(y3, 0, 3 * static_cast<int64_t>(py_ - 1));
  auto inside = [&](const Node& nd) {  // counter-clockwise (a, r, l), coordinates in thirds
    return cross64(3 * nd.ax, 3 * nd.ay, 3 * nd.rx, 3 * nd.ry, x3, y3) >= 0 &&
           cross64(3 * nd.rx, 3 * nd.ry, 3 * nd.lx, 3 * nd.ly, x3, y3) >= 0 &&
           cross64(3 * nd.lx, 3 * nd.ly, 3 * nd.ax, 3 * nd.ay, x3, y3) >= 0;
  };
  // The base square, then down the tree: the child whose triangle holds the point.
  const int64_t side3 = 3 * static_cast<int64_t>(rootSide_);
  const int qi = static_cast<int>(std::min<int64_t>(x3 / side3, rootsX_ - 1));
  const int qj = static_cast<int>(std::min<int64_t>(y3 / side3, rootsY_ - 1));
  uint32_t n = 2u * static_cast<uint32_t>(qj * rootsX_ + qi);
  if (!inside(nodes_[n])) ++n;
  while (nodes_[n].children != kNone) n = inside(nodes_[nodes_[n].children]) ? nodes_[n].children : nodes_[n].children + 1;
  return n;
}

RoamTriangle Roam::leafAt(int64_t x3, int64_t y3) const {
  const Node& nd = nodes_[leafNodeAt(x3, y3)];
  return RoamTriangle{{{nd.ax, nd.ay}, {nd.rx, nd.ry}, {nd.lx, nd.ly}}};
}

double Roam::meshHeight(int x, int y) const {
  // The mesh as drawn: corners clamped onto the DEM. Where leaves reach beyond the DEM's east /
  // north edge, a clamped leaf need not hold the point the unclamped one holds, so the walk
  // keeps to clamped triangles: the clamped children of a diamond tile its clamped halves (the
  // drawn mesh tiles the DEM after every split), so one of the four holds the point.
  const int64_t cx = std::clamp(x, 0, width_ - 1), cy = std::clamp(y, 0, height_ - 1);
  struct Weights {
    int64_t area, wa, wr, wl;
  };
  auto weights = [&](const Node& nd, Weights& w) {
    const int64_t ax = std::min(nd.ax, width_ - 1), ay = std::min(nd.ay, height_ - 1);
    const int64_t rx = std::min(nd.rx, width_ - 1), ry = std::min(nd.ry, height_ - 1);
    const int64_t lx = std::min(nd.lx, width_ - 1), ly = std::min(nd.ly, height_ - 1);
    w.area = cross64(ax, ay, rx, ry, lx, ly);
    w.wa = cross64(rx, ry, lx, ly, cx, cy);
    w.wr = cross64(lx, ly, ax, ay, cx, cy);
    w.wl = cross64(ax, ay, rx, ry, cx, cy);
    return w.area > 0 && w.wa >= 0 && w.wr >= 0 && w.wl >= 0;  // counter-clockwise when not zero
  };
  uint32_t n = kNone;
  Weights w{};
  // The base square holding the point (its clamped halves tile the square's clamped part).
  const int qi = static_cast<int>(std::min<int64_t>(cx / rootSide_, rootsX_ - 1));
  const int qj = static_cast<int>(std::min<int64_t>(cy / rootSide_, rootsY_ - 1));
  const uint32_t root = 2u * static_cast<uint32_t>(qj * rootsX_ + qi);
  for (uint32_t r = root; r < root + 2 && n == kNone; ++r)
    if (weights(nodes_[r], w)) n = r;
  while (n != kNone && nodes_[n].children != kNone) {
    const uint32_t p = nodes_[n].partner;
    uint32_t next = kNone;
    for (const uint32_t z : {n, p}) {
      if (z == kNone || nodes_[z].children == kNone || next != kNone) continue;
      for (uint32_t c = nodes_[z].children; c < nodes_[z].children + 2 && next == kNone; ++c)
        if (weights(nodes_[c], w)) next = c;
    }
    n = next;
  }
  if (n == kNone) {  // not expected (the clamped mesh tiles the DEM): the leaf over the grid point
    const Node& nd = nodes_[leafNodeAt(3 * static_cast<int64_t>(x), 3 * static_cast<int64_t>(y))];
    x = std::clamp(x, 0, px_ - 1);
    y = std::clamp(y, 0, py_ - 1);
    const double a = static_cast<double>(cross64(nd.ax, nd.ay, nd.rx, nd.ry, nd.lx, nd.ly));
    const double wa = static_cast<double>(cross64(nd.rx, nd.ry, nd.lx, nd.ly, x, y)) / a;
    const double wr = static_cast<double>(cross64(nd.lx, nd.ly, nd.ax, nd.ay, x, y)) / a;
    return wa * static_cast<double>(heightAt(nd.ax, nd.ay)) + wr * static_cast<double>(heightAt(nd.rx, nd.ry)) +
           (1.0 - wa - wr) * static_cast<double>(heightAt(nd.lx, nd.ly));
  }
  weights(nodes_[n], w);  // n's own weights (the loop may have tested others last)
  const Node& nd = nodes_[n];
  const double area = static_cast<double>(w.area);
  return (static_cast<double>(w.wa) * static_cast<double>(heightAt(nd.ax, nd.ay)) +
          static_cast<double>(w.wr) * static_cast<double>(heightAt(nd.rx, nd.ry)) +
          static_cast<double>(w.wl) * static_cast<double>(heightAt(nd.lx, nd.ly))) /
         area;
}

double Roam::maxErrorPx(const RoamView& view) const {
  const ViewState vs = makeViewState(view);
  double worst = 0.0;
  const uint32_t end = 2 * highPairs_;
  for (uint32_t n = 0; n < end; ++n) {
    const Node& nd = nodes_[n];
    if (nd.free || nd.children != kNone) continue;
    worst = std::max(worst, priority(nd, vs));
  }
  return worst;
}

// ---- validation --------------------------------------------------------------------------

bool Roam::validate(std::string* why) const {
  auto fail = [&](const std::string& msg) {
    if (why) *why = msg;
    return false;
  };
  auto nodeName = [&](uint32_t n) {
    const Node& nd = nodes_[n];
    return "node " + std::to_string(n) + " L" + std::to_string(nd.level) + " apex (" + std::to_string(nd.ax) + "," +
           std::to_string(nd.ay) + ") l (" + std::to_string(nd.lx) + "," + std::to_string(nd.ly) + ") r (" +
           std::to_string(nd.rx) + "," + std::to_string(nd.ry) + ")";
  };
  auto onBorder = [&](int x0, int y0, int x1, int y1) {
    return (x0 == x1 && (x0 == 0 || x0 == px_ - 1)) || (y0 == y1 && (y0 == 0 || y0 == py_ - 1));
  };
  const uint32_t end = 2 * highPairs_;
  const uint32_t base = static_cast<uint32_t>(baseTriangles());
  size_t live = 0, leaves = 0;
  for (uint32_t n = 0; n < end; ++n) {
    const Node& nd = nodes_[n];
    if (nd.free) continue;
    ++live;
    if (nd.level > maxLevel_) return fail(nodeName(n) + ": level above the finest");
    // Parent / child links and geometry.
    if (n < base) {
      if (nd.parent != kNone || nd.level != 0) return fail(nodeName(n) + ": base triangle with a parent");
    } else {
      if (nd.parent == kNone || nd.parent >= end || nodes_[nd.parent].free) return fail(nodeName(n) + ": bad parent");
      const Node& p = nodes_[nd.parent];
      if (p.children != (n & ~1u) || p.level + 1 != nd.level) return fail(nodeName(n) + ": parent does not own it");
      const int mx = (p.lx + p.rx) / 2, my = (p.ly + p.ry) / 2;
      const bool geo = (n & 1u) == 0 ? (nd.ax == mx && nd.ay == my && nd.lx == p.ax && nd.ly == p.ay && nd.rx == p.lx && nd.ry == p.ly)
                                     : (nd.ax == mx && nd.ay == my && nd.lx == p.rx && nd.ly == p.ry && nd.rx == p.ax && nd.ry == p.ay);
      if (!geo) return fail(nodeName(n) + ": geometry differs from its parent's split");
    }
    if (nd.children != kNone) {
      if (nd.children >= end || (nd.children & 1u) != 0) return fail(nodeName(n) + ": bad children index");
      for (uint32_t c = nd.children; c < nd.children + 2; ++c) {
        if (nodes_[c].free || nodes_[c].parent != n) return fail(nodeName(n) + ": child not linked back");
      }
    } else {
      ++leaves;
    }
    // Partner (same-level base neighbour): symmetric, same hypotenuse, split together.
    if (nd.partner != kNone) {
      if (nd.partner >= end || nodes_[nd.partner].free) return fail(nodeName(n) + ": partner freed");
      const Node& q = nodes_[nd.partner];
      if (q.partner != n) return fail(nodeName(n) + ": partner link not symmetric");
      if (q.level != nd.level || q.lx != nd.rx || q.ly != nd.ry || q.rx != nd.lx || q.ry != nd.ly)
        return fail(nodeName(n) + ": partner does not share the hypotenuse");
      if ((q.children == kNone) != (nd.children == kNone)) return fail(nodeName(n) + ": diamond half split");
    } else if (nd.children != kNone && !onBorder(nd.lx, nd.ly, nd.rx, nd.ry)) {
      return fail(nodeName(n) + ": split without its base neighbour");
    }
    // Leg neighbours (derived): symmetric and mirrored, or the leg lies on the border.
    for (int side = 0; side < 2; ++side) {
      const int ex = side == 0 ? nd.lx : nd.rx, ey = side == 0 ? nd.ly : nd.ry;
      const uint32_t o = legNode(n, side);
      if (o == kNone) {
        if (!onBorder(nd.ax, nd.ay, ex, ey)) return fail(nodeName(n) + ": interior leg without a neighbour");
        continue;
      }
      if (o >= end || nodes_[o].free) return fail(nodeName(n) + ": leg neighbour freed");
      const Node& q = nodes_[o];
      const int qx = side == 0 ? q.rx : q.lx, qy = side == 0 ? q.ry : q.ly;
      if (q.level != nd.level || q.ax != nd.ax || q.ay != nd.ay || qx != ex || qy != ey || legNode(o, 1 - side) != n)
        return fail(nodeName(n) + ": leg neighbour not mirrored / symmetric: " + nodeName(o));
    }
  }
  if (live != liveNodes_) return fail("live node count " + std::to_string(live) + " != " + std::to_string(liveNodes_));
  if (leaves != triangles_) return fail("leaf count " + std::to_string(leaves) + " != " + std::to_string(triangles_));
  // Every live node reachable from the base triangles.
  {
    size_t reached = 0;
    std::vector<uint32_t> todo;
    for (uint32_t r = 0; r < base; ++r) todo.push_back(r);
    while (!todo.empty()) {
      const uint32_t n = todo.back();
      todo.pop_back();
      ++reached;
      if (nodes_[n].children != kNone) {
        todo.push_back(nodes_[n].children);
        todo.push_back(nodes_[n].children + 1);
      }
    }
    if (reached != live) return fail("unreachable nodes: " + std::to_string(live - reached));
  }
  // Leaf edges: each interior edge exactly twice, border edges once; levels differ by <= 1;
  // areas sum to the grid (so there are no holes, overlaps or T-junctions).
  std::map<std::pair<uint64_t, uint64_t>, std::pair<int, int>> edges;  // -> (count, level)
  int64_t area2 = 0;
  for (uint32_t n = 0; n < end; ++n) {
    const Node& nd = nodes_[n];
    if (nd.free || nd.children != kNone) continue;
    const int xs[3] = {nd.ax, nd.rx, nd.lx}, ys[3] = {nd.ay, nd.ry, nd.ly};
    const int64_t a2 = static_cast<int64_t>(xs[1] - xs[0]) * (ys[2] - ys[0]) - static_cast<int64_t>(ys[1] - ys[0]) * (xs[2] - xs[0]);
    if (a2 <= 0) return fail(nodeName(n) + ": not counter-clockwise");
    area2 += a2;
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3;
      const uint64_t va = static_cast<uint64_t>(ys[i]) * static_cast<uint64_t>(px_) + static_cast<uint64_t>(xs[i]);
      const uint64_t vb = static_cast<uint64_t>(ys[j]) * static_cast<uint64_t>(px_) + static_cast<uint64_t>(xs[j]);
      auto& e = edges[{std::min(va, vb), std::max(va, vb)}];
      if (e.first == 1 && std::abs(e.second - nd.level) > 1)
        return fail(nodeName(n) + ": neighbour across an edge differs by more than one level");
      ++e.first;
      e.second = nd.level;
      if (e.first > 2) return fail(nodeName(n) + ": edge shared by more than two leaves");
    }
  }
  if (area2 != 2 * static_cast<int64_t>(px_ - 1) * (py_ - 1)) return fail("leaf areas do not cover the grid");
  for (const auto& [key, e] : edges) {
    if (e.first == 2) continue;
    const int x0 = static_cast<int>(key.first % static_cast<uint64_t>(px_)), y0 = static_cast<int>(key.first / static_cast<uint64_t>(px_));
    const int x1 = static_cast<int>(key.second % static_cast<uint64_t>(px_)), y1 = static_cast<int>(key.second / static_cast<uint64_t>(px_));
    if (!onBorder(x0, y0, x1, y1)) {
      return fail("T-junction or crack: interior edge (" + std::to_string(x0) + "," + std::to_string(y0) + ")-(" +
                  std::to_string(x1) + "," + std::to_string(y1) + ") used by one leaf");
    }
  }
  return true;
}

double nearestTriangleBox(std::span<const RoamTriangle> triangles, std::span<const float> heights_m, int width, int height,
                          double spacing_m, const glm::dvec3& point, double enough) {
  double nearest = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < triangles.size() && nearest >= enough; ++i) {
    Aabb box{glm::dvec3(std::numeric_limits<double>::infinity()), glm::dvec3(-std::numeric_limits<double>::infinity())};
    for (const RoamVertex& v : triangles[i].v) {
      const int x = std::clamp(v.x, 0, width - 1), y = std::clamp(v.y, 0, height - 1);
      const glm::dvec3 at(x * spacing_m, y * spacing_m,
                          static_cast<double>(heights_m[static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x)]));
      box.min = glm::min(box.min, at);
      box.max = glm::max(box.max, at);
    }
    nearest = std::min(nearest, distanceToBox(box, point));
  }
  return nearest;
}

}  // namespace ig::lod
