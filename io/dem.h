// Elevation models (DEMs) from files: 16-bit greyscale PNG, GeoTIFF (libtiff; int16, uint16,
// int32, float32 single-band, strips or tiles) and SRTM .hgt. Untrusted input: every failure
// returns false with a message naming the file and the bad value, never asserts.
//
// Voids: samples equal to the no-data value (GDAL_NODATA tag, -32768 in .hgt, or the value
// the caller names), NaN and +-inf are voids. The fill rule (DemVoids::Fill): each void gets
// the mean of its valid 8-neighbours, repeated outward until every void is filled (a
// diffusion from the void's rim, so small holes get smooth plausible heights). A DEM whose
// void share exceeds DemLoadOptions::maxVoidFraction, or that has no valid sample, is rejected.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace ig::io {

enum class DemVoids { Fill, Reject };

struct DemLoadOptions {
  double pngScale_m = 1.0;        // 16-bit PNG: height = offset + scale * value
  double pngOffset_m = 0.0;
  bool hasNoData = false;         // a no-data value for formats that do not carry one
  double noData = 0.0;
  DemVoids voids = DemVoids::Fill;
  double maxVoidFraction = 0.5;   // reject above this share of voids
  int64_t maxSamples = 16385LL * 16385LL;  // refuse larger files before allocating
};

struct Dem {
  int width = 0;                  // samples per row (west -> east)
  int height = 0;                 // rows; row 0 is the NORTH edge as stored in the file
  double spacing_m = 0.0;         // 0 if the file does not say (PNG); .hgt: from latitude
  std::vector<float> heights_m;   // width * height, row-major
  uint64_t voidsFilled = 0;
  std::string format;             // "png16", "geotiff", "hgt"
  float at(int x, int y) const { return heights_m[static_cast<size_t>(y) * static_cast<size_t>(width) + x]; }
};

// Reverses the row order in place: files store the north row first, the LOD grids want row y
// to grow northwards (ENU).
void flipRows(Dem& dem);

// Chooses the reader by extension (.png, .tif/.tiff, .hgt), then by content.
bool loadDem(const std::string& file, const DemLoadOptions& options, Dem& out, std::string& error);

// The void rule above, exposed for tests and for readers of other formats. `isVoid` marks
// the samples to fill. Returns false if no sample is valid.
bool fillVoids(std::vector<float>& heights, int width, int height, std::vector<uint8_t>& isVoid);

// Large DEMs (up to 16385 x 16385 and beyond): a raw cache file, memory-mapped read-only, so
// start-up after the first load costs a page-table set-up instead of a decode (pages are
// read as the LOD touches them). Layout: a 64-byte header ("IGDEMRAW", version, width,
// height, spacing_m, size and modification time of the source) then width * height float32
// heights, row-major, rows SOUTH first (already flipped for the LOD grids, unlike Dem).
class MappedDem {
 public:
  MappedDem() = default;
  MappedDem(const MappedDem&) = delete;
  MappedDem& operator=(const MappedDem&) = delete;
  MappedDem(MappedDem&& o) noexcept;
  MappedDem& operator=(MappedDem&& o) noexcept;
  ~MappedDem();

  int width() const { return width_; }
  int height() const { return height_; }
  double spacing_m() const { return spacing_m_; }
  std::span<const float> heights_m() const { return {heights_, static_cast<size_t>(width_) * static_cast<size_t>(height_)}; }
  size_t mappedBytes() const { return bytes_; }

 private:
  friend bool mapDemCache(const std::string&, MappedDem&, std::string&, uint64_t, int64_t);
  void* base_ = nullptr;
  size_t bytes_ = 0;
  const float* heights_ = nullptr;
  int width_ = 0, height_ = 0;
  double spacing_m_ = 0.0;
};

// Writes a cache file (heights south row first, as the LOD wants them) atomically (a temporary
// file of its own, unique per call, renamed into place: concurrent writers of one path, threads
// or processes, each rename a whole file; a reader sees an old or a whole new one).
// sourceBytes / sourceMtime identify what it was made from.
bool writeDemCache(const std::string& path, std::span<const float> heights_m, int width, int height, double spacing_m,
                   uint64_t sourceBytes, int64_t sourceMtime, std::string& error);
// Maps a cache file. With sourceBytes != 0, a cache made from another source version is
// refused (error names the mismatch). Checks the header and the file size against the grid.
bool mapDemCache(const std::string& path, MappedDem& out, std::string& error, uint64_t sourceBytes = 0,
                 int64_t sourceMtime = 0);

struct DemCacheInfo {
  std::string cacheFile;
  bool fromCache = false;  // true: mapped an existing cache; false: decoded and wrote it
  double loadMs = 0.0;     // filled by callers that time it (io/ has no clock)
};
// loadDem + flipRows through a cache in cacheDir (created if missing): maps the cache when it
// exists and matches the file's size and modification time, else decodes the file, writes the
// cache and maps it. Falls back to an error (never to a silent decode) when the cache cannot be
// written.
bool loadDemCached(const std::string& file, const std::string& cacheDir, const DemLoadOptions& options, MappedDem& out,
                   DemCacheInfo& info, std::string& error);

}  // namespace ig::io
