// HDLOD model files beyond OBJ: PLY (own reader), glTF 2.0 (Debian's libtinygltf) and IFC
// (Debian's libassimp). See hdlod_scene.h.
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <glm/mat4x4.hpp>

#include "lod/hdlod_scene.h"

namespace ig::lod::hdlod {
namespace {

Model finish(Model m) {
  Scene tmp;
  tmp.models.push_back(std::move(m));
  computeModelBoxes(tmp);
  return std::move(tmp.models[0]);
}

bool endsWith(const std::string& s, const char* suffix) {
  const size_t n = std::strlen(suffix);
  if (s.size() < n) return false;
  for (size_t i = 0; i < n; ++i) {
    if (std::tolower(static_cast<unsigned char>(s[s.size() - n + i])) != suffix[i]) return false;
  }
  return true;
}

// ---------------------------------------------------------------- PLY

enum class PlyType : uint8_t { I8, U8, I16, U16, I32, U32, F32, F64 };

bool plyType(const std::string& name, PlyType& t) {
  static const std::pair<const char*, PlyType> kTypes[] = {
      {"char", PlyType::I8},     {"int8", PlyType::I8},      {"uchar", PlyType::U8},   {"uint8", PlyType::U8},
      {"short", PlyType::I16},   {"int16", PlyType::I16},    {"ushort", PlyType::U16}, {"uint16", PlyType::U16},
      {"int", PlyType::I32},     {"int32", PlyType::I32},    {"uint", PlyType::U32},   {"uint32", PlyType::U32},
      {"float", PlyType::F32},   {"float32", PlyType::F32},  {"double", PlyType::F64}, {"float64", PlyType::F64},
  };
  for (const auto& [n, v] : kTypes) {
    if (name == n) {
      t = v;
      return true;
    }
  }
  return false;
}

size_t plySize(PlyType t) {
  switch (t) {
    case PlyType::I8:
    case PlyType::U8: return 1;
    case PlyType::I16:
    case PlyType::U16: return 2;
    case PlyType::I32:
    case PlyType::U32:
    case PlyType::F32: return 4;
    case PlyType::F64: return 8;
  }
  return 1;
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::F32;
  bool list = false;
  PlyType countType = PlyType::U8;
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;
};

// Reads values from the body: ASCII tokens or binary of either byte order.
class PlyBody {
 public:
  PlyBody(const std::string& data, size_t at, int format) : data_(data), at_(at), format_(format) {}
  bool read(PlyType t, double& out) {
    bad_.clear();
    if (format_ == 0) {
      while (at_ < data_.size() && std::isspace(static_cast<unsigned char>(data_[at_]))) ++at_;
      if (at_ >= data_.size()) return false;
      const char* begin = data_.c_str() + at_;
      char* end = nullptr;
      out = std::strtod(begin, &end);
      if (end == begin || !std::isfinite(out)) {
        size_t e = at_;
        while (e < data_.size() && e - at_ < 32 && !std::isspace(static_cast<unsigned char>(data_[e]))) ++e;
        bad_ = data_.substr(at_, e - at_);
        return false;
      }
      at_ += static_cast<size_t>(end - begin);
      return true;
    }
    const size_t n = plySize(t);
    if (at_ + n > data_.size()) return false;
    unsigned char b[8];
    std::memcpy(b, data_.data() + at_, n);
    at_ += n;
    if (format_ == 2) std::reverse(b, b + n);
    switch (t) {
      case PlyType::I8: out = static_cast<int8_t>(b[0]); break;
      case PlyType::U8: out = b[0]; break;
      case PlyType::I16: { int16_t v; std::memcpy(&v, b, 2); out = v; break; }
      case PlyType::U16: { uint16_t v; std::memcpy(&v, b, 2); out = v; break; }
      case PlyType::I32: { int32_t v; std::memcpy(&v, b, 4); out = v; break; }
      case PlyType::U32: { uint32_t v; std::memcpy(&v, b, 4); out = v; break; }
      case PlyType::F32: { float v; std::memcpy(&v, b, 4); out = static_cast<double>(v); break; }
      case PlyType::F64: { double v; std::memcpy(&v, b, 8); out = v; break; }
    }
    if (std::isfinite(out)) return true;
    bad_ = std::isnan(out) ? "nan" : out > 0 ? "inf" : "-inf";
    return false;
  }
  size_t remaining() const { return data_.size() - at_; }
  // Why the last read() failed: "truncated" at the end of the data, else the value as written.
  std::string why() const { return bad_.empty() ? std::string("truncated") : "not a finite number: '" + bad_ + "'"; }

 private:
  const std::string& data_;
  size_t at_;
  int format_;  // 0 ascii, 1 binary little endian, 2 binary big endian
  std::string bad_;
};

// ---------------------------------------------------------------- glTF

glm::dmat4 nodeMatrix(const tinygltf::Node& n) {
  if (n.matrix.size() == 16) return glm::make_mat4(n.matrix.data());
  glm::dmat4 m(1.0);
  if (n.translation.size() == 3) m[3] = glm::dvec4(n.translation[0], n.translation[1], n.translation[2], 1.0);
  if (n.rotation.size() == 4) m = m * glm::mat4_cast(glm::dquat(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]));
  if (n.scale.size() == 3) {
    m[0] *= n.scale[0];
    m[1] *= n.scale[1];
    m[2] *= n.scale[2];
  }
  return m;
}

// The element data of an accessor: pointer, stride and count, or false when out of range.
bool accessorData(const tinygltf::Model& g, int index, int wantComponents, const unsigned char*& data, size_t& stride,
                  size_t& count, int& componentType, std::string& why) {
  if (index < 0 || static_cast<size_t>(index) >= g.accessors.size()) {
    why = "accessor " + std::to_string(index) + " out of range";
    return false;
  }
  const tinygltf::Accessor& a = g.accessors[static_cast<size_t>(index)];
  if (a.sparse.isSparse) {
    why = "sparse accessor " + std::to_string(index) + " (not supported)";
    return false;
  }
  const int components = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(a.type));
  if (components != wantComponents || a.bufferView < 0 || static_cast<size_t>(a.bufferView) >= g.bufferViews.size()) {
    why = "accessor " + std::to_string(index) + ": unexpected type or buffer view";
    return false;
  }
  const tinygltf::BufferView& v = g.bufferViews[static_cast<size_t>(a.bufferView)];
  if (v.buffer < 0 || static_cast<size_t>(v.buffer) >= g.buffers.size()) {
    why = "buffer view " + std::to_string(a.bufferView) + ": no buffer";
    return false;
  }
  const tinygltf::Buffer& b = g.buffers[static_cast<size_t>(v.buffer)];
  const int componentBytes = tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(a.componentType));
  if (componentBytes <= 0) {
    why = "accessor " + std::to_string(index) + ": bad component type";
    return false;
  }
  const size_t element = static_cast<size_t>(componentBytes) * static_cast<size_t>(components);
  stride = v.byteStride ? v.byteStride : element;
  count = a.count;
  // Every offset, length and count is a 64-bit number from the file: compare without sums or
  // products that can wrap (a count of 2^62 + 1 with stride 4 made (count - 1) * stride zero).
  const size_t size = b.data.size();
  if (v.byteOffset > size || v.byteLength > size - v.byteOffset || a.byteOffset > v.byteLength ||
      (count > 0 && (element > v.byteLength - a.byteOffset || count - 1 > (v.byteLength - a.byteOffset - element) / stride))) {
    why = "accessor " + std::to_string(index) + ": data past the end of its buffer (byteOffset " + std::to_string(a.byteOffset) +
          ", count " + std::to_string(count) + ", buffer view " + std::to_string(a.bufferView) + " of " +
          std::to_string(v.byteLength) + " bytes at " + std::to_string(v.byteOffset) + ")";
    return false;
  }
  data = b.data.data() + v.byteOffset + a.byteOffset;
  componentType = a.componentType;
  return true;
}

// Totals of one loaded glTF (a mesh counts once per node that instances it): 1.2 GB of
// vertices, 1.2 GB of indices.
constexpr size_t kMaxGltfVertices = 100000000;
constexpr size_t kMaxGltfIndices = 300000000;

// A double that stays finite when stored as the model's float (1e39 does not).
bool finiteAsFloat(double v) { return std::isfinite(v) && std::abs(v) <= static_cast<double>(std::numeric_limits<float>::max()); }

bool skipImages(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) { return true; }

}  // namespace

std::optional<Model> loadPly(const std::string& path, std::string& error, glm::dvec3* localOrigin) {
  if (localOrigin) *localOrigin = glm::dvec3(0.0);
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = path + ": cannot open";
    return std::nullopt;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string data = ss.str();
  // Header.
  size_t at = 0;
  int lineNo = 0, format = -1;
  std::vector<PlyElement> elements;
  auto fail = [&](const std::string& what) {
    error = path + ":" + std::to_string(lineNo) + ": " + what;
    return std::nullopt;
  };
  bool ended = false;
  while (!ended) {
    const size_t eol = data.find('\n', at);
    if (eol == std::string::npos) {
      ++lineNo;
      return fail("no 'end_header'");
    }
    std::string line = data.substr(at, eol - at);
    at = eol + 1;
    ++lineNo;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (lineNo == 1) {
      if (word != "ply") return fail("not a PLY file (first line '" + line + "')");
      continue;
    }
    if (word == "format") {
      std::string f;
      ls >> f;
      format = f == "ascii" ? 0 : f == "binary_little_endian" ? 1 : f == "binary_big_endian" ? 2 : -2;
      if (format == -2) return fail("unknown format: " + f);
    } else if (word == "element") {
      PlyElement e;
      long long count = -1;
      ls >> e.name >> count;
      if (e.name.empty() || count < 0) return fail("bad element line: " + line);
      e.count = static_cast<uint64_t>(count);
      elements.push_back(e);
    } else if (word == "property") {
      if (elements.empty()) return fail("property before any element: " + line);
      PlyProperty p;
      std::string type;
      ls >> type;
      if (type == "list") {
        std::string countType, itemType;
        ls >> countType >> itemType >> p.name;
        if (!plyType(countType, p.countType) || !plyType(itemType, p.type)) return fail("unknown list type: " + line);
        p.list = true;
      } else {
        ls >> p.name;
        if (!plyType(type, p.type)) return fail("unknown property type: " + type);
      }
      elements.back().properties.push_back(p);
    } else if (word == "end_header") {
      ended = true;
    } else if (word != "comment" && word != "obj_info" && !word.empty()) {
      return fail("unknown header line: " + line);
    }
  }
  if (format < 0) return fail("missing 'format' line");
  PlyBody body(data, at, format);
  Model m;
  m.name = path;
  for (const PlyElement& e : elements) {
    const bool isVertex = e.name == "vertex", isFace = e.name == "face";
    if (e.count > body.remaining() + 1) {
      error = path + ": element " + e.name + ": count " + std::to_string(e.count) + " larger than the file";
      return std::nullopt;
    }
    int xi = -1, yi = -1, zi = -1;
    for (size_t k = 0; k < e.properties.size(); ++k) {
      const std::string& n = e.properties[k].name;
      if (n == "x") xi = static_cast<int>(k);
      if (n == "y") yi = static_cast<int>(k);
      if (n == "z") zi = static_cast<int>(k);
    }
    if (isVertex && (xi < 0 || yi < 0 || zi < 0)) {
      error = path + ": element vertex without x, y and z properties";
      return std::nullopt;
    }
    std::vector<uint32_t> face;
    for (uint64_t i = 0; i < e.count; ++i) {
      double xyz[3] = {0, 0, 0};
      for (size_t k = 0; k < e.properties.size(); ++k) {
        const PlyProperty& p = e.properties[k];
        if (!p.list) {
          double v = 0;
          if (!body.read(p.type, v)) {
            error = path + ": element " + e.name + " " + std::to_string(i) + ": property " + p.name + ": " + body.why();
            return std::nullopt;
          }
          if (static_cast<int>(k) == xi) xyz[0] = v;
          if (static_cast<int>(k) == yi) xyz[1] = v;
          if (static_cast<int>(k) == zi) xyz[2] = v;
          continue;
        }
        double n = 0;
        if (!body.read(p.countType, n)) {
          error = path + ": element " + e.name + " " + std::to_string(i) + ": list length: " + body.why();
          return std::nullopt;
        }
        if (n < 0 || n > 1e6 || n != std::floor(n)) {
          char written[32];
          std::snprintf(written, sizeof written, "%.15g", n);
          error = path + ": element " + e.name + " " + std::to_string(i) + ": bad list length " + written + " (0 .. 1000000)";
          return std::nullopt;
        }
        const bool indices = isFace && (p.name == "vertex_indices" || p.name == "vertex_index");
        face.clear();
        for (int j = 0; j < static_cast<int>(n); ++j) {
          double v = 0;
          if (!body.read(p.type, v)) {
            error = path + ": element " + e.name + " " + std::to_string(i) + ": list item " + std::to_string(j) + ": " + body.why();
            return std::nullopt;
          }
          if (!indices) continue;
          if (v < 0 || v >= static_cast<double>(m.positions.size()) || v != std::floor(v)) {
            char written[32];  // as written: a float index may be a fraction or beyond any integer type
            std::snprintf(written, sizeof written, "%.15g", v);
            error = path + ": face " + std::to_string(i) + ": bad vertex index " + written + " (" +
                    std::to_string(m.positions.size()) + " vertices)";
            return std::nullopt;
          }
          face.push_back(static_cast<uint32_t>(v));
        }
        for (size_t j = 2; j < face.size(); ++j) m.indices.insert(m.indices.end(), {face[0], face[j - 1], face[j]});
      }
      if (isVertex) {
        if (localOrigin && m.positions.empty()) *localOrigin = glm::dvec3(xyz[0], xyz[1], xyz[2]);
        if (localOrigin)
          for (int c = 0; c < 3; ++c) xyz[c] -= (*localOrigin)[c];
        if (!finiteAsFloat(xyz[0]) || !finiteAsFloat(xyz[1]) || !finiteAsFloat(xyz[2])) {
          error = path + ": vertex " + std::to_string(i) + ": coordinate out of the float range";
          return std::nullopt;
        }
        m.positions.emplace_back(static_cast<float>(xyz[0]), static_cast<float>(xyz[1]), static_cast<float>(xyz[2]));
      }
    }
  }
  return finish(std::move(m));
}

std::optional<Model> loadGltf(const std::string& path, std::string& error, glm::dvec3* localOrigin) {
  if (localOrigin) *localOrigin = glm::dvec3(0.0);
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&skipImages, nullptr);
  tinygltf::Model g;
  std::string err, warn;
  const bool ok = endsWith(path, ".glb") ? loader.LoadBinaryFromFile(&g, &err, &warn, path) : loader.LoadASCIIFromFile(&g, &err, &warn, path);
  if (!ok) {
    while (!err.empty() && (err.back() == '\n' || err.back() == '\r')) err.pop_back();
    error = path + ": cannot load glTF: " + (err.empty() ? std::string("unknown error") : err);
    return std::nullopt;
  }
  // glTF is y up; ours z up (x east, y north): (x, y, z) -> (x, -z, y).
  const glm::dmat4 yUpToZUp(glm::dvec4(1, 0, 0, 0), glm::dvec4(0, 0, 1, 0), glm::dvec4(0, -1, 0, 0), glm::dvec4(0, 0, 0, 1));
  Model m;
  m.name = path;
  std::string why;
  std::vector<std::pair<int, glm::dmat4>> stack;
  std::vector<int> roots;
  if (!g.scenes.empty()) {
    const size_t s = g.defaultScene >= 0 && static_cast<size_t>(g.defaultScene) < g.scenes.size() ? static_cast<size_t>(g.defaultScene) : 0;
    roots = g.scenes[s].nodes;
  } else {
    // No scene: the roots are the nodes no other node names as a child (taking every node as a
    // root drew each child twice, once without its parents' transforms).
    std::vector<uint8_t> isChild(g.nodes.size(), 0);
    for (const tinygltf::Node& n : g.nodes)
      for (int c : n.children)
        if (c >= 0 && static_cast<size_t>(c) < g.nodes.size()) isChild[static_cast<size_t>(c)] = 1;
    for (size_t i = 0; i < g.nodes.size(); ++i)
      if (!isChild[i]) roots.push_back(static_cast<int>(i));
    if (roots.empty() && !g.nodes.empty()) {
      error = path + ": every node is a child of another (a cycle)";
      return std::nullopt;
    }
  }
  for (int r : roots) stack.emplace_back(r, yUpToZUp);
  // glTF node hierarchies are strict trees (each node has at most one parent): a node reached
  // twice is a cycle or a shared child, which could multiply the geometry exponentially.
  std::vector<uint8_t> seen(g.nodes.size(), 0);
  while (!stack.empty()) {
    const auto [index, parent] = stack.back();
    stack.pop_back();
    if (index < 0 || static_cast<size_t>(index) >= g.nodes.size()) {
      error = path + ": bad node index " + std::to_string(index) + " (" + std::to_string(g.nodes.size()) + " nodes)";
      return std::nullopt;
    }
    if (seen[static_cast<size_t>(index)]++) {
      error = path + ": node " + std::to_string(index) + " is reached twice (a cycle, or a node with two parents)";
      return std::nullopt;
    }
    const tinygltf::Node& node = g.nodes[static_cast<size_t>(index)];
    const glm::dmat4 world = parent * nodeMatrix(node);
    for (int c : node.children) stack.emplace_back(c, world);
    if (node.mesh < 0) continue;
    if (static_cast<size_t>(node.mesh) >= g.meshes.size()) {
      error = path + ": node " + std::to_string(index) + ": bad mesh index " + std::to_string(node.mesh);
      return std::nullopt;
    }
    for (const tinygltf::Primitive& prim : g.meshes[static_cast<size_t>(node.mesh)].primitives) {
      const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
      if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) continue;
      const auto pos = prim.attributes.find("POSITION");
      if (pos == prim.attributes.end()) continue;
      const unsigned char* pdata = nullptr;
      size_t pstride = 0, pcount = 0;
      int ptype = 0;
      if (!accessorData(g, pos->second, 3, pdata, pstride, pcount, ptype, why) || ptype != TINYGLTF_COMPONENT_TYPE_FLOAT) {
        error = path + ": " + (why.empty() ? "POSITION is not float" : why);
        return std::nullopt;
      }
      // Meshes may be instanced by many nodes: bound the total before allocating (and keep
      // every vertex addressable by a 32-bit index).
      if (pcount > kMaxGltfVertices - m.positions.size()) {
        error = path + ": node " + std::to_string(index) + ": more than " + std::to_string(kMaxGltfVertices) +
                " vertices in all (POSITION count " + std::to_string(pcount) + ")";
        return std::nullopt;
      }
      const uint32_t base = static_cast<uint32_t>(m.positions.size());
      for (size_t i = 0; i < pcount; ++i) {
        float p[3];
        std::memcpy(p, pdata + i * pstride, sizeof p);
        glm::dvec4 w = world * glm::dvec4(p[0], p[1], p[2], 1.0);
        if (localOrigin && m.positions.empty()) *localOrigin = glm::dvec3(w);
        if (localOrigin) w -= glm::dvec4(*localOrigin, 0.0);
        if (!finiteAsFloat(w.x) || !finiteAsFloat(w.y) || !finiteAsFloat(w.z)) {
          error = path + ": vertex " + std::to_string(i) + " not finite";
          return std::nullopt;
        }
        m.positions.emplace_back(static_cast<float>(w.x), static_cast<float>(w.y), static_cast<float>(w.z));
      }
      std::vector<uint32_t> idx;
      if (prim.indices >= 0) {
        const unsigned char* idata = nullptr;
        size_t istride = 0, icount = 0;
        int itype = 0;
        if (!accessorData(g, prim.indices, 1, idata, istride, icount, itype, why)) {
          error = path + ": " + why;
          return std::nullopt;
        }
        for (size_t i = 0; i < icount; ++i) {
          uint32_t v = 0;
          if (itype == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE) {
            v = idata[i * istride];
          } else if (itype == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) {
            uint16_t s;
            std::memcpy(&s, idata + i * istride, 2);
            v = s;
          } else if (itype == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
            std::memcpy(&v, idata + i * istride, 4);
          } else {
            error = path + ": index accessor " + std::to_string(prim.indices) + ": bad component type";
            return std::nullopt;
          }
          if (v >= pcount) {
            error = path + ": index " + std::to_string(v) + " past the " + std::to_string(pcount) + " vertices of its primitive";
            return std::nullopt;
          }
          idx.push_back(v);
        }
      } else {
        for (size_t i = 0; i < pcount; ++i) idx.push_back(static_cast<uint32_t>(i));
      }
      if (idx.size() * 3 > kMaxGltfIndices - m.indices.size()) {
        error = path + ": node " + std::to_string(index) + ": more than " + std::to_string(kMaxGltfIndices) + " indices in all";
        return std::nullopt;
      }
      if (mode == TINYGLTF_MODE_TRIANGLES) {
        for (size_t i = 0; i + 2 < idx.size(); i += 3) m.indices.insert(m.indices.end(), {base + idx[i], base + idx[i + 1], base + idx[i + 2]});
      } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        for (size_t i = 2; i < idx.size(); ++i) {
          const bool odd = (i & 1) != 0;
          m.indices.insert(m.indices.end(), {base + idx[odd ? i - 1 : i - 2], base + idx[odd ? i - 2 : i - 1], base + idx[i]});
        }
      } else {
        for (size_t i = 2; i < idx.size(); ++i) m.indices.insert(m.indices.end(), {base + idx[0], base + idx[i - 1], base + idx[i]});
      }
    }
  }
  // A rotation or mirror in the node matrices can turn triangles inside out; the renderer
  // shades both sides, so the winding is kept as is.
  return finish(std::move(m));
}

std::optional<Model> loadIfc(const std::string& path, std::string& error, glm::dvec3* localOrigin) {
  if (localOrigin) *localOrigin = glm::dvec3(0.0);
  {
    // assimp picks its importer by content when the extension does not match, so an OBJ named
    // .ifc would load as OBJ: check the STEP magic first.
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      error = path + ": cannot open";
      return std::nullopt;
    }
    char magic[13] = {};
    in.read(magic, sizeof magic);
    if (in.gcount() != static_cast<std::streamsize>(sizeof magic) || std::memcmp(magic, "ISO-10303-21;", sizeof magic) != 0) {
      error = path + ": not an IFC (STEP) file: expected 'ISO-10303-21;' at its start";
      return std::nullopt;
    }
  }
  Assimp::Importer importer;
  // Lines and points are dropped (aiProcess_SortByPType + the removal flag); node transforms
  // are applied to the vertices (aiProcess_PreTransformVertices).
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const aiScene* s = importer.ReadFile(path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_SortByPType |
                                                 aiProcess_PreTransformVertices);
  if (s == nullptr || (s->mFlags & AI_SCENE_FLAGS_INCOMPLETE) != 0) {
    std::string why = importer.GetErrorString();
    while (!why.empty() && (why.back() == '\n' || why.back() == '\r')) why.pop_back();
    error = path + ": cannot load IFC: " + (why.empty() ? std::string("incomplete scene") : why);
    return std::nullopt;
  }
  // assimp's IFC importer converts the file's length unit to metres and its z up to y up; back
  // to ours: (x, y, z) -> (x, -z, y).
  Model m;
  m.name = path;
  for (unsigned i = 0; i < s->mNumMeshes; ++i) {
    const aiMesh* mesh = s->mMeshes[i];
    const uint32_t base = static_cast<uint32_t>(m.positions.size());
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D& p = mesh->mVertices[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
        error = path + ": mesh " + std::to_string(i) + ": vertex " + std::to_string(v) + " not finite";
        return std::nullopt;
      }
      const glm::dvec3 q(static_cast<double>(p.x), -static_cast<double>(p.z), static_cast<double>(p.y));
      if (localOrigin && m.positions.empty()) *localOrigin = q;
      const glm::dvec3 r = localOrigin ? q - *localOrigin : q;
      m.positions.emplace_back(static_cast<float>(r.x), static_cast<float>(r.y), static_cast<float>(r.z));
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;
      for (unsigned k = 0; k < 3; ++k) {
        if (face.mIndices[k] >= mesh->mNumVertices) {
          error = path + ": mesh " + std::to_string(i) + ": index " + std::to_string(face.mIndices[k]) + " out of range";
          return std::nullopt;
        }
        m.indices.push_back(base + face.mIndices[k]);
      }
    }
  }
  if (m.indices.empty()) {
    error = path + ": IFC file without triangles";
    return std::nullopt;
  }
  return finish(std::move(m));
}

std::optional<Model> loadModelFile(const std::string& path, std::string& error, glm::dvec3* localOrigin) {
  if (localOrigin) *localOrigin = glm::dvec3(0.0);
  if (endsWith(path, ".obj")) return loadObj(path, error, localOrigin);
  if (endsWith(path, ".ply")) return loadPly(path, error, localOrigin);
  if (endsWith(path, ".gltf") || endsWith(path, ".glb")) return loadGltf(path, error, localOrigin);
  if (endsWith(path, ".ifc")) return loadIfc(path, error, localOrigin);
  error = path + ": unknown model format (.obj, .ply, .gltf, .glb, .ifc)";
  return std::nullopt;
}

}  // namespace ig::lod::hdlod
