// lod/cells_db: the packed cell database. Write -> open round trip (the tree identical, every
// payload's crc matches and decodes to exactly V voxels at the pyramid's places and colours);
// corrupt header / index / payload, a truncated file, a wrong magic and version are refused with
// a message naming the value; every truncation of a payload fails cleanly; an empty mesh writes
// nothing; a scene 1e7 m from the origin; the crc is zlib's.
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "lod/cells_db.h"

using namespace ig::lod;

namespace {

std::string tempPath(const char* name) {
  return testing::TempDir() + "/" + name + "_" + std::to_string(::getpid()) + ".ighc";
}

std::vector<uint8_t> readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void writeAll(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}
uint32_t le32(const uint8_t* p) { return p[0] | p[1] << 8 | p[2] << 16 | static_cast<uint32_t>(p[3]) << 24; }
void putLe32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
// Rewrites the header crc after a deliberate edit of a header field.
void resealHeader(std::vector<uint8_t>& f) { putLe32(f.data() + 124, cellDbCrc32({f.data(), 124})); }

VoxelPyramid spheres(const glm::dvec3& origin, int levels) {
  VoxelMesh m;
  appendSphere(m, origin + glm::dvec3(30, 30, 30), 20, 48, 0xFF2040E0u);
  appendSphere(m, origin + glm::dvec3(70, 60, 40), 15, 40, 0xFF10C020u);
  appendQuad(m, origin + glm::dvec3(5, 90, 5), origin + glm::dvec3(95, 90, 5), origin + glm::dvec3(95, 90, 95),
             origin + glm::dvec3(5, 90, 95), 0xFFC0C0C0u);
  VoxelizeConfig vc;
  vc.levels = levels;
  vc.boxMin_m = origin;
  vc.boxEdge_m = 100.0;
  VoxelPyramid p;
  std::string err;
  EXPECT_TRUE(voxelize(m, vc, p, err)) << err;
  return p;
}

struct Written {
  std::string path;
  VoxelPyramid pyramid;
  CellTree tree;
  ~Written() { std::remove(path.c_str()); }
};

void writeScene(Written& w, const char* name, const glm::dvec3& origin = glm::dvec3(0.0)) {
  w.path = tempPath(name);
  w.pyramid = spheres(origin, 7);
  CellBuildConfig bc;
  bc.cellLevels = 5;
  bc.cellVoxelDepth = 2;
  std::string err;
  ASSERT_TRUE(writeCellDb(w.path, w.pyramid, bc, &w.tree, err)) << err;
}

// Every cell decodes to its V voxels; together a level's cells hold exactly the pyramid's voxels
// of level q + d, at their centres and with their colours.
void checkAllCells(const CellDbFile& db, const VoxelPyramid& pyramid) {
  const CellTree& t = db.tree();
  const int d = t.info().cellVoxelDepth;
  std::vector<CellPoint> pts;
  std::string err;
  for (int q = 0; q < t.levels(); ++q) {
    const auto& codes = pyramid.codes[static_cast<size_t>(q + d)];
    const auto& colors = pyramid.colors[static_cast<size_t>(q + d)];
    const double edge = t.voxelEdge_m(q);
    size_t seen = 0;
    for (uint32_t c = t.levelBegin(q); c < t.levelBegin(q + 1); ++c) {
      const auto payload = db.payload(c);
      ASSERT_EQ(payload.size(), t.bytes(c));
      ASSERT_EQ(cellDbCrc32(payload), db.entries()[c].crc32) << "cell " << c;
      pts.clear();
      ASSERT_TRUE(decodeCell(t, c, payload, pts, err)) << err;
      ASSERT_EQ(pts.size(), t.voxels(c));
      const Aabb box = t.box(c);
      for (const CellPoint& p : pts) {
        const glm::dvec3 world = t.info().rootMin_m + glm::dvec3(p.pos);
        ASSERT_TRUE(box.contains(world)) << "cell " << c;
        const glm::dvec3 v = glm::dvec3(p.pos) / edge - 0.5;
        const glm::uvec3 iv(static_cast<uint32_t>(std::lround(v.x)), static_cast<uint32_t>(std::lround(v.y)),
                            static_cast<uint32_t>(std::lround(v.z)));
        ASSERT_NEAR(v.x, iv.x, 1e-3);  // exactly a voxel centre
        const uint64_t code = mortonEncode(iv.x, iv.y, iv.z);
        const auto it = std::lower_bound(codes.begin(), codes.end(), code);
        ASSERT_TRUE(it != codes.end() && *it == code) << "cell " << c << ": a voxel the pyramid does not have";
        EXPECT_EQ(p.rgba, colors[static_cast<size_t>(it - codes.begin())] | 0xFF000000u);
      }
      seen += pts.size();
    }
    EXPECT_EQ(seen, codes.size()) << "level " << q;
  }
}

TEST(CellsDb, RoundTrip) {
  Written w;
  writeScene(w, "roundtrip");
  CellDbFile db;
  std::string err;
  ASSERT_TRUE(db.open(w.path, err)) << err;
  const CellTree& t = db.tree();
  ASSERT_GT(t.size(), 100u);
  ASSERT_EQ(t.size(), w.tree.size());
  EXPECT_EQ(t.levels(), 5);
  EXPECT_EQ(t.info().rootMin_m, w.tree.info().rootMin_m);
  EXPECT_EQ(t.info().rootEdge_m, w.tree.info().rootEdge_m);
  EXPECT_EQ(t.info().cellVoxelDepth, 2);
  for (uint32_t c = 0; c < t.size(); ++c) {
    ASSERT_EQ(t.parent(c), w.tree.parent(c));
    ASSERT_EQ(t.voxels(c), w.tree.voxels(c));
    ASSERT_EQ(t.bytes(c), w.tree.bytes(c));
    ASSERT_EQ(t.coord(c), w.tree.coord(c));
  }
  EXPECT_EQ(db.header().fileBytes, readAll(w.path).size());
  EXPECT_EQ(db.header().payloadBytes, t.totalBytes());
  checkAllCells(db, w.pyramid);
  // The tree writeCellDb returns is the one buildCellTree builds.
  CellTree ref;
  CellBuildConfig bc;
  bc.cellLevels = 5;
  bc.cellVoxelDepth = 2;
  ASSERT_TRUE(buildCellTree(w.pyramid, bc, ref, err)) << err;
  EXPECT_EQ(ref.size(), t.size());
  EXPECT_EQ(ref.totalBytes(), t.totalBytes());
}

TEST(CellsDb, DepthZeroAndDeepCells) {
  const VoxelPyramid p = spheres(glm::dvec3(0.0), 6);
  for (int d : {0, 4}) {
    const std::string path = tempPath(d == 0 ? "d0" : "d4");
    CellBuildConfig bc;
    bc.cellLevels = d == 0 ? 7 : 3;
    bc.cellVoxelDepth = d;
    std::string err;
    ASSERT_TRUE(writeCellDb(path, p, bc, nullptr, err)) << err;
    CellDbFile db;
    ASSERT_TRUE(db.open(path, err)) << err;
    checkAllCells(db, p);
    db.close();
    std::remove(path.c_str());
  }
}

TEST(CellsDb, CrcIsZlibs) {
  const char* text = "123456789";
  const std::span<const uint8_t> bytes(reinterpret_cast<const uint8_t*>(text), 9);
  EXPECT_EQ(cellDbCrc32(bytes), 0xCBF43926u);  // the CRC-32 check value
  Written w;
  writeScene(w, "crc");
  const auto f = readAll(w.path);
  CellDbHeader h;
  std::string err;
  ASSERT_TRUE(parseCellDbHeader(f, h, err)) << err;
  EXPECT_EQ(le32(f.data() + 120), ::crc32(0, f.data() + h.indexOffset, static_cast<uInt>(h.indexBytes)));
  EXPECT_EQ(le32(f.data() + 124), ::crc32(0, f.data(), 124));
  CellDbFile db;
  ASSERT_TRUE(db.open(w.path, err)) << err;
  for (uint32_t c = 0; c < db.tree().size(); c += 37) {
    const auto& e = db.entries()[c];
    EXPECT_EQ(e.crc32, ::crc32(0, f.data() + e.offset, e.bytes));
  }
}

TEST(CellsDb, BadFilesAreRefusedNamingTheValue) {
  Written w;
  writeScene(w, "bad");
  const auto good = readAll(w.path);
  const std::string bad = tempPath("bad_copy");
  CellDbFile db;
  std::string err;
  auto openBad = [&](const std::vector<uint8_t>& bytes) {
    writeAll(bad, bytes);
    const bool ok = db.open(bad, err);
    EXPECT_FALSE(db.isOpen() && !ok);
    return ok;
  };
  // Wrong magic.
  auto f = good;
  f[0] = 'X';
  EXPECT_FALSE(openBad(f));
  EXPECT_NE(err.find(bad), std::string::npos) << err;
  EXPECT_NE(err.find("magic 'XGHCDB01'"), std::string::npos) << err;
  // A header field changed: the header crc catches it.
  f = good;
  f[12] ^= 1;
  EXPECT_FALSE(openBad(f));
  EXPECT_NE(err.find("header crc 0x"), std::string::npos) << err;
  EXPECT_NE(err.find(" != 0x"), std::string::npos) << err;
  // A valid-crc header with a bad version / depth / root edge.
  f = good;
  putLe32(f.data() + 8, 2);
  resealHeader(f);
  EXPECT_FALSE(openBad(f));
  EXPECT_NE(err.find("version 2"), std::string::npos) << err;
  f = good;
  putLe32(f.data() + 20, 9);
  resealHeader(f);
  EXPECT_FALSE(openBad(f));
  EXPECT_NE(err.find("voxel depth 9"), std::string::npos) << err;
  f = good;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(f.data() + 48, &nan, 8);
  resealHeader(f);
  EXPECT_FALSE(openBad(f));
  EXPECT_NE(err.find("root edge nan"), std::string::npos) << err;
  // The index: one byte flipped.
  f = good;
  f[kCellDbHeaderBytes + 40] ^= 0x10;
  EXPECT_FALSE(openBad(f));
  EXPECT_NE(err.find("index crc 0x"), std::string::npos) << err;
  EXPECT_NE(err.find("in the header"), std::string::npos) << err;
  // An index with a valid crc but a bad entry (V of cell 3 changed).
  f = good;
  CellDbHeader h;
  ASSERT_TRUE(parseCellDbHeader(good, h, err)) << err;
  putLe32(f.data() + h.indexOffset + 3 * kCellDbEntryBytes + 8, 0);
  putLe32(f.data() + 120, cellDbCrc32({f.data() + h.indexOffset, h.indexBytes}));
  resealHeader(f);
  EXPECT_FALSE(openBad(f));
  EXPECT_NE(err.find("index entry 3: V = 0"), std::string::npos) << err;
  // Truncated, and appended to.
  f = good;
  f.resize(f.size() - 5);
  EXPECT_FALSE(openBad(f));
  EXPECT_NE(err.find(std::to_string(f.size()) + " bytes, the header says " + std::to_string(good.size())),
            std::string::npos)
      << err;
  f = std::vector<uint8_t>(good.begin(), good.begin() + 100);
  EXPECT_FALSE(openBad(f));
  EXPECT_NE(err.find("100 bytes"), std::string::npos) << err;
  f = good;
  f.push_back(0);
  EXPECT_FALSE(openBad(f));
  // A payload byte flipped: the file opens (payloads are checked when used), the crc differs.
  f = good;
  const uint32_t victim = 5;
  ASSERT_TRUE(db.open(w.path, err)) << err;
  const CellDbEntry e = db.entries()[victim];
  f[e.offset + e.bytes - 1] ^= 0xFF;
  ASSERT_TRUE(openBad(f)) << err;
  EXPECT_NE(cellDbCrc32(db.payload(victim)), db.entries()[victim].crc32);
  EXPECT_EQ(cellDbCrc32(db.payload(victim + 1)), db.entries()[victim + 1].crc32);
  // Missing file.
  EXPECT_FALSE(db.open(bad + ".missing", err));
  EXPECT_NE(err.find(".missing: cannot open"), std::string::npos) << err;
  std::remove(bad.c_str());
}

TEST(CellsDb, DecodeChecksStructure) {
  Written w;
  writeScene(w, "structure");
  CellDbFile db;
  std::string err;
  ASSERT_TRUE(db.open(w.path, err)) << err;
  const CellTree& t = db.tree();
  uint32_t cell = t.levelBegin(2);
  const auto good = db.payload(cell);
  std::vector<uint8_t> p(good.begin(), good.end());
  std::vector<CellPoint> out(3);  // decodeCell appends; on failure leaves it unchanged
  auto expectFail = [&](const std::vector<uint8_t>& bytes, uint32_t c, const char* what) {
    EXPECT_FALSE(decodeCell(t, c, bytes, out, err)) << what;
    EXPECT_NE(err.find(what), std::string::npos) << err;
    EXPECT_EQ(out.size(), 3u);
  };
  ASSERT_TRUE(decodeCell(t, cell, p, out, err)) << err;
  EXPECT_EQ(out.size(), 3u + t.voxels(cell));
  out.resize(3);
  // Another cell's payload.
  expectFail(p, cell + 1, "payload");
  auto q = p;
  putLe32(q.data(), cell + 1);
  expectFail(q, cell, "payload header names cell");
  q = p;
  q[8] ^= 1;  // y coordinate
  expectFail(q, cell, "coordinate");
  q = p;
  q[16] = 0;  // the cell's own child mask
  expectFail(q, cell, "child mask at byte 16 (depth 0) is 0");
  q = p;
  putLe32(q.data() + 12, t.voxels(cell) + 1);
  expectFail(q, cell, "payload header V =");
  expectFail(p, t.size(), "out of range");
  // Every truncation and every extension by a byte fails cleanly.
  for (size_t n = 0; n < p.size(); ++n) {
    const std::vector<uint8_t> cut(p.begin(), p.begin() + static_cast<std::ptrdiff_t>(n));
    EXPECT_FALSE(decodeCell(t, cell, cut, out, err)) << n;
  }
  q = p;
  q.push_back(0);
  EXPECT_FALSE(decodeCell(t, cell, q, out, err));
  EXPECT_EQ(out.size(), 3u);
  // Random byte damage never crashes (ASAN) and never yields more than V points.
  uint32_t seed = 7;
  for (int i = 0; i < 2000; ++i) {
    q = p;
    seed = seed * 1664525u + 1013904223u;
    q[seed % q.size()] ^= static_cast<uint8_t>(1 + (seed >> 24) % 255);
    out.resize(3);
    if (decodeCell(t, cell, q, out, err)) {
      EXPECT_EQ(out.size(), 3u + t.voxels(cell));
    }
  }
}

// An octree image of depth d holds at most 8^d voxels, so an index entry (with a valid index crc)
// claiming more is corrupt: open() must refuse it, naming the entry and V, instead of accepting a
// tree whose V the selector budgets with and whose payload can never decode.
TEST(CellsDb, IndexEntryClaimingMoreVoxelsThan8PowDepthIsRefused) {
  Written w;
  writeScene(w, "toomany");  // d = 2: at most 64 voxels a cell
  const auto good = readAll(w.path);
  CellDbHeader h;
  std::string err;
  ASSERT_TRUE(parseCellDbHeader(good, h, err)) << err;
  ASSERT_EQ(h.voxelDepth, 2u);
  std::vector<uint8_t> index(good.begin() + static_cast<std::ptrdiff_t>(h.indexOffset),
                             good.begin() + static_cast<std::ptrdiff_t>(h.indexOffset + h.indexBytes));
  // The last cell is a leaf of the last level: more voxels keep the tree monotone.
  uint8_t* e = index.data() + (h.cellCount - 1) * kCellDbEntryBytes;
  const uint32_t oldS = le32(e + 12);
  const uint32_t V = 65, S = 16 + 3 * V + 2;  // the smallest S the index allows for V = 65, d = 2
  putLe32(e + 8, V);
  putLe32(e + 12, S);
  h.fileBytes = h.fileBytes - oldS + S;
  h.payloadBytes = h.fileBytes - h.dataOffset;
  h.indexCrc32 = cellDbCrc32(index);
  CellTree t;
  std::vector<CellDbEntry> entries;
  EXPECT_FALSE(parseCellDbIndex(h, index, t, entries, err));
  EXPECT_NE(err.find("index entry " + std::to_string(h.cellCount - 1) + ": V = 65"), std::string::npos) << err;
  // 8^d itself is fine (d = 0: exactly one voxel).
  putLe32(e + 8, 64);
  putLe32(e + 12, 16 + 3 * 64 + 2);
  h.fileBytes = h.fileBytes - S + (16 + 3 * 64 + 2);
  h.payloadBytes = h.fileBytes - h.dataOffset;
  h.indexCrc32 = cellDbCrc32(index);
  EXPECT_TRUE(parseCellDbIndex(h, index, t, entries, err)) << err;
}

// decodeCell takes any CellTree (whose depth may be 0..20), but the payload format holds at most
// 8 levels (a cell's local Morton code is 24 bits, one mask level per depth): a tree of a larger
// depth must be refused, not decoded past the end of the per-depth arrays.
TEST(CellsDb, DecodeRefusesATreeDeeperThanTheFormat) {
  const int d = 10;
  CellTreeInfo info;
  info.cellVoxelDepth = d;
  const uint32_t S = 16 + d + 3;
  const CellDesc root{kNoCell, 0, 1, S};
  CellTree t;
  std::string err;
  ASSERT_TRUE(t.build(info, std::span<const CellDesc>(&root, 1), err)) << err;
  std::vector<uint8_t> p(S, 0);
  p[5] = static_cast<uint8_t>(d);
  putLe32(p.data() + 12, 1);
  for (int k = 0; k < d; ++k) p[16 + static_cast<size_t>(k)] = 0x01;  // one octant 0 child per depth
  p[S - 3] = 10;
  std::vector<CellPoint> out;
  EXPECT_FALSE(decodeCell(t, 0, p, out, err));
  EXPECT_NE(err.find("depth 10"), std::string::npos) << err;
  EXPECT_TRUE(out.empty());
}

TEST(CellsDb, HeaderParserRefusesShortInput) {
  std::vector<uint8_t> b(127, 0);
  CellDbHeader h;
  std::string err;
  EXPECT_FALSE(parseCellDbHeader(b, h, err));
  EXPECT_NE(err.find("127 bytes, need 128"), std::string::npos) << err;
}

TEST(CellsDb, EmptyMeshWritesNothing) {
  VoxelMesh empty;
  VoxelizeConfig vc;
  vc.levels = 5;
  VoxelPyramid p;
  std::string err;
  ASSERT_TRUE(voxelize(empty, vc, p, err)) << err;
  const std::string path = tempPath("empty");
  CellTree t;
  EXPECT_FALSE(writeCellDb(path, p, CellBuildConfig{3, 2}, &t, err));
  EXPECT_NE(err.find(path), std::string::npos) << err;
  EXPECT_NE(err.find("empty"), std::string::npos) << err;
  EXPECT_TRUE(readAll(path).empty());
  EXPECT_TRUE(readAll(path + ".tmp").empty());
  // A bad config is refused the same way.
  const VoxelPyramid s = spheres(glm::dvec3(0.0), 5);
  EXPECT_FALSE(writeCellDb(path, s, CellBuildConfig{5, 3}, &t, err));
  EXPECT_NE(err.find("= 7"), std::string::npos) << err;
  // An unwritable path names the file.
  EXPECT_FALSE(writeCellDb("/nonexistent-dir/x.ighc", s, CellBuildConfig{3, 2}, &t, err));
  EXPECT_NE(err.find("/nonexistent-dir/x.ighc"), std::string::npos) << err;
}

TEST(CellsDb, HugeCoordinates) {
  Written w;
  const glm::dvec3 origin(1.0e7, -2.0e7, 3.0e6);
  writeScene(w, "huge", origin);
  CellDbFile db;
  std::string err;
  ASSERT_TRUE(db.open(w.path, err)) << err;
  EXPECT_EQ(db.tree().info().rootMin_m, origin);  // doubles stored exactly
  checkAllCells(db, w.pyramid);  // points are relative to rootMin: float-exact voxel centres
}

}  // namespace
