// libFuzzer target for the CIGI decoders: host messages (both byte orders), Start of Frame, the
// assembler (field validation, late / restart logic, eye computation), the HAT/HOT answers to
// the requests it accepted (computeHatHot and the responder's queue, on a small terrain grid,
// every other input with an object on it: io::SceneSurfaces), the LOS answers likewise
// (computeLos, lod::intersectGround) and the pcap reader.
// Properties checked beyond "no crash, no UB, no leak": a message that decodes re-decodes to the
// same IG Control after re-encoding it in the other byte order; the assembler's visibility is
// never NaN or above 1e7 m; a valid HAT/HOT answer is
// finite with its normal's elevation in [0, 90] degrees; a valid LOS answer is finite, its range
// within the segment / vector, its normal's elevation in [0, 90] on the terrain and in [-90, 90]
// on an object (seen from below); a frame's answers fit their buffer and one 1,472-byte datagram.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cmath>
#include <cstring>
#include <memory>
#include <span>
#include <vector>

#include "io/cigi.h"
#include "io/cigi_link.h"
#include "io/pcap.h"
#include "lod/geo.h"
#include "lod/heightfield.h"

using namespace ig::io;

namespace {

// A 100 x 100 x 60 m block standing on the grid around the origin (ENU z 100 ... 160), as an
// [hdlod] layer would answer for it: the segment's entry into the box (slab test), the entry
// face's normal facing the start. A segment starting inside the box meets nothing.
struct Block final : SceneSurfaces {
  glm::dvec3 lo{-50.0, -50.0, 100.0}, hi{50.0, 50.0, 160.0};
  bool intersect(const glm::dvec3& from, const glm::dvec3& to, SurfaceMask mask, SurfaceHit& hit,
                 uint32_t* work) const override {
    if (work) ++*work;
    if (!(mask & surfaceBit(kSurfaceObject))) return false;
    const glm::dvec3 d = to - from;
    double t0 = 0.0, t1 = 1.0;
    int axis = -1;
    for (int a = 0; a < 3; ++a) {
      if (!std::isfinite(d[a]) || !std::isfinite(from[a])) return false;
      if (d[a] == 0.0) {
        if (from[a] < lo[a] || from[a] > hi[a]) return false;
        continue;
      }
      double ta = (lo[a] - from[a]) / d[a], tb = (hi[a] - from[a]) / d[a];
      if (ta > tb) std::swap(ta, tb);
      if (ta > t0) t0 = ta, axis = a;
      t1 = std::min(t1, tb);
      if (t0 > t1) return false;
    }
    if (axis < 0) return false;  // starts inside
    hit.t = t0;
    hit.point_m = from + d * t0;
    hit.normal = glm::dvec3(0.0);
    hit.normal[axis] = d[axis] > 0.0 ? -1.0 : 1.0;
    hit.material = kSurfaceObject;
    return true;
  }
  double top_m() const override { return hi.z; }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static auto message = std::make_unique<cigi::HostMessage>();
  static auto assembler = std::make_unique<CigiAssembler>(CigiAssemblerConfig{}, ig::lod::Geodetic{45.0, 7.0, 0.0});
  static LinkCounters counters;
  const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(data), size);

  if (cigi::decodeHostMessage(bytes, *message) == cigi::CigiStatus::ok) {
    if (message->entityCount > cigi::HostMessage::kMaxEntities) std::abort();
    std::byte buf[cigi::kIgControlSize];
    const cigi::ByteOrder other =
        message->byteOrder == cigi::ByteOrder::big ? cigi::ByteOrder::little : cigi::ByteOrder::big;
    cigi::encode(message->igControl, other, buf);
    cigi::HostMessage again;
    if (cigi::decodeHostMessage(buf, again) != cigi::CigiStatus::ok) std::abort();
    if (again.igControl.hostFrame != message->igControl.hostFrame ||
        again.igControl.timestamp_10us != message->igControl.timestamp_10us ||
        again.igControl.databaseNumber != message->igControl.databaseNumber || again.byteOrder != other)
      std::abort();
  }
  cigi::StartOfFrame sof;
  (void)cigi::decodeStartOfFrame(bytes, sof);
  // The assembler keeps state across inputs, like a long-running link.
  const CigiAssembler::Result applied = assembler->apply(bytes, counters);
  // The host's visibility is "not given" or a checked one (Atmosphere Control).
  if (const double vis = assembler->state().visibility_m; std::isnan(vis) || vis > 1e7) std::abort();

  // HAT/HOT: the accepted message's requests answered over a 1 km grid of sloped terrain around
  // the origin, as the frame loop answers them (the responder keeps its queue across inputs).
  static const ig::lod::Geodetic origin{45.0, 7.0, 0.0};
  static const ig::lod::EnuFrame enu(origin);
  static const std::vector<float> heights = [] {
    std::vector<float> h(33 * 33);
    for (size_t i = 0; i < h.size(); ++i) h[i] = 100.0f + 3.0f * static_cast<float>(i % 33) - 2.0f * static_cast<float>(i / 33);
    return h;
  }();
  static const ig::lod::HeightGrid grid{heights, 33, 33, 31.25, glm::dvec3(-500.0, -500.0, 0.0)};
  static auto responder = std::make_unique<CigiHatHotResponder>(origin);
  static const Block block;
  static uint32_t igFrame = 0;
  const QueryScene scene(&grid, igFrame % 2 == 0 ? &block : nullptr);
  static std::byte answers[CigiHatHotResponder::kMaxBytesPerFrame];
  if (applied == CigiAssembler::Result::accepted || applied == CigiAssembler::Result::published) {
    const HostState* host = assembler->hasPosition() ? &assembler->state() : nullptr;
    const CigiAssembler::HatHotJobs jobs = assembler->hatHotJobs();
    for (size_t i = 0; i < jobs.requests.size(); ++i) {
      if (jobs.bad[i] == 0) {
        const HatHotAnswer a = computeHatHot(jobs.requests[i], enu, origin.height_m, scene, host);
        if (a.valid && (!std::isfinite(a.hat_m) || !std::isfinite(a.hot_m) || !std::isfinite(a.normalAzimuth_deg) ||
                        !(a.normalElevation_deg >= 0.0f && a.normalElevation_deg <= 90.0f)))
          std::abort();
      }
      responder->add({jobs.requests[i], jobs.bad[i]}, igFrame);
    }
    const CigiAssembler::LosJobs los = assembler->losJobs();
    for (size_t i = 0; i < los.requests.size(); ++i) {
      const cigi::LosRequest& r = los.requests[i];
      if (los.bad[i] == 0) {
        const LosAnswer a = computeLos(r, enu, scene, host);
        const float lowest = a.materialCode == kMaterialObject ? -90.0f : 0.0f;
        // Segments are at most ~2e6 m long (validated points); vectors end at the maximum range.
        const double maxRange = r.kind == cigi::LosRequest::kVector ? static_cast<double>(r.maxRange_m) + 1e-3 : 1e8;
        if (a.valid && (!std::isfinite(a.range_m) || a.range_m < 0.0 || a.range_m > maxRange || !std::isfinite(a.lat_deg) ||
                        !std::isfinite(a.lon_deg) || !std::isfinite(a.alt_m) || !std::isfinite(a.normalAzimuth_deg) ||
                        !(a.normalElevation_deg >= lowest && a.normalElevation_deg <= 90.0f)))
          std::abort();
      }
      responder->add(LosJob{r, los.bad[i]}, igFrame);
    }
    const size_t n = responder->answer(igFrame, assembler->lastHostFrame(), scene, host,
                                       static_cast<cigi::ByteOrder>(igFrame % 2), answers);
    if (n > sizeof answers || cigi::kStartOfFrameSize + n > 1472) std::abort();
    ++igFrame;
  }
  // The same bytes as a capture file.
  std::string error;
  (void)parsePcapUdp(bytes, "fuzz.pcap", [&](const UdpDatagram& d) { (void)assembler->apply(d.payload, counters); },
                     error);
  return 0;
}
