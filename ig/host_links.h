// Builds the live host link a service config names ([host] source = "cigi", "can",
// "modbus-tcp" or "modbus-rtu") from its [host.<link>] table.
#pragma once

#include <memory>
#include <string>

#include "ig/config.h"
#include "io/link.h"
#include "lod/geo.h"

namespace ig {

// true for the sources that are live links (not "none" or "replay").
bool isLinkSource(HostSource source);

// The link's own checks of its [host.<link>] table (io/*_link.h: addresses that parse or resolve,
// a baud rate the serial line takes), without opening anything; true for sources that are not
// links. The error's key is "host.<link>.<key>" (or "host.source" when this build has no such
// link). The config loader runs it, so --check-config finds such a value.
bool validateHostLinkConfig(const ServiceConfig& config, io::LinkConfigError& error);

// The link, not yet started; nullptr and an error naming the key on failure.
std::unique_ptr<io::HostLink> makeHostLink(const ServiceConfig& config, const lod::Geodetic& origin,
                                           std::string& error);

}  // namespace ig
