// Geomorphing: a new vertex moves from its start height to its true height over morph_s,
// finished morphs expire, a full table lets vertices pop instead of failing, 0 s is off.
#include <gtest/gtest.h>

#include "lod/geomorph.h"

using namespace ig::lod;

TEST(Geomorph, MovesLinearlyToTheTrueHeightThenExpires) {
  Geomorph g(64, 0.5);
  g.start(10, 20, 100.0f, 2.0);
  EXPECT_TRUE(g.contains(10, 20));
  EXPECT_FALSE(g.contains(20, 10));
  EXPECT_FLOAT_EQ(g.height(10, 20, 200.0f, 2.0), 100.0f);
  EXPECT_FLOAT_EQ(g.height(10, 20, 200.0f, 2.25), 150.0f);
  EXPECT_FLOAT_EQ(g.height(10, 20, 200.0f, 2.5), 200.0f);
  EXPECT_FLOAT_EQ(g.height(10, 20, 200.0f, 9.0), 200.0f);
  EXPECT_FLOAT_EQ(g.height(11, 20, 200.0f, 2.0), 200.0f);  // not morphing: the true height
  g.start(10, 20, 0.0f, 2.1);                             // already morphing: unchanged
  EXPECT_FLOAT_EQ(g.height(10, 20, 200.0f, 2.25), 150.0f);
  EXPECT_TRUE(g.active(2.4));
  g.expire(2.4);
  EXPECT_EQ(g.size(), 1u);
  g.expire(2.5);
  EXPECT_EQ(g.size(), 0u);
  EXPECT_FALSE(g.contains(10, 20));
  EXPECT_FALSE(g.active(2.6));
}

TEST(Geomorph, ManyVerticesExpireSelectivelyAndAFullTablePops) {
  Geomorph g(100, 1.0);
  for (int i = 0; i < 100; ++i) g.start(i, -i, static_cast<float>(i), i < 50 ? 0.0 : 0.5);
  EXPECT_EQ(g.size(), 100u);
  g.start(1000, 1000, 5.0f, 0.5);  // over capacity: ignored, the vertex pops
  EXPECT_FALSE(g.contains(1000, 1000));
  g.expire(1.2);  // the first 50 finished at 1.0, the rest run until 1.5
  EXPECT_EQ(g.size(), 50u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(g.contains(i, -i), i >= 50) << i;
  EXPECT_FLOAT_EQ(g.height(70, -70, 170.0f, 1.0), 120.0f);  // start 70, halfway to 170
}

TEST(Geomorph, ZeroTimeIsOff) {
  Geomorph g(16, 0.0);
  g.start(1, 1, 5.0f, 0.0);
  EXPECT_EQ(g.size(), 0u);
  EXPECT_FLOAT_EQ(g.height(1, 1, 9.0f, 0.0), 9.0f);
}
