// Command-line parsing shared by igd, igbench and igtool: a bad option or value exits 2 (the
// documented "bad config or option" code, which the systemd unit's RestartPreventExitStatus=2
// keeps from a restart loop), --help exits 0.
#pragma once

#include <CLI/CLI.hpp>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <string>

namespace ig {

namespace detail {

// CLI11 2.1 lets some bad numbers through its own conversions and checks: CLI::Range,
// PositiveNumber and NonNegativeNumber compare (`v < min || v > max`), which every NaN passes;
// strtoll's out-of-range result is taken without looking at errno (99999999999999999999 reads as
// INT64_MAX); strtoull reads "-1" as 2^64 - 1; and integers are read with base 0, so a decimal
// with a leading zero is octal ("--frames 0300" is 192 frames). This check, added to every numeric
// option of every tool, refuses the first three with the option and the value named and drops the
// leading zeros of a decimal integer. Values it cannot parse are left to CLI11's own conversion
// error.
inline std::string checkNumberText(const std::string& type, std::string& text) {
  if (text.empty()) return {};
  if (type != "FLOAT") {
    const size_t digits = (text[0] == '-' || text[0] == '+') ? 1 : 0;
    if (text.size() > digits + 1 && text[digits] == '0' &&
        text.find_first_not_of("0123456789", digits) == std::string::npos) {
      const size_t nonZero = text.find_first_not_of('0', digits);
      text.erase(digits, (nonZero == std::string::npos ? text.size() - 1 : nonZero) - digits);
    }
  }
  const char* begin = text.c_str();
  char* end = nullptr;
  errno = 0;
  if (type == "FLOAT") {
    const double v = std::strtod(begin, &end);
    if (end != begin + text.size()) return {};
    if (!std::isfinite(v)) return "must be a finite number, not '" + text + "'";
    return {};
  }
  if (type == "UINT") {
    const size_t first = text.find_first_not_of(" \t");
    if (first != std::string::npos && text[first] == '-') return "must not be negative, not '" + text + "'";
    (void)std::strtoull(begin, &end, 0);
  } else {
    (void)std::strtoll(begin, &end, 0);
  }
  if (end == begin + text.size() && errno == ERANGE) return "'" + text + "' is out of range of a 64-bit integer";
  return {};
}

inline void addNumberChecks(CLI::App& app) {
  for (CLI::Option* opt : app.get_options()) {
    const std::string full = opt->get_type_name();
    const std::string type = full.substr(0, full.find(':'));
    if (type != "FLOAT" && type != "INT" && type != "UINT") continue;
    // First (transform() puts it in front of the option's own checks, which then see the value
    // as it will be read).
    opt->transform(CLI::Validator([type](std::string& text) { return checkNumberText(type, text); }, "", "number"));
  }
  for (CLI::App* sub : app.get_subcommands(std::function<bool(CLI::App*)>{})) addNumberChecks(*sub);
}

}  // namespace detail

// Parses; returns the exit code to return from main, or nothing to continue.
inline std::optional<int> parseCommandLine(CLI::App& app, int argc, char** argv) {
  detail::addNumberChecks(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);  // prints help or the error
    return rc == 0 ? 0 : 2;
  }
  return std::nullopt;
}

}  // namespace ig
