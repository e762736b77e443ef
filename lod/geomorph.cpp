#include "lod/geomorph.h"

#include <algorithm>
#include <cmath>

namespace ig::lod {

Geomorph::Geomorph(size_t capacity, double morph_s, bool splits) : morph_s_(morph_s), capacity_(capacity) {
  size_t n = 16;
  while (n < 2 * capacity) n <<= 1;
  table_.assign(n, Entry{0, 0.0, 0.0f, false});
  scratch_.assign(n, Entry{0, 0.0, 0.0f, false});
  if (splits) {
    size_t c = 16;
    while (c < 2 * std::min(capacity, Roam::kCreatedCapacity)) c <<= 1;
    created_.assign(c, NewVertex{0, 0});
  }
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
  if (morph_s_ <= 0.0 || !std::isfinite(now_s) || samplesX < 1 || samplesY < 1) return;
  if (samplesX != demX_ || samplesY != demY_) {
    // Keys are the DEM samples vertices are drawn at: entries keyed for another DEM are void.
    if (live_ > 0) {
      std::fill(table_.begin(), table_.end(), Entry{0, 0.0, 0.0f, false});
      live_ = 0;
    }
    demX_ = samplesX;
    demY_ = samplesY;
  }
  auto clamped = [&](const RoamVertex& v) {
    return RoamVertex{std::clamp(v.x, 0, samplesX - 1), std::clamp(v.y, 0, samplesY - 1)};
  };
  // The height vertex v is drawn with now (its DEM sample's height, or its morph's).
  auto drawn = [&](const RoamVertex& v) {
    const RoamVertex c = clamped(v);
    const float h = heights_m[static_cast<size_t>(c.y) * static_cast<size_t>(samplesX) + static_cast<size_t>(c.x)];
    return static_cast<double>(height(v.x, v.y, h, now_s));
  };
  auto cross = [](const RoamVertex& o, const RoamVertex& p, const RoamVertex& q) {
    return static_cast<int64_t>(p.x - o.x) * (q.y - o.y) - static_cast<int64_t>(p.y - o.y) * (q.x - o.x);
  };
  // The vertices created so far in this update (padded grid), to tell the triangles that were
  // drawn before it (their apex is older) from those this update made.
  // Entries of earlier calls (another stamp) are empty.
  if (++stamp_ == 0) {
    std::fill(created_.begin(), created_.end(), NewVertex{0, 0});
    stamp_ = 1;
  }
  const size_t newMask = created_.empty() ? 0 : created_.size() - 1;
  size_t newCount = 0;
  auto newSlot = [&](const RoamVertex& v) {
    const uint64_t k = rawKey(v.x, v.y);
    size_t i = static_cast<size_t>((k * 0x9E3779B97F4A7C15ull) >> 20) & newMask;
    while (created_[i].stamp == stamp_ && created_[i].key != k) i = (i + 1) & newMask;
    return i;
  };
  auto isNew = [&](const RoamVertex& v) { return !created_.empty() && created_[newSlot(v)].stamp == stamp_; };
  // The surface drawn before this update at DEM point c, which a new vertex v is drawn at. The
  // triangle of v's diamond (hypotenuse a-b, apex on either side) holding c once clamped onto
  // the DEM: if its apex is older than this update, it was drawn (a leaf until v split it);
  // else it is a child this update made of the diamond split at its apex, whose triangles hold
  // it (clamped triangles tile the diamond's before and after a split): look there. Inside
  // the DEM this is the midpoint of a and b as drawn; where diamonds reach beyond the DEM's
  // east / north edge, c need not be the midpoint of a's and b's clamped points, nor lie in a
  // triangle drawn before. False if only zero-area (never drawn) triangles hold c.
  auto drawnBefore = [&](RoamVertex d, const RoamVertex& c, double& z) {
    for (int guard = 0; guard < 64; ++guard) {
      RoamVertex a, b;
      if (!roam.splitEnds(d.x, d.y, a, b)) return false;
      const RoamVertex ca = clamped(a), cb = clamped(b);
      const int dx = (b.x - a.x) / 2, dy = (b.y - a.y) / 2;
      RoamVertex up{-1, -1};  // a new apex whose diamond holds c
      for (const RoamVertex apex : {RoamVertex{d.x - dy, d.y + dx}, RoamVertex{d.x + dy, d.y - dx}}) {
        if (apex.x < 0 || apex.y < 0 || apex.x >= roam.gridWidth() || apex.y >= roam.gridHeight()) continue;
        const RoamVertex cp = clamped(apex);
        const int64_t area = cross(ca, cb, cp);
        // Barycentric weights of c (exact in integers; the sign of the area normalised).
        const int64_t wp = cross(ca, cb, c), wa = cross(cb, cp, c), wb = cross(cp, ca, c);
        const bool inside = area > 0 ? (wp >= 0 && wa >= 0 && wb >= 0)
                                     : area < 0 ? (wp <= 0 && wa <= 0 && wb <= 0) : (wp == 0 && wa == 0 && wb == 0);
        if (!inside) continue;
        if (isNew(apex)) {
          if (up.x < 0 || area != 0) up = apex;  // a half that is drawn once clamped first
          continue;
        }
        if (area == 0) continue;  // zero area once clamped: never drawn
        z = (static_cast<double>(wa) * drawn(a) + static_cast<double>(wb) * drawn(b) + static_cast<double>(wp) * drawn(apex)) /
            static_cast<double>(area);
        return true;
      }
      if (up.x < 0) return false;
      d = up;
    }
    return false;
  };
  // In creation order: a vertex's split ends are vertices of the triangle it splits, so they
  // are in the mesh before it (created by an earlier update, or listed before it).
  for (const RoamVertex& v : roam.createdVertices()) {
    double from = 0.0;
    const bool drawnThere = drawnBefore(v, clamped(v), from);
    if (newCount + 1 < created_.size() / 2) {
      const size_t i = newSlot(v);
      if (created_[i].stamp != stamp_) {
        created_[i] = NewVertex{rawKey(v.x, v.y), stamp_};
        ++newCount;
      }
    }
    // Only zero-area triangles hold it: nothing was drawn at its point that it could start
    // from (a vertex beyond the DEM whose point a vertex drawn so far may share): no morph.
    if (!drawnThere) continue;
    // A vertex that still has the morph of an earlier life (created, merged away, created
    // again within morph_s) was not drawn until now: its morph starts again from here. (A
    // vertex is listed twice for a diamond split, at the same time: the first start holds.)
    const uint64_t k = key(v.x, v.y);
    Entry& e = table_[slot(k)];
    if (e.key == k && e.start_s != now_s) {
      e = Entry{k, now_s, static_cast<float>(from), false};
      lastEnd_s_ = std::max(lastEnd_s_, now_s + morph_s_);
      continue;
    }
    start(v.x, v.y, static_cast<float>(from), now_s);
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
  const double t = morphFraction(now_s, e.start_s);
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
  return morphFraction(now_s, e.start_s);
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
      vertices_(capacityTriangles, morph_s, false) {}

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
  // A time that is not a number: the merges pop (a cover ending at NaN would stay hidden and
  // its ghosts drawn for good).
  if (morph_s_ <= 0.0 || removedVertices.empty() || !std::isfinite(now_s)) return st;
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
