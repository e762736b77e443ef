#include "ig/bench_latency.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <thread>
#include <vector>

#include "ig/app_common.h"
#include "ig/clock.h"
#include "ig/json.h"
#include "ig/service.h"
#include "ig/stats.h"
#include "lod/geo.h"

#if IG_LINK_CIGI
#include "io/cigi.h"
#include "io/cigi_link.h"
#endif

namespace ig {

#if IG_LINK_CIGI
namespace {

namespace cigi = io::cigi;

// The ownship flies a 1.5 km circle at 600 m over the scene origin, one lap a minute.
struct Ownship {
  lod::EnuFrame frame;
  explicit Ownship(const lod::Geodetic& origin) : frame(origin) {}
  cigi::EntityControl at(double t_s) const {
    const double a = t_s * 2.0 * 3.14159265358979323846 / 60.0;
    const lod::Geodetic g = frame.toGeodetic({1500.0 * std::cos(a), 1500.0 * std::sin(a), 600.0});
    cigi::EntityControl e;
    e.lat_deg = g.lat_deg;
    e.lon_deg = g.lon_deg;
    e.alt_m = g.height_m;
    e.yaw_deg = static_cast<float>(std::fmod(360.0 - a * 180.0 / 3.14159265358979323846 + 360.0, 360.0));
    e.pitch_deg = -8.0f;
    return e;
  }
};

// One host message: IG Control + the ownship's Entity Control.
size_t buildMessage(std::span<std::byte> buf, uint32_t hostFrame, double t_s, const Ownship& ship,
                    cigi::ByteOrder order) {
  cigi::IgControl ig;
  ig.hostFrame = hostFrame;
  ig.timestampValid = true;
  ig.timestamp_10us = static_cast<uint32_t>(t_s * 1e5);
  size_t n = cigi::encode(ig, order, buf);
  n += cigi::encode(ship.at(t_s), order, buf.subspan(n));
  return n;
}

double decodeRate(const Ownship& ship, cigi::ByteOrder order) {
  std::array<std::byte, 256> buf{};
  const size_t n = buildMessage(buf, 1, 1.0, ship, order);
  auto message = std::make_unique<cigi::HostMessage>();
  uint64_t decoded = 0, ok = 0;
  const auto t0 = std::chrono::steady_clock::now();
  double elapsed = 0.0;
  do {
    for (int i = 0; i < 20000; ++i) ok += cigi::decodeHostMessage(std::span(buf.data(), n), *message) == cigi::CigiStatus::ok;
    decoded += 20000;
    elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  } while (elapsed < 0.5);
  return ok == decoded ? static_cast<double>(decoded) / elapsed : 0.0;
}

struct Sender {
  int fd = -1;
  sockaddr_in to{};
  explicit Sender(uint16_t port) {
    fd = ::socket(AF_INET, SOCK_DGRAM, 0);
    to.sin_family = AF_INET;
    to.sin_port = htons(port);
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  }
  ~Sender() {
    if (fd >= 0) ::close(fd);
  }
  bool send(std::span<const std::byte> b) const {
    return ::sendto(fd, b.data(), b.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof to) ==
           static_cast<ssize_t>(b.size());
  }
};

struct Run {
  std::unique_ptr<Service> service;
  uint16_t port = 0;
  ServiceConfig config;
  SceneConfig scene;
};

// 0, or the exit code of the failure: 2 a bad config (as igd), 3 a start-up failure.
int startService(const LatencyBenchOptions& opt, double seconds, const std::string& statsFile, Run& run) {
  Overrides o;
  if (opt.width_px > 0) o.width_px = opt.width_px;
  if (opt.height_px > 0) o.height_px = opt.height_px;
  o.statsFile = statsFile;
  o.snapshotEvery = 0;
  std::string error;
  if (!loadConfigs(opt.configFile, o, run.config, run.scene, error)) {
    std::fprintf(stderr, "igbench: %s\n", error.c_str());
    return 2;
  }
  run.config.snapshotFrames.clear();
  run.config.freeRun = false;
  run.config.frames = std::max<int64_t>(1, std::llround(seconds * run.config.rate_hz));
  run.config.host = HostSource::Cigi;
  run.config.recordFile = "";
  run.config.cigi.bind_address = "127.0.0.1";
  run.config.cigi.port = 0;  // any free port
  run.config.cigi.host_address = "127.0.0.1";
  run.config.cigi.host_port = 9;  // discard: nobody listens for the Start of Frame here
  const lod::Geodetic origin{run.scene.originGeodetic[0], run.scene.originGeodetic[1], run.scene.originGeodetic[2]};
  auto link = io::makeCigiLink(run.config.cigi, origin);
  io::CigiLink* raw = link.get();
  run.service = Service::create(run.config, run.scene, error, std::move(link));
  if (!run.service) {
    std::fprintf(stderr, "igbench: start-up failed: %s\n", error.c_str());
    return 3;
  }
  run.port = raw->localPort();
  return 0;
}

}  // namespace

int runLatencyBench(const LatencyBenchOptions& opt) {
  const auto tmp = std::filesystem::temp_directory_path() / ("igbench_latency_" + std::to_string(::getpid()));
  std::filesystem::create_directories(tmp);
  const std::string statsFile = (tmp / "stats.csv").string();

  // 1. Latency: the host sends at its own rate; each host frame's send time against the end
  //    of the first IG frame that rendered it.
  Run run;
  if (const int rc = startService(opt, opt.seconds, statsFile, run); rc != 0) return rc;
  const lod::Geodetic origin{run.scene.originGeodetic[0], run.scene.originGeodetic[1], run.scene.originGeodetic[2]};
  const Ownship ship(origin);
  MonotonicClock clock;
  std::vector<int64_t> sent_ns(static_cast<size_t>(opt.seconds * opt.hostRate_hz * 2 + 100), -1);
  std::atomic<bool> stopSender{false};
  std::thread host([&] {
    Sender s(run.port);
    std::array<std::byte, 256> buf{};
    const int64_t t0 = clock.now_ns();
    const int64_t period = static_cast<int64_t>(1e9 / opt.hostRate_hz);
    for (uint32_t f = 1; f < sent_ns.size() && !stopSender.load(); ++f) {
      clock.sleepUntil_ns(t0 + f * period);
      const size_t n = buildMessage(buf, f, static_cast<double>(f) / opt.hostRate_hz, ship, cigi::nativeByteOrder());
      sent_ns[f] = clock.now_ns();
      s.send(std::span(buf.data(), n));
    }
  });
  std::atomic<bool> stop{false};
  const int rc = run.service->run(clock, stop);
  stopSender = true;
  host.join();
  if (rc != 0) return 1;
  const RunSummary latencyRun = run.service->summary();
  const io::LinkCountersSnapshot latencyCounters = io::snapshot(run.service->hostLink()->counters());
  std::vector<double> latency_ms;
  {
    FILE* f = std::fopen(statsFile.c_str(), "r");
    if (f == nullptr) return 1;
    char line[1024];
    std::vector<std::string> header;
    if (std::fgets(line, sizeof line, f)) {
      std::string h(line);
      for (size_t a = 0, b; a < h.size(); a = b + 1) {
        b = std::min(h.find_first_of(",\n", a), h.size());
        header.push_back(h.substr(a, b - a));
      }
    }
    const auto col = [&](const char* name) {
      return static_cast<size_t>(std::find(header.begin(), header.end(), name) - header.begin());
    };
    const size_t cT = col("t_ms"), cW = col("work_ms"), cH = col("host_frame");
    uint64_t lastHost = 0;
    while (std::fgets(line, sizeof line, f)) {
      std::vector<double> v;
      for (char* p = line; *p;) {
        char* end = nullptr;
        v.push_back(std::strtod(p, &end));
        p = (*end == ',') ? end + 1 : end + std::strlen(end);
      }
      if (v.size() <= std::max({cT, cW, cH})) continue;
      const auto h = static_cast<uint64_t>(v[cH]);
      if (h == 0 || h == lastHost || h >= sent_ns.size() || sent_ns[h] < 0) continue;
      lastHost = h;
      const double end_ns = static_cast<double>(run.service->loopStart_ns()) + (v[cT] + v[cW]) * 1e6;
      latency_ms.push_back((end_ns - static_cast<double>(sent_ns[h])) * 1e-6);
    }
    std::fclose(f);
  }
  const std::string renderer = run.service->info().context;
  const double period_ms = 1000.0 / run.config.rate_hz;
  const int width = run.config.width_px, height = run.config.height_px;
  run.service.reset();

  // 2. Decode throughput, one core.
  const double decodeNative = decodeRate(ship, cigi::nativeByteOrder());
  const double decodeSwapped =
      decodeRate(ship, cigi::nativeByteOrder() == cigi::ByteOrder::big ? cigi::ByteOrder::little : cigi::ByteOrder::big);

  // 3. Flood: a loopback sender pushes valid messages at floodRate_pps while the IG renders.
  Run flood;
  if (const int floodRc = startService(opt, opt.floodSeconds, "", flood); floodRc != 0) return floodRc;
  std::atomic<uint64_t> floodSent{0};
  stopSender = false;
  std::thread flooder([&] {
    // The flood stands for traffic from other machines: here it shares the IG's two cores, so
    // it runs below the render threads (nice +10) and reports the rate it achieved.
    setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 10);
    Sender s(flood.port);
    std::array<std::byte, 256> buf{};
    const int64_t t0 = clock.now_ns();
    constexpr int kBatch = 100;  // packets per 1 ms tick at 100k/s
    const double perTick = opt.floodRate_pps / 1000.0;
    double owed = 0.0;
    uint32_t f = 1;
    for (int64_t tick = 1; !stopSender.load(); ++tick) {
      clock.sleepUntil_ns(t0 + tick * 1'000'000);
      owed += perTick;
      while (owed >= 1.0) {
        const int n = static_cast<int>(std::min<double>(owed, kBatch * 10));
        for (int i = 0; i < n; ++i, ++f) {
          const size_t len = buildMessage(buf, f, static_cast<double>(f) * 1e-5, ship, cigi::nativeByteOrder());
          if (s.send(std::span(buf.data(), len))) ++floodSent;
        }
        owed -= n;
      }
    }
  });
  const int64_t floodStart_ns = clock.now_ns();
  const int floodRc = flood.service->run(clock, stop);
  stopSender = true;
  const double floodElapsed_s = static_cast<double>(clock.now_ns() - floodStart_ns) * 1e-9;
  flooder.join();
  if (floodRc != 0) return 1;
  const RunSummary floodRun = flood.service->summary();
  const io::LinkCountersSnapshot floodCounters = io::snapshot(flood.service->hostLink()->counters());
  flood.service.reset();
  std::filesystem::remove_all(tmp);

  const double p50 = percentile(latency_ms, 50), p99 = percentile(latency_ms, 99);
  const double lmax = latency_ms.empty() ? 0.0 : *std::max_element(latency_ms.begin(), latency_ms.end());
  const double goal_ms = period_ms + latencyRun.workMs_p99;
  if (opt.json) {
    std::printf(
        "{\"suite\":\"latency\",\"renderer\":\"%s\",\"width_px\":%d,\"height_px\":%d,\"rate_hz\":%.3f,"
        "\"period_ms\":%.3f,\"host_rate_hz\":%.3f,\"samples\":%zu,\"latency_ms_p50\":%.3f,\"latency_ms_p99\":%.3f,"
        "\"latency_ms_max\":%.3f,\"render_ms_p50\":%.3f,\"render_ms_p99\":%.3f,\"latency_goal_ms\":%.3f,"
        "\"latency_run_overruns\":%lld,\"host_messages_received\":%llu,\"host_messages_accepted\":%llu,"
        "\"decode_msgs_per_s\":%.0f,\"decode_msgs_per_s_swapped\":%.0f,\"flood_rate_pps\":%.0f,"
        "\"flood_seconds\":%.1f,\"flood_rate_achieved_pps\":%.0f,\"flood_frames\":%lld,\"flood_overruns\":%lld,\"flood_frame_ms_p99\":%.3f,"
        "\"flood_packets_sent\":%llu,\"flood_packets_received\":%llu,\"flood_packets_accepted\":%llu}\n",
        jsonEscape(renderer).c_str(), width, height, 1000.0 / period_ms, period_ms, opt.hostRate_hz, latency_ms.size(), p50, p99,
        lmax, latencyRun.workMs_p50, latencyRun.workMs_p99, goal_ms, static_cast<long long>(latencyRun.overruns),
        static_cast<unsigned long long>(latencyCounters.received),
        static_cast<unsigned long long>(latencyCounters.accepted), decodeNative, decodeSwapped, opt.floodRate_pps,
        opt.floodSeconds, static_cast<double>(floodSent.load()) / floodElapsed_s, static_cast<long long>(floodRun.frames), static_cast<long long>(floodRun.overruns),
        floodRun.workMs_p99, static_cast<unsigned long long>(floodSent.load()),
        static_cast<unsigned long long>(floodCounters.received), static_cast<unsigned long long>(floodCounters.accepted));
  } else {
    std::printf("latency suite: %dx%d at %.1f Hz, %s\n", width, height, 1000.0 / period_ms, renderer.c_str());
    std::printf("  host at %.0f Hz over CIGI/UDP loopback: %zu host frames rendered\n", opt.hostRate_hz,
                latency_ms.size());
    std::printf("  packet sent -> end of the frame that used it: p50 %.2f ms, p99 %.2f ms, max %.2f ms\n", p50, p99,
                lmax);
    std::printf("  goal p99 <= period %.2f ms + render p99 %.2f ms = %.2f ms: %s\n", period_ms, latencyRun.workMs_p99,
                goal_ms, p99 <= goal_ms ? "met" : "NOT met");
    std::printf("  CIGI decode (IG Control + Entity Control): %.2f M msgs/s native order, %.2f M swapped\n",
                decodeNative * 1e-6, decodeSwapped * 1e-6);
    std::printf("  flood %.0f packets/s (achieved %.0f) for %.0f s: %llu sent, %llu received, %lld of %lld frames over "
                "budget (frame p99 %.2f ms; %lld over budget without the flood)\n",
                opt.floodRate_pps, static_cast<double>(floodSent.load()) / floodElapsed_s, opt.floodSeconds,
                static_cast<unsigned long long>(floodSent.load()),
                static_cast<unsigned long long>(floodCounters.received), static_cast<long long>(floodRun.overruns),
                static_cast<long long>(floodRun.frames), floodRun.workMs_p99,
                static_cast<long long>(latencyRun.overruns));
  }
  return 0;
}

#else

int runLatencyBench(const LatencyBenchOptions&) {
  std::fprintf(stderr, "igbench latency: this build has no CIGI link (IG_HOST_LINKS)\n");
  return 2;
}

#endif

}  // namespace ig
