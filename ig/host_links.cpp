#include "ig/host_links.h"

#if IG_LINK_CIGI
#include "io/cigi_link.h"
#endif
#if IG_LINK_CAN
#include "io/can_link.h"
#endif
#if IG_LINK_MODBUS
#include "io/modbus_link.h"
#endif

namespace ig {

bool isLinkSource(HostSource source) {
  switch (source) {
    case HostSource::None:
    case HostSource::Replay: return false;
    case HostSource::Cigi:
    case HostSource::Can:
    case HostSource::ModbusTcp:
    case HostSource::ModbusRtu: return true;
  }
  return false;
}

bool validateHostLinkConfig(const ServiceConfig& config, io::LinkConfigError& error) {
  switch (config.host) {
    case HostSource::None:
    case HostSource::Replay: return true;
#if IG_LINK_CIGI
    case HostSource::Cigi: return io::validateCigiLinkConfig(config.cigi, error);
#endif
#if IG_LINK_CAN
    case HostSource::Can: return io::validateCanLinkConfig(config.can, error);
#endif
#if IG_LINK_MODBUS
    case HostSource::ModbusTcp: return io::validateModbusLinkConfig(config.modbus, io::ModbusTransport::Tcp, error);
    case HostSource::ModbusRtu: return io::validateModbusLinkConfig(config.modbus, io::ModbusTransport::Rtu, error);
#endif
    default: break;
  }
  error = {"host.source", std::string("\"") + toString(config.host) + "\"",
           "this build has no such host link (configure with -DIG_HOST_LINKS=\"cigi;can;modbus\")"};
  return false;
}

std::unique_ptr<io::HostLink> makeHostLink(const ServiceConfig& config, const lod::Geodetic& origin,
                                           std::string& error) {
  [[maybe_unused]] const auto& o = origin;
  switch (config.host) {
#if IG_LINK_CIGI
    case HostSource::Cigi:
      if (!io::validateCigiLinkConfig(config.cigi, error)) return nullptr;
      return io::makeCigiLink(config.cigi, o);
#endif
#if IG_LINK_CAN
    case HostSource::Can:
      if (!io::validateCanLinkConfig(config.can, error)) return nullptr;
      return io::makeCanLink(config.can, o);
#endif
#if IG_LINK_MODBUS
    case HostSource::ModbusTcp:
      if (!io::validateModbusLinkConfig(config.modbus, io::ModbusTransport::Tcp, error)) return nullptr;
      return io::makeModbusTcpLink(config.modbus, o);
    case HostSource::ModbusRtu:
      if (!io::validateModbusLinkConfig(config.modbus, io::ModbusTransport::Rtu, error)) return nullptr;
      return io::makeModbusRtuLink(config.modbus, o);
#endif
    default: break;
  }
  error = std::string("host.source = \"") + toString(config.host) +
          "\": this build has no such host link (configure with -DIG_HOST_LINKS=\"cigi;can;modbus\")";
  return nullptr;
}

}  // namespace ig
