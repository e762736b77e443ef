// Tree models for the forest (paper 004, shared/SEEDS.md section 004): one indexed triangle
// mesh per model in model space (metres, z up, the foot of the trunk at the origin), with a
// per-vertex normal and albedo. The same meshes draw the near 3D trees and, offline, the layer
// texture T and fin texture S (render/forest_pass.h), so near and far match in colour.
//
// Real models (Debian's sweethome3d-furniture, Scopia's pine and cypress, CC-BY) are read and
// simplified by igtool forest-textures (ig/forest_tool.h); makeProceduralTree is the fallback
// when they are not available, and what the tests use (deterministic, no data files).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ig::lod {

struct TreeVertex {
  float position[3];  // model space, metres, z up, trunk foot at (0, 0, 0)
  float normal[3];    // unit
  uint8_t rgba[4];    // albedo (linear), a = 255
};
static_assert(sizeof(TreeVertex) == 28);

struct TreeMesh {
  std::string name;
  std::vector<TreeVertex> vertices;
  std::vector<uint32_t> indices;  // triangles, counter-clockwise seen from outside
  float height_m = 0.0f;          // top of the mesh above the foot (measureTree)
  float radius_m = 0.0f;          // largest horizontal distance from the trunk axis
};

enum class ProceduralTree { Pine, Cypress };

// A stylised tree: a trunk cylinder and a crown of stacked cones (pine: broad tiers; cypress: a
// narrow spindle), `segments` around (>= 3), scaled to height_m. Deterministic.
TreeMesh makeProceduralTree(ProceduralTree kind, double height_m, int segments = 8);

// Sets height_m and radius_m from the vertices.
void measureTree(TreeMesh& mesh);

// Checks indices in range, a multiple of 3, finite positions, z >= -0.5 m; error names the
// mesh and the bad value.
bool validateTreeMesh(const TreeMesh& mesh, std::string& error);

}  // namespace ig::lod
