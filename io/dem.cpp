#include "io/dem.h"

#include <fcntl.h>
#include <png.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <tiffio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>

namespace ig::io {
namespace {

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool sizeOk(const std::string& file, int64_t w, int64_t h, const DemLoadOptions& o, std::string& error) {
  if (w < 2 || h < 2) {
    error = file + ": DEM size " + std::to_string(w) + "x" + std::to_string(h) + " is too small (need >= 2x2)";
    return false;
  }
  if (w * h > o.maxSamples) {
    error = file + ": DEM size " + std::to_string(w) + "x" + std::to_string(h) + " exceeds the limit of " +
            std::to_string(o.maxSamples) + " samples";
    return false;
  }
  return true;
}

// Marks voids (no-data, NaN, inf), applies the void policy.
bool finish(const std::string& file, const DemLoadOptions& o, bool hasNoData, double noData, Dem& dem,
            std::string& error) {
  std::vector<uint8_t> isVoid(dem.heights_m.size(), 0);
  uint64_t voids = 0;
  // The samples are floats: compare with the no-data value rounded to float the same way (as
  // GDAL does), or a float32 DEM whose no-data is -9999.9 kept its voids as
  // heights. A no-data value outside the float range matches no finite sample.
  // A value a printing's rounding beyond the float range (-3.40282346639e+38: the float minimum
  // with 12 digits, as ArcGIS and GDAL tools write it) names +-FLT_MAX, as GDAL takes it.
  constexpr double kFloatMax = static_cast<double>(std::numeric_limits<float>::max());
  if (hasNoData && std::isfinite(noData) && std::abs(noData) > kFloatMax && std::abs(noData) <= kFloatMax * (1.0 + 1e-10))
    noData = std::copysign(kFloatMax, noData);
  const bool noDataFits = hasNoData && std::isfinite(noData) && std::abs(noData) <= kFloatMax;
  const float noDataF = noDataFits ? static_cast<float>(noData) : 0.0f;
  for (size_t i = 0; i < dem.heights_m.size(); ++i) {
    const float h = dem.heights_m[i];
    if (!std::isfinite(h) || (noDataFits && h == noDataF)) {
      isVoid[i] = 1;
      ++voids;
    }
  }
  if (voids == 0) return true;
  const double share = static_cast<double>(voids) / static_cast<double>(dem.heights_m.size());
  if (o.voids == DemVoids::Reject) {
    error = file + ": " + std::to_string(voids) + " void samples (no-data/NaN) and voids are set to be rejected";
    return false;
  }
  if (share > o.maxVoidFraction) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.1f %%", share * 100.0);
    error = file + ": " + buf + " of the samples are voids (limit " + std::to_string(o.maxVoidFraction * 100.0) + " %)";
    return false;
  }
  if (!fillVoids(dem.heights_m, dem.width, dem.height, isVoid)) {
    error = file + ": no valid sample";
    return false;
  }
  dem.voidsFilled = voids;
  return true;
}

// libpng's error callback: keeps the message and jumps back to readPngSamples' setjmp.
[[noreturn]] void pngError(png_structp png, png_const_charp message) {
  auto* text = static_cast<std::string*>(png_get_error_ptr(png));
  if (text) *text = message ? message : "libpng error";
  png_longjmp(png, 1);
}
void pngWarning(png_structp, png_const_charp) {}

// The libpng part of loadPng16, kept free of C++ objects with destructors, so that libpng's
// longjmp out of a decode skips none. The samples as stored: no gamma or sRGB transform (the
// simplified API "linearises" grey by the file's gAMA / sRGB chunks, which bends heights).
// Returns 0 on success, 1 when libpng failed (message in *pngMessage), 2 for a refused
// colour type (message in *pngMessage), 3 for a size sizeOk refuses.
int readPngSamples(png_structp png, png_infop info, std::FILE* f, const DemLoadOptions& o, std::vector<uint16_t>& raw,
                   png_uint_32& width, png_uint_32& height, const char** refused) {
  if (setjmp(png_jmpbuf(png))) return 1;
  png_init_io(png, f);
  png_read_info(png, info);
  width = png_get_image_width(png, info);
  height = png_get_image_height(png, info);
  const int colorType = png_get_color_type(png, info);
  const int depth = png_get_bit_depth(png, info);
  if (colorType != PNG_COLOR_TYPE_GRAY || png_get_valid(png, info, PNG_INFO_tRNS)) {
    *refused = (colorType & PNG_COLOR_MASK_COLOR) != 0 ? "colour" : "grey + alpha";
    return 2;
  }
  if (width < 2 || height < 2 || static_cast<int64_t>(width) * static_cast<int64_t>(height) > o.maxSamples) return 3;
  if (depth < 8) png_set_expand_gray_1_2_4_to_8(png);  // 0 ... 255, as the simplified API gave them
  const int passes = png_set_interlace_handling(png);
  png_read_update_info(png, info);
  const size_t rowBytes = png_get_rowbytes(png, info);
  const size_t bytesPerSample = depth == 16 ? 2 : 1;
  if (rowBytes != static_cast<size_t>(width) * bytesPerSample) return 1;
  raw.assign(static_cast<size_t>(width) * height * bytesPerSample / 2 + 1, 0);  // bytes, as 16-bit words
  auto* bytes = reinterpret_cast<png_bytep>(raw.data());
  for (int pass = 0; pass < passes; ++pass)
    for (png_uint_32 y = 0; y < height; ++y) png_read_row(png, bytes + static_cast<size_t>(y) * rowBytes, nullptr);
  png_read_end(png, nullptr);
  return 0;
}

bool loadPng16(const std::string& file, const DemLoadOptions& o, Dem& dem, std::string& error) {
  std::FILE* f = std::fopen(file.c_str(), "rb");
  if (!f) {
    error = file + ": not a readable PNG: " + std::strerror(errno);
    return false;
  }
  unsigned char signature[8] = {};
  if (std::fread(signature, 1, sizeof signature, f) != sizeof signature || png_sig_cmp(signature, 0, sizeof signature) != 0) {
    std::fclose(f);
    error = file + ": not a readable PNG: no PNG signature";
    return false;
  }
  std::rewind(f);
  std::string message;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &message, pngError, pngWarning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!info) {
    if (png) png_destroy_read_struct(&png, nullptr, nullptr);
    std::fclose(f);
    error = file + ": not a readable PNG: out of memory";
    return false;
  }
  std::vector<uint16_t> raw;
  png_uint_32 w = 0, h = 0;
  const char* refused = nullptr;
  const int status = readPngSamples(png, info, f, o, raw, w, h, &refused);
  const int depth = png_get_bit_depth(png, info);
  png_destroy_read_struct(&png, &info, nullptr);
  std::fclose(f);
  if (status == 1) {
    error = file + ": " + (w == 0 ? "not a readable PNG: " : "PNG decode failed: ") + message;
    return false;
  }
  if (status == 2) {
    // Colour is turned into luminance and alpha composited away: neither gives heights.
    error = file + ": " + refused + " PNG; a DEM must be a 16-bit (or 8-bit) greyscale PNG without alpha";
    return false;
  }
  if (!sizeOk(file, w, h, o, error)) return false;
  const auto* bytes = reinterpret_cast<const uint8_t*>(raw.data());
  const size_t count = static_cast<size_t>(w) * h;
  dem.width = static_cast<int>(w);
  dem.height = static_cast<int>(h);
  dem.heights_m.resize(count);
  for (size_t i = 0; i < count; ++i) {
    const unsigned v = depth == 16 ? (static_cast<unsigned>(bytes[2 * i]) << 8) | bytes[2 * i + 1] : bytes[i];  // big-endian
    dem.heights_m[i] = static_cast<float>(o.pngOffset_m + o.pngScale_m * v);
  }
  dem.format = "png16";
  return finish(file, o, o.hasNoData, o.pngOffset_m + o.pngScale_m * o.noData, dem, error);
}

bool loadHgt(const std::string& file, const DemLoadOptions& o, Dem& dem, std::string& error) {
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(file, ec);
  if (ec) {
    error = file + ": cannot stat: " + ec.message();
    return false;
  }
  // SRTM tiles are square, big-endian int16: 1201 x 1201 (3") or 3601 x 3601 (1").
  const auto samples = static_cast<int64_t>(bytes / 2);
  const auto side = static_cast<int64_t>(std::llround(std::sqrt(static_cast<double>(samples))));
  if (bytes % 2 != 0 || side * side != samples) {
    error = file + ": " + std::to_string(bytes) + " bytes is not a square grid of 16-bit samples (.hgt)";
    return false;
  }
  if (!sizeOk(file, side, side, o, error)) return false;
  std::ifstream in(file, std::ios::binary);
  std::vector<uint8_t> raw(bytes);
  if (!in.read(reinterpret_cast<char*>(raw.data()), static_cast<std::streamsize>(bytes))) {
    error = file + ": read failed";
    return false;
  }
  dem.width = dem.height = static_cast<int>(side);
  dem.heights_m.resize(static_cast<size_t>(samples));
  for (size_t i = 0; i < dem.heights_m.size(); ++i)
    dem.heights_m[i] = static_cast<float>(static_cast<int16_t>((raw[2 * i] << 8) | raw[2 * i + 1]));
  // Latitude from the SRTM file name (N46E007.hgt): the sample spacing east-west shrinks with
  // cos(latitude); north-south it is 1/(side-1) degree. We use the north-south spacing.
  dem.spacing_m = 111320.0 / static_cast<double>(side - 1);
  dem.format = "hgt";
  return finish(file, o, true, -32768.0, dem, error);
}

struct TiffCloser {
  void operator()(TIFF* t) const { TIFFClose(t); }
};

// GeoTIFF / GDAL tags libtiff does not know: registered through a tag extender so that
// TIFFGetField reads them with a known signature.
constexpr ttag_t kModelPixelScaleTag = 33550;  // double[3]: sample spacing x, y, z
constexpr ttag_t kGeoKeyDirectoryTag = 34735;  // SHORT[4 + 4 n]: header, then (key, location, count, value)
constexpr ttag_t kGdalNoDataTag = 42113;       // ASCII: the no-data value
constexpr uint16_t kGTModelTypeGeoKey = 1024;  // 1 projected, 2 geographic (degrees), 3 geocentric
TIFFExtendProc gParentExtender = nullptr;
void extendTags(TIFF* tif) {
  static const TIFFFieldInfo info[] = {
      {kModelPixelScaleTag, -1, -1, TIFF_DOUBLE, FIELD_CUSTOM, 1, 1, const_cast<char*>("ModelPixelScaleTag")},
      {kGeoKeyDirectoryTag, -1, -1, TIFF_SHORT, FIELD_CUSTOM, 1, 1, const_cast<char*>("GeoKeyDirectoryTag")},
      {kGdalNoDataTag, -1, -1, TIFF_ASCII, FIELD_CUSTOM, 1, 0, const_cast<char*>("GDALNoDataValue")}};
  TIFFMergeFieldInfo(tif, info, 3);
  if (gParentExtender) gParentExtender(tif);
}

bool loadGeoTiff(const std::string& file, const DemLoadOptions& o, Dem& dem, std::string& error) {
  static const bool extended = [] {
    gParentExtender = TIFFSetTagExtender(extendTags);
    return true;
  }();
  (void)extended;
  TIFFSetWarningHandler(nullptr);
  static thread_local std::string tiffError;
  TIFFSetErrorHandler([](const char* module, const char* fmt, va_list ap) {
    char buf[512];
    // libtiff hands its own printf format here.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wformat-nonliteral"
    std::vsnprintf(buf, sizeof buf, fmt, ap);
#pragma GCC diagnostic pop
    tiffError = std::string(module ? module : "tiff") + ": " + buf;
  });
  tiffError.clear();
  std::unique_ptr<TIFF, TiffCloser> tif(TIFFOpen(file.c_str(), "r"));
  if (!tif) {
    error = file + ": not a readable TIFF" + (tiffError.empty() ? "" : " (" + tiffError + ")");
    return false;
  }
  uint32_t w = 0, h = 0;
  uint16_t spp = 1, bps = 0, format = SAMPLEFORMAT_UINT;
  TIFFGetField(tif.get(), TIFFTAG_IMAGEWIDTH, &w);
  TIFFGetField(tif.get(), TIFFTAG_IMAGELENGTH, &h);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLESPERPIXEL, &spp);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_BITSPERSAMPLE, &bps);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLEFORMAT, &format);
  if (!sizeOk(file, w, h, o, error)) return false;
  if (spp != 1) {
    error = file + ": " + std::to_string(spp) + " samples per pixel; a DEM needs exactly 1 band";
    return false;
  }
  const bool supported = (format == SAMPLEFORMAT_INT && (bps == 16 || bps == 32)) ||
                         (format == SAMPLEFORMAT_UINT && bps == 16) || (format == SAMPLEFORMAT_IEEEFP && bps == 32);
  if (!supported) {
    error = file + ": sample format " + std::to_string(format) + " with " + std::to_string(bps) +
            " bits is not supported (int16, uint16, int32, float32)";
    return false;
  }
  dem.width = static_cast<int>(w);
  dem.height = static_cast<int>(h);
  dem.heights_m.assign(static_cast<size_t>(w) * h, 0.0f);
  auto convert = [&](const uint8_t* src, size_t count, float* dst) {
    for (size_t i = 0; i < count; ++i) {
      if (format == SAMPLEFORMAT_IEEEFP) {
        float v;
        std::memcpy(&v, src + 4 * i, 4);
        dst[i] = v;
      } else if (format == SAMPLEFORMAT_INT && bps == 32) {
        int32_t v;
        std::memcpy(&v, src + 4 * i, 4);
        dst[i] = static_cast<float>(v);
      } else if (format == SAMPLEFORMAT_INT) {
        int16_t v;
        std::memcpy(&v, src + 2 * i, 2);
        dst[i] = static_cast<float>(v);
      } else {
        uint16_t v;
        std::memcpy(&v, src + 2 * i, 2);
        dst[i] = static_cast<float>(v);
      }
    }
  };
  const size_t bytesPerSample = bps / 8;
  if (TIFFIsTiled(tif.get())) {
    uint32_t tw = 0, th = 0;
    TIFFGetField(tif.get(), TIFFTAG_TILEWIDTH, &tw);
    TIFFGetField(tif.get(), TIFFTAG_TILELENGTH, &th);
    std::vector<uint8_t> tile(static_cast<size_t>(TIFFTileSize(tif.get())));
    std::vector<float> row(tw);
    for (uint32_t ty = 0; ty < h; ty += th) {
      for (uint32_t tx = 0; tx < w; tx += tw) {
        if (TIFFReadTile(tif.get(), tile.data(), tx, ty, 0, 0) < 0) {
          error = file + ": tile at (" + std::to_string(tx) + ", " + std::to_string(ty) + ") unreadable: " + tiffError;
          return false;
        }
        for (uint32_t y = 0; y < th && ty + y < h; ++y) {
          convert(tile.data() + static_cast<size_t>(y) * tw * bytesPerSample, tw, row.data());
          const uint32_t n = std::min(tw, w - tx);
          std::copy(row.begin(), row.begin() + n, dem.heights_m.begin() + static_cast<std::ptrdiff_t>((ty + y) * static_cast<size_t>(w) + tx));
        }
      }
    }
  } else {
    std::vector<uint8_t> line(static_cast<size_t>(TIFFScanlineSize(tif.get())));
    for (uint32_t y = 0; y < h; ++y) {
      if (TIFFReadScanline(tif.get(), line.data(), y, 0) < 0) {
        error = file + ": row " + std::to_string(y) + " unreadable: " + tiffError;
        return false;
      }
      convert(line.data(), w, dem.heights_m.data() + static_cast<size_t>(y) * w);
    }
  }
  // GeoTIFF pixel scale (tag 33550): sample spacing in the file's units (metres for projected
  // DEMs, degrees for geographic ones: converted at the equator scale).
  uint16_t count = 0;
  double* scale = nullptr;
  if (TIFFGetField(tif.get(), kModelPixelScaleTag, &count, &scale) == 1 && scale && count >= 2 && scale[1] > 0 &&
      std::isfinite(scale[1])) {
    // Degrees or metres: from GTModelTypeGeoKey when the file has a GeoKey directory (a 0.5 m
    // lidar DEM is projected, not 0.5 degrees); the old guess (below 1 = degrees) only without.
    int modelType = 0;
    uint16_t keyCount = 0;
    uint16_t* keys = nullptr;
    if (TIFFGetField(tif.get(), kGeoKeyDirectoryTag, &keyCount, &keys) == 1 && keys && keyCount >= 4) {
      const size_t entries = std::min<size_t>(keys[3], (keyCount - 4u) / 4u);
      for (size_t k = 0; k < entries; ++k) {
        const uint16_t* e = keys + 4 + 4 * k;
        if (e[0] == kGTModelTypeGeoKey && e[1] == 0 && e[2] == 1) modelType = e[3];
      }
    }
    const bool degrees = modelType == 2 || (modelType == 0 && scale[1] < 1.0);
    dem.spacing_m = degrees ? scale[1] * 111320.0 : scale[1];
  }
  bool hasNoData = o.hasNoData;
  double noData = o.noData;
  char* gdalNoData = nullptr;
  if (TIFFGetField(tif.get(), kGdalNoDataTag, &gdalNoData) == 1 && gdalNoData) {
    char* end = nullptr;
    const double v = std::strtod(gdalNoData, &end);
    if (end != gdalNoData) {
      hasNoData = true;
      noData = v;
    }
  }
  dem.format = "geotiff";
  return finish(file, o, hasNoData, noData, dem, error);
}

}  // namespace

bool fillVoids(std::vector<float>& heights, int width, int height, std::vector<uint8_t>& isVoid) {
  // Layer by layer outwards from the valid samples: layer k + 1 is the voids next to layer k,
  // each filled with the mean of its 8-neighbours that were valid or filled in an earlier layer
  // (a layer is applied after it is computed, so the result does not depend on the scan order).
  // Each void is visited once per neighbour: linear in the DEM (a pass over every remaining void
  // per layer took ~an hour for a 16k DEM whose sea is no-data).
  const size_t w = static_cast<size_t>(width), n = heights.size();
  size_t voids = 0;
  for (uint8_t v : isVoid) voids += v ? 1 : 0;
  if (voids == 0) return true;
  if (voids == n) return false;
  auto forNeighbours = [&](size_t i, auto&& fn) {
    const int x = static_cast<int>(i % w), y = static_cast<int>(i / w);
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = x + dx, ny = y + dy;
        if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= width || ny >= height) continue;
        fn(static_cast<size_t>(ny) * w + static_cast<size_t>(nx));
      }
  };
  // queued: a void already in the current or the next layer.
  std::vector<uint8_t> queued(n, 0);
  std::vector<size_t> layer, next;
  for (size_t i = 0; i < n; ++i) {
    if (!isVoid[i]) continue;
    bool rim = false;
    forNeighbours(i, [&](size_t j) { rim = rim || !isVoid[j]; });
    if (rim) {
      layer.push_back(i);
      queued[i] = 1;
    }
  }
  std::vector<float> fills;
  while (!layer.empty()) {
    fills.clear();
    for (size_t i : layer) {
      double sum = 0.0;
      int k = 0;
      forNeighbours(i, [&](size_t j) {
        if (!isVoid[j]) {
          sum += static_cast<double>(heights[j]);
          ++k;
        }
      });
      fills.push_back(static_cast<float>(sum / k));  // k > 0: a layer's voids touch a filled sample
    }
    for (size_t m = 0; m < layer.size(); ++m) {
      heights[layer[m]] = fills[m];
      isVoid[layer[m]] = 0;
    }
    next.clear();
    for (size_t i : layer)
      forNeighbours(i, [&](size_t j) {
        if (isVoid[j] && !queued[j]) {
          queued[j] = 1;
          next.push_back(j);
        }
      });
    layer.swap(next);
  }
  return true;
}

void flipRows(Dem& dem) {
  const auto w = static_cast<std::ptrdiff_t>(dem.width);
  for (int y = 0; y < dem.height / 2; ++y)
    std::swap_ranges(dem.heights_m.begin() + y * w, dem.heights_m.begin() + (y + 1) * w,
                     dem.heights_m.begin() + (dem.height - 1 - y) * w);
}

bool loadDem(const std::string& file, const DemLoadOptions& options, Dem& out, std::string& error) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) {
    error = file + ": no such file";
    return false;
  }
  const std::string ext = lower(std::filesystem::path(file).extension().string());
  Dem dem;
  bool ok = false;
  if (ext == ".png") ok = loadPng16(file, options, dem, error);
  else if (ext == ".tif" || ext == ".tiff") ok = loadGeoTiff(file, options, dem, error);
  else if (ext == ".hgt") ok = loadHgt(file, options, dem, error);
  else {
    error = file + ": unknown DEM extension '" + ext + "' (expected .png, .tif, .tiff or .hgt)";
    return false;
  }
  if (!ok) return false;
  out = std::move(dem);
  return true;
}

// ---- memory-mapped cache ----------------------------------------------------------------

namespace {

struct CacheHeader {
  char magic[8];        // "IGDEMRAW"
  uint32_t version;     // 1
  int32_t width, height;
  uint32_t pad;
  double spacing_m;
  uint64_t sourceBytes;
  int64_t sourceMtime;
  uint8_t reserved[16];
};
static_assert(sizeof(CacheHeader) == 64, "cache header is 64 bytes");
constexpr char kCacheMagic[8] = {'I', 'G', 'D', 'E', 'M', 'R', 'A', 'W'};

}  // namespace

MappedDem::MappedDem(MappedDem&& o) noexcept { *this = std::move(o); }

MappedDem& MappedDem::operator=(MappedDem&& o) noexcept {
  if (this != &o) {
    if (base_) munmap(base_, bytes_);
    base_ = o.base_;
    bytes_ = o.bytes_;
    heights_ = o.heights_;
    width_ = o.width_;
    height_ = o.height_;
    spacing_m_ = o.spacing_m_;
    o.base_ = nullptr;
    o.bytes_ = 0;
    o.heights_ = nullptr;
    o.width_ = o.height_ = 0;
  }
  return *this;
}

MappedDem::~MappedDem() {
  if (base_) munmap(base_, bytes_);
}

bool writeDemCache(const std::string& path, std::span<const float> heights_m, int width, int height, double spacing_m,
                   uint64_t sourceBytes, int64_t sourceMtime, std::string& error) {
  if (width < 2 || height < 2 || heights_m.size() < static_cast<size_t>(width) * static_cast<size_t>(height)) {
    error = path + ": bad DEM size " + std::to_string(width) + "x" + std::to_string(height) + " for a cache";
    return false;
  }
  CacheHeader h{};
  std::memcpy(h.magic, kCacheMagic, 8);
  h.version = 1;
  h.width = width;
  h.height = height;
  h.spacing_m = spacing_m;
  h.sourceBytes = sourceBytes;
  h.sourceMtime = sourceMtime;
  // A name of its own per call, not only per process: two threads writing the same cache shared
  // "path.tmpPID" (the second truncated the first one's file, wrote on into the inode the first
  // had renamed into place, and its own rename failed).
  static std::atomic<uint64_t> sequence{0};
  const std::string tmp = path + ".tmp" + std::to_string(getpid()) + "." + std::to_string(sequence.fetch_add(1));
  std::FILE* f = std::fopen(tmp.c_str(), "wbx");  // x: exclusive, never someone else's file
  if (!f) {
    error = path + ": cannot write the DEM cache: " + std::strerror(errno);
    return false;
  }
  const size_t n = static_cast<size_t>(width) * static_cast<size_t>(height);
  bool ok = std::fwrite(&h, sizeof h, 1, f) == 1 && std::fwrite(heights_m.data(), sizeof(float), n, f) == n;
  ok = std::fclose(f) == 0 && ok;
  if (!ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    error = path + ": cannot write the DEM cache: " + std::strerror(errno);
    std::remove(tmp.c_str());
    return false;
  }
  return true;
}

bool mapDemCache(const std::string& path, MappedDem& out, std::string& error, uint64_t sourceBytes, int64_t sourceMtime) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    error = path + ": cannot open the DEM cache: " + std::strerror(errno);
    return false;
  }
  struct stat st {};
  if (fstat(fd, &st) != 0 || st.st_size < static_cast<off_t>(sizeof(CacheHeader))) {
    error = path + ": not a DEM cache (" + std::to_string(st.st_size) + " bytes)";
    ::close(fd);
    return false;
  }
  const auto bytes = static_cast<size_t>(st.st_size);
  void* base = mmap(nullptr, bytes, PROT_READ, MAP_SHARED, fd, 0);
  ::close(fd);
  if (base == MAP_FAILED) {
    error = path + ": mmap failed: " + std::strerror(errno);
    return false;
  }
  CacheHeader h;
  std::memcpy(&h, base, sizeof h);
  auto fail = [&](const std::string& why) {
    munmap(base, bytes);
    error = path + ": " + why;
    return false;
  };
  if (std::memcmp(h.magic, kCacheMagic, 8) != 0 || h.version != 1) return fail("not a DEM cache (bad magic or version)");
  if (h.width < 2 || h.height < 2) return fail("bad size " + std::to_string(h.width) + "x" + std::to_string(h.height));
  const size_t need = sizeof h + static_cast<size_t>(h.width) * static_cast<size_t>(h.height) * sizeof(float);
  if (bytes != need) return fail(std::to_string(bytes) + " bytes, expected " + std::to_string(need) + " (truncated?)");
  if (!(h.spacing_m >= 0.0) || !std::isfinite(h.spacing_m)) return fail("bad spacing " + std::to_string(h.spacing_m));
  if (sourceBytes != 0 && (h.sourceBytes != sourceBytes || h.sourceMtime != sourceMtime))
    return fail("made from another version of the source (size or time differs)");
  // The LOD walks the DEM locally but not in file order; the kernel's read-ahead still helps.
  madvise(base, bytes, MADV_WILLNEED);
  MappedDem m;
  m.base_ = base;
  m.bytes_ = bytes;
  m.heights_ = reinterpret_cast<const float*>(static_cast<const char*>(base) + sizeof h);
  m.width_ = h.width;
  m.height_ = h.height;
  m.spacing_m_ = h.spacing_m;
  out = std::move(m);
  return true;
}

bool loadDemCached(const std::string& file, const std::string& cacheDir, const DemLoadOptions& options, MappedDem& out,
                   DemCacheInfo& info, std::string& error) {
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) {
    error = file + ": cannot stat: " + std::strerror(errno);
    return false;
  }
  std::error_code ec;
  std::filesystem::create_directories(cacheDir, ec);
  if (ec) {
    error = cacheDir + ": cannot create the DEM cache folder: " + ec.message();
    return false;
  }
  const auto bytes = static_cast<uint64_t>(st.st_size);
  const auto mtime = static_cast<int64_t>(st.st_mtim.tv_sec) * 1000000000LL + st.st_mtim.tv_nsec;
  // One cache file per source path and load options (scale, no-data, and the void rule and
  // size limit, so that a caller who rejects voids is not served a DEM another caller's rule
  // filled): a readable name plus a hash.
  char limits[96];
  std::snprintf(limits, sizeof limits, "|%d|%.17g|%lld", options.voids == DemVoids::Reject ? 1 : 0,
                options.maxVoidFraction, static_cast<long long>(options.maxSamples));
  const std::string key = std::filesystem::absolute(file, ec).string() + "|" + std::to_string(options.pngScale_m) + "|" +
                          std::to_string(options.pngOffset_m) + "|" + std::to_string(options.hasNoData ? options.noData : -1e300) +
                          limits;
  uint64_t hash = 1469598103934665603ull;
  for (unsigned char c : key) hash = (hash ^ c) * 1099511628211ull;
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash));
  info.cacheFile = (std::filesystem::path(cacheDir) / (std::filesystem::path(file).filename().string() + "." + hex + ".igdem")).string();
  std::string why;
  if (mapDemCache(info.cacheFile, out, why, bytes, mtime)) {
    info.fromCache = true;
    return true;
  }
  Dem dem;
  if (!loadDem(file, options, dem, error)) return false;
  flipRows(dem);
  if (!writeDemCache(info.cacheFile, dem.heights_m, dem.width, dem.height, dem.spacing_m, bytes, mtime, error)) return false;
  info.fromCache = false;
  return mapDemCache(info.cacheFile, out, error, bytes, mtime);
}

}  // namespace ig::io
