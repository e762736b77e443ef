// igtool: offline tools around igd — render one frame to PNG, make the built-in host
// recording, compare images, check configs.
#include "ig/cli.h"

#include <algorithm>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "ig/app_common.h"
#include "ig/json.h"
#include "ig/service.h"
#include "io/dem.h"
#if IG_LINK_CIGI
#include "io/pcap.h"
#endif
#if IG_LINK_CAN
#include "io/can_map.h"
#endif
#include "io/replay.h"
#include "render/image.h"
#include "ig/forest_tool.h"
#include "ig/hdlod_tool.h"
#include "ig/cells_tool.h"

namespace {

// igtool convert: a capture of real host traffic -> a recording igd replays.
int convertCommand(const std::string& configFile, const std::string& format, const std::string& in,
                   const std::string& out, int port, int64_t staleMs) {
  ig::ServiceConfig config;
  ig::SceneConfig scene;
  std::string error;
  if (!ig::loadConfigs(configFile, {}, config, scene, error)) {
    std::fprintf(stderr, "igtool convert: %s\n", error.c_str());
    return 2;
  }
  [[maybe_unused]] const ig::lod::Geodetic origin{scene.originGeodetic[0], scene.originGeodetic[1],
                                                  scene.originGeodetic[2]};
  (void)port, (void)staleMs;  // unused when the build has neither link
  ig::io::Recording rec;
  bool ok = false;
  if (format == "pcap") {
#if IG_LINK_CIGI
    ig::io::CigiAssemblerConfig cigi;
    cigi.entityId = static_cast<uint16_t>(config.cigi.entity_id);
    cigi.viewId = static_cast<uint16_t>(config.cigi.view_id);
    cigi.database = config.cigi.database;
    ok = ig::io::cigiPcapToRecording(in, static_cast<uint16_t>(port > 0 ? port : config.cigi.port), origin, rec,
                                     error, cigi);
#else
    error = "this build has no CIGI link";
#endif
  } else {
#if IG_LINK_CAN
    ig::io::CanLinkConfig can = config.can;
    if (staleMs > 0) can.stale_ms = staleMs;
    ok = ig::io::candumpToRecording(in, can, origin, rec, error);
#else
    error = "this build has no CAN link";
#endif
  }
  if (!ok) {
    std::fprintf(stderr, "igtool convert: %s\n", error.c_str());
    return 2;
  }
  if (!ig::io::saveRecording(out, rec, error)) {
    std::fprintf(stderr, "igtool convert: %s\n", error.c_str());
    return 1;
  }
  std::printf("igtool convert: %s -> %s: %zu samples over %.3f s\n", in.c_str(), out.c_str(), rec.samples.size(),
              rec.duration_s());
  return 0;
}

int renderCommand(const std::string& configFile, const ig::Overrides& o, double time_s, const std::string& out) {
  ig::ServiceConfig config;
  ig::SceneConfig scene;
  std::string error;
  if (!ig::loadConfigs(configFile, o, config, scene, error)) {
    std::fprintf(stderr, "igtool render: %s\n", error.c_str());
    return 2;
  }
  if (config.host != ig::HostSource::Replay) {
    std::fprintf(stderr, "igtool render: %s: host.source must be 'replay' to pick an eyepoint\n", config.path.c_str());
    return 2;
  }
  ig::io::Recording rec;
  if (!ig::io::loadRecording(config.replayFile, rec, error)) {
    std::fprintf(stderr, "igtool render: %s\n", error.c_str());
    return 2;
  }
  config.replayFile = "";
  config.host = ig::HostSource::None;
  config.snapshotEvery = 0;  // one frame to --out: no snapshot folder, thread or stats file
  config.snapshotFrames.clear();
  config.statsFile.clear();
  auto service = ig::Service::create(config, scene, error);
  if (!service) {
    std::fprintf(stderr, "igtool render: start-up failed: %s\n", error.c_str());
    return 3;
  }
  ig::render::Image image;
  const ig::FrameRecord r = service->renderOnce(ig::io::sampleAt(rec, time_s).state, &image);
  if (!ig::render::writePng(out, image, error)) {
    std::fprintf(stderr, "igtool render: %s\n", error.c_str());
    return 1;
  }
  std::printf("igtool render: %s (%dx%d, t = %.3f s, %llu triangles, %u draw calls)\n", out.c_str(), image.width,
              image.height, time_s, static_cast<unsigned long long>(r.triangles), r.drawCalls);
  return 0;
}

int compareCommand(const std::string& a, const std::string& b, double maxRmse) {
  ig::render::Image ia, ib;
  std::string error;
  if (!ig::render::readPng(a, ia, error) || !ig::render::readPng(b, ib, error)) {
    std::fprintf(stderr, "igtool compare: %s\n", error.c_str());
    return 2;
  }
  const double e = ig::render::rmse(ia, ib);
  if (e < 0) {
    std::fprintf(stderr, "igtool compare: sizes differ: %s is %dx%d, %s is %dx%d\n", a.c_str(), ia.width, ia.height,
                 b.c_str(), ib.width, ib.height);
    return 2;  // an input error like an unreadable file, not "the images differ" (1)
  }
  const double frac = ig::render::fractionDifferent(ia, ib, 8);
  std::printf("rmse %.4f (8-bit levels), %.4f %% of pixels differ by more than 8 levels\n", e, 100.0 * frac);
  return e <= maxRmse ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"igtool - offline tools for the igd image generator."};
  app.require_subcommand(1);

  std::string configFile = "config/igd.toml";
  ig::Overrides o;
  double time_s = 0.0;
  std::string out = "frame.png";
  CLI::App* render = app.add_subcommand(
      "render", "Render one frame of a service config's scene, with the eyepoint its host recording has at\n"
                "replay time --time, to a PNG (used to make golden images).");
  render->add_option("-c,--config", configFile, "Service config (TOML)")->capture_default_str();
  render->add_option("-t,--time", time_s, "Replay time in seconds")->capture_default_str();
  render->add_option("-o,--out", out, "Output PNG")->capture_default_str();
  render->add_option("--width", o.width_px, "Width in pixels (default: the config's)");
  render->add_option("--height", o.height_px, "Height in pixels (default: the config's)");
  render->add_option("--output", o.output, "Context: headless | osmesa | window");
  render->add_option("--scene", o.sceneFile, "Scene config (default: the config's)");

  double rate_hz = 60.0, duration_s = 20.0;
  std::string recOut = "config/recordings/default.rec";
  CLI::App* makeRec = app.add_subcommand(
      "make-recording", "Write the built-in host recording of the default scene (an orbit over the terrain\n"
                        "with simulation time) as a text recording igd can replay.");
  makeRec->add_option("--rate", rate_hz, "Samples per second")->capture_default_str()->check(CLI::Range(1.0, 1000.0));
  makeRec->add_option("--duration", duration_s, "Length in seconds")->capture_default_str()->check(CLI::Range(0.0, 36000.0));
  makeRec->add_option("-o,--out", recOut, "Output file")->capture_default_str();

  std::string imgA, imgB;
  double maxRmse = 2.0;
  CLI::App* compare = app.add_subcommand(
      "compare", "Compare two PNGs: print the RMSE over RGB in 8-bit levels and the share of pixels that\n"
                 "differ by more than 8 levels; exit 1 if the RMSE exceeds --max-rmse, 2 if a file is not a\n"
                 "readable PNG or the two sizes differ.");
  compare->add_option("a", imgA, "First PNG")->required();
  compare->add_option("b", imgB, "Second PNG")->required();
  compare->add_option("--max-rmse", maxRmse, "Largest RMSE that passes")->capture_default_str()->check(CLI::NonNegativeNumber);

  std::vector<std::string> checkFiles;
  CLI::App* check = app.add_subcommand(
      "check-config", "Validate service configs (and the scenes they name); print the first error of each\n"
                      "with file, line, key and value. Exit 2 if any is bad.");
  check->add_option("files", checkFiles, "Service config files")->required();
  std::string demFile;
  ig::io::DemLoadOptions demOptions;
  bool demReject = false;
  CLI::App* demInfo = app.add_subcommand(
      "dem-info", "Load a DEM (16-bit PNG, GeoTIFF, SRTM .hgt) as igd would and print its size, height range,\n"
                  "voids filled and load time. Exit 2 if the file is rejected (the message says why).");
  demInfo->add_option("file", demFile, "DEM file")->required();
  demInfo->add_option("--png-scale", demOptions.pngScale_m, "16-bit PNG: metres per unit")->capture_default_str();
  demInfo->add_option("--png-offset", demOptions.pngOffset_m, "16-bit PNG: height of value 0 in metres")->capture_default_str();
  demInfo->add_flag("--reject-voids", demReject, "Reject a DEM with voids instead of filling them");
  demInfo->add_option("--max-void-fraction", demOptions.maxVoidFraction, "Reject above this share of voids")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0));
  std::string convFormat, convIn, convOut, convConfig = "config/igd.toml";
  int convPort = 0;
  int64_t convStaleMs = 0;
  CLI::App* convert = app.add_subcommand(
      "convert", "Turn a capture of real host traffic into a recording igd can replay ([host] source =\n"
                 "\"replay\"): a pcap of CIGI over UDP (tcpdump/tshark/dumpcap; Ethernet, Linux cooked, raw IP\n"
                 "or loopback captures) or a candump log (candump -l) of the CAN frame map. The messages go\n"
                 "through the same decoder as the live link, with the [host.cigi] / [host.can] settings and\n"
                 "the scene origin of --config; sample times are capture times from the first sample.");
  convert->add_option("format", convFormat, "pcap | candump")->required()->check(CLI::IsMember({"pcap", "candump"}));
  convert->add_option("input", convIn, "Capture file")->required();
  convert->add_option("-o,--out", convOut, "Recording to write")->required();
  convert->add_option("-c,--config", convConfig, "Service config giving the link settings and scene origin")
      ->capture_default_str();
  convert->add_option("--port", convPort, "pcap: UDP destination port of the host messages (default: host.cigi.port)")
      ->check(CLI::Range(1, 65535));
  convert->add_option("--stale-ms", convStaleMs,
                      "candump: drop a frame set not complete within this many ms (default: host.can.stale_ms)")
      ->check(CLI::Range(int64_t{1}, int64_t{60000}));
  ig::SiteToolOptions siteOptions;
  std::vector<double> siteOrigin;
  CLI::App* site = app.add_subcommand(
      "site", "Writes the HDLOD synthetic construction site (docs/hdlod.md) as OUT/site.sched with\n"
              "OUT/models/*.obj: ground and site buildings, columns, beams, slabs, facade panels and windows\n"
              "installed floor by floor, scaffolding put up and taken down, cranes, excavators and trucks on\n"
              "paths. With --cache it also builds the 4D cluster tree into a cache file igd loads at start-up.");
  site->add_option("--out", siteOptions.out, "Output folder (created)")->capture_default_str();
  site->add_option("--scale", siteOptions.scale, "Site scale: 1 = the paper's ~56k objects / ~4 M triangles")
      ->capture_default_str()->check(CLI::Range(0.001, 10.0));
  site->add_option("--seed", siteOptions.seed, "Generator seed")->capture_default_str();
  site->add_option("--floors", siteOptions.floors, "Floors of the tower at scale 1")->capture_default_str()->check(CLI::Range(1, 1000));
  site->add_option("--bays", siteOptions.bays, "Structural bays per side")->capture_default_str()->check(CLI::Range(1, 100));
  site->add_option("--days", siteOptions.durationDays, "Length of the schedule T in days")
      ->capture_default_str()->check(CLI::PositiveNumber);
  site->add_option("--origin", siteOrigin, "Site centre X Y Z in the scene's local ENU frame (m)")->expected(3);
  site->add_option("--cache", siteOptions.cache, "Also build the tree into this cache file");
  site->add_option("--simplifier", siteOptions.simplifier, "Parent-cluster simplifier")
      ->capture_default_str()->check(CLI::IsMember({"meshoptimizer", "openmesh", "clustering"}));
  site->add_flag("--progress", siteOptions.progress, "Build progress bar on stderr even when it is not a terminal");
  ig::ForestTexturesOptions ftOptions;
  CLI::App* forestTex = app.add_subcommand(
      "forest-textures",
      "Builds the forest assets igd's [forest] assets key points at (docs/forest.md): near LOD models\n"
      "of the pine and cypress (meshoptimizer), and, rendered offline from a denser LOD on a tile of\n"
      "forest, the layer texture T (horizontal slices, lower layers darker) and the fin texture S\n"
      "(vertical slices) as PNG. Run scripts/fetch-forest first for the real models.");
  forestTex->add_option("--source", ftOptions.source, "Folder with pine.obj and cypress.obj")->capture_default_str();
  forestTex->add_option("--out", ftOptions.out, "Assets folder to write")->capture_default_str();
  forestTex->add_option("--layers", ftOptions.layers, "Shell layers in T")->capture_default_str()->check(CLI::Range(1, 32));
  forestTex->add_option("--size", ftOptions.size_px, "Texture size per layer in pixels")->capture_default_str()->check(CLI::Range(8, 2048));
  forestTex->add_option("--tile", ftOptions.tile_m,
                         "Forest tile side in metres (default: the larger of 24 and 4 x --spacing, at least 16 trees);\n"
                         "refused when tile^2 / spacing^2 rounds to a tree count 10 % off the density")
      ->check(CLI::PositiveNumber);
  forestTex->add_option("--spacing", ftOptions.spacing_m, "Placement slot; the tile gets tile^2 / spacing^2 trees")
      ->capture_default_str()->check(CLI::PositiveNumber);
  forestTex->add_option("--triangles", ftOptions.triangles, "Near LOD triangles per model")->capture_default_str()->check(CLI::Range(8, 10000000));
  forestTex->add_option("--bake-triangles", ftOptions.bakeTriangles, "LOD the textures are rendered from (>= --triangles)")
      ->capture_default_str()->check(CLI::Range(8, 100000000));
  forestTex->add_flag("--procedural", ftOptions.procedural, "Use the procedural models (no download)");
  ig::CellsBuildOptions cbOptions;
  CLI::App* cellsBuild = app.add_subcommand(
      "cells-build",
      "Builds a hierarchical-cells database (paper 003, docs/cells.md): a mesh (OBJ, PLY, glTF; run\n"
      "scripts/fetch-cells for the Stanford bunny), --copies N scattered copies of it, or --scene\n"
      "spheres:N -> voxel pyramid -> cell tree -> one packed file of octree images with an index and\n"
      "crc32s. Prints the box-counting dimension per voxel level (about 2 for surfaces) and the cells\n"
      "and bytes per level, then reads the file back and checks every cell.");
  cellsBuild->add_option("input", cbOptions.input, "Mesh file (.obj, .ply, .gltf, .glb)");
  cellsBuild->add_option("--scene", cbOptions.scene, "Procedural scene instead of a mesh: spheres:N (1,024 m cube)");
  cellsBuild->add_option("--copies", cbOptions.copies, "Scatter N copies of the mesh (random place, turn, scale)")
      ->check(CLI::Range(0, 100000));
  cellsBuild->add_option("--size", cbOptions.size_m, "Scale the mesh so that its largest extent is this many metres (0: as is)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  cellsBuild->add_flag("--y-up", cbOptions.yUp, "The mesh is y up (the bunny): turn it to z up");
  cellsBuild->add_flag("!--no-shading", cbOptions.shading, "Do not bake sun shading into the voxel colours");
  cellsBuild->add_option("--voxel-levels", cbOptions.voxelLevels, "Finest voxel level (0: cell levels - 1 + depth)")
      ->capture_default_str()->check(CLI::Range(0, 16));
  cellsBuild->add_option("--cell-levels", cbOptions.cellLevels, "Cell levels L")->capture_default_str()->check(CLI::Range(1, 16));
  cellsBuild->add_option("--depth", cbOptions.voxelDepth, "Voxel octree depth d per cell")->capture_default_str()->check(CLI::Range(0, 8));
  cellsBuild->add_flag("--solid", cbOptions.solid, "Fill the inside of closed meshes");
  cellsBuild->add_option("-o,--out", cbOptions.out, "Database file to write")->capture_default_str();
  cellsBuild->add_option("--seed", cbOptions.seed, "Seed for spheres and copies")->capture_default_str();
  cellsBuild->add_flag("--json", cbOptions.json, "Print one JSON object");
  if (const auto rc = ig::parseCommandLine(app, argc, argv)) return *rc;
  if (cellsBuild->parsed()) return ig::runCellsBuild(cbOptions);
  if (forestTex->parsed()) return ig::runForestTextures(ftOptions);
  if (site->parsed()) {
    if (siteOrigin.size() == 3) {
      siteOptions.originX_m = siteOrigin[0];
      siteOptions.originY_m = siteOrigin[1];
      siteOptions.originZ_m = siteOrigin[2];
    }
    return ig::runSiteTool(siteOptions);
  }
  if (convert->parsed()) return convertCommand(convConfig, convFormat, convIn, convOut, convPort, convStaleMs);

  if (demInfo->parsed()) {
    if (demReject) demOptions.voids = ig::io::DemVoids::Reject;
    // Every 16-bit value 0 ... 65535 must give a float height: a scale or offset beyond the float
    // range made every sample inf, reported as voids (or "no valid sample") instead of the option.
    constexpr double kFloatMax = static_cast<double>(std::numeric_limits<float>::max());
    const double top = demOptions.pngOffset_m + demOptions.pngScale_m * 65535.0;
    if (!(std::abs(demOptions.pngOffset_m) <= kFloatMax && std::abs(top) <= kFloatMax)) {
      std::fprintf(stderr,
                   "igtool dem-info: --png-scale %g with --png-offset %g: 16-bit PNG heights up to %g m are beyond "
                   "the float range (+-%g)\n",
                   demOptions.pngScale_m, demOptions.pngOffset_m, top, kFloatMax);
      return 2;
    }
    ig::io::Dem dem;
    std::string error;
    const auto t0 = std::chrono::steady_clock::now();
    if (!ig::io::loadDem(demFile, demOptions, dem, error)) {
      std::fprintf(stderr, "igtool dem-info: %s\n", error.c_str());
      return 2;
    }
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    float lo = dem.heights_m[0], hi = dem.heights_m[0];
    for (float h : dem.heights_m) {
      lo = std::min(lo, h);
      hi = std::max(hi, h);
    }
    std::printf("{\"file\":%s,\"format\":%s,\"width\":%d,\"height\":%d,\"spacing_m\":%.4f,"
                "\"min_m\":%.2f,\"max_m\":%.2f,\"voids_filled\":%llu,\"load_ms\":%.1f}\n",
                ig::jsonString(demFile).c_str(), ig::jsonString(dem.format).c_str(), dem.width, dem.height, dem.spacing_m, static_cast<double>(lo),
                static_cast<double>(hi), static_cast<unsigned long long>(dem.voidsFilled), ms);
    return 0;
  }

  if (render->parsed()) return renderCommand(configFile, o, time_s, out);
  if (makeRec->parsed()) {
    std::string error;
    if (!ig::io::saveRecording(recOut, ig::io::makeDefaultRecording(rate_hz, duration_s), error)) {
      std::fprintf(stderr, "igtool make-recording: %s\n", error.c_str());
      return 1;
    }
    std::printf("igtool make-recording: %s (%.1f s at %.1f Hz)\n", recOut.c_str(), duration_s, rate_hz);
    return 0;
  }
  if (compare->parsed()) return compareCommand(imgA, imgB, maxRmse);
  if (check->parsed()) {
    int rc = 0;
    for (const auto& f : checkFiles) {
      ig::ServiceConfig s;
      ig::SceneConfig sc;
      std::string error;
      if (ig::loadConfigs(f, {}, s, sc, error)) {
        std::printf("%s: OK (scene %s)\n", f.c_str(), sc.path.c_str());
      } else {
        std::printf("%s\n", error.c_str());
        rc = 2;
      }
    }
    return rc;
  }
  return 2;
}
