// igtool forest-textures: tree models and the offline textures T and S of paper 004
// (shared/SEEDS.md section 004). See forest_tool.h.
#include "ig/forest_tool.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <tuple>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "render/context.h"
#include "render/image.h"

namespace ig {
namespace {

bool isBark(std::string name) {
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return name.find("trunk") != std::string::npos || name.find("bark") != std::string::npos;
}

// One OBJ face corner "v", "v/vt", "v//vn", "v/vt/vn" -> (v, vn), 1-based, negative = relative.
// The whole token: anything else ("1abc", "1/2x", "1//", "1/2/3/4") is refused (strtol stopped at
// the first non-digit and the rest was ignored: "f 1abc 2 3" read as "f 1 2 3").
bool parseCorner(const std::string& s, long nv, long nn, long& v, long& n) {
  const auto number = [](const char*& p, long& value) {
    char* end = nullptr;
    errno = 0;
    value = std::strtol(p, &end, 10);
    if (end == p || errno == ERANGE) return false;
    p = end;
    return true;
  };
  const char* p = s.c_str();
  n = 0;
  if (!number(p, v)) return false;
  if (*p == '/') {
    ++p;
    long vt = 0;
    if (*p != '/' && !number(p, vt)) return false;
    if (*p == '/') {
      ++p;
      if (!number(p, n) || n == 0) return false;
    }
  }
  if (*p != '\0') return false;
  if (v < 0) v = nv + v + 1;
  if (n < 0) n = nn + n + 1;
  return v >= 1 && v <= nv && n >= 0 && n <= nn;
}

}  // namespace

bool loadTreeObj(const std::string& file, bool sourceUnits, const TreeObjOptions& o, lod::TreeMesh& out,
                 std::string& error) {
  std::ifstream in(file);
  if (!in) {
    error = "tree model '" + file + "': cannot open";
    return false;
  }
  std::vector<std::array<float, 3>> pos, nrm;
  std::vector<std::array<uint8_t, 3>> vcol;
  bool hasVertexColours = false;
  struct Key {
    long v, n;
    int mat;
    bool operator<(const Key& k) const { return std::tie(v, n, mat) < std::tie(k.v, k.n, k.mat); }
  };
  std::map<Key, uint32_t> corners;
  std::vector<Key> keys;
  std::vector<uint32_t> indices;
  int material = 0;  // 0 foliage, 1 bark
  std::string line;
  size_t lineNo = 0;
  while (std::getline(in, line)) {
    ++lineNo;
    std::istringstream ls(line);
    std::string tag;
    ls >> tag;
    if (tag == "v") {
      std::array<float, 3> p{};
      ls >> p[0] >> p[1] >> p[2];
      if (!ls) {
        error = "tree model '" + file + "' line " + std::to_string(lineNo) + ": bad vertex '" + line + "'";
        return false;
      }
      float r = 0, g = 0, b = 0;
      if (ls >> r >> g >> b) {
        hasVertexColours = true;
        vcol.push_back({static_cast<uint8_t>(std::clamp(std::lround(r * 255.0f), 0L, 255L)),
                        static_cast<uint8_t>(std::clamp(std::lround(g * 255.0f), 0L, 255L)),
                        static_cast<uint8_t>(std::clamp(std::lround(b * 255.0f), 0L, 255L))});
      } else {
        vcol.push_back({0, 0, 0});
      }
      pos.push_back(p);
    } else if (tag == "vn") {
      std::array<float, 3> n{};
      ls >> n[0] >> n[1] >> n[2];
      nrm.push_back(n);
    } else if (tag == "usemtl") {
      std::string name;
      ls >> name;
      material = isBark(name) ? 1 : 0;
    } else if (tag == "f") {
      std::vector<uint32_t> face;
      std::string c;
      while (ls >> c) {
        long v = 0, n = 0;
        if (!parseCorner(c, static_cast<long>(pos.size()), static_cast<long>(nrm.size()), v, n)) {
          error = "tree model '" + file + "' line " + std::to_string(lineNo) + ": bad face corner '" + c + "'";
          return false;
        }
        const Key k{v, n, material};
        auto [it, added] = corners.emplace(k, static_cast<uint32_t>(keys.size()));
        if (added) keys.push_back(k);
        face.push_back(it->second);
      }
      for (size_t i = 2; i < face.size(); ++i) indices.insert(indices.end(), {face[0], face[i - 1], face[i]});
    }
  }
  if (keys.empty() || indices.empty()) {
    error = "tree model '" + file + "': no faces";
    return false;
  }
  // Axes and scale.
  const auto toModel = [&](const std::array<float, 3>& p) {
    return sourceUnits ? glm::dvec3(p[0], -p[2], p[1]) * 0.01 : glm::dvec3(p[0], p[1], p[2]);
  };
  glm::dvec3 lo(1e30), hi(-1e30);
  for (const Key& k : keys) {
    const glm::dvec3 p = toModel(pos[static_cast<size_t>(k.v - 1)]);
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  glm::dvec3 centre(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), lo.z), scale(1.0);
  if (sourceUnits) {
    const double h = std::max(hi.z - lo.z, 1e-6), r = std::max(0.5 * std::max(hi.x - lo.x, hi.y - lo.y), 1e-6);
    scale.z = o.height_m / h;
    scale.x = scale.y = o.radius_m > 0.0 ? o.radius_m / r : scale.z;
  } else {
    centre = glm::dvec3(0.0);
  }
  out = {};
  out.name = std::filesystem::path(file).stem().string();
  out.vertices.reserve(keys.size());
  // Normals transform with the inverse of the (diagonal) scale.
  for (const Key& k : keys) {
    lod::TreeVertex tv{};
    const glm::dvec3 p = (toModel(pos[static_cast<size_t>(k.v - 1)]) - centre) * scale;
    glm::dvec3 n(0.0, 0.0, 1.0);
    if (k.n > 0) {
      const auto& a = nrm[static_cast<size_t>(k.n - 1)];
      n = sourceUnits ? glm::dvec3(a[0], -a[2], a[1]) / scale : glm::dvec3(a[0], a[1], a[2]);
      const double l = glm::length(n);
      n = l > 0 ? n / l : glm::dvec3(0.0, 0.0, 1.0);
    }
    for (int i = 0; i < 3; ++i) {
      tv.position[i] = static_cast<float>(p[i]);
      tv.normal[i] = static_cast<float>(n[i]);
    }
    const uint8_t* c = hasVertexColours ? vcol[static_cast<size_t>(k.v - 1)].data() : (k.mat ? o.bark : o.foliage);
    tv.rgba[0] = c[0], tv.rgba[1] = c[1], tv.rgba[2] = c[2], tv.rgba[3] = 255;
    out.vertices.push_back(tv);
  }
  out.indices = std::move(indices);
  // Files without normals (Scopia's pine has none): smooth area-weighted vertex normals.
  if (nrm.empty()) {
    std::vector<glm::dvec3> acc(out.vertices.size(), glm::dvec3(0.0));
    for (size_t i = 0; i + 2 < out.indices.size(); i += 3) {
      const auto p = [&](size_t k) {
        const float* q = out.vertices[out.indices[i + k]].position;
        return glm::dvec3(q[0], q[1], q[2]);
      };
      const glm::dvec3 fn = glm::cross(p(1) - p(0), p(2) - p(0));
      for (size_t k = 0; k < 3; ++k) acc[out.indices[i + k]] += fn;
    }
    for (size_t i = 0; i < acc.size(); ++i) {
      const double l = glm::length(acc[i]);
      const glm::dvec3 n = l > 0 ? acc[i] / l : glm::dvec3(0.0, 0.0, 1.0);
      for (int k = 0; k < 3; ++k) out.vertices[i].normal[k] = static_cast<float>(n[k]);
    }
  }
  lod::measureTree(out);
  return lod::validateTreeMesh(out, error);
}

bool writeTreeObj(const std::string& file, const lod::TreeMesh& m, std::string& error) {
  std::ofstream f(file);
  if (!f) {
    error = "tree model '" + file + "': cannot write";
    return false;
  }
  f << "# igtool forest-textures: " << m.name << ", z up, metres, vertex colours\n";
  char buf[160];
  for (const lod::TreeVertex& v : m.vertices) {
    std::snprintf(buf, sizeof buf, "v %.4f %.4f %.4f %.4f %.4f %.4f\n", static_cast<double>(v.position[0]),
                  static_cast<double>(v.position[1]), static_cast<double>(v.position[2]), v.rgba[0] / 255.0,
                  v.rgba[1] / 255.0, v.rgba[2] / 255.0);
    f << buf;
  }
  for (const lod::TreeVertex& v : m.vertices) {
    std::snprintf(buf, sizeof buf, "vn %.4f %.4f %.4f\n", static_cast<double>(v.normal[0]), static_cast<double>(v.normal[1]),
                  static_cast<double>(v.normal[2]));
    f << buf;
  }
  for (size_t i = 0; i + 2 < m.indices.size(); i += 3) {
    const uint32_t a = m.indices[i] + 1, b = m.indices[i + 1] + 1, c = m.indices[i + 2] + 1;
    f << "f " << a << "//" << a << ' ' << b << "//" << b << ' ' << c << "//" << c << '\n';
  }
  if (!f) {
    error = "tree model '" + file + "': write failed";
    return false;
  }
  return true;
}

lod::TreeMesh simplifyTree(const lod::TreeMesh& m, size_t targetTriangles) {
  lod::TreeMesh out = m;
  if (targetTriangles == 0 || m.indices.size() / 3 <= targetTriangles) return out;
  const size_t target = targetTriangles * 3;
  std::vector<uint32_t> idx(m.indices.size());
  const auto* positions = &m.vertices[0].position[0];
  size_t n = meshopt_simplify(idx.data(), m.indices.data(), m.indices.size(), positions, m.vertices.size(),
                              sizeof(lod::TreeVertex), target, 0.05f, 0, nullptr);
  if (n > target * 3 / 2) {
    n = meshopt_simplifySloppy(idx.data(), m.indices.data(), m.indices.size(), positions, m.vertices.size(),
                               sizeof(lod::TreeVertex), target, 1.0f, nullptr);
  }
  idx.resize(n);
  meshopt_optimizeVertexCache(idx.data(), idx.data(), idx.size(), m.vertices.size());
  std::vector<lod::TreeVertex> v(m.vertices.size());
  v.resize(meshopt_optimizeVertexFetch(v.data(), idx.data(), idx.size(), m.vertices.data(), m.vertices.size(),
                                       sizeof(lod::TreeVertex)));
  out.vertices = std::move(v);
  out.indices = std::move(idx);
  lod::measureTree(out);
  // Simplification eats tips (the crown top, branch ends): scale back to the original's height
  // and crown radius, so the 3D trees match the layers baked from the detailed model.
  const float sz = out.height_m > 0.0f ? m.height_m / out.height_m : 1.0f;
  const float sxy = out.radius_m > 0.0f ? m.radius_m / out.radius_m : 1.0f;
  for (lod::TreeVertex& tv : out.vertices) {
    tv.position[0] *= sxy, tv.position[1] *= sxy, tv.position[2] *= sz;
  }
  lod::measureTree(out);
  return out;
}

bool writeForestAssets(const std::string& dir, const std::vector<lod::TreeMesh>& models,
                       const render::ForestTextures& t, std::string& error) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    error = "forest assets '" + dir + "': cannot create: " + ec.message();
    return false;
  }
  std::string names;
  for (const lod::TreeMesh& m : models) {
    if (!writeTreeObj(dir + "/" + m.name + ".obj", m, error)) return false;
    names += " " + m.name;
  }
  if (!render::writePng(dir + "/layers.png", t.layers, error) || !render::writePng(dir + "/fins.png", t.fins, error))
    return false;
  std::ofstream f(dir + "/forest_textures.txt");
  f << "layers " << t.layerCount << "\nfin_slices " << t.finSlices << "\ntile_m " << t.tile_m << "\nheight_m "
    << t.height_m << "\n";
  if (t.spacing_m > 0.0) f << "spacing_m " << t.spacing_m << "\n";
  f << "models" << names << "\n";
  if (!f) {
    error = "forest assets '" + dir + "/forest_textures.txt': write failed";
    return false;
  }
  return true;
}

bool readForestAssets(const std::string& dir, std::vector<lod::TreeMesh>& models, render::ForestTextures& t,
                      std::string& error) {
  const std::string meta = dir + "/forest_textures.txt";
  std::ifstream f(meta);
  if (!f) {
    error = "forest assets '" + meta + "': no such file (run igtool forest-textures)";
    return false;
  }
  t = {};
  std::vector<std::string> names;
  std::string line;
  int lineNo = 0;
  while (std::getline(f, line)) {
    ++lineNo;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    // One whole number after each key, nothing after it ('tile_m 24abc', 'layers 4 5': refused).
    auto one = [&](auto& out) {
      std::string value, extra;
      ls >> value;
      const bool trailing = static_cast<bool>(ls >> extra);
      std::istringstream vs(value);
      vs >> out;
      if (value.empty() || trailing || !vs || vs.peek() != std::char_traits<char>::eof()) {
        error = "forest assets '" + meta + "': line " + std::to_string(lineNo) + ": " + key + " = '" + value +
                (trailing ? " " + extra : std::string()) + "': not a single number";
        return false;
      }
      return true;
    };
    if (key == "layers") {
      if (!one(t.layerCount)) return false;
    } else if (key == "fin_slices") {
      if (!one(t.finSlices)) return false;
    } else if (key == "tile_m") {
      if (!one(t.tile_m)) return false;
    } else if (key == "height_m") {
      if (!one(t.height_m)) return false;
    } else if (key == "spacing_m") {
      std::string value, extra;
      ls >> value;
      char* end = nullptr;
      t.spacing_m = std::strtod(value.c_str(), &end);
      if (value.empty() || *end != '\0' || !std::isfinite(t.spacing_m) || t.spacing_m < 0.0 || ls >> extra) {
        error = "forest assets '" + meta + "': line " + std::to_string(lineNo) + ": spacing_m = '" + value +
                (extra.empty() ? std::string() : " " + extra) + "': must be a finite number >= 0";
        return false;
      }
    }    else if (key == "models")
      for (std::string n; ls >> n;) names.push_back(n);
    else if (!key.empty()) {
      error = "forest assets '" + meta + "': unknown key '" + key + "'";
      return false;
    }
  }
  if (names.empty()) {
    error = "forest assets '" + meta + "': no models listed";
    return false;
  }
  if (!render::readPng(dir + "/layers.png", t.layers, error) || !render::readPng(dir + "/fins.png", t.fins, error))
    return false;
  if (!render::validateForestTextures(t, error)) {
    error = "forest assets '" + dir + "': " + error;
    return false;
  }
  models.clear();
  for (const std::string& n : names) {
    lod::TreeMesh m;
    if (!loadTreeObj(dir + "/" + n + ".obj", false, {}, m, error)) return false;
    models.push_back(std::move(m));
  }
  return true;
}

bool loadScopiaTrees(const std::string& src, size_t triangles, std::vector<lod::TreeMesh>& out, std::string& error) {
  out.clear();
  TreeObjOptions pine;
  pine.height_m = 18.0;
  pine.radius_m = 3.5;
  TreeObjOptions cypress;
  cypress.height_m = 14.0;
  cypress.radius_m = 2.2;
  cypress.foliage[0] = 40, cypress.foliage[1] = 76, cypress.foliage[2] = 42;
  const std::pair<const char*, const TreeObjOptions*> files[] = {{"pine.obj", &pine}, {"cypress.obj", &cypress}};
  for (const auto& [name, opt] : files) {
    lod::TreeMesh m;
    if (!loadTreeObj(src + "/" + name, true, *opt, m, error)) return false;
    out.push_back(simplifyTree(m, triangles));
  }
  return true;
}

std::vector<lod::TreeMesh> proceduralTrees() {
  return {lod::makeProceduralTree(lod::ProceduralTree::Pine, 18.0, 8),
          lod::makeProceduralTree(lod::ProceduralTree::Cypress, 14.0, 8)};
}

double forestTextureTile_m(const ForestTexturesOptions& o) {
  return o.tile_m > 0.0 ? o.tile_m : std::max(24.0, 4.0 * o.spacing_m);
}

render::ForestTextureDesc forestTextureDesc(double spacing_m, int layers, double tile_m) {
  render::ForestTextureDesc td;
  td.layers = layers;
  td.tile_m = tile_m > 0.0 ? tile_m : std::max(24.0, 4.0 * spacing_m);
  const double trees = std::min(td.tile_m * td.tile_m / (spacing_m * spacing_m), 1e9);
  td.treesPerTile = std::max(1, static_cast<int>(std::lround(trees)));
  return td;
}

std::string forestTexturesSpacingMismatch(const render::ForestTextures& t, double spacing_m, const std::string& source) {
  if (!(t.spacing_m > 0.0) || !(spacing_m > 0.0)) return {};
  const double ratio = std::max(t.spacing_m, spacing_m) / std::min(t.spacing_m, spacing_m);
  if (ratio <= 1.1) return {};
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "%s: baked for a tree spacing of %g m, but forest.spacing_m = %g m: the shell layers would stand for "
                "a forest %.2f times as dense as the trees planted (rebake with igtool forest-textures --spacing %g, "
                "or set forest.spacing_m = %g)",
                source.c_str(), t.spacing_m, spacing_m, (spacing_m * spacing_m) / (t.spacing_m * t.spacing_m),
                spacing_m, t.spacing_m);
  return buf;
}

int runForestTextures(const ForestTexturesOptions& o) {
  const double tile_m = forestTextureTile_m(o);
  if (o.layers < 1 || o.layers > 32 || o.size_px < 8 || o.size_px > 2048 || !(tile_m > 0.0) || !std::isfinite(tile_m) ||
      !(o.spacing_m > 0.0) || !std::isfinite(o.spacing_m) ||
      o.triangles < 8 || o.bakeTriangles < o.triangles) {
    std::fprintf(stderr,
                 "igtool forest-textures: layers = %d, size = %d, tile = %g m, spacing = %g m, triangles = %d, bake "
                 "triangles = %d: need layers 1..32, size 8..2048, tile and spacing > 0, triangles >= 8 and <= bake "
                 "triangles\n",
                 o.layers, o.size_px, tile_m, o.spacing_m, o.triangles, o.bakeTriangles);
    return 2;
  }
  // The trees planted in one tile: each is drawn into every layer, and more trees than a layer
  // has pixels add nothing (the count also has to fit an int).
  constexpr double kMaxTreesPerTile = 65536.0;
  const double trees = tile_m * tile_m / (o.spacing_m * o.spacing_m);
  if (!(trees <= kMaxTreesPerTile)) {
    std::fprintf(stderr,
                 "igtool forest-textures: --tile %g m with --spacing %g m plants %.3g trees in a tile: at most %.0f "
                 "(raise --spacing or lower --tile)\n",
                 tile_m, o.spacing_m, trees, kMaxTreesPerTile);
    return 2;
  }
  // A whole number of trees: the layers stand for treesPerTile / tile^2 trees per square metre,
  // which must be the forest's 1 / spacing^2 (a tile of less than one slot still got one tree).
  const int treesPerTile = std::max(1, static_cast<int>(std::lround(trees)));
  const double density = static_cast<double>(treesPerTile) / trees;
  if (std::abs(density - 1.0) > 0.1) {
    std::fprintf(stderr,
                 "igtool forest-textures: --tile %g m with --spacing %g m holds %.3g trees, planted as %d: the layers "
                 "would stand for a forest %.2f times as dense as the one planted (use --tile %g or more, or leave "
                 "--tile out)\n",
                 tile_m, o.spacing_m, trees, treesPerTile, density, 4.0 * o.spacing_m);
    return 2;
  }
  std::string error;
  std::vector<lod::TreeMesh> bake, nearLod;
  if (o.procedural) {
    bake = nearLod = proceduralTrees();
  } else {
    std::vector<lod::TreeMesh> full;
    if (!loadScopiaTrees(o.source, 0, full, error)) {
      std::fprintf(stderr, "igtool forest-textures: %s (run scripts/fetch-forest, or pass --procedural)\n", error.c_str());
      return 1;
    }
    for (const lod::TreeMesh& m : full) {
      bake.push_back(simplifyTree(m, static_cast<size_t>(o.bakeTriangles)));
      nearLod.push_back(simplifyTree(m, static_cast<size_t>(o.triangles)));
    }
  }
  auto ctx = render::createContext(render::ContextKind::Headless, 64, 64, error);
  if (!ctx) {
    std::fprintf(stderr, "igtool forest-textures: %s\n", error.c_str());
    return 1;
  }
  render::ForestTextureDesc td = forestTextureDesc(o.spacing_m, o.layers, tile_m);
  td.size_px = o.size_px;
  render::ForestTextures tex;
  if (!render::renderForestTextures(bake, td, tex, error)) {
    std::fprintf(stderr, "igtool forest-textures: %s\n", error.c_str());
    return 1;
  }
  tex.spacing_m = o.spacing_m;
  if (!writeForestAssets(o.out, nearLod, tex, error)) {
    std::fprintf(stderr, "igtool forest-textures: %s\n", error.c_str());
    return 1;
  }
  for (size_t i = 0; i < nearLod.size(); ++i)
    std::printf("%s: %zu triangles (textures from %zu), %.1f m high, crown radius %.1f m\n", nearLod[i].name.c_str(),
                nearLod[i].indices.size() / 3, bake[i].indices.size() / 3, static_cast<double>(nearLod[i].height_m),
                static_cast<double>(nearLod[i].radius_m));
  std::printf("wrote %s/{layers.png (%d layers), fins.png (%d slices), forest_textures.txt, *.obj}\n", o.out.c_str(),
              tex.layerCount, tex.finSlices);
  return 0;
}

}  // namespace ig
