// Runs inside user-mode Linux (tests/uml/init.sh starts it after loading vcan and can-raw and
// creating vcan0): starts the real CanLink on vcan0 and drives it with can-utils (cansend,
// canplayer, candump) and an independent python3-can sender that encodes from the DBC file.
// Writes <work>/result: "PASS" or "FAIL", then key=value lines the ctest wrapper asserts.
//
//   can_uml_probe <source dir> <work dir>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "io/can_link.h"
#include "io/can_map.h"
#include "scene_attitude.h"

using namespace ig::io;
using Clock = std::chrono::steady_clock;

namespace {

const ig::lod::Geodetic kOrigin{47.25, 11.35, 600.0};
std::vector<std::string> gFailures;
std::ostringstream gLog;

#define CHECK(cond, ...)                                                      \
  do {                                                                        \
    if (!(cond)) {                                                            \
      char msg_[512];                                                         \
      std::snprintf(msg_, sizeof msg_, __VA_ARGS__);                          \
      gFailures.push_back(std::string("line ") + std::to_string(__LINE__) + ": " + msg_); \
      std::fprintf(stderr, "probe: FAIL line %d: %s\n", __LINE__, msg_);      \
    }                                                                         \
  } while (0)

struct Sink : HostSink {
  std::mutex mutex;
  std::vector<HostState> states;
  void publish(const HostState& s) override {
    std::lock_guard<std::mutex> lock(mutex);
    states.push_back(s);
  }
  std::vector<HostState> copy() {
    std::lock_guard<std::mutex> lock(mutex);
    return states;
  }
};

bool waitFor(const std::function<bool()>& pred, double timeout_s = 10.0) {
  const auto end = Clock::now() + std::chrono::duration<double>(timeout_s);
  while (Clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return pred();
}

bool sh(const std::string& cmd) {
  const int rc = std::system(cmd.c_str());
  if (rc != 0) std::fprintf(stderr, "probe: command failed (%d): %s\n", rc, cmd.c_str());
  return rc == 0;
}

CanEyeSet makeSet(int k) {
  CanEyeSet s;
  s.lat_deg = 47.2612345 + 0.0001 * k;
  s.lon_deg = 11.3598765 - 0.0002 * k;
  s.height_m = 1523.456 + 0.5 * k;
  s.heading_deg = std::fmod(271.25 + 3.0 * k, 360.0);
  s.pitch_deg = -3.5 + 0.1 * k;
  s.roll_deg = 12.75 - 0.3 * k;
  s.simTime_s = 36000.125 + k / 60.0;
  s.hostFrame = static_cast<uint32_t>(5000 + k);
  return s;
}

std::string cansendArg(const CanFrame& f) {
  char buf[40];
  int n = std::snprintf(buf, sizeof buf, "%03X#", f.id);
  for (int i = 0; i < f.len; ++i) n += std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "%02X", f.data[static_cast<size_t>(i)]);
  return buf;
}

void cansend(const CanFrame& f) { CHECK(sh("cansend vcan0 " + cansendArg(f)), "cansend %s", cansendArg(f).c_str()); }

std::array<CanFrame, kCanFrameCount> frames(int k, uint8_t seq) {
  std::array<CanFrame, kCanFrameCount> f;
  encodeCanSet(makeSet(k), seq, 0x100, f);
  return f;
}

// The received state matches set k to the resolution of the map; the attitude as sent (true
// north at the eye) converted to kOrigin's axes, independently of igd (tests/scene_attitude.h).
void checkState(const HostState& s, int k, const char* what) {
  const CanEyeSet want = makeSet(k);
  const ig::test::SceneAttitude att = ig::test::sceneAttitude(kOrigin.lat_deg, kOrigin.lon_deg, s.lat_deg, s.lon_deg,
                                                              want.heading_deg, want.pitch_deg, want.roll_deg);
  const bool ok = std::fabs(s.lat_deg - want.lat_deg) <= 0.5e-7 && std::fabs(s.lon_deg - want.lon_deg) <= 0.5e-7 &&
                  std::fabs(s.height_m - want.height_m) <= 0.5e-3 &&
                  std::fabs(ig::test::headingDiff_deg(s.heading_deg, att.heading_deg)) <= 0.005 &&
                  std::fabs(s.pitch_deg - att.pitch_deg) <= 0.005 && std::fabs(s.roll_deg - att.roll_deg) <= 0.005 &&
                  std::fabs(s.simTime_s - want.simTime_s) <= 0.5e-3 && s.hostFrame == want.hostFrame;
  CHECK(ok, "%s: state (lat %.7f lon %.7f h %.3f hdg %.2f p %.2f r %.2f t %.3f frame %llu) != set %d", what,
        s.lat_deg, s.lon_deg, s.height_m, s.heading_deg, s.pitch_deg, s.roll_deg, s.simTime_s,
        static_cast<unsigned long long>(s.hostFrame), k);
  const glm::dvec3 enu = ig::lod::EnuFrame(kOrigin).fromGeodetic({s.lat_deg, s.lon_deg, s.height_m});
  CHECK(std::fabs(enu.x - s.eyeEnu_m.x) < 1e-6 && std::fabs(enu.y - s.eyeEnu_m.y) < 1e-6 &&
            std::fabs(enu.z - s.eyeEnu_m.z) < 1e-6,
        "%s: ENU eyepoint does not match lat/lon/height", what);
}

pid_t spawnCandump(const std::string& logPath) {
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = ::open(logPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0) _exit(127);
    dup2(fd, 1);
    execlp("candump", "candump", "-L", "vcan0", static_cast<char*>(nullptr));
    _exit(127);
  }
  return pid;
}

// candump has subscribed when the kernel lists a raw receiver for vcan0 in rx_all (the link's
// own filters are single-id entries in other lists).
bool candumpListening() {
  std::ifstream in("/proc/net/can/rcvlist_all");
  std::string line;
  while (std::getline(in, line))
    if (line.find("vcan0") != std::string::npos && line.find("raw") != std::string::npos) return true;
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: can_uml_probe <source dir> <work dir>\n");
    return 2;
  }
  const std::string src = argv[1], work = argv[2];
  const auto t0 = Clock::now();
  std::string error;
  Sink sink;

  // Start-up errors against the real kernel.
  {
    CanLinkConfig c;
    c.interface = "can9";
    CanLink link(c, kOrigin);
    CHECK(!link.start(sink, error) && error == "host.can.interface = can9: no such CAN interface", "can9: '%s'",
          error.c_str());
    c.interface = "lo";
    CanLink lo(c, kOrigin);
    CHECK(!lo.start(sink, error) && error == "host.can.interface = lo: not a CAN interface", "lo: '%s'", error.c_str());
  }

  const std::string candumpLog = work + "/candump.log";
  const pid_t candump = spawnCandump(candumpLog);
  CHECK(waitFor(candumpListening), "candump did not subscribe to vcan0");

  CanLinkConfig config;  // vcan0, base 0x100
  config.stale_ms = 3000;  // generous: a cansend process takes 50-200 ms inside UML, 5 of them a set
  CanLink link(config, kOrigin);
  if (!link.start(sink, error)) {
    std::ofstream(work + "/result") << "FAIL\nstart: " << error << "\n";
    kill(candump, SIGINT);
    return 1;
  }
  const LinkCounters& ctr = link.counters();
  auto accepted = [&] { return snapshot(ctr).accepted; };

  // A: three complete sets with cansend, the third in reverse order.
  for (int k = 0; k < 3; ++k) {
    auto f = frames(k, static_cast<uint8_t>(10 + k));
    if (k == 2) std::reverse(f.begin(), f.end());
    for (const CanFrame& fr : f) cansend(fr);
  }
  CHECK(waitFor([&] { return accepted() == 3; }), "A: accepted %llu, want 3",
        static_cast<unsigned long long>(accepted()));
  {
    const auto states = sink.copy();
    for (size_t k = 0; k < states.size() && k < 3; ++k) checkState(states[k], static_cast<int>(k), "A");
  }

  // B: an incomplete set dropped by a newer counter, a late frame, a stale lone frame.
  {
    const auto f13 = frames(3, 13);
    cansend(f13[0]);
    cansend(f13[1]);
    for (const CanFrame& fr : frames(4, 14)) cansend(fr);
    CHECK(waitFor([&] { return accepted() == 4; }), "B: set 14 not committed");
    cansend(f13[2]);  // older than the committed set 14, within stale_ms of it
    CHECK(waitFor([&] { return snapshot(ctr).late == 1; }), "B: late %llu, want 1",
          static_cast<unsigned long long>(snapshot(ctr).late));
    CHECK(snapshot(ctr).dropped == 1, "B: dropped %llu, want 1 (set 13)",
          static_cast<unsigned long long>(snapshot(ctr).dropped));
    const auto lone = Clock::now();
    cansend(frames(5, 15)[0]);
    CHECK(waitFor([&] { return snapshot(ctr).dropped == 2; }), "B: the lone frame of set 15 was not dropped as stale");
    const double staleAfter_s = std::chrono::duration<double>(Clock::now() - lone).count();
    gLog << "stale_drop_after_ms=" << static_cast<int>(staleAfter_s * 1000) << "\n";
    CHECK(staleAfter_s >= 2.9 && staleAfter_s < 8.0, "B: stale drop after %.3f s (stale_ms 3000)", staleAfter_s);
    const auto states = sink.copy();
    if (states.size() >= 4) checkState(states[3], 4, "B");
  }

  // C: malformed frames of the map, frames of other ids (filtered out), bus error frames.
  {
    const uint64_t received = snapshot(ctr).received;
    CHECK(sh("cansend vcan0 101#0011"), "cansend short");          // 2 bytes
    CHECK(sh("cansend vcan0 102#R"), "cansend remote");            // remote frame
    CHECK(sh("cansend vcan0 103##1" + std::string(16, '0')), "cansend fd");  // CAN FD, 8 bytes
    CHECK(sh("cansend vcan0 200#0011223344556677"), "cansend other");        // not in the map
    CHECK(sh("cansend vcan0 12345678#0011223344556677"), "cansend eff");      // 29-bit
    CHECK(waitFor([&] { return snapshot(ctr).malformed == 3; }), "C: malformed %llu, want 3",
          static_cast<unsigned long long>(snapshot(ctr).malformed));
    for (int i = 0; i < 3; ++i) CHECK(sh("cansend vcan0 20000004#0004000000000000"), "cansend error frame");
    CHECK(waitFor([&] { return link.busErrors() == 3; }), "C: bus errors %llu, want 3",
          static_cast<unsigned long long>(link.busErrors()));
    CHECK(snapshot(ctr).received == received + 3, "C: received grew by %llu, want 3 (other ids are filtered)",
          static_cast<unsigned long long>(snapshot(ctr).received - received));
  }

  // D: canplayer replays a candump log of 60 sets at 100 Hz.
  const int kPlayed = 60;
  {
    std::string log;
    for (int j = 0; j < kPlayed; ++j) {
      const auto f = frames(100 + j, static_cast<uint8_t>(16 + j));
      for (size_t i = 0; i < f.size(); ++i) {
        char ts[48];
        std::snprintf(ts, sizeof ts, "(%d.%06d) vcan0 ", 100 + j / 100, (j % 100) * 10000 + static_cast<int>(i) * 100);
        log += ts + cansendArg(f[i]) + "\n";
      }
    }
    std::ofstream(work + "/player.log") << log;
    const auto start = Clock::now();
    CHECK(sh("canplayer -I " + work + "/player.log"), "canplayer");
    CHECK(waitFor([&] { return accepted() == 4u + kPlayed; }), "D: accepted %llu, want %d",
          static_cast<unsigned long long>(accepted()), 4 + kPlayed);
    gLog << "canplayer_s=" << std::chrono::duration<double>(Clock::now() - start).count() << "\n";
    const auto states = sink.copy();
    for (int j = 0; j < kPlayed && 4 + j < static_cast<int>(states.size()); ++j)
      checkState(states[static_cast<size_t>(4 + j)], 100 + j, "D");
    // The same log converted offline gives the same states, bit for bit.
    Recording rec;
    CHECK(candumpToRecording(work + "/player.log", config, kOrigin, rec, error), "D: %s", error.c_str());
    CHECK(rec.samples.size() == static_cast<size_t>(kPlayed), "D: offline sets %zu", rec.samples.size());
    for (size_t j = 0; j < rec.samples.size() && 4 + j < states.size(); ++j) {
      const HostState& a = rec.samples[j].state;
      const HostState& b = states[4 + j];
      CHECK(a.lat_deg == b.lat_deg && a.lon_deg == b.lon_deg && a.height_m == b.height_m &&
                a.heading_deg == b.heading_deg && a.simTime_s == b.simTime_s && a.hostFrame == b.hostFrame &&
                a.eyeEnu_m == b.eyeEnu_m,
            "D: offline set %zu differs from the live one", j);
    }
    if (rec.samples.size() == static_cast<size_t>(kPlayed))
      CHECK(std::fabs(rec.samples.back().t_s - 0.59) < 1e-9, "D: last t_s %.6f, want 0.59", rec.samples.back().t_s);
  }

  // E: an independent sender (python3-can) that encodes physical values from the DBC file.
  {
    const std::string cmd = "/usr/bin/python3 " + src + "/tests/can_dbc_send.py " + src +
                            "/config/igd_host.dbc vcan0 76 EyeLatitude=-33.8688197 EyeLongitude=151.2092955 "
                            "EyeHeight=-12.5 Heading=359.99 Pitch=-90 Roll=180 SimTime=4000000.001 HostFrame=16777215 "
                            "Visibility=10000000 TimeOfDay=86399.99";
    CHECK(sh(cmd), "python3-can sender");
    CHECK(waitFor([&] { return accepted() == 5u + kPlayed; }), "E: set from the DBC sender not committed");
    const auto states = sink.copy();
    if (states.size() == static_cast<size_t>(5 + kPlayed)) {
      const HostState& s = states.back();
      // Heading 359.99, pitch -90, roll 180 at the eye in Sydney, in the axes of kOrigin.
      const ig::test::SceneAttitude att =
          ig::test::sceneAttitude(kOrigin.lat_deg, kOrigin.lon_deg, -33.8688197, 151.2092955, 359.99, -90.0, 180.0);
      CHECK(std::fabs(s.lat_deg + 33.8688197) < 1e-9 && std::fabs(s.lon_deg - 151.2092955) < 1e-9 &&
                std::fabs(s.height_m + 12.5) < 1e-9 &&
                std::fabs(ig::test::headingDiff_deg(s.heading_deg, att.heading_deg)) < 1e-9 &&
                std::fabs(s.pitch_deg - att.pitch_deg) < 1e-9 && std::fabs(s.roll_deg - att.roll_deg) < 1e-9 &&
                std::fabs(s.simTime_s - 4000000.001) < 1e-6 &&
                s.hostFrame == 16777215u && s.visibility_m == 1e7 &&
                std::fabs(s.timeOfDay_h - 86399.99 / 3600.0) < 1e-9,
            "E: DBC-encoded set decoded as lat %.7f lon %.7f h %.3f hdg %.2f p %.2f r %.2f t %.3f frame %llu vis %.1f",
            s.lat_deg, s.lon_deg, s.height_m, s.heading_deg, s.pitch_deg, s.roll_deg, s.simTime_s,
            static_cast<unsigned long long>(s.hostFrame), s.visibility_m);
    }
  }

  // Stop: the receive thread joins within a poll period.
  const auto stopStart = Clock::now();
  link.stop();
  const double stop_ms = std::chrono::duration<double, std::milli>(Clock::now() - stopStart).count();
  CHECK(stop_ms < 500.0, "stop took %.1f ms", stop_ms);

  // The real candump's log of everything above, through the same assembler.
  kill(candump, SIGINT);
  int status = 0;
  waitpid(candump, &status, 0);
  CandumpStats stats;
  Recording rec;
  CHECK(candumpToRecording(candumpLog, config, kOrigin, rec, error, &stats), "candump log: %s", error.c_str());
  const auto states = sink.copy();
  CHECK(rec.samples.size() == states.size(), "candump log: %zu sets, the live link %zu", rec.samples.size(),
        states.size());
  for (size_t j = 0; j < rec.samples.size() && j < states.size(); ++j)
    CHECK(rec.samples[j].state.hostFrame == states[j].hostFrame && rec.samples[j].state.lat_deg == states[j].lat_deg,
          "candump log: set %zu differs", j);

  const auto c = snapshot(ctr);
  std::ofstream out(work + "/result");
  out << (gFailures.empty() ? "PASS" : "FAIL") << "\n";
  out << "received=" << c.received << "\naccepted=" << c.accepted << "\nmalformed=" << c.malformed
      << "\nout_of_range=" << c.outOfRange << "\nlate=" << c.late << "\ndropped=" << c.dropped
      << "\nbus_errors=" << link.busErrors() << "\ncandump_sets=" << rec.samples.size()
      << "\ncandump_lines=" << stats.lines << "\nstop_ms=" << stop_ms
      << "\nprobe_s=" << std::chrono::duration<double>(Clock::now() - t0).count() << "\n"
      << gLog.str();
  for (const std::string& f : gFailures) out << "failure: " << f << "\n";
  return gFailures.empty() ? 0 : 1;
}
