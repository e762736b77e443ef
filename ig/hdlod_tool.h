// igtool site (HDLOD, paper 000): writes the synthetic construction site (lod/hdlod_site.h) as a
// 4D schedule file (docs/hdlod.md) with its models as OBJ files, and optionally builds the
// HDLOD tree into a cache file (lod/hdlod_cache.h) so that igd starts without building.
//
// Also the console progress bar the HDLOD build uses (igtool site, igbench hdlod, the [hdlod]
// layer at start-up).
#pragma once

#include <cstdint>
#include <functional>
#include <string>

namespace ig {

// A one-line progress bar on stderr, redrawn in place ("\r"), only when stderr is a terminal or
// `force` is set; otherwise silent. finish() ends the line.
class ProgressBar {
 public:
  ProgressBar(std::string label, bool force);
  ~ProgressBar();
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;
  bool enabled() const { return enabled_; }
  // Redraws when the shown percentage or stage changes.
  void update(double fraction, const char* stage);
  void finish();
  // A callback for lod::hdlod::BuildConfig::progress (empty when disabled).
  std::function<void(double, const char*)> callback();

 private:
  std::string label_, stage_;
  bool enabled_ = false, open_ = false;
  int shown_ = -1;
};

struct SiteToolOptions {
  std::string out = "site";        // output folder (created): site.sched + models/*.obj
  double scale = 1.0;              // lod::hdlod::SiteParams::scale
  uint32_t seed = 1;
  int floors = 62;                 // at scale 1
  int bays = 10;
  double durationDays = 365.0;     // T
  double originX_m = 0.0, originY_m = 0.0, originZ_m = 0.0;  // the site's centre
  std::string cache;               // also build the tree into this cache file ("" = no)
  std::string simplifier = "meshoptimizer";
  bool progress = false;           // progress bar even when stderr is not a terminal
};

// Returns the exit code (0 ok, 2 bad option, 1 write failure) and prints a one-line summary.
int runSiteTool(const SiteToolOptions& options);

}  // namespace ig
