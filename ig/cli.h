// Command-line parsing shared by igd, igbench and igtool: a bad option or value exits 2 (the
// documented "bad config or option" code, which the systemd unit's RestartPreventExitStatus=2
// keeps from a restart loop), --help exits 0.
#pragma once

#include <CLI/CLI.hpp>

#include <optional>

namespace ig {

// Parses; returns the exit code to return from main, or nothing to continue.
inline std::optional<int> parseCommandLine(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);  // prints help or the error
    return rc == 0 ? 0 : 2;
  }
  return std::nullopt;
}

}  // namespace ig
