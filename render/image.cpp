#include "render/image.h"

#include <png.h>

#include <cerrno>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>

namespace ig::render {
namespace {
struct FileCloser {
  void operator()(FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<FILE, FileCloser>;
}  // namespace

bool writePng(const std::string& file, const Image& image, std::string& error) {
  if (image.width <= 0 || image.height <= 0 ||
      image.rgba.size() != size_t{4} * static_cast<size_t>(image.width) * static_cast<size_t>(image.height)) {
    error = file + ": image of " + std::to_string(image.width) + " x " + std::to_string(image.height) + " pixels holds " +
            std::to_string(image.rgba.size()) + " bytes, not 4 a pixel";
    return false;
  }
  FilePtr f(std::fopen(file.c_str(), "wb"));
  if (!f) {
    error = file + ": cannot write: " + std::strerror(errno);
    return false;
  }
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width);
  png.height = static_cast<png_uint_32>(image.height);
  png.format = PNG_FORMAT_RGBA;
  if (!png_image_write_to_stdio(&png, f.get(), 0, image.rgba.data(), 0, nullptr)) {
    error = file + ": PNG write failed: " + png.message;
    return false;
  }
  // The last part of the file (all of a small one) is still in stdio's buffer: a write error
  // there (a full disk, EIO) shows only in fflush / fclose, and must not pass as a written file.
  errno = 0;
  const bool flushed = std::fflush(f.get()) == 0 && std::ferror(f.get()) == 0;
  int writeErrno = flushed ? 0 : errno;
  const bool closed = std::fclose(f.release()) == 0;
  if (!closed && flushed) writeErrno = errno;
  if (!flushed || !closed) {
    error = file + ": PNG write failed: " + (writeErrno != 0 ? std::strerror(writeErrno) : "write error");
    return false;
  }
  return true;
}

bool readPng(const std::string& file, Image& image, std::string& error) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, file.c_str())) {
    error = file + ": cannot read PNG: " + png.message;
    return false;
  }
  // The header's size is allocated (zero-filled) before a row is decoded: a 60-byte file saying
  // 32768 x 16384 cost 2 GiB (std::bad_alloc under a memory limit). 2^28 pixels (1 GiB of RGBA)
  // is far above any image igd reads or writes.
  constexpr uint64_t kMaxPixels = uint64_t{1} << 28;
  if (uint64_t{png.width} * uint64_t{png.height} > kMaxPixels) {
    error = file + ": PNG of " + std::to_string(png.width) + "x" + std::to_string(png.height) + " pixels, more than " +
            std::to_string(kMaxPixels) + " in all";
    png_image_free(&png);
    return false;
  }
  png.format = PNG_FORMAT_RGBA;
  Image out;
  out.width = static_cast<int>(png.width);
  out.height = static_cast<int>(png.height);
  out.rgba.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, out.rgba.data(), 0, nullptr)) {
    error = file + ": PNG decode failed: " + png.message;
    png_image_free(&png);
    return false;
  }
  image = std::move(out);
  return true;
}

double rmse(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height || a.rgba.size() != b.rgba.size()) return -1.0;
  if (a.rgba.empty()) return 0.0;
  double sum = 0.0;
  for (size_t i = 0; i < a.rgba.size(); i += 4) {
    for (size_t c = 0; c < 3; ++c) {
      const double d = static_cast<double>(a.rgba[i + c]) - static_cast<double>(b.rgba[i + c]);
      sum += d * d;
    }
  }
  return std::sqrt(sum / static_cast<double>(a.rgba.size() / 4 * 3));
}

double psnrDb(const Image& a, const Image& b) {
  const double e = rmse(a, b);
  if (e < 0.0) return -1.0;
  // Capped at the value of identical images: the smallest error an image of more than ~40,000
  // pixels can have (one level in one channel of one pixel) is above 99 dB, and a near-identical
  // image must not score better than an identical one.
  return e > 0.0 ? std::min(99.0, 20.0 * std::log10(255.0 / e)) : 99.0;
}

double fractionDifferent(const Image& a, const Image& b, int threshold) {
  if (a.width != b.width || a.height != b.height || a.rgba.size() != b.rgba.size()) return 1.0;
  if (a.rgba.empty()) return 0.0;
  size_t differ = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4) {
    int m = 0;
    for (size_t c = 0; c < 3; ++c) m = std::max(m, std::abs(static_cast<int>(a.rgba[i + c]) - static_cast<int>(b.rgba[i + c])));
    if (m > threshold) ++differ;
  }
  return static_cast<double>(differ) / static_cast<double>(a.rgba.size() / 4);
}

}  // namespace ig::render
