// CIGI 3.3 host link: the message assembler (pure) and the UDP transport.
#include "io/cigi_link.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstring>

#include <glm/geometric.hpp>
#include <glm/matrix.hpp>

namespace ig::io {
namespace {

constexpr size_t kRxBytes = 65536;         // one slot holds the largest IPv4 UDP datagram
constexpr unsigned kRxSlots = 8;           // datagrams per recvmmsg call
constexpr int kPollTimeout_ms = 50;
constexpr int kMaxBatchesPerWake = 32;     // then check the stop flag again

std::string errnoText(int e) { return std::strerror(e); }

// Resolves an IPv4 address or host name (start-up only; may block on DNS).
bool resolveIpv4(const std::string& host, in_addr& out) {
  if (inet_pton(AF_INET, host.c_str(), &out) == 1) return true;
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* res = nullptr;
  if (getaddrinfo(host.c_str(), nullptr, &hints, &res) != 0 || !res) return false;
  out = reinterpret_cast<const sockaddr_in*>(res->ai_addr)->sin_addr;
  freeaddrinfo(res);
  return true;
}

uint64_t packAddress(const sockaddr_in& a) {
  return (static_cast<uint64_t>(ntohl(a.sin_addr.s_addr)) << 16) | ntohs(a.sin_port) | (1ull << 48);
}
sockaddr_in unpackAddress(uint64_t v) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(static_cast<uint32_t>((v >> 16) & 0xffffffffu));
  a.sin_port = htons(static_cast<uint16_t>(v & 0xffffu));
  return a;
}

}  // namespace

bool validateCigiLinkConfig(const CigiLinkConfig& c, LinkConfigError& error) {
  auto fail = [&](const char* key, const std::string& value, const char* why) {
    error = {std::string("host.cigi.") + key, value, why};
    return false;
  };
  in_addr a{};
  if (inet_pton(AF_INET, c.bind_address.c_str(), &a) != 1)
    return fail("bind_address", "'" + c.bind_address + "'", "not an IPv4 address (e.g. \"0.0.0.0\")");
  if (c.port < 0 || c.port > 65535) return fail("port", std::to_string(c.port), "must be 1..65535");
  if (c.host_port < 0 || c.host_port > 65535) return fail("host_port", std::to_string(c.host_port), "must be 1..65535 (0: reply to the source port)");
  if (!c.host_address.empty() && !resolveIpv4(c.host_address, a))
    return fail("host_address", "'" + c.host_address + "'", "not an IPv4 address or known host name");
  if (!c.host_address.empty() && c.host_port == 0)
    return fail("host_port", "0", "a fixed host_address needs a port (1..65535)");
  if (c.entity_id < 0 || c.entity_id > 65535) return fail("entity_id", std::to_string(c.entity_id), "must be 0..65535");
  if (c.view_id < 0 || c.view_id > 65535) return fail("view_id", std::to_string(c.view_id), "must be 0..65535");
  if (c.database < -1 || c.database > 127) return fail("database", std::to_string(c.database), "must be -1 (any) or 0..127");
  return true;
}

bool validateCigiLinkConfig(const CigiLinkConfig& config, std::string& error) {
  LinkConfigError e;
  if (validateCigiLinkConfig(config, e)) return true;
  error = e.message();
  return false;
}

// ---------------------------------------------------------------------------------------------
// Assembler

EyePose cigiEyePose(const lod::Geodetic& entity, double yaw_deg, double pitch_deg, double roll_deg,
                    const glm::dvec3& offsetBody_m, double viewYaw_deg, double viewPitch_deg, double viewRoll_deg) {
  const glm::dmat3 ned = lod::nedToEcef(entity.lat_deg, entity.lon_deg);
  const glm::dmat3 body = ned * lod::bodyToNed(yaw_deg, pitch_deg, roll_deg);
  // The common case, a view looking straight along the entity's nose, skips the second rotation.
  const bool viewRotated = viewYaw_deg != 0.0 || viewPitch_deg != 0.0 || viewRoll_deg != 0.0;
  const glm::dmat3 view = viewRotated ? body * lod::bodyToNed(viewYaw_deg, viewPitch_deg, viewRoll_deg) : body;
  EyePose p;
  p.ecef_m = lod::geodeticToEcef(entity) + body * offsetBody_m;
  p.forwardEcef = view[0];
  p.rightEcef = view[1];
  p.downEcef = view[2];
  return p;
}

CigiAssembler::CigiAssembler(const CigiAssemblerConfig& config, const lod::Geodetic& origin)
    : config_(config), enu_(origin) {
  near_m_ = state_.near_m;
  far_m_ = state_.far_m;
  top_deg_ = 0.5 * state_.fovY_deg;
  bottom_deg_ = -0.5 * state_.fovY_deg;
  if (config_.database > 0) database_ = static_cast<int8_t>(config_.database);
}

bool CigiAssembler::isLate(const cigi::IgControl& ig) {
  if (!started_) return false;
  const int32_t frameStep = static_cast<int32_t>(ig.hostFrame - lastFrame_);
  bool late = frameStep < 0;
  if (frameStep == 0 && ig.timestampValid && haveTimestamp_)
    late = static_cast<int32_t>(ig.timestamp_10us - lastTimestamp_) < 0;
  if (!late) {
    lateInARow_ = 0;
    return false;
  }
  const bool bigJump = frameStep < 0 && static_cast<uint32_t>(-static_cast<int64_t>(frameStep)) >= kRestartFrameGap;
  if (bigJump || ++lateInARow_ >= kRestartAfterLate) {
    started_ = false;  // host restart: the sequence starts over with this message
    haveTimestamp_ = false;
    lateInARow_ = 0;
    return false;
  }
  return true;
}

CigiAssembler::Result CigiAssembler::apply(std::span<const std::byte> datagram, LinkCounters& counters) {
  cigi::HostMessageFilter filter;
  filter.entityId = config_.entityId;
  filter.viewId = config_.viewId;
  if (cigi::decodeHostMessage(datagram, msg_, filter) != cigi::CigiStatus::ok) {
    counters.malformed.fetch_add(1, std::memory_order_relaxed);
    return Result::malformed;
  }
  const cigi::IgControl& ig = msg_.igControl;
  if (isLate(ig)) {
    counters.late.fetch_add(1, std::memory_order_relaxed);
    return Result::late;
  }
  // Frame and time, unwrapped across the 32-bit wrap.
  if (!started_) {
    frame64_ = ig.hostFrame;
    started_ = true;
  } else {
    frame64_ += static_cast<uint32_t>(ig.hostFrame - lastFrame_);
  }
  lastFrame_ = ig.hostFrame;
  if (ig.timestampValid) {
    if (!haveTimestamp_) {
      timestamp64_ = ig.timestamp_10us;
      haveTimestamp_ = true;
    } else {
      timestamp64_ += static_cast<int32_t>(ig.timestamp_10us - lastTimestamp_);
    }
    lastTimestamp_ = ig.timestamp_10us;
    state_.simTime_s = static_cast<double>(timestamp64_) * 1e-5;
  }
  state_.hostFrame = frame64_;
  hostMode_ = ig.igMode;
  if (ig.databaseNumber != 0) {
    if (config_.database >= 0 && ig.databaseNumber != config_.database) {
      counters.outOfRange.fetch_add(1, std::memory_order_relaxed);  // igd has only its own database
    } else if (config_.database < 0 && ig.databaseNumber > 0) {
      database_ = ig.databaseNumber;
    }
  }

  for (size_t i = 0; i < msg_.entityCount; ++i) applyEntity(msg_.entities[i], counters);
  for (size_t i = 0; i < msg_.viewControlCount; ++i) applyView(msg_.viewControls[i], counters);
  for (size_t i = 0; i < msg_.viewDefinitionCount; ++i) applyViewDefinition(msg_.viewDefinitions[i], counters);
  if (msg_.hasCelestial) applyCelestial(msg_.celestial, counters);
  if (msg_.hasAtmosphere) applyAtmosphere(msg_.atmosphere, counters);
  checkHatHot(counters);
  checkLos(counters);

  counters.accepted.fetch_add(1, std::memory_order_relaxed);
  if (!hasPosition()) return Result::accepted;
  computeEye();
  return Result::published;
}

void CigiAssembler::applyEntity(const cigi::EntityControl& e, LinkCounters& counters) {
  if (e.attached) {  // an ownship attached to a parent entity is not supported
    counters.outOfRange.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  const uint32_t bad = cigi::validateEntity(e);
  counters.outOfRange.fetch_add(static_cast<uint64_t>(std::popcount(bad)), std::memory_order_relaxed);
  if (!(bad & cigi::kEntityRoll)) roll_deg_ = static_cast<double>(e.roll_deg);
  if (!(bad & cigi::kEntityPitch)) pitch_deg_ = static_cast<double>(e.pitch_deg);
  if (!(bad & cigi::kEntityYaw)) yaw_deg_ = static_cast<double>(e.yaw_deg);
  if (!(bad & cigi::kEntityLat)) lat_deg_ = e.lat_deg, hasLat_ = true;
  if (!(bad & cigi::kEntityLon)) lon_deg_ = e.lon_deg, hasLon_ = true;
  if (!(bad & cigi::kEntityAlt)) alt_m_ = e.alt_m, hasAlt_ = true;
}

void CigiAssembler::applyView(const cigi::ViewControl& v, LinkCounters& counters) {
  if (v.entityId != config_.entityId) {  // igd's view follows the ownship only
    counters.outOfRange.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  const uint32_t bad = cigi::validateViewControl(v);
  counters.outOfRange.fetch_add(static_cast<uint64_t>(std::popcount(bad)), std::memory_order_relaxed);
  auto ok = [&](uint8_t enable, uint32_t field) { return (v.enable & enable) && !(bad & field); };
  if (ok(cigi::ViewControl::kX, cigi::kViewX)) viewOffset_m_[0] = static_cast<double>(v.x_m);
  if (ok(cigi::ViewControl::kY, cigi::kViewY)) viewOffset_m_[1] = static_cast<double>(v.y_m);
  if (ok(cigi::ViewControl::kZ, cigi::kViewZ)) viewOffset_m_[2] = static_cast<double>(v.z_m);
  if (ok(cigi::ViewControl::kRoll, cigi::kViewRoll)) viewRoll_deg_ = static_cast<double>(v.roll_deg);
  if (ok(cigi::ViewControl::kPitch, cigi::kViewPitch)) viewPitch_deg_ = static_cast<double>(v.pitch_deg);
  if (ok(cigi::ViewControl::kYaw, cigi::kViewYaw)) viewYaw_deg_ = static_cast<double>(v.yaw_deg);
}

void CigiAssembler::applyViewDefinition(const cigi::ViewDefinition& d, LinkCounters& counters) {
  const uint32_t bad = cigi::validateViewDefinition(d);
  // Pairs, with the current value standing in for a disabled or rejected field.
  const bool nearOk = (d.enable & cigi::ViewDefinition::kNear) && !(bad & cigi::kViewNear);
  const bool farOk = (d.enable & cigi::ViewDefinition::kFar) && !(bad & cigi::kViewFar);
  const double near_m = nearOk ? static_cast<double>(d.near_m) : near_m_, far_m = farOk ? static_cast<double>(d.far_m) : far_m_;
  int pairsRejected = 0;  // a rejected pair counts once
  if ((nearOk || farOk) && !(near_m < far_m)) {
    ++pairsRejected;
  } else {
    near_m_ = near_m;
    far_m_ = far_m;
  }
  const bool topOk = (d.enable & cigi::ViewDefinition::kTop) && !(bad & cigi::kViewTop);
  const bool bottomOk = (d.enable & cigi::ViewDefinition::kBottom) && !(bad & cigi::kViewBottom);
  const double top = topOk ? static_cast<double>(d.top_deg) : top_deg_, bottom = bottomOk ? static_cast<double>(d.bottom_deg) : bottom_deg_;
  // An edge at +-90 deg has no finite tangent: the window needs -90 < bottom < top < 90.
  if ((topOk || bottomOk) && !(bottom < top && bottom > -90.0 && top < 90.0)) {
    ++pairsRejected;
  } else {
    top_deg_ = top;
    bottom_deg_ = bottom;
  }
  // Left and right set the window's width and horizontal centre (an asymmetric frustum). Before
  // the first pair a lone left or right stands with its mirror image (the window was centred).
  const bool leftOk = (d.enable & cigi::ViewDefinition::kLeft) && !(bad & cigi::kViewLeft);
  const bool rightOk = (d.enable & cigi::ViewDefinition::kRight) && !(bad & cigi::kViewRight);
  if (leftOk || rightOk) {
    const double givenL = static_cast<double>(d.left_deg), givenR = static_cast<double>(d.right_deg);
    const double left = leftOk ? givenL : hasLeftRight_ ? left_deg_ : -givenR;
    const double right = rightOk ? givenR : hasLeftRight_ ? right_deg_ : -givenL;
    if (!(left < right && left > -90.0 && right < 90.0)) {
      ++pairsRejected;
    } else {
      left_deg_ = left;
      right_deg_ = right;
      hasLeftRight_ = true;
    }
  }
  counters.outOfRange.fetch_add(static_cast<uint64_t>(std::popcount(bad) + pairsRejected), std::memory_order_relaxed);
}

void CigiAssembler::applyCelestial(const cigi::CelestialSphereControl& c, LinkCounters& counters) {
  if (!c.dateTimeValid) return;  // hour, minute and date are not meant to apply
  const uint32_t bad = cigi::validateCelestial(c) & (cigi::kCelestialTime | cigi::kCelestialDate);
  counters.outOfRange.fetch_add(static_cast<uint64_t>(std::popcount(bad)), std::memory_order_relaxed);
  if (!(bad & cigi::kCelestialTime)) state_.timeOfDay_h = c.hour + c.minute / 60.0;
  if (!(bad & cigi::kCelestialDate)) state_.dateYmd = cigi::dateToYmd(c.date_mmddyyyy);
}

void CigiAssembler::applyAtmosphere(const cigi::AtmosphereControl& a, LinkCounters& counters) {
  if (cigi::validateAtmosphere(a) & cigi::kAtmosphereVisibility) {
    counters.outOfRange.fetch_add(1, std::memory_order_relaxed);  // the last good visibility stays
    return;
  }
  // 0 (nothing visible) and huge values or infinity (a host's "unlimited") are meant: clamped to
  // what the fog can show, 1 m ... 10,000 km.
  state_.visibility_m = std::clamp(static_cast<double>(a.visibility_m), kMinVisibility_m, kMaxVisibility_m);
}

void CigiAssembler::checkHatHot(LinkCounters& counters) {
  for (size_t i = 0; i < msg_.hatHotCount; ++i) {
    const cigi::HatHotRequest& r = msg_.hatHotRequests[i];
    uint32_t bad = cigi::validateHatHotRequest(r);
    if (r.entityCoordinates && r.entityId != config_.entityId) bad |= kHatHotUnknownEntity;
    hatHotBad_[i] = bad;
    counters.outOfRange.fetch_add(static_cast<uint64_t>(std::popcount(bad)), std::memory_order_relaxed);
  }
}

void CigiAssembler::checkLos(LinkCounters& counters) {
  for (size_t i = 0; i < msg_.losCount; ++i) {
    const cigi::LosRequest& r = msg_.losRequests[i];
    uint32_t bad = cigi::validateLosRequest(r);
    const bool entity = r.sourceEntity || (r.kind == cigi::LosRequest::kSegment && r.destinationEntity) ||
                        (r.extended && r.responseEntity);
    if (entity && r.entityId != config_.entityId) bad |= kLosUnknownEntity;
    losBad_[i] = bad;
    counters.outOfRange.fetch_add(static_cast<uint64_t>(std::popcount(bad)), std::memory_order_relaxed);
  }
}

void CigiAssembler::computeEye() {
  const EyePose pose = cigiEyePose({lat_deg_, lon_deg_, alt_m_}, yaw_deg_, pitch_deg_, roll_deg_,
                                   {viewOffset_m_[0], viewOffset_m_[1], viewOffset_m_[2]}, viewYaw_deg_,
                                   viewPitch_deg_, viewRoll_deg_);
  state_.eyeEnu_m = enu_.toEnu(pose.ecef_m);
  // Without an eye offset the eye is the entity itself: no ECEF -> geodetic iteration needed.
  const bool offset = viewOffset_m_[0] != 0.0 || viewOffset_m_[1] != 0.0 || viewOffset_m_[2] != 0.0;
  const lod::Geodetic g = offset ? lod::ecefToGeodetic(pose.ecef_m) : lod::Geodetic{lat_deg_, lon_deg_, alt_m_};
  state_.lat_deg = g.lat_deg;
  state_.lon_deg = g.lon_deg;
  state_.height_m = g.height_m;
  // Attitude in the scene's ENU axes (lod::viewRotation's convention), the same conversion as
  // the CAN link's (lod::EnuFrame::attitudeFromGeodetic).
  const lod::Attitude att = enu_.attitudeFromEcef(pose.forwardEcef, pose.rightEcef);
  state_.heading_deg = att.heading_deg;
  state_.pitch_deg = att.pitch_deg;
  state_.roll_deg = att.roll_deg;
  // The window in tangent units (lod::Camera's convention): a symmetric one keeps fovy = top - bottom exactly.
  constexpr double kRad = 3.14159265358979323846 / 180.0;
  const double t = std::tan(top_deg_ * kRad), b = std::tan(bottom_deg_ * kRad);
  state_.fovY_deg = top_deg_ == -bottom_deg_ ? top_deg_ - bottom_deg_ : 2.0 * std::atan(0.5 * (t - b)) / kRad;
  state_.windowShiftY = top_deg_ == -bottom_deg_ ? 0.0 : 0.5 * (t + b);
  if (hasLeftRight_) {
    const double l = std::tan(left_deg_ * kRad), r = std::tan(right_deg_ * kRad);
    state_.windowShiftX = left_deg_ == -right_deg_ ? 0.0 : 0.5 * (r + l);
    state_.windowWidth_tan = r - l;
  }
  state_.near_m = near_m_;
  state_.far_m = far_m_;
  state_.hasOwnship = true;
  state_.ownshipLat_deg = lat_deg_;
  state_.ownshipLon_deg = lon_deg_;
  state_.ownshipAlt_m = alt_m_;
  state_.ownshipYaw_deg = yaw_deg_;
  state_.ownshipPitch_deg = pitch_deg_;
  state_.ownshipRoll_deg = roll_deg_;
}

// ---------------------------------------------------------------------------------------------
// HAT/HOT

namespace {
// A terrain normal (unit, scene ENU) at `enuPoint`, as CIGI's HAT/HOT and LOS Extended Responses
// give it: azimuth from true north, clockwise, and elevation above the local horizontal at
// lat_deg / lon_deg (the point's geodetic position).
void normalAngles(const lod::EnuFrame& enu, const glm::dvec3& enuPoint, const glm::dvec3& normal, double lat_deg,
                  double lon_deg, float& azimuth_deg, float& elevation_deg) {
  const glm::dvec3 nEcef = enu.toEcef(enuPoint + normal) - enu.toEcef(enuPoint);
  const glm::dvec3 nNed = glm::transpose(lod::nedToEcef(lat_deg, lon_deg)) * nEcef;
  const double len = glm::length(nNed);
  constexpr double kDeg = 180.0 / 3.14159265358979323846;
  azimuth_deg = static_cast<float>(std::atan2(nNed.y, nNed.x) * kDeg);
  elevation_deg = static_cast<float>(std::asin(std::clamp(-nNed.z / len, -1.0, 1.0)) * kDeg);
}
}  // namespace

HatHotAnswer computeHatHot(const cigi::HatHotRequest& r, const lod::EnuFrame& enu, double originHeight_m,
                           const QueryScene& scene, const HostState* host) {
  HatHotAnswer a;
  const lod::HeightGrid* terrain = scene.terrain;
  if (!terrain) return a;
  lod::Geodetic point{r.lat_deg, r.lon_deg, r.alt_m};
  bool hasAltitude = r.requestType != cigi::HatHotRequest::kHot;
  if (r.entityCoordinates) {
    if (!host || !host->hasOwnship) return a;
    const lod::Geodetic own{host->ownshipLat_deg, host->ownshipLon_deg, host->ownshipAlt_m};
    const glm::dmat3 body = lod::nedToEcef(own.lat_deg, own.lon_deg) *
                            lod::bodyToNed(host->ownshipYaw_deg, host->ownshipPitch_deg, host->ownshipRoll_deg);
    point = lod::ecefToGeodetic(lod::geodeticToEcef(own) + body * glm::dvec3(r.lat_deg, r.lon_deg, r.alt_m));
    hasAltitude = true;
  }
  // The terrain is drawn in the ENU plane: find the grid point under (lat, lon) at a guessed
  // height, take the surface there back to geodetic; then again at the height found (the ENU up
  // axis leans from the local vertical by distance / earth radius, so the guess matters a little).
  double guess_m = hasAltitude ? point.height_m : originHeight_m;
  lod::GroundSample ground;
  glm::dvec3 surface{0.0}, normal{0.0, 0.0, 1.0};
  for (int pass = 0; pass < 2; ++pass) {
    const glm::dvec3 p = enu.fromGeodetic({point.lat_deg, point.lon_deg, guess_m});
    ++a.work;
    if (!lod::sampleGround(*terrain, p.x, p.y, ground)) return a;
    surface = {p.x, p.y, ground.height_m};
    normal = ground.normal;
    guess_m = enu.toGeodetic(surface).height_m;
  }
  if (!std::isfinite(guess_m)) return a;
  if (scene.objects != nullptr) {
    // Down the ENU vertical to the terrain: from the requested point (HAT, extended), or from
    // above every object (HOT). (The ENU up axis leans from the local vertical by distance /
    // earth radius: 1.6 mrad 10 km from the origin, 3 cm over a 20 m building.)
    const double from_m = hasAltitude ? enu.fromGeodetic(point).z : scene.objects->top_m() + 1.0;
    SurfaceHit hit;
    if (from_m > surface.z && std::isfinite(from_m) &&
        scene.objects->intersect({surface.x, surface.y, from_m}, surface, kHeightSurfaces, hit, &a.work)) {
      const double height_m = enu.toGeodetic(hit.point_m).height_m;
      if (std::isfinite(height_m)) {
        surface = hit.point_m;
        normal = hit.normal;
        guess_m = height_m;
        a.materialCode = hit.material;
      }
    }
  }
  a.valid = true;
  a.hot_m = guess_m;
  a.hat_m = hasAltitude ? point.height_m - a.hot_m : 0.0;
  normalAngles(enu, surface, normal, point.lat_deg, point.lon_deg, a.normalAzimuth_deg, a.normalElevation_deg);
  return a;
}

LosAnswer computeLos(const cigi::LosRequest& r, const lod::EnuFrame& enu, const QueryScene& scene,
                     const HostState* host) {
  LosAnswer a;
  const lod::HeightGrid* terrain = scene.terrain;
  if (!terrain) return a;
  const bool segment = r.kind == cigi::LosRequest::kSegment;
  const bool needOwnship = r.sourceEntity || (segment && r.destinationEntity) || (r.extended && r.responseEntity);
  glm::dmat3 body(1.0);
  glm::dvec3 ownEcef(0.0);
  if (needOwnship) {
    if (!host || !host->hasOwnship) return a;
    body = lod::nedToEcef(host->ownshipLat_deg, host->ownshipLon_deg) *
           lod::bodyToNed(host->ownshipYaw_deg, host->ownshipPitch_deg, host->ownshipRoll_deg);
    ownEcef = lod::geodeticToEcef({host->ownshipLat_deg, host->ownshipLon_deg, host->ownshipAlt_m});
  }
  auto toEcef = [&](bool entity, double x, double y, double z) {
    return entity ? ownEcef + body * glm::dvec3(x, y, z) : lod::geodeticToEcef({x, y, z});
  };
  const glm::dvec3 source = toEcef(r.sourceEntity, r.srcLat_deg, r.srcLon_deg, r.srcAlt_m);
  glm::dvec3 from = source, to{0.0};
  double range0_m = 0.0;
  if (segment) {
    to = toEcef(r.destinationEntity, r.dstLat_deg, r.dstLon_deg, r.dstAlt_m);
  } else {
    // Azimuth from true north and elevation above the local horizontal, at the source point.
    const lod::Geodetic g = r.sourceEntity ? lod::ecefToGeodetic(source) : lod::Geodetic{r.srcLat_deg, r.srcLon_deg, r.srcAlt_m};
    constexpr double kRad = 3.14159265358979323846 / 180.0;
    const double az = static_cast<double>(r.azimuth_deg) * kRad, el = static_cast<double>(r.elevation_deg) * kRad;
    const glm::dvec3 dir = lod::nedToEcef(g.lat_deg, g.lon_deg) *
                           glm::dvec3(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), -std::sin(el));
    range0_m = static_cast<double>(r.minRange_m);
    from = source + dir * range0_m;
    to = source + dir * static_cast<double>(r.maxRange_m);
  }
  const glm::dvec3 fromEnu = enu.toEnu(from), toEnu = enu.toEnu(to);
  const double length_m = glm::length(toEnu - fromEnu);
  if (!std::isfinite(length_m)) return a;
  // The host's material mask: bit n registers hits with material code n (0 terrain, 1 object,
  // 2 tree); 0 (what most hosts send) registers every surface.
  const SurfaceMask mask = r.materialMask != 0 ? r.materialMask : kSightSurfaces;
  lod::GroundHit hit;
  bool found = (mask & surfaceBit(kSurfaceTerrain)) && lod::intersectGround(*terrain, fromEnu, toEnu, hit, &a.cells);
  if (scene.objects != nullptr && (mask & (kSightSurfaces & ~surfaceBit(kSurfaceTerrain)))) {
    // An object before the terrain hit (or anywhere along the segment when there is none).
    SurfaceHit o;
    const glm::dvec3 end = found ? hit.point_m : toEnu;
    if (scene.objects->intersect(fromEnu, end, mask, o, &a.cells)) {
      const double t = found ? o.t * hit.t : o.t;
      hit.t = t;
      hit.point_m = o.point_m;
      hit.normal = o.normal;
      found = true;
      a.materialCode = o.material;
    }
  }
  if (!found) {
    a.visible = segment;  // nothing in the way (no terrain along it, or none above it, and no object)
    return a;
  }
  const double along_m = hit.t * length_m;
  const lod::Geodetic g = enu.toGeodetic(hit.point_m);
  if (!std::isfinite(g.lat_deg) || !std::isfinite(g.lon_deg) || !std::isfinite(g.height_m)) return a;
  a.valid = true;
  a.visible = segment && along_m >= length_m - 1e-3;  // the destination itself lies on the ground
  a.range_m = range0_m + along_m;
  if (r.responseEntity) {
    const glm::dvec3 offset = glm::transpose(body) * (enu.toEcef(hit.point_m) - ownEcef);
    a.lat_deg = offset.x;
    a.lon_deg = offset.y;
    a.alt_m = offset.z;
  } else {
    a.lat_deg = g.lat_deg;
    a.lon_deg = g.lon_deg;
    a.alt_m = g.height_m;
  }
  normalAngles(enu, hit.point_m, hit.normal, g.lat_deg, g.lon_deg, a.normalAzimuth_deg, a.normalElevation_deg);
  return a;
}

CigiHatHotResponder::CigiHatHotResponder(const lod::Geodetic& origin) : enu_(origin), originHeight_m_(origin.height_m) {}

size_t CigiHatHotResponder::Job::responseSize() const {
  if (los) return losJob.request.extended ? cigi::kLosExtendedResponseSize : cigi::kLosResponseSize;
  return hatHot.request.requestType == cigi::HatHotRequest::kExtended ? cigi::kHatHotExtendedResponseSize
                                                                      : cigi::kHatHotResponseSize;
}

bool CigiHatHotResponder::push(const Job& job) {
  if (pendingCount_ == kMaxPending) return false;
  pending_[(pendingHead_ + pendingCount_) % kMaxPending] = job;
  ++pendingCount_;
  if (job.los) ++pendingLos_;
  return true;
}

void CigiHatHotResponder::add(const HatHotJob& job, uint32_t igFrame) {
  Job j;
  j.hatHot = job;
  addJob(j, igFrame);
}

void CigiHatHotResponder::add(const LosJob& job, uint32_t igFrame) {
  Job j;
  j.los = true;
  j.losJob = job;
  addJob(j, igFrame);
}

void CigiHatHotResponder::addJob(const Job& job, uint32_t igFrame) {
  const uint8_t period = job.period();
  size_t same = periodicCount_;
  for (size_t i = 0; i < periodicCount_; ++i)
    if (periodic_[i].job.los == job.los && periodic_[i].job.id() == job.id()) same = i;
  if (period == 0 || job.bad() != 0) {
    if (period == 0 && same < periodicCount_) periodic_[same] = periodic_[--periodicCount_];  // cancel
  } else if (same < periodicCount_) {
    periodic_[same] = {job, igFrame + period};
  } else if (periodicCount_ < kMaxPeriodic) {
    periodic_[periodicCount_++] = {job, igFrame + period};
  } else {
    refuse(job);  // no room to hold it: answered this once
  }
  if (!push(job)) refuse(job);
}

size_t CigiHatHotResponder::answer(uint32_t igFrame, uint32_t lastHostFrame, const QueryScene& scene,
                                   const HostState* host, cigi::ByteOrder order, std::span<std::byte> out) {
  assert(out.size() >= kMaxBytesPerFrame && "CigiHatHotResponder::answer: output span too small");
  for (size_t i = 0; i < periodicCount_; ++i) {
    Periodic& p = periodic_[i];
    // Due (serial arithmetic: IG frame numbers wrap); a full queue leaves it due for the next frame.
    if (static_cast<int32_t>(igFrame - p.nextDue) >= 0 && push(p.job)) p.nextDue = igFrame + p.job.period();
  }
  const uint8_t lsn = static_cast<uint8_t>(lastHostFrame & 0x0f);
  size_t bytes = 0, n = 0, nLos = 0;
  uint32_t work = 0;
  for (; n < kMaxAnswersPerFrame && pendingCount_ > 0; ++n) {
    const Job& next = pending_[pendingHead_];
    if (bytes + next.responseSize() > kMaxBytesPerFrame) break;  // the datagram is full
    if (work >= kMaxQueryWorkPerFrame) break;                      // this frame's query work is spent
    const Job any = next;
    pendingHead_ = (pendingHead_ + 1) % kMaxPending;
    --pendingCount_;
    if (any.los) {
      --pendingLos_;
      ++nLos;
      const cigi::LosRequest& r = any.losJob.request;
      const LosAnswer a = any.losJob.bad == 0 ? computeLos(r, enu_, scene, host) : LosAnswer{};
      work += a.cells;
      if (r.extended) {
        cigi::LosExtendedResponse x;
        x.losId = r.losId;
        x.valid = a.valid;
        x.rangeValid = a.valid;
        x.visible = a.visible;
        x.hostFrameLsn = lsn;
        x.range_m = a.range_m;
        x.lat_deg = a.lat_deg;
        x.lon_deg = a.lon_deg;
        x.alt_m = a.alt_m;
        x.materialCode = a.materialCode;
        x.normalAzimuth_deg = a.normalAzimuth_deg;
        x.normalElevation_deg = a.normalElevation_deg;
        bytes += cigi::encode(x, order, out.subspan(bytes));
      } else {
        cigi::LosResponse x;
        x.losId = r.losId;
        x.valid = a.valid;
        x.visible = a.visible;
        x.hostFrameLsn = lsn;
        x.range_m = a.range_m;
        bytes += cigi::encode(x, order, out.subspan(bytes));
      }
      continue;
    }
    const HatHotJob& job = any.hatHot;
    const cigi::HatHotRequest& r = job.request;
    const HatHotAnswer a = job.bad == 0 ? computeHatHot(r, enu_, originHeight_m_, scene, host) : HatHotAnswer{};
    work += a.work;
    if (r.requestType == cigi::HatHotRequest::kExtended) {
      cigi::HatHotExtendedResponse x;
      x.hatHotId = r.hatHotId;
      x.valid = a.valid;
      x.hostFrameLsn = lsn;
      x.hat_m = a.hat_m;
      x.hot_m = a.hot_m;
      x.materialCode = a.materialCode;
      x.normalAzimuth_deg = a.normalAzimuth_deg;
      x.normalElevation_deg = a.normalElevation_deg;
      bytes += cigi::encode(x, order, out.subspan(bytes));
    } else {
      cigi::HatHotResponse x;
      x.hatHotId = r.hatHotId;
      x.valid = a.valid;
      x.hot = r.requestType == cigi::HatHotRequest::kHot;
      x.hostFrameLsn = lsn;
      x.height_m = x.hot ? a.hot_m : a.hat_m;
      bytes += cigi::encode(x, order, out.subspan(bytes));
    }
  }
  answered_.fetch_add(n - nLos, std::memory_order_relaxed);
  losAnswered_.fetch_add(nLos, std::memory_order_relaxed);
  if (pendingCount_ > pendingLos_) deferred_.fetch_add(pendingCount_ - pendingLos_, std::memory_order_relaxed);
  if (pendingLos_ > 0) losDeferred_.fetch_add(pendingLos_, std::memory_order_relaxed);
  return bytes;
}

// ---------------------------------------------------------------------------------------------
// UDP transport

CigiLink::CigiLink(const CigiLinkConfig& config, const lod::Geodetic& origin)
    : config_(config),
      assembler_(std::make_unique<CigiAssembler>(
          CigiAssemblerConfig{static_cast<uint16_t>(config.entity_id), static_cast<uint16_t>(config.view_id),
                              config.database},
          origin)),
      responder_(origin) {}

CigiLink::~CigiLink() { stop(); }

bool CigiLink::start(HostSink& sink, std::string& error) {
  if (fd_ >= 0) {
    error = "cigi link already started";
    return false;
  }
  if (!validateCigiLinkConfig(config_, error)) return false;
  in_addr bindAddr{};
  inet_pton(AF_INET, config_.bind_address.c_str(), &bindAddr);
  const std::string where = config_.bind_address + ":" + std::to_string(config_.port);
  if (!config_.host_address.empty()) {
    sockaddr_in h{};
    h.sin_family = AF_INET;
    resolveIpv4(config_.host_address, h.sin_addr);
    h.sin_port = htons(static_cast<uint16_t>(config_.host_port));
    fixedReply_ = packAddress(h);
    reply_.store(fixedReply_);
  }
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    error = "cannot open a UDP socket for " + where + ": " + errnoText(errno);
    return false;
  }
  const int rcvbuf = 4 << 20;  // absorbs bursts while the thread is descheduled
  setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr = bindAddr;
  a.sin_port = htons(static_cast<uint16_t>(config_.port));
  if (bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) {
    error = "cannot bind " + where + ": " + errnoText(errno);
    close(fd);
    return false;
  }
  socklen_t len = sizeof a;
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  localPort_ = ntohs(a.sin_port);
  rx_ = std::make_unique<std::byte[]>(kRxBytes * kRxSlots);
  fd_ = fd;
  sink_ = &sink;
  database_.store(assembler_->database());
  stopping_.store(false);
  thread_ = std::thread([this] { run(); });
  return true;
}

void CigiLink::stop() {
  stopping_.store(true);
  if (thread_.joinable()) thread_.join();
  if (fd_ >= 0) {
    close(fd_);
    fd_ = -1;
  }
}

void CigiLink::run() {
  lowerLinkThreadPriority();
  // One recvmmsg call reads up to kRxSlots datagrams: under a packet flood the thread spends
  // its time decoding, not in system calls.
  mmsghdr msgs[kRxSlots];
  iovec iov[kRxSlots];
  sockaddr_in src[kRxSlots];
  while (!stopping_.load(std::memory_order_relaxed)) {
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, kPollTimeout_ms) <= 0) continue;
    for (int batch = 0; batch < kMaxBatchesPerWake; ++batch) {
      for (unsigned i = 0; i < kRxSlots; ++i) {
        iov[i] = {rx_.get() + i * kRxBytes, kRxBytes};
        msgs[i] = {};
        msgs[i].msg_hdr.msg_iov = &iov[i];
        msgs[i].msg_hdr.msg_iovlen = 1;
        msgs[i].msg_hdr.msg_name = &src[i];
        msgs[i].msg_hdr.msg_namelen = sizeof src[i];
      }
      const int got = recvmmsg(fd_, msgs, kRxSlots, MSG_DONTWAIT, nullptr);
      if (got <= 0) break;  // EAGAIN: drained (other errors: try again after the next poll)
      for (int i = 0; i < got; ++i) handleDatagram(iov[i].iov_base, msgs[i].msg_len, msgs[i].msg_hdr.msg_flags, src[i]);
      if (got < static_cast<int>(kRxSlots)) break;
    }
  }
}

void CigiLink::handleDatagram(const void* data, size_t size, int flags, sockaddr_in src) {
  counters_.received.fetch_add(1, std::memory_order_relaxed);
  if ((flags & MSG_TRUNC) != 0) {  // cannot happen with IPv4 UDP; be safe
    counters_.malformed.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  const auto result = assembler_->apply(std::span<const std::byte>(static_cast<const std::byte*>(data), size), counters_);
  if (result == CigiAssembler::Result::malformed || result == CigiAssembler::Result::late) return;
  if (fixedReply_ == 0) {
    if (config_.host_port != 0) src.sin_port = htons(static_cast<uint16_t>(config_.host_port));
    reply_.store(packAddress(src), std::memory_order_relaxed);
  }
  lastHostFrame_.store(assembler_->lastHostFrame(), std::memory_order_relaxed);
  hostMode_.store(static_cast<int>(assembler_->hostIgMode()), std::memory_order_relaxed);
  database_.store(assembler_->database(), std::memory_order_relaxed);
  // HAT/HOT requests go to the frame loop, which answers them after its Start of Frame.
  const CigiAssembler::HatHotJobs jobs = assembler_->hatHotJobs();
  if (!jobs.requests.empty() || assembler_->lastMessage().hatHotOmitted > 0) {
    hatHotRequests_.fetch_add(jobs.requests.size() + assembler_->lastMessage().hatHotOmitted, std::memory_order_relaxed);
    responder_.countRefused(assembler_->lastMessage().hatHotOmitted);
    for (size_t i = 0; i < jobs.requests.size(); ++i) {
      const size_t tail = hatHotTail_.load(std::memory_order_relaxed);
      if (tail - hatHotHead_.load(std::memory_order_acquire) == kHatHotQueue) {
        responder_.countRefused(jobs.requests.size() - i);
        break;
      }
      hatHotRing_[tail % kHatHotQueue] = {jobs.requests[i], jobs.bad[i]};
      hatHotTail_.store(tail + 1, std::memory_order_release);
    }
  }
  const CigiAssembler::LosJobs los = assembler_->losJobs();
  if (!los.requests.empty() || assembler_->lastMessage().losOmitted > 0) {
    losRequests_.fetch_add(los.requests.size() + assembler_->lastMessage().losOmitted, std::memory_order_relaxed);
    responder_.countLosRefused(assembler_->lastMessage().losOmitted);
    for (size_t i = 0; i < los.requests.size(); ++i) {
      const size_t tail = losTail_.load(std::memory_order_relaxed);
      if (tail - losHead_.load(std::memory_order_acquire) == kLosQueue) {
        responder_.countLosRefused(los.requests.size() - i);
        break;
      }
      losRing_[tail % kLosQueue] = {los.requests[i], los.bad[i]};
      losTail_.store(tail + 1, std::memory_order_release);
    }
  }
  if (result == CigiAssembler::Result::published) {
    // Counted before it is visible: whoever saw the state published (a test waiting on the
    // sink) and then starts a frame finds it counted. A frame that starts between the two
    // counts a state it does not render yet, so `dropped` may undercount by one then.
    publishedSinceFrame_.fetch_add(1, std::memory_order_relaxed);
    sink_->publish(assembler_->state());
  }
}

void CigiLink::frameStarted(const FrameStart& frame) {
  // Samples published since the previous frame, beyond the one this frame renders, were
  // overwritten in the mailbox unseen.
  const uint32_t published = publishedSinceFrame_.exchange(0, std::memory_order_relaxed);
  if (published > 1) counters_.dropped.fetch_add(published - 1, std::memory_order_relaxed);

  const uint64_t reply = reply_.load(std::memory_order_relaxed);
  if (fd_ < 0 || reply == 0) return;  // nowhere to send yet
  cigi::StartOfFrame sof;
  sof.databaseNumber = static_cast<int8_t>(database_.load(std::memory_order_relaxed));
  sof.igStatus = frame.hostLost ? kStatusHostLost : frame.overrun ? kStatusOverrun : kStatusNormal;
  sof.igMode = frame.hostLost ? cigi::IgMode::standby : cigi::IgMode::operate;
  sof.timestampValid = true;
  sof.igFrame = frame.igFrame;
  const double ticks = std::max(0.0, frame.time_s) * 1e5;
  sof.timestamp_10us = static_cast<uint32_t>(static_cast<uint64_t>(std::fmod(ticks, 4294967296.0)));
  sof.lastHostFrame = lastHostFrame_.load(std::memory_order_relaxed);
  size_t n = cigi::encode(sof, cigi::nativeByteOrder(), tx_);
  // HAT/HOT and LOS responses follow in the same datagram. Nothing to do (the common case): four loads.
  const size_t tail = hatHotTail_.load(std::memory_order_acquire);
  size_t head = hatHotHead_.load(std::memory_order_relaxed);
  const size_t losTail = losTail_.load(std::memory_order_acquire);
  size_t losHead = losHead_.load(std::memory_order_relaxed);
  if (head != tail || losHead != losTail || !responder_.idle()) {
    for (; head != tail; ++head) responder_.add(hatHotRing_[head % kHatHotQueue], frame.igFrame);
    hatHotHead_.store(head, std::memory_order_release);
    for (; losHead != losTail; ++losHead) responder_.add(losRing_[losHead % kLosQueue], frame.igFrame);
    losHead_.store(losHead, std::memory_order_release);
    n += responder_.answer(frame.igFrame, sof.lastHostFrame, QueryScene(frame.terrain, frame.objects), frame.host, cigi::nativeByteOrder(),
                           std::span(tx_).subspan(n));
  }
  const sockaddr_in to = unpackAddress(reply);
  if (sendto(fd_, tx_.data(), n, MSG_DONTWAIT | MSG_NOSIGNAL, reinterpret_cast<const sockaddr*>(&to), sizeof to) ==
      static_cast<ssize_t>(n)) {
    sofSent_.fetch_add(1, std::memory_order_relaxed);
  } else {
    sendErrors_.fetch_add(1, std::memory_order_relaxed);
  }
}

std::string CigiLink::extraCounters() const {
  std::string s;
  if (hatHotRequests() > 0)
    s += " hat_hot_requests " + std::to_string(hatHotRequests()) + " hat_hot_answered " + std::to_string(hatHotAnswered()) +
         " hat_hot_refused " + std::to_string(hatHotRefused()) + " hat_hot_deferred " + std::to_string(hatHotDeferred());
  if (losRequests() > 0)
    s += " los_requests " + std::to_string(losRequests()) + " los_answered " + std::to_string(losAnswered()) +
         " los_refused " + std::to_string(losRefused()) + " los_deferred " + std::to_string(losDeferred());
  return s;
}

std::unique_ptr<CigiLink> makeCigiLink(const CigiLinkConfig& config, const lod::Geodetic& origin) {
  return std::make_unique<CigiLink>(config, origin);
}

int cigiHostIgMode(const HostLink& link) {
  const auto* cigiLink = dynamic_cast<const CigiLink*>(&link);
  return cigiLink ? cigiLink->hostIgMode() : -1;
}

}  // namespace ig::io
