// The packed hierarchical-cells database (paper 003, section 3: the server holds every cell's
// octree image; the client fetches them by cell). One file, all little-endian:
//
//   [0, 128)                    header (CellDbHeader; field table in docs/cells.md)
//   [indexOffset, +indexBytes)  index: one 32-byte entry per cell, breadth-first (CellTree order)
//   [dataOffset, fileBytes)     payloads: each cell's octree image, exactly S(cell) bytes,
//                               in cell order, back to back
//
// Index entry (32 bytes): u32 parent (0xFFFFFFFF for the root), u8 octant, u8 level, u16 0,
// u32 V, u32 S, u64 absolute payload offset, u32 crc32 of the payload, u32 0.
//
// Payload (cells_voxel.h's BVO encoding, S = 16 + masks + 3 V):
//   16-byte header: u32 cell id, u8 level q, u8 voxel depth d, u16 x, u16 y, u16 z (the cell's
//   coordinate in its level's grid), u32 V;
//   breadth-first child masks: one byte per occupied node of levels q .. q + d - 1 inside the
//   cell (the cell itself first), bit o = octant o occupied (bit 0 = +x, 1 = +y, 2 = +z), nodes
//   of a level in Morton order (so the children of one node are contiguous);
//   then R, G, B per voxel of level q + d, in the same order.
//
// CRCs are zlib's crc32 (also what the HTTP fetcher checks): of the index, of each payload, and
// of the header's first 124 bytes (the last field).
//
// Two error channels: bad bytes (a file, a download) return false with a message naming the bad
// value; nothing here asserts on data. File errors are prefixed with the file name.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/cells.h"
#include "lod/cells_voxel.h"

namespace ig::lod {

inline constexpr size_t kCellDbHeaderBytes = 128;
inline constexpr size_t kCellDbEntryBytes = 32;
inline constexpr size_t kCellDbPayloadHeaderBytes = 16;
inline constexpr uint32_t kCellDbVersion = 1;
inline constexpr char kCellDbMagic[8] = {'I', 'G', 'H', 'C', 'D', 'B', '0', '1'};

struct CellDbHeader {
  uint32_t version = kCellDbVersion;
  uint32_t cellCount = 0;      // >= 1
  uint32_t cellLevels = 0;     // L, 1..kMaxCellLevels
  uint32_t voxelDepth = 0;     // d, 0..8
  glm::dvec3 rootMin_m{0.0};   // the root cube's lowest corner (finite)
  double rootEdge_m = 1.0;     // > 0, finite
  uint64_t indexOffset = 0, indexBytes = 0, dataOffset = 0, fileBytes = 0;
  uint64_t payloadBytes = 0;   // sum of S over all cells = fileBytes - dataOffset
  uint32_t indexCrc32 = 0;     // zlib crc32 of the index bytes
  uint32_t headerCrc32 = 0;    // zlib crc32 of the header's bytes [0, 124)
};

// Where a cell's payload lies in the file, and its checksum.
struct CellDbEntry {
  uint64_t offset = 0;  // absolute file offset
  uint32_t bytes = 0;   // = S(cell)
  uint32_t crc32 = 0;   // zlib crc32 of the payload
};

// zlib's crc32 of `bytes` (the one the file uses).
uint32_t cellDbCrc32(std::span<const uint8_t> bytes);

// Writes the database of the cell tree buildCellTree(pyramid, config) would build, streamed per
// cell (one payload buffer; memory beyond the pyramid ~ 90 bytes per cell), to `path` (through
// `path`.tmp, renamed when complete). The tree written goes to `treeOut` if not null. Fails on
// what buildCellTree refuses (an empty pyramid, a bad config) and on I/O errors, naming the file.
bool writeCellDb(const std::string& path, const VoxelPyramid& pyramid, const CellBuildConfig& config, CellTree* treeOut,
                 std::string& error);

// Parses and checks the first kCellDbHeaderBytes of `bytes`: size, magic, version, header crc,
// counts and ranges, offsets consistent with each other (not with a file size: the caller
// compares fileBytes with what it has).
bool parseCellDbHeader(std::span<const uint8_t> bytes, CellDbHeader& out, std::string& error);

// Checks the index (size, crc against the header, every entry) and builds the tree from it
// (CellTree::build validates the structure). `entries` gets one entry per cell.
bool parseCellDbIndex(const CellDbHeader& header, std::span<const uint8_t> index, CellTree& tree,
                      std::vector<CellDbEntry>& entries, std::string& error);

// One decoded voxel.
struct CellPoint {
  glm::vec3 pos{0.0f};  // voxel centre relative to the tree's rootMin_m, metres
  uint32_t rgba = 0;    // RGBA8 0xAABBGGRR, alpha 255
};
static_assert(sizeof(CellPoint) == 16);

// Decodes one cell's payload and appends its V voxels to `out` (in Morton order of the cell's
// finest voxels). Checks the structure, not the crc (the caller compares cellDbCrc32(payload)
// with the entry's): size == S(cell), the header names this cell (id, level, depth, coordinate,
// V), every mask non-zero, node counts consistent, point count == V. Allocates only when `out`
// must grow (reserve V). On failure `out` is unchanged.
bool decodeCell(const CellTree& tree, uint32_t cell, std::span<const uint8_t> payload, std::vector<CellPoint>& out,
                std::string& error);

// Local-disk mode: the whole file memory-mapped read-only, header and index checked at open(),
// payloads handed out as spans into the map (check their crc with cellDbCrc32 before decoding).
class CellDbFile {
 public:
  CellDbFile() = default;
  ~CellDbFile();
  CellDbFile(const CellDbFile&) = delete;
  CellDbFile& operator=(const CellDbFile&) = delete;

  // Errors are prefixed with the path; a file whose size is not the header's fileBytes is refused.
  bool open(const std::string& path, std::string& error);
  void close();
  bool isOpen() const { return map_ != nullptr; }
  const std::string& path() const { return path_; }
  const CellDbHeader& header() const { return header_; }
  const CellTree& tree() const { return tree_; }
  const std::vector<CellDbEntry>& entries() const { return entries_; }
  // The cell's payload bytes (empty for a cell out of range or a closed file).
  std::span<const uint8_t> payload(uint32_t cell) const;
  // The whole mapped file.
  std::span<const uint8_t> bytes() const { return {static_cast<const uint8_t*>(map_), size_}; }

 private:
  std::string path_;
  void* map_ = nullptr;
  size_t size_ = 0;
  CellDbHeader header_;
  CellTree tree_;
  std::vector<CellDbEntry> entries_;
};

}  // namespace ig::lod
