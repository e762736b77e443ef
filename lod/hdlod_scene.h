// HDLOD, part 1: the 4D scene model of paper 000 (shared/seeds/000, section 2; digest in
// shared/SEEDS.md): a scene S(t), t in [0, T], is a list of objects s = (g_s, v_s, p_s) with
// triangle geometry g_s (a "polygon soup": no manifold or connectivity assumptions), a
// visibility function v_s(t) -> {0, 1} and a position function p_s(t) -> 4x4 matrix.
//
// Here g_s is an instance of a shared Model (indexed triangles, float positions in model space),
// v_s is a list of sorted, non-overlapping presence intervals [appear, disappear), and p_s is a
// list of keyframes (time, position, heading) interpolated linearly (heading along the shorter
// arc) and held constant before the first and after the last keyframe.
//
// Time: every function of time clamps t to [0, T] first (NaN reads as 0). The presence at t is
// a step function on [0, T] whose breakpoints are the interval ends inside [0, T): an interval
// that reaches T (disappear >= T) includes T itself, one that starts at or before 0 includes 0.
//
// Classes (paper, section 2): static (present on all of [0, T], never moves), pseudo-dynamic
// (appears and/or disappears, never moves), dynamic (moves). "Moves" means two keyframes differ
// in position or heading.
//
// The text schedule format and its loader are documented in docs/hdlod.md; loadSchedule() names
// file:line and the bad value on every error.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "lod/view.h"

namespace ig::lod::hdlod {

struct Model {
  std::string name;
  std::vector<glm::vec3> positions;  // model space, metres (x east, y north, z up at heading 0)
  std::vector<uint32_t> indices;     // three per triangle, each < positions.size()
  Aabb box;                          // of positions; all zero for a model without vertices
  size_t triangleCount() const { return indices.size() / 3; }
};

// Present on [appear_s, disappear_s).
struct Interval {
  double appear_s = 0.0;
  double disappear_s = 0.0;
};

struct Keyframe {
  double t_s = 0.0;
  glm::dvec3 position_m{0.0};  // world (local ENU), where the model's origin goes
  double heading_deg = 0.0;    // clockwise from north, about the up axis
};

struct Object {
  std::string name;
  uint32_t model = 0;
  std::vector<Interval> visible;  // sorted, non-overlapping, appear < disappear; empty = never present
  std::vector<Keyframe> path;     // at least one, strictly increasing t_s
};

enum class ObjectClass : uint8_t { Static, PseudoDynamic, Dynamic };
const char* objectClassName(ObjectClass c);

struct Scene {
  double duration_s = 1.0;  // T > 0
  std::vector<Model> models;
  std::vector<Object> objects;
};

// t clamped to [0, T]; NaN -> 0.
double clampTime(double t_s, double duration_s);
// v_s(t) with the clamping and end rules above.
bool isPresent(const Object& object, double t_s, double duration_s);
// p_s(t): translate(position) * rotateZ(-heading). t is clamped like every function of time.
glm::dmat4 objectMatrix(const Object& object, double t_s, double duration_s);
// The matrix of a keyframe.
glm::dmat4 keyframeMatrix(const Keyframe& k);
ObjectClass classify(const Object& object, double duration_s);
// The model's box transformed by a rigid matrix (conservative, exact for rotations about z).
Aabb transformBox(const Aabb& box, const glm::dmat4& m);
// A box holding the model at every time of the object's path (keyframe positions + the model's
// radius around its origin), so it holds the interpolated positions too.
Aabb sweptBox(const Object& object, const Model& model);

// Recomputes every model's box from its positions.
void computeModelBoxes(Scene& scene);
// Checks the invariants above (indices in range, intervals sorted and non-overlapping, keyframes
// increasing, finite numbers, T > 0, model indices valid). Returns "" or the first problem,
// naming the object or model and the bad value.
std::string validateScene(const Scene& scene);

// Loads a schedule file (docs/hdlod.md). Relative model paths are relative to the file. On error
// returns nothing and sets `error` to "file:line: what: value".
std::optional<Scene> loadSchedule(const std::string& path, std::string& error);
// Parses schedule text (`name` is used in error messages, `baseDir` for model paths).
std::optional<Scene> parseSchedule(const std::string& text, const std::string& name, const std::string& baseDir,
                                   std::string& error);
// Writes a schedule file that loadSchedule() reads back into the same scene (numbers with 17
// significant digits, float vertices with 9): every model as `<modelDir>/<name>.obj` next to
// the schedule (`modelDir` relative to the schedule's folder; the folder must exist), then the
// objects. Names must be non-empty without blanks, '#' or '/'. False + error naming the file.
bool saveSchedule(const Scene& scene, const std::string& path, const std::string& modelDir, std::string& error);
// Every loader below reads coordinates in double and stores them as float. With `localOrigin`
// the loader sets *localOrigin to the file's first vertex (0 without vertices) and stores each
// vertex relative to it (file coordinate = *localOrigin + position), so a mesh in absolute
// coordinates (UTM northings ~6e6 m, ECEF ~6.4e6 m, where a float's step is 0.5 m) keeps its
// detail; without it the coordinates are stored as they are. (IFC: assimp hands over floats.)
//
// A minimal Wavefront OBJ reader: `v x y z` and `f a b c ...` (polygons fanned, negative
// indices, `a/b/c` forms); everything else ignored. Error: "file:line: what: value".
std::optional<Model> loadObj(const std::string& path, std::string& error, glm::dvec3* localOrigin = nullptr);

// A PLY reader (lod/hdlod_models.cpp): ascii, binary_little_endian and binary_big_endian;
// `vertex` x y z of any scalar type, `face` vertex_indices (or vertex_index) lists, polygons
// fanned; other elements and properties skipped. Error: "file[:line]: what: value".
std::optional<Model> loadPly(const std::string& path, std::string& error, glm::dvec3* localOrigin = nullptr);
// glTF 2.0 through Debian's libtinygltf (.gltf with external or data-URI buffers, .glb): the
// triangle, strip and fan primitives of every node of the default scene, with the node
// transforms, converted from glTF's y up to z up ((x, y, z) -> (x, -z, y)); textures ignored.
std::optional<Model> loadGltf(const std::string& path, std::string& error, glm::dvec3* localOrigin = nullptr);
// IFC (Industry Foundation Classes, STEP text starting 'ISO-10303-21;') through Debian's libassimp:
// every triangle of the building's geometry with the placements applied, in metres (assimp
// converts the file's length unit), z up as in the file; lines and points dropped. Errors
// name the file ("not an IFC (STEP) file", "cannot load IFC: <assimp's reason>", "IFC file
// without triangles").
std::optional<Model> loadIfc(const std::string& path, std::string& error, glm::dvec3* localOrigin = nullptr);
// By extension: .obj, .ply, .gltf, .glb, .ifc (case-insensitive).
std::optional<Model> loadModelFile(const std::string& path, std::string& error, glm::dvec3* localOrigin = nullptr);

// An axis-aligned box model (12 triangles), centred on x and y, standing on z = 0.
Model makeBoxModel(const std::string& name, const glm::dvec3& size_m);

}  // namespace ig::lod::hdlod
