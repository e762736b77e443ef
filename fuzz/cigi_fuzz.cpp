// libFuzzer target for the CIGI decoders: host messages (both byte orders), Start of Frame, the
// assembler (field validation, late / restart logic, eye computation) and the pcap reader.
// Property checked beyond "no crash, no UB, no leak": a message that decodes re-decodes to the
// same IG Control after re-encoding it in the other byte order.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <span>

#include "io/cigi.h"
#include "io/cigi_link.h"
#include "io/pcap.h"

using namespace ig::io;

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
  (void)assembler->apply(bytes, counters);
  // The same bytes as a capture file.
  std::string error;
  (void)parsePcapUdp(bytes, "fuzz.pcap", [&](const UdpDatagram& d) { (void)assembler->apply(d.payload, counters); },
                     error);
  return 0;
}
