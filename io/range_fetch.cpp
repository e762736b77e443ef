// Asynchronous byte-range fetcher (io/range_fetch.h): an HTTP/1.1 client on POSIX sockets with
// pipelining and range coalescing, or pread on a local file, in one worker thread.
#include "io/range_fetch.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <mutex>
#include <thread>

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <zlib.h>

namespace ig::io {

namespace {

constexpr size_t kMaxHeadBytes = 16 << 10;
// Largest body of a response other than 206 that is read and dropped on a kept connection (an
// error page); a longer one (a 200 with the whole file) is not read: the connection is reopened.
constexpr int64_t kMaxRefusalBody = 64 << 10;
constexpr size_t kCoalesceWindow = 64;  // pending requests scanned for neighbours

int64_t nowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::string rangeText(uint64_t first, uint64_t last) {
  return "bytes " + std::to_string(first) + "-" + std::to_string(last);
}

char lower(char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; }

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (lower(a[i]) != lower(b[i])) return false;
  return true;
}

bool icontainsToken(std::string_view value, std::string_view token) {
  // Comma-separated tokens, case-insensitive.
  size_t i = 0;
  while (i <= value.size()) {
    size_t j = value.find(',', i);
    if (j == std::string_view::npos) j = value.size();
    std::string_view t = value.substr(i, j - i);
    while (!t.empty() && (t.front() == ' ' || t.front() == '\t')) t.remove_prefix(1);
    while (!t.empty() && (t.back() == ' ' || t.back() == '\t')) t.remove_suffix(1);
    if (iequals(t, token)) return true;
    i = j + 1;
  }
  return false;
}

bool parseU64(std::string_view s, uint64_t& v) {
  if (s.empty() || s.size() > 19) return false;
  for (char c : s)
    if (c < '0' || c > '9') return false;
  auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

// Whether a 206 head answers the range [first, last]: that range exactly, or (RFC 9110 14.1.2,
// what nginx does) the part of it up to the resource's end, with the total naming that end.
bool answersRange(const HttpResponseHead& h, uint64_t first, uint64_t last) {
  if (!h.hasRange || h.rangeFirst != first || h.contentLength < 0 ||
      static_cast<uint64_t>(h.contentLength) != h.rangeLast - h.rangeFirst + 1)
    return false;
  return h.rangeLast == last || (h.rangeLast < last && h.totalKnown && h.rangeLast + 1 == h.total);
}

std::string trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return std::string(s);
}

}  // namespace

// ------------------------------------------------------------------------------------------
// Pure parts.

bool looksLikeUrl(std::string_view source) {
  size_t p = source.find("://");
  if (p == std::string_view::npos || p == 0) return false;
  for (size_t i = 0; i < p; ++i) {
    char c = source[i];
    bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (i > 0 && ((c >= '0' && c <= '9') || c == '+' ||
                                                                              c == '-' || c == '.'));
    if (!ok) return false;
  }
  return true;
}

bool parseHttpUrl(const std::string& source, HttpUrl& url, std::string& error) {
  const std::string where = "range fetch source '" + source + "': ";
  url = HttpUrl{};
  if (source.empty()) {
    error = "range fetch source is empty (want http://HOST:PORT/path or a file path)";
    return false;
  }
  size_t sep = source.find("://");
  if (sep == std::string::npos) {
    error = where + "not a URL (want http://HOST:PORT/path)";
    return false;
  }
  std::string scheme = source.substr(0, sep);
  if (!iequals(scheme, "http")) {
    error = where + "scheme '" + scheme + "' is not supported (only http://HOST:PORT/path or a local file path)";
    return false;
  }
  std::string_view rest = std::string_view(source).substr(sep + 3);
  size_t slash = rest.find('/');
  std::string_view authority = rest.substr(0, slash);
  for (char c : authority) {
    if (c == '?' || c == '#') {
      error = where + "no path after the host (want http://HOST:PORT/path)";
      return false;
    }
  }
  if (authority.empty()) {
    error = where + "no host (want http://HOST:PORT/path)";
    return false;
  }
  if (authority.find('@') != std::string_view::npos) {
    error = where + "user info '" + std::string(authority.substr(0, authority.find('@'))) + "' is not supported";
    return false;
  }
  std::string_view host, port;
  if (authority.front() == '[') {
    size_t close = authority.find(']');
    if (close == std::string_view::npos) {
      error = where + "unterminated IPv6 address '" + std::string(authority) + "'";
      return false;
    }
    host = authority.substr(1, close - 1);
    std::string_view after = authority.substr(close + 1);
    if (!after.empty()) {
      if (after.front() != ':') {
        error = where + "unexpected '" + std::string(after) + "' after the IPv6 address";
        return false;
      }
      port = after.substr(1);
      if (port.empty()) {
        error = where + "empty port after ':'";
        return false;
      }
    }
    for (char c : host) {
      bool ok = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f') || (c >= 'A' && c <= 'F') || c == ':' || c == '.';
      if (!ok) {
        error = where + "host '" + std::string(host) + "' is not an IPv6 address";
        return false;
      }
    }
  } else {
    size_t colon = authority.find(':');
    host = authority.substr(0, colon);
    if (colon != std::string_view::npos) {
      port = authority.substr(colon + 1);
      if (port.empty()) {
        error = where + "empty port after ':'";
        return false;
      }
    }
    for (char c : host) {
      bool ok = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '-' || c == '.';
      if (!ok) {
        error = where + "host '" + std::string(host) + "' has a character that is not allowed ('" + c + "')";
        return false;
      }
    }
  }
  if (host.empty()) {
    error = where + "no host (want http://HOST:PORT/path)";
    return false;
  }
  url.host = std::string(host);
  if (!port.empty()) {
    uint64_t p = 0;
    if (!parseU64(port, p) || p < 1 || p > 65535) {
      error = where + "port '" + std::string(port) + "' is not a number in 1..65535";
      return false;
    }
    url.port = static_cast<uint16_t>(p);
  }
  if (slash == std::string_view::npos) {
    error = where + "no path after the host (want http://HOST:PORT/path)";
    return false;
  }
  std::string_view path = rest.substr(slash);
  for (size_t i = 0; i < path.size(); ++i) {
    auto c = static_cast<unsigned char>(path[i]);
    if (c <= 0x20 || c >= 0x7f || c == '#') {
      char hex[8];
      std::snprintf(hex, sizeof hex, "0x%02x", c);
      error = where + "the path has a character that must be percent-encoded (" + hex + " at position " +
              std::to_string(i) + ")";
      return false;
    }
  }
  url.path = std::string(path);
  return true;
}

HeadParse parseHttpResponseHead(std::string_view buf, HttpResponseHead& head, std::string& error) {
  head = HttpResponseHead{};
  size_t end = buf.find("\r\n\r\n");
  if (end == std::string_view::npos) {
    if (buf.size() >= kMaxHeadBytes) {
      error = "response head longer than " + std::to_string(kMaxHeadBytes) + " bytes";
      return HeadParse::Bad;
    }
    // A status line that cannot become valid is refused early.
    std::string_view start = buf.substr(0, std::min<size_t>(buf.size(), 5));
    if (std::string_view("HTTP/").substr(0, start.size()) != start) {
      error = "response does not start with 'HTTP/'";
      return HeadParse::Bad;
    }
    return HeadParse::Incomplete;
  }
  if (end + 4 > kMaxHeadBytes) {
    error = "response head longer than " + std::to_string(kMaxHeadBytes) + " bytes";
    return HeadParse::Bad;
  }
  head.headBytes = end + 4;
  std::string_view text = buf.substr(0, end);
  size_t lineEnd = text.find("\r\n");
  std::string_view status = text.substr(0, lineEnd);
  // "HTTP/1.x SSS reason"
  if (status.size() < 12 || status.substr(0, 5) != "HTTP/" || status[8] != ' ') {
    error = "bad status line '" + std::string(status.substr(0, 80)) + "'";
    return HeadParse::Bad;
  }
  bool http10 = status.substr(0, 8) == "HTTP/1.0";
  uint64_t code = 0;
  if (!parseU64(status.substr(9, 3), code) || code < 100 || code > 599 || (status.size() > 12 && status[12] != ' ')) {
    error = "bad status line '" + std::string(status.substr(0, 80)) + "'";
    return HeadParse::Bad;
  }
  head.status = static_cast<int>(code);
  head.close = http10;
  bool keepAlive = false;
  size_t pos = lineEnd == std::string_view::npos ? text.size() : lineEnd + 2;
  while (pos < text.size()) {
    size_t e = text.find("\r\n", pos);
    if (e == std::string_view::npos) e = text.size();
    std::string_view line = text.substr(pos, e - pos);
    pos = e + 2;
    size_t colon = line.find(':');
    if (colon == std::string_view::npos || colon == 0) {
      error = "bad header line '" + std::string(line.substr(0, 80)) + "'";
      return HeadParse::Bad;
    }
    std::string_view name = line.substr(0, colon);
    std::string value = trim(line.substr(colon + 1));
    if (iequals(name, "content-length")) {
      uint64_t n = 0;
      if (!parseU64(value, n) || n > (uint64_t{1} << 40)) {
        error = "bad Content-Length '" + value + "'";
        return HeadParse::Bad;
      }
      if (head.contentLength >= 0 && static_cast<uint64_t>(head.contentLength) != n) {
        error = "two different Content-Length headers";
        return HeadParse::Bad;
      }
      head.contentLength = static_cast<int64_t>(n);
    } else if (iequals(name, "content-range")) {
      std::string_view v = value;
      if (v.size() < 6 || !iequals(v.substr(0, 6), "bytes ")) {
        error = "bad Content-Range '" + value + "'";
        return HeadParse::Bad;
      }
      v.remove_prefix(6);
      size_t slashPos = v.find('/');
      if (slashPos == std::string_view::npos) {
        error = "bad Content-Range '" + value + "'";
        return HeadParse::Bad;
      }
      std::string_view range = v.substr(0, slashPos), total = v.substr(slashPos + 1);
      if (total != "*") {
        if (!parseU64(total, head.total)) {
          error = "bad Content-Range total in '" + value + "'";
          return HeadParse::Bad;
        }
        head.totalKnown = true;
      }
      if (range != "*") {
        size_t dash = range.find('-');
        if (dash == std::string_view::npos || !parseU64(range.substr(0, dash), head.rangeFirst) ||
            !parseU64(range.substr(dash + 1), head.rangeLast) || head.rangeLast < head.rangeFirst ||
            (head.totalKnown && head.rangeLast >= head.total)) {
          error = "bad Content-Range '" + value + "'";
          return HeadParse::Bad;
        }
        head.hasRange = true;
      }
    } else if (iequals(name, "connection")) {
      if (icontainsToken(value, "close")) head.close = true;
      if (icontainsToken(value, "keep-alive")) keepAlive = true;
    } else if (iequals(name, "transfer-encoding")) {
      if (!iequals(value, "identity")) head.chunked = true;
    }
  }
  if (http10 && keepAlive) head.close = false;
  return HeadParse::Ok;
}

bool validRangeFetcherOptions(const RangeFetcherOptions& o, std::string& error) {
  auto bad = [&](const char* field, const std::string& value, const char* rule) {
    error = std::string("range fetch option ") + field + " = " + value + ": " + rule;
    return false;
  };
  if (!(o.connectTimeout_s > 0.0) || !(o.connectTimeout_s <= 3600.0))
    return bad("connectTimeout_s", std::to_string(o.connectTimeout_s), "must be > 0 and <= 3600");
  if (!(o.ioTimeout_s > 0.0) || !(o.ioTimeout_s <= 3600.0))
    return bad("ioTimeout_s", std::to_string(o.ioTimeout_s), "must be > 0 and <= 3600");
  if (o.retryMin_ms < 1 || o.retryMin_ms > 3600000)
    return bad("retryMin_ms", std::to_string(o.retryMin_ms), "must be 1..3600000");
  if (o.retryMax_ms < o.retryMin_ms || o.retryMax_ms > 3600000)
    return bad("retryMax_ms", std::to_string(o.retryMax_ms), "must be retryMin_ms..3600000");
  if (o.pipelineDepth < 1 || o.pipelineDepth > 64)
    return bad("pipelineDepth", std::to_string(o.pipelineDepth), "must be 1..64");
  if (o.maxRange_bytes < 1 || o.maxRange_bytes > (1u << 30))
    return bad("maxRange_bytes", std::to_string(o.maxRange_bytes), "must be 1..1073741824");
  if (o.maxCoalesce_bytes > (1u << 30))
    return bad("maxCoalesce_bytes", std::to_string(o.maxCoalesce_bytes), "must be 0..1073741824");
  if (o.coalesceGap_bytes > (1u << 20))
    return bad("coalesceGap_bytes", std::to_string(o.coalesceGap_bytes), "must be 0..1048576");
  return true;
}

// ------------------------------------------------------------------------------------------
// The fetcher.

struct RangeFetcher::Impl {
  struct Job {
    uint64_t id = 0;
    uint32_t key = 0;
    uint64_t offset = 0;
    uint32_t size = 0;
    uint32_t crc = 0;
    bool verify = false;
    bool sync = false;
    bool noCoalesce = false;
    uint32_t attempts = 0;
    uint32_t corruptCount = 0;
    int64_t notBefore_ns = 0;
    uint64_t last() const { return offset + size - 1; }
  };
  struct Wire {  // one GET on the connection: [first, last] covering its parts
    uint64_t first = 0, last = 0;
    std::vector<Job> parts;
  };

  // Set by open(), then constant.
  std::string source;
  bool http = false;
  HttpUrl url;
  std::string hostHeader;
  int fileFd = -1;
  int wakeFd = -1;
  RangeFetcherOptions opt;
  std::thread worker;
  std::atomic<bool> stop{false};
  std::atomic<uint64_t> total{0};
  std::atomic<uint64_t> syncWaitId{0};

  // Shared with callers, under m.
  mutable std::mutex m;
  std::condition_variable syncCv;
  std::vector<Job> inbox;
  std::vector<RangeResult> done;
  RangeFetcherStats st;
  uint64_t nextId = 1;
  bool syncReady = false;
  RangeResult syncResult;
  std::mutex syncCallMutex;

  // Worker only.
  std::deque<Job> pending;
  std::vector<Job> taken;  // inbox contents, swapped out under the lock
  int sock = -1;
  enum class Conn { Idle, Connecting, Connected } conn = Conn::Idle;
  int64_t connStart_ns = 0, lastProgress_ns = 0, reconnectAt_ns = 0;
  uint32_t backoff_ms = 0;
  std::string sendBuf;
  size_t sendOff = 0;
  std::string recvBuf;
  size_t recvOff = 0;
  bool headParsed = false;
  HttpResponseHead head;
  std::deque<Wire> inflight;
  uint64_t responsesOnConn = 0;
  struct addrinfo* addrs = nullptr;
  struct addrinfo* addrNext = nullptr;

  ~Impl() {
    if (addrs) freeaddrinfo(addrs);
  }

  // ---- shared-state helpers (take the lock briefly) ----
  void wake() {
    uint64_t one = 1;
    ssize_t r = ::write(wakeFd, &one, sizeof one);
    (void)r;  // the counter cannot overflow in practice; a missed wake only delays to the next timeout
  }

  void complete(Job& j, bool ok, std::vector<uint8_t>&& data, std::string&& error) {
    std::lock_guard<std::mutex> lock(m);
    if (ok) st.bytes += data.size();
    if (j.sync) {
      if (syncWaitId.load() == j.id) {
        syncResult.key = j.key;
        syncResult.ok = ok;
        syncResult.data = std::move(data);
        syncResult.error = std::move(error);
        syncReady = true;
        syncCv.notify_all();
      }
      return;
    }
    RangeResult r;
    r.key = j.key;
    r.ok = ok;
    r.data = std::move(data);
    r.error = std::move(error);
    done.push_back(std::move(r));
  }

  template <typename F>
  void bump(F&& f) {
    std::lock_guard<std::mutex> lock(m);
    f(st);
  }

  uint32_t nextBackoff() {
    backoff_ms = backoff_ms == 0 ? opt.retryMin_ms : std::min(opt.retryMax_ms, backoff_ms * 2);
    return backoff_ms;
  }
  uint32_t jobBackoff(uint32_t n) const {  // n-th failure of one job
    uint64_t b = opt.retryMin_ms;
    for (uint32_t i = 1; i < n && b < opt.retryMax_ms; ++i) b *= 2;
    return static_cast<uint32_t>(std::min<uint64_t>(b, opt.retryMax_ms));
  }

  std::string rangeName(const Job& j) const {
    return (j.sync ? std::string("sync range ") : "range key " + std::to_string(j.key) + " ") + "(" +
           rangeText(j.offset, j.last()) + ")";
  }

  // A failed attempt of a job: requeue it (front), or give up after maxAttempts.
  void failAttempt(Job&& j, const std::string& reason, int64_t notBefore_ns, bool front) {
    ++j.attempts;
    if (opt.maxAttempts != 0 && j.attempts >= opt.maxAttempts) {
      complete(j, false, {},
               rangeName(j) + " of " + source + ": gave up after " + std::to_string(j.attempts) + " attempts: " + reason);
      return;
    }
    bump([](RangeFetcherStats& s) { ++s.retries; });
    j.notBefore_ns = notBefore_ns;
    if (front)
      pending.push_front(std::move(j));
    else
      pending.push_back(std::move(j));
  }

  void takeInbox() {
    {
      std::lock_guard<std::mutex> lock(m);
      taken.swap(inbox);
    }
    for (Job& j : taken) {
      if (j.sync)
        pending.push_front(std::move(j));
      else
        pending.push_back(std::move(j));
    }
    taken.clear();
  }

  bool ready(const Job& j, int64_t now) const { return j.notBefore_ns <= now; }

  // Drops sync jobs nobody waits for any more; returns the index of the first ready job or -1.
  long firstReady(int64_t now) {
    for (size_t i = 0; i < pending.size(); ++i) {
      Job& j = pending[i];
      if (j.sync && syncWaitId.load() != j.id) {
        pending.erase(pending.begin() + static_cast<long>(i));
        --i;
        continue;
      }
      if (ready(j, now)) return static_cast<long>(i);
    }
    return -1;
  }

  int64_t earliestNotBefore() const {
    int64_t t = INT64_MAX;
    for (const Job& j : pending) t = std::min(t, j.notBefore_ns);
    return t;
  }

  // A queued job past the end of the (now known) resource is refused without a request.
  bool refusePastEnd(Job& j) {
    uint64_t t = total.load();
    if (j.sync || t == 0 || j.offset + j.size <= t) return false;
    bump([](RangeFetcherStats& s) { ++s.refused; });
    complete(j, false, {},
             rangeName(j) + " is beyond the end of " + source + " (" + std::to_string(t) +
                 " bytes): the client refuses");
    return true;
  }

  // ---- local file mode ----
  void runFile() {
    std::vector<uint8_t> buf;
    while (!stop.load()) {
      takeInbox();
      int64_t now = nowNs();
      long i = firstReady(now);
      if (i < 0) {
        int64_t t = earliestNotBefore();
        int timeout = 1000;
        if (t != INT64_MAX) timeout = static_cast<int>(std::clamp<int64_t>((t - now) / 1000000 + 1, 0, 1000));
        waitWake(-1, 0, timeout);
        continue;
      }
      Job j = std::move(pending[static_cast<size_t>(i)]);
      pending.erase(pending.begin() + i);
      if (refusePastEnd(j)) continue;
      std::vector<uint8_t> data(j.size);
      size_t got = 0;
      int err = 0;
      while (got < j.size) {
        ssize_t n = ::pread(fileFd, data.data() + got, j.size - got, static_cast<off_t>(j.offset + got));
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
          err = errno;
          break;
        }
        if (n == 0) break;
        got += static_cast<size_t>(n);
      }
      bump([&](RangeFetcherStats& s) {
        ++s.wireRequests;
        s.wireBytes += got;
      });
      if (err != 0) {
        failAttempt(std::move(j), std::string("read failed: ") + std::strerror(err), nowNs() + int64_t{jobBackoff(j.attempts + 1)} * 1000000, false);
        continue;
      }
      if (got < j.size) {
        struct stat sb {};
        uint64_t size = ::fstat(fileFd, &sb) == 0 ? static_cast<uint64_t>(sb.st_size) : 0;
        bump([](RangeFetcherStats& s) { ++s.refused; });
        complete(j, false, {}, rangeName(j) + " is beyond the end of " + source + " (" + std::to_string(size) + " bytes)");
        continue;
      }
      deliver(j, std::move(data));
    }
  }

  // Checks the crc; completes the job or requeues it.
  void deliver(Job& j, std::vector<uint8_t>&& data) {
    if (j.verify) {
      uLong c = crc32(0L, Z_NULL, 0);
      c = crc32(c, data.data(), static_cast<uInt>(data.size()));
      if (static_cast<uint32_t>(c) != j.crc) {
        ++j.corruptCount;
        bump([](RangeFetcherStats& s) { ++s.corrupt; });
        char msg[96];
        std::snprintf(msg, sizeof msg, "crc32 mismatch (got %08x, want %08x)", static_cast<unsigned>(c), j.crc);
        if (opt.maxCorruptAttempts != 0 && j.corruptCount >= opt.maxCorruptAttempts) {
          complete(j, false, {},
                   rangeName(j) + " of " + source + ": " + msg + " " + std::to_string(j.corruptCount) + " times");
          return;
        }
        failAttempt(std::move(j), msg, nowNs() + int64_t{jobBackoff(j.corruptCount)} * 1000000, false);
        return;
      }
    }
    complete(j, true, std::move(data), {});
  }

  // Waits for the wake fd (and the socket when fd >= 0) up to timeout_ms. Returns the socket's revents.
  short waitWake(int fd, short events, int timeout_ms) {
    pollfd fds[2] = {{wakeFd, POLLIN, 0}, {fd, events, 0}};
    int n = ::poll(fds, fd >= 0 ? 2 : 1, timeout_ms);
    if (n > 0 && (fds[0].revents & POLLIN)) {
      uint64_t v;
      ssize_t r = ::read(wakeFd, &v, sizeof v);
      (void)r;
    }
    return n > 0 && fd >= 0 ? fds[1].revents : 0;
  }

  // ---- HTTP mode ----
  void closeSocket() {
    if (sock >= 0) ::close(sock);
    sock = -1;
    conn = Conn::Idle;
    sendBuf.clear();
    sendOff = 0;
    recvBuf.clear();
    recvOff = 0;
    headParsed = false;
    responsesOnConn = 0;
  }

  // Drops the connection; the requests on it go back to the front of the queue.
  //  charge: count a failed attempt for each; delay: backoff before reconnecting.
  //  chargeFrontOnly (with charge): only the first request in flight (the one whose response
  //  had begun) is charged; the others, without a byte of their response, are resent uncharged.
  void dropConnection(const std::string& reason, bool charge, bool delay, bool chargeFrontOnly = false) {
    closeSocket();
    int64_t now = nowNs();
    reconnectAt_ns = delay ? now + int64_t{nextBackoff()} * 1000000 : now;
    while (!inflight.empty()) {
      Wire w = std::move(inflight.back());
      inflight.pop_back();
      const bool chargeThis = charge && (!chargeFrontOnly || inflight.empty());
      for (auto it = w.parts.rbegin(); it != w.parts.rend(); ++it) {
        if (chargeThis)
          failAttempt(std::move(*it), reason, 0, true);
        else
          pending.push_front(std::move(*it));
      }
    }
  }

  void connectFailed(const std::string& reason) {
    // Charged to the requests that would have gone out first.
    closeSocket();
    bump([](RangeFetcherStats& s) { ++s.connectFailures; });
    int64_t now = nowNs();
    reconnectAt_ns = now + int64_t{nextBackoff()} * 1000000;
    uint32_t n = 0;
    std::vector<Job> charged;
    while (n < opt.pipelineDepth) {
      long i = firstReady(now);
      if (i < 0) break;
      charged.push_back(std::move(pending[static_cast<size_t>(i)]));
      pending.erase(pending.begin() + i);
      ++n;
    }
    for (auto it = charged.rbegin(); it != charged.rend(); ++it) failAttempt(std::move(*it), reason, 0, true);
  }

  void startConnect() {
    int64_t now = nowNs();
    if (!addrNext) {
      if (addrs) freeaddrinfo(addrs);
      addrs = nullptr;
      addrinfo hints{};
      hints.ai_family = AF_UNSPEC;
      hints.ai_socktype = SOCK_STREAM;
      std::string port = std::to_string(url.port);
      int rc = ::getaddrinfo(url.host.c_str(), port.c_str(), &hints, &addrs);
      if (rc != 0 || !addrs) {
        connectFailed("cannot resolve host '" + url.host + "': " + gai_strerror(rc));
        return;
      }
      addrNext = addrs;
    }
    addrinfo* a = addrNext;
    addrNext = a->ai_next;
    sock = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (sock < 0) {
      connectFailed(std::string("socket: ") + std::strerror(errno));
      return;
    }
    int one = 1;
    ::setsockopt(sock, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    connStart_ns = now;
    lastProgress_ns = now;
    int rc = ::connect(sock, a->ai_addr, a->ai_addrlen);
    if (rc == 0) {
      onConnected();
    } else if (errno == EINPROGRESS) {
      conn = Conn::Connecting;
    } else {
      std::string reason = "connect to " + url.host + ":" + std::to_string(url.port) + ": " + std::strerror(errno);
      if (addrNext) {  // try the host's next address at once
        closeSocket();
        startConnect();
      } else {
        connectFailed(reason);
      }
    }
  }

  void onConnected() {
    conn = Conn::Connected;
    addrNext = nullptr;  // resolve again next time
    lastProgress_ns = nowNs();
    bump([](RangeFetcherStats& s) { ++s.connections; });
  }

  void dispatch(int64_t now) {
    while (inflight.size() < opt.pipelineDepth) {
      long i = firstReady(now);
      if (i < 0) return;
      Job j = std::move(pending[static_cast<size_t>(i)]);
      pending.erase(pending.begin() + i);
      if (refusePastEnd(j)) continue;
      Wire w;
      w.first = j.offset;
      w.last = j.last();
      bool coalesce = opt.maxCoalesce_bytes > 0 && !j.sync && !j.noCoalesce && total.load() != 0;
      w.parts.push_back(std::move(j));
      uint64_t t = total.load();
      while (coalesce) {
        bool grown = false;
        size_t limit = std::min(pending.size(), kCoalesceWindow);
        for (size_t k = 0; k < limit; ++k) {
          Job& q = pending[k];
          if (q.sync || q.noCoalesce || !ready(q, now) || q.offset + q.size > t) continue;
          uint64_t gap = opt.coalesceGap_bytes;
          bool near = q.offset <= w.last + 1 + gap && q.last() + 1 + gap >= w.first;
          if (!near) continue;
          uint64_t first = std::min(w.first, q.offset), last = std::max(w.last, q.last());
          if (last - first + 1 > opt.maxCoalesce_bytes) continue;
          w.first = first;
          w.last = last;
          w.parts.push_back(std::move(q));
          pending.erase(pending.begin() + static_cast<long>(k));
          grown = true;
          break;
        }
        if (!grown) break;
      }
      sendBuf += "GET ";
      sendBuf += url.path;
      sendBuf += " HTTP/1.1\r\nHost: ";
      sendBuf += hostHeader;
      sendBuf += "\r\nRange: bytes=";
      sendBuf += std::to_string(w.first);
      sendBuf += '-';
      sendBuf += std::to_string(w.last);
      sendBuf += "\r\nAccept-Encoding: identity\r\nConnection: keep-alive\r\nUser-Agent: igd-range-fetch\r\n\r\n";
      if (inflight.empty()) lastProgress_ns = now;
      inflight.push_back(std::move(w));
      bump([](RangeFetcherStats& s) { ++s.wireRequests; });
    }
  }

  // Handles one complete response for inflight.front(). Returns false if the connection was dropped.
  bool onResponse(std::string_view body) {
    Wire w = std::move(inflight.front());
    inflight.pop_front();
    ++responsesOnConn;
    const int status = head.status;
    const std::string range = rangeText(w.first, w.last);
    if (head.totalKnown && head.total > 0) total.store(head.total);
    if (status == 206) {
      if (!answersRange(head, w.first, w.last) || body.size() != head.rangeLast - head.rangeFirst + 1) {
        std::string got = head.hasRange ? rangeText(head.rangeFirst, head.rangeLast) : std::string("no Content-Range");
        inflight.push_front(std::move(w));
        dropConnection("asked for " + range + ", the server answered 206 with " + got + " and " +
                           std::to_string(body.size()) + " body bytes",
                       true, true);
        return false;
      }
      backoff_ms = 0;
      for (Job& j : w.parts) {
        if (j.last() > head.rangeLast) {  // the server sent the range up to the resource's end
          bump([](RangeFetcherStats& s) { ++s.refused; });
          complete(j, false, {},
                   rangeName(j) + " is beyond the end of " + source + " (" + std::to_string(head.total) +
                       " bytes): the server sent " + rangeText(head.rangeFirst, head.rangeLast));
          continue;
        }
        const auto* p = reinterpret_cast<const uint8_t*>(body.data()) + (j.offset - w.first);
        deliver(j, std::vector<uint8_t>(p, p + j.size));
      }
      return true;
    }
    backoff_ms = 0;
    std::string reason = "HTTP " + std::to_string(status) + " for " + range;
    if (status == 416 && w.parts.size() > 1) {
      // A coalesced range ran past the end (the file shrank?): ask for each part on its own.
      for (auto it = w.parts.rbegin(); it != w.parts.rend(); ++it) {
        it->noCoalesce = true;
        pending.push_front(std::move(*it));
      }
      return true;
    }
    if (status >= 500 || status == 408 || status == 429) {
      int64_t at = nowNs();
      for (auto it = w.parts.rbegin(); it != w.parts.rend(); ++it)
        failAttempt(std::move(*it), reason, at + int64_t{jobBackoff(it->attempts + 1)} * 1000000, true);
      return true;
    }
    if (status == 416 && head.totalKnown) reason += " (the resource has " + std::to_string(head.total) + " bytes)";
    if (status == 200) reason += " (the server ignored the Range header)";
    for (Job& j : w.parts) {
      bump([](RangeFetcherStats& s) { ++s.refused; });
      complete(j, false, {}, rangeName(j) + " of " + source + ": refused: " + reason);
    }
    return true;
  }

  // Parses as many complete responses as the buffer holds. Returns false if the connection was dropped.
  bool parseResponses() {
    for (;;) {
      std::string_view avail = std::string_view(recvBuf).substr(recvOff);
      if (avail.empty()) break;
      if (inflight.empty()) {
        dropConnection("unexpected " + std::to_string(avail.size()) + " bytes from the server", false, true);
        return false;
      }
      if (!headParsed) {
        std::string err;
        HeadParse r = parseHttpResponseHead(avail, head, err);
        if (r == HeadParse::Incomplete) break;
        if (r == HeadParse::Bad || head.chunked || (head.contentLength < 0 && head.status != 204 && head.status != 304)) {
          if (r == HeadParse::Ok) err = head.chunked ? "chunked responses are not supported" : "no Content-Length";
          dropConnection("protocol error from " + source + ": " + err, true, true);
          return false;
        }
        headParsed = true;
        // Checked before the body is read (and before room is reserved for it): a 206 must carry
        // the range asked for (or its part up to the resource's end) and a Content-Length to match;
        // any other status is handled without its body when the body is long (the connection is
        // then reopened).
        const Wire& w = inflight.front();
        if (head.status == 206 && !answersRange(head, w.first, w.last)) {
          if (head.totalKnown && head.total > 0) total.store(head.total);
          std::string got = head.hasRange ? rangeText(head.rangeFirst, head.rangeLast) : std::string("no Content-Range");
          dropConnection("asked for " + rangeText(w.first, w.last) + ", the server answered 206 with " + got +
                             " and Content-Length " + std::to_string(head.contentLength),
                         true, true);
          return false;
        }
        if (head.status != 206 && head.contentLength > kMaxRefusalBody) {
          recvOff = recvBuf.size();
          headParsed = false;
          if (!onResponse({})) return false;
          dropConnection("a response body of " + std::to_string(head.contentLength) + " bytes was not read", false, false);
          return false;
        }
      }
      size_t bodyLen = head.contentLength < 0 ? 0 : static_cast<size_t>(head.contentLength);
      if (avail.size() < head.headBytes + bodyLen) break;
      std::string_view body = avail.substr(head.headBytes, bodyLen);
      recvOff += head.headBytes + bodyLen;
      headParsed = false;
      bool close = head.close;
      if (!onResponse(body)) return false;
      if (close) {  // announced: reopen at once and resend the rest without counting retries
        dropConnection("the server closed the connection", false, false);
        return false;
      }
    }
    if (recvOff > 0 && recvOff == recvBuf.size()) {
      recvBuf.clear();
      recvOff = 0;
    } else if (recvOff > (1u << 20)) {
      recvBuf.erase(0, recvOff);
      recvOff = 0;
    }
    return true;
  }

  void onReadable() {
    for (;;) {
      size_t old = recvBuf.size();
      constexpr size_t want = 64 << 10;
      if (headParsed && head.contentLength > 0)  // room for the whole body: no reallocation while it arrives
        recvBuf.reserve(recvOff + head.headBytes + static_cast<size_t>(head.contentLength) + want);
      recvBuf.resize(old + want);
      ssize_t n = ::recv(sock, recvBuf.data() + old, want, 0);
      if (n > 0) {
        recvBuf.resize(old + static_cast<size_t>(n));
        lastProgress_ns = nowNs();
        bump([n](RangeFetcherStats& s) { s.wireBytes += static_cast<uint64_t>(n); });
        if (!parseResponses()) return;
        if (static_cast<size_t>(n) < want) return;
        continue;
      }
      recvBuf.resize(old);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
      // EOF or error.
      bool midResponse = headParsed || recvOff < recvBuf.size();
      std::string why = n == 0 ? "the server closed the connection" : std::string("recv: ") + std::strerror(errno);
      if (inflight.empty() && !midResponse) {
        closeSocket();
        return;
      }
      // A keep-alive connection the server closed between responses (a stale keep-alive: its
      // idle timeout ran out as requests went out) is retried at once, and the requests on it,
      // none of which got a byte of its response, are resent without counting a failed attempt
      // (the connection answered before, so each such drop completes at least one request: no
      // endless loop). One that dies mid-response charges the request whose response had begun
      // (only it); one that dies before any response charges all and waits for the backoff.
      bool quick = !midResponse && responsesOnConn > 0;
      if (quick)
        dropConnection(why, false, false);
      else
        dropConnection(why + (midResponse ? " mid-response" : ""), true, true, midResponse);
      return;
    }
  }

  void onWritable() {
    while (sendOff < sendBuf.size()) {
      ssize_t n = ::send(sock, sendBuf.data() + sendOff, sendBuf.size() - sendOff, MSG_NOSIGNAL);
      if (n > 0) {
        sendOff += static_cast<size_t>(n);
        lastProgress_ns = nowNs();
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
      // On a connection that answered before, a send that fails (EPIPE, ECONNRESET) is a stale
      // keep-alive: the requests not answered yet got no byte of a response; resent uncharged.
      if (responsesOnConn > 0 && !headParsed && recvOff == recvBuf.size()) {
        dropConnection(std::string("send: ") + std::strerror(errno), false, false);
        return;
      }
      dropConnection(std::string("send: ") + std::strerror(errno), true, true);
      return;
    }
    sendBuf.clear();
    sendOff = 0;
  }

  void runHttp() {
    while (!stop.load()) {
      takeInbox();
      int64_t now = nowNs();
      if (conn == Conn::Idle && now >= reconnectAt_ns && firstReady(now) >= 0) startConnect();
      if (conn == Conn::Connected) dispatch(now);

      // Sleep until something happens or a deadline passes.
      int64_t deadline = now + 1000 * int64_t{1000000};
      short events = 0;
      if (conn == Conn::Idle) {
        if (!pending.empty()) deadline = std::min(deadline, std::max(reconnectAt_ns, earliestNotBefore()));
      } else if (conn == Conn::Connecting) {
        events = POLLOUT;
        deadline = std::min(deadline, connStart_ns + static_cast<int64_t>(opt.connectTimeout_s * 1e9));
      } else {
        events = POLLIN;
        if (sendOff < sendBuf.size()) events |= POLLOUT;
        if (!inflight.empty()) deadline = std::min(deadline, lastProgress_ns + static_cast<int64_t>(opt.ioTimeout_s * 1e9));
        if (!pending.empty() && inflight.size() < opt.pipelineDepth) deadline = std::min(deadline, earliestNotBefore());
      }
      int timeout = static_cast<int>(std::clamp<int64_t>((deadline - now + 999999) / 1000000, 0, 1000));
      short re = waitWake(conn == Conn::Idle ? -1 : sock, events, timeout);
      if (stop.load()) break;
      now = nowNs();
      if (conn == Conn::Connecting) {
        if (re & (POLLOUT | POLLERR | POLLHUP)) {
          int err = 0;
          socklen_t len = sizeof err;
          ::getsockopt(sock, SOL_SOCKET, SO_ERROR, &err, &len);
          if (err == 0) {
            onConnected();
          } else {
            std::string reason = "connect to " + url.host + ":" + std::to_string(url.port) + ": " + std::strerror(err);
            closeSocket();
            if (addrNext)
              startConnect();
            else
              connectFailed(reason);
          }
        } else if (now - connStart_ns > static_cast<int64_t>(opt.connectTimeout_s * 1e9)) {
          addrNext = nullptr;
          connectFailed("connect to " + url.host + ":" + std::to_string(url.port) + ": timed out after " +
                        std::to_string(opt.connectTimeout_s) + " s");
        }
        continue;
      }
      if (conn != Conn::Connected) continue;
      if (re & POLLOUT) onWritable();
      if (conn == Conn::Connected && (re & (POLLIN | POLLERR | POLLHUP))) onReadable();
      if (conn == Conn::Connected && !inflight.empty() &&
          nowNs() - lastProgress_ns > static_cast<int64_t>(opt.ioTimeout_s * 1e9)) {
        dropConnection("no data from the server for " + std::to_string(opt.ioTimeout_s) + " s", true, true);
      }
    }
    closeSocket();
  }

  void run() {
    if (http)
      runHttp();
    else
      runFile();
  }
};

RangeFetcher::RangeFetcher(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

RangeFetcher::~RangeFetcher() {
  if (!impl_) return;
  impl_->stop.store(true);
  impl_->wake();
  if (impl_->worker.joinable()) impl_->worker.join();
  if (impl_->fileFd >= 0) ::close(impl_->fileFd);
  if (impl_->wakeFd >= 0) ::close(impl_->wakeFd);
}

std::unique_ptr<RangeFetcher> RangeFetcher::open(const std::string& source, const RangeFetcherOptions& options,
                                                 std::string& error) {
  if (!validRangeFetcherOptions(options, error)) return nullptr;
  auto impl = std::make_unique<Impl>();
  impl->source = source;
  impl->opt = options;
  if (source.empty()) {
    error = "range fetch source is empty (want http://HOST:PORT/path or a file path)";
    return nullptr;
  }
  if (looksLikeUrl(source)) {
    if (!parseHttpUrl(source, impl->url, error)) return nullptr;
    impl->http = true;
    bool v6 = impl->url.host.find(':') != std::string::npos;
    impl->hostHeader = (v6 ? "[" + impl->url.host + "]" : impl->url.host) + ":" + std::to_string(impl->url.port);
  } else {
    int fd = ::open(source.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
      error = "range fetch source '" + source + "': cannot open: " + std::strerror(errno);
      return nullptr;
    }
    struct stat sb {};
    if (::fstat(fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
      ::close(fd);
      error = "range fetch source '" + source + "': not a regular file";
      return nullptr;
    }
    impl->fileFd = fd;
    impl->total.store(static_cast<uint64_t>(sb.st_size));
  }
  impl->wakeFd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (impl->wakeFd < 0) {
    error = "range fetch source '" + source + "': eventfd: " + std::strerror(errno);
    if (impl->fileFd >= 0) ::close(impl->fileFd);
    return nullptr;
  }
  impl->inbox.reserve(256);
  impl->done.reserve(256);
  Impl* p = impl.get();
  std::unique_ptr<RangeFetcher> f(new RangeFetcher(std::move(impl)));
  p->worker = std::thread([p] { p->run(); });
  return f;
}

namespace {
bool checkRequest(const RangeRequest& r, const RangeFetcherOptions& opt, uint64_t total, const std::string& source,
                  std::string& error) {
  std::string name = "range key " + std::to_string(r.key) + " (offset " + std::to_string(r.offset) + ", size " +
                     std::to_string(r.size) + ")";
  if (r.size == 0) {
    error = name + ": size 0: the client refuses";
    return false;
  }
  if (r.size > opt.maxRange_bytes) {
    error = name + ": larger than maxRange_bytes = " + std::to_string(opt.maxRange_bytes) + ": the client refuses";
    return false;
  }
  if (r.offset > UINT64_MAX - r.size) {
    error = name + ": the offset overflows: the client refuses";
    return false;
  }
  if (total != 0 && r.offset + r.size > total) {
    error = "range key " + std::to_string(r.key) + " (" + rangeText(r.offset, r.offset + r.size - 1) +
            ") is beyond the end of " + source + " (" + std::to_string(total) + " bytes): the client refuses";
    return false;
  }
  return true;
}
}  // namespace

bool RangeFetcher::submit(const RangeRequest& request, std::string& error) {
  return submit(std::span<const RangeRequest>(&request, 1), error);
}

bool RangeFetcher::submit(std::span<const RangeRequest> requests, std::string& error) {
  Impl& I = *impl_;
  uint64_t total = I.total.load();
  for (const RangeRequest& r : requests)
    if (!checkRequest(r, I.opt, total, I.source, error)) return false;
  bool wasEmpty;
  {
    std::lock_guard<std::mutex> lock(I.m);
    wasEmpty = I.inbox.empty();
    for (const RangeRequest& r : requests) {
      Impl::Job j;
      j.id = I.nextId++;
      j.key = r.key;
      j.offset = r.offset;
      j.size = r.size;
      j.crc = r.crc32;
      j.verify = r.verifyCrc;
      I.inbox.push_back(j);
    }
    I.st.requests += requests.size();
  }
  if (wasEmpty && !requests.empty()) I.wake();
  return true;
}

size_t RangeFetcher::poll(std::vector<RangeResult>& out) {
  Impl& I = *impl_;
  std::lock_guard<std::mutex> lock(I.m);
  size_t n = I.done.size();
  for (RangeResult& r : I.done) {
    if (!r.ok) ++I.st.failed;
    out.push_back(std::move(r));
  }
  I.st.completed += n;
  I.done.clear();
  return n;
}

bool RangeFetcher::fetchSync(uint64_t offset, uint32_t size, std::vector<uint8_t>& out, std::string& error,
                             double timeout_s) {
  Impl& I = *impl_;
  std::lock_guard<std::mutex> one(I.syncCallMutex);
  std::string name = "sync range (offset " + std::to_string(offset) + ", size " + std::to_string(size) + ")";
  if (size == 0 || size > I.opt.maxRange_bytes || offset > UINT64_MAX - size) {
    error = name + " of " + I.source + ": size must be 1.." + std::to_string(I.opt.maxRange_bytes) +
            " and the range must not overflow";
    return false;
  }
  if (!(timeout_s > 0.0)) {
    error = name + ": timeout_s = " + std::to_string(timeout_s) + ": must be > 0";
    return false;
  }
  std::unique_lock<std::mutex> lock(I.m);
  Impl::Job j;
  j.id = I.nextId++;
  j.offset = offset;
  j.size = size;
  j.sync = true;
  I.syncReady = false;
  I.syncWaitId.store(j.id);
  bool wasEmpty = I.inbox.empty();
  I.inbox.push_back(j);
  lock.unlock();
  if (wasEmpty) I.wake();
  lock.lock();
  bool got = I.syncCv.wait_for(lock, std::chrono::duration<double>(timeout_s), [&] { return I.syncReady; });
  I.syncWaitId.store(0);
  if (!got) {
    error = name + " of " + I.source + ": no answer within " + std::to_string(timeout_s) + " s";
    return false;
  }
  I.syncReady = false;
  if (!I.syncResult.ok) {
    error = I.syncResult.error;
    return false;
  }
  out = std::move(I.syncResult.data);
  return true;
}

uint64_t RangeFetcher::resourceBytes() const { return impl_->total.load(); }

RangeFetcherStats RangeFetcher::stats() const {
  std::lock_guard<std::mutex> lock(impl_->m);
  return impl_->st;
}

uint64_t RangeFetcher::outstanding() const {
  std::lock_guard<std::mutex> lock(impl_->m);
  return impl_->st.requests - impl_->st.completed;
}

const std::string& RangeFetcher::source() const { return impl_->source; }

}  // namespace ig::io
