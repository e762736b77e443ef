// Small helpers for the hand-written JSON that igbench and igtool print: every string that comes
// from outside (a scene name, a file path, the GL renderer string) goes through jsonEscape, and
// a number that may be NaN or infinite through jsonNumber (JSON has neither: they print null).
#pragma once

#include <cmath>
#include <cstdio>
#include <string>
#include <string_view>

namespace ig {

// `s` with '"', '\\' and control characters escaped, without the surrounding quotes.
inline std::string jsonEscape(std::string_view s) {
  std::string o;
  o.reserve(s.size());
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      o += '\\';
      o += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(static_cast<unsigned char>(c)));
      o += buf;
    } else {
      o += c;
    }
  }
  return o;
}

// `s` as a JSON string, quotes included.
inline std::string jsonString(std::string_view s) {
  std::string o(1, '"');
  o.append(jsonEscape(s));
  o.push_back('"');
  return o;
}

// `v` with `decimals` fixed decimals, or null when it is not finite.
inline std::string jsonNumber(double v, int decimals) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

}  // namespace ig
