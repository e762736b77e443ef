// HDLOD render pass: see hdlod_pass.h.
#include "render/hdlod_pass.h"


#include <algorithm>
#include <cstring>
#include <vector>

#include <glm/gtc/type_ptr.hpp>
#include <glm/mat4x4.hpp>

#include "render/gl.h"
#include "render/renderer.h"

namespace ig::render {
namespace {

namespace hd = lod::hdlod;


const char* kVs = R"(#version 450 core
layout(location = 0) in vec3 aPosition;   // model space, or relative to a merged mesh's origin
layout(location = 1) in uint aMaterial;   // scene model index
layout(location = 2) in uint aSlot;       // per instance: the draw's slot (baseInstance)
layout(std430, binding = 0) readonly buffer Matrices { mat4 uModel[]; };  // relative to the octant centre
layout(std430, binding = 1) readonly buffer Materials { vec4 uColor[]; };
uniform mat4 uViewProjection;             // projection * world->camera rotation
uniform vec3 uOctantOffset;               // octant centre - eye (double on the CPU)
out vec3 vEyeToPoint;
flat out vec3 vColor;
void main() {
  vec3 rel = (uModel[aSlot] * vec4(aPosition, 1.0)).xyz + uOctantOffset;
  vEyeToPoint = rel;
  vColor = uColor[min(aMaterial, uint(uColor.length() - 1))].rgb;
  gl_Position = uViewProjection * vec4(rel, 1.0);
}
)";

const char* kFs = R"(#version 450 core
in vec3 vEyeToPoint;
flat in vec3 vColor;
uniform vec3 uSunDirection;
uniform vec3 uSunColor;
uniform float uAmbient;
uniform vec3 uFogColor;
uniform float uFogDensity;
out vec4 fragColor;
void main() {
  vec3 n = normalize(cross(dFdx(vEyeToPoint), dFdy(vEyeToPoint)));
  if (dot(n, vEyeToPoint) > 0.0) n = -n;   // face the eye (two-sided)
  float diffuse = max(dot(n, uSunDirection), 0.0);
  vec3 lit = vColor * (uAmbient + (1.0 - uAmbient) * diffuse * uSunColor);
  float fog = exp(-uFogDensity * length(vEyeToPoint));
  fragColor = vec4(mix(uFogColor, lit, fog), 1.0);
}
)";

struct Vertex {
  glm::vec3 position;
  uint32_t material;
};

struct Command {
  uint32_t count, instanceCount, firstIndex;
  int32_t baseVertex;
  uint32_t baseInstance;
};

struct Range {
  uint32_t firstIndex = 0, indexCount = 0;
  int32_t baseVertex = 0;
};

constexpr uint32_t kNone = ~0u;

struct Node {
  glm::dvec3 centre{0.0};
  std::vector<Command> commands;
  std::vector<glm::mat4> matrices;
  std::vector<uint32_t> keys;
  std::vector<uint32_t> triangles;
  uint64_t triangleSum = 0;
  uint32_t dirtyLo = kNone, dirtyHi = 0;
  uint32_t capacity = 0;
  bool listed = false;  // in Impl::active
  GlBuffer commandBuffer, matrixBuffer;
  void dirty(uint32_t i) {
    dirtyLo = std::min(dirtyLo, i);
    dirtyHi = std::max(dirtyHi, i + 1);
  }
};

}  // namespace

struct HdlodPass::Impl {
  const hd::HdlodTree* tree = nullptr;
  const hd::Scene* scene = nullptr;
  GlProgram program;
  GlBuffer vertexBuffer, indexBuffer, slotBuffer, materialBuffer;
  GlVertexArray vertexArray;
  GLint uViewProjection = -1, uOctantOffset = -1, uSunDirection = -1, uSunColor = -1, uAmbient = -1, uFogColor = -1,
        uFogDensity = -1;
  std::vector<Range> modelRange, meshRange;
  int depth = 3;
  lod::Aabb box;
  std::vector<Node> nodes;                  // level order: level k starts at (8^k - 1) / 7
  // A draw's key: cluster * lodSlots + its version (0 = the model itself), lodSlots = 1 + the
  // most versions of any model, so every version of a leaf is its own draw (with a fixed 8, a
  // leaf switching between versions 8 and 9 kept the first one's command).
  uint32_t lodSlots = 1;
  std::vector<uint32_t> slotNode, slotIndex, seen;  // per key
  std::vector<uint32_t> clusterNode;        // static and merged clusters: their node
  std::vector<uint32_t> active;             // nodes with draws
  uint32_t frame = 0;
  uint64_t geometryBytes = 0;
  HdlodPassStats stats;

  // The deepest node holding `b` (single reference).
  uint32_t nodeFor(const lod::Aabb& b) const {
    uint32_t node = 0, first = 0, count = 1;
    glm::dvec3 lo = box.min, hi = box.max;
    if (glm::any(glm::lessThan(b.min, lo)) || glm::any(glm::greaterThan(b.max, hi))) return 0;
    glm::u32vec3 cell(0);
    for (int level = 0; level < depth; ++level) {
      const glm::dvec3 mid = (lo + hi) * 0.5;
      glm::u32vec3 bit(0);
      for (int a = 0; a < 3; ++a) {
        if (b.max[a] <= mid[a]) {
          hi[a] = mid[a];
        } else if (b.min[a] >= mid[a]) {
          lo[a] = mid[a];
          bit[a] = 1;
        } else {
          return node;
        }
      }
      cell = cell * 2u + bit;
      first += count;
      count *= 8;
      const uint32_t side = 1u << (level + 1);
      node = first + (cell.z * side + cell.y) * side + cell.x;
    }
    return node;
  }

  Range rangeOf(const hd::Draw& d) const {
    const hd::Cluster& c = tree->clusters[d.cluster];
    if (c.kind == hd::ClusterKind::Merged) return meshRange[c.mesh];
    if (d.lod == 0) return modelRange[c.mesh];
    const auto lods = tree->lodsOf(c.mesh);
    return d.lod <= lods.size() ? meshRange[lods[d.lod - 1].mesh] : modelRange[c.mesh];
  }

  uint32_t trianglesOf(const hd::Draw& d) const { return rangeOf(d).indexCount / 3; }

  glm::mat4 relative(const Node& n, const glm::dmat4& m) const {
    glm::dmat4 r = m;
    r[3] = glm::dvec4(glm::dvec3(m[3]) - n.centre, 1.0);
    return glm::mat4(r);
  }

  void add(uint32_t nodeId, uint32_t key, const hd::Draw& d) {
    Node& n = nodes[nodeId];
    if (!n.listed) {
      active.push_back(nodeId);
      n.listed = true;
    }
    const uint32_t i = static_cast<uint32_t>(n.keys.size());
    const Range r = rangeOf(d);
    n.commands.push_back({r.indexCount, 1, r.firstIndex, r.baseVertex, i});
    n.matrices.push_back(relative(n, *d.model));
    n.keys.push_back(key);
    n.triangles.push_back(r.indexCount / 3);
    n.triangleSum += r.indexCount / 3;
    n.dirty(i);
    slotNode[key] = nodeId;
    slotIndex[key] = i;
    ++stats.added;
  }

  void remove(uint32_t key) {
    Node& n = nodes[slotNode[key]];
    const uint32_t i = slotIndex[key], last = static_cast<uint32_t>(n.keys.size() - 1);
    n.triangleSum -= n.triangles[i];
    if (i != last) {
      n.commands[i] = n.commands[last];
      n.commands[i].baseInstance = i;
      n.matrices[i] = n.matrices[last];
      n.keys[i] = n.keys[last];
      n.triangles[i] = n.triangles[last];
      slotIndex[n.keys[i]] = i;
      n.dirty(i);
    }
    n.commands.pop_back();
    n.matrices.pop_back();
    n.keys.pop_back();
    n.triangles.pop_back();
    if (n.dirtyHi > n.keys.size()) n.dirtyHi = static_cast<uint32_t>(n.keys.size());
    slotNode[key] = kNone;
  }

  void update(std::span<const hd::Draw> draws) {
    stats = {};
    ++frame;
    for (const hd::Draw& d : draws) {
      if (d.cluster >= tree->clusters.size() || !d.model) continue;
      const uint32_t key = d.cluster * lodSlots + std::min(d.lod, lodSlots - 1);
      const hd::Cluster& c = tree->clusters[d.cluster];
      const bool moving = c.kind == hd::ClusterKind::Dynamic;
      uint32_t node = clusterNode[d.cluster];
      if (moving) node = nodeFor(hd::transformBox(scene->models[c.mesh].box, *d.model));
      seen[key] = frame;
      if (slotNode[key] == kNone) {
        add(node, key, d);
      } else if (slotNode[key] != node) {
        remove(key);
        add(node, key, d);
        --stats.added;
        ++stats.movedAcross;
      } else if (moving) {
        Node& n = nodes[node];
        const glm::mat4 m = relative(n, *d.model);
        const uint32_t i = slotIndex[key];
        if (std::memcmp(&m, &n.matrices[i], sizeof m) != 0) {
          n.matrices[i] = m;
          n.dirty(i);
          ++stats.matrixUpdates;
        }
      }
    }
    // Draws not selected this frame leave their octant.
    for (uint32_t nodeId : active) {
      Node& n = nodes[nodeId];
      for (uint32_t i = 0; i < n.keys.size();) {
        if (seen[n.keys[i]] != frame) {
          remove(n.keys[i]);
          ++stats.removed;
        } else {
          ++i;
        }
      }
    }
    active.erase(std::remove_if(active.begin(), active.end(),
                                [&](uint32_t id) {
                                  if (!nodes[id].keys.empty()) return false;
                                  nodes[id].listed = false;
                                  return true;
                                }),
                 active.end());
    // Upload the changed ranges (whole arrays when a node outgrows its buffers).
    for (uint32_t nodeId : active) {
      Node& n = nodes[nodeId];
      const uint32_t size = static_cast<uint32_t>(n.keys.size());
      if (size > n.capacity) {
        n.capacity = std::max<uint32_t>(64, 2 * size);
        GLuint ids[2];
        gl.CreateBuffers(2, ids);
        n.commandBuffer = GlBuffer::wrap(ids[0]);
        n.matrixBuffer = GlBuffer::wrap(ids[1]);
        gl.NamedBufferStorage(ids[0], static_cast<GLsizeiptr>(n.capacity * sizeof(Command)), nullptr, GL_DYNAMIC_STORAGE_BIT);
        gl.NamedBufferStorage(ids[1], static_cast<GLsizeiptr>(n.capacity * sizeof(glm::mat4)), nullptr, GL_DYNAMIC_STORAGE_BIT);
        n.dirtyLo = 0;
        n.dirtyHi = size;
      }
      if (n.dirtyLo < n.dirtyHi) {
        const uint32_t lo = n.dirtyLo, count = n.dirtyHi - lo;
        gl.NamedBufferSubData(n.commandBuffer.id(), static_cast<GLintptr>(lo * sizeof(Command)),
                              static_cast<GLsizeiptr>(count * sizeof(Command)), n.commands.data() + lo);
        gl.NamedBufferSubData(n.matrixBuffer.id(), static_cast<GLintptr>(lo * sizeof(glm::mat4)),
                              static_cast<GLsizeiptr>(count * sizeof(glm::mat4)), n.matrices.data() + lo);
        stats.uploadedBytes += count * (sizeof(Command) + sizeof(glm::mat4));
      }
      n.dirtyLo = kNone;
      n.dirtyHi = 0;
    }
  }

  uint64_t gpuBytes() const {
    uint64_t b = geometryBytes;
    for (const Node& n : nodes) b += static_cast<uint64_t>(n.capacity) * (sizeof(Command) + sizeof(glm::mat4));
    return b;
  }
};

HdlodPass::HdlodPass() : impl_(std::make_unique<Impl>()) {}
HdlodPass::~HdlodPass() = default;

void hdlodMaterialColor(const std::string& name, float rgb[3]) {
  struct Named {
    const char* name;
    float r, g, b;
  };
  static const Named kColors[] = {
      {"ground_tile", 0.42f, 0.38f, 0.30f}, {"office", 0.85f, 0.85f, 0.80f},  {"fence", 0.30f, 0.45f, 0.30f},
      {"crane_mast", 0.90f, 0.72f, 0.10f},  {"crane_jib", 0.90f, 0.72f, 0.10f}, {"column", 0.70f, 0.70f, 0.68f},
      {"beam", 0.55f, 0.55f, 0.58f},        {"slab", 0.75f, 0.74f, 0.70f},     {"facade_panel", 0.80f, 0.72f, 0.60f},
      {"window", 0.35f, 0.50f, 0.65f},      {"scaffold", 0.85f, 0.45f, 0.15f}, {"load", 0.55f, 0.40f, 0.25f},
      {"truck", 0.80f, 0.20f, 0.15f},       {"excavator", 0.95f, 0.65f, 0.10f},
  };
  for (const Named& n : kColors) {
    if (name == n.name) {
      rgb[0] = n.r;
      rgb[1] = n.g;
      rgb[2] = n.b;
      return;
    }
  }
  uint32_t h = 2166136261u;  // FNV-1a
  for (unsigned char ch : name) h = (h ^ ch) * 16777619u;
  for (int i = 0; i < 3; ++i) rgb[i] = 0.35f + 0.5f * static_cast<float>((h >> (8 * i)) & 0xffu) / 255.0f;
}

bool HdlodPass::init(const hd::HdlodTree& tree, const hd::Scene& scene, int octreeDepth, std::string& error) {
  Impl& m = *impl_;
  if (octreeDepth < 0 || octreeDepth > 6) {
    error = "hdlod pass: octree depth " + std::to_string(octreeDepth) + ": must be 0..6";
    return false;
  }
  m.tree = &tree;
  m.scene = &scene;
  m.depth = octreeDepth;
  m.program = buildProgram(kVs, kFs, error);
  if (!m.program) {
    error = "hdlod pass: " + error;
    return false;
  }
  const GLuint p = m.program.id();
  m.uViewProjection = gl.GetUniformLocation(p, "uViewProjection");
  m.uOctantOffset = gl.GetUniformLocation(p, "uOctantOffset");
  m.uSunDirection = gl.GetUniformLocation(p, "uSunDirection");
  m.uSunColor = gl.GetUniformLocation(p, "uSunColor");
  m.uAmbient = gl.GetUniformLocation(p, "uAmbient");
  m.uFogColor = gl.GetUniformLocation(p, "uFogColor");
  m.uFogDensity = gl.GetUniformLocation(p, "uFogDensity");

  // Geometry: models, then meshes (merged clusters and model versions).
  std::vector<Vertex> vertices;
  std::vector<uint32_t> indices;
  auto append = [&](std::span<const glm::vec3> pos, std::span<const uint32_t> idx, auto materialOf) {
    Range r;
    r.firstIndex = static_cast<uint32_t>(indices.size());
    r.indexCount = static_cast<uint32_t>(idx.size());
    r.baseVertex = static_cast<int32_t>(vertices.size());
    for (size_t i = 0; i < pos.size(); ++i) vertices.push_back({pos[i], materialOf(i)});
    indices.insert(indices.end(), idx.begin(), idx.end());
    return r;
  };
  m.modelRange.clear();
  for (size_t i = 0; i < scene.models.size(); ++i) {
    const hd::Model& model = scene.models[i];
    m.modelRange.push_back(append(model.positions, model.indices, [&](size_t) { return static_cast<uint32_t>(i); }));
  }
  // Meshes carry a material per triangle: their vertices are unshared (three per triangle).
  m.meshRange.clear();
  std::vector<glm::vec3> flat;
  std::vector<uint32_t> flatIndices;
  for (const hd::ClusterMesh& mesh : tree.meshes) {
    flat.clear();
    flatIndices.clear();
    for (uint32_t i : mesh.indices) {
      flatIndices.push_back(static_cast<uint32_t>(flat.size()));
      flat.push_back(mesh.positions[i]);
    }
    m.meshRange.push_back(append(flat, flatIndices, [&](size_t v) {
      return v / 3 < mesh.materials.size() ? static_cast<uint32_t>(mesh.materials[v / 3]) : 0u;
    }));
  }
  std::vector<glm::vec4> colors;
  for (const hd::Model& model : scene.models) {
    float rgb[3];
    hdlodMaterialColor(model.name, rgb);
    colors.emplace_back(rgb[0], rgb[1], rgb[2], 1.0f);
  }
  if (colors.empty()) colors.emplace_back(0.7f, 0.7f, 0.7f, 1.0f);
  if (vertices.empty()) vertices.push_back({glm::vec3(0.0f), 0});
  if (indices.empty()) indices.assign(3, 0);
  const size_t maxSlots = std::max<size_t>(1, hd::drawBound(tree));
  std::vector<uint32_t> slots(maxSlots);
  for (size_t i = 0; i < slots.size(); ++i) slots[i] = static_cast<uint32_t>(i);

  GLuint ids[4];
  gl.CreateBuffers(4, ids);
  m.vertexBuffer = GlBuffer::wrap(ids[0]);
  m.indexBuffer = GlBuffer::wrap(ids[1]);
  m.slotBuffer = GlBuffer::wrap(ids[2]);
  m.materialBuffer = GlBuffer::wrap(ids[3]);
  const auto vb = static_cast<GLsizeiptr>(vertices.size() * sizeof(Vertex));
  const auto ib = static_cast<GLsizeiptr>(indices.size() * sizeof(uint32_t));
  const auto sb = static_cast<GLsizeiptr>(slots.size() * sizeof(uint32_t));
  const auto cb = static_cast<GLsizeiptr>(colors.size() * sizeof(glm::vec4));
  gl.NamedBufferStorage(ids[0], vb, vertices.data(), 0);
  gl.NamedBufferStorage(ids[1], ib, indices.data(), 0);
  gl.NamedBufferStorage(ids[2], sb, slots.data(), 0);
  gl.NamedBufferStorage(ids[3], cb, colors.data(), 0);
  m.geometryBytes = static_cast<uint64_t>(vb + ib + sb + cb);

  GLuint vao = 0;
  gl.CreateVertexArrays(1, &vao);
  m.vertexArray = GlVertexArray::wrap(vao);
  gl.VertexArrayVertexBuffer(vao, 0, ids[0], 0, sizeof(Vertex));
  gl.VertexArrayVertexBuffer(vao, 1, ids[2], 0, sizeof(uint32_t));
  gl.VertexArrayBindingDivisor(vao, 1, 1);
  gl.EnableVertexArrayAttrib(vao, 0);
  gl.VertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
  gl.VertexArrayAttribBinding(vao, 0, 0);
  gl.EnableVertexArrayAttrib(vao, 1);
  gl.VertexArrayAttribIFormat(vao, 1, 1, GL_UNSIGNED_INT, offsetof(Vertex, material));
  gl.VertexArrayAttribBinding(vao, 1, 0);
  gl.EnableVertexArrayAttrib(vao, 2);
  gl.VertexArrayAttribIFormat(vao, 2, 1, GL_UNSIGNED_INT, 0);
  gl.VertexArrayAttribBinding(vao, 2, 1);
  gl.VertexArrayElementBuffer(vao, ids[1]);

  // Octree over the root box.
  m.box = tree.root < tree.clusters.size() ? tree.clusters[tree.root].box : lod::Aabb{};
  m.nodes.clear();
  size_t count = 1;
  for (int level = 0; level <= m.depth; ++level) {
    const uint32_t side = 1u << level;
    const glm::dvec3 size = (m.box.max - m.box.min) / static_cast<double>(side);
    for (size_t i = 0; i < count; ++i) {
      Node n;
      const glm::dvec3 cell(static_cast<double>(i % side), static_cast<double>((i / side) % side), static_cast<double>(i / side / side));
      n.centre = m.box.min + (cell + 0.5) * size;
      m.nodes.push_back(std::move(n));
    }
    count *= 8;
  }
  // Versions per model: BuildConfig::modelLodLevels + 1 (each eps twice the one before), so
  // more than 63 is no tree the builder makes (a damaged cache's would overflow the keys).
  constexpr uint32_t kMaxLodSlots = 64;
  m.lodSlots = 1;
  for (size_t i = 0; i + 1 < tree.modelLodBegin.size(); ++i) {
    const uint64_t versions = uint64_t{tree.modelLodBegin[i + 1]} - tree.modelLodBegin[i];
    if (tree.modelLodBegin[i + 1] < tree.modelLodBegin[i] || versions + 1 > kMaxLodSlots ||
        tree.clusters.size() * kMaxLodSlots > uint64_t{kNone}) {
      error = "hdlod pass: model " + std::to_string(i) + ": " + std::to_string(versions) + " versions for " +
              std::to_string(tree.clusters.size()) + " clusters (at most " + std::to_string(kMaxLodSlots - 1) + " versions)";
      return false;
    }
    m.lodSlots = std::max(m.lodSlots, static_cast<uint32_t>(versions + 1));
  }
  const size_t keys = tree.clusters.size() * m.lodSlots;
  m.slotNode.assign(keys, kNone);
  m.slotIndex.assign(keys, kNone);
  m.seen.assign(keys, 0);
  m.clusterNode.resize(tree.clusters.size());
  for (size_t i = 0; i < tree.clusters.size(); ++i) m.clusterNode[i] = m.nodeFor(tree.clusters[i].box);
  m.active.clear();
  m.active.reserve(m.nodes.size());
  const std::string e = glErrors();
  if (!e.empty()) {
    error = "hdlod pass: GL errors at init: " + e;
    return false;
  }
  return true;
}

void HdlodPass::draw(Renderer& renderer, std::span<const hd::Draw> draws) {
  Impl& m = *impl_;
  if (!m.tree) return;
  m.update(draws);
  const lod::Camera& camera = renderer.camera();
  const Lighting& lighting = renderer.lighting();
  const GLuint p = m.program.id();
  const glm::mat4 viewProjection(lod::projection(camera) *
                                 glm::dmat4(lod::viewRotation(camera)));
  gl.ProgramUniformMatrix4fv(p, m.uViewProjection, 1, GL_FALSE, glm::value_ptr(viewProjection));
  const glm::vec3 sun(lighting.sunDirection), sunColor(lighting.sunColor), fogColor(lighting.fogColor);
  gl.ProgramUniform3fv(p, m.uSunDirection, 1, glm::value_ptr(sun));
  gl.ProgramUniform3fv(p, m.uSunColor, 1, glm::value_ptr(sunColor));
  gl.ProgramUniform1f(p, m.uAmbient, static_cast<float>(lighting.ambient));
  gl.ProgramUniform3fv(p, m.uFogColor, 1, glm::value_ptr(fogColor));
  gl.ProgramUniform1f(p, m.uFogDensity, lighting.fog ? static_cast<float>(kFogExtinction / lighting.fogVisibility_m) : 0.0f);
  gl.UseProgram(p);
  gl.BindVertexArray(m.vertexArray.id());
  gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, m.materialBuffer.id());
  for (uint32_t nodeId : m.active) {
    const Node& n = m.nodes[nodeId];
    const glm::vec3 offset(n.centre - camera.eye_m);
    gl.ProgramUniform3fv(p, m.uOctantOffset, 1, glm::value_ptr(offset));
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, n.matrixBuffer.id());
    gl.BindBuffer(GL_DRAW_INDIRECT_BUFFER, n.commandBuffer.id());
    gl.MultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_INT, nullptr, static_cast<GLsizei>(n.keys.size()), 0);
    ++m.stats.multiDraws;
    m.stats.draws += static_cast<uint32_t>(n.keys.size());
    m.stats.triangles += n.triangleSum;
  }
  gl.BindBuffer(GL_DRAW_INDIRECT_BUFFER, 0);
  gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, 0);
  gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, 0);
  gl.BindVertexArray(0);
  gl.UseProgram(0);
  renderer.addStats(m.stats.triangles, m.stats.multiDraws);
}

const HdlodPassStats& HdlodPass::lastStats() const { return impl_->stats; }

uint64_t HdlodPass::bufferBytes() const { return impl_->gpuBytes(); }

void HdlodPass::clear() {
  Impl& m = *impl_;
  for (uint32_t id : m.active) {
    Node& n = m.nodes[id];
    for (uint32_t key : n.keys) m.slotNode[key] = kNone;
    n.commands.clear();
    n.matrices.clear();
    n.keys.clear();
    n.triangles.clear();
    n.triangleSum = 0;
    n.listed = false;
  }
  m.active.clear();
}

}  // namespace ig::render
