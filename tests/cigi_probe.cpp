// Test driver for tests/cigi_interop_test.py: runs igd's CIGI link alone (no renderer) or the
// pcap converter, and prints what it decoded, one line per sample, for a script to compare.
//
//   cigi_probe link <host_port> <lat,lon,h>   bind 127.0.0.1 on a free port, print "PORT <p>",
//       send Start of Frame to 127.0.0.1:<host_port> every 10 ms (host lost -> Standby until the
//       first sample), print "SAMPLE ..." per published sample; exit when stdin closes
//       (or after 60 s), printing "COUNTERS ...". HAT/HOT requests are answered from a
//       synthetic terrain: 41 x 41 posts 100 m apart around the origin, the plane
//       z = 30 + 0.03 east - 0.02 north (ENU metres; tests/cigi_interop_test.py knows it).
//   cigi_probe pcap <file> <port> <lat,lon,h>  convert a capture; print SAMPLE lines and COUNTERS.
//
// SAMPLE t_s host_frame sim_time_s east_m north_m up_m lat_deg lon_deg height_m heading_deg
//        pitch_deg roll_deg fovy_deg near_m far_m time_of_day_h date_ymd visibility_m
#include <poll.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <string>
#include <vector>

#include "io/cigi_link.h"
#include "io/pcap.h"

using namespace ig::io;

namespace {

void printSample(double t_s, const HostState& s) {
  std::printf("SAMPLE %.6f %llu %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %d %.17g\n",
              t_s, static_cast<unsigned long long>(s.hostFrame), s.simTime_s, s.eyeEnu_m.x, s.eyeEnu_m.y,
              s.eyeEnu_m.z, s.lat_deg, s.lon_deg, s.height_m, s.heading_deg, s.pitch_deg, s.roll_deg, s.fovY_deg,
              s.near_m, s.far_m, s.timeOfDay_h, s.dateYmd, s.visibility_m);
  std::fflush(stdout);
}

void printCounters(const LinkCountersSnapshot& c, uint64_t sof, uint64_t sendErrors) {
  std::printf("COUNTERS received=%llu accepted=%llu malformed=%llu out_of_range=%llu late=%llu dropped=%llu sof=%llu send_errors=%llu\n",
              static_cast<unsigned long long>(c.received), static_cast<unsigned long long>(c.accepted),
              static_cast<unsigned long long>(c.malformed), static_cast<unsigned long long>(c.outOfRange),
              static_cast<unsigned long long>(c.late), static_cast<unsigned long long>(c.dropped),
              static_cast<unsigned long long>(sof), static_cast<unsigned long long>(sendErrors));
  std::fflush(stdout);
}

bool parseOrigin(const char* s, ig::lod::Geodetic& g) {
  return std::sscanf(s, "%lf,%lf,%lf", &g.lat_deg, &g.lon_deg, &g.height_m) == 3;
}

class PrintSink : public HostSink {
 public:
  void publish(const HostState& s) override {
    std::lock_guard<std::mutex> lock(m_);
    printSample(0.0, s);
    ++count_;
  }
  uint64_t count() {
    std::lock_guard<std::mutex> lock(m_);
    return count_;
  }

 private:
  std::mutex m_;
  uint64_t count_ = 0;
};

int runLink(int hostPort, const ig::lod::Geodetic& origin) {
  CigiLinkConfig cfg;
  cfg.bind_address = "127.0.0.1";
  cfg.port = 0;
  cfg.host_address = "127.0.0.1";
  cfg.host_port = hostPort;
  auto link = makeCigiLink(cfg, origin);
  PrintSink sink;
  std::string error;
  if (!link->start(sink, error)) {
    std::fprintf(stderr, "cigi_probe: %s\n", error.c_str());
    return 1;
  }
  std::printf("PORT %u\n", link->localPort());
  std::fflush(stdout);
  std::vector<float> heights;
  for (int y = 0; y < 41; ++y)
    for (int x = 0; x < 41; ++x) heights.push_back(static_cast<float>(30.0 + 0.03 * (-2000.0 + 100.0 * x) - 0.02 * (-2000.0 + 100.0 * y)));
  const ig::lod::HeightGrid terrain{heights, 41, 41, 100.0, {-2000.0, -2000.0, 0.0}};
  const auto t0 = std::chrono::steady_clock::now();
  FrameStart f;
  f.terrain = &terrain;
  for (;;) {
    const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (t > 60.0) break;
    f.time_s = t;
    f.hostLost = sink.count() == 0;
    link->frameStarted(f);
    ++f.igFrame;
    pollfd in{0, POLLIN, 0};
    if (poll(&in, 1, 10) > 0) {
      char buf[256];
      if (read(0, buf, sizeof buf) <= 0) break;  // stdin closed: done
    }
  }
  link->stop();
  printCounters(snapshot(link->counters()), link->startOfFramesSent(), link->sendErrors());
  std::printf("HATHOT%s\n", link->extraCounters().c_str());
  return 0;
}

int runPcap(const char* file, int port, const ig::lod::Geodetic& origin) {
  Recording r;
  std::string error;
  LinkCountersSnapshot c;
  const bool ok = cigiPcapToRecording(file, static_cast<uint16_t>(port), origin, r, error, {}, &c);
  if (!ok) {
    std::fprintf(stderr, "cigi_probe: %s\n", error.c_str());
    return 1;
  }
  for (const HostSample& s : r.samples) printSample(s.t_s, s.state);
  printCounters(c, 0, 0);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  ig::lod::Geodetic origin;
  if (argc == 4 && std::string(argv[1]) == "link" && parseOrigin(argv[3], origin))
    return runLink(std::atoi(argv[2]), origin);
  if (argc == 5 && std::string(argv[1]) == "pcap" && parseOrigin(argv[4], origin))
    return runPcap(argv[2], std::atoi(argv[3]), origin);
  std::fprintf(stderr, "usage: cigi_probe link <host_port> <lat,lon,h> | cigi_probe pcap <file> <port> <lat,lon,h>\n");
  return 2;
}
