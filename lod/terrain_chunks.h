// The ROAM mesh kept in GPU memory by chunk, so that a frame costs what ROAM changed plus one
// pass over the chunks, not a walk over every leaf (lod/roam.h, docs/terrain.md).
//
// The grid is cut into square chunks of `chunkSide` samples; each leaf belongs to the chunk
// holding its centroid (a leaf at or below the chunk size lies inside it; a coarser one spans
// several, and its chunk's box grows to hold it). Each chunk owns blocks of triangle slots in
// one vertex buffer (16 ... 1024 slots a block, growing with the chunk), so a frame draws the
// chunks inside the frustum as one range per block (a multi-draw); a slot whose triangle left
// stays degenerate until the chunk takes a new triangle into it. A chunk that empties returns
// its blocks; one that shrinks below a quarter of its slots (and holds more than two of the
// smallest blocks) is packed into fresh blocks.
//
// Per frame: apply() replays Roam's leaf-change log (O(changes)), and lists the slots the
// caller must write (the triangle now in each, or degenerate); cull() tests groups of 8 x 8
// chunks against the frustum, then the non-empty chunks of the groups in view, and lists the
// draw ranges. When the log cannot describe the
// change (a restart from the base triangles, a log overflow) apply() re-reads every leaf:
// O(leaves), as rare as teleports. Pure bookkeeping: every buffer is allocated at construction
// except the caller's draw-range list, which only grows.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <span>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "lod/roam.h"
#include "lod/view.h"

namespace ig::lod {

struct TerrainChunksConfig {
  // Samples along a chunk's edge (rounded down to a power of two); 0 = a 32nd of the grid,
  // 8 ... 64 (64: ~2 km at 30 m; smaller chunks cull closer, larger ones cost fewer ranges).
  int chunkSide = 0;
  size_t capacityTriangles = 0;  // slots in the vertex buffer; 0 = 3/2 * the Roam's triangle cap
  size_t logCapacity = 1u << 20; // leaf-log entries an update may append before a full re-read
};

struct TerrainDrawRange {
  uint32_t first;     // first slot (triangle index; vertex = 3 * slot)
  uint32_t count;     // slots
  uint32_t near = 1;  // 1: the range's chunks lie (partly) within cull()'s nearReach_m of the eye
};

class TerrainChunks {
 public:
  static constexpr uint32_t kNone = 0xFFFFFFFFu;
  static constexpr uint32_t kMinBlock = 16, kMaxBlock = 1024;

  // Enables the Roam's leaf log; the roam must outlive this object and not be given to another.
  TerrainChunks(Roam& roam, const TerrainChunksConfig& config = {});

  struct Changes {
    size_t dirty = 0;        // slots listed by dirtySlots() (write each: slotNode() or degenerate)
    size_t added = 0;        // triangles placed
    size_t removed = 0;      // triangles taken out
    size_t packedChunks = 0; // chunks packed into fresh blocks
    size_t packedSlots = 0;  // slots those chunks had (each written again, or degenerate)
    bool reread = false;     // every leaf was read again (restart, log overflow, first call)
    size_t dropped = 0;      // leaves that found no slot (buffer full): not drawn; see overflowed()
  };
  // After roam.update(): brings the slots up to date with the current leaves and clears the log.
  Changes apply();
  // The slots to write after apply(), each once.
  std::span<const uint32_t> dirtySlots() const { return {dirty_.data(), dirtyCount_}; }
  // The leaf node in slot s (its triangle: Roam::leafTriangle), or kNone: degenerate.
  uint32_t slotNode(uint32_t s) const { return slotNode_[s]; }
  // After apply(): calls write(slot, triangle) for each dirty slot that holds a leaf and
  // hide(slot) for each that is now free (draw it degenerate).
  template <class Write, class Hide>
  void forEachDirty(Write&& write, Hide&& hide) const {
    for (const uint32_t s : dirtySlots()) {
      RoamTriangle t;
      if (slotNode_[s] != kNone && roam_->leafTriangle(slotNode_[s], &t)) write(s, t);
      else hide(s);
    }
  }

  // Draw ranges of the chunks whose box meets the frustum, merged where contiguous. Returns the
  // live triangles in those chunks (the degenerate slots in the ranges are not counted).
  // `nearReach_m`: a range is marked `near` when its chunk's box comes closer to the eye than
  // this (the renderer shades near ground with detail that far ground does not need); ranges
  // of different marks are not merged. +inf: every range near. `nearest_m` (optional): the
  // smallest distance from the eye to the box of a chunk drawn (+inf: none drawn).
  size_t cull(const Camera& camera, std::vector<TerrainDrawRange>& ranges,
              double nearReach_m = std::numeric_limits<double>::infinity(), double* nearest_m = nullptr) const;

  size_t capacity() const { return capacity_; }
  size_t liveTriangles() const { return live_; }
  size_t slotsInUse() const;        // slots in blocks handed to chunks (live + degenerate)
  size_t chunkCount() const { return chunks_.size(); }
  int chunkSide() const { return side_; }
  bool overflowed() const { return overflowed_; }  // the last apply() dropped leaves
  // Debug check: every live emittable leaf in exactly one slot, slots and chunks consistent.
  // Allocates. Returns false and writes the first problem to *why.
  bool validate(std::string* why) const;

 private:
  struct Block {
    uint32_t first;  // first slot
    uint32_t size;   // slots (a power of two, kMinBlock ... kMaxBlock)
    uint32_t used;   // slots handed out from the front (bump)
    uint32_t next;   // next block of the same chunk, or the next free block of this size
    uint32_t chunk;  // owner, kNone while free
  };
  struct Chunk {
    uint32_t firstBlock = kNone;  // newest first
    uint32_t freeSlot = kNone;    // free slots inside its blocks (through nextFree_)
    uint32_t live = 0;            // triangles
    uint32_t slots = 0;           // slots in its blocks
    uint32_t dirtyStamp = 0;      // touched in this apply (packing candidates)
    glm::dvec3 lo{0.0}, hi{0.0};  // ENU box of its triangles (grows until the chunk empties)
  };

  // kGroupSide x kGroupSide chunks: cull() tests a group's box before its chunks', so a frame
  // costs the groups plus the chunks of the groups in view (65,536 chunks at 16385^2: 1,024
  // groups). A group's box holds its chunks' boxes; apply() recomputes it for touched chunks.
  static constexpr int kGroupSide = 8;
  struct Group {
    glm::dvec3 lo{0.0}, hi{0.0};
    uint32_t live = 0;   // triangles in its chunks
    uint32_t stamp = 0;  // recomputed in this apply
  };
  void updateGroup(uint32_t g);
  static void mergeLast(std::vector<TerrainDrawRange>& ranges);
  size_t cullChunk(const Chunk& c, const Frustum& frustum, const glm::dvec3& eye, double nearReach_m,
                   std::vector<TerrainDrawRange>& ranges, double& nearest_m) const;
  uint32_t groupOf(uint32_t chunk) const {
    return static_cast<uint32_t>((chunk / static_cast<uint32_t>(chunksX_)) / kGroupSide * static_cast<uint32_t>(groupsX_) +
                                 (chunk % static_cast<uint32_t>(chunksX_)) / kGroupSide);
  }

  uint32_t chunkOf(const RoamTriangle& t) const;
  bool place(uint32_t node);                 // a new leaf: a slot in its chunk, box grown
  void remove(uint32_t node);                // a leaf that left: its slot freed
  uint32_t takeSlot(uint32_t chunk);         // kNone: buffer full
  uint32_t newBlock(uint32_t sizeClass);     // kNone: no room left at all; may return a smaller block
  void releaseBlocks(Chunk& c);
  void pack(uint32_t chunk);
  void markDirty(uint32_t slot);
  void growBox(Chunk& c, const RoamTriangle& t) const;
  void reread();

  Roam* roam_;
  int side_ = 64;
  int chunksX_ = 1, chunksY_ = 1;
  int groupsX_ = 1, groupsY_ = 1;
  std::vector<Group> groups_;
  size_t capacity_ = 0;
  std::vector<Chunk> chunks_;
  std::vector<Block> blocks_;            // kMinBlock-slot units: block of unit u is blockOfUnit_[u]
  std::vector<uint32_t> blockOfUnit_;
  std::vector<uint32_t> freeBlocks_;     // per size class (log2(size / kMinBlock)): head of a list
  std::vector<uint32_t> spareBlocks_;    // Block records not in use
  uint32_t bump_ = 0;                    // slots never handed to a block
  std::vector<uint32_t> slotNode_;       // kNone = free
  std::vector<uint32_t> nextFree_;       // per slot: the chunk's next free slot
  struct FreeDeleter {
    void operator()(uint32_t* p) const;
  };
  std::unique_ptr<uint32_t[], FreeDeleter> nodeSlot_;  // per pool node: its slot + 1 (0 = none); calloc'd
  std::vector<uint32_t> order_;          // reread: leaves sorted by chunk
  std::vector<uint32_t> dirty_;
  std::vector<uint32_t> dirtyMark_;      // per slot: stamp of the apply() that listed it
  size_t dirtyCount_ = 0;
  std::vector<uint32_t> touchedChunks_;
  size_t touchedCount_ = 0;
  std::vector<uint32_t> scratch_;        // reread / pack
  uint32_t stamp_ = 0;
  size_t live_ = 0;
  size_t dropped_ = 0;
  size_t packedSlots_ = 0;
  bool overflowed_ = false;
  bool first_ = true;
  bool needReread_ = false;              // leaves were dropped: read them all again next time
};

}  // namespace ig::lod
