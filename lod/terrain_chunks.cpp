#include "lod/terrain_chunks.h"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cstdlib>
#include <new>

namespace ig::lod {

namespace {
constexpr uint32_t kClasses = 7;  // 16, 32, ..., 1024 slots
uint32_t classOf(uint32_t size) { return static_cast<uint32_t>(std::countr_zero(size / TerrainChunks::kMinBlock)); }
}  // namespace

void TerrainChunks::FreeDeleter::operator()(uint32_t* p) const { std::free(p); }

TerrainChunks::TerrainChunks(Roam& roam, const TerrainChunksConfig& config) : roam_(&roam) {
  static_assert((kMaxBlock >> (kClasses - 1)) == kMinBlock);
  const int gridSide = std::max(1, std::min(roam.gridWidth(), roam.gridHeight()) - 1);
  const int want = config.chunkSide > 0 ? config.chunkSide : std::clamp(gridSide / 32, 8, 64);
  side_ = static_cast<int>(std::bit_floor(static_cast<unsigned>(std::clamp(want, 1, gridSide))));
  chunksX_ = (roam.gridWidth() - 1 + side_ - 1) / side_;
  chunksY_ = (roam.gridHeight() - 1 + side_ - 1) / side_;
  chunksX_ = std::max(chunksX_, 1);
  chunksY_ = std::max(chunksY_, 1);
  chunks_.resize(static_cast<size_t>(chunksX_) * static_cast<size_t>(chunksY_));
  groupsX_ = (chunksX_ + kGroupSide - 1) / kGroupSide;
  groupsY_ = (chunksY_ + kGroupSide - 1) / kGroupSide;
  groups_.resize(static_cast<size_t>(groupsX_) * static_cast<size_t>(groupsY_));
  size_t cap = config.capacityTriangles != 0 ? config.capacityTriangles : roam.triangleCap() / 2 * 3;
  cap = std::max<size_t>(cap, 2 * kMaxBlock);
  cap = (cap + kMinBlock - 1) / kMinBlock * kMinBlock;
  cap = std::min<size_t>(cap, size_t{1} << 31);
  capacity_ = cap;
  const size_t units = capacity_ / kMinBlock;
  blocks_.resize(units);
  blockOfUnit_.assign(units, kNone);
  spareBlocks_.resize(units);
  for (size_t i = 0; i < units; ++i) spareBlocks_[i] = static_cast<uint32_t>(units - 1 - i);
  freeBlocks_.assign(kClasses, kNone);
  slotNode_.assign(capacity_, kNone);
  nextFree_.assign(capacity_, kNone);
  dirty_.resize(capacity_);
  dirtyMark_.assign(capacity_, 0);
  touchedChunks_.resize(chunks_.size());
  nodeSlot_.reset(static_cast<uint32_t*>(std::calloc(roam.nodeCapacity(), sizeof(uint32_t))));
  if (!nodeSlot_) throw std::bad_alloc();
  scratch_.resize(roam.nodeCapacity() / 2 + roam.baseTriangles() + 16);
  order_.resize(scratch_.size());
  roam.enableLeafLog(config.logCapacity);
}

uint32_t TerrainChunks::chunkOf(const RoamTriangle& t) const {
  const int64_t x3 = int64_t{t.v[0].x} + t.v[1].x + t.v[2].x, y3 = int64_t{t.v[0].y} + t.v[1].y + t.v[2].y;
  const int64_t s3 = 3 * int64_t{side_};
  const auto cx = static_cast<uint32_t>(std::clamp<int64_t>(x3 / s3, 0, chunksX_ - 1));
  const auto cy = static_cast<uint32_t>(std::clamp<int64_t>(y3 / s3, 0, chunksY_ - 1));
  return cy * static_cast<uint32_t>(chunksX_) + cx;
}

void TerrainChunks::markDirty(uint32_t slot) {
  if (dirtyMark_[slot] == stamp_) return;
  dirtyMark_[slot] = stamp_;
  dirty_[dirtyCount_++] = slot;
}

void TerrainChunks::growBox(Chunk& c, const RoamTriangle& t) const {
  for (const RoamVertex& v : t.v) {
    const glm::dvec3 p = roam_->vertexPosition(v.x, v.y);
    if (c.live == 0 && &v == &t.v[0]) {
      c.lo = c.hi = p;
      continue;
    }
    c.lo = glm::min(c.lo, p);
    c.hi = glm::max(c.hi, p);
  }
}

uint32_t TerrainChunks::newBlock(uint32_t cls) {
  const uint32_t want = kMinBlock << cls;
  uint32_t b = kNone;
  if (freeBlocks_[cls] != kNone) {
    b = freeBlocks_[cls];
    freeBlocks_[cls] = blocks_[b].next;
  } else if (bump_ + want <= capacity_) {
    b = spareBlocks_.back();
    spareBlocks_.pop_back();
    blocks_[b].first = bump_;
    blocks_[b].size = want;
    bump_ += want;
    for (uint32_t u = blocks_[b].first / kMinBlock; u < (blocks_[b].first + want) / kMinBlock; ++u) blockOfUnit_[u] = b;
  } else {
    // Split a larger free block (buddies are not merged again: a re-read starts afresh).
    for (uint32_t k = cls + 1; k < kClasses && b == kNone; ++k) {
      if (freeBlocks_[k] == kNone) continue;
      const uint32_t big = freeBlocks_[k];
      freeBlocks_[k] = blocks_[big].next;
      for (uint32_t j = k; j > cls; --j) {  // halve down to cls; the upper halves go free
        const uint32_t half = blocks_[big].size / 2;
        const uint32_t upper = spareBlocks_.back();
        spareBlocks_.pop_back();
        blocks_[upper] = Block{blocks_[big].first + half, half, 0, freeBlocks_[j - 1], kNone};
        freeBlocks_[j - 1] = upper;
        for (uint32_t u = blocks_[upper].first / kMinBlock; u < (blocks_[upper].first + half) / kMinBlock; ++u)
          blockOfUnit_[u] = upper;
        blocks_[big].size = half;
      }
      b = big;
    }
    // Nothing as large: the largest smaller block there is.
    for (uint32_t k = cls; k-- > 0 && b == kNone;) {
      if (freeBlocks_[k] == kNone) continue;
      b = freeBlocks_[k];
      freeBlocks_[k] = blocks_[b].next;
    }
    if (b == kNone && bump_ + kMinBlock <= capacity_) {  // the tail of the buffer
      const uint32_t size = std::bit_floor(static_cast<uint32_t>(capacity_ - bump_));
      return newBlock(classOf(std::min(size, want)));
    }
  }
  if (b != kNone) blocks_[b].used = 0;
  return b;
}

uint32_t TerrainChunks::takeSlot(uint32_t ci) {
  Chunk& c = chunks_[ci];
  if (c.freeSlot != kNone) {
    const uint32_t s = c.freeSlot;
    c.freeSlot = nextFree_[s];
    return s;
  }
  if (c.firstBlock != kNone) {
    Block& b = blocks_[c.firstBlock];
    if (b.used < b.size) return b.first + b.used++;
  }
  // A new block as large as the chunk's slots so far (doubling), within the size classes.
  const uint32_t want = std::clamp(std::bit_ceil(std::max<uint32_t>(c.slots, 1)), kMinBlock, kMaxBlock);
  const uint32_t b = newBlock(classOf(want));
  if (b == kNone) return kNone;
  blocks_[b].chunk = ci;
  blocks_[b].next = c.firstBlock;
  c.firstBlock = b;
  c.slots += blocks_[b].size;
  return blocks_[b].first + blocks_[b].used++;
}

void TerrainChunks::releaseBlocks(Chunk& c) {
  for (uint32_t b = c.firstBlock; b != kNone;) {
    const uint32_t next = blocks_[b].next;
    blocks_[b].chunk = kNone;
    blocks_[b].used = 0;
    const uint32_t cls = classOf(blocks_[b].size);
    blocks_[b].next = freeBlocks_[cls];
    freeBlocks_[cls] = b;
    b = next;
  }
  c.firstBlock = kNone;
  c.freeSlot = kNone;
  c.slots = 0;
}

bool TerrainChunks::place(uint32_t node) {
  if (nodeSlot_[node] != 0) remove(node);  // an older life of this node id: placed again
  RoamTriangle t;
  if (!roam_->leafTriangle(node, &t)) return true;
  const uint32_t ci = chunkOf(t);
  const uint32_t s = takeSlot(ci);
  if (s == kNone) {
    ++dropped_;
    return false;
  }
  Chunk& c = chunks_[ci];
  growBox(c, t);
  ++c.live;
  ++live_;
  slotNode_[s] = node;
  nodeSlot_[node] = s + 1;
  markDirty(s);
  if (c.dirtyStamp != stamp_) {
    c.dirtyStamp = stamp_;
    touchedChunks_[touchedCount_++] = ci;
  }
  return true;
}

void TerrainChunks::remove(uint32_t node) {
  const uint32_t s1 = nodeSlot_[node];
  if (s1 == 0) return;
  const uint32_t s = s1 - 1;
  nodeSlot_[node] = 0;
  slotNode_[s] = kNone;
  markDirty(s);
  const uint32_t ci = blocks_[blockOfUnit_[s / kMinBlock]].chunk;
  Chunk& c = chunks_[ci];
  --c.live;
  --live_;
  if (c.dirtyStamp != stamp_) {
    c.dirtyStamp = stamp_;
    touchedChunks_[touchedCount_++] = ci;
  }
  if (c.live == 0) {
    releaseBlocks(c);
    return;
  }
  nextFree_[s] = c.freeSlot;
  c.freeSlot = s;
}

void TerrainChunks::updateGroup(uint32_t gi) {
  Group& g = groups_[gi];
  g.live = 0;
  const int gx = static_cast<int>(gi) % groupsX_, gy = static_cast<int>(gi) / groupsX_;
  for (int cy = gy * kGroupSide; cy < std::min(chunksY_, (gy + 1) * kGroupSide); ++cy)
    for (int cx = gx * kGroupSide; cx < std::min(chunksX_, (gx + 1) * kGroupSide); ++cx) {
      const Chunk& c = chunks_[static_cast<size_t>(cy) * static_cast<size_t>(chunksX_) + static_cast<size_t>(cx)];
      if (c.live == 0) continue;
      if (g.live == 0) {
        g.lo = c.lo;
        g.hi = c.hi;
      } else {
        g.lo = glm::min(g.lo, c.lo);
        g.hi = glm::max(g.hi, c.hi);
      }
      g.live += c.live;
    }
}

void TerrainChunks::pack(uint32_t ci) {
  Chunk& c = chunks_[ci];
  packedSlots_ += c.slots;
  size_t n = 0;
  for (uint32_t b = c.firstBlock; b != kNone; b = blocks_[b].next)
    for (uint32_t s = blocks_[b].first; s < blocks_[b].first + blocks_[b].used; ++s) {
      if (slotNode_[s] == kNone) continue;
      scratch_[n++] = slotNode_[s];
      nodeSlot_[slotNode_[s]] = 0;
      slotNode_[s] = kNone;
      markDirty(s);  // degenerate unless the packing reuses it
    }
  live_ -= c.live;
  c.live = 0;
  releaseBlocks(c);
  // Oldest first (the list is newest first): keeps the order the slots had.
  std::reverse(scratch_.begin(), scratch_.begin() + static_cast<std::ptrdiff_t>(n));
  for (size_t i = 0; i < n; ++i) place(scratch_[i]);
}

void TerrainChunks::reread() {
  // Every slot handed out so far is written again: the new leaves, or degenerate.
  for (uint32_t s = 0; s < bump_; ++s) {
    if (slotNode_[s] != kNone) {
      nodeSlot_[slotNode_[s]] = 0;
      slotNode_[s] = kNone;
    }
    markDirty(s);
  }
  for (Chunk& c : chunks_) c = Chunk{};
  const size_t units = capacity_ / kMinBlock;
  spareBlocks_.resize(units);
  for (size_t i = 0; i < units; ++i) spareBlocks_[i] = static_cast<uint32_t>(units - 1 - i);
  std::fill(blockOfUnit_.begin(), blockOfUnit_.begin() + bump_ / kMinBlock, kNone);
  std::fill(freeBlocks_.begin(), freeBlocks_.end(), kNone);
  bump_ = 0;
  live_ = 0;
  // Leaves sorted by chunk (a counting sort), so each chunk's slots come out contiguous.
  const size_t n = roam_->emitLeafNodes(scratch_);
  std::vector<uint32_t>& count = touchedChunks_;  // reused as the histogram, cleared below
  std::fill(count.begin(), count.end(), 0u);
  for (size_t i = 0; i < n; ++i) {
    RoamTriangle t;
    roam_->leafTriangle(scratch_[i], &t);
    ++count[chunkOf(t)];
  }
  uint32_t sum = 0;
  for (uint32_t& c : count) {
    const uint32_t k = c;
    c = sum;
    sum += k;
  }
  for (size_t i = 0; i < n; ++i) {
    RoamTriangle t;
    roam_->leafTriangle(scratch_[i], &t);
    order_[count[chunkOf(t)]++] = scratch_[i];
  }
  touchedCount_ = 0;
  for (size_t i = 0; i < n; ++i) place(order_[i]);
}

TerrainChunks::Changes TerrainChunks::apply() {
  Changes ch;
  if (++stamp_ == 0) {  // wrapped: clear the marks once every 2^32 applies
    std::fill(dirtyMark_.begin(), dirtyMark_.end(), 0u);
    for (Chunk& c : chunks_) c.dirtyStamp = 0;
    for (Group& g : groups_) g.stamp = 0;
    stamp_ = 1;
  }
  dirtyCount_ = 0;
  touchedCount_ = 0;
  dropped_ = 0;
  packedSlots_ = 0;
  const size_t liveBefore = live_;
  if (first_ || needReread_ || roam_->leafLogReset()) {
    reread();
    ch.reread = true;
    ch.added = live_;
    ch.removed = liveBefore;
  } else {
    for (const uint32_t e : roam_->leafLog()) {
      if (e & Roam::kLeafRemoved) {
        remove(e & ~Roam::kLeafRemoved);
        ++ch.removed;
      } else {
        place(e);
        ++ch.added;
      }
    }
    // Chunks that shrank to under a quarter of their slots: packed into fresh blocks.
    const size_t touched = touchedCount_;
    for (size_t i = 0; i < touched; ++i) {
      const uint32_t ci = touchedChunks_[i];
      const Chunk& c = chunks_[ci];
      if (c.live > 0 && c.slots > 2 * kMinBlock && 4 * static_cast<size_t>(c.live) < c.slots) {
        pack(ci);
        ++ch.packedChunks;
      }
    }
  }
  // The groups of the chunks that changed (all of them after a re-read).
  if (ch.reread) {
    for (uint32_t g = 0; g < groups_.size(); ++g) updateGroup(g);
  } else {
    for (size_t i = 0; i < touchedCount_; ++i) {
      const uint32_t g = groupOf(touchedChunks_[i]);
      if (groups_[g].stamp == stamp_) continue;
      groups_[g].stamp = stamp_;
      updateGroup(g);
    }
  }
  first_ = false;
  roam_->clearLeafLog();
  ch.dropped = dropped_;
  ch.packedSlots = packedSlots_;
  overflowed_ = dropped_ > 0;
  needReread_ = overflowed_;
  ch.dirty = dirtyCount_;
  return ch;
}

size_t TerrainChunks::cull(const Camera& camera, std::vector<TerrainDrawRange>& ranges, double nearReach_m,
                           double* nearest_m) const {
  ranges.clear();
  double nearest = std::numeric_limits<double>::infinity();
  const Frustum frustum = makeFrustum(camera);
  size_t triangles = 0;
  for (uint32_t gi = 0; gi < groups_.size(); ++gi) {
    const Group& g = groups_[gi];
    if (g.live == 0 || !frustum.intersects(Aabb{g.lo - camera.eye_m, g.hi - camera.eye_m})) continue;
    const int gx = static_cast<int>(gi) % groupsX_, gy = static_cast<int>(gi) / groupsX_;
    for (int cy = gy * kGroupSide; cy < std::min(chunksY_, (gy + 1) * kGroupSide); ++cy)
      for (int cx = gx * kGroupSide; cx < std::min(chunksX_, (gx + 1) * kGroupSide); ++cx)
        triangles += cullChunk(chunks_[static_cast<size_t>(cy) * static_cast<size_t>(chunksX_) + static_cast<size_t>(cx)],
                               frustum, camera.eye_m, nearReach_m, ranges, nearest);
  }
  if (nearest_m) *nearest_m = nearest;
  return triangles;
}

// The last range grew: while it now touches the range before it (same mark), the two become one
// (consecutive ranges of one mark are never contiguous: "merged where contiguous").
void TerrainChunks::mergeLast(std::vector<TerrainDrawRange>& ranges) {
  while (ranges.size() >= 2) {
    TerrainDrawRange& prev = ranges[ranges.size() - 2];
    const TerrainDrawRange last = ranges.back();
    if (prev.near != last.near) return;
    if (prev.first + prev.count == last.first) {
      prev.count += last.count;
    } else if (last.first + last.count == prev.first) {
      prev.first = last.first;
      prev.count += last.count;
    } else {
      return;
    }
    ranges.pop_back();
  }
}

size_t TerrainChunks::cullChunk(const Chunk& c, const Frustum& frustum, const glm::dvec3& eye, double nearReach_m,
                                std::vector<TerrainDrawRange>& ranges, double& nearest_m) const {
  if (c.live == 0 || !frustum.intersects(Aabb{c.lo - eye, c.hi - eye})) return 0;
  const double distance = distanceToBox(Aabb{c.lo, c.hi}, eye);
  const uint32_t near = distance < nearReach_m ? 1u : 0u;
  nearest_m = std::min(nearest_m, distance);
  for (uint32_t b = c.firstBlock; b != kNone; b = blocks_[b].next) {
    const Block& k = blocks_[b];
    if (k.used == 0) continue;
    if (!ranges.empty() && ranges.back().near == near) {
      TerrainDrawRange& r = ranges.back();
      if (r.first + r.count == k.first) {
        r.count += k.used;
        mergeLast(ranges);
        continue;
      }
      if (k.first + k.used == r.first) {
        r.first = k.first;
        r.count += k.used;
        mergeLast(ranges);
        continue;
      }
    }
    ranges.push_back({k.first, k.used, near});
  }
  return c.live;
}

size_t TerrainChunks::slotsInUse() const {
  size_t n = 0;
  for (const Chunk& c : chunks_) n += c.slots;
  return n;
}

bool TerrainChunks::validate(std::string* why) const {
  auto fail = [&](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  std::vector<uint32_t> leaves(roam_->nodeCapacity() / 2 + roam_->baseTriangles() + 16);
  leaves.resize(roam_->emitLeafNodes(leaves));
  size_t placed = 0;
  for (const uint32_t n : leaves) {
    if (nodeSlot_[n] == 0) continue;  // dropped (buffer full): counted below
    const uint32_t s = nodeSlot_[n] - 1;
    if (slotNode_[s] != n) return fail("leaf " + std::to_string(n) + ": slot " + std::to_string(s) + " holds another node");
    RoamTriangle t;
    roam_->leafTriangle(n, &t);
    const uint32_t b = blockOfUnit_[s / kMinBlock];
    if (b == kNone || blocks_[b].chunk != chunkOf(t))
      return fail("leaf " + std::to_string(n) + ": slot " + std::to_string(s) + " not in a block of its chunk");
    if (s >= blocks_[b].first + blocks_[b].used) return fail("slot " + std::to_string(s) + " beyond its block's used part");
    const Chunk& c = chunks_[chunkOf(t)];
    for (const RoamVertex& v : t.v) {
      const glm::dvec3 p = roam_->vertexPosition(v.x, v.y);
      if (glm::any(glm::lessThan(p, c.lo)) || glm::any(glm::greaterThan(p, c.hi)))
        return fail("leaf " + std::to_string(n) + " outside its chunk's box");
    }
    ++placed;
  }
  if (!overflowed_ && placed != leaves.size())
    return fail(std::to_string(leaves.size() - placed) + " leaves without a slot and no overflow");
  if (placed != live_) return fail("live count " + std::to_string(live_) + " != placed leaves " + std::to_string(placed));
  size_t occupied = 0, chunkLive = 0;
  for (const Chunk& c : chunks_) {
    chunkLive += c.live;
    uint32_t slots = 0;
    for (uint32_t b = c.firstBlock; b != kNone; b = blocks_[b].next) {
      slots += blocks_[b].size;
      for (uint32_t s = blocks_[b].first; s < blocks_[b].first + blocks_[b].used; ++s) occupied += slotNode_[s] != kNone;
    }
    if (slots != c.slots) return fail("chunk slot count mismatch");
  }
  std::vector<uint32_t> groupLive(groups_.size(), 0u);
  for (uint32_t ci = 0; ci < chunks_.size(); ++ci) {
    const Chunk& c = chunks_[ci];
    if (c.live == 0) continue;
    const Group& g = groups_[groupOf(ci)];
    groupLive[groupOf(ci)] += c.live;
    if (glm::any(glm::lessThan(c.lo, g.lo)) || glm::any(glm::greaterThan(c.hi, g.hi)))
      return fail("chunk " + std::to_string(ci) + "'s box outside its group " + std::to_string(groupOf(ci)) + "'s");
  }
  for (uint32_t gi = 0; gi < groups_.size(); ++gi)
    if (groupLive[gi] != groups_[gi].live) return fail("group " + std::to_string(gi) + " live count mismatch");
  if (occupied != live_ || chunkLive != live_) return fail("occupied slots " + std::to_string(occupied) + " != live " + std::to_string(live_));
  return true;
}

}  // namespace ig::lod
