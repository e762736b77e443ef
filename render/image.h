// RGBA8 images: PNG read/write (libpng) and the per-pixel error used by golden-image tests and
// the image-error columns of the LOD benchmarks. No GL here.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ig::render {

struct Image {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> rgba;  // row 0 = top
};

bool writePng(const std::string& file, const Image& image, std::string& error);
// Refuses (error naming the file and size) an image of more than 2^28 pixels before allocating.
bool readPng(const std::string& file, Image& image, std::string& error);
// Root-mean-square difference over R, G, B of all pixels, in 8-bit levels (0..255).
// Returns a negative value if the sizes differ.
double rmse(const Image& a, const Image& b);
// Peak signal-to-noise ratio over R, G, B in dB: 20 log10(255 / rmse), at most 99 (the value of
// identical images, also for images that differ by less); negative if the sizes differ.
double psnrDb(const Image& a, const Image& b);
// Fraction of pixels whose largest channel difference exceeds `threshold` levels.
double fractionDifferent(const Image& a, const Image& b, int threshold);

}  // namespace ig::render
