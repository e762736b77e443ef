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

#include <cstdint>
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

}  // namespace ig::io
