#include "ig/host_links.h"

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

std::unique_ptr<io::HostLink> makeHostLink(const ServiceConfig& config, const lod::Geodetic& /*origin*/,
                                           std::string& error) {
  error = std::string("host.source = \"") + toString(config.host) + "\": this link is not built yet";
  return nullptr;
}

}  // namespace ig
