#include "lod/geomorph.h"

#include <algorithm>
#include <cmath>

namespace ig::lod {

Geomorph::Geomorph(size_t capacity, double morph_s) : morph_s_(morph_s), capacity_(capacity) {
  size_t n = 16;
  while (n < 2 * capacity) n <<= 1;
  table_.assign(n, Entry{0, 0.0, 0.0f, false});
  scratch_.assign(n, Entry{0, 0.0, 0.0f, false});
}

size_t Geomorph::slot(uint64_t k) const {
  const size_t mask = table_.size() - 1;
  size_t i = static_cast<size_t>((k * 0x9E3779B97F4A7C15ull) >> 20) & mask;
  while (table_[i].key != 0 && table_[i].key != k) i = (i + 1) & mask;
  return i;
}

void Geomorph::start(int x, int y, float startHeight_m, double now_s) {
  // Off, full, or a time that is not a number (its morph would never end and hold its slot for
  // good): the vertex pops.
  if (morph_s_ <= 0.0 || live_ >= capacity_ || !std::isfinite(now_s)) return;
  const uint64_t k = key(x, y);
  const size_t i = slot(k);
  if (table_[i].key == k) return;
  table_[i] = Entry{k, now_s, startHeight_m, false};
  ++live_;
  lastEnd_s_ = std::max(lastEnd_s_, now_s + morph_s_);
}

void Geomorph::startSplits(const Roam& roam, std::span<const float> heights_m, int samplesX, int samplesY, double now_s) {
  if (morph_s_ <= 0.0 || !std::isfinite(now_s)) return;
  auto sample = [&](int x, int y) {
    x = std::clamp(x, 0, samplesX - 1);
    y = std::clamp(y, 0, samplesY - 1);
    return heights_m[static_cast<size_t>(y) * static_cast<size_t>(samplesX) + static_cast<size_t>(x)];
  };
  // In creation order: a vertex's split ends are vertices of the triangle it splits, so they
  // are in the mesh before it (created by an earlier update, or listed before it).
  for (const RoamVertex& v : roam.createdVertices()) {
    RoamVertex a, b;
    if (!roam.splitEnds(v.x, v.y, a, b)) continue;
    const double ha = static_cast<double>(height(a.x, a.y, sample(a.x, a.y), now_s));
    const double hb = static_cast<double>(height(b.x, b.y, sample(b.x, b.y), now_s));
    const float from = static_cast<float>(0.5 * (ha + hb));
    // A vertex that still has the morph of an earlier life (created, merged away, created
    // again within morph_s) was not drawn until now: its morph starts again from here. (A
    // vertex is listed twice for a diamond split, at the same time: the first start holds.)
    const uint64_t k = key(v.x, v.y);
    Entry& e = table_[slot(k)];
    if (e.key == k && e.start_s != now_s) {
      e = Entry{k, now_s, from, false};
      lastEnd_s_ = std::max(lastEnd_s_, now_s + morph_s_);
      continue;
    }
    start(v.x, v.y, from, now_s);
  }
}

void Geomorph::startOut(int x, int y, float targetHeight_m, double now_s) {
  if (morph_s_ <= 0.0 || !std::isfinite(now_s)) return;
  const uint64_t k = key(x, y);
  const size_t i = slot(k);
  if (table_[i].key != k) {
    if (live_ >= capacity_) return;  // full: the vertex pops
    ++live_;
  }
  table_[i] = Entry{k, now_s, targetHeight_m, true};
  lastEnd_s_ = std::max(lastEnd_s_, now_s + morph_s_);
}

float Geomorph::height(int x, int y, float trueHeight_m, double now_s) const {
  if (live_ == 0) return trueHeight_m;
  const Entry& e = table_[slot(key(x, y))];
  if (e.key == 0) return trueHeight_m;
  const double t = std::clamp((now_s - e.start_s) / morph_s_, 0.0, 1.0);
  if (e.out)
    return static_cast<float>(static_cast<double>(trueHeight_m) +
                              (static_cast<double>(e.startHeight_m) - static_cast<double>(trueHeight_m)) * t);
  return static_cast<float>(static_cast<double>(e.startHeight_m) +
                            (static_cast<double>(trueHeight_m) - static_cast<double>(e.startHeight_m)) * t);
}

double Geomorph::progress(int x, int y, double now_s) const {
  if (live_ == 0) return -1.0;
  const Entry& e = table_[slot(key(x, y))];
  if (e.key == 0) return -1.0;
  return std::clamp((now_s - e.start_s) / morph_s_, 0.0, 1.0);
}

void Geomorph::expire(double now_s) {
  if (live_ == 0) return;
  bool any = false;
  for (const Entry& e : table_) any = any || (e.key != 0 && now_s >= e.start_s + morph_s_);
  if (!any) return;
  // Rebuild without the finished entries (keeps linear probing valid without tombstones).
  std::fill(scratch_.begin(), scratch_.end(), Entry{0, 0.0, 0.0f, false});
  table_.swap(scratch_);
  live_ = 0;
  for (const Entry& e : scratch_) {
    if (e.key == 0 || now_s >= e.start_s + morph_s_) continue;
    table_[slot(e.key)] = e;
    ++live_;
  }
}

// ---- MorphOut -----------------------------------------------------------------------------

namespace {

// Twice the area of t in grid units (exact).
int64_t area2(const RoamTriangle& t) {
  const int64_t ax = t.v[1].x - t.v[0].x, ay = t.v[1].y - t.v[0].y;
  const int64_t bx = t.v[2].x - t.v[0].x, by = t.v[2].y - t.v[0].y;
  const int64_t c = ax * by - ay * bx;
  return c < 0 ? -c : c;
}

bool same(const RoamTriangle& a, const RoamTriangle& b) {
  for (int i = 0; i < 3; ++i)
    if (a.v[i].x != b.v[i].x || a.v[i].y != b.v[i].y) return false;
  return true;
}

}  // namespace

MorphOut::MorphOut(size_t capacityTriangles, double morph_s)
    : morph_s_(morph_s),
      capacity_(capacityTriangles),
      ghosts_(capacityTriangles),
      ghostCover_(capacityTriangles),
      covers_(capacityTriangles),
      released_(capacityTriangles),
      remap_(capacityTriangles),
      area_(capacityTriangles),
      vertices_(capacityTriangles, morph_s) {}

size_t MorphOut::findCover(const RoamTriangle& t) const {
  for (size_t i = 0; i < coverCount_; ++i)
    if (same(covers_[i].tri, t)) return i;
  return coverCount_;
}

bool MorphOut::hidden(const RoamTriangle& t) const {
  const size_t c = findCover(t);
  return c < coverCount_ && covers_[c].hide;
}

float MorphOut::height(int x, int y, float trueHeight_m, double now_s) const {
  return vertices_.height(x, y, trueHeight_m, now_s);
}

MorphOut::Stats MorphOut::update(std::span<const RoamTriangle> left, std::span<const RoamTriangle> coverOf,
                                 std::span<const RoamVertex> removedVertices, std::span<const float> targetHeights_m,
                                 double now_s) {
  Stats st;
  // Covers that left the mesh (the region changed again): their ghosts go now.
  if (coverCount_ > 0 && left.size() * coverCount_ <= kMaxPairTests) {
    for (const RoamTriangle& t : left) {
      const size_t c = findCover(t);
      if (c == coverCount_) continue;
      covers_[c].end_s = -1e300;  // dropped below
    }
    size_t keepC = 0;
    for (size_t c = 0; c < coverCount_; ++c) {
      remap_[c] = covers_[c].end_s == -1e300 ? UINT32_MAX : static_cast<uint32_t>(keepC);
      if (remap_[c] != UINT32_MAX) covers_[keepC++] = covers_[c];
    }
    size_t keepG = 0;
    for (size_t g = 0; g < ghostCount_; ++g) {
      const uint32_t c = remap_[ghostCover_[g]];
      if (c == UINT32_MAX) {
        ++st.ghostsDropped;
        continue;
      }
      ghosts_[keepG] = ghosts_[g];
      ghostCover_[keepG++] = c;
    }
    coverCount_ = keepC;
    ghostCount_ = keepG;
  }
  if (morph_s_ <= 0.0 || removedVertices.empty()) return st;
  if (left.size() * (coverCount_ + 1) > kMaxPairTests || coverOf.size() < left.size()) {
    st.popped = left.size();
    return st;
  }
  for (size_t i = 0; i < removedVertices.size() && i < targetHeights_m.size(); ++i)
    vertices_.startOut(removedVertices[i].x, removedVertices[i].y, targetHeights_m[i], now_s);
  // Ghosts: the triangles that left with a vertex removed by a merge (now morphing out).
  const size_t firstCover = coverCount_, firstGhost = ghostCount_;
  size_t lastCover = coverCount_;
  for (size_t i = 0; i < left.size(); ++i) {
    const RoamTriangle& t = left[i];
    bool merged = false;
    for (const RoamVertex& v : t.v) merged = merged || vertices_.contains(v.x, v.y);
    if (!merged) continue;
    if (ghostCount_ == capacity_) {
      ++st.popped;
      continue;
    }
    size_t c = lastCover < coverCount_ && same(covers_[lastCover].tri, coverOf[i]) ? lastCover : findCover(coverOf[i]);
    if (c == coverCount_) {
      if (coverCount_ == capacity_) {
        ++st.popped;
        continue;
      }
      covers_[coverCount_++] = Cover{coverOf[i], now_s + morph_s_, true};
    }
    lastCover = c;
    ghosts_[ghostCount_] = t;
    ghostCover_[ghostCount_++] = static_cast<uint32_t>(c);
    ++st.ghostsAdded;
  }
  // A new cover is hidden only if its ghosts tile it. Where `left` lacks some of the triangles
  // under it (a renderer that passes only the triangles it drew, the cover reaching beyond
  // them), hiding it would open a hole: it is drawn under its ghosts instead (no hole, and no
  // crack against its neighbours' ghosts; where a ghost lies below it, that part pops).
  if (coverCount_ > firstCover) {
    for (size_t c = firstCover; c < coverCount_; ++c) area_[c] = 0;
    for (size_t g = firstGhost; g < ghostCount_; ++g)
      if (ghostCover_[g] >= firstCover) area_[ghostCover_[g]] += area2(ghosts_[g]);
    for (size_t c = firstCover; c < coverCount_; ++c) {
      covers_[c].hide = area_[c] == area2(covers_[c].tri);
      st.untiled += covers_[c].hide ? 0 : 1;
    }
  }
  return st;
}

std::span<const RoamTriangle> MorphOut::expire(double now_s) {
  size_t released = 0, keepC = 0;
  for (size_t c = 0; c < coverCount_; ++c) {
    if (now_s >= covers_[c].end_s) {
      released_[released++] = covers_[c].tri;
      remap_[c] = UINT32_MAX;
    } else {
      remap_[c] = static_cast<uint32_t>(keepC);
      covers_[keepC++] = covers_[c];
    }
  }
  if (released > 0) {
    size_t keepG = 0;
    for (size_t g = 0; g < ghostCount_; ++g) {
      const uint32_t c = remap_[ghostCover_[g]];
      if (c == UINT32_MAX) continue;
      ghosts_[keepG] = ghosts_[g];
      ghostCover_[keepG++] = c;
    }
    ghostCount_ = keepG;
    coverCount_ = keepC;
  }
  vertices_.expire(now_s);
  return {released_.data(), released};
}

}  // namespace ig::lod
