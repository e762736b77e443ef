// lod/hdlod_scene: presence at 0, T, before 0, after T and NaN; keyframe interpolation;
// classification; the schedule format and its errors (file:line and the bad value); OBJ models.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>

#include "lod/hdlod_scene.h"

using namespace ig::lod;
using namespace ig::lod::hdlod;

namespace {

Object objectWith(std::vector<Interval> visible, std::vector<Keyframe> path = {{0.0, glm::dvec3(0.0), 0.0}}) {
  Object o;
  o.name.push_back('o');  // (GCC 12 -O3 warns falsely on assigning a literal here)
  o.visible = std::move(visible);
  o.path = std::move(path);
  return o;
}

std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = std::string(IG_BINARY_DIR) + "/" + name;
  std::ofstream(path) << text;
  return path;
}

}  // namespace

TEST(HdlodScene, PresenceAtTheEndsOfTime) {
  const double T = 100.0, nan = std::numeric_limits<double>::quiet_NaN();
  const Object always = objectWith({{0.0, T}});
  for (double t : {-5.0, 0.0, 50.0, T, 1e9, nan}) EXPECT_TRUE(isPresent(always, t, T)) << t;
  const Object later = objectWith({{10.0, 20.0}, {30.0, T}});
  EXPECT_FALSE(isPresent(later, -1.0, T));
  EXPECT_FALSE(isPresent(later, 0.0, T));
  EXPECT_TRUE(isPresent(later, 10.0, T));   // appear is inclusive
  EXPECT_FALSE(isPresent(later, 20.0, T));  // disappear is exclusive
  EXPECT_TRUE(isPresent(later, T, T));      // an interval reaching T includes T
  EXPECT_TRUE(isPresent(later, 2 * T, T));  // clamped to T
  EXPECT_FALSE(isPresent(later, nan, T));   // NaN reads as 0
  const Object early = objectWith({{-10.0, 5.0}});
  EXPECT_TRUE(isPresent(early, -3.0, T));
  EXPECT_TRUE(isPresent(early, 0.0, T));
  EXPECT_FALSE(isPresent(early, 5.0, T));
  const Object atEnd = objectWith({{T, T + 10}});  // starts at T: its breakpoint is dropped
  EXPECT_FALSE(isPresent(atEnd, T, T));
  EXPECT_FALSE(isPresent(objectWith({}), 50.0, T));
}

TEST(HdlodScene, KeyframesInterpolateAndClamp) {
  const double T = 10.0;
  const Object o = objectWith({{0, T}}, {{2.0, {0, 0, 0}, 350.0}, {4.0, {10, 20, 30}, 10.0}});
  const glm::dmat4 mid = objectMatrix(o, 3.0, T);
  EXPECT_NEAR(mid[3].x, 5.0, 1e-12);
  EXPECT_NEAR(mid[3].y, 10.0, 1e-12);
  EXPECT_NEAR(mid[3].z, 15.0, 1e-12);
  // 350 -> 10 deg goes through north (0), the shorter arc: the model's +y stays north.
  EXPECT_NEAR(mid[1].x, 0.0, 1e-12);
  EXPECT_NEAR(mid[1].y, 1.0, 1e-12);
  // Heading 90 (east): the model's +y points east.
  const glm::dmat4 east = keyframeMatrix({0.0, glm::dvec3(0.0), 90.0});
  EXPECT_NEAR(east[1].x, 1.0, 1e-12);
  EXPECT_NEAR(east[1].y, 0.0, 1e-12);
  // Before the first / after the last keyframe, and beyond [0, T]: held.
  EXPECT_EQ(objectMatrix(o, 0.0, T), objectMatrix(o, 2.0, T));
  EXPECT_EQ(objectMatrix(o, -50.0, T), objectMatrix(o, 2.0, T));
  EXPECT_EQ(objectMatrix(o, 1e9, T), objectMatrix(o, 4.0, T));
  EXPECT_EQ(objectMatrix(o, std::numeric_limits<double>::quiet_NaN(), T), objectMatrix(o, 2.0, T));
}

TEST(HdlodScene, Classification) {
  const double T = 10.0;
  EXPECT_EQ(classify(objectWith({{0, T}}), T), ObjectClass::Static);
  EXPECT_EQ(classify(objectWith({{-1, 2 * T}}), T), ObjectClass::Static);
  EXPECT_EQ(classify(objectWith({{2, T}}), T), ObjectClass::PseudoDynamic);
  EXPECT_EQ(classify(objectWith({}), T), ObjectClass::PseudoDynamic);  // absent
  EXPECT_EQ(classify(objectWith({{0, T}}, {{0, {0, 0, 0}, 0}, {5, {0, 0, 0}, 360}}), T), ObjectClass::Static);
  EXPECT_EQ(classify(objectWith({{0, T}}, {{0, {0, 0, 0}, 0}, {5, {0, 0, 0}, 30}}), T), ObjectClass::Dynamic);
  EXPECT_EQ(classify(objectWith({{0, T}}, {{0, {0, 0, 0}, 0}, {5, {1, 0, 0}, 0}}), T), ObjectClass::Dynamic);
}

TEST(HdlodScene, TransformedAndSweptBoxesHoldTheModel) {
  const Model m = makeBoxModel("b", {4, 2, 1});
  const Aabb r = transformBox(m.box, keyframeMatrix({0, {100, 0, 0}, 90}));
  EXPECT_NEAR(r.min.x, 99.0, 1e-9);
  EXPECT_NEAR(r.max.x, 101.0, 1e-9);
  EXPECT_NEAR(r.min.y, -2.0, 1e-9);
  EXPECT_NEAR(r.max.y, 2.0, 1e-9);
  const Object o = objectWith({{0, 10}}, {{0, {0, 0, 0}, 0}, {10, {50, 0, 0}, 180}});
  const Aabb s = sweptBox(o, m);
  for (double t = 0; t <= 10; t += 0.5) {
    const Aabb b = transformBox(m.box, objectMatrix(o, t, 10));
    EXPECT_TRUE(s.contains(b.min) && s.contains(b.max)) << t;
  }
}

TEST(HdlodScene, ScheduleParses) {
  const std::string text =
      "hdlod-schedule 1\n# a comment\nduration_s 100\nmodel col box 0.5 0.5 3\n"
      "object c1 col\nat c1 0 10 20 0 45\nvisible c1 10 50\nvisible c1 60 200\n"
      "object c2 col\nat c2 0 0 0 0 0\n"
      "object truck col\nat truck 0 0 0 0 0\nat truck 50 100 0 0 90   # moves\n"
      "object gone col\nat gone 0 0 0 0 0\nvisible gone never\n";
  std::string error;
  const auto s = parseSchedule(text, "site.sched", "", error);
  ASSERT_TRUE(s) << error;
  EXPECT_EQ(s->duration_s, 100.0);
  ASSERT_EQ(s->objects.size(), 4u);
  EXPECT_EQ(s->objects[0].visible.size(), 2u);
  EXPECT_EQ(classify(s->objects[0], s->duration_s), ObjectClass::PseudoDynamic);
  EXPECT_EQ(classify(s->objects[1], s->duration_s), ObjectClass::Static);  // no 'visible': always
  EXPECT_EQ(classify(s->objects[2], s->duration_s), ObjectClass::Dynamic);
  EXPECT_TRUE(s->objects[3].visible.empty());
  EXPECT_EQ(s->models[0].triangleCount(), 12u);
}

TEST(HdlodScene, ScheduleErrorsNameFileLineAndValue) {
  struct Case {
    std::string text, expect;
  };
  const std::string head = "hdlod-schedule 1\nduration_s 100\nmodel m box 1 1 1\nobject a m\n";
  const Case cases[] = {
      {"", "s.sched: empty file"},
      {"hdlod-schedule 2\n", "s.sched:1: expected header"},
      {"hdlod-schedule 1\nduration_s -4\n", "s.sched:2: duration_s: must be one finite number > 0: duration_s -4"},
      {"hdlod-schedule 1\nduration_s nan\n", "s.sched:2: duration_s"},
      {"hdlod-schedule 1\nmodel m box 1 1\n", "s.sched:2: model box"},
      {"hdlod-schedule 1\nduration_s 1\n", "s.sched: missing"},  // fine so far; no objects is allowed
      {head + "at a 0 1 2 x 0\n", "s.sched:5: at: expected"},
      {head + "at a 0 1 2 inf 0\n", "s.sched:5: at: expected"},
      {head + "at a 5 0 0 0 0\nat a 5 1 0 0 0\n", "s.sched:6: at a: keyframe time 5 not after"},
      {head + "at a 0 0 0 0 0\nvisible a 10 20\nvisible a 15 30\n", "s.sched:7: visible a: interval appearing at 15 overlaps"},
      {head + "at a 0 0 0 0 0\nvisible a 20 10\n", "s.sched:6: visible a: appear 20 not before disappear 10"},
      {head + "object b nosuch\n", "s.sched:5: object b: unknown model: nosuch"},
      {head + "object a m\n", "s.sched:5: object: duplicate name: a"},
      {head + "visible zz 0 1\n", "s.sched:5: visible: unknown object: zz"},
      {head, "s.sched:4: object a: no 'at' keyframe"},
      {head + "at a 0 0 0 0 0\nfly a\n", "s.sched:6: unknown line kind: fly"},
      {"hdlod-schedule 1\nduration_s 5\nmodel m obj missing.obj\n", "s.sched:3: model m: missing.obj: cannot open"},
  };
  for (const Case& c : cases) {
    std::string error;
    const auto s = parseSchedule(c.text, "s.sched", "", error);
    if (c.expect == "s.sched: missing") {
      EXPECT_TRUE(s) << error;  // a header and a duration make a valid (empty) scene
      continue;
    }
    EXPECT_FALSE(s) << c.text;
    EXPECT_EQ(error.rfind(c.expect, 0), 0u) << "got: " << error << "\nwant prefix: " << c.expect;
  }
  std::string error;
  EXPECT_FALSE(loadSchedule("/nonexistent/x.sched", error));
  EXPECT_EQ(error, "/nonexistent/x.sched: cannot open");
}

TEST(HdlodScene, ObjModelsRelativeToTheSchedule) {
  writeTemp("hdlod_tri.obj", "# two triangles as a quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1/1/1 2//1 3 4\n");
  const std::string sched = writeTemp("hdlod_obj.sched", "hdlod-schedule 1\nduration_s 10\nmodel q obj hdlod_tri.obj\nobject a q\nat a 0 0 0 0 0\n");
  std::string error;
  const auto s = loadSchedule(sched, error);
  ASSERT_TRUE(s) << error;
  EXPECT_EQ(s->models[0].triangleCount(), 2u);
  EXPECT_EQ(s->models[0].box.max.x, 1.0);
  const std::string bad = writeTemp("hdlod_bad.obj", "v 0 0 0\nv 1 0 0\nf 1 2 7\n");
  EXPECT_FALSE(loadObj(bad, error));
  EXPECT_NE(error.find("hdlod_bad.obj:3: bad vertex index: 7"), std::string::npos) << error;
}

TEST(HdlodScene, ValidateCatchesBrokenScenes) {
  Scene s;
  s.duration_s = 10;
  s.models.push_back(makeBoxModel("b", {1, 1, 1}));
  s.objects.push_back(objectWith({{0, 10}}));
  EXPECT_EQ(validateScene(s), "");
  s.models[0].indices.push_back(99);
  EXPECT_NE(validateScene(s), "");
  s.models[0].indices.resize(36);
  s.objects[0].path.push_back({0.0, glm::dvec3(std::nan("")), 0});
  EXPECT_NE(validateScene(s).find("non-finite keyframe"), std::string::npos);
}
