// HDLOD, part 6: the cache file of a built tree, so that a service starts without rebuilding.
//
// Format (little-endian, version kHdlodCacheVersion): a 64-byte header — magic "IGHDLOD\0",
// format version, the key (a hash of the scene and the build config, hdlodCacheKey()), the
// payload size and a checksum of the payload (64-bit FNV-1a over 8-byte words) — then the payload: the
// tree's arrays one after the other, each as a count and its raw elements.
//
// Loading maps the file (mmap, read-only), checks the magic, version, key, size and checksum
// before reading anything else, and copies the arrays into the tree. Every failure is reported
// with the file name and the reason ("missing", "not an HDLOD cache", "version 3, expected 4",
// "stale: built for another scene or config", "truncated", "checksum mismatch", "does not fit the
// scene" for references out of the scene's range), never a crash:
// loadOrBuildHdlod() then rebuilds and rewrites the file.
#pragma once

#include <cstdint>
#include <string>

#include "lod/hdlod_build.h"
#include "lod/hdlod_scene.h"

namespace ig::lod::hdlod {

// 2: merged clusters are simplified per material (the builder's output changed, not the layout).
inline constexpr uint32_t kHdlodCacheVersion = 2;

// A hash of everything the tree depends on: the scene (T, models, objects) and the config.
uint64_t hdlodCacheKey(const Scene& scene, const BuildConfig& config);

// Writes the tree (atomically: a temporary file renamed over `path`). False + error on failure.
bool saveHdlodCache(const std::string& path, const HdlodTree& tree, uint64_t key, std::string& error);

// Reads a cache written for `key`. False + error (naming the file and the reason) otherwise;
// `tree` is then left empty.
bool loadHdlodCache(const std::string& path, uint64_t key, HdlodTree& tree, std::string& error);
// The same, then checks the tree's references into `scene` (each leaf's object and model, the
// meshes' materials, one objectCluster entry per object): a file that names an object or model
// the scene does not have is refused ("does not fit the scene: cluster 12 (a leaf) names object
// 4294967295, the scene has 57 objects"), never traversed. loadOrBuildHdlod() loads with this.
bool loadHdlodCache(const std::string& path, uint64_t key, const Scene& scene, HdlodTree& tree, std::string& error);

enum class CacheOutcome : uint8_t { Disabled, Loaded, Built, Rebuilt };
const char* cacheOutcomeName(CacheOutcome o);

// Loads the tree from `path` when it holds this scene and config; else builds it and (re)writes
// the file. An empty path only builds. `note` says why a cache was not used or could not be
// written ("" when loaded or disabled).
HdlodTree loadOrBuildHdlod(const Scene& scene, const BuildConfig& config, const std::string& path, CacheOutcome& outcome,
                           std::string& note);

}  // namespace ig::lod::hdlod
