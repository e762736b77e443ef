#include "lod/geomorph.h"

#include <algorithm>

namespace ig::lod {

Geomorph::Geomorph(size_t capacity, double morph_s) : morph_s_(morph_s), capacity_(capacity) {
  size_t n = 16;
  while (n < 2 * capacity) n <<= 1;
  table_.assign(n, Entry{0, 0.0, 0.0f});
  scratch_.assign(n, Entry{0, 0.0, 0.0f});
}

size_t Geomorph::slot(uint64_t k) const {
  const size_t mask = table_.size() - 1;
  size_t i = static_cast<size_t>((k * 0x9E3779B97F4A7C15ull) >> 20) & mask;
  while (table_[i].key != 0 && table_[i].key != k) i = (i + 1) & mask;
  return i;
}

void Geomorph::start(int x, int y, float startHeight_m, double now_s) {
  if (morph_s_ <= 0.0 || live_ >= capacity_) return;  // off, or full: the vertex pops
  const uint64_t k = key(x, y);
  const size_t i = slot(k);
  if (table_[i].key == k) return;
  table_[i] = Entry{k, now_s, startHeight_m};
  ++live_;
  lastEnd_s_ = std::max(lastEnd_s_, now_s + morph_s_);
}

float Geomorph::height(int x, int y, float trueHeight_m, double now_s) const {
  if (live_ == 0) return trueHeight_m;
  const Entry& e = table_[slot(key(x, y))];
  if (e.key == 0) return trueHeight_m;
  const double t = std::clamp((now_s - e.start_s) / morph_s_, 0.0, 1.0);
  return static_cast<float>(static_cast<double>(e.startHeight_m) +
                            (static_cast<double>(trueHeight_m) - static_cast<double>(e.startHeight_m)) * t);
}

void Geomorph::expire(double now_s) {
  if (live_ == 0) return;
  bool any = false;
  for (const Entry& e : table_) any = any || (e.key != 0 && now_s >= e.start_s + morph_s_);
  if (!any) return;
  // Rebuild without the finished entries (keeps linear probing valid without tombstones).
  std::fill(scratch_.begin(), scratch_.end(), Entry{0, 0.0, 0.0f});
  table_.swap(scratch_);
  live_ = 0;
  for (const Entry& e : scratch_) {
    if (e.key == 0 || now_s >= e.start_s + morph_s_) continue;
    table_[slot(e.key)] = e;
    ++live_;
  }
}

}  // namespace ig::lod
