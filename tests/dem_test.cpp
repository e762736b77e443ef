// DEM readers: 16-bit PNG, GeoTIFF (strips and tiles, int16 and float32, GDAL no-data) and
// SRTM .hgt written by this test with libpng / libtiff / plain bytes; voids filled or
// rejected; truncated and corrupt files rejected with a message naming the file.
#include <gtest/gtest.h>

#include <png.h>
#include <tiffio.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <thread>

#include "io/dem.h"

using namespace ig::io;
namespace fs = std::filesystem;

namespace {

struct TempDir {
  fs::path path = fs::temp_directory_path() / ("igd_dem_test_" + std::to_string(::getpid()));
  TempDir() { fs::create_directories(path); }
  ~TempDir() { fs::remove_all(path); }
  std::string operator/(const std::string& name) const { return (path / name).string(); }
};

float sampleHeight(int x, int y) { return static_cast<float>(100 + 3 * x + 7 * y); }

void writePng16(const std::string& file, int w, int h) {
  std::vector<uint16_t> v(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) v[static_cast<size_t>(y) * w + x] = static_cast<uint16_t>(sampleHeight(x, y));
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(w);
  png.height = static_cast<png_uint_32>(h);
  png.format = PNG_FORMAT_LINEAR_Y;
  ASSERT_TRUE(png_image_write_to_file(&png, file.c_str(), 0, v.data(), 0, nullptr)) << png.message;
}

// One band of float32 or int16 samples, w x h, strips unless the caller sets tiles.
void setGreyTiff(TIFF* t, int w, int h, bool floatSamples) {
  TIFFSetField(t, TIFFTAG_IMAGEWIDTH, w);
  TIFFSetField(t, TIFFTAG_IMAGELENGTH, h);
  TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
  TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, floatSamples ? 32 : 16);
  TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, floatSamples ? SAMPLEFORMAT_IEEEFP : SAMPLEFORMAT_INT);
  TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
  TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
}

void writeTiff(const std::string& file, int w, int h, bool floatSamples, bool tiled, const char* noData,
               const std::vector<std::pair<int, int>>& voids = {}) {
  TIFF* t = TIFFOpen(file.c_str(), "w");
  ASSERT_NE(t, nullptr);
  setGreyTiff(t, w, h, floatSamples);
  std::vector<float> f(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) f[static_cast<size_t>(y) * w + x] = sampleHeight(x, y);
  for (auto [x, y] : voids) f[static_cast<size_t>(y) * w + x] = floatSamples ? NAN : -9999.0f;
  if (noData) {
    static const TIFFFieldInfo info[] = {{42113, -1, -1, TIFF_ASCII, FIELD_CUSTOM, 1, 0, const_cast<char*>("GDALNoDataValue")}};
    TIFFMergeFieldInfo(t, info, 1);
    TIFFSetField(t, 42113, noData);
  }
  const size_t bps = floatSamples ? 4 : 2;
  auto pack = [&](const float* src, size_t n, std::vector<uint8_t>& dst) {
    dst.resize(n * bps);
    for (size_t i = 0; i < n; ++i) {
      if (floatSamples) std::memcpy(&dst[4 * i], &src[i], 4);
      else {
        const auto v = static_cast<int16_t>(src[i]);
        std::memcpy(&dst[2 * i], &v, 2);
      }
    }
  };
  std::vector<uint8_t> buf;
  if (tiled) {
    const int tw = 16, th = 16;
    TIFFSetField(t, TIFFTAG_TILEWIDTH, tw);
    TIFFSetField(t, TIFFTAG_TILELENGTH, th);
    std::vector<float> tile(static_cast<size_t>(tw) * th, 0.0f);
    for (int ty = 0; ty < h; ty += th)
      for (int tx = 0; tx < w; tx += tw) {
        for (int y = 0; y < th; ++y)
          for (int x = 0; x < tw; ++x)
            tile[static_cast<size_t>(y) * tw + x] =
                (tx + x < w && ty + y < h) ? f[static_cast<size_t>(ty + y) * w + tx + x] : 0.0f;
        pack(tile.data(), tile.size(), buf);
        ASSERT_GE(TIFFWriteTile(t, buf.data(), static_cast<uint32_t>(tx), static_cast<uint32_t>(ty), 0, 0), 0);
      }
  } else {
    for (int y = 0; y < h; ++y) {
      pack(f.data() + static_cast<size_t>(y) * w, static_cast<size_t>(w), buf);
      ASSERT_GE(TIFFWriteScanline(t, buf.data(), static_cast<uint32_t>(y), 0), 0);
    }
  }
  TIFFClose(t);
}

void writeHgt(const std::string& file, int side, std::vector<std::pair<int, int>> voids = {}) {
  std::vector<uint8_t> b(static_cast<size_t>(side) * side * 2);
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      int16_t v = static_cast<int16_t>(sampleHeight(x, y));
      for (auto [vx, vy] : voids)
        if (vx == x && vy == y) v = -32768;
      const size_t i = (static_cast<size_t>(y) * side + x) * 2;
      b[i] = static_cast<uint8_t>((static_cast<uint16_t>(v) >> 8) & 0xFF);
      b[i + 1] = static_cast<uint8_t>(static_cast<uint16_t>(v) & 0xFF);
    }
  std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

void expectSamples(const Dem& d, int w, int h) {
  ASSERT_EQ(d.width, w);
  ASSERT_EQ(d.height, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) ASSERT_FLOAT_EQ(d.at(x, y), sampleHeight(x, y)) << x << "," << y;
}

}  // namespace

TEST(Dem, Png16) {
  TempDir tmp;
  writePng16(tmp / "a.png", 37, 20);  // non-power-of-two
  Dem d;
  std::string e;
  ASSERT_TRUE(loadDem(tmp / "a.png", {}, d, e)) << e;
  expectSamples(d, 37, 20);
  DemLoadOptions o;
  o.pngScale_m = 0.5;
  o.pngOffset_m = -10;
  ASSERT_TRUE(loadDem(tmp / "a.png", o, d, e)) << e;
  EXPECT_FLOAT_EQ(d.at(1, 0), -10.0f + 0.5f * sampleHeight(1, 0));
}

TEST(Dem, GeoTiffStripsTilesInt16Float32) {
  TempDir tmp;
  writeTiff(tmp / "s.tif", 40, 33, false, false, nullptr);
  writeTiff(tmp / "t.tiff", 40, 33, true, true, nullptr);  // tiles overhang the edges
  Dem d;
  std::string e;
  ASSERT_TRUE(loadDem(tmp / "s.tif", {}, d, e)) << e;
  expectSamples(d, 40, 33);
  EXPECT_EQ(d.format, "geotiff");
  ASSERT_TRUE(loadDem(tmp / "t.tiff", {}, d, e)) << e;
  expectSamples(d, 40, 33);
}

TEST(Dem, VoidsAreFilledFromTheirNeighboursOrRejected) {
  TempDir tmp;
  // A NaN hole in float data and a GDAL no-data hole in int16 data.
  writeTiff(tmp / "nan.tif", 20, 20, true, false, nullptr, {{5, 5}, {6, 5}, {5, 6}, {6, 6}});
  writeTiff(tmp / "nd.tif", 20, 20, false, false, "-9999", {{0, 0}, {10, 10}});
  Dem d;
  std::string e;
  ASSERT_TRUE(loadDem(tmp / "nan.tif", {}, d, e)) << e;
  EXPECT_EQ(d.voidsFilled, 4u);
  for (float h : d.heights_m) ASSERT_TRUE(std::isfinite(h));
  // The field is a plane: a hole filled from its rim lies within the rim's range.
  EXPECT_NEAR(d.at(5, 5), sampleHeight(5, 5), 12.0f);
  ASSERT_TRUE(loadDem(tmp / "nd.tif", {}, d, e)) << e;
  EXPECT_EQ(d.voidsFilled, 2u);
  EXPECT_GT(d.at(0, 0), 50.0f);  // not -9999
  DemLoadOptions reject;
  reject.voids = DemVoids::Reject;
  EXPECT_FALSE(loadDem(tmp / "nd.tif", reject, d, e));
  EXPECT_NE(e.find("nd.tif"), std::string::npos);
  EXPECT_NE(e.find("2 void samples"), std::string::npos) << e;
}

namespace {

// The void fill as first written (every remaining void rescanned per layer: quadratic), kept
// here as the reference the linear fill must match bit for bit.
bool fillVoidsByPasses(std::vector<float>& heights, int width, int height, std::vector<uint8_t>& isVoid) {
  std::vector<size_t> pending, next;
  for (size_t i = 0; i < isVoid.size(); ++i)
    if (isVoid[i]) pending.push_back(i);
  if (pending.size() == heights.size()) return false;
  std::vector<std::pair<size_t, float>> fills;
  while (!pending.empty()) {
    next.clear();
    fills.clear();
    for (size_t i : pending) {
      const int x = static_cast<int>(i % static_cast<size_t>(width)), y = static_cast<int>(i / static_cast<size_t>(width));
      double sum = 0.0;
      int n = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= width || ny >= height) continue;
          const size_t j = static_cast<size_t>(ny) * static_cast<size_t>(width) + static_cast<size_t>(nx);
          if (!isVoid[j]) {
            sum += static_cast<double>(heights[j]);
            ++n;
          }
        }
      if (n > 0) fills.emplace_back(i, static_cast<float>(sum / n));
      else next.push_back(i);
    }
    for (const auto& [i, h] : fills) {
      heights[i] = h;
      isVoid[i] = 0;
    }
    pending.swap(next);
  }
  return true;
}

}  // namespace

// Random void masks (scattered holes, blobs, a "sea" over most of the DEM, single valid
// samples, 1-wide DEMs): the layered fill gives exactly the heights of the pass-by-pass one.
TEST(Dem, VoidFillMatchesThePassByPassFillBitForBit) {
  std::mt19937 rng(7);
  int compared = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const int width = 1 + static_cast<int>(rng() % 40), height = 1 + static_cast<int>(rng() % 40);
    const size_t n = static_cast<size_t>(width) * static_cast<size_t>(height);
    std::vector<float> h(n);
    std::uniform_real_distribution<float> z(-50.0f, 3000.0f);
    for (float& v : h) v = z(rng);
    std::vector<uint8_t> mask(n, 0);
    const int kind = trial % 4;
    const double p = kind == 0 ? 0.2 : kind == 1 ? 0.9 : kind == 2 ? 0.995 : 0.5;
    std::bernoulli_distribution hole(p);
    for (size_t i = 0; i < n; ++i) mask[i] = hole(rng) ? 1 : 0;
    if (kind == 3)  // a sea: everything south of a wavy coast
      for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
          mask[static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x)] =
              y < height / 2 + static_cast<int>(3.0 * std::sin(x * 0.7)) ? 1 : 0;
    std::vector<float> a = h, b = h;
    std::vector<uint8_t> va = mask, vb = mask;
    const bool okA = fillVoids(a, width, height, va);
    const bool okB = fillVoidsByPasses(b, width, height, vb);
    ASSERT_EQ(okA, okB) << "trial " << trial;
    if (!okA) continue;
    ++compared;
    EXPECT_EQ(va, vb) << "trial " << trial;
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(a[i], b[i]) << "trial " << trial << " sample " << i;
  }
  EXPECT_GT(compared, 40);
  // A 1,025 x 1,025 DEM whose southern 45 % is a no-data sea fills (a pass per layer over every
  // remaining void took ~1.3 s here; the layered fill ~0.1 s: no time is asserted).
  const int side = 1025;
  std::vector<float> h(static_cast<size_t>(side) * side, 10.0f);
  std::vector<uint8_t> v(h.size(), 0);
  for (size_t i = 0; i < h.size() * 45 / 100; ++i) v[i] = 1;
  ASSERT_TRUE(fillVoids(h, side, side, v));
  EXPECT_EQ(h.front(), 10.0f);
  EXPECT_EQ(std::count(v.begin(), v.end(), uint8_t{1}), 0);
}

TEST(Dem, MostlyVoidIsRejectedAndAllVoidCannotBeFilled) {
  std::vector<float> h(9, 1.0f);
  std::vector<uint8_t> v(9, 1);
  EXPECT_FALSE(fillVoids(h, 3, 3, v));
  TempDir tmp;
  std::vector<std::pair<int, int>> many;
  for (int y = 0; y < 20; ++y)
    for (int x = 0; x < 15; ++x) many.emplace_back(x, y);
  writeTiff(tmp / "holes.tif", 20, 20, true, false, nullptr, many);
  Dem d;
  std::string e;
  EXPECT_FALSE(loadDem(tmp / "holes.tif", {}, d, e));
  EXPECT_NE(e.find("75.0 %"), std::string::npos) << e;
}

TEST(Dem, SrtmHgtBigEndianWithVoids) {
  TempDir tmp;
  writeHgt(tmp / "N46E007.hgt", 121, {{3, 4}});
  Dem d;
  std::string e;
  ASSERT_TRUE(loadDem(tmp / "N46E007.hgt", {}, d, e)) << e;
  EXPECT_EQ(d.width, 121);
  EXPECT_EQ(d.voidsFilled, 1u);
  EXPECT_FLOAT_EQ(d.at(7, 9), sampleHeight(7, 9));
  EXPECT_NEAR(d.spacing_m, 111320.0 / 120.0, 1e-6);
}

TEST(Dem, TwoByTwoIsTheSmallestAccepted) {
  TempDir tmp;
  writePng16(tmp / "two.png", 2, 2);
  writePng16(tmp / "one.png", 1, 5);
  Dem d;
  std::string e;
  ASSERT_TRUE(loadDem(tmp / "two.png", {}, d, e)) << e;
  expectSamples(d, 2, 2);
  EXPECT_FALSE(loadDem(tmp / "one.png", {}, d, e));
  EXPECT_NE(e.find("1x5"), std::string::npos) << e;
}

TEST(Dem, CorruptAndTruncatedFilesFailCleanlyNamingTheFile) {
  TempDir tmp;
  writePng16(tmp / "a.png", 30, 30);
  writeTiff(tmp / "a.tif", 30, 30, false, false, nullptr);
  writeHgt(tmp / "a.hgt", 31);
  for (const std::string name : {"a.png", "a.tif", "a.hgt"}) {
    std::ifstream in(tmp / name, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    // Cuts into the header and into the sample data (not into trailers after complete data,
    // and never at an even .hgt length that is itself a valid smaller square).
    for (size_t cut : {size_t{0}, size_t{1}, size_t{7}, size_t{33}, bytes.size() / 2 | 1, bytes.size() * 3 / 4 | 1}) {
      const std::string file = tmp / ("cut_" + name);
      std::ofstream(file, std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(cut));
      Dem d;
      d.width = 77;  // must survive a failed load
      std::string e;
      EXPECT_FALSE(loadDem(file, {}, d, e)) << name << " cut at " << cut;
      EXPECT_EQ(d.width, 77);
      EXPECT_NE(e.find("cut_" + name), std::string::npos) << e;
    }
  }
  Dem d;
  std::string e;
  EXPECT_FALSE(loadDem(tmp / "missing.png", {}, d, e));
  EXPECT_NE(e.find("no such file"), std::string::npos);
  std::ofstream(tmp / "x.asc") << "ncols 2";
  EXPECT_FALSE(loadDem(tmp / "x.asc", {}, d, e));
  EXPECT_NE(e.find("'.asc'"), std::string::npos) << e;
}

// The memory-mapped cache: the first load decodes and writes it, the second maps it (same
// heights, rows south first), a changed source is decoded again, and a corrupt or truncated
// cache is refused with a message naming it.
TEST(Dem, MappedCacheRoundTripAndInvalidation) {
  TempDir tmp;
  const std::string file = tmp / "N46E007.hgt";
  writeHgt(file, 121);
  Dem direct;
  std::string error;
  ASSERT_TRUE(loadDem(file, {}, direct, error)) << error;
  flipRows(direct);
  MappedDem a, b;
  DemCacheInfo ia, ib;
  ASSERT_TRUE(loadDemCached(file, tmp / "cache", {}, a, ia, error)) << error;
  EXPECT_FALSE(ia.fromCache);
  ASSERT_TRUE(loadDemCached(file, tmp / "cache", {}, b, ib, error)) << error;
  EXPECT_TRUE(ib.fromCache);
  EXPECT_EQ(ia.cacheFile, ib.cacheFile);
  ASSERT_EQ(b.width(), 121);
  ASSERT_EQ(b.height(), 121);
  EXPECT_NEAR(b.spacing_m(), direct.spacing_m, 1e-9);
  ASSERT_EQ(b.heights_m().size(), direct.heights_m.size());
  EXPECT_TRUE(std::equal(direct.heights_m.begin(), direct.heights_m.end(), b.heights_m().begin()));
  EXPECT_GE(b.mappedBytes(), 121u * 121u * 4u);
  MappedDem moved = std::move(b);
  EXPECT_EQ(moved.width(), 121);
  EXPECT_EQ(b.width(), 0);

  // A changed source (another size) is not served from the stale cache.
  writeHgt(file, 61);
  MappedDem c;
  DemCacheInfo ic;
  ASSERT_TRUE(loadDemCached(file, tmp / "cache", {}, c, ic, error)) << error;
  EXPECT_FALSE(ic.fromCache);
  EXPECT_EQ(c.width(), 61);

  // Truncated and foreign files are refused, naming the file.
  const std::string bad = tmp / "bad.igdem";
  {
    std::ifstream in(ic.cacheFile, std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream out(bad, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size() - 10));
  }
  MappedDem d;
  EXPECT_FALSE(mapDemCache(bad, d, error));
  EXPECT_NE(error.find(bad), std::string::npos) << error;
  EXPECT_NE(error.find("truncated"), std::string::npos) << error;
  EXPECT_FALSE(mapDemCache(file, d, error));  // an .hgt is not a cache
  EXPECT_NE(error.find("not a DEM cache"), std::string::npos) << error;
  EXPECT_FALSE(mapDemCache(tmp / "missing.igdem", d, error));
  EXPECT_NE(error.find("missing.igdem"), std::string::npos) << error;
  // A cache folder that cannot be created is an error naming it, not a silent decode.
  MappedDem e;
  DemCacheInfo ie;
  EXPECT_FALSE(loadDemCached(file, file + "/sub", {}, e, ie, error));
  EXPECT_NE(error.find("cache"), std::string::npos) << error;
}

// Float32 GeoTIFF whose GDAL no-data is not exactly a float (-9999.9): the voids are
// samples equal to float(-9999.9) and must be found (they were compared as doubles and kept
// as 10 km pits). Same for a PNG whose scaled no-data is not a float (offset -500, scale 0.01).
TEST(Dem, NoDataThatIsNotExactlyAFloatStillMarksVoids) {
  TempDir tmp;
  const std::string file = tmp / "nd_float.tif";
  {
    TIFF* t = TIFFOpen(file.c_str(), "w");
    ASSERT_NE(t, nullptr);
    setGreyTiff(t, 8, 8, true);
    static const TIFFFieldInfo info[] = {{42113, -1, -1, TIFF_ASCII, FIELD_CUSTOM, 1, 0, const_cast<char*>("GDALNoDataValue")}};
    TIFFMergeFieldInfo(t, info, 1);
    TIFFSetField(t, 42113, "-9999.9");
    for (int y = 0; y < 8; ++y) {
      std::vector<float> row(8, 100.0f);
      if (y == 3) row[4] = -9999.9f;
      ASSERT_GE(TIFFWriteScanline(t, row.data(), static_cast<uint32_t>(y), 0), 0);
    }
    TIFFClose(t);
  }
  Dem d;
  std::string e;
  ASSERT_TRUE(loadDem(file, {}, d, e)) << e;
  EXPECT_EQ(d.voidsFilled, 1u);
  EXPECT_FLOAT_EQ(d.at(4, 3), 100.0f);

  writePng16(tmp / "nd.png", 6, 6);  // values 100 + 3x + 7y: only (0, 1) is 107
  DemLoadOptions o;
  o.pngScale_m = 0.01;
  o.pngOffset_m = -500.0;
  o.hasNoData = true;
  o.noData = 107.0;  // raw value; -500 + 0.01 * 107 = -498.93 in double, not a float
  ASSERT_TRUE(loadDem(tmp / "nd.png", o, d, e)) << e;
  EXPECT_EQ(d.voidsFilled, 1u);
}

// 8-bit greyscale PNGs (accepted, per the error text) must give the stored values, not
// their sRGB-to-linear decoding; colour and alpha PNGs of any depth are refused.
TEST(Dem, Png8BitGreyIsReadAsStoredAndColourIsRefused) {
  TempDir tmp;
  {
    std::vector<uint8_t> v = {0, 64, 128, 255, 0, 64, 128, 255};
    png_image png{};
    png.version = PNG_IMAGE_VERSION;
    png.width = 4;
    png.height = 2;
    png.format = PNG_FORMAT_GRAY;
    ASSERT_TRUE(png_image_write_to_file(&png, (tmp / "g8.png").c_str(), 0, v.data(), 0, nullptr)) << png.message;
  }
  Dem d;
  std::string e;
  ASSERT_TRUE(loadDem(tmp / "g8.png", {}, d, e)) << e;
  EXPECT_FLOAT_EQ(d.at(1, 0), 64.0f);
  EXPECT_FLOAT_EQ(d.at(2, 0), 128.0f);
  EXPECT_FLOAT_EQ(d.at(3, 1), 255.0f);
  {
    std::vector<uint16_t> v(2 * 2 * 3, 1000);
    png_image png{};
    png.version = PNG_IMAGE_VERSION;
    png.width = 2;
    png.height = 2;
    png.format = PNG_FORMAT_LINEAR_RGB;
    ASSERT_TRUE(png_image_write_to_file(&png, (tmp / "rgb16.png").c_str(), 0, v.data(), 0, nullptr)) << png.message;
  }
  EXPECT_FALSE(loadDem(tmp / "rgb16.png", {}, d, e));
  EXPECT_NE(e.find("rgb16.png"), std::string::npos) << e;
  EXPECT_NE(e.find("colour"), std::string::npos) << e;
}

// A projected GeoTIFF (GTModelTypeGeoKey = 1) with 0.5 m pixels is 0.5 m, not 0.5
// degrees (55 km); a geographic one (= 2) is converted; infinite scales are ignored.
TEST(Dem, GeoTiffPixelScaleUnitsFollowTheModelType) {
  TempDir tmp;
  auto write = [&](const std::string& file, double scale, int modelType) {
    TIFF* t = TIFFOpen(file.c_str(), "w");
    ASSERT_NE(t, nullptr);
    static const TIFFFieldInfo info[] = {
        {33550, -1, -1, TIFF_DOUBLE, FIELD_CUSTOM, 1, 1, const_cast<char*>("ModelPixelScaleTag")},
        {34735, -1, -1, TIFF_SHORT, FIELD_CUSTOM, 1, 1, const_cast<char*>("GeoKeyDirectoryTag")}};
    TIFFMergeFieldInfo(t, info, 2);
    setGreyTiff(t, 4, 4, false);
    double s[3] = {scale, scale, 0.0};
    TIFFSetField(t, 33550, 3, s);
    uint16_t keys[8] = {1, 1, 0, 1, 1024, 0, 1, static_cast<uint16_t>(modelType)};
    if (modelType) TIFFSetField(t, 34735, 8, keys);
    for (int y = 0; y < 4; ++y) {
      int16_t row[4] = {1, 2, 3, 4};
      ASSERT_GE(TIFFWriteScanline(t, row, static_cast<uint32_t>(y), 0), 0);
    }
    TIFFClose(t);
  };
  write(tmp / "proj.tif", 0.5, 1);
  write(tmp / "geo.tif", 0.5, 2);
  write(tmp / "inf.tif", INFINITY, 1);
  Dem d;
  std::string e;
  ASSERT_TRUE(loadDem(tmp / "proj.tif", {}, d, e)) << e;
  EXPECT_DOUBLE_EQ(d.spacing_m, 0.5);
  ASSERT_TRUE(loadDem(tmp / "geo.tif", {}, d, e)) << e;
  EXPECT_DOUBLE_EQ(d.spacing_m, 0.5 * 111320.0);
  ASSERT_TRUE(loadDem(tmp / "inf.tif", {}, d, e)) << e;
  EXPECT_EQ(d.spacing_m, 0.0);
}

// A float32 GeoTIFF whose GDAL no-data is the float minimum printed with 12 digits
// ("-3.40282346639e+38", as ArcGIS and many GDAL tools write it): the double lies just beyond
// the float range, but it names -FLT_MAX, the value the voids hold (GDAL snaps it the same
// way). The voids were kept as heights of -3.4e38 m.
TEST(Dem, NoDataJustBeyondTheFloatRangeNamesTheFloatMinimum) {
  TempDir tmp;
  const std::string file = tmp / "nd_fltmax.tif";
  {
    TIFF* t = TIFFOpen(file.c_str(), "w");
    ASSERT_NE(t, nullptr);
    setGreyTiff(t, 8, 8, true);
    static const TIFFFieldInfo info[] = {{42113, -1, -1, TIFF_ASCII, FIELD_CUSTOM, 1, 0, const_cast<char*>("GDALNoDataValue")}};
    TIFFMergeFieldInfo(t, info, 1);
    TIFFSetField(t, 42113, "-3.40282346639e+38");
    for (int y = 0; y < 8; ++y) {
      std::vector<float> row(8, 100.0f);
      if (y == 5) row[2] = -std::numeric_limits<float>::max();
      ASSERT_GE(TIFFWriteScanline(t, row.data(), static_cast<uint32_t>(y), 0), 0);
    }
    TIFFClose(t);
  }
  Dem d;
  std::string e;
  ASSERT_TRUE(loadDem(file, {}, d, e)) << e;
  EXPECT_EQ(d.voidsFilled, 1u);
  EXPECT_FLOAT_EQ(d.at(2, 5), 100.0f);
}

// The cache serves a DEM loaded under the same void rule only: a file with voids cached under
// DemVoids::Fill must still be refused when the caller asks for DemVoids::Reject (or a lower
// maxVoidFraction), as loadDem refuses it. It was served from the cache.
TEST(Dem, CachedDemHonoursTheVoidRuleOfTheCaller) {
  TempDir tmp;
  const std::string file = tmp / "N10E010.hgt";
  writeHgt(file, 31, {{3, 4}, {10, 10}});
  MappedDem a;
  DemCacheInfo ia;
  std::string error;
  ASSERT_TRUE(loadDemCached(file, tmp / "cache", {}, a, ia, error)) << error;
  DemLoadOptions reject;
  reject.voids = DemVoids::Reject;
  Dem direct;
  EXPECT_FALSE(loadDem(file, reject, direct, error));
  MappedDem b;
  DemCacheInfo ib;
  EXPECT_FALSE(loadDemCached(file, tmp / "cache", reject, b, ib, error)) << "served from " << ib.cacheFile;
  DemLoadOptions strict;
  strict.maxVoidFraction = 1e-4;  // 2 voids in 961 samples is above this
  EXPECT_FALSE(loadDemCached(file, tmp / "cache", strict, b, ib, error)) << "served from " << ib.cacheFile;
}

// A 16-bit greyscale PNG heightmap that carries a gAMA chunk (ImageMagick and many image
// tools write one): the samples are heights, not light, and must come out as stored. libpng's
// simplified reader "linearised" them (32768 -> ~14000 with gamma 1/2.2), bending the terrain.
TEST(Dem, Png16WithAGammaChunkIsReadAsStored) {
  TempDir tmp;
  const std::string file = tmp / "gamma.png";
  const int w = 5, h = 4;
  {
    std::FILE* f = std::fopen(file.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
    png_infop info = png_create_info_struct(png);
    png_init_io(png, f);
    png_set_IHDR(png, info, w, h, 16, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
                 PNG_FILTER_TYPE_DEFAULT);
    png_set_gAMA(png, info, 1.0 / 2.2);
    png_write_info(png, info);
    std::vector<uint8_t> row(static_cast<size_t>(w) * 2);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const auto v = static_cast<uint16_t>(1000 * x + 10000 * y + 7);
        row[2 * static_cast<size_t>(x)] = static_cast<uint8_t>(v >> 8);  // PNG is big-endian
        row[2 * static_cast<size_t>(x) + 1] = static_cast<uint8_t>(v & 0xFF);
      }
      png_write_row(png, row.data());
    }
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
    std::fclose(f);
  }
  Dem d;
  std::string e;
  ASSERT_TRUE(loadDem(file, {}, d, e)) << e;
  ASSERT_EQ(d.width, w);
  ASSERT_EQ(d.height, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) ASSERT_EQ(d.at(x, y), static_cast<float>(1000 * x + 10000 * y + 7)) << x << "," << y;
}

// Two threads of one process writing the same cache at once (the temporary name was
// "path.tmpPID" for both): each write succeeds and the file is one writer's whole grid, never a
// mix or a truncated one; no temporary file is left.
TEST(Dem, TwoThreadsWritingOneCacheEachWriteAWholeFile) {
  TempDir tmp;
  const std::string path = tmp / "shared.igdem";
  const int w = 513, h = 513;
  const std::vector<float> ones(static_cast<size_t>(w) * h, 1.0f), twos(static_cast<size_t>(w) * h, 2.0f);
  for (int round = 0; round < 20; ++round) {
    std::atomic<int> ready{0};
    bool okA = false, okB = false;
    std::string errA, errB;
    auto writer = [&](const std::vector<float>& v, bool& ok, std::string& err) {
      ++ready;
      while (ready < 2) {
      }
      ok = writeDemCache(path, v, w, h, 30.0, 0, 0, err);
    };
    std::thread a(writer, std::cref(ones), std::ref(okA), std::ref(errA));
    std::thread b(writer, std::cref(twos), std::ref(okB), std::ref(errB));
    a.join();
    b.join();
    EXPECT_TRUE(okA) << "round " << round << ": " << errA;
    EXPECT_TRUE(okB) << "round " << round << ": " << errB;
    MappedDem m;
    std::string error;
    ASSERT_TRUE(mapDemCache(path, m, error)) << "round " << round << ": " << error;
    const std::span<const float> hs = m.heights_m();
    ASSERT_EQ(hs.size(), ones.size());
    const float first = hs[0];
    EXPECT_TRUE(first == 1.0f || first == 2.0f) << "round " << round << ": " << first;
    EXPECT_EQ(std::count(hs.begin(), hs.end(), first), static_cast<std::ptrdiff_t>(hs.size())) << "round " << round;
    if (HasFailure()) break;
  }
  size_t left = 0;  // no temporary file left behind
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(tmp.path)) ++left;
  EXPECT_EQ(left, 1u);
}
