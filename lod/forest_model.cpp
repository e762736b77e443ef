// Procedural fallback tree models for paper 004 (shared/SEEDS.md section 004).
#include "lod/forest_model.h"

#include <algorithm>
#include <cmath>

namespace ig::lod {
namespace {

constexpr double kPi = 3.14159265358979323846;

void addVertex(TreeMesh& m, double x, double y, double z, double nx, double ny, double nz, const uint8_t* rgb) {
  TreeVertex v{};
  const double l = std::sqrt(nx * nx + ny * ny + nz * nz);
  v.position[0] = static_cast<float>(x);
  v.position[1] = static_cast<float>(y);
  v.position[2] = static_cast<float>(z);
  v.normal[0] = static_cast<float>(nx / l);
  v.normal[1] = static_cast<float>(ny / l);
  v.normal[2] = static_cast<float>(nz / l);
  v.rgba[0] = rgb[0];
  v.rgba[1] = rgb[1];
  v.rgba[2] = rgb[2];
  v.rgba[3] = 255;
  m.vertices.push_back(v);
}

// A frustum of a cone from (z0, r0) to (z1, r1), open at both ends, plus a bottom disc when
// r0 > 0 (the underside of a crown tier).
void addCone(TreeMesh& m, int seg, double z0, double r0, double z1, double r1, const uint8_t* rgb, bool bottom) {
  const auto base = static_cast<uint32_t>(m.vertices.size());
  const double slope = (r0 - r1) / std::max(z1 - z0, 1e-6);  // outward normal: (cos, sin, slope)
  for (int i = 0; i <= seg; ++i) {
    const double a = 2.0 * kPi * i / seg, c = std::cos(a), s = std::sin(a);
    addVertex(m, r0 * c, r0 * s, z0, c, s, slope, rgb);
    addVertex(m, r1 * c, r1 * s, z1, c, s, slope, rgb);
  }
  for (uint32_t i = 0; i < static_cast<uint32_t>(seg); ++i) {
    const uint32_t a = base + 2 * i, b = a + 1, c = a + 2, d = a + 3;
    m.indices.insert(m.indices.end(), {a, c, d, a, d, b});
  }
  if (bottom && r0 > 0.0) {
    const auto centre = static_cast<uint32_t>(m.vertices.size());
    addVertex(m, 0, 0, z0, 0, 0, -1, rgb);
    for (int i = 0; i <= seg; ++i) {
      const double a = 2.0 * kPi * i / seg;
      addVertex(m, r0 * std::cos(a), r0 * std::sin(a), z0, 0, 0, -1, rgb);
    }
    for (uint32_t i = 0; i < static_cast<uint32_t>(seg); ++i)
      m.indices.insert(m.indices.end(), {centre, centre + 2 + i, centre + 1 + i});
  }
}

}  // namespace

TreeMesh makeProceduralTree(ProceduralTree kind, double height_m, int segments) {
  TreeMesh m;
  const int seg = std::max(segments, 3);
  const double h = height_m > 0.0 && std::isfinite(height_m) ? height_m : 1.0;
  const uint8_t bark[3] = {92, 64, 42};
  if (kind == ProceduralTree::Pine) {
    m.name = "procedural-pine";
    const uint8_t needles[3] = {46, 84, 40};
    addCone(m, seg, 0.0, 0.025 * h, 0.45 * h, 0.015 * h, bark, false);
    // Four tiers, each a cone whose base overlaps the one below.
    const double tiers[4][3] = {{0.30, 0.62, 0.20}, {0.48, 0.78, 0.16}, {0.64, 0.92, 0.12}, {0.78, 1.00, 0.08}};
    for (const auto& t : tiers) addCone(m, seg, t[0] * h, t[2] * h, t[1] * h, 0.0, needles, true);
  } else {
    m.name = "procedural-cypress";
    const uint8_t leaves[3] = {38, 72, 36};
    addCone(m, seg, 0.0, 0.02 * h, 0.2 * h, 0.015 * h, bark, false);
    addCone(m, seg, 0.08 * h, 0.05 * h, 0.35 * h, 0.11 * h, leaves, true);
    addCone(m, seg, 0.35 * h, 0.11 * h, 0.7 * h, 0.085 * h, leaves, false);
    addCone(m, seg, 0.7 * h, 0.085 * h, 1.0 * h, 0.0, leaves, false);
  }
  measureTree(m);
  return m;
}

void measureTree(TreeMesh& m) {
  float top = 0.0f, r2 = 0.0f;
  for (const TreeVertex& v : m.vertices) {
    top = std::max(top, v.position[2]);
    r2 = std::max(r2, v.position[0] * v.position[0] + v.position[1] * v.position[1]);
  }
  m.height_m = top;
  m.radius_m = std::sqrt(r2);
}

bool validateTreeMesh(const TreeMesh& m, std::string& error) {
  const std::string what = "tree model '" + m.name + "': ";
  if (m.vertices.empty() || m.indices.empty() || m.indices.size() % 3 != 0) {
    error = what + std::to_string(m.vertices.size()) + " vertices, " + std::to_string(m.indices.size()) +
            " indices: needs vertices and whole triangles";
    return false;
  }
  for (size_t i = 0; i < m.indices.size(); ++i) {
    if (m.indices[i] >= m.vertices.size()) {
      error = what + "index[" + std::to_string(i) + "] = " + std::to_string(m.indices[i]) + " >= vertex count " +
              std::to_string(m.vertices.size());
      return false;
    }
  }
  for (size_t i = 0; i < m.vertices.size(); ++i) {
    const float* p = m.vertices[i].position;
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]) || p[2] < -0.5f) {
      error = what + "vertex " + std::to_string(i) + " z = " + std::to_string(p[2]) + ": not finite or below the foot";
      return false;
    }
  }
  return true;
}

}  // namespace ig::lod
