// Service and scene configuration loading: TOML text -> validated ServiceConfig / SceneConfig.
// A small Reader layer does the bookkeeping (dotted key names, source lines, the value as
// written, known-key checks, range checks) so that each key below is one line.
#include "ig/config.h"
#include "ig/host_links.h"
#include "io/host_state.h"

#include <cerrno>
#include <cstdio>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <utility>

// toml++ 3.3 (Debian 12) is clean under the project's warning set (GCC 12 and Clang 14, -O0..-O3),
// so it needs no diagnostic pragmas.
#include <toml++/toml.h>

namespace ig {

const char* toString(OutputMode mode) {
  switch (mode) {
    case OutputMode::Headless: return "headless";
    case OutputMode::Window: return "window";
    case OutputMode::OSMesa: return "osmesa";
  }
  return "?";
}

const char* toString(StatsFormat format) {
  switch (format) {
    case StatsFormat::Csv: return "csv";
    case StatsFormat::JsonLines: return "jsonl";
  }
  return "?";
}

const char* toString(HostSource source) {
  switch (source) {
    case HostSource::None: return "none";
    case HostSource::Replay: return "replay";
    case HostSource::Cigi: return "cigi";
    case HostSource::Can: return "can";
    case HostSource::ModbusTcp: return "modbus-tcp";
    case HostSource::ModbusRtu: return "modbus-rtu";
  }
  return "?";
}

std::string channelAspectMismatch(const ServiceConfig& config) {
  if (!config.channel.frustum) return "";
  lod::Camera cam;
  const lod::WindowAngles& w = *config.channel.frustum;
  if (!lod::setWindow(cam, w)) return "the frustum is not a window (each edge in (-90, 90), left < right, bottom < top)";
  const double output = static_cast<double>(config.width_px) / static_cast<double>(config.height_px);
  if (std::abs(cam.aspect / output - 1.0) <= kChannelAspectTolerance) return "";
  char text[320];
  std::snprintf(text, sizeof text,
                "the frustum's aspect ratio (tan(right) - tan(left)) / (tan(top) - tan(bottom)) = %.4f differs from "
                "output.width_px / output.height_px = %d / %d = %.4f by more than 1 %% (the picture would be "
                "stretched): fix the frustum or the output size",
                cam.aspect, config.width_px, config.height_px, output);
  return text;
}

std::string ConfigError::what() const {
  std::string s = file;
  if (line > 0) s.append(":").append(std::to_string(line));
  if (!s.empty()) s += ": ";
  if (!key.empty()) {
    s += key;
    if (!value.empty()) s.append(" = ").append(value);
    s += ": ";
  }
  s += message;
  return s;
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int64_t kInt64Max = std::numeric_limits<int64_t>::max();
constexpr int64_t kInt64Min = std::numeric_limits<int64_t>::min();

using KeyList = std::initializer_list<std::string_view>;

// Concatenates strings by appending (operator+ on temporaries trips GCC 12's -Wrestrict at -O3).
template <typename... Parts>
std::string cat(const Parts&... parts) {
  std::string s;
  (s.append(std::string_view(parts)), ...);
  return s;
}

// Shortest round-trip spelling; whole numbers without exponent (1000000, not 1e+06).
std::string formatNumber(double v) {
  char buf[64];
  std::to_chars_result r{};
  if (std::isfinite(v) && v == std::trunc(v) && std::fabs(v) < 1e15) {
    r = std::to_chars(buf, buf + sizeof buf, static_cast<int64_t>(v));
  } else {
    r = std::to_chars(buf, buf + sizeof buf, v);
  }
  return r.ec == std::errc{} ? std::string(buf, r.ptr) : std::string("?");
}

// Allowed interval for a floating-point value; open ends are exclusive.
struct Range {
  double min = -kInf;
  double max = kInf;
  bool minOpen = false;
  bool maxOpen = false;

  bool contains(double v) const {
    return (minOpen ? v > min : v >= min) && (maxOpen ? v < max : v <= max);
  }
  std::string describe() const {
    if (min == -kInf) return cat(maxOpen ? "< " : "<= ", formatNumber(max));
    if (max == kInf) return cat(minOpen ? "> " : ">= ", formatNumber(min));
    return cat(minOpen ? "(" : "[", formatNumber(min), ", ", formatNumber(max), maxOpen ? ")" : "]");
  }
};

constexpr Range closed(double lo, double hi) { return {lo, hi, false, false}; }
constexpr Range openClosed(double lo, double hi) { return {lo, hi, true, false}; }
constexpr Range atLeast(double lo) { return {lo, kInf, false, false}; }
constexpr Range openRange(double lo, double hi) { return {lo, hi, true, true}; }

// Allowed closed interval for an integer value.
struct IntRange {
  int64_t min = kInt64Min;
  int64_t max = kInt64Max;

  bool contains(int64_t v) const { return v >= min && v <= max; }
  std::string describe() const {
    if (max == kInt64Max) return cat(">= ", std::to_string(min));
    return cat("[", std::to_string(min), ", ", std::to_string(max), "]");
  }
};

std::string joinKeys(KeyList keys, std::string_view quote = "") {
  std::string s;
  for (std::string_view k : keys) {
    if (!s.empty()) s += ", ";
    s.append(quote).append(k).append(quote);
  }
  return s;
}

std::string typeName(const toml::node& node) {
  std::ostringstream ss;
  ss << node.type();
  return ss.str();
}

// Byte offset of 1-based codepoint column `column` in a UTF-8 line.
size_t byteOffset(std::string_view line, uint32_t column) {
  size_t i = 0;
  for (uint32_t c = 1; c < column && i < line.size(); ++c) {
    ++i;
    while (i < line.size() && (static_cast<unsigned char>(line[i]) & 0xC0u) == 0x80u) ++i;
  }
  return i;
}

std::string resolvePath(const std::string& path, const std::string& baseDir) {
  if (path.empty() || baseDir.empty()) return path;
  std::filesystem::path p(path);
  if (p.is_absolute()) return path;
  return (std::filesystem::path(baseDir) / p).lexically_normal().string();
}

// A table of the document (or an absent one: node_ == nullptr) with its dotted path.
struct Table {
  const toml::table* node_ = nullptr;
  std::string path_;  // "" for the root
  int line_ = 0;      // where the table starts, 0 when absent

  bool present() const { return node_ != nullptr; }
  std::string keyOf(std::string_view key) const {
    return path_.empty() ? std::string(key) : cat(path_, ".", key);
  }
};

// Parses one document and reads typed, range-checked values out of it. The first error is kept;
// after it every call is a no-op, so callers read all keys unconditionally and check ok() once.
class Reader {
 public:
  Reader(std::string_view text, std::string file) : text_(text), file_(std::move(file)) {
    size_t start = 0;
    while (start <= text_.size()) {
      size_t nl = text_.find('\n', start);
      if (nl == std::string_view::npos) nl = text_.size();
      std::string_view line = text_.substr(start, nl - start);
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      lines_.push_back(line);
      start = nl + 1;
    }
  }

  bool ok() const { return !failed_; }
  const ConfigError& error() const { return error_; }

  // Parses the text; returns the root table, which must only hold `knownKeys`.
  Table parse(KeyList knownKeys) {
    try {
      doc_ = toml::parse(text_, std::string_view(file_));
    } catch (const toml::parse_error& e) {
      fail(static_cast<int>(e.source().begin.line), "", "", std::string(e.description()));
      return {};
    }
    Table root{&doc_, "", 1};
    checkKnownKeys(root, knownKeys);
    return root;
  }

  // Sub-table `key` of `parent`; absent (not an error) when the key is missing.
  Table table(const Table& parent, std::string_view key, KeyList knownKeys) {
    Table t{nullptr, parent.keyOf(key), 0};
    const toml::node* node = find(parent, key);
    if (node == nullptr) return t;
    if (!node->is_table()) {
      failType(*node, t.path_, "a table");
      return t;
    }
    t.node_ = node->as_table();
    t.line_ = lineOf(*node);
    checkKnownKeys(t, knownKeys);
    return t;
  }

  void get(const Table& t, std::string_view key, double& field, Range range) {
    if (const toml::node* node = find(t, key)) readNumber(*node, t.keyOf(key), range, field);
  }

  void get(const Table& t, std::string_view key, int64_t& field, IntRange range) {
    if (const toml::node* node = find(t, key)) readInteger(*node, t.keyOf(key), range, field);
  }

  template <typename Int>
    requires std::is_integral_v<Int>
  void get(const Table& t, std::string_view key, Int& field, IntRange range) {
    int64_t v = 0;
    const toml::node* node = find(t, key);
    if (node != nullptr && readInteger(*node, t.keyOf(key), range, v)) field = static_cast<Int>(v);
  }

  void get(const Table& t, std::string_view key, bool& field) {
    const toml::node* node = find(t, key);
    if (node == nullptr) return;
    if (const auto* b = node->as_boolean()) {
      field = b->get();
    } else {
      failType(*node, t.keyOf(key), "a boolean (true or false)");
    }
  }

  void get(const Table& t, std::string_view key, std::string& field, bool allowEmpty = true) {
    const toml::node* node = find(t, key);
    if (node == nullptr) return;
    const auto* s = node->as_string();
    if (s == nullptr) {
      failType(*node, t.keyOf(key), "a string");
    } else if (!allowEmpty && s->get().empty()) {
      fail(*node, t.keyOf(key), "must not be empty");
    } else {
      field = s->get();
    }
  }

  template <size_t N>
  void get(const Table& t, std::string_view key, std::array<double, N>& field, Range range) {
    const toml::node* node = find(t, key);
    if (node == nullptr) return;
    const std::string name = t.keyOf(key);
    const auto* arr = node->as_array();
    if (arr == nullptr) {
      failType(*node, name, cat("an array of exactly ", std::to_string(N), " numbers"));
      return;
    }
    if (arr->size() != field.size()) {
      fail(*node, name, cat("expected an array of exactly ", std::to_string(N), " numbers, got ", std::to_string(arr->size()), " elements"));
      return;
    }
    std::array<double, N> v{};
    for (size_t i = 0; i < v.size(); ++i) {
      if (!readNumber(*arr->get(i), cat(name, "[", std::to_string(i), "]"), range, v[i])) return;
    }
    field = v;
  }

  void get(const Table& t, std::string_view key, std::vector<int64_t>& field, IntRange range) {
    const toml::node* node = find(t, key);
    if (node == nullptr) return;
    const std::string name = t.keyOf(key);
    const auto* arr = node->as_array();
    if (arr == nullptr) {
      failType(*node, name, "an array of integers");
      return;
    }
    std::vector<int64_t> v(arr->size());
    for (size_t i = 0; i < v.size(); ++i) {
      if (!readInteger(*arr->get(i), cat(name, "[", std::to_string(i), "]"), range, v[i])) return;
    }
    field = std::move(v);
  }

  // A string key restricted to the spellings in `values`.
  template <typename E>
  void getEnum(const Table& t, std::string_view key, E& field,
               std::initializer_list<std::pair<std::string_view, E>> values) {
    const toml::node* node = find(t, key);
    if (node == nullptr) return;
    std::string allowed;
    for (const auto& [spelling, e] : values) {
      if (!allowed.empty()) allowed += ", ";
      allowed.append("\"").append(spelling).append("\"");
    }
    const auto* s = node->as_string();
    if (s == nullptr) {
      failType(*node, t.keyOf(key), cat("a string, one of ", allowed));
      return;
    }
    for (const auto& [spelling, e] : values) {
      if (s->get() == spelling) {
        field = e;
        return;
      }
    }
    fail(*node, t.keyOf(key), cat("unknown value (allowed: ", allowed, ")"));
  }

  // Fails unless `key` is present in `t`. The error points at the table when it is present.
  void require(const Table& t, std::string_view key, const std::string& why) {
    if (failed_ || (t.present() && t.node_->contains(key))) return;
    fail(t.line_, t.keyOf(key), "", cat("missing required key: ", why));
  }

  // The node for `key` in `t`, or nullptr (also after an error).
  const toml::node* find(const Table& t, std::string_view key) const {
    if (failed_ || !t.present()) return nullptr;
    return t.node_->get(key);
  }

  void fail(const toml::node& node, std::string key, std::string message) {
    fail(lineOf(node), std::move(key), asWritten(node), std::move(message));
  }

  void fail(int line, std::string key, std::string value, std::string message) {
    if (failed_) return;
    failed_ = true;
    error_ = ConfigError{file_, line, std::move(key), std::move(value), std::move(message)};
  }

 private:
  static int lineOf(const toml::node& node) { return static_cast<int>(node.source().begin.line); }

  // The node's text exactly as written when it sits on one line, else a normalised TOML spelling.
  // Tables written as [header] (or implied by dotted keys) have no value text: "".
  std::string asWritten(const toml::node& node) const {
    if (node.is_table() && !node.as_table()->is_inline()) return "";
    const toml::source_region& src = node.source();
    if (src.begin.line >= 1 && src.begin.line == src.end.line && src.begin.line <= lines_.size()) {
      std::string_view line = lines_[src.begin.line - 1];
      size_t from = byteOffset(line, src.begin.column);
      size_t to = byteOffset(line, src.end.column);
      if (from < to) return std::string(line.substr(from, to - from));
    }
    std::ostringstream ss;
    ss << toml::node_view<const toml::node>(node);
    return ss.str();
  }

  void failType(const toml::node& node, std::string key, const std::string& expected) {
    fail(node, std::move(key), cat("wrong type: expected ", expected, ", got ", typeName(node)));
  }

  void checkKnownKeys(const Table& t, KeyList known) {
    // Report the first unknown key in file order, not in the table's (sorted) order.
    const toml::key* worst = nullptr;
    const toml::node* worstNode = nullptr;
    for (auto&& [k, v] : *t.node_) {
      bool isKnown = false;
      for (std::string_view name : known) isKnown = isKnown || k.str() == name;
      if (!isKnown && (worst == nullptr || k.source().begin.line < worst->source().begin.line)) {
        worst = &k;
        worstNode = &v;
      }
    }
    if (worst == nullptr) return;
    const bool isTable = worstNode->is_table() && !worstNode->as_table()->is_inline();
    fail(static_cast<int>(worst->source().begin.line), t.keyOf(worst->str()), asWritten(*worstNode),
         cat(isTable ? "unknown table" : "unknown key", " (known keys: ", joinKeys(known), ")"));
  }

  bool readNumber(const toml::node& node, const std::string& key, Range range, double& out) {
    double v = 0.0;
    if (const auto* f = node.as_floating_point()) {
      v = f->get();
    } else if (const auto* i = node.as_integer()) {
      v = static_cast<double>(i->get());
    } else {
      failType(node, key, "a number");
      return false;
    }
    if (!std::isfinite(v)) {
      fail(node, key, cat("must be a finite number (allowed range: ", range.describe(), ")"));
      return false;
    }
    if (!range.contains(v)) {
      fail(node, key, cat("out of range (allowed range: ", range.describe(), ")"));
      return false;
    }
    out = v;
    return true;
  }

  bool readInteger(const toml::node& node, const std::string& key, IntRange range, int64_t& out) {
    const auto* i = node.as_integer();
    if (i == nullptr) {
      failType(node, key, "an integer");
      return false;
    }
    if (!range.contains(i->get())) {
      fail(node, key, cat("out of range (allowed range: ", range.describe(), ")"));
      return false;
    }
    out = i->get();
    return true;
  }

  std::string_view text_;
  std::string file_;
  std::vector<std::string_view> lines_;
  toml::table doc_;
  bool failed_ = false;
  ConfigError error_;
};

bool readFile(const std::string& file, std::string& text, ConfigError& error) {
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) {
    error = ConfigError{file, 0, "", "", cat("cannot open: ", std::make_error_code(std::errc::is_a_directory).message())};
    return false;
  }
  errno = 0;
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    const int err = errno != 0 ? errno : ENOENT;
    error = ConfigError{file, 0, "", "", cat("cannot open: ", std::error_code(err, std::generic_category()).message())};
    return false;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) {
    error = ConfigError{file, 0, "", "", cat("cannot read: ", std::error_code(errno, std::generic_category()).message())};
    return false;
  }
  text = ss.str();
  return true;
}

std::string parentDir(const std::string& file) {
  return std::filesystem::path(file).parent_path().string();
}

bool parseService(const std::string& text, const std::string& name, const std::string& baseDir,
                  ServiceConfig& out, ConfigError& error) {
  ServiceConfig cfg;
  cfg.path = name;
  Reader r(text, name);
  const Table root = r.parse({"frame", "output", "stats", "host", "scene", "channel", "budget", "governor", "service"});

  const Table frame = r.table(root, "frame", {"rate_hz", "frames", "free_run"});
  // At least 0.01 Hz: the period (and every deadline derived from it) must fit int64 nanoseconds.
  r.get(frame, "rate_hz", cfg.rate_hz, closed(0.01, 1000.0));
  r.get(frame, "frames", cfg.frames, IntRange{0});
  r.get(frame, "free_run", cfg.freeRun);

  const Table output = r.table(root, "output", {"mode", "width_px", "height_px", "msaa", "fullscreen", "monitor",
                                                "snapshot_dir", "snapshot_every", "snapshot_frames"});
  r.getEnum(output, "mode", cfg.output,
            {{"headless", OutputMode::Headless}, {"window", OutputMode::Window}, {"osmesa", OutputMode::OSMesa}});
  r.get(output, "width_px", cfg.width_px, IntRange{16, 16384});
  r.get(output, "height_px", cfg.height_px, IntRange{16, 16384});
  r.get(output, "msaa", cfg.msaa, IntRange{1, 8});
  if (cfg.msaa == 3 || cfg.msaa == 5 || cfg.msaa == 6 || cfg.msaa == 7) {
    if (const toml::node* node = r.find(output, "msaa"))
      r.fail(*node, "output.msaa", cat("samples per pixel must be 1, 2, 4 or 8, not ", std::to_string(cfg.msaa)));
  }
  r.get(output, "fullscreen", cfg.fullscreen);
  r.get(output, "monitor", cfg.monitor, IntRange{0, 63});
  r.get(output, "snapshot_dir", cfg.snapshotDir, false);
  r.get(output, "snapshot_every", cfg.snapshotEvery, IntRange{0});
  r.get(output, "snapshot_frames", cfg.snapshotFrames, IntRange{0});

  const Table stats = r.table(root, "stats", {"file", "format", "max_mb", "keep"});
  r.get(stats, "file", cfg.statsFile);
  r.getEnum(stats, "format", cfg.statsFormat, {{"csv", StatsFormat::Csv}, {"jsonl", StatsFormat::JsonLines}});
  r.get(stats, "max_mb", cfg.statsMax_mb, closed(0.0, 1048576.0));  // up to 1 TiB
  r.get(stats, "keep", cfg.statsKeep, IntRange{0, 1000});

  const Table host = r.table(root, "host", {"source", "replay_file", "replay_loop", "link_timeout_s",
                                            "record_file", "cigi", "can", "modbus"});
  r.getEnum(host, "source", cfg.host,
            {{"none", HostSource::None}, {"replay", HostSource::Replay}, {"cigi", HostSource::Cigi},
             {"can", HostSource::Can}, {"modbus-tcp", HostSource::ModbusTcp}, {"modbus-rtu", HostSource::ModbusRtu}});
  r.get(host, "replay_file", cfg.replayFile, false);
  r.get(host, "replay_loop", cfg.replayLoop);
  r.get(host, "link_timeout_s", cfg.linkTimeout_s, closed(0.01, 3600.0));
  r.get(host, "record_file", cfg.recordFile);
  if (!cfg.recordFile.empty() && (cfg.host == HostSource::None || cfg.host == HostSource::Replay)) {
    if (const toml::node* node = r.find(host, "record_file"))
      r.fail(*node, "host.record_file",
             cat("only live host links are recorded (host.source = \"", toString(cfg.host),
                 "\"; use cigi, can, modbus-tcp or modbus-rtu, or remove record_file)"));
  }
  if (cfg.host == HostSource::Replay) {
    r.require(host, "replay_file", "host.source = \"replay\" needs the recording to play (or set source = \"none\")");
  }

  const Table cigi = r.table(host, "cigi", {"bind_address", "port", "host_address", "host_port", "sync",
                                            "entity_id", "view_id", "database"});
  r.get(cigi, "bind_address", cfg.cigi.bind_address, false);
  r.get(cigi, "port", cfg.cigi.port, IntRange{1, 65535});
  r.get(cigi, "host_address", cfg.cigi.host_address);
  r.get(cigi, "host_port", cfg.cigi.host_port, IntRange{1, 65535});
  r.get(cigi, "sync", cfg.cigi.sync);
  r.get(cigi, "entity_id", cfg.cigi.entity_id, IntRange{0, 65535});
  r.get(cigi, "view_id", cfg.cigi.view_id, IntRange{0, 65535});
  r.get(cigi, "database", cfg.cigi.database, IntRange{-1, 127});

  const Table can = r.table(host, "can", {"interface", "base_id", "stale_ms"});
  r.get(can, "interface", cfg.can.interface, false);
  r.get(can, "base_id", cfg.can.baseId, IntRange{0, 0x7FB});
  r.get(can, "stale_ms", cfg.can.stale_ms, IntRange{1, 60000});

  const Table modbus = r.table(host, "modbus", {"tcp_address", "tcp_port", "unit_id", "serial_device", "baud",
                                                "parity", "data_bits", "stop_bits", "word_order"});
  r.get(modbus, "tcp_address", cfg.modbus.tcpAddress, false);
  r.get(modbus, "tcp_port", cfg.modbus.tcpPort, IntRange{1, 65535});
  r.get(modbus, "unit_id", cfg.modbus.unitId, IntRange{1, 247});
  r.get(modbus, "serial_device", cfg.modbus.serialDevice, false);
  r.get(modbus, "baud", cfg.modbus.baud, IntRange{1200, 1000000});
  r.getEnum(modbus, "parity", cfg.modbus.parity, {{"N", 'N'}, {"E", 'E'}, {"O", 'O'}});
  r.get(modbus, "data_bits", cfg.modbus.dataBits, IntRange{7, 8});
  r.get(modbus, "stop_bits", cfg.modbus.stopBits, IntRange{1, 2});
  r.getEnum(modbus, "word_order", cfg.modbus.wordOrder,
            {{"low_first", io::modbus::WordOrder::LowFirst}, {"high_first", io::modbus::WordOrder::HighFirst}});
  if (cfg.host == HostSource::ModbusRtu) {
    r.require(modbus, "serial_device", "host.source = \"modbus-rtu\" needs the serial line (e.g. \"/dev/ttyUSB0\")");
  }

  // The link's own checks (an address that does not parse or resolve, a baud rate the serial line
  // cannot take) here too: such a value is a config error (file:line, exit 2, found by
  // --check-config and refused by a reload), not a start-up failure after "config OK".
  if (r.ok()) {
    io::LinkConfigError why;
    if (!validateHostLinkConfig(cfg, why)) {
      const std::string& key = why.key;
      const Table& t = key.starts_with("host.cigi.")     ? cigi
                       : key.starts_with("host.can.")    ? can
                       : key.starts_with("host.modbus.") ? modbus
                                                         : host;
      const std::string leaf = key.substr(key.rfind('.') + 1);
      if (const toml::node* node = r.find(t, leaf)) r.fail(*node, key, why.reason);
      else r.fail(t.line_ > 0 ? t.line_ : host.line_, key, why.value, why.reason);
    }
  }

  const Table scene = r.table(root, "scene", {"file"});
  r.get(scene, "file", cfg.sceneFile, false);
  r.require(scene, "file", "path of the scene file ([scene] file = \"scenes/default.toml\")");

  const Table channel = r.table(root, "channel", {"yaw_deg", "pitch_deg", "roll_deg", "left_deg", "right_deg",
                                                  "bottom_deg", "top_deg"});
  ChannelSettings& ch = cfg.channel;
  r.get(channel, "yaw_deg", ch.yaw_deg, closed(-180.0, 180.0));
  r.get(channel, "pitch_deg", ch.pitch_deg, closed(-90.0, 90.0));
  r.get(channel, "roll_deg", ch.roll_deg, closed(-180.0, 180.0));
  {
    constexpr const char* kEdges[] = {"left_deg", "right_deg", "bottom_deg", "top_deg"};
    lod::WindowAngles w;
    double* edges[] = {&w.left_deg, &w.right_deg, &w.bottom_deg, &w.top_deg};
    int given = 0;
    for (size_t i = 0; i < 4; ++i) {
      if (r.find(channel, kEdges[i]) == nullptr) continue;
      ++given;
      r.get(channel, kEdges[i], *edges[i], openRange(-90.0, 90.0));
    }
    if (r.ok() && given > 0 && given < 4) {
      for (const char* key : kEdges) {
        if (r.find(channel, key) != nullptr) continue;
        r.fail(channel.line_, channel.keyOf(key), "",
               "missing: the channel frustum needs all four of left_deg, right_deg, bottom_deg, top_deg (or none)");
        break;
      }
    }
    if (r.ok() && given == 4) {
      const char* bad = !(w.left_deg < w.right_deg) ? "right_deg" : !(w.bottom_deg < w.top_deg) ? "top_deg" : nullptr;
      if (bad != nullptr) {
        const bool lr = bad[0] == 'r';
        r.fail(*r.find(channel, bad), channel.keyOf(bad),
               cat("must be greater than ", channel.keyOf(lr ? "left_deg" : "bottom_deg"), " (",
                   formatNumber(lr ? w.left_deg : w.bottom_deg), ")"));
      } else {
        ch.frustum = w;
        if (const std::string why = channelAspectMismatch(cfg); !why.empty())
          r.fail(channel.line_, channel.path_, "", why);
      }
    }
  }

  const Table budget = r.table(root, "budget", {"frame_ms", "triangles"});
  r.get(budget, "frame_ms", cfg.budgetFrame_ms, closed(0.0, 100000.0));
  r.get(budget, "triangles", cfg.budgetTriangles, IntRange{1000});

  const Table gov = r.table(root, "governor", {"enabled", "decrease_above", "increase_below", "margin_sigmas",
                                              "max_decrease", "max_increase", "raise_interval_frames",
                                              "hold_after_decrease_frames", "spike_window_frames", "terrain", "forest",
                                              "hdlod", "cells"});
  GovernorSettings& g = cfg.governor;
  r.get(gov, "enabled", g.enabled);
  r.get(gov, "decrease_above", g.decreaseAbove, openClosed(0.0, 1.5));
  r.get(gov, "increase_below", g.increaseBelow, openClosed(0.0, 1.5));
  r.get(gov, "margin_sigmas", g.marginSigmas, closed(0.0, 10.0));
  r.get(gov, "max_decrease", g.maxDecrease, closed(0.01, 0.99));
  r.get(gov, "max_increase", g.maxIncrease, closed(1.001, 4.0));
  r.get(gov, "raise_interval_frames", g.raiseInterval_frames, IntRange{1, 100000});
  r.get(gov, "hold_after_decrease_frames", g.holdAfterDecrease_frames, IntRange{0, 100000});
  r.get(gov, "spike_window_frames", g.spikeWindow_frames, IntRange{0, 1000000});
  const Table govTerrain = r.table(gov, "terrain", {"min_px", "max_px", "load_exponent"});
  r.get(govTerrain, "min_px", g.terrainMin_px, closed(0.0, 1000.0));
  r.get(govTerrain, "max_px", g.terrainMax_px, openClosed(0.0, 1000.0));
  // lod::Governor::validate allows |load_exponent| <= 8: a value it refuses must not pass here
  // (start-up would fail with no file named, and a reload would apply it unchecked).
  r.get(govTerrain, "load_exponent", g.terrainLoadExponent, closed(-8.0, -0.1));
  const Table govForest = r.table(gov, "forest", {"min_m", "max_m", "min_layers", "max_layers"});
  r.get(govForest, "min_m", g.forestMin_m, openClosed(0.0, 1e6));
  r.get(govForest, "max_m", g.forestMax_m, closed(0.0, 1e6));
  r.get(govForest, "min_layers", g.forestMinLayers, IntRange{1, 32});
  r.get(govForest, "max_layers", g.forestMaxLayers, IntRange{0, 32});
  const Table govHdlod = r.table(gov, "hdlod", {"min_px", "max_px", "load_exponent"});
  r.get(govHdlod, "min_px", g.hdlodMin_px, closed(0.0, 1000.0));
  r.get(govHdlod, "max_px", g.hdlodMax_px, openClosed(0.0, 1000.0));
  r.get(govHdlod, "load_exponent", g.hdlodLoadExponent, closed(-8.0, -0.1));
  const Table govCells = r.table(gov, "cells", {"min_voxels", "max_voxels"});
  r.get(govCells, "min_voxels", g.cellsMin_voxels, IntRange{1000, 1'000'000'000});
  r.get(govCells, "max_voxels", g.cellsMax_voxels, IntRange{0, 1'000'000'000});
  if (r.ok() && g.increaseBelow >= g.decreaseAbove) {
    const std::string message = cat("must be below governor.decrease_above (", formatNumber(g.decreaseAbove), ")");
    if (const toml::node* node = r.find(gov, "increase_below")) {
      r.fail(*node, gov.keyOf("increase_below"), message);
    } else {
      r.fail(gov.line_, gov.keyOf("increase_below"), formatNumber(g.increaseBelow), message);
    }
  }
  if (r.ok() && g.terrainMin_px > 0.0 && g.terrainMin_px >= g.terrainMax_px) {
    const std::string message = cat("must be below governor.terrain.max_px (", formatNumber(g.terrainMax_px), ")");
    if (const toml::node* node = r.find(govTerrain, "min_px")) r.fail(*node, govTerrain.keyOf("min_px"), message);
  }
  if (r.ok() && g.forestMax_m > 0.0 && g.forestMin_m >= g.forestMax_m) {
    const std::string message = cat("must be below governor.forest.max_m (", formatNumber(g.forestMax_m), ")");
    if (const toml::node* node = r.find(govForest, "min_m")) r.fail(*node, govForest.keyOf("min_m"), message);
    else r.fail(govForest.line_, govForest.keyOf("min_m"), formatNumber(g.forestMin_m), message);
  }
  if (r.ok() && g.forestMaxLayers > 0 && g.forestMinLayers > g.forestMaxLayers) {
    const std::string message = cat("must be at most governor.forest.max_layers (", std::to_string(g.forestMaxLayers), ")");
    if (const toml::node* node = r.find(govForest, "min_layers")) r.fail(*node, govForest.keyOf("min_layers"), message);
    else r.fail(govForest.line_, govForest.keyOf("min_layers"), std::to_string(g.forestMinLayers), message);
  }
  if (r.ok() && g.hdlodMin_px > 0.0 && g.hdlodMin_px >= g.hdlodMax_px) {
    const std::string message = cat("must be below governor.hdlod.max_px (", formatNumber(g.hdlodMax_px), ")");
    if (const toml::node* node = r.find(govHdlod, "min_px")) r.fail(*node, govHdlod.keyOf("min_px"), message);
  }
  if (r.ok() && g.cellsMax_voxels > 0 && g.cellsMin_voxels >= g.cellsMax_voxels) {
    const std::string message = cat("must be below governor.cells.max_voxels (", std::to_string(g.cellsMax_voxels), ")");
    if (const toml::node* node = r.find(govCells, "min_voxels")) r.fail(*node, govCells.keyOf("min_voxels"), message);
    else r.fail(govCells.line_, govCells.keyOf("min_voxels"), std::to_string(g.cellsMin_voxels), message);
  }

  const Table service = r.table(root, "service", {"watchdog_interval_s", "realtime_priority", "cpu_affinity",
                                                  "lock_memory", "status_file", "status_interval_s"});
  r.get(service, "watchdog_interval_s", cfg.watchdogInterval_s, closed(0.0, 3600.0));
  r.get(service, "realtime_priority", cfg.realtimePriority, IntRange{0, 99});
  r.get(service, "cpu_affinity", cfg.cpuAffinity, IntRange{0, 1023});
  r.get(service, "lock_memory", cfg.lockMemory);
  r.get(service, "status_file", cfg.statusFile);
  r.get(service, "status_interval_s", cfg.statusInterval_s, closed(0.05, 3600.0));

  if (!r.ok()) {
    error = r.error();
    return false;
  }
  for (std::string* path :
       {&cfg.snapshotDir, &cfg.statsFile, &cfg.replayFile, &cfg.sceneFile, &cfg.recordFile, &cfg.statusFile}) {
    *path = resolvePath(*path, baseDir);
  }
  out = std::move(cfg);
  return true;
}

// size_m / grid_step_m must give a sane number of posts per side.
void checkTerrainGrid(Reader& r, const Table& t, const TerrainLayerConfig& terrain) {
  constexpr Range kQuadsPerSide = closed(2.0, 8192.0);
  const double quads = terrain.size_m / terrain.gridStep_m;
  if (!r.ok() || kQuadsPerSide.contains(quads)) return;
  const std::string_view key = r.find(t, "grid_step_m") != nullptr ? "grid_step_m" : "size_m";
  const std::string message = cat("size_m / grid_step_m = ", formatNumber(quads),
                                  " quads per side, out of range (allowed range: ", kQuadsPerSide.describe(), ")");
  if (const toml::node* node = r.find(t, key)) {
    r.fail(*node, t.keyOf(key), message);
  } else {
    r.fail(t.line_, t.keyOf(key), "", message);
  }
}

bool parseScene(const std::string& text, const std::string& name, const std::string& baseDir,
                SceneConfig& out, ConfigError& error) {
  SceneConfig cfg;
  cfg.path = name;
  Reader r(text, name);
  const Table root = r.parse({"name", "origin", "terrain", "forest", "hdlod", "cells", "sun", "fog"});
  r.get(root, "name", cfg.name, false);

  const Table origin = r.table(root, "origin", {"lat_deg", "lon_deg", "height_m"});
  r.get(origin, "lat_deg", cfg.originGeodetic[0], closed(-90.0, 90.0));
  r.get(origin, "lon_deg", cfg.originGeodetic[1], closed(-180.0, 180.0));
  r.get(origin, "height_m", cfg.originGeodetic[2], closed(-1e4, 1e5));

  const Table terrain = r.table(root, "terrain", {"source", "lod", "file", "spacing_m", "png_scale_m", "png_offset_m",
                                                  "tolerance_px", "lod_budget_ms", "morph_s", "roam_mode", "seed",
                                                  "size_m", "grid_step_m", "height_scale_m", "offset_m", "chunk_quads"});
  if (terrain.present()) {
    TerrainLayerConfig& t = cfg.terrain.emplace();
    r.getEnum(terrain, "source", t.source,
              {{"procedural", TerrainLayerConfig::Source::Procedural}, {"dem", TerrainLayerConfig::Source::Dem}});
    r.getEnum(terrain, "lod", t.lod,
              {{"grid", TerrainLayerConfig::Lod::Grid},
               {"roam", TerrainLayerConfig::Lod::Roam},
               {"block", TerrainLayerConfig::Lod::Block}});
    r.get(terrain, "file", t.file, false);
    r.get(terrain, "spacing_m", t.demSpacing_m, closed(0.0, 1e5));
    r.get(terrain, "png_scale_m", t.pngScale_m, Range{0.0, 1e4, true, false});
    r.get(terrain, "png_offset_m", t.pngOffset_m, closed(-1e5, 1e5));
    r.get(terrain, "tolerance_px", t.tolerance_px, Range{0.0, 1000.0, true, false});
    r.get(terrain, "lod_budget_ms", t.lodBudget_ms, closed(0.0, 1000.0));
    r.get(terrain, "morph_s", t.morph_s, closed(0.0, 60.0));
    r.getEnum(terrain, "roam_mode", t.roamMode,
              {{"deferred", TerrainLayerConfig::RoamMode::Deferred}, {"enhmerge", TerrainLayerConfig::RoamMode::EnhMerge}});
    if (r.ok() && t.source == TerrainLayerConfig::Source::Dem) {
      r.require(terrain, "file", "source = \"dem\" needs the DEM file (.png, .tif, .tiff, .hgt)");
      if (r.ok() && t.lod == TerrainLayerConfig::Lod::Grid) {
        const toml::node* node = r.find(terrain, "lod");
        const std::string message = "lod = \"grid\" draws only the procedural terrain; use \"roam\" or \"block\" for a DEM";
        if (node) r.fail(*node, terrain.keyOf("lod"), message);
        else r.fail(terrain.line_, terrain.keyOf("lod"), "", message);
      }
    }
    r.get(terrain, "seed", t.seed, IntRange{0, std::numeric_limits<uint32_t>::max()});
    r.get(terrain, "size_m", t.size_m, openClosed(0.0, 1e6));
    r.get(terrain, "grid_step_m", t.gridStep_m, Range{0.0, kInf, true, false});
    r.get(terrain, "height_scale_m", t.heightScale_m, closed(0.0, 20000.0));
    r.get(terrain, "offset_m", t.offset_m, closed(-1e8, 1e8));
    r.get(terrain, "chunk_quads", t.chunkQuads, IntRange{4, 1024});
    checkTerrainGrid(r, terrain, t);
  }

  const Table forest = r.table(root, "forest", {"assets", "map", "seed", "cell_m", "glade_fraction",
                                                "feature_size_m", "area_m", "spacing_m", "layers",
                                                "near_fade_start_m", "near_fade_end_m", "fade_out_m",
                                                "far_plane_m", "fins", "critical_angle_deg",
                                                "fin_alpha_threshold", "leaf_size_m", "max_trees"});
  if (forest.present()) {
    ForestLayerConfig& f = cfg.forest.emplace();
    r.get(forest, "assets", f.assets);
    r.get(forest, "map", f.map);
    r.get(forest, "seed", f.seed, IntRange{0, 0xFFFFFFFFll});
    r.get(forest, "cell_m", f.cell_m, closed(1.0, 10000.0));
    r.get(forest, "glade_fraction", f.gladeFraction, closed(0.0, 1.0));
    r.get(forest, "feature_size_m", f.featureSize_m, closed(10.0, 100000.0));
    r.get(forest, "area_m", f.area_m, closed(-1e8, 1e8));
    r.get(forest, "spacing_m", f.spacing_m, closed(1.0, 1000.0));
    r.get(forest, "layers", f.layers, IntRange{1, 32});
    r.get(forest, "near_fade_start_m", f.nearFadeStart_m, openClosed(0.0, 1e6));
    r.get(forest, "near_fade_end_m", f.nearFadeEnd_m, openClosed(0.0, 1e6));
    r.get(forest, "fade_out_m", f.fadeOut_m, openClosed(0.0, 1e7));
    r.get(forest, "far_plane_m", f.farPlane_m, openClosed(0.0, 1e7));
    r.get(forest, "fins", f.fins);
    r.get(forest, "critical_angle_deg", f.criticalAngle_deg, closed(90.0, 180.0));
    r.get(forest, "fin_alpha_threshold", f.finAlphaThreshold, closed(0.0, 1.0));
    r.get(forest, "leaf_size_m", f.leafSize_m, closed(16.0, 10000.0));
    r.get(forest, "max_trees", f.maxTrees, IntRange{1, 4194304});
    // The fade bands must be ordered: near start < near end < fade out < far plane.
    const std::pair<const char*, double> bands[] = {{"near_fade_start_m", f.nearFadeStart_m},
                                                    {"near_fade_end_m", f.nearFadeEnd_m},
                                                    {"fade_out_m", f.fadeOut_m},
                                                    {"far_plane_m", f.farPlane_m}};
    for (size_t i = 1; r.ok() && i < std::size(bands); ++i) {
      if (bands[i].second > bands[i - 1].second) continue;
      const std::string message = cat("must be greater than forest.", bands[i - 1].first, " (",
                                      formatNumber(bands[i - 1].second), ")");
      if (const toml::node* node = r.find(forest, bands[i].first)) {
        r.fail(*node, forest.keyOf(bands[i].first), message);
      } else {
        r.fail(forest.line_, forest.keyOf(bands[i].first), formatNumber(bands[i].second), message);
      }
    }
  }

  // The shell layers and the fins are drawn from the terrain mesh, which lod = "grid" does not
  // build (checked here so that --check-config finds it; igd would fail at start-up).
  if (r.ok() && cfg.forest && (!cfg.terrain || cfg.terrain->lod == TerrainLayerConfig::Lod::Grid)) {
    const std::string message = cfg.terrain ? "[forest] needs [terrain] with lod = \"roam\" or \"block\" (the shell layers are "
                                              "drawn from the terrain mesh; lod = \"grid\" has none)"
                                            : "[forest] needs a [terrain] with lod = \"roam\" or \"block\" to stand on";
    if (const toml::node* node = cfg.terrain ? r.find(terrain, "lod") : nullptr) r.fail(*node, terrain.keyOf("lod"), message);
    else if (cfg.terrain) r.fail(terrain.line_, terrain.keyOf("lod"), "\"grid\" (the default)", message);
    else r.fail(forest.line_, "forest", "", message);
  }

  const Table hdlod = r.table(root, "hdlod", {"schedule", "site_scale", "site_seed", "site_origin_m", "cache",
                                              "simplifier", "tolerance_px", "time_offset_s", "time_scale",
                                              "octree_depth"});
  if (hdlod.present()) {
    HdlodLayerConfig& h = cfg.hdlod.emplace();
    r.get(hdlod, "schedule", h.schedule);
    r.get(hdlod, "site_scale", h.siteScale, closed(0.001, 10.0));
    r.get(hdlod, "site_seed", h.siteSeed, IntRange{0, 0xFFFFFFFFll});
    std::array<double, 3> siteOrigin{h.siteX_m, h.siteY_m, h.siteZ_m};
    r.get(hdlod, "site_origin_m", siteOrigin, closed(-1e7, 1e7));
    h.siteX_m = siteOrigin[0];
    h.siteY_m = siteOrigin[1];
    h.siteZ_m = siteOrigin[2];
    r.get(hdlod, "cache", h.cache);
    r.getEnum(hdlod, "simplifier", h.simplifier,
              {{"meshoptimizer", std::string("meshoptimizer")}, {"openmesh", std::string("openmesh")},
               {"clustering", std::string("clustering")}});
    r.get(hdlod, "tolerance_px", h.tolerance_px, openClosed(0.0, 1000.0));
    r.get(hdlod, "time_offset_s", h.timeOffset_s, closed(-1e12, 1e12));
    r.get(hdlod, "time_scale", h.timeScale, closed(-1e9, 1e9));
    r.get(hdlod, "octree_depth", h.octreeDepth, IntRange{0, 6});
  }

  const Table cells = r.table(root, "cells", {"source", "origin_m", "voxel_budget", "w_bytes", "min_voxel_px",
                                              "gpu_mb", "memory_mb", "point_scale", "open_timeout_s",
                                              "select_threads", "select_budget_ms"});
  if (cells.present()) {
    CellsLayerConfig& c = cfg.cells.emplace();
    r.require(cells, "source", "the cell database (a file, or http://HOST:PORT/path)");
    r.get(cells, "source", c.source, false);
    if (r.ok() && c.source.find("://") != std::string::npos && c.source.rfind("http://", 0) != 0)
      r.fail(*r.find(cells, "source"), cells.keyOf("source"), "only http:// URLs or file paths are supported");
    r.get(cells, "origin_m", c.origin_m, closed(-1e8, 1e8));
    r.get(cells, "voxel_budget", c.voxelBudget, IntRange{1000, 1'000'000'000});
    r.get(cells, "w_bytes", c.wBytes, IntRange{4096, int64_t{1} << 30});
    r.get(cells, "min_voxel_px", c.minVoxel_px, closed(0.0, 100.0));
    r.get(cells, "gpu_mb", c.gpu_mb, IntRange{1, 32768});  // 2^31 points: render/cells_pass.h
    r.get(cells, "memory_mb", c.memory_mb, IntRange{1, 65536});
    r.get(cells, "point_scale", c.pointScale, openClosed(0.0, 16.0));
    r.get(cells, "open_timeout_s", c.openTimeout_s, openClosed(0.0, 600.0));
    r.get(cells, "select_threads", c.selectThreads, IntRange{0, 2});
    r.get(cells, "select_budget_ms", c.selectBudget_ms, closed(0.0, 1000.0));
  }

  const Table sun = r.table(root, "sun", {"azimuth_deg", "elevation_deg", "color", "ambient"});
  r.get(sun, "azimuth_deg", cfg.sun.azimuth_deg, closed(-360.0, 360.0));
  r.get(sun, "elevation_deg", cfg.sun.elevation_deg, closed(-90.0, 90.0));
  r.get(sun, "color", cfg.sun.color, closed(0.0, 1.0));
  r.get(sun, "ambient", cfg.sun.ambient, closed(0.0, 1.0));

  const Table fog = r.table(root, "fog", {"enabled", "visibility_m", "color", "cull"});
  r.get(fog, "enabled", cfg.fog.enabled);
  r.get(fog, "cull", cfg.fog.cull);
  r.get(fog, "visibility_m", cfg.fog.visibility_m, openClosed(0.0, io::kMaxVisibility_m));
  r.get(fog, "color", cfg.fog.color, closed(0.0, 1.0));

  if (!r.ok()) {
    error = r.error();
    return false;
  }
  if (cfg.terrain && !cfg.terrain->file.empty()) cfg.terrain->file = resolvePath(cfg.terrain->file, baseDir);
  if (cfg.forest) {
    if (!cfg.forest->assets.empty()) cfg.forest->assets = resolvePath(cfg.forest->assets, baseDir);
    if (!cfg.forest->map.empty()) cfg.forest->map = resolvePath(cfg.forest->map, baseDir);
  }
  if (cfg.hdlod) {
    if (!cfg.hdlod->schedule.empty()) cfg.hdlod->schedule = resolvePath(cfg.hdlod->schedule, baseDir);
    if (!cfg.hdlod->cache.empty()) cfg.hdlod->cache = resolvePath(cfg.hdlod->cache, baseDir);
  }
  if (cfg.cells && cfg.cells->source.rfind("http://", 0) != 0) cfg.cells->source = resolvePath(cfg.cells->source, baseDir);
  out = std::move(cfg);
  return true;
}

// Runs `parse` and turns any stray exception (e.g. std::bad_alloc) into a ConfigError.
template <typename Fn>
bool guarded(const std::string& file, ConfigError& error, Fn&& parse) {
  try {
    return parse();
  } catch (const std::exception& e) {
    error = ConfigError{file, 0, "", "", cat("internal error: ", e.what())};
  } catch (...) {
    error = ConfigError{file, 0, "", "", "internal error"};
  }
  return false;
}

}  // namespace

bool parseServiceConfig(const std::string& text, const std::string& name, const std::string& baseDir,
                        ServiceConfig& out, ConfigError& error) {
  return guarded(name, error, [&] { return parseService(text, name, baseDir, out, error); });
}

bool parseSceneConfig(const std::string& text, const std::string& name, const std::string& baseDir,
                      SceneConfig& out, ConfigError& error) {
  return guarded(name, error, [&] { return parseScene(text, name, baseDir, out, error); });
}

bool loadServiceConfig(const std::string& file, ServiceConfig& out, ConfigError& error) {
  return guarded(file, error, [&] {
    std::string text;
    return readFile(file, text, error) && parseService(text, file, parentDir(file), out, error);
  });
}

bool loadSceneConfig(const std::string& file, SceneConfig& out, ConfigError& error) {
  return guarded(file, error, [&] {
    std::string text;
    return readFile(file, text, error) && parseScene(text, file, parentDir(file), out, error);
  });
}

}  // namespace ig
