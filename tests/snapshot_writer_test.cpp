// The snapshot writer: PNGs are written off the frame thread, slots are fixed, a full writer
// drops (and counts) instead of blocking, and a failing path is reported, not fatal.
#include <gtest/gtest.h>

#include <filesystem>

#include "ig/snapshot_writer.h"

using namespace ig;

TEST(SnapshotWriter, WritesQueuedImagesAndDropsWhenAllSlotsAreBusy) {
  const auto dir = std::filesystem::temp_directory_path() / ("igd_snap_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  SnapshotWriter w(2, 8, 4);
  render::Image* a = w.acquire();
  render::Image* b = w.acquire();
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  EXPECT_NE(a, b);
  EXPECT_EQ(a->rgba.size(), 8u * 4u * 4u);  // preallocated at start-up
  EXPECT_EQ(w.acquire(), nullptr);          // both slots filling: dropped, not blocked
  EXPECT_EQ(w.dropped(), 1u);
  a->rgba.assign(a->rgba.size(), 200);
  w.submit(a, (dir / "a.png").c_str());
  w.submit(b, "/nonexistent-dir/b.png");
  w.flush();
  EXPECT_EQ(w.written(), 1u);
  EXPECT_EQ(w.failed(), 1u);
  EXPECT_NE(w.firstError().find("/nonexistent-dir/b.png"), std::string::npos) << w.firstError();
  render::Image back;
  std::string error;
  ASSERT_TRUE(render::readPng((dir / "a.png").string(), back, error)) << error;
  EXPECT_EQ(back.width, 8);
  EXPECT_EQ(back.rgba[0], 200);
  EXPECT_NE(w.acquire(), nullptr);  // slots are free again after the writes
  std::filesystem::remove_all(dir);
}

// A write error the C library reports only when the file is flushed or closed (a full disk,
// an I/O error) is a failed snapshot, not a written one: a small PNG fits in stdio's buffer,
// so every byte of it reaches the disk in fclose(). /dev/full fails every write with ENOSPC.
TEST(SnapshotWriter, AWriteErrorAtCloseIsAFailureNotAWrittenSnapshot) {
  ASSERT_TRUE(std::filesystem::exists("/dev/full"));  // Linux always has it
  render::Image small;
  small.width = 16;
  small.height = 16;
  small.rgba.assign(16u * 16u * 4u, 128);
  std::string error;
  EXPECT_FALSE(render::writePng("/dev/full", small, error));
  EXPECT_NE(error.find("/dev/full"), std::string::npos) << error;

  SnapshotWriter w(1, 16, 16);
  render::Image* a = w.acquire();
  ASSERT_NE(a, nullptr);
  a->rgba.assign(a->rgba.size(), 90);
  w.submit(a, "/dev/full");
  w.flush();
  EXPECT_EQ(w.written(), 0u);
  EXPECT_EQ(w.failed(), 1u);
}

// An image whose pixel buffer does not hold width x height RGBA pixels is refused, naming the
// sizes, before anything is read from it (libpng would read past the buffer) or written.
TEST(SnapshotWriter, AnImageSmallerThanItsSizeIsRefused) {
  const std::string file = std::filesystem::temp_directory_path() / ("igd_short_" + std::to_string(::getpid()) + ".png");
  std::filesystem::remove(file);
  ig::render::Image image;
  image.width = 64;
  image.height = 64;
  image.rgba.assign(16, 0);
  std::string error;
  EXPECT_FALSE(ig::render::writePng(file, image, error));
  EXPECT_NE(error.find("64 x 64"), std::string::npos) << error;
  EXPECT_NE(error.find("16 bytes"), std::string::npos) << error;
  EXPECT_FALSE(std::filesystem::exists(file));
  image.rgba.clear();
  image.width = 0;
  EXPECT_FALSE(ig::render::writePng(file, image, error));
  EXPECT_FALSE(std::filesystem::exists(file));
}
