// Small helpers for the hand-written JSON that igbench and igtool print: every string that comes
// from outside (a scene name, a file path, the GL renderer string) goes through jsonEscape, and
// a number that may be NaN or infinite through jsonNumber (JSON has neither: they print null).
#pragma once

#include <cmath>
#include <cstdio>
#include <string>
#include <string_view>

namespace ig {

namespace detail {

// Bytes in the well-formed UTF-8 sequence at s[i] (1 - 4), or 0 where there is none (a stray
// continuation byte, a truncated, overlong or surrogate sequence, beyond U+10FFFF).
inline size_t utf8Length(std::string_view s, size_t i) {
  const auto b = [&](size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned c = b(i);
  if (c < 0x80) return 1;
  const size_t n = c >= 0xC2 && c <= 0xDF ? 2 : c >= 0xE0 && c <= 0xEF ? 3 : c >= 0xF0 && c <= 0xF4 ? 4 : 0;
  if (n == 0 || n > s.size() - i) return 0;
  for (size_t k = 1; k < n; ++k)
    if ((b(i + k) & 0xC0) != 0x80) return 0;
  if ((c == 0xE0 && b(i + 1) < 0xA0) || (c == 0xED && b(i + 1) > 0x9F) || (c == 0xF0 && b(i + 1) < 0x90) ||
      (c == 0xF4 && b(i + 1) > 0x8F))
    return 0;
  return n;
}

}  // namespace detail

// `s` with '"', '\\' and control characters escaped, without the surrounding quotes. JSON text
// is Unicode: a byte that is not part of well-formed UTF-8 (a Latin-1 file name) is written as
// U+FFFD, so that the output stays parseable.
inline std::string jsonEscape(std::string_view s) {
  std::string o;
  o.reserve(s.size());
  for (size_t i = 0; i < s.size();) {
    const char c = s[i];
    const size_t n = detail::utf8Length(s, i);
    if (n == 0) {
      o += "\\ufffd";
      ++i;
      continue;
    }
    if (n > 1) {
      o.append(s.substr(i, n));
    } else if (c == '"' || c == '\\') {
      o += '\\';
      o += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(static_cast<unsigned char>(c)));
      o += buf;
    } else {
      o += c;
    }
    i += n;
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
