#include "ig/status.h"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>

namespace ig {
namespace {

void appendf(std::string& out, const char* fmt, ...) __attribute__((format(printf, 2, 3)));
void appendf(std::string& out, const char* fmt, ...) {
  char buf[512];
  va_list ap;
  va_start(ap, fmt);
  const int n = std::vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  if (n > 0) out.append(buf, static_cast<size_t>(std::min<int>(n, static_cast<int>(sizeof buf) - 1)));
}

void appendJsonString(std::string& out, const std::string& s) {
  out += '"';
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      appendf(out, "\\u%04x", static_cast<unsigned>(static_cast<unsigned char>(c)));
    } else {
      out += c;
    }
  }
  out += '"';
}

// Percentile of the first n values, reordering `v` (no allocation).
double percentileInPlace(std::vector<double>& v, size_t n, double p) {
  if (n == 0) return 0.0;
  const auto k = static_cast<size_t>(std::min<double>(static_cast<double>(n - 1), std::ceil(p * static_cast<double>(n)) - 1.0));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.begin() + static_cast<std::ptrdiff_t>(n));
  return v[k];
}

}  // namespace

StatusReporter::StatusReporter(std::string file, double interval_s, double rate_hz) {
  reconfigure(std::move(file), interval_s, rate_hz);
  json_.reserve(2048);
  line_.reserve(256);
}

void StatusReporter::reconfigure(std::string file, double interval_s, double rate_hz) {
  // A reload that moves the report: the old file goes (left, it would say "running" forever).
  if (!file_.empty() && file != file_) std::remove(file_.c_str());
  file_ = std::move(file);
  tmpFile_ = file_.empty() ? std::string() : file_ + ".tmp";
  interval_ns_ = static_cast<int64_t>(std::max(interval_s, 0.01) * 1e9);
  // Room for the frames of 4 intervals at the rate, at most kExactFrames (1000 Hz x 3600 s
  // reserved 230 MB); the histogram takes every frame beyond.
  const double perInterval = std::ceil(std::max(interval_s, 0.01) * std::max(rate_hz, 1.0));
  work_ms_.reserve(static_cast<size_t>(std::min(4.0 * perInterval + 16.0, static_cast<double>(kExactFrames))));
  histogram_.resize(kHistogramBins, 0u);
  fileError_.clear();
}

size_t StatusReporter::histogramBin(double work_ms) {
  const double us = std::round(work_ms * 1e3);
  constexpr double kTop = static_cast<double>(uint64_t{1} << (kSubBits + kMaxShift + 1)) - 1.0;
  const auto x = static_cast<uint64_t>(!(us > 0.0) ? 0.0 : std::min(us, kTop));  // NaN: 0
  if (x < 2 * kSubBuckets) return static_cast<size_t>(x);
  const int shift = static_cast<int>(std::bit_width(x)) - 1 - kSubBits;
  return static_cast<size_t>(static_cast<uint64_t>(shift + 1) * kSubBuckets + (x >> shift) - kSubBuckets);
}

double StatusReporter::histogramValue_ms(size_t bin) {
  // The lowest value of the bin.
  if (bin < 2 * kSubBuckets) return static_cast<double>(bin) * 1e-3;
  const auto shift = static_cast<int>(bin / kSubBuckets) - 1;
  const uint64_t sub = bin % kSubBuckets + kSubBuckets;
  return static_cast<double>(sub << shift) * 1e-3;
}

// Nearest rank, as percentileInPlace, over the histogram of every frame of the interval.
double StatusReporter::histogramPercentile(double p) const {
  if (frames_ <= 0) return 0.0;
  const auto n = static_cast<double>(frames_);
  const auto k = static_cast<uint64_t>(std::min(n - 1.0, std::ceil(p * n) - 1.0));
  uint64_t seen = 0;
  for (size_t b = 0; b < histogram_.size(); ++b) {
    seen += histogram_[b];
    if (seen > k) return std::min(histogramValue_ms(b), workMax_ms_);
  }
  return workMax_ms_;
}

void StatusReporter::addFrame(const FrameTiming& t, uint64_t triangles) {
  if (work_ms_.size() < work_ms_.capacity()) work_ms_.push_back(t.work_ms);
  ++histogram_[histogramBin(t.work_ms)];
  workMax_ms_ = std::max(workMax_ms_, t.work_ms);
  for (int p = 0; p < kPhaseCount; ++p) phaseMax_ms_[static_cast<size_t>(p)] =
      std::max(phaseMax_ms_[static_cast<size_t>(p)], t.phase_ms[static_cast<size_t>(p)]);
  ++frames_;
  ++totalFrames_;
  if (t.overrun) {
    ++overruns_;
    ++totalOverruns_;
  }
  missed_ += t.missedSlots;
  totalMissed_ += t.missedSlots;
  triangles_ += triangles;
  lastFrame_ = t.frame;
}

const std::string& StatusReporter::report(int64_t now_ns, const StatusContext& ctx) {
  const double seconds = static_cast<double>(now_ns - lastReport_ns_) * 1e-9;
  // Exact over the frames kept when they are all of the interval's, else from the histogram
  // of every frame (reordering work_ms_ is harmless: it is cleared below).
  const size_t n = work_ms_.size();
  const bool exact = static_cast<int64_t>(n) >= frames_;
  const double p50 = exact ? percentileInPlace(work_ms_, n, 0.50) : histogramPercentile(0.50);
  const double p99 = exact ? percentileInPlace(work_ms_, n, 0.99) : histogramPercentile(0.99);
  // Of every frame of the interval: a loop faster than the rate (free-run, a host pacing the
  // frames) runs more frames than work_ms_ keeps.
  const double mx = frames_ > 0 ? workMax_ms_ : 0.0;

  json_.clear();
  appendf(json_, "{\"state\":\"%s\",\"time_unix_s\":%lld,\"frame\":%lld,\"rate_hz\":%.3f,", ctx.state,
          static_cast<long long>(std::time(nullptr)), static_cast<long long>(lastFrame_), ctx.rate_hz);
  appendf(json_, "\"frames\":%lld,\"overruns\":%lld,\"missed_slots\":%lld,", static_cast<long long>(totalFrames_),
          static_cast<long long>(totalOverruns_), static_cast<long long>(totalMissed_));
  appendf(json_,
          "\"interval\":{\"seconds\":%.3f,\"frames\":%lld,\"work_ms_p50\":%.3f,\"work_ms_p99\":%.3f,"
          "\"work_ms_max\":%.3f,\"overruns\":%lld,\"missed_slots\":%lld,\"triangles_mean\":%.0f,\"phase_ms_max\":{",
          seconds, static_cast<long long>(frames_), p50, p99, mx, static_cast<long long>(overruns_),
          static_cast<long long>(missed_),
          frames_ ? static_cast<double>(triangles_) / static_cast<double>(frames_) : 0.0);
  for (int p = 0; p < kPhaseCount; ++p)
    appendf(json_, "%s\"%s\":%.3f", p ? "," : "", phaseName(static_cast<Phase>(p)), phaseMax_ms_[static_cast<size_t>(p)]);
  appendf(json_, "}},\"budget\":{\"frame_ms\":%.3f,\"triangles\":%lld},", ctx.budgetFrame_ms,
          static_cast<long long>(ctx.budgetTriangles));
  json_ += "\"host\":{\"source\":";
  appendJsonString(json_, ctx.hostSource);
  appendf(json_, ",\"lost\":%s,\"rejected\":%llu", ctx.hostLost ? "true" : "false",
          static_cast<unsigned long long>(ctx.hostRejected));
  if (ctx.haveLink)
    appendf(json_,
            ",\"link\":{\"received\":%llu,\"accepted\":%llu,\"malformed\":%llu,\"out_of_range\":%llu,\"late\":%llu,"
            "\"dropped\":%llu}",
            static_cast<unsigned long long>(ctx.link.received), static_cast<unsigned long long>(ctx.link.accepted),
            static_cast<unsigned long long>(ctx.link.malformed),
            static_cast<unsigned long long>(ctx.link.outOfRange), static_cast<unsigned long long>(ctx.link.late),
            static_cast<unsigned long long>(ctx.link.dropped));
  if (ctx.haveHatHot)
    appendf(json_, ",\"hat_hot\":{\"requests\":%llu,\"answered\":%llu,\"refused\":%llu,\"deferred\":%llu}",
            static_cast<unsigned long long>(ctx.hatHot.requests), static_cast<unsigned long long>(ctx.hatHot.answered),
            static_cast<unsigned long long>(ctx.hatHot.refused), static_cast<unsigned long long>(ctx.hatHot.deferred));
  if (ctx.haveHatHot)
    appendf(json_, ",\"los\":{\"requests\":%llu,\"answered\":%llu,\"refused\":%llu,\"deferred\":%llu}",
            static_cast<unsigned long long>(ctx.hatHot.losRequests), static_cast<unsigned long long>(ctx.hatHot.losAnswered),
            static_cast<unsigned long long>(ctx.hatHot.losRefused), static_cast<unsigned long long>(ctx.hatHot.losDeferred));
  appendf(json_, "},\"config_generation\":%d,\"last_reload_error\":", ctx.configGeneration);
  appendJsonString(json_, ctx.lastReloadError);
  json_ += ",\"layers\":";
  appendJsonString(json_, ctx.layers);
  json_ += ",\"scheduling\":";
  appendJsonString(json_, ctx.scheduling);
  if (ctx.haveGovernor) {
    // A knob of a layer the scene does not have is null.
    const std::pair<const char*, double> knobs[] = {{"terrain_tolerance_px", ctx.terrainTolerance_px},
                                                    {"forest_near_m", ctx.forestNear_m},
                                                    {"hdlod_tolerance_px", ctx.hdlodTolerance_px},
                                                    {"cells_voxel_budget", ctx.cellsVoxelBudget},
                                                    {"forest_layers", ctx.forestLayers}};
    json_ += ",\"governor\":{";
    for (const auto& [name, value] : knobs) {
      if (!std::isfinite(value)) appendf(json_, "\"%s\":null,", name);  // JSON has no NaN or inf
      else appendf(json_, "\"%s\":%.3f,", name, value);
    }
    appendf(json_, "\"decreases\":%lld,\"increases\":%lld,\"emergencies\":%lld}",
            static_cast<long long>(ctx.governorDecreases), static_cast<long long>(ctx.governorIncreases),
            static_cast<long long>(ctx.governorEmergencies));
  } else {
    json_ += ",\"governor\":null";
  }
  json_ += "}\n";

  line_.clear();
  appendf(line_, "frame %lld, %.2f Hz: work p99 %.1f of %.1f ms, overruns %lld (%lld in last %.1f s); host %s %s",
          static_cast<long long>(lastFrame_), ctx.rate_hz, p99, ctx.budgetFrame_ms,
          static_cast<long long>(totalOverruns_), static_cast<long long>(overruns_), seconds,
          ctx.hostSource.c_str(), ctx.hostSource == "none" ? "" : (ctx.hostLost ? "LOST" : "ok"));
  appendf(line_, "; config #%d%s", ctx.configGeneration, ctx.lastReloadError.empty() ? "" : " (last reload failed)");
  if (ctx.haveGovernor) {
    // What detail the governor gives now, e.g. "; detail: terrain 4.00 px, cells 12000 voxels".
    const char* sep = "; detail: ";
    if (!std::isnan(ctx.terrainTolerance_px)) {
      appendf(line_, "%sterrain %.2f px", sep, ctx.terrainTolerance_px);
      sep = ", ";
    }
    if (!std::isnan(ctx.forestNear_m)) {
      appendf(line_, "%sforest trees to %.0f m", sep, ctx.forestNear_m);
      if (!std::isnan(ctx.forestLayers)) appendf(line_, ", %.0f shell layers", ctx.forestLayers);
      sep = ", ";
    }
    if (!std::isnan(ctx.hdlodTolerance_px)) {
      appendf(line_, "%shdlod %.2f px", sep, ctx.hdlodTolerance_px);
      sep = ", ";
    }
    if (!std::isnan(ctx.cellsVoxelBudget)) appendf(line_, "%scells %.0f voxels", sep, ctx.cellsVoxelBudget);
  }

  if (!file_.empty()) {
    fileError_.clear();
    FILE* f = std::fopen(tmpFile_.c_str(), "w");
    if (!f && errno == ENOENT) {
      // The report's folder is made as the stats' and snapshots' are (then the write is tried once more).
      std::error_code ec;
      std::filesystem::create_directories(std::filesystem::path(file_).parent_path(), ec);
      if (!ec) f = std::fopen(tmpFile_.c_str(), "w");
      if (!f && ec) errno = ec.value();
    }
    if (!f) {
      fileError_ = "service.status_file '" + file_ + "': cannot write '" + tmpFile_ + "': " + std::strerror(errno);
    } else {
      const bool wrote = std::fwrite(json_.data(), 1, json_.size(), f) == json_.size();
      const bool closed = std::fclose(f) == 0;
      if (!wrote || !closed) {
        fileError_ = "service.status_file '" + file_ + "': write failed: " + std::strerror(errno);
        std::remove(tmpFile_.c_str());
      } else if (std::rename(tmpFile_.c_str(), file_.c_str()) != 0) {
        fileError_ = "service.status_file '" + file_ + "': rename failed: " + std::strerror(errno);
        std::remove(tmpFile_.c_str());
      }
    }
  }
  // New interval.
  lastReport_ns_ = now_ns;
  work_ms_.clear();
  std::fill(histogram_.begin(), histogram_.end(), 0u);
  phaseMax_ms_.fill(0.0);
  workMax_ms_ = 0.0;
  overruns_ = missed_ = frames_ = 0;
  triangles_ = 0;
  return line_;
}

}  // namespace ig
