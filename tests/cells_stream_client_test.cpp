// ig/cells_stream: the client side of cell streaming (paper 003) from a local database file and
// from an HTTP server: the byte budget W and the voxel budget hold every frame; streaming
// converges to the all-resident optimum and the quality never falls while the view is still; a
// corrupt cell is rejected, refetched, then marked broken while its parent stays drawn; a
// request outside the database is refused by the client; the memory budget evicts the least
// recently drawn cells (never a drawn one or its ancestors); with the server down the frame loop
// goes on with what is resident and the fetches resume when it is back.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "ig/cells_stream.h"
#include "lod/cells_db.h"
#include "lod/cells_select.h"
#include "lod/cells_voxel.h"
#include "cells_test_db.h"
#include "test_servers.h"

using namespace ig;
using Clock = std::chrono::steady_clock;

namespace {

struct Db {
  std::string path;
  lod::CellTree tree;
  ~Db() { std::remove(path.c_str()); }
};

void writeDb(Db& db, const char* name) {
  db.path = testing::TempDir() + "/" + name + "_" + std::to_string(::getpid()) + ".ighc";
  lod::VoxelMesh m;
  lod::appendSphere(m, {30, 30, 30}, 20, 48, 0xFF2040E0u);
  lod::appendSphere(m, {70, 60, 40}, 15, 40, 0xFF10C020u);
  lod::appendQuad(m, {5, 90, 5}, {95, 90, 5}, {95, 90, 95}, {5, 90, 95}, 0xFFC0C0C0u);
  std::string err;
  ASSERT_TRUE(ig::test::writeTestCellDb(m, db.path, &db.tree, err)) << err;
}

// Keeps what was uploaded, like the GPU arena would.
class RecordingSink final : public CellSink {
 public:
  std::set<uint32_t> held;
  uint64_t uploads = 0, evictions = 0, points = 0;
  bool upload(uint32_t cell, std::span<const lod::CellPoint> pts) override {
    held.insert(cell);
    ++uploads;
    points += pts.size();
    return true;
  }
  void evict(uint32_t cell) override {
    EXPECT_EQ(held.erase(cell), 1u) << "evicting cell " << cell << " that was not uploaded";
    ++evictions;
  }
};

lod::CellView viewAt(const glm::dvec3& eye, const glm::dvec3& target, uint64_t budget, uint64_t w) {
  lod::CellView v;
  v.camera.eye_m = eye;
  const glm::dvec3 d = target - eye;
  v.camera.heading_deg = std::atan2(d.x, d.y) * 57.29577951308232;
  v.camera.pitch_deg = std::atan2(d.z, std::hypot(d.x, d.y)) * 57.29577951308232;
  v.camera.fovY_deg = 60.0;
  v.camera.aspect = 16.0 / 9.0;
  v.camera.near_m = 0.1;
  v.camera.far_m = 1000.0;
  v.viewportHeight_px = 720;
  v.voxelBudget = budget;
  v.byteBudget = w;
  return v;
}

struct Loop {
  CellStream& stream;
  RecordingSink& sink;
  lod::CellSelector selector;
  std::vector<lod::CellDraw> draw;
  std::vector<uint32_t> requests;
  uint64_t frame = 0;
  Loop(CellStream& s, RecordingSink& k)
      : stream(s), sink(k), selector(s.tree()), draw(s.tree().size()), requests(s.tree().size()) {}
  lod::CellSelectStats step(const lod::CellView& v) {
    stream.receive(sink);
    const lod::CellSelectStats st = selector.select(v, stream.residency(), draw, requests);
    EXPECT_LE(st.drawnVoxels, v.voxelBudget);
    EXPECT_LE(st.requestedBytes, v.byteBudget);
    for (uint32_t i = 0; i < st.drawnCells; ++i)
      EXPECT_TRUE(sink.held.count(draw[i].cell)) << "drawn cell " << draw[i].cell << " was never uploaded";
    stream.request({requests.data(), st.requestedCells});
    stream.drawn({draw.data(), st.drawnCells}, ++frame, sink);
    return st;
  }
};

float optimum(const lod::CellTree& tree, const lod::CellView& v) {
  lod::CellSelector s(tree);
  std::vector<lod::CellDraw> d(tree.size());
  std::vector<uint32_t> r(tree.size());
  return s.select(v, {}, d, r).maxVoxel_px;
}

}  // namespace

TEST(CellStream, LocalFileConvergesToTheOptimumWithinBudgets) {
  Db db;
  writeDb(db, "local");
  CellStream stream;
  CellStreamOptions o;
  o.source = db.path;
  std::string err;
  ASSERT_TRUE(stream.open(o, err)) << err;
  EXPECT_EQ(stream.tree().size(), db.tree.size());
  RecordingSink sink;
  Loop loop(stream, sink);
  const lod::CellView v = viewAt({50, -60, 50}, {50, 50, 50}, 20000, 2048);
  const float best = optimum(stream.tree(), v);
  float last = 1e30f;
  bool reached = false;
  const auto t0 = Clock::now();
  for (int i = 0; i < 2000 && !reached; ++i) {
    const lod::CellSelectStats st = loop.step(v);
    if (st.drawnCells > 0) {
      EXPECT_LE(st.maxVoxel_px, last * 1.000001f) << "quality fell at frame " << i;
      last = st.maxVoxel_px;
    }
    reached = st.drawnCells > 0 && st.maxVoxel_px <= best * 1.000001f;
    if (!reached && stream.stats().inFlight > 0) std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  EXPECT_TRUE(reached) << "largest voxel " << last << " px, optimum " << best << " px";
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 10.0);
  EXPECT_EQ(stream.stats().broken, 0u);
  EXPECT_GT(stream.stats().arrived, 1u);
}

TEST(CellStream, CorruptCellIsRefetchedThenBrokenAndItsParentStaysDrawn) {
  Db db;
  writeDb(db, "corrupt");
  lod::CellDbFile file;
  std::string err;
  ASSERT_TRUE(file.open(db.path, err)) << err;
  // The first non-empty cell of level 2.
  const lod::CellTree& t = file.tree();
  uint32_t victim = lod::kNoCell;
  for (uint32_t c = t.levelBegin(2); c < t.levelBegin(3) && victim == lod::kNoCell; ++c)
    if (t.voxels(c) > 0) victim = c;
  ASSERT_NE(victim, lod::kNoCell);
  const uint64_t at = file.entries()[victim].offset + file.entries()[victim].bytes - 1;
  const uint32_t victimParent = t.parent(victim);
  const uint32_t cells = t.size();
  file.close();  // `t` is gone from here on
  {
    std::fstream f(db.path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(static_cast<std::streamoff>(at));
    char c = 0;
    f.read(&c, 1);
    c = static_cast<char>(c ^ 0x5A);
    f.seekp(static_cast<std::streamoff>(at));
    f.write(&c, 1);
  }
  CellStream stream;
  CellStreamOptions o;
  o.source = db.path;
  o.fetch.retryMin_ms = 1;
  o.fetch.retryMax_ms = 2;
  ASSERT_TRUE(stream.open(o, err)) << err;  // the header and index are intact
  RecordingSink sink;
  Loop loop(stream, sink);
  // Look at everything from afar with a big budget: the victim is wanted.
  const lod::CellView v = viewAt({50, -150, 50}, {50, 50, 50}, 1000000, 1 << 20);
  for (int i = 0; i < 400 && !stream.isBroken(victim); ++i) {
    loop.step(v);
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  ASSERT_TRUE(stream.isBroken(victim)) << "the corrupt cell was never rejected";
  EXPECT_GE(stream.fetchStats().corrupt, 2u) << "it must have been fetched again before giving up";
  EXPECT_EQ(stream.stats().broken, 1u);
  EXPECT_NE(stream.lastError().find("cell " + std::to_string(victim)), std::string::npos) << stream.lastError();
  EXPECT_EQ(sink.held.count(victim), 0u);
  // The selection goes on: the victim's parent is drawn in its place, never the victim.
  for (int i = 0; i < 50; ++i) {
    const lod::CellSelectStats st = loop.step(v);
    for (uint32_t k = 0; k < st.drawnCells; ++k) EXPECT_NE(loop.draw[k].cell, victim);
  }
  std::vector<uint32_t> cut(cells);
  cut.resize(loop.selector.realization(cut));
  bool parentIn = false;
  for (uint32_t c : cut) parentIn = parentIn || c == victimParent;
  EXPECT_TRUE(parentIn) << "the broken cell's parent should stand in for it";
}

TEST(CellStream, RequestOutsideTheDatabaseIsRefusedByTheClient) {
  Db db;
  writeDb(db, "outside");
  CellStream stream;
  CellStreamOptions o;
  o.source = db.path;
  std::string err;
  ASSERT_TRUE(stream.open(o, err)) << err;
  const uint32_t bad[] = {stream.tree().size(), stream.tree().size() + 100};
  stream.request(bad);
  EXPECT_EQ(stream.stats().broken, 2u);
  EXPECT_EQ(stream.stats().requested, 0u);
  EXPECT_EQ(stream.fetchStats().requests, 0u) << "nothing may reach the fetcher";
  EXPECT_NE(stream.lastError().find("outside the database"), std::string::npos) << stream.lastError();
}

TEST(CellStream, MemoryBudgetEvictsLeastRecentlyDrawnNeverDrawnCells) {
  Db db;
  writeDb(db, "budget");
  CellStream stream;
  CellStreamOptions o;
  o.source = db.path;
  o.memoryBudget_bytes = 40000;  // ~2,500 voxels: far less than the two views need together
  std::string err;
  ASSERT_TRUE(stream.open(o, err)) << err;
  RecordingSink sink;
  Loop loop(stream, sink);
  const lod::CellView a = viewAt({30, -20, 30}, {30, 30, 30}, 2000, 1 << 20);
  const lod::CellView b = viewAt({110, 60, 40}, {70, 60, 40}, 2000, 1 << 20);
  for (int round = 0; round < 4; ++round) {
    const lod::CellView& v = round % 2 ? b : a;
    for (int i = 0; i < 60; ++i) {
      const lod::CellSelectStats st = loop.step(v);
      // Drawn cells (pinned with their ancestors) are never evicted: they are still held.
      for (uint32_t k = 0; k < st.drawnCells; ++k) EXPECT_TRUE(sink.held.count(loop.draw[k].cell));
      std::this_thread::sleep_for(std::chrono::microseconds(300));
    }
  }
  EXPECT_GT(stream.stats().evicted, 0u) << "switching views under a small budget must evict";
  EXPECT_EQ(sink.evictions, stream.stats().evicted);
  EXPECT_EQ(sink.held.size(), stream.stats().residentCells);
  // Over budget only by what is pinned this frame (the drawn cells and their ancestors).
  uint64_t pinned = 0;
  std::set<uint32_t> seen;
  const lod::CellSelectStats st = loop.step(b);
  for (uint32_t k = 0; k < st.drawnCells; ++k)
    for (uint32_t c = loop.draw[k].cell; c != lod::kNoCell; c = stream.tree().parent(c))
      if (seen.insert(c).second) pinned += uint64_t{stream.tree().voxels(c)} * sizeof(lod::CellPoint);
  EXPECT_LE(stream.stats().residentBytes, std::max<uint64_t>(o.memoryBudget_bytes, pinned));
}

TEST(CellStream, OpenRefusesBadSourcesNamingThem) {
  CellStream stream;
  CellStreamOptions o;
  std::string err;
  o.source = "/nonexistent/cells.ighc";
  EXPECT_FALSE(stream.open(o, err));
  EXPECT_NE(err.find("/nonexistent/cells.ighc"), std::string::npos) << err;
  // Not a cell database.
  const std::string junk = testing::TempDir() + "/junk_" + std::to_string(::getpid()) + ".ighc";
  {
    std::ofstream f(junk, std::ios::binary);
    f << std::string(4096, 'x');
  }
  o.source = junk;
  err.clear();
  EXPECT_FALSE(stream.open(o, err));
  EXPECT_NE(err.find(junk), std::string::npos) << err;
  EXPECT_NE(err.find("magic"), std::string::npos) << err;
  std::remove(junk.c_str());
  // A server that is not there: open() gives up after its timeout, naming the source.
  o.source = "http://127.0.0.1:9/cells.ighc";
  o.openTimeout_s = 0.3;
  err.clear();
  const auto t0 = Clock::now();
  EXPECT_FALSE(stream.open(o, err));
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 3.0);
  EXPECT_NE(err.find("127.0.0.1:9"), std::string::npos) << err;
  EXPECT_FALSE(stream.isOpen());
}

TEST(CellStream, ServerDownTheFrameLoopGoesOnAndFetchesResume) {
  ig::test::TempDir dir;
  Db db;
  writeDb(db, "served");
  const std::filesystem::path served = dir.path / "cells.ighc";
  std::filesystem::copy_file(db.path, served);
  ig::test::Nginx nginx(dir.path);
  const int port = ig::test::freePort();
  nginx.start(dir.path, port, 0);
  ASSERT_TRUE(nginx.running);
  CellStream stream;
  CellStreamOptions o;
  o.source = nginx.url + "cells.ighc";
  o.fetch.retryMin_ms = 20;
  o.fetch.retryMax_ms = 100;
  o.fetch.connectTimeout_s = 0.5;
  std::string err;
  ASSERT_TRUE(stream.open(o, err)) << err;
  RecordingSink sink;
  Loop loop(stream, sink);
  // A small W: the picture needs many frames to sharpen.
  const lod::CellView v = viewAt({50, -60, 50}, {50, 50, 50}, 20000, 1500);
  const float best = optimum(stream.tree(), v);
  lod::CellSelectStats st;
  for (int i = 0; i < 400 && stream.stats().arrived < 6; ++i) {
    st = loop.step(v);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ASSERT_GE(stream.stats().arrived, 6u);
  nginx.stop();
  // Server down: every frame still selects and draws what is resident, and returns at once.
  // What nginx had already sent may still arrive in the first frames; then nothing. The count
  // to compare with is taken one frame after the fetcher has met the dead server (a failed
  // connect or a retry), not after a fixed number of frames: the fetcher has one keep-alive
  // connection and queues the responses it finished before it counts that failure.
  const io::RangeFetcherStats down = stream.fetchStats();
  uint64_t arrivedBefore = 0;
  bool seenDown = false;
  int slowFrames = 0, counted = 0;
  for (int i = 0; i < 2000 && counted < 40; ++i) {
    const io::RangeFetcherStats now = stream.fetchStats();
    const bool met = now.connectFailures + now.retries > down.connectFailures + down.retries;
    if (seenDown && counted == 0) arrivedBefore = stream.stats().arrived;
    if (seenDown) ++counted;
    seenDown = seenDown || met;
    const auto t0 = Clock::now();
    st = loop.step(v);
    // One stalled frame is the machine (a loaded CI host); a fetch that blocked on the dead
    // server would stall every frame that requests.
    if (std::chrono::duration<double, std::milli>(Clock::now() - t0).count() > 50.0) ++slowFrames;
    EXPECT_GT(st.drawnCells, 0u) << "frame " << i << " drew nothing while the server was down";
    std::this_thread::sleep_for(std::chrono::milliseconds(3));
  }
  ASSERT_TRUE(seenDown) << "the fetcher never met the dead server (no failed connect, no retry)";
  ASSERT_EQ(counted, 40) << "the fetcher met the dead server too late to watch 40 frames after it";
  EXPECT_LE(slowFrames, 2) << "frames blocked on the dead server";
  EXPECT_EQ(stream.stats().arrived, arrivedBefore) << "cells arrived from a server that is down";
  EXPECT_GT(st.maxVoxel_px, best) << "the test needs streaming left to do when the server goes down";
  // Back up on the same port: the fetches resume and the picture reaches the optimum.
  nginx.start(dir.path, port, 0);
  bool reached = false;
  for (int i = 0; i < 3000 && !reached; ++i) {
    st = loop.step(v);
    reached = st.drawnCells > 0 && st.maxVoxel_px <= best * 1.000001f;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_TRUE(reached) << "largest voxel " << st.maxVoxel_px << " px, optimum " << best;
  EXPECT_GT(stream.fetchStats().connectFailures + stream.fetchStats().retries, 0u);
  EXPECT_EQ(stream.stats().broken, 0u) << stream.lastError();
}

// A database truncated below its 128-byte header, served by nginx: nginx answers the header's
// range with the bytes it has (206, "bytes 0-49/50"), which names the file's end. open() refuses at
// once naming the size (it took the answer for a protocol error and retried until the open
// timeout, then reported "no answer"), and a cell range across the end is refused, not retried.
TEST(CellStream, TruncatedDatabaseOverHttpIsRefusedAtOnce) {
  ig::test::TempDir dir;
  Db db;
  writeDb(db, "truncated");
  {
    std::ifstream in(db.path, std::ios::binary);
    std::string head(50, '\0');
    in.read(head.data(), 50);
    std::ofstream(dir.path / "short.ighc", std::ios::binary) << head;
  }
  ig::test::Nginx nginx(dir.path);
  nginx.start(dir.path, 0, 0);
  ASSERT_TRUE(nginx.running);
  CellStream stream;
  CellStreamOptions o;
  o.source = nginx.url + "short.ighc";
  o.openTimeout_s = 5.0;
  o.fetch.retryMin_ms = 20;
  o.fetch.retryMax_ms = 100;
  std::string err;
  const auto t0 = Clock::now();
  EXPECT_FALSE(stream.open(o, err));
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 2.0) << err;
  EXPECT_NE(err.find(o.source), std::string::npos) << err;
  EXPECT_NE(err.find("50 bytes"), std::string::npos) << err;

  // The fetcher itself, before it knows the size: the part of a range inside the file is not
  // what was asked for, so the request is refused (once), naming the size.
  auto f = io::RangeFetcher::open(o.source, o.fetch, err);
  ASSERT_TRUE(f) << err;
  ASSERT_TRUE(f->submit({7, 40, 20, 0, false}, err)) << err;
  std::vector<io::RangeResult> res;
  for (int i = 0; i < 2000 && res.empty(); ++i) {
    f->poll(res);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_EQ(res.size(), 1u);
  EXPECT_FALSE(res[0].ok);
  EXPECT_NE(res[0].error.find("beyond the end"), std::string::npos) << res[0].error;
  EXPECT_NE(res[0].error.find("50 bytes"), std::string::npos) << res[0].error;
  EXPECT_EQ(f->resourceBytes(), 50u);
  EXPECT_EQ(f->stats().retries, 0u);
}

// An index larger than the fetcher's largest range (maxRange_bytes, 64 MiB by default: a database
// of more than 2 M cells) is read in pieces; open() refused it ("size must be 1..N").
TEST(CellStream, IndexLargerThanTheLargestRangeIsReadInPieces) {
  Db db;
  writeDb(db, "bigindex");
  CellStream stream;
  CellStreamOptions o;
  o.source = db.path;
  const uint64_t indexBytes = uint64_t{db.tree.size()} * lod::kCellDbEntryBytes;
  ASSERT_GT(indexBytes, 3 * 1000u) << "the test needs an index of a few pieces";
  o.fetch.maxRange_bytes = 1000;
  std::string err;
  ASSERT_TRUE(stream.open(o, err)) << err;
  EXPECT_EQ(stream.tree().size(), db.tree.size());
  EXPECT_EQ(stream.fetchStats().wireRequests, 1 + (indexBytes + 999) / 1000);
}
