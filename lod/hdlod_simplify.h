// HDLOD, part 3: the simplifiers that make a merged cluster's geometry (paper 000, appendix 2:
// "the union of the children simplified to eps(l)"). One entry point, three algorithms:
//
// - Meshoptimizer (default): the vertices are welded first (meshopt_generateVertexRemap on exact
//   positions, so children that share a seam, like the ground tiles, become one surface), index-
//   degenerate triangles are dropped, then meshopt_simplify (edge collapses ordered by a quadric
//   error, topology preserving) with target_error = eps / meshopt_simplifyScale (the mesh extent:
//   meshoptimizer's errors are relative to it) and no triangle target (it stops at the error).
//   Edge collapses cannot remove a closed component (a box stays at least a tetrahedron), so a
//   union of many small parts stays large: when the result still has more than
//   `sloppyAboveTriangles` triangles, meshopt_simplifySloppy (a vertex grid with quadric-placed
//   representatives, topology not preserved: small parts vanish) is run with the same
//   target_error and taken when it has fewer triangles and its measured distance (below) is
//   within the target. meshoptimizer only
//   estimates its errors (and sloppy's estimate is the grid cell), so the builder measures the
//   result (sampled Hausdorff): that measured distance, never the estimate, is eps_c.
// - OpenMesh: the welded mesh less its thin parts (a connected part whose every vertex lies
//   within eps of the segment along its box's longest axis vanishes as that segment, as such
//   parts do in meshoptimizer's collapses; the Decimater never removes a closed part) as an
//   OpenMesh TriMesh (triangles that would make a non-manifold edge go into further layers of
//   vertex copies, up to 4, the rest are kept unchanged), OpenMesh's Decimater with ModQuadric
//   (priority, bounded by 16 eps^2: OpenMesh's quadric sums over all planes around both vertices,
//   eps^2 refused harmless collapses), ModHausdorff (binary: no collapse moves an original
//   point farther than eps from the surface) and ModNormalFlipping (binary: no triangle's normal
//   turns by more than 90 degrees; without it collapses folded triangles over each other, which
//   keeps every point near some triangle but uncovers parts of the surface), decimated as far as
//   they allow; then the same sloppy fallback as meshoptimizer's when more than
//   `sloppyAboveTriangles` triangles remain.
// - Clustering: the earlier placeholder, kept for comparison. Vertex clustering on a grid of cell
//   eps anchored at `gridOffset_m` (vertices of a cell collapse to their mean; triangles that lose
//   a corner become the segments / points in `collapsed`, the Rossignac-Borrel complex the error
//   is measured against; duplicates are dropped).
//
// All three are deterministic. Positions are floats in one frame (the cluster's origin).
#pragma once

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>

namespace ig::lod::hdlod {

enum class Simplifier : uint8_t { Meshoptimizer, OpenMesh, Clustering };

// "meshoptimizer", "openmesh", "clustering".
const char* simplifierName(Simplifier s);
// Parses one of the names above; false for anything else.
bool parseSimplifier(std::string_view name, Simplifier& out);

struct SimplifyParams {
  Simplifier simplifier = Simplifier::Meshoptimizer;
  // Clustering: the grid corner minus the positions' frame origin, world metres (so that the
  // grid, anchored at the tree's box, does not move with the cluster's origin).
  glm::dvec3 gridOffset_m{0.0};
  // Meshoptimizer and OpenMesh: try meshopt_simplifySloppy when the topology-preserving pass
  // leaves more triangles.
  uint32_t sloppyAboveTriangles = 64;
  // Meshoptimizer and OpenMesh: the result is measured (sampled Hausdorff from the input's
  // vertices and triangle centroids, at most maxSamples, to the result's triangles and vanished
  // parts); while it is farther than eps, the target is halved, at most maxRetries times, after
  // which the welded input is returned unsimplified.
  uint32_t maxSamples = 4096;
  int maxRetries = 4;
};

struct SimplifiedMesh {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;    // triangles
  // Not drawn, part of the complex the error is measured against: triangles that became
  // segments or points (Clustering), parts that vanished as a segment (Meshoptimizer).
  std::vector<uint32_t> collapsed;
  bool sloppy = false;              // Meshoptimizer: the sloppy fallback was taken
};

// Simplifies the triangles (positions, indices: 3 per triangle, each < positions.size()) so that
// the surface moves by about eps_m at most (metres; see above for what each algorithm
// guarantees). Empty input or eps_m <= 0 / NaN gives the input unchanged (welded, without
// index-degenerate triangles). `out` is overwritten.
void simplifyMesh(std::span<const glm::vec3> positions, std::span<const uint32_t> indices, double eps_m,
                  const SimplifyParams& params, SimplifiedMesh& out);

}  // namespace ig::lod::hdlod
