// The packed hierarchical-cells database (paper 003, section 3). Format in cells_db.h.
#include "lod/cells_db.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cstdarg>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace ig::lod {
namespace {

constexpr size_t kHeaderCrcBytes = 124;

void put16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}
void put32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
void put64(uint8_t* p, uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
void putF64(uint8_t* p, double v) { put64(p, std::bit_cast<uint64_t>(v)); }
uint16_t get16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | p[1] << 8); }
uint32_t get32(const uint8_t* p) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<uint32_t>(p[i]) << (8 * i);
  return v;
}
uint64_t get64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<uint64_t>(p[i]) << (8 * i);
  return v;
}
double getF64(const uint8_t* p) { return std::bit_cast<double>(get64(p)); }

bool fail(std::string& error, const char* fmt, ...) __attribute__((format(printf, 2, 3)));
bool fail(std::string& error, const char* fmt, ...) {
  char msg[320];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(msg, sizeof msg, fmt, args);
  va_end(args);
  error = msg;
  return false;
}

using ull = unsigned long long;

void encodeHeader(const CellDbHeader& h, uint8_t* b) {
  std::memset(b, 0, kCellDbHeaderBytes);
  std::memcpy(b, kCellDbMagic, 8);
  put32(b + 8, h.version);
  put32(b + 12, h.cellCount);
  put32(b + 16, h.cellLevels);
  put32(b + 20, h.voxelDepth);
  putF64(b + 24, h.rootMin_m.x);
  putF64(b + 32, h.rootMin_m.y);
  putF64(b + 40, h.rootMin_m.z);
  putF64(b + 48, h.rootEdge_m);
  put64(b + 56, h.indexOffset);
  put64(b + 64, h.indexBytes);
  put64(b + 72, h.dataOffset);
  put64(b + 80, h.fileBytes);
  put64(b + 88, h.payloadBytes);
  put32(b + 96, static_cast<uint32_t>(kCellDbEntryBytes));
  put32(b + 100, static_cast<uint32_t>(kCellDbPayloadHeaderBytes));
  // [104, 120) reserved, zero
  put32(b + 120, h.indexCrc32);
  put32(b + 124, cellDbCrc32({b, kHeaderCrcBytes}));
}

struct FileCloser {
  FILE* f = nullptr;
  ~FileCloser() {
    if (f) std::fclose(f);
  }
};

}  // namespace

uint32_t cellDbCrc32(std::span<const uint8_t> bytes) {
  uLong crc = ::crc32(0L, Z_NULL, 0);
  const uint8_t* p = bytes.data();
  size_t n = bytes.size();
  while (n > 0) {  // zlib takes uInt lengths
    const auto chunk = static_cast<uInt>(std::min<size_t>(n, 1u << 30));
    crc = ::crc32(crc, p, chunk);
    p += chunk;
    n -= chunk;
  }
  return static_cast<uint32_t>(crc);
}

bool writeCellDb(const std::string& path, const VoxelPyramid& pyramid, const CellBuildConfig& config, CellTree* treeOut,
                 std::string& error) {
  CellTree local;
  CellTree& tree = treeOut ? *treeOut : local;
  if (!buildCellTree(pyramid, config, tree, error)) {
    error = path + ": nothing written: " + error;
    return false;
  }
  const uint32_t n = tree.size();
  const int L = tree.levels(), d = config.cellVoxelDepth;
  CellDbHeader h;
  h.cellCount = n;
  h.cellLevels = static_cast<uint32_t>(L);
  h.voxelDepth = static_cast<uint32_t>(d);
  h.rootMin_m = tree.info().rootMin_m;
  h.rootEdge_m = tree.info().rootEdge_m;
  h.indexOffset = kCellDbHeaderBytes;
  h.indexBytes = uint64_t{n} * kCellDbEntryBytes;
  h.dataOffset = h.indexOffset + h.indexBytes;
  h.payloadBytes = tree.totalBytes();
  h.fileBytes = h.dataOffset + h.payloadBytes;

  const std::string tmp = path + ".tmp";
  FileCloser file;
  file.f = std::fopen(tmp.c_str(), "wb");
  if (!file.f) {
    error = path + ": cannot write the cell database: " + std::strerror(errno);
    return false;
  }
  auto ioFail = [&](const char* what) {
    error = path + ": cannot write the cell database (" + what + "): " + std::strerror(errno);
    std::fclose(file.f);
    file.f = nullptr;
    std::remove(tmp.c_str());
    return false;
  };
  std::vector<uint8_t> index(h.indexBytes, 0);
  if (std::fseek(file.f, static_cast<long>(h.dataOffset), SEEK_SET) != 0) return ioFail("seek");

  std::vector<uint8_t> payload;
  uint64_t offset = h.dataOffset;
  for (int q = 0; q < L; ++q) {
    const auto& cellCodes = pyramid.codes[static_cast<size_t>(q)];
    std::array<size_t, 9> cursor{};  // per depth k: first node of level q + k not yet passed
    for (uint32_t c = tree.levelBegin(q); c < tree.levelBegin(q + 1); ++c) {
      const uint64_t code = cellCodes[c - tree.levelBegin(q)];
      const uint32_t V = tree.voxels(c), S = tree.bytes(c);
      payload.assign(S, 0);
      uint8_t* p = payload.data();
      const glm::uvec3 xyz = tree.coord(c);
      put32(p, c);
      p[4] = static_cast<uint8_t>(q);
      p[5] = static_cast<uint8_t>(d);
      put16(p + 6, static_cast<uint16_t>(xyz.x));
      put16(p + 8, static_cast<uint16_t>(xyz.y));
      put16(p + 10, static_cast<uint16_t>(xyz.z));
      put32(p + 12, V);
      // Node ranges of this cell per depth.
      std::array<size_t, 9> begin{}, end{};
      for (int k = 0; k <= d; ++k) {
        const auto& lc = pyramid.codes[static_cast<size_t>(q + k)];
        const auto ku = static_cast<size_t>(k);
        const uint64_t lo = code << (3 * k), hi = (code + 1) << (3 * k);
        while (cursor[ku] < lc.size() && lc[cursor[ku]] < lo) ++cursor[ku];
        begin[ku] = cursor[ku];
        while (cursor[ku] < lc.size() && lc[cursor[ku]] < hi) ++cursor[ku];
        end[ku] = cursor[ku];
      }
      size_t w = kCellDbPayloadHeaderBytes;
      for (int k = 0; k < d; ++k) {
        const auto ku = static_cast<size_t>(k);
        const auto& lc = pyramid.codes[static_cast<size_t>(q + k)];
        const auto& nc = pyramid.codes[static_cast<size_t>(q + k + 1)];
        size_t j = begin[ku + 1];
        for (size_t i = begin[ku]; i < end[ku]; ++i) {
          uint8_t mask = 0;
          for (; j < end[ku + 1] && (nc[j] >> 3) == lc[i]; ++j) mask = static_cast<uint8_t>(mask | 1u << (nc[j] & 7));
          if (w < S) p[w] = mask;
          ++w;
        }
      }
      const auto du = static_cast<size_t>(d);
      const auto& colors = pyramid.colors[static_cast<size_t>(q + d)];
      if (end[du] - begin[du] != V || w + 3 * size_t{V} != S) {
        std::fclose(file.f);
        file.f = nullptr;
        std::remove(tmp.c_str());
        return fail(error, "%s: cell %u: %zu voxels and %zu bytes encoded, the tree says V = %u, S = %u (internal error)",
                    path.c_str(), c, end[du] - begin[du], w + 3 * (end[du] - begin[du]), V, S);
      }
      for (size_t i = begin[du]; i < end[du]; ++i) {
        const uint32_t rgba = colors[i];
        p[w++] = static_cast<uint8_t>(rgba);
        p[w++] = static_cast<uint8_t>(rgba >> 8);
        p[w++] = static_cast<uint8_t>(rgba >> 16);
      }
      uint8_t* e = index.data() + size_t{c} * kCellDbEntryBytes;
      put32(e, tree.parent(c));
      e[4] = static_cast<uint8_t>(c == 0 ? 0 : code & 7);
      e[5] = static_cast<uint8_t>(q);
      put32(e + 8, V);
      put32(e + 12, S);
      put64(e + 16, offset);
      put32(e + 24, cellDbCrc32(payload));
      if (std::fwrite(payload.data(), 1, S, file.f) != S) return ioFail("payload");
      offset += S;
    }
  }
  h.indexCrc32 = cellDbCrc32(index);
  uint8_t header[kCellDbHeaderBytes];
  encodeHeader(h, header);
  if (std::fseek(file.f, 0, SEEK_SET) != 0) return ioFail("seek");
  if (std::fwrite(header, 1, sizeof header, file.f) != sizeof header) return ioFail("header");
  if (std::fwrite(index.data(), 1, index.size(), file.f) != index.size()) return ioFail("index");
  const int closed = std::fclose(file.f);
  file.f = nullptr;
  if (closed != 0 || std::rename(tmp.c_str(), path.c_str()) != 0) {
    error = path + ": cannot write the cell database: " + std::strerror(errno);
    std::remove(tmp.c_str());
    return false;
  }
  error.clear();
  return true;
}

bool parseCellDbHeader(std::span<const uint8_t> bytes, CellDbHeader& out, std::string& error) {
  if (bytes.size() < kCellDbHeaderBytes)
    return fail(error, "cell database header: %zu bytes, need %zu", bytes.size(), kCellDbHeaderBytes);
  const uint8_t* b = bytes.data();
  if (std::memcmp(b, kCellDbMagic, 8) != 0) {
    char shown[9];
    for (int i = 0; i < 8; ++i) shown[i] = b[i] >= 32 && b[i] < 127 ? static_cast<char>(b[i]) : '?';
    shown[8] = '\0';
    return fail(error, "magic '%s' != 'IGHCDB01': not a cell database", shown);
  }
  const uint32_t stored = get32(b + 124), actual = cellDbCrc32({b, kHeaderCrcBytes});
  if (stored != actual) return fail(error, "header crc 0x%08x != 0x%08x stored in the header", actual, stored);
  CellDbHeader h;
  h.version = get32(b + 8);
  h.cellCount = get32(b + 12);
  h.cellLevels = get32(b + 16);
  h.voxelDepth = get32(b + 20);
  h.rootMin_m = {getF64(b + 24), getF64(b + 32), getF64(b + 40)};
  h.rootEdge_m = getF64(b + 48);
  h.indexOffset = get64(b + 56);
  h.indexBytes = get64(b + 64);
  h.dataOffset = get64(b + 72);
  h.fileBytes = get64(b + 80);
  h.payloadBytes = get64(b + 88);
  h.indexCrc32 = get32(b + 120);
  h.headerCrc32 = stored;
  if (h.version != kCellDbVersion) return fail(error, "version %u: this build reads version %u", h.version, kCellDbVersion);
  if (get32(b + 96) != kCellDbEntryBytes) return fail(error, "index entry size %u != %zu", get32(b + 96), kCellDbEntryBytes);
  if (get32(b + 100) != kCellDbPayloadHeaderBytes)
    return fail(error, "payload header size %u != %zu", get32(b + 100), kCellDbPayloadHeaderBytes);
  for (size_t i = 104; i < 120; ++i)
    if (b[i] != 0) return fail(error, "reserved header byte %zu = %u: must be 0", i, b[i]);
  if (h.cellCount == 0 || h.cellCount == kNoCell) return fail(error, "cell count %u: out of range 1..%u", h.cellCount, kNoCell - 1);
  if (h.cellLevels < 1 || h.cellLevels > static_cast<uint32_t>(kMaxCellLevels))
    return fail(error, "cell levels %u: allowed range 1..%d", h.cellLevels, kMaxCellLevels);
  if (h.voxelDepth > 8) return fail(error, "voxel depth %u: allowed range 0..8", h.voxelDepth);
  if (!std::isfinite(h.rootMin_m.x) || !std::isfinite(h.rootMin_m.y) || !std::isfinite(h.rootMin_m.z))
    return fail(error, "root min (%g, %g, %g): not finite", h.rootMin_m.x, h.rootMin_m.y, h.rootMin_m.z);
  if (!(h.rootEdge_m > 0.0) || !std::isfinite(h.rootEdge_m)) return fail(error, "root edge %g m: must be finite and > 0", h.rootEdge_m);
  constexpr uint64_t kLimit = uint64_t{1} << 56;  // no sum below overflows
  if (h.indexOffset < kCellDbHeaderBytes || h.indexOffset > kLimit)
    return fail(error, "index offset %llu: must be >= %zu", static_cast<ull>(h.indexOffset), kCellDbHeaderBytes);
  if (h.indexBytes != uint64_t{h.cellCount} * kCellDbEntryBytes)
    return fail(error, "index bytes %llu != %u cells x %zu", static_cast<ull>(h.indexBytes), h.cellCount, kCellDbEntryBytes);
  if (h.dataOffset < h.indexOffset + h.indexBytes || h.dataOffset > kLimit)
    return fail(error, "data offset %llu: before the end of the index (%llu)", static_cast<ull>(h.dataOffset),
                static_cast<ull>(h.indexOffset + h.indexBytes));
  if (h.fileBytes < h.dataOffset || h.fileBytes > kLimit || h.payloadBytes != h.fileBytes - h.dataOffset)
    return fail(error, "file bytes %llu, data offset %llu and payload bytes %llu disagree", static_cast<ull>(h.fileBytes),
                static_cast<ull>(h.dataOffset), static_cast<ull>(h.payloadBytes));
  if (h.payloadBytes < uint64_t{h.cellCount} * (kCellDbPayloadHeaderBytes + 3))
    return fail(error, "payload bytes %llu: too few for %u cells", static_cast<ull>(h.payloadBytes), h.cellCount);
  out = h;
  error.clear();
  return true;
}

bool parseCellDbIndex(const CellDbHeader& header, std::span<const uint8_t> index, CellTree& tree,
                      std::vector<CellDbEntry>& entries, std::string& error) {
  if (index.size() != header.indexBytes)
    return fail(error, "index: %zu bytes, the header says %llu", index.size(), static_cast<ull>(header.indexBytes));
  const uint32_t crc = cellDbCrc32(index);
  if (crc != header.indexCrc32) return fail(error, "index crc 0x%08x != 0x%08x in the header", crc, header.indexCrc32);
  const uint32_t n = header.cellCount;
  const uint64_t d = header.voxelDepth;
  if (d > 8) return fail(error, "voxel depth %llu: allowed range 0..8", static_cast<ull>(d));  // a header not from parseCellDbHeader
  std::vector<CellDesc> cells(n);
  std::vector<uint8_t> levels(n);
  entries.assign(n, CellDbEntry{});
  uint64_t offset = header.dataOffset;
  for (uint32_t i = 0; i < n; ++i) {
    const uint8_t* e = index.data() + size_t{i} * kCellDbEntryBytes;
    CellDesc& c = cells[i];
    c.parent = get32(e);
    c.octant = e[4];
    levels[i] = e[5];
    c.voxels = get32(e + 8);
    c.bytes = get32(e + 12);
    const uint64_t off = get64(e + 16);
    if (get16(e + 6) != 0 || get32(e + 28) != 0) return fail(error, "index entry %u: reserved bytes not 0", i);
    if (c.voxels == 0) return fail(error, "index entry %u: V = 0 (every cell holds at least one voxel)", i);
    if (uint64_t{c.voxels} > uint64_t{1} << (3 * d))
      return fail(error, "index entry %u: V = %u: more than the 8^%llu voxels of a depth-%llu octree image", i, c.voxels,
                  static_cast<ull>(d), static_cast<ull>(d));
    const uint64_t minS = kCellDbPayloadHeaderBytes + 3 * uint64_t{c.voxels} + d;
    const uint64_t maxS = kCellDbPayloadHeaderBytes + 3 * uint64_t{c.voxels} + (d == 0 ? 0 : 1 + (d - 1) * c.voxels);
    if (c.bytes < minS || c.bytes > maxS)
      return fail(error, "index entry %u: S = %u: not in %llu..%llu for V = %u and depth %llu", i, c.bytes,
                  static_cast<ull>(minS), static_cast<ull>(maxS), c.voxels, static_cast<ull>(d));
    if (off != offset)
      return fail(error, "index entry %u: offset %llu != %llu (payloads are back to back in cell order)", i,
                  static_cast<ull>(off), static_cast<ull>(offset));
    offset += c.bytes;
    if (offset > header.fileBytes)
      return fail(error, "index entry %u: payload ends at %llu, past the file's %llu bytes", i, static_cast<ull>(offset),
                  static_cast<ull>(header.fileBytes));
    entries[i] = {off, c.bytes, get32(e + 24)};
  }
  if (offset != header.fileBytes)
    return fail(error, "index: payloads end at %llu, the file has %llu bytes", static_cast<ull>(offset),
                static_cast<ull>(header.fileBytes));
  CellTreeInfo info;
  info.rootMin_m = header.rootMin_m;
  info.rootEdge_m = header.rootEdge_m;
  info.cellVoxelDepth = static_cast<int>(header.voxelDepth);
  if (!tree.build(info, cells, error)) {
    entries.clear();
    error = "index: " + error;
    return false;
  }
  for (uint32_t i = 0; i < n; ++i) {
    if (levels[i] != tree.level(i)) {
      const int lvl = tree.level(i);
      tree = CellTree{};
      entries.clear();
      return fail(error, "index entry %u: level %u, but its parents put it at level %d", i, levels[i], lvl);
    }
  }
  if (static_cast<uint32_t>(tree.levels()) != header.cellLevels) {
    const int lv = tree.levels();
    tree = CellTree{};
    entries.clear();
    return fail(error, "index: %d cell levels, the header says %u", lv, header.cellLevels);
  }
  error.clear();
  return true;
}

bool decodeCell(const CellTree& tree, uint32_t cell, std::span<const uint8_t> payload, std::vector<CellPoint>& out,
                std::string& error) {
  if (cell >= tree.size()) return fail(error, "cell %u: out of range (%u cells)", cell, tree.size());
  const uint32_t V = tree.voxels(cell), S = tree.bytes(cell);
  if (payload.size() != S) return fail(error, "cell %u: payload of %zu bytes != S = %u", cell, payload.size(), S);
  if (payload.size() < kCellDbPayloadHeaderBytes + 3)
    return fail(error, "cell %u: payload of %zu bytes: shorter than a header and one voxel", cell, payload.size());
  const uint8_t* p = payload.data();
  const int q = tree.level(cell), d = tree.info().cellVoxelDepth;
  // The format's limit (a CellTree allows deeper images): one mask level per depth, 24-bit local codes.
  if (d < 0 || d > 8) return fail(error, "cell %u: voxel depth %d: the cell database holds depths 0..8", cell, d);
  const glm::uvec3 xyz = tree.coord(cell);
  if (get32(p) != cell) return fail(error, "cell %u: payload header names cell %u", cell, get32(p));
  if (p[4] != q || p[5] != d)
    return fail(error, "cell %u: payload header says level %u depth %u, the tree %d and %d", cell, p[4], p[5], q, d);
  if (get16(p + 6) != xyz.x || get16(p + 8) != xyz.y || get16(p + 10) != xyz.z)
    return fail(error, "cell %u: payload header coordinate (%u, %u, %u) != (%u, %u, %u)", cell, get16(p + 6),
                get16(p + 8), get16(p + 10), xyz.x, xyz.y, xyz.z);
  if (get32(p + 12) != V) return fail(error, "cell %u: payload header V = %u, the index %u", cell, get32(p + 12), V);
  if (3 * uint64_t{V} + kCellDbPayloadHeaderBytes > S)
    return fail(error, "cell %u: S = %u: too small for V = %u", cell, S, V);
  const size_t maskEnd = S - 3 * size_t{V};
  // Check the masks level by level before touching `out`.
  std::array<size_t, 9> levelStart{};
  size_t pos = kCellDbPayloadHeaderBytes, nodes = 1;
  for (int k = 0; k < d; ++k) {
    levelStart[static_cast<size_t>(k)] = pos;
    if (pos + nodes > maskEnd)
      return fail(error, "cell %u: masks of depth %d run past byte %zu (into the colours)", cell, k, maskEnd);
    size_t next = 0;
    for (size_t i = 0; i < nodes; ++i) {
      const uint8_t m = p[pos + i];
      if (m == 0) return fail(error, "cell %u: child mask at byte %zu (depth %d) is 0", cell, pos + i, k);
      next += static_cast<size_t>(std::popcount(m));
    }
    if (next > V) return fail(error, "cell %u: %zu nodes at depth %d, more than V = %u", cell, next, k + 1, V);
    pos += nodes;
    nodes = next;
  }
  if (nodes != V) return fail(error, "cell %u: masks give %zu voxels != V = %u", cell, nodes, V);
  if (pos != maskEnd) return fail(error, "cell %u: masks end at byte %zu, colours start at %zu", cell, pos, maskEnd);

  const size_t base = out.size();
  out.resize(base + V);
  CellPoint* o = out.data() + base;
  o[0].rgba = 0;  // local Morton code, expanded in place (a level never has more nodes than V)
  nodes = 1;
  for (int k = 0; k < d; ++k) {
    const uint8_t* masks = p + levelStart[static_cast<size_t>(k)];
    size_t end = 0;
    for (size_t i = 0; i < nodes; ++i) end += static_cast<size_t>(std::popcount(masks[i]));
    const size_t next = end;
    for (size_t i = nodes; i-- > 0;) {
      const uint32_t code = o[i].rgba;
      for (int oct = 7; oct >= 0; --oct)
        if (masks[i] & (1u << oct)) o[--end].rgba = code << 3 | static_cast<uint32_t>(oct);
    }
    nodes = next;
  }
  const double edge = tree.voxelEdge_m(q);
  const double scale = std::ldexp(1.0, d);
  const uint8_t* rgb = p + maskEnd;
  for (uint32_t i = 0; i < V; ++i) {
    const glm::uvec3 local = mortonDecode(o[i].rgba);
    const glm::dvec3 v = glm::dvec3(xyz) * scale + glm::dvec3(local) + 0.5;
    o[i].pos = glm::vec3(v * edge);
    o[i].rgba = static_cast<uint32_t>(rgb[0]) | static_cast<uint32_t>(rgb[1]) << 8 | static_cast<uint32_t>(rgb[2]) << 16 |
                0xFF000000u;
    rgb += 3;
  }
  error.clear();
  return true;
}

CellDbFile::~CellDbFile() { close(); }

void CellDbFile::close() {
  if (map_) ::munmap(map_, size_);
  map_ = nullptr;
  size_ = 0;
  header_ = {};
  tree_ = CellTree{};
  entries_.clear();
}

bool CellDbFile::open(const std::string& path, std::string& error) {
  close();
  path_ = path;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    error = path + ": cannot open the cell database: " + std::strerror(errno);
    return false;
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    error = path + ": not a regular file";
    return false;
  }
  const auto size = static_cast<size_t>(st.st_size);
  if (size < kCellDbHeaderBytes) {
    ::close(fd);
    return fail(error, "%s: %zu bytes: shorter than the %zu-byte header (truncated?)", path.c_str(), size, kCellDbHeaderBytes);
  }
  void* map = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
  ::close(fd);
  if (map == MAP_FAILED) {
    error = path + ": mmap failed: " + std::strerror(errno);
    return false;
  }
  map_ = map;
  size_ = size;
  const auto* b = static_cast<const uint8_t*>(map);
  std::string why;
  CellDbHeader h;
  if (!parseCellDbHeader({b, size}, h, why)) {
    close();
    error = path + ": " + why;
    return false;
  }
  if (h.fileBytes != size) {
    close();
    return fail(error, "%s: %zu bytes, the header says %llu (truncated or appended to)", path.c_str(), size,
                static_cast<ull>(h.fileBytes));
  }
  header_ = h;
  if (!parseCellDbIndex(h, {b + h.indexOffset, static_cast<size_t>(h.indexBytes)}, tree_, entries_, why)) {
    close();
    error = path + ": " + why;
    return false;
  }
  error.clear();
  return true;
}

std::span<const uint8_t> CellDbFile::payload(uint32_t cell) const {
  if (!map_ || cell >= entries_.size()) return {};
  return {static_cast<const uint8_t*>(map_) + entries_[cell].offset, entries_[cell].bytes};
}

}  // namespace ig::lod
