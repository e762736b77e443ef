// HDLOD simplifiers (see hdlod_simplify.h): meshoptimizer (Kapoulkine, edge collapse with
// quadrics, and its sloppy grid variant), OpenMesh's Decimater (Garland-Heckbert quadrics bounded
// by a Hausdorff tolerance, Klein et al. 1996) and vertex clustering (Rossignac-Borrel 1993).
#include "lod/hdlod_simplify.h"

#include "lod/hdlod_build.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <limits>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/gtc/type_precision.hpp>
#include <meshoptimizer.h>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModHausdorffT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

namespace ig::lod::hdlod {
namespace {

// Welds vertices with exactly equal positions (-0 and +0 alike) and drops triangles with a
// repeated index. out.positions / out.indices get the welded mesh.
void weld(std::span<const glm::vec3> positions, std::span<const uint32_t> indices, SimplifiedMesh& out) {
  out.positions.clear();
  out.indices.clear();
  if (positions.empty() || indices.size() < 3) return;
  std::vector<glm::vec3> clean(positions.begin(), positions.end());
  for (glm::vec3& p : clean) p += glm::vec3(0.0f);  // -0 -> +0: the remap compares bytes
  std::vector<uint32_t> remap(clean.size());
  const size_t unique = meshopt_generateVertexRemap(remap.data(), nullptr, clean.size(), clean.data(), clean.size(), sizeof(glm::vec3));
  out.positions.resize(unique);
  meshopt_remapVertexBuffer(out.positions.data(), clean.data(), clean.size(), sizeof(glm::vec3), remap.data());
  // Drops repeated-index triangles and duplicates (the same corners in any order: coincident
  // objects), keeping the first occurrence and the input order.
  const size_t nt = indices.size() / 3;
  std::vector<std::pair<std::array<uint32_t, 3>, uint32_t>> keyed;
  keyed.reserve(nt);
  for (size_t t = 0; t < nt; ++t) {
    std::array<uint32_t, 3> k = {remap[indices[3 * t]], remap[indices[3 * t + 1]], remap[indices[3 * t + 2]]};
    std::sort(k.begin(), k.end());
    if (k[0] == k[1] || k[1] == k[2]) continue;
    keyed.push_back({k, static_cast<uint32_t>(t)});
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<uint32_t> keep;
  for (size_t i = 0; i < keyed.size(); ++i) {
    if (i == 0 || keyed[i].first != keyed[i - 1].first) keep.push_back(keyed[i].second);
  }
  std::sort(keep.begin(), keep.end());
  out.indices.reserve(keep.size() * 3);
  for (uint32_t t : keep) {
    out.indices.insert(out.indices.end(), {remap[indices[3 * t]], remap[indices[3 * t + 1]], remap[indices[3 * t + 2]]});
  }
}

// Keeps only the vertices the indices use (first-use order).
void compact(SimplifiedMesh& m) {
  std::vector<uint32_t> used(m.positions.size(), ~0u);
  std::vector<glm::vec3> positions;
  auto fix = [&](uint32_t& i) {
    if (used[i] == ~0u) {
      used[i] = static_cast<uint32_t>(positions.size());
      positions.push_back(m.positions[i]);
    }
    i = used[i];
  };
  for (uint32_t& i : m.indices) fix(i);
  for (uint32_t& i : m.collapsed) fix(i);
  m.positions = std::move(positions);
}

// ---------------------------------------------------------------- vanished parts

// The connected part of each vertex of m (through its triangles): the smallest vertex index in
// the part. Vertices in no triangle are their own part.
std::vector<uint32_t> partRoots(const SimplifiedMesh& m) {
  const uint32_t nv = static_cast<uint32_t>(m.positions.size());
  std::vector<uint32_t> parent(nv);
  for (uint32_t i = 0; i < nv; ++i) parent[i] = i;
  auto find = [&](uint32_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    for (int k = 1; k < 3; ++k) {
      const uint32_t a = find(m.indices[t]), b = find(m.indices[t + static_cast<size_t>(k)]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  }
  for (uint32_t i = 0; i < nv; ++i) parent[i] = find(i);
  return parent;
}

// Edge collapses and the sloppy grid may remove a whole connected part (a thin column, a small
// box). Each part of the input with no triangle left in `kept` (which indexes the same vertices)
// is recorded in m.collapsed as the segment it shrank to: its box's longest axis through the box
// centre (Rossignac-Borrel: a column counts as an error of about its thickness, as in vertex
// clustering, not as its distance to the nearest surviving surface). Appends the segment ends to
// m.positions.
void recordVanishedParts(std::span<const uint32_t> kept, SimplifiedMesh& m) {
  const uint32_t nv = static_cast<uint32_t>(m.positions.size());
  const std::vector<uint32_t> root = partRoots(m);
  std::vector<uint8_t> alive(nv, 0), used(nv, 0);
  for (uint32_t i : kept) alive[root[i]] = 1;
  for (uint32_t i : m.indices) used[i] = 1;
  std::vector<glm::vec3> lo(nv, glm::vec3(std::numeric_limits<float>::max())), hi(nv, glm::vec3(-std::numeric_limits<float>::max()));
  for (uint32_t i = 0; i < nv; ++i) {
    if (!used[i]) continue;
    const uint32_t r = root[i];
    lo[r] = glm::min(lo[r], m.positions[i]);
    hi[r] = glm::max(hi[r], m.positions[i]);
  }
  for (uint32_t r = 0; r < nv; ++r) {
    if (!used[r] || root[r] != r || alive[r]) continue;
    const glm::vec3 c = (lo[r] + hi[r]) * 0.5f, e = hi[r] - lo[r];
    const int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
    glm::vec3 a = c, b = c;
    a[axis] = lo[r][axis];
    b[axis] = hi[r][axis];
    const uint32_t ia = static_cast<uint32_t>(m.positions.size());
    m.positions.push_back(a);
    m.positions.push_back(b);
    m.collapsed.insert(m.collapsed.end(), {ia, ia + 1, ia + 1});
  }
}

// ---------------------------------------------------------------- meshoptimizer

// meshopt_simplify, or with `sloppy` meshopt_simplifySloppy, at eps; m keeps the welded vertices.
void simplifyMeshopt(double eps_m, bool sloppy, SimplifiedMesh& m) {
  const size_t nv = m.positions.size();
  const float* xyz = &m.positions[0].x;
  const float scale = meshopt_simplifyScale(xyz, nv, sizeof(glm::vec3));
  if (!(scale > 0.0f)) return;
  const float target = static_cast<float>(eps_m / static_cast<double>(scale));
  std::vector<uint32_t> out(m.indices.size());
  float error = 0.0f;
  const size_t n = sloppy ? meshopt_simplifySloppy(out.data(), m.indices.data(), m.indices.size(), xyz, nv, sizeof(glm::vec3), 0, target, &error)
                          : meshopt_simplify(out.data(), m.indices.data(), m.indices.size(), xyz, nv, sizeof(glm::vec3), 0, target, 0, &error);
  out.resize(n);
  m.sloppy = sloppy;
  recordVanishedParts(out, m);
  m.indices.swap(out);
}

// ---------------------------------------------------------------- OpenMesh

struct OmTraits : public OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
  using Normal = OpenMesh::Vec3d;
};
using OmMesh = OpenMesh::TriMesh_ArrayKernelT<OmTraits>;

// Connected parts of m whose every vertex lies within eps of the segment along their box's
// longest axis (what recordVanishedParts() measures them as: columns, bars, small boxes) are
// removed and recorded as that segment. meshopt_simplify and the sloppy grid remove such parts
// by collapsing them away; OpenMesh's Decimater never removes a closed part.
void dropThinParts(double eps_m, SimplifiedMesh& m) {
  const uint32_t nv = static_cast<uint32_t>(m.positions.size());
  const std::vector<uint32_t> root = partRoots(m);
  std::vector<glm::vec3> lo(nv, glm::vec3(std::numeric_limits<float>::max())), hi(nv, glm::vec3(-std::numeric_limits<float>::max()));
  for (uint32_t i : m.indices) {
    const uint32_t r = root[i];
    lo[r] = glm::min(lo[r], m.positions[i]);
    hi[r] = glm::max(hi[r], m.positions[i]);
  }
  // Largest squared distance of a part's vertices from its segment.
  std::vector<float> far2(nv, 0.0f);
  for (uint32_t i : m.indices) {
    const uint32_t r = root[i];
    const glm::vec3 c = (lo[r] + hi[r]) * 0.5f, e = hi[r] - lo[r];
    const int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
    glm::vec3 d = m.positions[i] - c;
    d[axis] = 0.0f;  // the segment spans the box along its axis
    far2[r] = std::max(far2[r], glm::dot(d, d));
  }
  const float eps2 = static_cast<float>(eps_m * eps_m);
  std::vector<uint32_t> kept;
  kept.reserve(m.indices.size());
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    if (far2[root[m.indices[t]]] > eps2) kept.insert(kept.end(), {m.indices[t], m.indices[t + 1], m.indices[t + 2]});
  }
  if (kept.size() == m.indices.size()) return;
  recordVanishedParts(kept, m);
  m.indices.swap(kept);
}

constexpr double kQuadricBound = 16.0;

void simplifyOpenMesh(double eps_m, SimplifiedMesh& m) {
  dropThinParts(eps_m, m);
  OmMesh mesh;
  mesh.request_vertex_status();
  mesh.request_edge_status();
  mesh.request_face_status();
  mesh.request_face_normals();
  // Triangles OpenMesh refuses (a third face on an edge: parts welded along an edge, a flipped
  // neighbour) go into a second layer of vertex copies, then a third..., so that they are
  // simplified too (as separate sheets whose seams are boundaries); those refused by every
  // layer stay as they are.
  constexpr int kLayers = 4;
  std::vector<uint32_t> kept, pending(m.indices.begin(), m.indices.end());
  std::vector<OmMesh::VertexHandle> vh(m.positions.size());
  {
    // OpenMesh reports refused faces on std::cerr (omerr); keep the log quiet.
    const bool wasEnabled = omerr().is_enabled();
    omerr().disable();
    for (int layer = 0; layer < kLayers && !pending.empty(); ++layer) {
      std::fill(vh.begin(), vh.end(), OmMesh::VertexHandle());
      auto vertex = [&](uint32_t i) {
        if (!vh[i].is_valid()) vh[i] = mesh.add_vertex(OmMesh::Point(m.positions[i].x, m.positions[i].y, m.positions[i].z));
        return vh[i];
      };
      kept.clear();
      for (size_t t = 0; t + 2 < pending.size(); t += 3) {
        const uint32_t a = pending[t], b = pending[t + 1], c = pending[t + 2];
        if (!mesh.add_face(vertex(a), vertex(b), vertex(c)).is_valid()) kept.insert(kept.end(), {a, b, c});
      }
      pending.swap(kept);
    }
    kept.swap(pending);
    if (wasEnabled) omerr().enable();
  }
  OpenMesh::Decimater::DecimaterT<OmMesh> decimater(mesh);
  OpenMesh::Decimater::ModQuadricT<OmMesh>::Handle quadric;
  OpenMesh::Decimater::ModHausdorffT<OmMesh>::Handle hausdorff;
  OpenMesh::Decimater::ModNormalFlippingT<OmMesh>::Handle flipping;
  decimater.add(quadric);
  decimater.add(hausdorff);
  decimater.add(flipping);
  // OpenMesh's quadric sums squared distances over every plane around both vertices, so eps^2
  // refused collapses that move no point by eps; unbounded, ModHausdorff (which checks vertices
  // only) lets curved surfaces drift between the vertices and the measurement fails. 16 eps^2:
  // the site's merged triangles at scale 0.25 fall from 98k to 87k, a bumpy tile still passes.
  decimater.module(quadric).set_max_err(kQuadricBound * eps_m * eps_m, /*binary=*/false);
  decimater.module(hausdorff).set_tolerance(eps_m);
  // Without it a collapse may fold a triangle over its neighbours: on a plane every removed point
  // still lies on some triangle (ModHausdorff is satisfied) but part of the surface is no longer
  // covered, the measured distance is metres and every retry fell back to the input (this was
  // why a flat tile stayed at 512 triangles).
  decimater.module(flipping).set_max_normal_deviation(90.0);
  mesh.update_face_normals();
  if (decimater.initialize()) decimater.decimate(0);
  mesh.garbage_collection();
  std::vector<glm::vec3> positions;
  positions.reserve(mesh.n_vertices() + m.positions.size());
  for (const auto& v : mesh.vertices()) {
    const OmMesh::Point& p = mesh.point(v);
    positions.emplace_back(static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2]));
  }
  std::vector<uint32_t> indices;
  indices.reserve(3 * mesh.n_faces() + kept.size());
  for (const auto& f : mesh.faces()) {
    for (const auto& v : f.vertices()) indices.push_back(static_cast<uint32_t>(v.idx()));
  }
  // The refused triangles index the original vertices, appended after OpenMesh's.
  const uint32_t base = static_cast<uint32_t>(positions.size());
  positions.insert(positions.end(), m.positions.begin(), m.positions.end());
  for (uint32_t i : kept) indices.push_back(base + i);
  for (uint32_t& i : m.collapsed) i += base;
  m.positions = std::move(positions);
  m.indices = std::move(indices);
}

// ---------------------------------------------------------------- vertex clustering

void simplifyClustering(double cell_m, const glm::dvec3& offset, SimplifiedMesh& m) {
  const size_t nv = m.positions.size();
  std::vector<glm::i64vec3> cellOf(nv);
  glm::i64vec3 lo(0), hi(0);
  double cell = cell_m;
  for (int attempt = 0;; ++attempt) {
    lo = glm::i64vec3(std::numeric_limits<int64_t>::max());
    hi = glm::i64vec3(std::numeric_limits<int64_t>::min());
    for (size_t i = 0; i < nv; ++i) {
      const glm::dvec3 w = glm::dvec3(m.positions[i]) - offset;
      cellOf[i] = glm::i64vec3(static_cast<int64_t>(std::floor(w.x / cell)), static_cast<int64_t>(std::floor(w.y / cell)),
                               static_cast<int64_t>(std::floor(w.z / cell)));
      lo = glm::min(lo, cellOf[i]);
      hi = glm::max(hi, cellOf[i]);
    }
    const glm::dvec3 range = glm::dvec3(hi - lo) + 1.0;
    if (range.x * range.y * range.z < 4.0e18 || attempt > 60) break;
    cell *= 2.0;
  }
  const uint64_t rx = static_cast<uint64_t>(hi.x - lo.x + 1), ry = static_cast<uint64_t>(hi.y - lo.y + 1);
  std::vector<std::pair<uint64_t, uint32_t>> keyed(nv);
  for (size_t i = 0; i < nv; ++i) {
    const glm::i64vec3 c = cellOf[i] - lo;
    keyed[i] = {static_cast<uint64_t>(c.x) + rx * (static_cast<uint64_t>(c.y) + ry * static_cast<uint64_t>(c.z)),
                static_cast<uint32_t>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<uint32_t> remap(nv);
  std::vector<glm::vec3> positions;
  for (size_t i = 0; i < nv;) {
    size_t j = i;
    glm::dvec3 sum(0.0);
    while (j < nv && keyed[j].first == keyed[i].first) {
      sum += glm::dvec3(m.positions[keyed[j].second]);
      remap[keyed[j].second] = static_cast<uint32_t>(positions.size());
      ++j;
    }
    positions.push_back(glm::vec3(sum / static_cast<double>(j - i)));
    i = j;
  }
  struct Tri {
    uint32_t sorted[3];
    uint32_t original;  // position in the input: keeps the first occurrence and the order
  };
  std::vector<Tri> tris;
  const size_t nt = m.indices.size() / 3;
  tris.reserve(nt);
  for (size_t t = 0; t < nt; ++t) {
    uint32_t s[3] = {remap[m.indices[3 * t]], remap[m.indices[3 * t + 1]], remap[m.indices[3 * t + 2]]};
    std::sort(s, s + 3);
    tris.push_back({{s[0], s[1], s[2]}, static_cast<uint32_t>(t)});
  }
  std::sort(tris.begin(), tris.end(), [](const Tri& x, const Tri& y) {
    if (x.sorted[0] != y.sorted[0]) return x.sorted[0] < y.sorted[0];
    if (x.sorted[1] != y.sorted[1]) return x.sorted[1] < y.sorted[1];
    if (x.sorted[2] != y.sorted[2]) return x.sorted[2] < y.sorted[2];
    return x.original < y.original;
  });
  std::vector<uint32_t> keep;
  m.collapsed.clear();
  for (size_t i = 0; i < tris.size(); ++i) {
    const uint32_t* s = tris[i].sorted;
    if (i > 0 && std::equal(s, s + 3, tris[i - 1].sorted)) continue;
    if (s[0] == s[1] || s[1] == s[2]) {
      m.collapsed.insert(m.collapsed.end(), {s[0], s[1], s[2]});
    } else {
      keep.push_back(tris[i].original);
    }
  }
  std::sort(keep.begin(), keep.end());
  std::vector<uint32_t> indices;
  indices.reserve(keep.size() * 3);
  for (uint32_t t : keep) {
    for (int k = 0; k < 3; ++k) indices.push_back(remap[m.indices[3 * t + static_cast<uint32_t>(k)]]);
  }
  m.positions = std::move(positions);
  m.indices = std::move(indices);
}

}  // namespace

const char* simplifierName(Simplifier s) {
  switch (s) {
    case Simplifier::Meshoptimizer: return "meshoptimizer";
    case Simplifier::OpenMesh: return "openmesh";
    case Simplifier::Clustering: return "clustering";
  }
  return "?";
}

bool parseSimplifier(std::string_view name, Simplifier& out) {
  for (Simplifier s : {Simplifier::Meshoptimizer, Simplifier::OpenMesh, Simplifier::Clustering}) {
    if (name == simplifierName(s)) {
      out = s;
      return true;
    }
  }
  return false;
}

void simplifyMesh(std::span<const glm::vec3> positions, std::span<const uint32_t> indices, double eps_m,
                  const SimplifyParams& params, SimplifiedMesh& out) {
  assert(indices.size() % 3 == 0);
  assert(std::all_of(indices.begin(), indices.end(), [&](uint32_t i) { return i < positions.size(); }));
  out.collapsed.clear();
  out.sloppy = false;
  weld(positions, indices, out);
  if (out.indices.empty() || !(eps_m > 0.0) || !std::isfinite(eps_m)) {
    compact(out);
    return;
  }
  // Vertices no triangle uses are not surface: they would be sampled below, lie far from every
  // simplified triangle and fail every measurement (the input came back unsimplified).
  {
    std::vector<uint8_t> used(out.positions.size(), 0);
    for (uint32_t i : out.indices) used[i] = 1;
    if (std::find(used.begin(), used.end(), uint8_t{0}) != used.end()) compact(out);
  }
  if (params.simplifier == Simplifier::Clustering) {
    simplifyClustering(eps_m, params.gridOffset_m, out);
    compact(out);
    return;
  }
  // meshoptimizer's quadric error is an area-weighted mean (a long thin box may shrink along its
  // length at a small "error"), OpenMesh's Hausdorff module checks the removed points only: the
  // result is measured and the target halved until the measured distance is within eps.
  std::vector<glm::vec3> samples;
  const size_t nt = out.indices.size() / 3, total = out.positions.size() + nt;
  const size_t cap = std::max<size_t>(1, params.maxSamples);
  const size_t stride = std::max<size_t>(1, (total + cap - 1) / cap);
  for (size_t i = 0; i < total; i += stride) {
    if (i < out.positions.size()) {
      samples.push_back(out.positions[i]);
    } else {
      const size_t t = i - out.positions.size();
      samples.push_back((out.positions[out.indices[3 * t]] + out.positions[out.indices[3 * t + 1]] + out.positions[out.indices[3 * t + 2]]) / 3.0f);
    }
  }
  const SimplifiedMesh welded = out;
  std::vector<uint32_t> complex;
  auto within = [&](const SimplifiedMesh& m) {
    complex = m.indices;
    complex.insert(complex.end(), m.collapsed.begin(), m.collapsed.end());
    return !complex.empty() && sampledHausdorff(samples, m.positions, complex) <= eps_m;
  };
  double target = eps_m;
  SimplifiedMesh candidate;
  for (int attempt = 0; attempt <= params.maxRetries; ++attempt, target *= 0.5) {
    candidate = welded;
    // The topology-preserving pass: OpenMesh's Decimater or meshopt_simplify. Either leaves every
    // closed part at least a tetrahedron, so both share the sloppy fallback below (without it
    // OpenMesh kept 705k of the site's merged triangles at scale 0.25 against meshoptimizer's 37k).
    if (params.simplifier == Simplifier::OpenMesh) {
      simplifyOpenMesh(target, candidate);
    } else {
      simplifyMeshopt(target, /*sloppy=*/false, candidate);
    }
    const bool regularOk = within(candidate);
    if (!regularOk || candidate.indices.size() / 3 > params.sloppyAboveTriangles) {
      SimplifiedMesh loose = welded;
      simplifyMeshopt(target, /*sloppy=*/true, loose);
      const size_t better = regularOk ? candidate.indices.size() : welded.indices.size();
      if (loose.indices.size() < better && within(loose)) {
        out = std::move(loose);
        break;
      }
    }
    if (regularOk) {
      out = std::move(candidate);
      break;
    }
  }
  compact(out);
}

}  // namespace ig::lod::hdlod
