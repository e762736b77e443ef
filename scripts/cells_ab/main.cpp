// scripts/cells-ab, step 2: the selection of two revisions side by side on igbench cells' tree
// and path, frame by frame in one process (which side goes first alternates), so that a noisy,
// shared machine slows both alike. Each frame's time is the fastest of --reps replays.
// Prints p50 / p99 / mean of both and their ratios (new / old), and whether both chose the same
// cells, requests, splits and merges in every frame (exit status 1 if not).
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#define SIDE_API(p)                                                                                    \
  extern "C" void* p##_init(const double*, const void*, uint64_t);                                   \
  extern "C" void p##_begin(void*, int, int, uint64_t, uint64_t, uint32_t, int);                     \
  extern "C" double p##_step(void*, int);                                                            \
  extern "C" uint64_t p##_signature(void*);
SIDE_API(old)
SIDE_API(new)

namespace {
double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(p / 100.0 * static_cast<double>(v.size() - 1) + 0.5)];
}
}  // namespace

int main(int argc, char** argv) {
  std::string treeFile;
  int reps = 5, frames = 600, latency = 3;
  uint64_t budget = 2000000, w = 1 << 20;
  uint32_t maxOps = 256;  // igbench cells --max-ops
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const char* v = i + 1 < argc ? argv[i + 1] : nullptr;
    if (a == "--tree" && v) treeFile = argv[++i];
    else if (a == "--reps" && v) reps = std::atoi(argv[++i]);
    else if (a == "--frames" && v) frames = std::atoi(argv[++i]);
    else if (a == "--voxel-budget" && v) budget = std::strtoull(argv[++i], nullptr, 10);
    else if (a == "--w-bytes" && v) w = std::strtoull(argv[++i], nullptr, 10);
    else if (a == "--max-ops" && v) maxOps = static_cast<uint32_t>(std::strtoul(argv[++i], nullptr, 10));
    else if (a == "--latency" && v) latency = std::atoi(argv[++i]);
    else {
      std::fprintf(stderr, "cells-ab: unknown or incomplete argument '%s'\n", a.c_str());
      return 2;
    }
  }
  if (treeFile.empty() || reps < 1 || frames < 3 || latency < 0) {
    std::fprintf(stderr, "cells-ab: --tree FILE is needed; --reps >= 1, --frames >= 3, --latency >= 0\n");
    return 2;
  }
  FILE* f = std::fopen(treeFile.c_str(), "rb");
  double header[5];
  uint64_t n = 0;
  if (!f || std::fread(header, sizeof header, 1, f) != 1 || std::fread(&n, sizeof n, 1, f) != 1 || n == 0 ||
      n > (1ull << 32)) {
    std::fprintf(stderr, "cells-ab: cannot read %s\n", treeFile.c_str());
    return 1;
  }
  std::vector<char> cells(n * 16);  // sizeof(ig::lod::CellDesc) on both sides
  if (std::fread(cells.data(), 16, n, f) != n) {
    std::fprintf(stderr, "cells-ab: %s is truncated\n", treeFile.c_str());
    return 1;
  }
  std::fclose(f);
  void* o = old_init(header, cells.data(), n);
  void* m = new_init(header, cells.data(), n);
  if (!o || !m) return 1;
  int differ = 0;
  for (int streaming = 1; streaming >= 0; --streaming) {
    std::vector<double> bo(static_cast<size_t>(frames), 1e300), bn(static_cast<size_t>(frames), 1e300);
    bool same = true;
    for (int r = 0; r < reps; ++r) {
      old_begin(o, streaming, frames, budget, w, maxOps, latency);
      new_begin(m, streaming, frames, budget, w, maxOps, latency);
      for (int i = 0; i < frames; ++i) {
        double a, b;
        if ((i + r) & 1) {
          a = old_step(o, i);
          b = new_step(m, i);
        } else {
          b = new_step(m, i);
          a = old_step(o, i);
        }
        bo[static_cast<size_t>(i)] = std::min(bo[static_cast<size_t>(i)], a);
        bn[static_cast<size_t>(i)] = std::min(bn[static_cast<size_t>(i)], b);
      }
      same = same && old_signature(o) == new_signature(m);
    }
    // Frame 0 (from the root) is not a steady frame.
    const std::vector<double> ro(bo.begin() + 1, bo.end()), rn(bn.begin() + 1, bn.end());
    double so = 0, sn = 0;
    for (size_t i = 0; i < ro.size(); ++i) {
      so += ro[i];
      sn += rn[i];
    }
    const double o50 = percentile(ro, 50), o99 = percentile(ro, 99), n50 = percentile(rn, 50), n99 = percentile(rn, 99);
    std::printf("cells-ab: %s (%d frames, voxel budget %llu%s): old p50 %.3f p99 %.3f mean %.3f ms | new p50 %.3f p99 %.3f "
                "mean %.3f ms | new/old p50 %.3f p99 %.3f mean %.3f | %s\n",
                streaming ? "streaming path" : "everything resident", frames, static_cast<unsigned long long>(budget),
                streaming ? "" : ", no op cap", o50, o99, so / static_cast<double>(ro.size()), n50, n99,
                sn / static_cast<double>(rn.size()), n50 / o50, n99 / o99, sn / so,
                same ? "the same choices in every frame" : "DIFFERENT CHOICES");
    if (!same) ++differ;
  }
  return differ ? 1 : 0;
}
