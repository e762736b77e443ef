// lod/hdlod_models: PLY (ascii with a quad fanned, binary little and big endian with extra
// properties skipped, bad index / truncated / not PLY named with the file) and glTF 2.0 (a
// data-URI buffer, node transforms, y up -> z up, bad files named), and schedules binding them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "lod/hdlod_scene.h"

using namespace ig::lod::hdlod;

namespace {

std::string tempPath(const std::string& name) { return std::string(IG_BINARY_DIR) + "/hdlod_models_test_" + name; }

std::string writeFile(const std::string& name, const std::string& bytes) {
  const std::string path = tempPath(name);
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

template <typename T>
void put(std::string& s, T v, bool bigEndian) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof v);
  if (bigEndian) std::reverse(b, b + sizeof v);
  s.append(b, sizeof v);
}

// A triangle (0,0,0) (1,0,0) (0,1,0) in glTF's y-up frame, indices as unsigned shorts, under a
// node translated by (10, 0, 0) whose child is translated by (0, 5, 0).
const char* kGltf = R"({
  "asset": {"version": "2.0"},
  "scene": 0,
  "scenes": [{"nodes": [0]}],
  "nodes": [{"translation": [10, 0, 0], "children": [1]}, {"translation": [0, 5, 0], "mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "buffers": [{"byteLength": 44, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
    {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
  ]
})";

}  // namespace

TEST(HdlodModels, PlyAsciiQuadIsFanned) {
  const std::string path = writeFile("quad.ply",
                                     "ply\nformat ascii 1.0\ncomment a unit quad\nelement vertex 4\nproperty float x\nproperty float y\n"
                                     "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                                     "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n");
  std::string error;
  const auto m = loadPly(path, error);
  ASSERT_TRUE(m) << error;
  EXPECT_EQ(m->positions.size(), 4u);
  EXPECT_EQ(m->indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(m->box.max, glm::dvec3(1, 1, 0));
}

TEST(HdlodModels, PlyBinaryBothByteOrdersSkipOtherProperties) {
  for (bool big : {false, true}) {
    std::string s = std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                    " 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\n"
                    "element face 1\nproperty uchar flags\nproperty list uchar uint vertex_index\nend_header\n";
    const double v[3][3] = {{0, 0, 0}, {2, 0, 0}, {0, 0, 3}};
    for (const auto& p : v) {
      for (double c : p) put(s, c, big);
      put<uint8_t>(s, 200, big);
    }
    put<uint8_t>(s, 7, big);
    put<uint8_t>(s, 3, big);
    for (uint32_t i : {2u, 1u, 0u}) put(s, i, big);
    std::string error;
    const auto m = loadPly(writeFile(big ? "be.ply" : "le.ply", s), error);
    ASSERT_TRUE(m) << error;
    EXPECT_EQ(m->indices, (std::vector<uint32_t>{2, 1, 0})) << big;
    EXPECT_EQ(m->box.max, glm::dvec3(2, 0, 3)) << big;
  }
}

TEST(HdlodModels, PlyErrorsNameTheFileAndValue) {
  std::string error;
  const std::string head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                           "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
  const std::string badIndex = writeFile("badindex.ply", head + "3 0 1 7\n");
  EXPECT_FALSE(loadPly(badIndex, error));
  EXPECT_NE(error.find(badIndex), std::string::npos) << error;
  EXPECT_NE(error.find("bad vertex index 7"), std::string::npos) << error;
  // Indices stored as floats: a fraction or one beyond every integer type is named as written.
  const std::string floatHead = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                "property float z\nelement face 1\nproperty list uchar double vertex_indices\n"
                                "end_header\n0 0 0\n1 0 0\n0 1 0\n";
  EXPECT_FALSE(loadPly(writeFile("hugeindex.ply", floatHead + "3 0 1 1e300\n"), error));
  EXPECT_NE(error.find("bad vertex index 1e+300 "), std::string::npos) << error;
  EXPECT_FALSE(loadPly(writeFile("halfindex.ply", floatHead + "3 0 1 1.5\n"), error));
  EXPECT_NE(error.find("bad vertex index 1.5 "), std::string::npos) << error;
  EXPECT_FALSE(loadPly(writeFile("truncated.ply", head + "3 0 1\n"), error));
  EXPECT_NE(error.find("truncated"), std::string::npos) << error;
  EXPECT_FALSE(loadPly(writeFile("notply.ply", "solid x\n"), error));
  EXPECT_NE(error.find("not a PLY file"), std::string::npos) << error;
  EXPECT_FALSE(loadPly(writeFile("noend.ply", "ply\nformat ascii 1.0\n"), error));
  EXPECT_NE(error.find("end_header"), std::string::npos) << error;
  EXPECT_FALSE(loadPly(writeFile("nan.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                                            "property float z\nend_header\n0 nan 0\n"),
                       error));
  EXPECT_FALSE(loadPly(tempPath("missing.ply"), error));
  EXPECT_NE(error.find("cannot open"), std::string::npos) << error;
}

TEST(HdlodModels, GltfNodesTransformedToZUp) {
  std::string error;
  const auto m = loadGltf(writeFile("tri.gltf", kGltf), error);
  ASSERT_TRUE(m) << error;
  ASSERT_EQ(m->positions.size(), 3u);
  EXPECT_EQ(m->indices, (std::vector<uint32_t>{0, 1, 2}));
  // glTF (x, y, z) + (10, 5, 0) -> ours (x, -z, y).
  EXPECT_EQ(m->positions[0], glm::vec3(10, 0, 5));
  EXPECT_EQ(m->positions[1], glm::vec3(11, 0, 5));
  EXPECT_EQ(m->positions[2], glm::vec3(10, 0, 6));
  // Through a schedule, and loadModelFile by extension.
  const std::string sched = writeFile("gltf.sched",
                                      "hdlod-schedule 1\nduration_s 10\nmodel tri gltf hdlod_models_test_tri.gltf\n"
                                      "model quad ply hdlod_models_test_gltf_quad.ply\nobject a tri\nat a 0 0 0 0 0\n");
  // Not quad.ply: PlyAsciiQuadIsFanned writes that one, and ctest -j runs the two at once.
  writeFile("gltf_quad.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                             "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  const auto scene = loadSchedule(sched, error);
  ASSERT_TRUE(scene) << error;
  EXPECT_EQ(scene->models[0].triangleCount(), 1u);
  EXPECT_EQ(scene->models[1].triangleCount(), 1u);
  EXPECT_TRUE(loadModelFile(tempPath("tri.gltf"), error)) << error;
  EXPECT_FALSE(loadModelFile(tempPath("tri.stl"), error));
  EXPECT_NE(error.find("unknown model format"), std::string::npos) << error;
}

TEST(HdlodModels, GltfErrorsNameTheFile) {
  std::string error;
  const std::string notJson = writeFile("bad.gltf", "{ not json");
  EXPECT_FALSE(loadGltf(notJson, error));
  EXPECT_NE(error.find(notJson), std::string::npos) << error;
  std::string bad = kGltf;
  bad.replace(bad.find("\"count\": 3, \"type\": \"SCALAR\""), std::strlen("\"count\": 3, \"type\": \"SCALAR\""),
              "\"count\": 30, \"type\": \"SCALAR\"");
  EXPECT_FALSE(loadGltf(writeFile("overrun.gltf", bad), error));
  EXPECT_NE(error.find("past the end"), std::string::npos) << error;
  EXPECT_FALSE(loadGltf(tempPath("missing.glb"), error));
  EXPECT_NE(error.find("missing.glb"), std::string::npos) << error;
}

namespace {
// kGltf with `from` replaced by `to` (once).
std::string gltfWith(const std::string& from, const std::string& to) {
  std::string s = kGltf;
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}
}  // namespace

// Accessor offsets and counts are 64-bit numbers from the file; sums and products that
// wrap must not let an accessor read outside its buffer. A count of 2^62 + 1 with byteStride 4
// made (count - 1) * stride zero and the loader read hundreds of vertices past the 44-byte
// buffer; a byteOffset of 2^64 - 8 made the accessor start 8 bytes before it.
TEST(HdlodModels, GltfAccessorOffsetAndCountCannotWrapPastTheBuffer) {
  std::string error;
  const std::string countWrap =
      gltfWith("{\"buffer\": 0, \"byteOffset\": 0, \"byteLength\": 36}", "{\"buffer\": 0, \"byteOffset\": 0, \"byteLength\": 36, \"byteStride\": 4}");
  const std::string countWrap2 = [&] {
    std::string s = countWrap;
    const std::string from = "\"componentType\": 5126, \"count\": 3";
    s.replace(s.find(from), from.size(), "\"componentType\": 5126, \"count\": 4611686018427387905");
    return s;
  }();
  EXPECT_FALSE(loadGltf(writeFile("count_wrap.gltf", countWrap2), error));
  EXPECT_NE(error.find("past the end"), std::string::npos) << error;
  EXPECT_NE(error.find("count_wrap.gltf"), std::string::npos) << error;
  const std::string offsetWrap = gltfWith("{\"bufferView\": 0, \"componentType\": 5126,",
                                          "{\"bufferView\": 0, \"byteOffset\": 18446744073709551608, \"componentType\": 5126,");
  EXPECT_FALSE(loadGltf(writeFile("offset_wrap.gltf", offsetWrap), error));
  EXPECT_NE(error.find("past the end"), std::string::npos) << error;
  const std::string viewWrap = gltfWith("{\"buffer\": 0, \"byteOffset\": 36, \"byteLength\": 6}",
                                        "{\"buffer\": 0, \"byteOffset\": 18446744073709551615, \"byteLength\": 6}");
  EXPECT_FALSE(loadGltf(writeFile("view_wrap.gltf", viewWrap), error));
  EXPECT_NE(error.find("past the end"), std::string::npos) << error;
}

// Without a "scenes" array every node was taken as a root, so a child node's mesh was
// loaded twice (once without its parent's transform). glTF hierarchies are strict trees: a node
// named as a child twice (which multiplies the geometry exponentially) is refused.
TEST(HdlodModels, GltfWithoutSceneLoadsEachNodeOnceAndSharedChildrenAreRefused) {
  std::string error;
  std::string noScene = gltfWith("\"scene\": 0,\n  \"scenes\": [{\"nodes\": [0]}],\n", "");
  const auto m = loadGltf(writeFile("noscene.gltf", noScene), error);
  ASSERT_TRUE(m) << error;
  EXPECT_EQ(m->triangleCount(), 1u);
  EXPECT_EQ(m->positions[0], glm::vec3(10, 0, 5));
  // Node 0 names node 1 twice; a 2-node cycle.
  const std::string shared = gltfWith("\"children\": [1]", "\"children\": [1, 1]");
  EXPECT_FALSE(loadGltf(writeFile("shared.gltf", shared), error));
  EXPECT_NE(error.find("reached twice"), std::string::npos) << error;
  const std::string cycle = gltfWith("{\"translation\": [0, 5, 0], \"mesh\": 0}", "{\"translation\": [0, 5, 0], \"mesh\": 0, \"children\": [0]}");
  EXPECT_FALSE(loadGltf(writeFile("cycle.gltf", cycle), error));
  EXPECT_NE(error.find("cycle.gltf"), std::string::npos) << error;
}

// Coordinates that are finite doubles but not finite floats (1e39) became infinite
// vertices in OBJ, PLY and glTF models; they are errors naming the file (and line for OBJ).
TEST(HdlodModels, CoordinatesBeyondTheFloatRangeAreErrors) {
  std::string error;
  const std::string obj = writeFile("huge.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_FALSE(loadObj(obj, error));
  EXPECT_NE(error.find(obj + ":2:"), std::string::npos) << error;
  const std::string ply = writeFile("huge.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nproperty double y\n"
                                                "property double z\nend_header\n0 -1e39 0\n");
  EXPECT_FALSE(loadPly(ply, error));
  EXPECT_NE(error.find("huge.ply"), std::string::npos) << error;
  const std::string gltf = gltfWith("\"translation\": [10, 0, 0]", "\"translation\": [1e39, 0, 0]");
  EXPECT_FALSE(loadGltf(writeFile("huge.gltf", gltf), error));
  EXPECT_NE(error.find("not finite"), std::string::npos) << error;
}

// A scan in absolute coordinates (ECEF ~6.4e6 m, where a float's step is 0.5 m) lost its detail
// when stored as float: with a local origin the loaders subtract the first vertex in double, so
// centimetre offsets survive (igtool cells-build loads this way).
TEST(HdlodModels, LocalOriginKeepsDetailFarFromTheOrigin) {
  constexpr double kFar = 6378137.0;
  const double want[3][3] = {{kFar, kFar, kFar}, {kFar + 0.012, kFar, kFar}, {kFar, kFar + 0.034, kFar - 0.021}};
  const auto check = [&](const std::optional<Model>& m, const glm::dvec3& origin, const std::string& error,
                         const char* what) {
    ASSERT_TRUE(m) << what << ": " << error;
    ASSERT_EQ(m->positions.size(), 3u) << what;
    for (size_t i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k)
        EXPECT_NEAR(origin[k] + static_cast<double>(m->positions[i][k]), want[i][k], 1e-5) << what << " vertex " << i;
  };
  char buf[512];
  std::snprintf(buf, sizeof buf, "v %.6f %.6f %.6f\nv %.6f %.6f %.6f\nv %.6f %.6f %.6f\nf 1 2 3\n", want[0][0], want[0][1],
                want[0][2], want[1][0], want[1][1], want[1][2], want[2][0], want[2][1], want[2][2]);
  const std::string obj = writeFile("far.obj", buf);
  std::string ply = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
                    "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  for (const auto& v : want)
    for (double c : v) put(ply, c, false);
  put(ply, uint8_t{3}, false);
  for (int32_t i = 0; i < 3; ++i) put(ply, i, false);
  const std::string plyPath = writeFile("far.ply", ply);
  std::string error;
  glm::dvec3 origin(1.0);
  check(loadObj(obj, error, &origin), origin, error, "obj");
  check(loadPly(plyPath, error, &origin), origin, error, "ply");
  check(loadModelFile(obj, error, &origin), origin, error, "loadModelFile obj");
  // Without a local origin the coordinates are stored as they are.
  const auto plain = loadObj(obj, error);
  ASSERT_TRUE(plain) << error;
  EXPECT_EQ(plain->positions[0], glm::vec3(static_cast<float>(kFar)));
  // glTF: a node translated far from the origin (the triangle's vertices 1 m apart), y up -> z up.
  const std::string gltf = gltfWith("\"translation\": [10, 0, 0]", "\"translation\": [6378137, 0, -6378137]");
  const auto g = loadGltf(writeFile("far.gltf", gltf), error, &origin);
  ASSERT_TRUE(g) << error;
  ASSERT_EQ(g->positions.size(), 3u);
  EXPECT_NEAR(origin.x, kFar, 1e-6);
  EXPECT_NEAR(origin.y, kFar, 1e-6);
  EXPECT_NEAR(origin.z, 5.0, 1e-6);
  EXPECT_EQ(g->positions[0], glm::vec3(0, 0, 0));
  EXPECT_EQ(g->positions[1], glm::vec3(1, 0, 0));
  EXPECT_EQ(g->positions[2], glm::vec3(0, 0, 1));
  // An empty model: the origin is 0.
  ASSERT_TRUE(loadObj(writeFile("empty.obj", ""), error, &origin)) << error;
  EXPECT_EQ(origin, glm::dvec3(0.0));
}

// A PLY value that is not a finite number was "truncated or not a number", naming neither: the
// error names the value as written (ascii) or read (binary), the property and the file.
TEST(HdlodModels, PlyBadValuesAreNamed) {
  const std::string head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                           "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  std::string error;
  EXPECT_FALSE(loadPly(writeFile("nanvalue.ply", head + "0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n"), error));
  EXPECT_NE(error.find("nanvalue.ply"), std::string::npos) << error;
  EXPECT_NE(error.find("property y: not a finite number: 'nan'"), std::string::npos) << error;
  EXPECT_FALSE(loadPly(writeFile("wordvalue.ply", head + "0 0 0\n1 0 0\n0 1 zero\n3 0 1 2\n"), error));
  EXPECT_NE(error.find("'zero'"), std::string::npos) << error;
  EXPECT_FALSE(loadPly(writeFile("badlength.ply", head + "0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n"), error));
  EXPECT_NE(error.find("bad list length -3"), std::string::npos) << error;
  std::string bin = "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                    "property float z\nend_header\n";
  put(bin, 0.0f, false);
  put(bin, -std::numeric_limits<float>::infinity(), false);
  put(bin, 0.0f, false);
  EXPECT_FALSE(loadPly(writeFile("infvalue.ply", bin), error));
  EXPECT_NE(error.find("property y: not a finite number: '-inf'"), std::string::npos) << error;
  // The end of the data is still "truncated".
  EXPECT_FALSE(loadPly(writeFile("shortvalue.ply", head + "0 0 0\n1 0 0\n0 1"), error));
  EXPECT_NE(error.find("property z: truncated"), std::string::npos) << error;
}
