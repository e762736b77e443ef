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

// The link, not yet started; nullptr and an error naming the key on failure.
std::unique_ptr<io::HostLink> makeHostLink(const ServiceConfig& config, const lod::Geodetic& origin,
                                           std::string& error);

}  // namespace ig
