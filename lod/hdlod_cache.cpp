// HDLOD cache file: see hdlod_cache.h.
#include "lod/hdlod_cache.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string_view>
#include <type_traits>
#include <vector>

namespace ig::lod::hdlod {
namespace {

constexpr char kMagic[8] = {'I', 'G', 'H', 'D', 'L', 'O', 'D', '\0'};
constexpr size_t kHeaderBytes = 64;
// Bump when the builder changes what it makes from the same scene and config (the key then
// changes, and old caches read as stale).
constexpr uint64_t kBuildRevision = 9;  // 9: presence exactly on its side of 1/2 (8: model versions measured on their drawn triangles, back samples spread over drawn triangles)

struct Header {
  char magic[8];
  uint32_t version;
  uint32_t reserved;
  uint64_t key;
  uint64_t payloadBytes;
  uint64_t checksum;
  uint8_t pad[kHeaderBytes - 40];
};
static_assert(sizeof(Header) == kHeaderBytes);

// 64-bit FNV-1a over 8-byte little-endian words (the tail zero-padded).
uint64_t checksumOf(const uint8_t* data, size_t n) {
  uint64_t h = 14695981039346656037ull;
  size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    uint64_t w;
    std::memcpy(&w, data + i, 8);
    h = (h ^ w) * 1099511628211ull;
  }
  if (i < n) {
    uint64_t w = 0;
    std::memcpy(&w, data + i, n - i);
    h = (h ^ w) * 1099511628211ull;
  }
  return h;
}

class Hasher {
 public:
  template <typename T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes(&v, sizeof v);
  }
  template <typename T, typename A>
  void array(const std::vector<T, A>& v) {
    put(static_cast<uint64_t>(v.size()));
    if (!v.empty()) bytes(v.data(), v.size() * sizeof(T));
  }
  void text(const std::string& s) {
    put(static_cast<uint64_t>(s.size()));
    bytes(s.data(), s.size());
  }
  uint64_t value() const { return h_; }

 private:
  void bytes(const void* p, size_t n) {
    const uint64_t c = checksumOf(static_cast<const uint8_t*>(p), n);
    h_ = (h_ ^ c) * 1099511628211ull;
    h_ = (h_ ^ n) * 1099511628211ull;
  }
  uint64_t h_ = 14695981039346656037ull;
};

class Writer {
 public:
  template <typename T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const uint8_t*>(&v);
    out.insert(out.end(), p, p + sizeof v);
  }
  template <typename T, typename A>
  void array(const std::vector<T, A>& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    put(static_cast<uint64_t>(v.size()));
    const auto* p = reinterpret_cast<const uint8_t*>(v.data());
    out.insert(out.end(), p, p + v.size() * sizeof(T));
  }
  std::vector<uint8_t> out;
};

class Reader {
 public:
  Reader(const uint8_t* p, size_t n) : p_(p), n_(n) {}
  template <typename T>
  T get() {
    T v{};
    if (ok && at_ + sizeof v <= n_) {
      std::memcpy(&v, p_ + at_, sizeof v);
      at_ += sizeof v;
    } else {
      ok = false;
    }
    return v;
  }
  template <typename T, typename A>
  void array(std::vector<T, A>& v) {
    const uint64_t count = get<uint64_t>();
    if (!ok || count > (n_ - at_) / sizeof(T)) {
      ok = false;
      v.clear();
      return;
    }
    v.resize(count);
    if (count) std::memcpy(v.data(), p_ + at_, count * sizeof(T));
    at_ += count * sizeof(T);
  }
  bool atEnd() const { return at_ == n_; }
  bool ok = true;

 private:
  const uint8_t* p_;
  size_t n_;
  size_t at_ = 0;
};

void writeCluster(Writer& w, const Cluster& c) {
  w.put(c.box.min);
  w.put(c.box.max);
  w.put(c.size_m);
  w.put(c.eps_m);
  w.put(c.gamma);
  for (uint32_t v : {c.firstChild, c.childCount, c.stepBegin, c.stepCount, c.object, c.mesh, c.triangles}) w.put(v);
  w.put(c.level);
  w.put(static_cast<uint8_t>(c.kind));
  w.put(static_cast<uint8_t>(0));
}

Cluster readCluster(Reader& r) {
  Cluster c;
  c.box.min = r.get<glm::dvec3>();
  c.box.max = r.get<glm::dvec3>();
  c.size_m = r.get<double>();
  c.eps_m = r.get<double>();
  c.gamma = r.get<double>();
  for (uint32_t* v : {&c.firstChild, &c.childCount, &c.stepBegin, &c.stepCount, &c.object, &c.mesh, &c.triangles}) *v = r.get<uint32_t>();
  c.level = r.get<uint16_t>();
  const uint8_t kind = r.get<uint8_t>();
  (void)r.get<uint8_t>();
  if (kind > static_cast<uint8_t>(ClusterKind::Group)) r.ok = false;
  c.kind = static_cast<ClusterKind>(kind);
  return c;
}

std::vector<uint8_t> serialize(const HdlodTree& t) {
  Writer w;
  w.put(t.duration_s);
  w.put(t.root);
  w.put(static_cast<uint64_t>(t.clusters.size()));
  for (const Cluster& c : t.clusters) writeCluster(w, c);
  w.array(t.children);
  w.array(t.stepTimes);
  w.array(t.stepValues);
  w.put(static_cast<uint64_t>(t.meshes.size()));
  for (const ClusterMesh& m : t.meshes) {
    w.put(m.origin_m);
    w.array(m.positions);
    w.array(m.indices);
    w.array(m.materials);
  }
  w.array(t.leafMatrix);
  w.array(t.objectCluster);
  w.array(t.modelLodBegin);
  w.put(static_cast<uint64_t>(t.modelLods.size()));
  for (const ModelLod& l : t.modelLods) {
    w.put(l.mesh);
    w.put(l.triangles);
    w.put(l.eps_m);
  }
  const BuildStats& s = t.stats;
  for (uint32_t v : {s.staticObjects, s.pseudoDynamicObjects, s.dynamicObjects, s.emptyObjects, s.mergedClusters, s.levels, s.modelLods,
                     s.sloppyClusters}) {
    w.put(v);
  }
  for (uint64_t v : {s.leafTriangles, s.mergedTriangles, s.hausdorffSamples}) w.put(v);
  for (double v : {s.simplifyErrorSum_m, s.simplifyErrorMax_m, s.simplifyRelativeSum, s.simplifyRelativeMax}) w.put(v);
  return std::move(w.out);
}

// Parses and checks the references (indices in range), so a loaded tree is safe to traverse.
bool deserialize(const uint8_t* p, size_t n, HdlodTree& t, std::string& why) {
  Reader r(p, n);
  t.duration_s = r.get<double>();
  t.root = r.get<uint32_t>();
  const uint64_t clusters = r.get<uint64_t>();
  if (!r.ok || clusters > n / 64) {
    why = "truncated";
    return false;
  }
  t.clusters.resize(clusters);
  for (Cluster& c : t.clusters) c = readCluster(r);
  r.array(t.children);
  r.array(t.stepTimes);
  r.array(t.stepValues);
  const uint64_t meshes = r.get<uint64_t>();
  if (!r.ok || meshes > n / 8) {
    why = "truncated";
    return false;
  }
  t.meshes.resize(meshes);
  for (ClusterMesh& m : t.meshes) {
    m.origin_m = r.get<glm::dvec3>();
    r.array(m.positions);
    r.array(m.indices);
    r.array(m.materials);
  }
  r.array(t.leafMatrix);
  r.array(t.objectCluster);
  r.array(t.modelLodBegin);
  const uint64_t lods = r.get<uint64_t>();
  if (!r.ok || lods > n / 16) {
    why = "truncated";
    return false;
  }
  t.modelLods.resize(lods);
  for (ModelLod& l : t.modelLods) {
    l.mesh = r.get<uint32_t>();
    l.triangles = r.get<uint32_t>();
    l.eps_m = r.get<double>();
  }
  BuildStats& s = t.stats;
  for (uint32_t* v : {&s.staticObjects, &s.pseudoDynamicObjects, &s.dynamicObjects, &s.emptyObjects, &s.mergedClusters, &s.levels,
                      &s.modelLods, &s.sloppyClusters}) {
    *v = r.get<uint32_t>();
  }
  for (uint64_t* v : {&s.leafTriangles, &s.mergedTriangles, &s.hausdorffSamples}) *v = r.get<uint64_t>();
  for (double* v : {&s.simplifyErrorSum_m, &s.simplifyErrorMax_m, &s.simplifyRelativeSum, &s.simplifyRelativeMax}) *v = r.get<double>();
  if (!r.ok || !r.atEnd()) {
    why = r.ok ? "trailing bytes" : "truncated";
    return false;
  }
  // References.
  const size_t nc = t.clusters.size();
  bool bad = (nc > 0 && t.root >= nc) || t.stepTimes.size() != t.stepValues.size() || t.leafMatrix.size() != nc ||
             (!t.modelLodBegin.empty() && t.modelLodBegin.back() != t.modelLods.size());
  for (size_t i = 0; !bad && i < nc; ++i) {
    const Cluster& c = t.clusters[i];
    bad = uint64_t{c.firstChild} + c.childCount > t.children.size() || uint64_t{c.stepBegin} + c.stepCount > t.stepTimes.size() ||
          (c.kind == ClusterKind::Merged && c.mesh >= t.meshes.size());
  }
  for (size_t i = 0; !bad && i < t.children.size(); ++i) bad = t.children[i] >= nc;
  for (size_t i = 0; !bad && i < t.objectCluster.size(); ++i) bad = t.objectCluster[i] != ~0u && t.objectCluster[i] >= nc;
  for (size_t i = 1; !bad && i < t.modelLodBegin.size(); ++i) bad = t.modelLodBegin[i] < t.modelLodBegin[i - 1];
  for (size_t i = 0; !bad && i < t.modelLods.size(); ++i) bad = t.modelLods[i].mesh >= t.meshes.size();
  for (size_t i = 0; !bad && i < t.meshes.size(); ++i) {
    const ClusterMesh& m = t.meshes[i];
    bad = m.indices.size() % 3 != 0 || (!m.materials.empty() && m.materials.size() != m.indices.size() / 3);
    for (size_t k = 0; !bad && k < m.indices.size(); ++k) bad = m.indices[k] >= m.positions.size();
  }
  if (bad || !prepareSelection(t)) {
    why = "inconsistent contents";
    return false;
  }
  return true;
}

// The tree's references into the scene (hdlod_build.h): a leaf's object and its model, a mesh
// triangle's material (a model index), one objectCluster entry per object. The key says which
// scene the file was built for, but a forged or damaged file with a valid key and checksum could
// still name an object or model the scene does not have (selectHdlod() and the HDLOD pass index
// the scene's arrays with them). "" when they fit, else the first bad reference.
std::string sceneMismatch(const HdlodTree& t, const Scene& scene) {
  const size_t objects = scene.objects.size(), models = scene.models.size();
  if (t.objectCluster.size() != objects) {
    return "has leaves for " + std::to_string(t.objectCluster.size()) + " objects, the scene has " + std::to_string(objects);
  }
  for (size_t i = 0; i < t.clusters.size(); ++i) {
    const Cluster& c = t.clusters[i];
    if (c.kind != ClusterKind::Object && c.kind != ClusterKind::Dynamic) continue;
    const std::string leaf = "cluster " + std::to_string(i) + " (a leaf)";
    if (c.object >= objects) {
      return leaf + " names object " + std::to_string(c.object) + ", the scene has " + std::to_string(objects) + " objects";
    }
    if (c.mesh >= models) {
      return leaf + " names model " + std::to_string(c.mesh) + ", the scene has " + std::to_string(models) + " models";
    }
    if (scene.objects[c.object].model != c.mesh) {
      return leaf + " names model " + std::to_string(c.mesh) + " for object " + std::to_string(c.object) +
             ", whose model in the scene is " + std::to_string(scene.objects[c.object].model);
    }
  }
  // Models past 65535 share material 65535 (hdlod_build.h); the renderer's colour table has
  // one entry per model (one when there is none).
  const size_t materials = std::max<size_t>(1, std::min<size_t>(models, 65536));
  for (size_t i = 0; i < t.meshes.size(); ++i) {
    for (uint16_t m : t.meshes[i].materials) {
      if (m >= materials) {
        return "mesh " + std::to_string(i) + " names material (model) " + std::to_string(m) + ", the scene has " +
               std::to_string(models) + " models";
      }
    }
  }
  return "";
}

}  // namespace

uint64_t hdlodCacheKey(const Scene& scene, const BuildConfig& c) {
  Hasher h;
  h.put(kHdlodCacheVersion);
  h.put(kBuildRevision);
  h.put(scene.duration_s);
  h.put(static_cast<uint64_t>(scene.models.size()));
  for (const Model& m : scene.models) {
    h.text(m.name);
    h.array(m.positions);
    h.array(m.indices);
  }
  h.put(static_cast<uint64_t>(scene.objects.size()));
  for (const Object& o : scene.objects) {
    h.text(o.name);
    h.put(o.model);
    h.array(o.visible);
    h.put(static_cast<uint64_t>(o.path.size()));
    for (const Keyframe& k : o.path) {
      h.put(k.t_s);
      h.put(k.position_m);
      h.put(k.heading_deg);
    }
  }
  h.put(c.levels);
  h.put(c.maxChildren);
  h.put(c.epsPerSize);
  h.put(static_cast<uint8_t>(c.simplifier));
  h.put(c.sloppyAboveTriangles);
  h.put(c.maxHausdorffSamples);
  h.put(static_cast<uint8_t>(c.strictHausdorff));
  h.put(static_cast<uint8_t>(c.twoSidedHausdorff));
  h.put(c.dynamicGroupSize);
  h.put(c.candidatesPerCell);
  h.put(c.modelLodLevels);
  h.put(c.modelLodMinTriangles);
  return h.value();
}

bool saveHdlodCache(const std::string& path, const HdlodTree& tree, uint64_t key, std::string& error) {
  const std::vector<uint8_t> payload = serialize(tree);
  Header header{};
  std::memcpy(header.magic, kMagic, sizeof kMagic);
  header.version = kHdlodCacheVersion;
  header.key = key;
  header.payloadBytes = payload.size();
  header.checksum = checksumOf(payload.data(), payload.size());
  const std::string tmp = path + ".tmp." + std::to_string(static_cast<long>(::getpid()));
  // The cache's folder is made as needed (a scene's `cache = "../../out/site.hdlod"` on a fresh
  // checkout has no out/ yet: the tree was built again at every start). A folder that cannot be
  // made shows as the failed open below.
  if (const std::filesystem::path parent = std::filesystem::path(path).parent_path(); !parent.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(parent, ec);
  }
  FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) {
    error = path + ": cannot write the HDLOD cache: " + std::strerror(errno);
    return false;
  }
  const bool ok = std::fwrite(&header, sizeof header, 1, f) == 1 &&
                  (payload.empty() || std::fwrite(payload.data(), payload.size(), 1, f) == 1);
  const bool closed = std::fclose(f) == 0;
  if (!ok || !closed || std::rename(tmp.c_str(), path.c_str()) != 0) {
    error = path + ": cannot write the HDLOD cache: " + std::strerror(errno);
    std::remove(tmp.c_str());
    return false;
  }
  return true;
}

bool loadHdlodCache(const std::string& path, uint64_t key, HdlodTree& tree, std::string& error) {
  tree = HdlodTree{};
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    // No file there (also when a folder on the path is a file): "missing", a first build.
    const bool none = errno == ENOENT || errno == ENOTDIR;
    error = path + ": HDLOD cache " + (none ? "missing" : std::string("unreadable: ") + std::strerror(errno));
    return false;
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    error = path + ": HDLOD cache: not a regular file";
    return false;
  }
  const size_t size = static_cast<size_t>(st.st_size);
  if (size < kHeaderBytes) {
    ::close(fd);
    error = path + ": not an HDLOD cache (" + std::to_string(size) + " bytes, shorter than the header)";
    return false;
  }
  void* map = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
  ::close(fd);
  if (map == MAP_FAILED) {
    error = path + ": HDLOD cache: mmap failed: " + std::strerror(errno);
    return false;
  }
  const auto* bytes = static_cast<const uint8_t*>(map);
  Header h;
  std::memcpy(&h, bytes, sizeof h);
  std::string why;
  if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0) {
    why = "not an HDLOD cache (bad magic)";
  } else if (h.version != kHdlodCacheVersion) {
    why = "version " + std::to_string(h.version) + ", expected " + std::to_string(kHdlodCacheVersion);
  } else if (h.key != key) {
    why = "stale: built for another scene or build config";
  } else if (h.payloadBytes != size - kHeaderBytes) {
    why = "truncated (" + std::to_string(size - kHeaderBytes) + " payload bytes, header says " + std::to_string(h.payloadBytes) + ")";
  } else if (checksumOf(bytes + kHeaderBytes, size - kHeaderBytes) != h.checksum) {
    why = "checksum mismatch";
  } else if (!deserialize(bytes + kHeaderBytes, size - kHeaderBytes, tree, why)) {
    tree = HdlodTree{};
  }
  ::munmap(map, size);
  if (!why.empty()) {
    tree = HdlodTree{};
    error = path + ": HDLOD cache " + why;
    return false;
  }
  return true;
}

bool loadHdlodCache(const std::string& path, uint64_t key, const Scene& scene, HdlodTree& tree, std::string& error) {
  if (!loadHdlodCache(path, key, tree, error)) return false;
  const std::string why = sceneMismatch(tree, scene);
  if (why.empty()) return true;
  tree = HdlodTree{};
  error = path + ": HDLOD cache does not fit the scene: " + why;
  return false;
}

const char* cacheOutcomeName(CacheOutcome o) {
  switch (o) {
    case CacheOutcome::Disabled: return "built";
    case CacheOutcome::Loaded: return "loaded";
    case CacheOutcome::Built: return "built+saved";
    case CacheOutcome::Rebuilt: return "rebuilt";
  }
  return "?";
}

HdlodTree loadOrBuildHdlod(const Scene& scene, const BuildConfig& config, const std::string& path, CacheOutcome& outcome,
                           std::string& note) {
  note.clear();
  if (path.empty()) {
    outcome = CacheOutcome::Disabled;
    return buildHdlod(scene, config);
  }
  const uint64_t key = hdlodCacheKey(scene, config);
  HdlodTree tree;
  std::string error;
  if (loadHdlodCache(path, key, scene, tree, error)) {
    outcome = CacheOutcome::Loaded;
    if (config.progress) config.progress(1.0, "loaded");
    return tree;
  }
  // The exact "missing" error (a path may contain the word itself).
  const bool existed = error != path + ": HDLOD cache missing";
  if (existed) note = error + "; rebuilding";
  outcome = existed ? CacheOutcome::Rebuilt : CacheOutcome::Built;
  tree = buildHdlod(scene, config);
  if (!saveHdlodCache(path, tree, key, error)) note += (note.empty() ? "" : "; ") + error;
  return tree;
}

}  // namespace ig::lod::hdlod
