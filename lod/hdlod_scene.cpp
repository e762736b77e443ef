#include "lod/hdlod_scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

#include <glm/geometric.hpp>

namespace ig::lod::hdlod {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

bool finite3(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

std::string num(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

std::vector<std::string> splitWords(const std::string& line) {
  std::vector<std::string> words;
  std::istringstream in(line);
  std::string w;
  while (in >> w) {
    if (w[0] == '#') break;
    words.push_back(w);
  }
  return words;
}

bool parseDouble(const std::string& s, double& out) {
  const char* begin = s.c_str();
  char* end = nullptr;
  out = std::strtod(begin, &end);
  return end != begin && *end == '\0' && std::isfinite(out);
}

std::string dirOf(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? std::string() : path.substr(0, slash + 1);
}

}  // namespace

const char* objectClassName(ObjectClass c) {
  switch (c) {
    case ObjectClass::Static: return "static";
    case ObjectClass::PseudoDynamic: return "pseudo-dynamic";
    case ObjectClass::Dynamic: return "dynamic";
  }
  return "?";
}

double clampTime(double t_s, double duration_s) {
  if (!(t_s > 0.0)) return 0.0;  // NaN and negative
  return t_s < duration_s ? t_s : duration_s;
}

bool isPresent(const Object& object, double t_s, double duration_s) {
  const double t = clampTime(t_s, duration_s);
  for (const Interval& iv : object.visible) {
    // Breakpoints at or after T are dropped: an interval reaching T includes T.
    const bool beforeEnd = t < iv.disappear_s || iv.disappear_s >= duration_s;
    const bool afterStart = t >= iv.appear_s || iv.appear_s <= 0.0;
    if (afterStart && beforeEnd && iv.appear_s < duration_s && iv.disappear_s > 0.0) return true;
  }
  return false;
}

glm::dmat4 keyframeMatrix(const Keyframe& k) {
  const double h = -k.heading_deg * kDeg;  // clockwise heading = negative rotation about z
  const double c = std::cos(h), s = std::sin(h);
  glm::dmat4 m(1.0);
  m[0][0] = c;
  m[0][1] = s;
  m[1][0] = -s;
  m[1][1] = c;
  m[3] = glm::dvec4(k.position_m, 1.0);
  return m;
}

glm::dmat4 objectMatrix(const Object& object, double t_s, double duration_s) {
  const auto& path = object.path;
  if (path.empty()) return glm::dmat4(1.0);
  const double t = clampTime(t_s, duration_s);
  if (t <= path.front().t_s || path.size() == 1) return keyframeMatrix(path.front());
  if (t >= path.back().t_s) return keyframeMatrix(path.back());
  const auto it = std::upper_bound(path.begin(), path.end(), t,
                                   [](double x, const Keyframe& k) { return x < k.t_s; });
  const Keyframe& b = *it;
  const Keyframe& a = *(it - 1);
  const double u = (t - a.t_s) / (b.t_s - a.t_s);
  Keyframe k;
  k.t_s = t;
  k.position_m = a.position_m + (b.position_m - a.position_m) * u;
  const double dh = std::remainder(b.heading_deg - a.heading_deg, 360.0);
  k.heading_deg = a.heading_deg + dh * u;
  return keyframeMatrix(k);
}

ObjectClass classify(const Object& object, double duration_s) {
  for (size_t i = 1; i < object.path.size(); ++i) {
    const Keyframe& a = object.path[0];
    const Keyframe& b = object.path[i];
    if (a.position_m != b.position_m || std::remainder(a.heading_deg - b.heading_deg, 360.0) != 0.0) {
      return ObjectClass::Dynamic;
    }
  }
  // Static: one interval covering [0, T].
  for (const Interval& iv : object.visible) {
    if (iv.appear_s <= 0.0 && iv.disappear_s >= duration_s) return ObjectClass::Static;
  }
  return ObjectClass::PseudoDynamic;
}

Aabb transformBox(const Aabb& box, const glm::dmat4& m) {
  const glm::dvec3 c = (box.min + box.max) * 0.5, e = (box.max - box.min) * 0.5;
  glm::dvec3 wc(m[3]), we(0.0);
  for (int col = 0; col < 3; ++col) {
    for (int row = 0; row < 3; ++row) {
      wc[row] += m[col][row] * c[col];
      we[row] += std::abs(m[col][row]) * e[col];
    }
  }
  return Aabb{wc - we, wc + we};
}

Aabb sweptBox(const Object& object, const Model& model) {
  double radius = 0.0;
  for (int i = 0; i < 8; ++i) {
    const glm::dvec3 corner{(i & 1) ? model.box.max.x : model.box.min.x, (i & 2) ? model.box.max.y : model.box.min.y,
                            (i & 4) ? model.box.max.z : model.box.min.z};
    radius = std::max(radius, glm::length(corner));
  }
  Aabb box{object.path.front().position_m, object.path.front().position_m};
  for (const Keyframe& k : object.path) {
    box.min = glm::min(box.min, k.position_m);
    box.max = glm::max(box.max, k.position_m);
  }
  box.min -= glm::dvec3(radius);
  box.max += glm::dvec3(radius);
  return box;
}

void computeModelBoxes(Scene& scene) {
  for (Model& m : scene.models) {
    if (m.positions.empty()) {
      m.box = Aabb{};
      continue;
    }
    glm::dvec3 lo(m.positions[0]), hi(m.positions[0]);
    for (const glm::vec3& p : m.positions) {
      lo = glm::min(lo, glm::dvec3(p));
      hi = glm::max(hi, glm::dvec3(p));
    }
    m.box = Aabb{lo, hi};
  }
}

std::string validateScene(const Scene& scene) {
  if (!(scene.duration_s > 0.0) || !std::isfinite(scene.duration_s)) {
    return "duration_s = " + num(scene.duration_s) + ": must be finite and > 0";
  }
  for (const Model& m : scene.models) {
    if (m.indices.size() % 3 != 0) return "model " + m.name + ": index count " + std::to_string(m.indices.size()) + " is not a multiple of 3";
    for (uint32_t i : m.indices) {
      if (i >= m.positions.size()) return "model " + m.name + ": index " + std::to_string(i) + " out of range";
    }
    for (const glm::vec3& p : m.positions) {
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return "model " + m.name + ": non-finite vertex";
    }
  }
  for (const Object& o : scene.objects) {
    if (o.model >= scene.models.size()) return "object " + o.name + ": model index " + std::to_string(o.model) + " out of range";
    if (o.path.empty()) return "object " + o.name + ": no keyframe";
    for (size_t i = 0; i < o.path.size(); ++i) {
      const Keyframe& k = o.path[i];
      if (!std::isfinite(k.t_s) || !finite3(k.position_m) || !std::isfinite(k.heading_deg)) {
        return "object " + o.name + ": non-finite keyframe at t = " + num(k.t_s);
      }
      if (i > 0 && !(k.t_s > o.path[i - 1].t_s)) return "object " + o.name + ": keyframe t = " + num(k.t_s) + " not after " + num(o.path[i - 1].t_s);
    }
    for (size_t i = 0; i < o.visible.size(); ++i) {
      const Interval& iv = o.visible[i];
      if (std::isnan(iv.appear_s) || std::isnan(iv.disappear_s) || !(iv.appear_s < iv.disappear_s)) {
        return "object " + o.name + ": interval [" + num(iv.appear_s) + ", " + num(iv.disappear_s) + ") is empty or NaN";
      }
      if (i > 0 && !(iv.appear_s > o.visible[i - 1].disappear_s)) {
        return "object " + o.name + ": interval appearing at " + num(iv.appear_s) + " overlaps or touches the one before (ends " +
               num(o.visible[i - 1].disappear_s) + ")";
      }
    }
  }
  return "";
}

Model makeBoxModel(const std::string& name, const glm::dvec3& size_m) {
  Model m;
  m.name = name;
  const glm::vec3 h(static_cast<float>(size_m.x * 0.5), static_cast<float>(size_m.y * 0.5), 0.0f);
  const float z = static_cast<float>(size_m.z);
  for (int i = 0; i < 8; ++i) {
    m.positions.emplace_back((i & 1) ? h.x : -h.x, (i & 2) ? h.y : -h.y, (i & 4) ? z : 0.0f);
  }
  // Outward-facing quads (counter-clockwise seen from outside), two triangles each.
  const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.indices.insert(m.indices.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
  }
  m.box = Aabb{glm::dvec3(-h.x, -h.y, 0.0), glm::dvec3(h.x, h.y, z)};
  return m;
}

std::optional<Model> loadObj(const std::string& path, std::string& error, glm::dvec3* localOrigin) {
  if (localOrigin) *localOrigin = glm::dvec3(0.0);
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open";
    return std::nullopt;
  }
  Model m;
  m.name = path;
  std::string line;
  int lineNo = 0;
  while (std::getline(in, line)) {
    ++lineNo;
    const auto w = splitWords(line);
    if (w.empty()) continue;
    const std::string where = path + ":" + std::to_string(lineNo) + ": ";
    if (w[0] == "v") {
      double x, y, z;
      if (w.size() < 4 || !parseDouble(w[1], x) || !parseDouble(w[2], y) || !parseDouble(w[3], z)) {
        error = where + "bad vertex: " + line;
        return std::nullopt;
      }
      if (localOrigin && m.positions.empty()) *localOrigin = glm::dvec3(x, y, z);
      if (localOrigin) x -= localOrigin->x, y -= localOrigin->y, z -= localOrigin->z;
      // Stored as float: 1e39 would become infinity.
      constexpr double kFloatMax = static_cast<double>(std::numeric_limits<float>::max());
      if (!(std::abs(x) <= kFloatMax) || !(std::abs(y) <= kFloatMax) || !(std::abs(z) <= kFloatMax)) {
        error = where + "vertex coordinate out of the float range: " + line;
        return std::nullopt;
      }
      m.positions.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    } else if (w[0] == "f") {
      if (w.size() < 4) {
        error = where + "face with fewer than 3 vertices: " + line;
        return std::nullopt;
      }
      std::vector<uint32_t> face;
      for (size_t i = 1; i < w.size(); ++i) {
        const std::string first = w[i].substr(0, w[i].find('/'));
        char* end = nullptr;
        const long v = std::strtol(first.c_str(), &end, 10);
        const long n = static_cast<long>(m.positions.size());
        const long idx = v > 0 ? v - 1 : n + v;
        if (end == first.c_str() || *end != '\0' || v == 0 || idx < 0 || idx >= n) {
          error = where + "bad vertex index: " + w[i];
          return std::nullopt;
        }
        face.push_back(static_cast<uint32_t>(idx));
      }
      for (size_t i = 2; i < face.size(); ++i) m.indices.insert(m.indices.end(), {face[0], face[i - 1], face[i]});
    }
  }
  Scene tmp;
  tmp.models.push_back(std::move(m));
  computeModelBoxes(tmp);
  return std::move(tmp.models[0]);
}

std::optional<Scene> parseSchedule(const std::string& text, const std::string& name, const std::string& baseDir,
                                   std::string& error) {
  Scene scene;
  bool haveHeader = false, haveDuration = false;
  std::unordered_map<std::string, uint32_t> modelIndex, objectIndex;
  std::vector<int> objectLine;        // where each object was declared
  std::vector<uint8_t> explicitVis;   // 0 none, 1 intervals, 2 never
  std::istringstream in(text);
  std::string line;
  int lineNo = 0;
  auto fail = [&](const std::string& what) {
    error = name + ":" + std::to_string(lineNo) + ": " + what;
    return std::nullopt;
  };
  while (std::getline(in, line)) {
    ++lineNo;
    const auto w = splitWords(line);
    if (w.empty()) continue;
    const std::string& cmd = w[0];
    if (!haveHeader) {
      if (cmd != "hdlod-schedule" || w.size() != 2 || w[1] != "1") return fail("expected header 'hdlod-schedule 1': " + line);
      haveHeader = true;
      continue;
    }
    auto number = [&](size_t i, double& out) { return parseDouble(w[i], out); };
    auto arity = [&](size_t n) { return w.size() == n; };
    if (cmd == "duration_s") {
      double T;
      if (!arity(2) || !number(1, T) || !(T > 0.0)) return fail("duration_s: must be one finite number > 0: " + line);
      if (!scene.objects.empty()) return fail("duration_s must come before the first object");
      scene.duration_s = T;
      haveDuration = true;
    } else if (cmd == "model") {
      if (w.size() < 3) return fail("model: expected 'model NAME box SX SY SZ' or 'model NAME obj PATH': " + line);
      if (modelIndex.count(w[1])) return fail("model: duplicate name: " + w[1]);
      Model m;
      if (w[2] == "box") {
        glm::dvec3 s;
        if (!arity(6) || !number(3, s.x) || !number(4, s.y) || !number(5, s.z) || s.x < 0 || s.y < 0 || s.z < 0) {
          return fail("model box: expected three finite sizes >= 0: " + line);
        }
        m = makeBoxModel(w[1], s);
      } else if (w[2] == "obj" || w[2] == "ply" || w[2] == "gltf" || w[2] == "ifc") {
        // model NAME KIND PATH [scale S]
        double scale = 1.0;
        if (w.size() == 6 && w[4] == "scale") {
          if (!number(5, scale) || !(scale > 0.0)) return fail("model " + w[1] + ": scale must be one finite number > 0: " + w[5]);
        } else if (!arity(4)) {
          return fail("model " + w[2] + ": expected 'model NAME " + w[2] + " PATH [scale S]': " + line);
        }
        const std::string p = w[3][0] == '/' ? w[3] : baseDir + w[3];
        std::string objError;
        auto loaded = w[2] == "obj"    ? loadObj(p, objError)
                      : w[2] == "ply"  ? loadPly(p, objError)
                      : w[2] == "gltf" ? loadGltf(p, objError)
                                       : loadIfc(p, objError);
        if (!loaded) return fail("model " + w[1] + ": " + objError);
        m = std::move(*loaded);
        m.name = w[1];
        if (scale != 1.0) {
          for (glm::vec3& v : m.positions) {
            v = glm::vec3(glm::dvec3(v) * scale);
            if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) return fail("model " + w[1] + ": scale too large: " + w[5]);
          }
          Scene tmp;
          tmp.models.push_back(std::move(m));
          computeModelBoxes(tmp);
          m = std::move(tmp.models[0]);
        }
      } else {
        return fail("model: unknown kind (box, obj, ply, gltf, ifc): " + w[2]);
      }
      modelIndex[w[1]] = static_cast<uint32_t>(scene.models.size());
      scene.models.push_back(std::move(m));
    } else if (cmd == "object") {
      if (!arity(3)) return fail("object: expected 'object NAME MODEL': " + line);
      if (objectIndex.count(w[1])) return fail("object: duplicate name: " + w[1]);
      const auto it = modelIndex.find(w[2]);
      if (it == modelIndex.end()) return fail("object " + w[1] + ": unknown model: " + w[2]);
      objectIndex[w[1]] = static_cast<uint32_t>(scene.objects.size());
      Object o;
      o.name = w[1];
      o.model = it->second;
      scene.objects.push_back(std::move(o));
      objectLine.push_back(lineNo);
      explicitVis.push_back(0);
    } else if (cmd == "at" || cmd == "visible") {
      if (w.size() < 2) return fail(cmd + ": missing object name");
      const auto it = objectIndex.find(w[1]);
      if (it == objectIndex.end()) return fail(cmd + ": unknown object: " + w[1]);
      Object& o = scene.objects[it->second];
      if (cmd == "at") {
        Keyframe k;
        if (!arity(7) || !number(2, k.t_s) || !number(3, k.position_m.x) || !number(4, k.position_m.y) ||
            !number(5, k.position_m.z) || !number(6, k.heading_deg)) {
          return fail("at: expected 'at OBJECT T_S X_M Y_M Z_M HEADING_DEG' with finite numbers: " + line);
        }
        if (!o.path.empty() && !(k.t_s > o.path.back().t_s)) {
          return fail("at " + o.name + ": keyframe time " + w[2] + " not after the previous one (" + num(o.path.back().t_s) + ")");
        }
        o.path.push_back(k);
      } else if (arity(3) && w[2] == "never") {
        if (explicitVis[it->second] == 1) return fail("visible " + o.name + ": 'never' after intervals");
        explicitVis[it->second] = 2;
      } else {
        Interval iv;
        // An end beyond the schedule may be infinite ("-inf" / "inf": present since always, for
        // ever), as validateScene allows and saveSchedule writes; NaN is never a time.
        auto end = [&](size_t i, double& out) {
          if (w[i] == "inf" || w[i] == "-inf") {
            out = (w[i][0] == '-' ? -1.0 : 1.0) * std::numeric_limits<double>::infinity();
            return true;
          }
          return number(i, out);
        };
        if (!arity(4) || !end(2, iv.appear_s) || !end(3, iv.disappear_s)) {
          return fail("visible: expected 'visible OBJECT APPEAR_S DISAPPEAR_S' or 'visible OBJECT never': " + line);
        }
        if (explicitVis[it->second] == 2) return fail("visible " + o.name + ": intervals after 'never'");
        if (!(iv.appear_s < iv.disappear_s)) return fail("visible " + o.name + ": appear " + w[2] + " not before disappear " + w[3]);
        if (!o.visible.empty() && !(iv.appear_s > o.visible.back().disappear_s)) {
          return fail("visible " + o.name + ": interval appearing at " + w[2] + " overlaps or touches the previous one (ends " +
                      num(o.visible.back().disappear_s) + ")");
        }
        o.visible.push_back(iv);
        explicitVis[it->second] = 1;
      }
    } else {
      return fail("unknown line kind: " + cmd);
    }
  }
  if (!haveHeader) {
    error = name + ": empty file (expected 'hdlod-schedule 1')";
    return std::nullopt;
  }
  if (!haveDuration) {
    error = name + ": missing 'duration_s'";
    return std::nullopt;
  }
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    Object& o = scene.objects[i];
    if (o.path.empty()) {
      error = name + ":" + std::to_string(objectLine[i]) + ": object " + o.name + ": no 'at' keyframe";
      return std::nullopt;
    }
    if (explicitVis[i] == 0) o.visible.push_back({0.0, scene.duration_s});
  }
  const std::string problem = validateScene(scene);
  if (!problem.empty()) {
    error = name + ": " + problem;
    return std::nullopt;
  }
  return scene;
}

std::optional<Scene> loadSchedule(const std::string& path, std::string& error) {
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open";
    return std::nullopt;
  }
  std::ostringstream text;
  text << in.rdbuf();
  return parseSchedule(text.str(), path, dirOf(path), error);
}

namespace {

bool plainName(const std::string& n) {
  if (n.empty()) return false;
  for (char c : n) {
    if (c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '#' || c == '/') return false;
  }
  return true;
}

}  // namespace

bool saveSchedule(const Scene& scene, const std::string& path, const std::string& modelDir, std::string& error) {
  const std::string problem = validateScene(scene);
  if (!problem.empty()) {
    error = path + ": cannot write an invalid scene: " + problem;
    return false;
  }
  const std::string base = dirOf(path);
  const std::string dirPrefix = modelDir.empty() ? std::string() : modelDir + "/";
  // loadSchedule() refuses duplicate names: refuse them here, before writing anything.
  std::unordered_set<std::string> modelNames, objectNames;
  for (const Model& m : scene.models) {
    if (!modelNames.insert(m.name).second) {
      error = path + ": model name '" + m.name + "': used twice";
      return false;
    }
  }
  for (const Object& o : scene.objects) {
    if (!objectNames.insert(o.name).second) {
      error = path + ": object name '" + o.name + "': used twice";
      return false;
    }
  }
  char buf[256];
  // Numbers only (at most 25 characters each): a name goes into the line as a string, so that a
  // long one is never cut with the rest of its line.
  auto g17 = [](double v) {
    char b[40];
    std::snprintf(b, sizeof b, "%.17g", v);
    return std::string(b);
  };
  for (const Model& m : scene.models) {
    if (!plainName(m.name)) {
      error = path + ": model name '" + m.name + "': must be non-empty without blanks, '#' or '/'";
      return false;
    }
    const std::string file = base + dirPrefix + m.name + ".obj";
    std::ofstream obj(file);
    if (!obj) {
      error = file + ": cannot write";
      return false;
    }
    obj << "# " << m.name << ": " << m.positions.size() << " vertices, " << m.triangleCount() << " triangles (igtool site)\n";
    for (const glm::vec3& v : m.positions) {
      std::snprintf(buf, sizeof buf, "v %.9g %.9g %.9g\n", static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z));
      obj << buf;
    }
    for (size_t i = 0; i + 2 < m.indices.size(); i += 3) obj << "f " << m.indices[i] + 1 << ' ' << m.indices[i + 1] + 1 << ' ' << m.indices[i + 2] + 1 << '\n';
    if (!obj) {
      error = file + ": write failed";
      return false;
    }
  }
  std::ofstream out(path);
  if (!out) {
    error = path + ": cannot write";
    return false;
  }
  out << "hdlod-schedule 1\n";
  std::snprintf(buf, sizeof buf, "duration_s %.17g\n", scene.duration_s);
  out << buf;
  for (const Model& m : scene.models) out << "model " << m.name << " obj " << dirPrefix << m.name << ".obj\n";
  for (const Object& o : scene.objects) {
    if (!plainName(o.name)) {
      error = path + ": object name '" + o.name + "': must be non-empty without blanks, '#' or '/'";
      return false;
    }
    out << "object " << o.name << ' ' << scene.models[o.model].name << '\n';
    for (const Keyframe& k : o.path) {
      out << "at " << o.name << ' ' << g17(k.t_s) << ' ' << g17(k.position_m.x) << ' ' << g17(k.position_m.y) << ' '
          << g17(k.position_m.z) << ' ' << g17(k.heading_deg) << '\n';
    }
    if (o.visible.empty()) out << "visible " << o.name << " never\n";
    for (const Interval& iv : o.visible) out << "visible " << o.name << ' ' << g17(iv.appear_s) << ' ' << g17(iv.disappear_s) << '\n';
  }
  out.flush();
  if (!out) {
    error = path + ": write failed";
    return false;
  }
  return true;
}

}  // namespace ig::lod::hdlod
