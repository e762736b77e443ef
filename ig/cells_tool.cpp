#include "ig/cells_tool.h"
#include "ig/json.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "lod/cells_db.h"
#include "lod/cells_voxel.h"
#include "lod/hdlod_scene.h"

namespace ig {
namespace {

using ToolClock = std::chrono::steady_clock;
double msSince(ToolClock::time_point t0) { return std::chrono::duration<double, std::milli>(ToolClock::now() - t0).count(); }

constexpr double kPi = 3.14159265358979323846;


// The model as a voxel mesh: turned to z up, scaled, centred on the origin, light clay colour.
// `origin`: where the model's coordinates are relative to (lod::hdlod::loadModelFile's local
// origin, so that a scan in absolute coordinates is centred in double, not rounded to float).
lod::VoxelMesh meshFromModel(const lod::hdlod::Model& model, const glm::dvec3& origin, bool yUp, double size_m) {
  lod::VoxelMesh m;
  m.positions_m.reserve(model.positions.size());
  glm::dvec3 lo(0.0), hi(0.0);
  for (size_t i = 0; i < model.positions.size(); ++i) {
    const glm::dvec3 p = origin + glm::dvec3(model.positions[i]);
    const glm::dvec3 q = yUp ? glm::dvec3(p.x, -p.z, p.y) : p;
    m.positions_m.push_back(q);
    lo = i == 0 ? q : glm::min(lo, q);
    hi = i == 0 ? q : glm::max(hi, q);
  }
  const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
  const double s = size_m > 0.0 && extent > 0.0 ? size_m / extent : 1.0;
  const glm::dvec3 centre = 0.5 * (lo + hi);
  for (auto& p : m.positions_m) p = (p - centre) * s;
  m.indices = model.indices;
  m.colors.assign(m.positions_m.size(), 0xFFA0B4C8u);  // 0xAABBGGRR: (200, 180, 160)
  return m;
}

// `copies` copies of `one` (centred on the origin) scattered through a cube, each turned about z,
// scaled 0.6 - 1.4 and tinted.
lod::VoxelMesh scatter(const lod::VoxelMesh& one, int copies, uint32_t seed) {
  glm::dvec3 lo(0.0), hi(0.0);
  for (size_t i = 0; i < one.positions_m.size(); ++i) {
    lo = i == 0 ? one.positions_m[i] : glm::min(lo, one.positions_m[i]);
    hi = i == 0 ? one.positions_m[i] : glm::max(hi, one.positions_m[i]);
  }
  const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z, 1e-9});
  const double edge = extent * std::max(2.0, 2.5 * std::cbrt(static_cast<double>(copies)));
  lod::VoxelMesh m;
  m.positions_m.reserve(one.positions_m.size() * static_cast<size_t>(copies));
  m.indices.reserve(one.indices.size() * static_cast<size_t>(copies));
  m.colors.reserve(m.positions_m.capacity());
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < copies; ++k) {
    const double scale = 0.6 + 0.8 * u(rng), turn = 2.0 * kPi * u(rng);
    const glm::dvec3 at(u(rng) * edge, u(rng) * edge, u(rng) * edge);
    const double c = std::cos(turn), s = std::sin(turn);
    const uint32_t tint = static_cast<uint32_t>(rng());
    const auto base = static_cast<uint32_t>(m.positions_m.size());
    for (size_t i = 0; i < one.positions_m.size(); ++i) {
      const glm::dvec3 p = one.positions_m[i] * scale;
      m.positions_m.push_back(at + glm::dvec3(c * p.x - s * p.y, s * p.x + c * p.y, p.z));
      uint32_t col = 0xFF000000u;
      for (int ch = 0; ch < 3; ++ch) {
        const uint32_t v = (one.colors[i] >> (8 * ch)) & 0xFF, t = 128 + ((tint >> (8 * ch)) & 0x7F);
        col |= (v * t / 255) << (8 * ch);
      }
      m.colors.push_back(col);
    }
    for (uint32_t idx : one.indices) m.indices.push_back(base + idx);
  }
  return m;
}

// Multiplies each vertex colour by ambient + diffuse sun light from its (area-weighted) normal, so
// that unlit splats show the shape. Two-sided: scanned meshes are not consistently wound.
void bakeShading(lod::VoxelMesh& m) {
  std::vector<glm::dvec3> n(m.positions_m.size(), glm::dvec3(0.0));
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    const uint32_t a = m.indices[t], b = m.indices[t + 1], c = m.indices[t + 2];
    if (a >= n.size() || b >= n.size() || c >= n.size()) continue;  // voxelize() reports it
    const glm::dvec3 f = glm::cross(m.positions_m[b] - m.positions_m[a], m.positions_m[c] - m.positions_m[a]);
    n[a] += f, n[b] += f, n[c] += f;
  }
  if (m.colors.size() != m.positions_m.size()) m.colors.assign(m.positions_m.size(), 0xFFFFFFFFu);
  const glm::dvec3 sun = glm::normalize(glm::dvec3(0.4, -0.5, 0.75));
  for (size_t i = 0; i < n.size(); ++i) {
    const double len = glm::length(n[i]);
    const double diffuse = len > 0.0 && std::isfinite(len) ? std::abs(glm::dot(n[i] / len, sun)) : 0.5;
    const double light = 0.3 + 0.7 * diffuse;
    uint32_t col = m.colors[i] & 0xFF000000u;
    for (int ch = 0; ch < 3; ++ch) {
      const double v = static_cast<double>((m.colors[i] >> (8 * ch)) & 0xFF) * light;
      col |= static_cast<uint32_t>(std::clamp(std::lround(v), 0L, 255L)) << (8 * ch);
    }
    m.colors[i] = col;
  }
}

std::string formatted(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string formatted(const char* format, ...) {
  char buf[1024];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buf, sizeof buf, format, args);
  va_end(args);
  return buf;
}

}  // namespace

lod::VoxelMesh cellsSphereScene(int count, uint32_t seed) {
  lod::VoxelMesh mesh;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < count; ++i) {
    const double r = 8.0 + 52.0 * u(rng) * u(rng);
    const glm::dvec3 c(r + (kCellsSceneEdge_m - 2 * r) * u(rng), r + (kCellsSceneEdge_m - 2 * r) * u(rng),
                       r + (kCellsSceneEdge_m - 2 * r) * u(rng));
    const int segments = std::clamp(static_cast<int>(r * 1.5), 16, 96);
    lod::appendSphere(mesh, c, r, segments, 0xFF000000u | (rng() & 0xFFFFFFu));
  }
  return mesh;
}

bool cellsBuildMesh(const CellsBuildOptions& o, lod::VoxelMesh& mesh, std::string& source, std::string& error) {
  mesh = {};
  if (!o.scene.empty()) {
    const std::string prefix = "spheres:";
    char* end = nullptr;
    const long n = o.scene.rfind(prefix, 0) == 0 ? std::strtol(o.scene.c_str() + prefix.size(), &end, 10) : -1;
    if (n < 1 || n > 1000000 || !end || *end != '\0') {
      error = formatted("--scene '%s': expected spheres:N with N in 1..1000000", o.scene.c_str());
      return false;
    }
    if (o.copies > 0) {
      error = formatted("--copies %d: needs an input mesh, not --scene", o.copies);
      return false;
    }
    mesh = cellsSphereScene(static_cast<int>(n), o.seed);
    source = o.scene;
  } else {
    glm::dvec3 origin(0.0);
    const auto model = lod::hdlod::loadModelFile(o.input, error, &origin);
    if (!model) return false;
    if (model->indices.empty()) {
      error = formatted("%s: no triangles", o.input.c_str());
      return false;
    }
    mesh = meshFromModel(*model, origin, o.yUp, o.size_m);
    constexpr uint64_t kMaxTriangles = 50000000;  // ~4 GB of vertices and voxelizer work
    const uint64_t total = uint64_t(mesh.indices.size() / 3) * static_cast<uint64_t>(std::max(o.copies, 1));
    if (total > kMaxTriangles) {
      error = formatted("--copies %d: %llu triangles in all, more than %llu", o.copies,
                        static_cast<unsigned long long>(total), static_cast<unsigned long long>(kMaxTriangles));
      return false;
    }
    // The vertices are copied too, the unused ones included (a scan with few faces): bounded as
    // three per triangle, which also keeps every copy's indices within 32 bits.
    constexpr uint64_t kMaxVertices = 3 * kMaxTriangles;
    const uint64_t vertices = uint64_t{mesh.positions_m.size()} * static_cast<uint64_t>(std::max(o.copies, 1));
    if (vertices > kMaxVertices) {
      error = formatted("--copies %d: %llu vertices in all, more than %llu", o.copies,
                        static_cast<unsigned long long>(vertices), static_cast<unsigned long long>(kMaxVertices));
      return false;
    }
    if (o.copies > 0) mesh = scatter(mesh, o.copies, o.seed);
    source = o.input;
  }
  if (o.shading) bakeShading(mesh);
  return true;
}

int runCellsBuild(const CellsBuildOptions& o) {
  const char* tool = "igtool cells-build";
  if (o.input.empty() == o.scene.empty()) {
    std::fprintf(stderr, "%s: give either an input mesh or --scene spheres:N (got %s)\n", tool,
                 o.input.empty() ? "neither" : "both");
    return 2;
  }
  if (o.cellLevels < 1 || o.cellLevels > lod::kMaxCellLevels) {
    std::fprintf(stderr, "%s: --cell-levels %d: allowed range 1..%d\n", tool, o.cellLevels, lod::kMaxCellLevels);
    return 2;
  }
  if (o.voxelDepth < 0 || o.voxelDepth > 8) {
    std::fprintf(stderr, "%s: --depth %d: allowed range 0..8\n", tool, o.voxelDepth);
    return 2;
  }
  const int levels = o.voxelLevels > 0 ? o.voxelLevels : o.cellLevels - 1 + o.voxelDepth;
  if (levels < 1 || levels > lod::kMaxVoxelLevels || levels < o.cellLevels - 1 + o.voxelDepth) {
    std::fprintf(stderr, "%s: --voxel-levels %d: allowed range %d..%d (cell levels - 1 + depth .. %d)\n", tool, levels,
                 std::max(1, o.cellLevels - 1 + o.voxelDepth), lod::kMaxVoxelLevels, lod::kMaxVoxelLevels);
    return 2;
  }
  if (o.copies < 0 || o.copies > 100000) {
    std::fprintf(stderr, "%s: --copies %d: allowed range 0..100000\n", tool, o.copies);
    return 2;
  }
  if (!(o.size_m >= 0.0) || !std::isfinite(o.size_m)) {
    std::fprintf(stderr, "%s: --size %g: must be finite and >= 0\n", tool, o.size_m);
    return 2;
  }
  if (o.out.empty()) {
    std::fprintf(stderr, "%s: --out is empty\n", tool);
    return 2;
  }

  const auto t0 = ToolClock::now();
  lod::VoxelMesh mesh;
  std::string source, error;
  if (!cellsBuildMesh(o, mesh, source, error)) {
    std::fprintf(stderr, "%s: %s\n", tool, error.c_str());
    return 2;
  }
  const double loadMs = msSince(t0);

  const auto t1 = ToolClock::now();
  lod::VoxelizeConfig vc;
  vc.levels = levels;
  vc.solid = o.solid;
  if (!o.scene.empty()) {
    vc.boxMin_m = glm::dvec3(0.0);
    vc.boxEdge_m = kCellsSceneEdge_m;
  }
  lod::VoxelPyramid pyramid;
  if (!lod::voxelize(mesh, vc, pyramid, error)) {
    std::fprintf(stderr, "%s: %s: %s\n", tool, source.c_str(), error.c_str());
    return 2;
  }
  const size_t triangles = mesh.indices.size() / 3;
  mesh = {};
  const double voxelizeMs = msSince(t1);

  const auto t2 = ToolClock::now();
  lod::CellBuildConfig bc;
  bc.cellLevels = o.cellLevels;
  bc.cellVoxelDepth = o.voxelDepth;
  lod::CellTree tree;
  if (!lod::writeCellDb(o.out, pyramid, bc, &tree, error)) {
    std::fprintf(stderr, "%s: %s\n", tool, error.c_str());
    return pyramid.count(0) == 0 ? 2 : 1;
  }
  const double writeMs = msSince(t2);

  // Read it back: header, index, every payload's crc and structure.
  const auto t3 = ToolClock::now();
  lod::CellDbFile db;
  if (!db.open(o.out, error)) {
    std::fprintf(stderr, "%s: written but unreadable: %s\n", tool, error.c_str());
    return 1;
  }
  std::vector<lod::CellPoint> points;
  uint32_t largest = 0;
  for (uint32_t c = 0; c < db.tree().size(); ++c) {
    const auto payload = db.payload(c);
    largest = std::max(largest, db.tree().bytes(c));
    points.clear();
    if (lod::cellDbCrc32(payload) != db.entries()[c].crc32 || !lod::decodeCell(db.tree(), c, payload, points, error)) {
      std::fprintf(stderr, "%s: %s: cell %u does not read back: %s\n", tool, o.out.c_str(), c,
                   error.empty() ? "crc mismatch" : error.c_str());
      return 1;
    }
  }
  const double verifyMs = msSince(t3);
  const lod::CellDbHeader& h = db.header();

  if (o.json) {
    std::string s = "{\"input\":" + jsonString(source) + ",\"out\":" + jsonString(o.out);
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  ",\"triangles\":%zu,\"copies\":%d,\"solid\":%s,\"voxel_levels\":%d,\"cell_levels\":%d,"
                  "\"voxel_depth\":%d,\"root_min_m\":[%.6f,%.6f,%.6f],\"root_edge_m\":%.6f,\"finest_voxel_m\":%.6g",
                  triangles, o.copies, o.solid ? "true" : "false", levels, o.cellLevels, o.voxelDepth,
                  pyramid.boxMin_m.x, pyramid.boxMin_m.y, pyramid.boxMin_m.z, pyramid.boxEdge_m,
                  std::ldexp(pyramid.boxEdge_m, -levels));
    s += buf;
    s += ",\"voxels\":[";
    for (int l = 0; l <= pyramid.levels(); ++l) {
      if (l) s += ',';
      s += std::to_string(pyramid.count(l));
    }
    s += "],\"dimension\":[";
    for (int l = 0; l < pyramid.levels(); ++l) {
      std::snprintf(buf, sizeof buf, "%s%.4f", l ? "," : "", pyramid.dimension(l));
      s += buf;
    }
    s += "],\"box_counting_dimension\":[";  // per level 0..levels(), the paper's Table 1
    for (int l = 0; l <= pyramid.levels(); ++l) {
      std::snprintf(buf, sizeof buf, "%s%.4f", l ? "," : "", pyramid.boxCountingDimension(l));
      s += buf;
    }
    s += "],\"cells_per_level\":[";
    for (int q = 0; q < tree.levels(); ++q) {
      if (q) s += ',';
      s += std::to_string(tree.levelBegin(q + 1) - tree.levelBegin(q));
    }
    s += "],\"bytes_per_level\":[";
    for (int q = 0; q < tree.levels(); ++q) {
      uint64_t b = 0;
      for (uint32_t c = tree.levelBegin(q); c < tree.levelBegin(q + 1); ++c) b += tree.bytes(c);
      if (q) s += ',';
      s += std::to_string(b);
    }
    std::snprintf(buf, sizeof buf,
                  "],\"cells\":%u,\"payload_bytes\":%llu,\"file_bytes\":%llu,\"largest_cell_bytes\":%u,"
                  "\"load_ms\":%.1f,\"voxelize_ms\":%.1f,\"write_ms\":%.1f,\"verify_ms\":%.1f}",
                  tree.size(), static_cast<unsigned long long>(h.payloadBytes),
                  static_cast<unsigned long long>(h.fileBytes), largest, loadMs, voxelizeMs, writeMs, verifyMs);
    s += buf;
    std::printf("%s\n", s.c_str());
    return 0;
  }
  std::printf("%s: %s: %zu triangles -> %d voxel levels (finest voxel %.4g m, root cube %.4g m)\n", tool,
              source.c_str(), triangles, levels, std::ldexp(pyramid.boxEdge_m, -levels), pyramid.boxEdge_m);
  std::printf("  level  voxels      D(l) = log2(N(l+1) / N(l))  H(l) = log2(N(l)) / l (Table 1)\n");
  for (int l = 0; l <= pyramid.levels(); ++l) {
    if (l < pyramid.levels()) {
      std::printf("  %5d  %-10zu  %-26.3f  %.3f\n", l, pyramid.count(l), pyramid.dimension(l),
                  pyramid.boxCountingDimension(l));
    } else {
      std::printf("  %5d  %-10zu  %-26s  %.3f\n", l, pyramid.count(l), "", pyramid.boxCountingDimension(l));
    }
  }
  std::printf("  cell level  cells       bytes        (depth d = %d: %d^3-voxel cells at most)\n", o.voxelDepth,
              1 << o.voxelDepth);
  for (int q = 0; q < tree.levels(); ++q) {
    uint64_t b = 0;
    for (uint32_t c = tree.levelBegin(q); c < tree.levelBegin(q + 1); ++c) b += tree.bytes(c);
    std::printf("  %10d  %-10u  %llu\n", q, tree.levelBegin(q + 1) - tree.levelBegin(q), static_cast<unsigned long long>(b));
  }
  std::printf("%s: %s: %u cells, %llu bytes (largest cell %u bytes); load %.0f ms, voxelize %.0f ms, write %.0f ms, "
              "verify %.0f ms\n",
              tool, o.out.c_str(), tree.size(), static_cast<unsigned long long>(h.fileBytes), largest, loadMs, voxelizeMs,
              writeMs, verifyMs);
  return 0;
}

}  // namespace ig
